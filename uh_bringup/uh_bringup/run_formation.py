"""``uh-run-formation`` (behind ``scripts/run_formation.sh``): run a team as one process per node.

Starts the recorder, one simulator and one controller per UH, the virtual leader and the clock,
each through its own entry point (``ros2 run`` on a ROS 2 machine), on a private DDS domain; waits
for the run to end; stops everything (also on Ctrl-C and when a node fails: no orphans); then
computes ``metrics.json`` from the recorded bag.

Output directory::

    DIR/bag/            rosbag2 MCAP bag of every topic
    DIR/logs/*.log      one log per node
    DIR/metrics.json    the metrics of DESIGN.md 2.8, computed from the bag
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

from uh_runtime.network import loopback_environment
from uh_topology import topics

__all__ = ['main', 'build_parser', 'node_specs', 'process_commands', 'LAYOUTS']

CASES = ('proposed', 'case1', 'case2')
CLOCKS = ('lockstep', 'realtime')


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
                   help='DDS domain id 0..232 (default: ROS_DOMAIN_ID, else one derived from the process id)')
    p.add_argument('--processes', default='per-node', choices=LAYOUTS,
                   help='process layout: one process per node (default), one per UH, or a single process; '
                        'results are identical')
    p.add_argument('--no-metrics', action='store_true', help='do not compute metrics.json after the run')
    p.add_argument('--startup-timeout', type=float, default=60.0, help='s to wait for all nodes to come up')
    return p


def _check_args(args) -> None:
    if not 0.01 <= args.rate <= 1000:
        raise UsageError(f'--rate {args.rate}: allowed 0.01 .. 1000 (simulated seconds per wall second)')
    if args.duration is not None and not 0 < args.duration <= 1e6:
        raise UsageError(f'--duration {args.duration}: must be > 0 s')
    if args.domain_id is not None and not 0 <= args.domain_id <= 232:
        raise UsageError(f'--domain-id {args.domain_id}: allowed 0..232')


def _prepare_out(out: Path, force: bool) -> None:
    if out.exists() and not out.is_dir():
        raise UsageError(f'--out {out}: exists and is not a directory')
    if out.exists() and any(out.iterdir()):
        if not force:
            raise UsageError(f'--out {out}: exists and is not empty (use --force to replace its content)')
        for child in out.iterdir():
            shutil.rmtree(child) if child.is_dir() and not child.is_symlink() else child.unlink()
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / '.write_test'
        probe.write_text('')
        probe.unlink()
    except OSError as exc:
        raise UsageError(f'--out {out}: cannot write there ({exc.strerror})') from None


def _entry(package: str, executable: str) -> list:
    """Command that starts a node's entry point: ``ros2 run`` on a ROS 2 machine, else the venv script."""
    if os.environ.get('UH_BACKEND') != 'dds' and shutil.which('ros2') and os.environ.get('ROS_DISTRO'):
        return ['ros2', 'run', package, executable]
    script = Path(sys.executable).with_name(executable)
    return [str(script)] if script.exists() else [executable]


#: node kind -> (package, entry point) of its console script
ENTRY_POINTS = {
    'recorder': ('uh_runtime', 'recorder_node'), 'sim': ('uh_sim_node', 'sim_node'),
    'controller': ('uh_controller_node', 'controller_node'),
    'visualization': ('uh_sim_node', 'visualization_node'),
    'virtual_leader': ('uh_sim_node', 'virtual_leader_node'), 'clock': ('uh_sim_node', 'lockstep_clock_node'),
}
LAYOUTS = ('per-node', 'per-uh', 'single')


def node_specs(scenario, scenario_arg: str, case: str, clock: str, rate: float, duration: float | None,
               bag_dir: Path, startup_timeout: float) -> list[tuple[str, str, list]]:
    """``[(name, node kind, ros args), ...]`` of every node of a run, recorder first and clock last."""
    common = ['-p', f'scenario:={scenario_arg}', '-p', f'clock_mode:={clock}']
    if duration is not None:
        common += ['-p', f'duration:={float(duration)}']
    per_step = [name for name, spec in topics.team_topics(scenario.ids) if spec.per_step]
    specs = [('recorder', 'recorder', ['--ros-args', '-p', f'output:={bag_dir}',
                                       '-p', f'progress_topics:=[{",".join(per_step)}]'])]
    for i in scenario.ids:
        ns = ['-r', f'__ns:={topics.uh_namespace(i)}', '-p', f'uh_id:={i}']
        specs.append((f'uh{i}_sim', 'sim', ['--ros-args', *ns, *common]))
        specs.append((f'uh{i}_controller', 'controller', ['--ros-args', *ns, *common, '-p', f'case:={case}']))
    specs.append(('visualization', 'visualization', ['--ros-args', *common]))
    specs.append(('virtual_leader', 'virtual_leader', ['--ros-args', *common]))
    specs.append(('clock', 'clock', ['--ros-args', *common, '-p', f'rate:={float(rate)}',
                                     '-p', 'expect_recorder:=true', '-p', f'startup_timeout:={float(startup_timeout)}']))
    return specs


