"""The benchmark suite: its sections and the results mapping (``scripts/bench.sh``).

Sections (every figure is measured in the same invocation as the baseline it is compared with):

``transport``
    What one message costs (:mod:`uh_bench.transport`): loopback UDP, a node of this stack in
    another process, publisher and subscription in one process.
``paper``
    The paper scenario in lockstep for each process layout (``per-node``: one process per node;
    ``per-uh``; ``single``), and the in-process reference simulation of the same scenario and
    duration: real-time factors and their ratio, CPU seconds of the node processes; and the
    per-node run again without ``/tf``, odom and ``/diagnostics`` (what they cost).
``components``
    Per-step cost of the controller and of the helicopter model in process (microseconds).
``scaling``
    Generated teams (:mod:`uh_topology.generate`) of 5, 10, 20 and 40 UHs in lockstep: real-time
    factor, total CPU seconds of the node processes, CPU per simulated second, and the
    in-process reference of the same team as baseline.
``realtime``
    Real-time runs at the nominal control rate (rate 1) with the latency probe
    (:mod:`uh_bench.probe`): state-to-command latency p50/p99 per controller, late and missed
    steps; 5 UHs is the paper scenario, larger teams are generated.
``backends``
    The paper scenario, one process per node, on the Cyclone DDS backend (``UH_BACKEND=dds``) and
    as a ROS 2 user runs it (the team's nodes on real rclpy, the recorder and the visualisation on
    the DDS backend), lockstep and real time at rate 1: real-time factor, CPU per step (node
    processes after start-up), p99 latency, late and missed steps. rclpy is skipped, with the
    reason in the results, when this Python cannot import it (no ROS 2 sourced).
    Then real time again on a busy machine (one busy-looping process per core, plus one), with the
    control loop under SCHED_FIFO (``--realtime-priority``, the default) and at normal priority
    (``--realtime-priority 0``): late and missed steps of each (docs/performance.md#real-time-scheduling).
    Also the CPU per received message of each executor (:mod:`uh_bench.executors`).
``campaign``
    ``uh-campaign`` throughput (:mod:`uh_bench.campaign`): runs per second of a campaign of
    paper-scenario runs (60 s simulated) on local worker processes against one run in process,
    as a fraction of every core busy with runs; and the time 1,000 such runs take at that rate.
``memory``
    Peak resident set of the node processes (from every lockstep and real-time run above).

The machine is described in the results (CPU model, cores, load average before and after), since
shared machines make absolute figures noisy; ratios measured in the same invocation are the
figures to compare.

The goals and their evaluation are :mod:`uh_bench.results`; the markdown tables of the results are
:mod:`uh_bench.tables` (:func:`markdown` is importable from here too).
"""
from __future__ import annotations

import contextlib
import datetime
import json
import os
import platform
import signal
import subprocess
import sys
import time
from pathlib import Path

from uh_runtime import scheduling
from uh_runtime.network import release_domain_id, reserve_domain_id
from uh_topology.scenario import load_scenario

from . import campaign, executors, inprocess, runs, transport
from .results import GOALS, all_runs, evaluate_goals
from .tables import markdown

__all__ = ['MODES', 'GOALS', 'run_suite', 'markdown', 'machine_info', 'evaluate_goals']

#: Section parameters of the quick (< 5 minutes) and the full suite.
MODES = {
    'quick': {'transport_quick': True, 'paper_duration': 20.0, 'paper_layouts': ('per-node', 'single'),
              'component_steps': 500, 'scaling_sizes': (5, 10, 20, 40), 'scaling_duration': 3.0,
              'scaling_layouts': ('per-node', 'workers', 'single'), 'realtime_duration': 8.0,
              'realtime_runs': ((5, 'per-node'), (5, 'single'), (20, 'per-node'), (20, 'workers'), (20, 'single')),
              'backend_lockstep_duration': 20.0, 'backend_realtime_duration': 20.0, 'campaign_runs': 100,
              'contention_runs': ('fifo', 'normal')},
    'full': {'transport_quick': False, 'paper_duration': 60.0, 'paper_layouts': ('per-node', 'per-uh', 'single'),
             'component_steps': 3000, 'scaling_sizes': (5, 10, 20, 40), 'scaling_duration': 20.0,
             'scaling_layouts': ('per-node', 'workers', 'single'), 'realtime_duration': 60.0,
             'realtime_runs': ((5, 'per-node'), (5, 'single'), (20, 'per-node'), (20, 'workers'), (20, 'single')),
             'backend_lockstep_duration': 60.0, 'backend_realtime_duration': 60.0, 'campaign_runs': 1000,
             'contention_runs': ('fifo', 'normal')},
}


