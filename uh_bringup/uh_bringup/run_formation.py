"""``uh-run-formation`` (behind ``scripts/run_formation.sh``): run a team as one process per node.

Starts the recorder, one simulator and one controller per UH, the virtual leader and the clock,
each through its own entry point (``ros2 run`` on a ROS 2 machine), on a private DDS domain; waits
for the run to end; stops everything (also on Ctrl-C and when a node fails: no orphans); then
computes ``metrics.json`` from the recorded bag.

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
the bag (killed), the bag is recovered up to its last complete chunk (:func:`uh_runtime.bag.recover_bag`).

``--hosts netns`` runs each UH's nodes in a network namespace of its own (:mod:`uh_bringup.netns`),
``--loss PCT`` drops that share of the packets on every link between helicopters.

Exit status: 0 success; 1 the run failed; 2 bad input (nothing was started); 3 the run completed
but nodes failed during it; 130 interrupted (Ctrl-C, SIGTERM).

Output directory::

    DIR/bag/            rosbag2 MCAP bag of every topic
    DIR/logs/*.log      one log per node
    DIR/metrics.json    the metrics of docs/metrics.md, computed from the bag
    DIR/run.json        what was run (command, scenario, case, clock, domain id, wall time, exit codes)
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import shutil
import signal
import sys
import time
from pathlib import Path

from uh_runtime.network import (MAX_DOMAIN_ID, default_cyclonedds_uri, environment_script, loopback_environment,
                                reserve_domain_id)
from uh_controller_node.gains import CASES
from uh_bringup.team_nodes import NODES, backend_environment, node_specs
from uh_runtime import live_view, scheduling
from uh_wire.run_config import DEFAULT_STALE_TIMEOUT

__all__ = ['main', 'build_parser', 'node_specs', 'process_commands', 'validate_team', 'LAYOUTS', 'MAX_RESPAWNS',
           'EXIT_OK', 'EXIT_FAILED', 'EXIT_USAGE', 'EXIT_DEGRADED', 'EXIT_INTERRUPTED']

CLOCKS = ('lockstep', 'realtime')
HOSTS = ('local', 'netns')
#: how often --respawn restarts one controller before giving up on it
MAX_RESPAWNS = 3
EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_DEGRADED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130


class UsageError(Exception):
    """Bad command-line input; printed as one line, exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog='run_formation.sh',
        description='Run a UH formation-containment team: one process per node, recorded to MCAP, '
                    'metrics computed from the bag.')
    p.add_argument('--scenario', default='paper', help='scenario YAML, or "paper" (default) for the bundled one')
    p.add_argument('--case', default='proposed', choices=CASES, help='controller variant (default: proposed)')
    p.add_argument('--clock', default='lockstep', choices=CLOCKS,
                   help='lockstep: deterministic, as fast as possible (default); realtime: wall-clock ticks')
    p.add_argument('--rate', type=float, default=1.0, help='realtime: simulated seconds per wall second (default 1)')
    p.add_argument('--duration', type=float, default=None, help='simulated seconds (default: the scenario\'s)')
    p.add_argument('--out', default=None, help='output directory (default runs/<timestamp>); must be new or empty')
    p.add_argument('--force', action='store_true', help='write into a non-empty --out (its old content is removed)')
    p.add_argument('--domain-id', type=int, default=None,
                   help=f'DDS domain id 0..{MAX_DOMAIN_ID} (default: ROS_DOMAIN_ID, else a free one that no other run, test or '
                        'benchmark on this machine holds)')
    p.add_argument('--processes', default='per-node', choices=LAYOUTS,
                   help='process layout: one process per node (default), one per UH, or a single process; '
                        'results are identical')
    p.add_argument('--no-metrics', action='store_true', help='do not compute metrics.json after the run')
    p.add_argument('--no-visualization', action='store_true',
                   help='do not start the visualisation node (no /markers in the bag): headless batch runs; '
                        'with one process per node it saves about 8 %% of the CPU of a lockstep step')
    live_view.add_arguments(p, 'the team')
    p.add_argument('--no-standard-views', action='store_true',
                   help='do not publish /tf, /uhN/odom and /diagnostics (docs/visualization.md): for '
                        'benchmarks and batch runs')
    p.add_argument('--startup-timeout', type=float, default=60.0, help='s to wait for all nodes to come up')
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
    return p


