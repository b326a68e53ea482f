"""``uh-run-formation`` (behind ``scripts/run_formation.sh``): run a team as one process per node.

Starts the recorder, one simulator and one controller per UH, the virtual leader and the clock,
each through its own entry point (``ros2 run`` on a ROS 2 machine), on a private DDS domain; waits
for the run to end; stops everything (also on Ctrl-C and when a node fails: no orphans); then
computes ``metrics.json`` from the recorded bag and writes the run's report (``report/index.html``).

Everything it is given is checked before anything starts: options (one line naming the option,
the value and what is allowed; exit status 2), the output directory (new or empty unless
``--force``, writable), the scenario, its gains and airframe files and the controller of every UH.

When a node dies during the run it is named with how it ended (exit status or signal) and the
tail of its log, and the run goes on only where that makes sense:

- lockstep: every step needs every node, so any death ends the run (status 1);
- realtime: the clock, the virtual leader and the recorder are essential (the run ends, status 1);
  a simulator's death loses that helicopter, whose neighbours report it stale and fly on without it
  (status 3 at the end: completed with failures); a controller is restarted with ``--respawn`` (up
  to ``MAX_RESPAWNS`` times) and rejoins the running team, otherwise its helicopter flies on with the
  last command it got (status 3); the visualisation is not needed (status 3).

Every node failure is listed in ``run.json`` (``node_failures``). If the recorder did not finalise
the bag (killed), the bag is recovered up to its last complete chunk (:func:`uh_runtime.bags.bag.recover_bag`).

``--hosts netns`` runs each UH's nodes in a network namespace of its own (:mod:`uh_bringup.netns`),
``--loss PCT`` drops that share of the packets on every link between helicopters.

Exit status: 0 success; 1 the run failed; 2 bad input (nothing was started); 3 the run completed
but nodes failed during it; 130 interrupted (Ctrl-C, SIGTERM).

The work is split by concern: :mod:`uh_bringup.run_checks` (options, scenario, team, output
directory), :mod:`uh_bringup.run_setup` (domain, environment, scheduling, network namespaces,
starting the processes), :mod:`uh_bringup.run_processes` (which nodes share a process),
:mod:`uh_bringup.run_watch` (what a node's death means) and :mod:`uh_bringup.run_outcome`
(``run.json``, exit status, bag recovery, metrics).

Output directory::

    DIR/bag/            rosbag2 MCAP bag of every topic
    DIR/logs/*.log      one log per node
    DIR/metrics.json    the metrics of docs/metrics.md, computed from the bag
    DIR/report/         the run's report: index.html / report.md with the metrics, the fault
                        isolation, the errors and XY snapshots (not with --no-report)
    DIR/run.json        what was run (command, scenario, case, clock, domain id, wall time, exit codes)
"""
from __future__ import annotations

import argparse
import signal
import sys
import time

from uh_bringup.netns import NetnsError
from uh_bringup.run_checks import CONFIG_ERRORS, HOSTS, LAYOUTS, UsageError, check_run, validate_team
from uh_bringup.run_outcome import (
    EXIT_DEGRADED,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    RunRecord,
    exit_status,
    overlap_notice,
    recover_bag_if_needed,
    run_info,
    write_metrics,
)
from uh_bringup.run_processes import process_commands
from uh_bringup.run_secure import SecureRunError, keystore_for_run, security_environment
from uh_bringup.run_setup import (
    open_network,
    realtime_priority,
    run_environment,
    run_node_names,
    start_team,
    team_specs,
    write_environment_script,
)
from uh_bringup.run_watch import MAX_RESPAWNS, RunProgress, RunWatcher
from uh_bringup.supervisor import Supervisor
from uh_bringup.team_nodes import node_specs
from uh_controller_node.gains import CASES
from uh_runtime import scheduling
from uh_runtime.bags import live_view
from uh_runtime.command_line import ArgumentParser
from uh_runtime.network import MAX_DOMAIN_ID
from uh_team.departures import scenario_departures
from uh_topology.safety import add_safety_argument
from uh_wire.run_defaults import CLOCK_MODES, DEFAULT_STALE_TIMEOUT, DEFAULT_STARTUP_TIMEOUT

__all__ = ['main', 'build_parser', 'node_specs', 'process_commands', 'validate_team', 'LAYOUTS', 'MAX_RESPAWNS',
           'EXIT_OK', 'EXIT_FAILED', 'EXIT_USAGE', 'EXIT_DEGRADED', 'EXIT_INTERRUPTED']