def machine_info() -> dict:
    """CPU model, core count, memory, load average, Python and the repository commit."""
    model = None
    try:
        for line in open('/proc/cpuinfo'):
            if line.startswith('model name'):
                model = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    mem_kb = None
    try:
        for line in open('/proc/meminfo'):
            if line.startswith('MemTotal:'):
                mem_kb = int(line.split()[1])
    except OSError:
        pass
    commit = None
    try:
        commit = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], capture_output=True, text=True,
                                cwd=Path(__file__).resolve().parent, timeout=10).stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        pass
    return {'cpu_model': model, 'nproc': os.cpu_count(), 'memory_mb': mem_kb // 1024 if mem_kb else None,
            'loadavg': os.getloadavg(), 'python': platform.python_version(), 'platform': platform.platform(),
            'commit': commit}


def _log(msg: str) -> None:
    print(f'[bench] {msg}', file=sys.stderr, flush=True)


def _team_file(workdir: Path, size: int, duration: float) -> Path:
    from uh_topology.generate import split_team, write_team_scenario
    n, m = split_team(size)
    return write_team_scenario(workdir / f'team{size}.yaml', n, m, duration=duration)


def _paper(cfg, workdir, results):
    d = cfg['paper_duration']
    _log(f'in-process reference, paper scenario, {d:g} s')
    ref = inprocess.reference_rtf('paper', d)
    section = {'duration_s': d, 'inprocess': ref, 'lockstep': {}}
    for layout in cfg['paper_layouts']:
        _log(f'lockstep paper scenario, {layout}, {d:g} s')
        run = runs.run_team('paper', workdir / f'paper-{layout}', layout=layout, duration=d,
                            timeout=60 + 30 * d)
        run['ratio_to_inprocess'] = run['rtf'] / ref['rtf'] if run['rtf'] else None
        section['lockstep'][layout] = run
        _log(f'  real-time factor {run["rtf"]}, CPU {run["cpu_s"]:.1f} s, status {run["status"]}')
    if 'per-node' in section['lockstep']:
        # what /tf, /uhN/odom and /diagnostics cost (docs/visualization.md): the same run without them
        _log(f'lockstep paper scenario, per-node, --no-standard-views, {d:g} s')
        bare = runs.run_team('paper', workdir / 'paper-per-node-no-views', layout='per-node', duration=d,
                             timeout=60 + 30 * d, extra_args=('--no-standard-views',))
        with_views = section['lockstep']['per-node']
        section['standard_views'] = {
            'without': bare,
            'rtf_ratio': with_views['rtf'] / bare['rtf'] if with_views['rtf'] and bare['rtf'] else None,
            'cpu_ratio': (with_views['cpu_run_s'] / bare['cpu_run_s']
                          if with_views.get('cpu_run_s') and bare.get('cpu_run_s') else None)}
        _log(f'  real-time factor {bare["rtf"]} without the views; with / without: '
             f'{section["standard_views"]["rtf_ratio"]}')
        section['safety'] = _safety_cost(d, workdir, section['lockstep']['per-node'])
    results['paper'] = section


def _safety_cost(d, workdir, default_run) -> dict:
    """Measure what the safety filter and its sensing node cost a per-node run (docs/safety.md#cost).

    ``default_run`` ran with the scenario's setting; the same run is made with the other one, so
    the ratio on / off comes from two runs of one sitting.
    """
    default_on = load_scenario('paper').safety.enabled
    other = 'off' if default_on else 'on'
    _log(f'lockstep paper scenario, per-node, --safety {other}, {d:g} s')
    run = runs.run_team('paper', workdir / f'paper-per-node-safety-{other}', layout='per-node', duration=d,
                        timeout=60 + 30 * d, extra_args=('--safety', other))
    on, off = (default_run, run) if default_on else (run, default_run)
    cost = {'on': on, 'off': off,
            'rtf_ratio': on['rtf'] / off['rtf'] if on['rtf'] and off['rtf'] else None,
            'cpu_ratio': on['cpu_run_s'] / off['cpu_run_s'] if on.get('cpu_run_s') and off.get('cpu_run_s') else None}
    _log(f'  real-time factor on / off: {cost["rtf_ratio"]}')
    return cost