def _check_args(args) -> None:
    if not 0.01 <= args.rate <= 1000:
        raise UsageError(f'--rate {args.rate}: allowed 0.01 .. 1000 (simulated seconds per wall second)')
    if args.duration is not None and not 0 < args.duration <= 1e6:
        raise UsageError(f'--duration {args.duration}: allowed > 0 .. 1e6 s')
    if args.domain_id is not None and not 0 <= args.domain_id <= MAX_DOMAIN_ID:
        raise UsageError(f'--domain-id {args.domain_id}: allowed 0..{MAX_DOMAIN_ID}')
    if not 0 < args.startup_timeout <= 3600:
        raise UsageError(f'--startup-timeout {args.startup_timeout}: allowed > 0 .. 3600 s')
    if not 0 < args.stale_timeout <= 60:
        raise UsageError(f'--stale-timeout {args.stale_timeout}: allowed > 0 .. 60 s (simulated)')
    if not 0 <= args.realtime_priority <= scheduling.MAX_PRIORITY:
        raise UsageError(f'--realtime-priority {args.realtime_priority}: allowed 0 (normal scheduling) .. '
                         f'{scheduling.MAX_PRIORITY}')
    if not 0 <= args.loss <= 100:
        raise UsageError(f'--loss {args.loss}: allowed 0 .. 100 (percent)')
    if args.loss > 0 and args.hosts != 'netns':
        raise UsageError(f'--loss {args.loss:g} needs --hosts netns (loss is applied on the links between '
                         'network namespaces)')
    if args.respawn and args.clock != 'realtime':
        raise UsageError('--respawn needs --clock realtime: a lockstep run cannot go on without the steps a '
                         'restarted controller missed')
    if args.respawn and args.processes != 'per-node':
        raise UsageError(f'--respawn needs --processes per-node (with {args.processes} a controller shares '
                         'its process with its simulator, which cannot be restarted)')
    if args.hosts == 'netns' and args.processes == 'single':
        raise UsageError('--hosts netns cannot run --processes single (one process cannot be in several '
                         'network namespaces)')


#: errors of a team's configuration (scenario and gains, airframe, faults, reference): exit status 2
def _config_errors() -> tuple:
    from uh_controller_node.controller import ControllerError
    from uh_sim_node.faults import FaultError
    from uh_core.airframe import HelicopterParamsError
    from uh_sim_node.reference import ReferenceParameterError
    from uh_topology.errors import ScenarioError
    return (ScenarioError, ControllerError, HelicopterParamsError, FaultError, ReferenceParameterError)


def validate_team(scenario, case: str) -> None:
    """Build what every node would build (each UH's controller and plant, the reference) so a bad
    gains or airframe file is reported before any process starts; raises the node's own error.
    """
    from uh_controller_node.controller import UHController
    from uh_controller_node.gains import ControllerGains
    from uh_core.airframe import load_helicopter_params
    from uh_sim_node.helicopter import plant_from_scenario
    from uh_sim_node.reference import VirtualLeaderReference

    # the gains first, named by their file (the controllers would name the scenario)
    ControllerGains.from_mapping(scenario.gains, case, source=str(scenario.gains_path or
                                                                  f'gains of scenario {scenario.name!r}'))
    params = load_helicopter_params(scenario.helicopter)
    for i in scenario.ids:
        UHController(i, scenario, case=case, helicopter_params=params)
        plant_from_scenario(scenario, i, params)
    VirtualLeaderReference(scenario.reference)


def _prepare_out(out: Path, force: bool) -> None:
    try:
        if out.exists() and not out.is_dir():
            raise UsageError(f'--out {out}: exists and is not a directory')
        if out.exists() and any(out.iterdir()):
            if not force:
                raise UsageError(f'--out {out}: exists and is not empty (use --force to replace its content)')
            for child in out.iterdir():
                shutil.rmtree(child) if child.is_dir() and not child.is_symlink() else child.unlink()
        out.mkdir(parents=True, exist_ok=True)
        probe = out / '.write_test'
        probe.write_text('')
        probe.unlink()
    except OSError as exc:
        where = f' ({exc.filename})' if exc.filename and str(exc.filename) != str(out) else ''
        raise UsageError(f'--out {out}: cannot write there: {exc.strerror}{where}') from None