def build_parser() -> argparse.ArgumentParser:
    """Return the parser of ``run_formation.sh``'s command line."""
    p = ArgumentParser(
        prog='run_formation.sh',
        description='Run a UH formation-containment team: one process per node, recorded to MCAP, '
                    'metrics computed from the bag.')
    p.add_argument('--scenario', default='paper', help='scenario YAML, or "paper" (default) for the bundled one')
    p.add_argument('--case', default='proposed', choices=CASES, help='controller variant (default: proposed)')
    add_safety_argument(p)
    p.add_argument('--clock', default='lockstep', choices=CLOCK_MODES,
                   help='lockstep: deterministic, as fast as possible (default); realtime: wall-clock ticks')
    p.add_argument('--rate', type=float, default=1.0, help='realtime: simulated seconds per wall second (default 1)')
    p.add_argument('--duration', type=float, default=None, help='simulated seconds (default: the scenario\'s)')
    p.add_argument('--out', default=None, help='output directory (default runs/<timestamp>); must be new or empty')
    p.add_argument('--force', action='store_true', help='write into a non-empty --out (its old content is removed)')
    p.add_argument('--domain-id', type=int, default=None,
                   help=f'DDS domain id 0..{MAX_DOMAIN_ID} (default: ROS_DOMAIN_ID, else a free one that no other '
                        'run, test or benchmark on this machine holds)')
    p.add_argument('--processes', default='per-node', choices=LAYOUTS,
                   help='process layout: one process per node (default), one per UH, a few workers holding '
                        'blocks of UHs, or a single process; results are identical')
    p.add_argument('--workers', type=int, default=None, metavar='N',
                   help='--processes workers: processes holding the UHs (default: the CPUs available); the team '
                        'nodes and the recorder run in one more each')
    p.add_argument('--no-metrics', action='store_true',
                   help='do not compute metrics.json after the run (and write no report)')
    p.add_argument('--no-report', action='store_true',
                   help='do not write the run\'s report (DIR/report/index.html: metrics, errors and XY snapshots)')
    p.add_argument('--no-visualization', action='store_true',
                   help='do not start the visualisation node (no /markers in the bag): headless batch runs; '
                        'with one process per node it saves about 8 %% of the CPU of a lockstep step')
    live_view.add_arguments(p, 'the team')
    p.add_argument('--no-standard-views', action='store_true',
                   help='do not publish /tf, /uhN/odom and /diagnostics (docs/visualization.md): for '
                        'benchmarks and batch runs')
    p.add_argument('--startup-timeout', type=float, default=DEFAULT_STARTUP_TIMEOUT,
                   help='s to wait for all nodes to come up')
    p.add_argument('--respawn', action='store_true',
                   help=f'realtime: restart a controller process that dies (up to {MAX_RESPAWNS} times each); '
                        'it rejoins the running team')
    p.add_argument('--stale-timeout', type=float, default=DEFAULT_STALE_TIMEOUT,
                   help='realtime: simulated s after which a neighbour\'s data is stale and left out '
                        f'(default {DEFAULT_STALE_TIMEOUT:g})')
    p.add_argument('--realtime-priority', type=int, default=scheduling.DEFAULT_PRIORITY, metavar='N',
                   help='realtime: run the clock, simulators, controllers and virtual leader under SCHED_FIFO '
                        f'priority N (1..{scheduling.MAX_PRIORITY}), so they keep the control period on a busy '
                        'machine; needs CAP_SYS_NICE (root has it) or an rtprio limit, else the run goes on at normal '
                        f'priority and says so; 0: normal scheduling (default {scheduling.DEFAULT_PRIORITY})')
    p.add_argument('--hosts', default='local', choices=HOSTS,
                   help='local: every node on this host (default); netns: each UH\'s nodes in their own network '
                        'namespace, linked by a bridge (needs root and iproute2)')
    p.add_argument('--loss', type=float, default=0.0,
                   help='with --hosts netns: percent of packets lost on every link between helicopters (nftables)')
    p.add_argument('--secure', action='store_true',
                   help='DDS Security: every node a process with its own identity, permissions from the scenario\'s '
                        'graph, payloads encrypted; on .venv-secure (Cyclone DDS 0.10.2), domains 0..230 '
                        '(docs/security.md)')
    p.add_argument('--keystore', default=None, metavar='DIR',
                   help='with --secure: the keystore of uh-security create for this scenario and safety setting '
                        '(made there if DIR is new; default: a new one in OUT/keystore)')
    return p