def _campaign(cfg, workdir, results):
    n = cfg.get('campaign_runs', 100)
    _log(f'campaign throughput: {n} paper-scenario runs of 60 s on local workers, and one run in process')
    results['campaign'] = campaign.measure(workdir, runs=n)
    c = results['campaign']
    _log(f'  {c["runs_per_s"]:.2f} runs/s against {c["ideal_runs_per_s"]:.2f} ideal: efficiency {c["efficiency"]:.2f}')


def _transport(cfg, workdir, results):
    _log('cost of one message: UDP, DDS between processes, in one process')
    domain = reserve_domain_id()
    try:
        results['transport'] = transport.measure(domain, quick=cfg.get('transport_quick', False))
    finally:
        release_domain_id(domain)


def _components(cfg, workdir, results):
    _log(f'per-step costs in process, {cfg["component_steps"]} steps')
    results['components'] = {'paper': inprocess.component_costs('paper', cfg['component_steps']),
                             'paper_safety': inprocess.component_costs('paper', cfg['component_steps'], safety=True)}


def _scaling(cfg, workdir, results):
    d = cfg['scaling_duration']
    rows = []
    for size in cfg['scaling_sizes']:
        path = _team_file(workdir, size, d)
        from uh_topology.scenario import load_scenario
        sc = load_scenario(path)
        _log(f'scaling: {size} UHs ({len(sc.leaders)} leaders, {len(sc.followers)} followers), in process, {d:g} s')
        ref = inprocess.reference_rtf(path, d)
        row = {'uhs': size, 'leaders': len(sc.leaders), 'followers': len(sc.followers),
               'edges': int((sc.adjacency != 0).sum()), 'duration_s': d, 'inprocess': ref, 'lockstep': {}}
        for layout in cfg['scaling_layouts']:
            _log(f'scaling: {size} UHs, lockstep, {layout}')
            run = runs.run_team(str(path), workdir / f'team{size}-{layout}', layout=layout, duration=d,
                                timeout=120 + 60 * d * max(1.0, size / 5))
            run['ratio_to_inprocess'] = run['rtf'] / ref['rtf'] if run['rtf'] else None
            row['lockstep'][layout] = run
            _log(f'  real-time factor {run["rtf"]}, CPU {run["cpu_s"]:.1f} s, status {run["status"]}')
        rows.append(row)
    results['scaling'] = rows


def _realtime_run(scenario, size, d, workdir, layout='per-node', env_extra=None, name=None, extra_args=()):
    out = workdir / (name or f'realtime{size}-{layout}')
    out.mkdir(parents=True, exist_ok=True)
    domain = reserve_domain_id()
    probe_out, ready = out / 'probe.json', out / 'probe.ready'
    last = int(round(d / 0.01))
    env = dict(os.environ)
    env.update({'ROS_DOMAIN_ID': str(domain)})
    from uh_runtime.network import loopback_environment
    env = loopback_environment(domain, env)
    bench_dir = str(Path(__file__).resolve().parents[1])
    env['PYTHONPATH'] = bench_dir + (os.pathsep + env['PYTHONPATH'] if env.get('PYTHONPATH') else '')
    probe = subprocess.Popen([sys.executable, '-P', '-m', 'uh_bench.probe', '--domain-id', str(domain),
                              '--ids', f'1..{size}', '--last-step', str(last), '--out', str(probe_out),
                              '--ready', str(ready)], env=env, stdout=subprocess.DEVNULL,
                             stderr=open(out / 'probe.log', 'w'))
    try:
        deadline = time.monotonic() + 60
        while not ready.exists() and probe.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        run = runs.run_team(str(scenario), out, layout=layout, clock='realtime', rate=1.0, duration=d,
                            domain_id=domain, timeout=120 + 3 * d, env=env_extra, extra_args=extra_args)
    finally:
        if probe.poll() is None:
            time.sleep(0.5)
            probe.send_signal(signal.SIGINT)
        try:
            probe.wait(timeout=30)
        except subprocess.TimeoutExpired:
            probe.kill()
            probe.wait()
        release_domain_id(domain)
    try:
        probed = json.loads(probe_out.read_text())['controllers']
    except (OSError, ValueError, KeyError):
        probed = {}
    ctl = list(probed.values())
    run['controllers'] = probed
    run['p50_ms_median'] = _median([c['p50_us'] / 1000 for c in ctl if c['p50_us'] is not None])
    run['p99_ms_max'] = max((c['p99_us'] / 1000 for c in ctl if c['p99_us'] is not None), default=None)
    run['max_ms'] = max((c['max_us'] / 1000 for c in ctl if c['max_us'] is not None), default=None)
    run['late_steps'] = sum(c['late_steps'] for c in ctl)
    run['missed_steps'] = sum(c['missed_steps'] for c in ctl)
    run['controller_steps'] = sum(c['commands'] for c in ctl)
    return run