def process_commands(specs, layout: str, spec_dir: Path) -> list[tuple[str, list]]:
    """``[(process name, command), ...]``: one process per node (``per-node``, each through its entry
    point), one per UH (``per-uh``: its sim and controller; the team nodes and the recorder in one
    more each) or everything in one (``single``). The process holding the clock is last."""
    if layout == 'per-node':
        return [(name, _entry(*ENTRY_POINTS[kind]) + args) for name, kind, args in specs]
    groups: dict[str, list] = {}
    for name, kind, args in specs:
        if layout == 'single':
            group = 'team'
        elif name.startswith('uh'):
            group = name.split('_')[0]
        else:
            group = 'recorder' if kind == 'recorder' else 'team'
        groups.setdefault(group, []).append({'node': kind, 'name': name, 'cli_args': args})
    spec_dir.mkdir(parents=True, exist_ok=True)
    out = []
    for group, nodes in sorted(groups.items(), key=lambda g: any(n['node'] == 'clock' for n in g[1])):
        path = spec_dir / f'{group}.nodes.json'
        path.write_text(json.dumps(nodes, indent=1))
        out.append((group, [sys.executable, '-P', '-m', 'uh_bringup.composed', str(path)]))
    return out


class _Progress:
    """Progress line on stderr from the clock's log ('step k/K ...' lines), redrawn in place on a tty."""

    def __init__(self, log_path: Path):
        self.log_path, self.offset, self.last = log_path, 0, ''
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
            if 'step ' in line or 'team complete' in line or 'run complete' in line:
                self.last = line.split(']: ')[-1]
                print(('\r\033[K' if self.tty else '') + f'[run] {self.last}', end='' if self.tty else '\n',
                      file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.tty and self.last:
            print(file=sys.stderr)


def run(args) -> int:
    from uh_bringup.supervisor import Supervisor
    from uh_topology.scenario import load_scenario

    _check_args(args)
    scenario = load_scenario(args.scenario)
    scenario_arg = args.scenario if args.scenario == 'paper' else str(Path(args.scenario).resolve())
    out = Path(args.out or Path('runs') / datetime.datetime.now().strftime('%Y%m%d-%H%M%S')).resolve()
    _prepare_out(out, args.force)
    domain = args.domain_id
    if domain is None:
        domain = int(os.environ['ROS_DOMAIN_ID']) if os.environ.get('ROS_DOMAIN_ID', '').isdigit() \
            else 1 + os.getpid() % 230
    env = loopback_environment(domain)
    env['PYTHONUNBUFFERED'] = '1'
    duration = args.duration if args.duration is not None else scenario.duration
    print(f'[run] {scenario.name}: {len(scenario.leaders)} leaders, {len(scenario.followers)} followers, '
          f'case {args.case}, {args.clock} clock, {duration:g} s simulated, DDS domain {domain}', file=sys.stderr)
    print(f'[run] output: {out}', file=sys.stderr)

    sup = Supervisor(out / 'logs', env)
    interrupted = []

    def on_signal(signum, _frame):
        interrupted.append(signum)
    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    started = time.monotonic()
    status, failure = 0, None
    try:
        specs = node_specs(scenario, scenario_arg, args.case, args.clock, args.rate, args.duration,
                           out / 'bag', args.startup_timeout)
        for name, cmd in process_commands(specs, args.processes, out / 'logs'):
            sup.start(name, cmd)
        clock = sup.nodes[-1]
        progress = _Progress(clock.log_path)
        while not interrupted:
            progress.update()
            if clock.poll() is not None:
                break
            dead = sup.failed(ignore=(clock.name,))
            if dead is not None:
                failure = dead
                break
            time.sleep(0.1)
        progress.update()
        progress.close()
        if failure is None and clock.poll() not in (None, 0):
            failure = clock
    finally:
        codes = sup.stop_all(last=('recorder',))
        for s, handler in previous.items():
            signal.signal(s, handler)
    wall = time.monotonic() - started
    if interrupted:
        print(f'\n[run] interrupted: every node stopped, bag finalised in {out / "bag"}', file=sys.stderr)
        status = 130
    elif failure is not None:
        print(f'[run] FAILED: node {failure.name} exited with status {failure.returncode}; '
              f'log {failure.log_path}:\n{failure.log_tail()}', file=sys.stderr)
        status = 1
    (out / 'run.json').write_text(json.dumps({
        'command': sys.argv, 'scenario': args.scenario, 'case': args.case, 'clock': args.clock,
        'rate': args.rate, 'processes': args.processes, 'duration_s': duration, 'domain_id': domain, 'wall_time_s': wall,
        'exit_codes': codes, 'pids': {n.name: n.proc.pid for n in sup.nodes if n.proc}, 'interrupted': bool(interrupted), 'failed_node': failure.name if failure else None,
    }, indent=2) + '\n')
    if status == 0 and not args.no_metrics:
        from uh_bringup.bag_metrics import write_metrics_from_bag
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
        parser.exit(2, f'{parser.prog}: error: {exc}\n')
    except Exception as exc:  # scenario errors and the like: one clear line, no traceback
        from uh_topology.errors import ScenarioError
        if isinstance(exc, ScenarioError):
            parser.exit(2, f'{parser.prog}: error: {exc}\n')
        raise


if __name__ == '__main__':
    sys.exit(main())