def _entry(package: str, executable: str) -> list:
    """Command that starts a node's entry point: ``ros2 run`` on a ROS 2 machine (the backend is
    chosen by the node's ``UH_BACKEND``), else the venv script.
    """
    if shutil.which('ros2') and os.environ.get('ROS_DISTRO'):
        return ['ros2', 'run', package, executable]
    script = Path(sys.executable).with_name(executable)
    return [str(script)] if script.exists() else [executable]


LAYOUTS = ('per-node', 'per-uh', 'single')


def process_commands(specs, layout: str, spec_dir: Path) -> list[tuple[str, list]]:
    """``[(process name, command), ...]``: one process per node (``per-node``, each through its entry
    point), one per UH (``per-uh``: its sim and controller; the team nodes and the recorder in one
    more each) or everything in one (``single``). The process holding the clock is last.
    """
    return [(name, cmd) for name, _kind, cmd in _processes(specs, layout, spec_dir)]


def _group_kind(group: str) -> str:
    """The node kind that decides what a composed process's death means (see the module docstring)."""
    if group in ('recorder', 'live_view'):
        return group
    return 'sim' if group.startswith('uh') else 'clock'


def _processes(specs, layout: str, spec_dir: Path) -> list[tuple[str, str, list]]:
    """As :func:`process_commands`, with the node kind of each process (for composed ones,
    :func:`_group_kind`).
    """
    if layout == 'per-node':
        return [(name, kind, _entry(NODES[kind].package, NODES[kind].executable) + args) for name, kind, args in specs]
    groups: dict[str, list] = {}
    for name, kind, args in specs:
        if layout == 'single':
            group = 'team'
        elif name.startswith('uh'):
            group = name.split('_')[0]
        else:
            group = kind if kind in ('recorder', 'live_view') else 'team'
        groups.setdefault(group, []).append({'node': kind, 'name': name, 'cli_args': args})
    spec_dir.mkdir(parents=True, exist_ok=True)
    out = []
    for group, nodes in sorted(groups.items(), key=lambda g: any(n['node'] == 'clock' for n in g[1])):
        path = spec_dir / f'{group}.nodes.json'
        path.write_text(json.dumps(nodes, indent=1))
        out.append((group, _group_kind(group), [sys.executable, '-P', '-m', 'uh_bringup.composed', str(path)]))
    return out