def _median(values):
    values = sorted(values)
    if not values:
        return None
    mid = len(values) // 2
    return values[mid] if len(values) % 2 else 0.5 * (values[mid - 1] + values[mid])


def _realtime(cfg, workdir, results):
    d = cfg['realtime_duration']
    rows = []
    for size, layout in cfg['realtime_runs']:
        scenario = 'paper' if size == 5 else _team_file(workdir, size, d)
        _log(f'real time: {size} UHs ({scenario if size == 5 else "generated"}), {layout}, rate 1, {d:g} s')
        run = _realtime_run(scenario, size, d, workdir, layout)
        run['uhs'] = size
        rows.append(run)
        _log(f'  p99 {run["p99_ms_max"]} ms, late {run["late_steps"]}, missed {run["missed_steps"]}, '
             f'status {run["status"]}')
    results['realtime'] = rows


def rclpy_available() -> str | None:
    """None if this Python imports rclpy (a sourced ROS 2), else why not."""
    probe = subprocess.run([sys.executable, '-c', 'import rclpy'], capture_output=True, text=True)
    if probe.returncode == 0:
        return None
    last = (probe.stderr.strip().splitlines() or ['import failed'])[-1]
    return f'rclpy is not importable by {sys.executable} ({last}); source a ROS 2 Jazzy to compare'


def _backends(cfg, workdir, results):
    """Run the paper scenario, one process per node, on the Cyclone DDS backend and on real rclpy.

    Both run in lockstep (real-time factor, CPU per step) and in real time at rate 1 (p99 latency, late and
    missed steps, CPU per step), in one run so the comparison is a ratio of this machine's numbers.
    """
    skipped = rclpy_available()
    backends = ['dds'] + ([] if skipped else ['rclpy'])
    section = {'skipped_rclpy': skipped, 'lockstep': {}, 'realtime': {}}
    d_lock, d_rt = cfg['backend_lockstep_duration'], cfg['backend_realtime_duration']
    for backend in backends:
        # rclpy as a ROS user runs the team: the default backend choice (rclpy for the team's nodes,
        # the recorder and the visualisation on the DDS backend, uh_bringup.team_nodes.backend_environment)
        env = {'UH_BACKEND': 'dds'} if backend == 'dds' else {}
        _log(f'backends: {backend}, lockstep paper scenario, {d_lock:g} s')
        lock = runs.run_team('paper', workdir / f'backend-{backend}-lockstep', layout='per-node',
                             duration=d_lock, timeout=120 + 30 * d_lock, env=env)
        lock['cpu_us_per_step'] = 1e6 * lock['cpu_run_s'] / lock['steps'] if lock.get('steps') else None
        section['lockstep'][backend] = lock
        _log(f'backends: {backend}, real time paper scenario, {d_rt:g} s')
        rt_run = _realtime_run('paper', 5, d_rt, workdir, 'per-node', env, name=f'backend-{backend}-realtime')
        rt_run['cpu_us_per_step'] = 1e6 * rt_run['cpu_run_s'] / rt_run['steps'] if rt_run.get('steps') else None
        section['realtime'][backend] = rt_run
        _log(f'  lockstep rtf {lock["rtf"]}, realtime p99 {rt_run["p99_ms_max"]} ms, late {rt_run["late_steps"]}, '
             f'missed {rt_run["missed_steps"]}, status {lock["status"]}/{rt_run["status"]}')
    # the same real-time run while other processes want every core: what SCHED_FIFO buys
    section['contention'] = {'busy_processes': _busy_count(), 'runs': {}}
    schedulings = {'fifo': scheduling.DEFAULT_PRIORITY, 'normal': 0}
    for backend in backends:
        env = {'UH_BACKEND': 'dds'} if backend == 'dds' else {}
        for label in cfg.get('contention_runs', ('fifo', 'normal')):
            priority = schedulings[label]
            _log(f'backends: {backend}, real time with {_busy_count()} busy processes, '
                 f'--realtime-priority {priority}, {d_rt:g} s')
            with busy_load(_busy_count()):
                run = _realtime_run('paper', 5, d_rt, workdir, 'per-node', env,
                                    name=f'backend-{backend}-contention-{label}',
                                    extra_args=('--realtime-priority', str(priority)))
            run['priority'] = priority
            run['priority_granted'] = priority > 0 and _granted(run)
            section['contention']['runs'][f'{backend}/{label}'] = run
            _log(f'  late {run["late_steps"]}, missed {run["missed_steps"]}, p99 {run["p99_ms_max"]} ms, '
                 f'status {run["status"]}')
    section['executors'] = []
    for case in [c for c, (backend, _) in executors.CASES.items() if backend in backends]:
        _log(f'backends: CPU per received message, executor {case}')
        section['executors'].append(executors.measure(case, cfg.get('executor_messages', 2500)))
    if skipped:
        _log(f'backends: rclpy skipped: {skipped}')
    results['backends'] = section