def _supervise(args, scenario, specs, out, env, sup, record) -> tuple:
    """Start the team's nodes ``specs``, watch it until it ends and stop every process.

    Returns ``(signals received, exit codes of the processes, packets dropped by the network or None)``.
    """
    interrupted = []

    def on_signal(signum, _frame):
        interrupted.append(signum)
    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    network = dropped = None
    try:
        network = open_network(args, scenario)
        start_team(args, specs, out, env, sup, network)
        progress = RunProgress(sup.nodes[-1].log_path)
        record.watcher = RunWatcher(args, scenario, sup, progress, on_change=record.write)
        record.write()
        record.watcher.watch(interrupted)
        progress.close()
    finally:
        codes = sup.stop_all(last=('recorder',))
        if network is not None:
            dropped = network.dropped()
            network.close()
        for s, handler in previous.items():
            signal.signal(s, handler)
    return interrupted, codes, dropped


def run(args) -> int:
    """Check, run and supervise the team of ``args``; return the exit status (module docstring)."""
    scenario, scenario_arg, out = check_run(args)
    store, domains = keystore_for_run(args, scenario, scenario_arg, out) if args.secure else (None, None)
    domain, env = run_environment(args.domain_id, domains)
    for name in [k for k in env if k.startswith('ROS_SECURITY_')]:   # e.g. from a secure run's env.sh
        del env[name]
    env.update(security_environment(store) if store else {})
    duration = args.duration if args.duration is not None else scenario.duration
    filter_state = 'on' if scenario.safety.enabled else "off (the paper's law alone)"
    print(f'[run] {scenario.name}: {len(scenario.leaders)} leaders, {len(scenario.followers)} followers, '
          f'case {args.case}, {args.clock} clock, {duration:g} s simulated, safety filter {filter_state}, '
          f'DDS domain {domain}', file=sys.stderr)
    priority = realtime_priority(args)
    specs = team_specs(args, scenario, scenario_arg, out, priority)
    write_environment_script(out, env, run_node_names(specs))
    sup = Supervisor(out / 'logs', env, respawn_priority=priority)
    record = RunRecord(out, run_info(args, duration, domain, priority, scenario.safety.enabled,
                                     scenario_departures(scenario, args.case)), sup)
    record.info.update(keystore=str(store) if store else None)
    started = time.monotonic()
    interrupted, codes, dropped = _supervise(args, scenario, specs, out, env, sup, record)
    wall = time.monotonic() - started
    recovery = recover_bag_if_needed(out / 'bag')
    watcher = record.watcher
    fatal = watcher.fatal if watcher else None
    status = exit_status(bool(interrupted), fatal, watcher.failures if watcher else [], out)
    record.info.update(wall_time_s=wall, exit_status=status, exit_codes=codes, interrupted=bool(interrupted),
                       failed_node=fatal.name if fatal else None, bag_recovery=recovery, dropped_packets=dropped)
    record.write()
    if status in (EXIT_OK, EXIT_DEGRADED) and not args.no_metrics:
        problem = write_metrics(out, scenario, args.case, wall, report=not args.no_report)
        if problem is not None:   # the run is not done without its metrics: say so in run.json too
            status = EXIT_FAILED
            record.info.update(exit_status=status, metrics_error=problem)
            record.write()
    after = time.monotonic() - started - wall
    print(f'[run] done in {wall + after:.1f} s wall ({wall:.1f} s the team, {after:.1f} s recovery, metrics and '
          f'report): {out}', file=sys.stderr)
    overlap = overlap_notice(out / 'metrics.json', scenario.safety.enabled)
    if overlap:
        print(f'[run] {overlap}', file=sys.stderr)
    return status


def main(argv=None) -> int:
    """Run ``run_formation.sh``'s command line ``argv``; return its exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return run(args)
    except (UsageError, SecureRunError) as exc:
        parser.exit(EXIT_USAGE, f'{parser.prog}: error: {exc}\n')
    except CONFIG_ERRORS as exc:  # scenario, gains, airframe: one clear line, no traceback
        parser.exit(EXIT_USAGE, f'{parser.prog}: error: {exc}\n')
    except NetnsError as exc:
        parser.exit(EXIT_FAILED, f'{parser.prog}: error: cannot set up the network namespaces: {exc}\n')


if __name__ == '__main__':
    sys.exit(main())