class _Progress:
    """Progress line on stderr from the clock's log ('step k/K ...' lines), redrawn in place on a tty."""

    def __init__(self, log_path: Path):
        self.log_path, self.offset, self.last = log_path, 0, ''
        self.team_complete = False
        self.tty = sys.stderr.isatty()

    def update(self) -> None:
        try:
            with open(self.log_path, errors='replace') as f:
                f.seek(self.offset)
                chunk = f.read()
                self.offset = f.tell()
        except OSError:
            return
        for line in chunk.splitlines():
            if 'team complete' in line:
                self.team_complete = True
            if 'step ' in line or 'team complete' in line or 'run complete' in line:
                self.last = line.split(']: ')[-1]
                print(('\r\033[K' if self.tty else '') + f'[run] {self.last}', end='' if self.tty else '\n',
                      file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.tty and self.last:
            print(file=sys.stderr)


def _neighbours_of(scenario, uh_id: int) -> list:
    """UHs whose controllers hear ``uh_id``."""
    return [i for i in scenario.ids if uh_id in scenario.neighbours(i)]


class _Run:
    """Watches a running team and decides what a node's death means (see the module docstring)."""

    def __init__(self, args, scenario, sup, progress, on_change=lambda: None):
        self.args, self.scenario, self.sup, self.progress = args, scenario, sup, progress
        self.on_change = on_change
        self.failures: list = []     # every node death: dicts for run.json
        self.fatal = None            # the NodeProcess whose death ended the run
        self.team_started = None     # wall time of the clock's 'team complete'

    def sim_time(self) -> str:
        if self.args.clock == 'realtime' and self.team_started is not None:
            return f'sim t ~ {(time.monotonic() - self.team_started) * self.args.rate:.1f} s'
        return self.progress.last or 'before the team was complete'

    def handle(self, node) -> None:
        what = node.describe()
        entry = {'node': node.name, 'kind': node.kind, 'how': what, 'returncode': node.returncode,
                 'wall_s': round(time.monotonic() - self.started, 2), 'when': self.sim_time()}
        action, note = self.decide(node)
        entry['action'] = action
        self.failures.append(entry)
        print(f'\n[run] node {node.name} {what} ({entry["when"]}); log {node.log_path}:\n{node.log_tail(8)}',
              file=sys.stderr)
        print(f'[run] {note}', file=sys.stderr)
        if action == 'stop':
            self.fatal = node
        elif action == 'respawn':
            self.sup.respawn(node)
        self.on_change()

    def decide(self, node) -> tuple[str, str]:
        kind = node.kind
        if kind == 'live_view':  # a viewer never stops the team, in either clock mode
            return 'continue', 'the live view is not needed by the team; the run goes on without it'
        if self.args.clock == 'lockstep':
            return 'stop', 'lockstep: every step needs every node; stopping the run'
        if kind in ('clock', 'virtual_leader', 'recorder'):
            return 'stop', f'the {kind.replace("_", " ")} is essential to the run; stopping it'
        if kind == 'visualization':
            return 'continue', 'the visualisation is not needed by the team; the run goes on without markers'
        uh = int(node.name[2:].split('_')[0])
        if kind == 'sim':
            hearers = ', '.join(f'uh{i}' for i in _neighbours_of(self.scenario, uh)) or 'no UH'
            return 'continue', (f'UH{uh} is lost; {hearers} hear it and report it stale after '
                                f'{self.args.stale_timeout:g} s (status.stale_neighbours), then fly on without it '
                                'or hold position; the run goes on')
        if kind == 'controller':
            if self.args.respawn and node.restarts < MAX_RESPAWNS:
                return 'respawn', (f'restarting {node.name} ({node.restarts + 1}/{MAX_RESPAWNS}); it rejoins the '
                                   'running team at the current step')
            why = f'it was restarted {MAX_RESPAWNS} times already' if self.args.respawn else 'no --respawn'
            return 'continue', (f'UH{uh} flies on with its last command ({why}); the run goes on')
        return 'stop', 'stopping the run'

    def watch(self, interrupted: list) -> None:
        clock = self.sup.nodes[-1]
        self.started = time.monotonic()
        while not interrupted:
            self.progress.update()
            if self.team_started is None and self.progress.team_complete:
                self.team_started = time.monotonic()
            if clock.poll() is not None:
                break
            for node in self.sup.exited(ignore=(clock.name,)):
                self.handle(node)
            if self.fatal is not None:
                return
            time.sleep(0.1)
        self.progress.update()
        if not interrupted and clock.poll() not in (None, 0):
            self.handle(clock)
            self.fatal = clock


def _recover_bag_if_needed(bag_dir: Path) -> dict | None:
    """Complete a bag the recorder did not finalise (it was killed); report what was kept."""
    from uh_runtime.bag import recover_bag
    from uh_runtime.bag_reader import BagError
    if (bag_dir / 'metadata.yaml').exists() or not bag_dir.is_dir():
        return None
    try:
        result = recover_bag(bag_dir)
    except BagError as exc:
        print(f'[run] the bag in {bag_dir} was not finalised and cannot be recovered: {exc}', file=sys.stderr)
        return {'recovered': False, 'problem': str(exc)}
    total = sum(result.counts.values())
    print(f'[run] the recorder did not finalise the bag: recovered {total} messages up to the last complete '
          f'chunk ({result.lost_bytes} bytes after it were unreadable); the damaged file is kept as '
          f'{result.path.name}', file=sys.stderr)
    return {'recovered': True, 'messages': total, 'lost_bytes': result.lost_bytes, 'problem': result.problem}


def run(args) -> int:
    from uh_bringup.supervisor import Supervisor
    from uh_topology.scenario import load_scenario

    _check_args(args)
    scenario = load_scenario(args.scenario)
    validate_team(scenario, args.case)
    if scenario.impairments is not None and args.clock != 'lockstep':
        raise UsageError(f'scenario {scenario.name!r} has impairments (docs/campaigns.md#impairments), which are '
                         'defined on control steps: run it with --clock lockstep')
    scenario_arg = args.scenario if args.scenario == 'paper' else str(Path(args.scenario).resolve())
    try:
        default_cyclonedds_uri()   # a bad ROS_AUTOMATIC_DISCOVERY_RANGE is refused before --out is touched
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    out = Path(args.out or Path('runs') / datetime.datetime.now().strftime('%Y%m%d-%H%M%S')).resolve()
    network = None
    if args.hosts == 'netns':
        from uh_bringup import netns
        try:
            netns.check_available(args.loss)
        except netns.NetnsError as exc:
            raise UsageError(str(exc)) from None
    if args.foxglove is not None:
        if args.hosts == 'netns':
            raise UsageError('--foxglove with --hosts netns: the live view would live in a network namespace '
                             'no viewer reaches; use one of them')
        try:    # before any node starts: a port in use is the user's to fix
            live_view.check_available(args.foxglove_host, args.foxglove)
        except live_view.LiveViewError as exc:
            raise UsageError(str(exc)) from None
    _prepare_out(out, args.force)
    domain = args.domain_id
    if domain is None:
        # held by this process for the run, so that runs started at once never share a domain
        domain = int(os.environ['ROS_DOMAIN_ID']) if os.environ.get('ROS_DOMAIN_ID', '').isdigit() \
            else reserve_domain_id()
    try:
        env = loopback_environment(domain)
    except ValueError as exc:   # a bad ROS_AUTOMATIC_DISCOVERY_RANGE
        raise UsageError(str(exc)) from None
    env['PYTHONUNBUFFERED'] = '1'
    duration = args.duration if args.duration is not None else scenario.duration
    print(f'[run] {scenario.name}: {len(scenario.leaders)} leaders, {len(scenario.followers)} followers, '
          f'case {args.case}, {args.clock} clock, {duration:g} s simulated, DDS domain {domain}', file=sys.stderr)
    priority = args.realtime_priority if args.clock == 'realtime' else 0
    if priority:
        why_not = scheduling.permitted(priority)
        print(f'[run] real-time scheduling: SCHED_FIFO priority {priority} for the clock, simulators, controllers '
              'and virtual leader' if why_not is None else
              f'[run] real-time scheduling not available, the control loop runs at normal priority and may miss '
              f'steps on a busy machine: {why_not}', file=sys.stderr)
        priority = priority if why_not is None else 0
    print(f'[run] output: {out}', file=sys.stderr)
    (out / 'env.sh').write_text(environment_script(env))
    print(f'[run] from another terminal: source {out / "env.sh"}   (then ros2 topic list, or uh topic list)',
          file=sys.stderr)

    sup = Supervisor(out / 'logs', env, respawn_priority=priority)
    interrupted = []

    def on_signal(signum, _frame):
        interrupted.append(signum)
    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    started = time.monotonic()
    watcher = None
    dropped = None
    # run.json is written when the nodes have started (status "running", their pids), after every
    # node failure and at the end
    info = {'command': sys.argv, 'scenario': args.scenario, 'case': args.case, 'clock': args.clock,
            'rate': args.rate, 'processes': args.processes, 'visualization': not args.no_visualization,
            'standard_views': not args.no_standard_views, 'duration_s': duration, 'domain_id': domain,
            'foxglove': None if args.foxglove is None else f'ws://{args.foxglove_host}:{args.foxglove}',
            'hosts': args.hosts, 'loss_pct': args.loss, 'respawn': args.respawn, 'realtime_priority': priority,
            'exit_status': None}

    def write_info():
        info.update(pids={n.name: n.proc.pid for n in sup.nodes if n.proc},
                    all_pids={n.name: n.pids for n in sup.nodes},
                    respawns={n.name: n.restarts for n in sup.nodes if n.restarts},
                    node_failures=watcher.failures if watcher else [])
        tmp = out / 'run.json.tmp'
        tmp.write_text(json.dumps(info, indent=2) + '\n')
        tmp.replace(out / 'run.json')
    try:
        if args.hosts == 'netns':
            from uh_bringup import netns
            swept = netns.sweep_stale()
            if swept:
                print(f'[run] removed {len(swept)} network namespaces left by runs that were killed', file=sys.stderr)
            network = netns.TeamNetwork(scenario.ids, args.loss).__enter__()
            print(f'[run] network: {network.describe()}', file=sys.stderr)
        specs = node_specs(scenario, scenario_arg, args.case, args.clock, args.rate, args.duration,
                           out / 'bag', args.startup_timeout, args.stale_timeout,
                           visualization=not args.no_visualization,
                           standard_views=not args.no_standard_views,
                           live_view=(args.foxglove_host, args.foxglove) if args.foxglove is not None else None,
                           realtime_priority=priority)
        if args.foxglove is not None:
            print(f'[run] live view: {live_view.connect_hint(args.foxglove_host, args.foxglove)}', file=sys.stderr)
        for name, kind, cmd in _processes(specs, args.processes, out / 'logs'):
            # composed processes: only the recorder's own process (per-uh) is of an infrastructure kind
            node_env = {**env, **backend_environment(kind, env)}
            if network is not None:
                sup.prefix[name] = network.prefix(name)
                node_env = network.environment(name, node_env)
            if node_env != env:
                sup.envs[name] = node_env
            sup.start(name, cmd, kind=kind)
        progress = _Progress(sup.nodes[-1].log_path)
        watcher = _Run(args, scenario, sup, progress, on_change=write_info)
        write_info()
        watcher.watch(interrupted)
        progress.close()
    finally:
        codes = sup.stop_all(last=('recorder',))
        if network is not None:
            dropped = network.dropped()
            network.close()
        for s, handler in previous.items():
            signal.signal(s, handler)
    wall = time.monotonic() - started
    recovery = _recover_bag_if_needed(out / 'bag')
    failures = watcher.failures if watcher else []
    fatal = watcher.fatal if watcher else None
    if interrupted:
        print(f'\n[run] interrupted: every node stopped, bag finalised in {out / "bag"}', file=sys.stderr)
        status = EXIT_INTERRUPTED
    elif fatal is not None:
        print(f'[run] FAILED: node {fatal.name} {fatal.describe()}; log {fatal.log_path}', file=sys.stderr)
        status = EXIT_FAILED
    elif failures:
        print('[run] completed with node failures: ' + '; '.join(f'{f["node"]} {f["how"]} ({f["action"]})'
                                                                 for f in failures), file=sys.stderr)
        status = EXIT_DEGRADED
    else:
        status = EXIT_OK
    info.update(wall_time_s=wall, exit_status=status, exit_codes=codes, interrupted=bool(interrupted),
                failed_node=fatal.name if fatal else None, bag_recovery=recovery, dropped_packets=dropped)
    write_info()
    if status in (EXIT_OK, EXIT_DEGRADED) and not args.no_metrics:
        from uh_report.bag_metrics import write_metrics_from_bag
        metrics = write_metrics_from_bag(out / 'bag', scenario, args.case, out / 'metrics.json', wall_time_s=wall)
        print('[run] metrics: ' + ', '.join(f'{k} {v:.4g}' for k, v in metrics.items()
                                            if isinstance(v, float)), file=sys.stderr)
    print(f'[run] done in {wall:.1f} s wall: {out}', file=sys.stderr)
    return status


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return run(args)
    except UsageError as exc:
        parser.exit(EXIT_USAGE, f'{parser.prog}: error: {exc}\n')
    except _config_errors() as exc:  # scenario, gains, airframe: one clear line, no traceback
        parser.exit(EXIT_USAGE, f'{parser.prog}: error: {exc}\n')
    except RuntimeError as exc:
        from uh_bringup.netns import NetnsError
        if isinstance(exc, NetnsError):
            parser.exit(EXIT_FAILED, f'{parser.prog}: error: cannot set up the network namespaces: {exc}\n')
        raise


if __name__ == '__main__':
    sys.exit(main())