def _busy_count() -> int:
    return (os.cpu_count() or 1) + 1


@contextlib.contextmanager
def busy_load(n: int):
    """Keep ``n`` processes spinning at normal priority for as long as the block runs.

    This makes a machine whose every core is wanted by someone else.
    """
    procs = [subprocess.Popen([sys.executable, '-c', 'while True: pass'], stdin=subprocess.DEVNULL)
             for _ in range(n)]
    try:
        yield procs
    finally:
        for proc in procs:
            proc.kill()
        for proc in procs:
            proc.wait()


def _granted(run) -> bool:
    """Whether the run's control loop got SCHED_FIFO (run.json records the priority it used)."""
    try:
        return json.loads((Path(run['out']) / 'run' / 'run.json').read_text()).get('realtime_priority', 0) > 0
    except (OSError, ValueError, KeyError):
        return False


def _memory(results):
    procs = []
    for run in results.get('paper', {}).get('lockstep', {}).values():
        if run['layout'] == 'per-node':
            procs += run['processes']
    by_kind = {}
    for proc in procs:
        for name in proc['nodes']:
            by_kind.setdefault(runs.node_kind(name), []).append(proc['peak_rss_kb'])
    results['memory'] = {
        'paper_per_node_max_kb': {k: max(v) for k, v in sorted(by_kind.items())},
        'per_run': {key: run['memory'] for key, run in all_runs(results)},
    }


def run_suite(mode, workdir, sections=('transport', 'paper', 'components', 'scaling', 'realtime')) -> dict:
    """Run the chosen sections in ``workdir``; return the results mapping.

    ``mode`` is ``'quick'`` or ``'full'`` (:data:`MODES`), or a mapping with the same keys (used
    by the harness's own test with tiny runs).
    """
    cfg = dict(MODES[mode]) if isinstance(mode, str) else dict(mode)
    mode = mode if isinstance(mode, str) else 'custom'
    workdir = Path(workdir)
    workdir.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    results = {'mode': mode, 'config': cfg, 'date': datetime.datetime.now().isoformat(timespec='seconds'),
               'machine': machine_info(), 'sections': list(sections)}
    table = {'transport': _transport, 'paper': _paper, 'components': _components, 'scaling': _scaling,
             'realtime': _realtime, 'backends': _backends, 'campaign': _campaign}
    for name in sections:
        table[name](cfg, workdir, results)
    _memory(results)
    results['machine']['loadavg_end'] = os.getloadavg()
    results['wall_s'] = time.monotonic() - started
    results['goals'] = [dict(zip(('key', 'description', 'target', 'comparison', 'measured', 'met'), g, strict=True))
                        for g in evaluate_goals(results)]
    return results
