"""The goals of the performance work and what the results say about them (docs/performance.md#goals).

Owns :data:`GOALS`, their evaluation against a results mapping of :func:`uh_bench.suite.run_suite`,
and the readings of that mapping the suite and its tables share: every team run by key
(:func:`all_runs`) and the per-node-kind costs of a one-process-per-node run (:func:`node_kind_costs`).
"""
from __future__ import annotations

from . import runs

__all__ = ['GOALS', 'node_kind_costs', 'all_runs', 'evaluate_goals']


#: The goals of the performance work (docs/performance.md#goals): (key, description, target, comparison).
GOALS = (
    ('paper_lockstep_rtf', 'paper scenario, lockstep, one process per node: real-time factor', 6.0, '>='),
    ('paper_lockstep_single_rtf', 'paper scenario, lockstep, `--processes single`: real-time factor', 20.0, '>='),
    ('standard_views_slowdown', 'paper scenario, lockstep, one process per node: real-time factor without '
     '/tf, odom and /diagnostics over with them', 1.10, '<='),
    ('safety_rtf_ratio', 'paper scenario, lockstep, one process per node: real-time factor with the safety '
     'filter and its sensing node over without (docs/safety.md#cost)', 0.85, '>='),
    ('inprocess_rtf', 'paper scenario, in-process reference: real-time factor', 200.0, '>='),
    ('clock_us_per_step', 'paper scenario, one process per node: run CPU per step of the clock (us)', 100.0, '<='),
    ('virtual_leader_us_per_step', 'the same, of the virtual leader (us)', 100.0, '<='),
    ('visualization_us_per_step', 'the same, of the visualisation (us)', 100.0, '<='),
    ('recorder_us_per_step', 'the same, of the recorder (us)', 300.0, '<='),
    ('uh_process_peak_rss_mb', 'paper scenario, one process per node: peak RSS of a simulator or controller '
     'process (MB)', 90.0, '<='),
    ('team40_lockstep_best_rtf', '40 UHs, lockstep, best process layout: real-time factor', 2.0, '>='),
    ('realtime20_best_missed', '20 UHs, real time, best process layout: missed + late steps', 0, '<='),
    ('realtime20_best_p99_ms', '20 UHs, real time, best process layout: worst controller p99 '
     'state-to-command latency (ms)', 5.0, '<'),
    ('realtime5_p99_ms', '5 UHs, real time, one process per node: worst controller p99 '
     'state-to-command latency (ms)', 5.0, '<'),
    ('realtime5_missed', '5 UHs, real time, one process per node: missed + late steps', 0, '<='),
    ('campaign_efficiency', 'campaign of paper-scenario runs on local workers: runs per second over '
     'cores / (one run in process)', 0.8, '>='),
    ('campaign_1000_runs_s', 'campaign: seconds for 1,000 paper-scenario runs of 60 s (at the measured rate)',
     120.0, '<'),
)


def node_kind_costs(run) -> dict:
    """``{kind: (processes, run CPU us per step each, start-up CPU s each, peak RSS MB max)}`` of a per-node run.

    Only processes holding one node count (a per-node run has no other kind).
    """
    kinds = {}
    for proc in run['processes']:
        if len(proc['nodes']) == 1:
            kinds.setdefault(runs.node_kind(proc['nodes'][0]), []).append(proc)
    out = {}
    for kind, procs in sorted(kinds.items()):
        n = len(procs)
        run_us = sum(p['cpu_s'] - p['startup_cpu_s'] for p in procs) / n * 1e6 / run['steps']
        start = sum(p['startup_cpu_s'] for p in procs) / n
        out[kind] = (n, run_us, start, max(p['peak_rss_kb'] for p in procs) / 1024)
    return out


def all_runs(results):
    """Yield ``(key, run)`` of every team run in ``results`` (``paper/per-node``, ``team20/single``, ...)."""
    for layout, run in results.get('paper', {}).get('lockstep', {}).items():
        yield f'paper/{layout}', run
    if 'standard_views' in results.get('paper', {}):
        yield 'paper/per-node-no-standard-views', results['paper']['standard_views']['without']
    for setting, run in results.get('paper', {}).get('safety', {}).items():
        if setting in ('on', 'off') and run is not lock_run(results):
            yield f'paper/per-node-safety-{setting}', run
    for row in results.get('scaling', []):
        for layout, run in row['lockstep'].items():
            yield f'team{row["uhs"]}/{layout}', run
    for mode in ('lockstep', 'realtime'):
        for backend, run in results.get('backends', {}).get(mode, {}).items():
            yield f'backends/{backend}/{mode}', run
    for run in results.get('realtime', []):
        yield f'realtime{run["uhs"]}/{run["layout"]}', run


def lock_run(results):
    """Return the per-node lockstep paper run of ``results`` (None without one)."""
    return results.get('paper', {}).get('lockstep', {}).get('per-node')


def evaluate_goals(results) -> list:
    """``[(key, description, target, comparison, measured, met), ...]`` (measured None: not run)."""
    measured = {}
    paper = results.get('paper', {})
    lock = paper.get('lockstep', {})
    if 'per-node' in lock:
        measured['paper_lockstep_rtf'] = lock['per-node']['rtf']
    if lock.get('single', {}).get('rtf'):
        measured['paper_lockstep_single_rtf'] = lock['single']['rtf']
    if lock.get('per-node', {}).get('steps'):
        costs = node_kind_costs(lock['per-node'])
        for kind in ('clock', 'virtual_leader', 'visualization', 'recorder'):
            if kind in costs:
                measured[f'{kind}_us_per_step'] = costs[kind][1]
        rss = [costs[k][3] for k in ('sim', 'controller') if k in costs]
        if rss:
            measured['uh_process_peak_rss_mb'] = max(rss)
    if 'inprocess' in paper:
        measured['inprocess_rtf'] = paper['inprocess']['rtf']
    views = paper.get('standard_views')
    if views and views['rtf_ratio']:
        measured['standard_views_slowdown'] = 1.0 / views['rtf_ratio']
    safety = paper.get('safety')
    if safety and safety['rtf_ratio']:
        measured['safety_rtf_ratio'] = safety['rtf_ratio']
    for row in results.get('scaling', []):
        rtfs = [r['rtf'] for r in row['lockstep'].values() if r.get('rtf')]
        if row['uhs'] == 40 and rtfs:
            measured['team40_lockstep_best_rtf'] = max(rtfs)
    best = None
    for run in results.get('realtime', []):
        if run['p99_ms_max'] is None:
            continue
        if run['uhs'] == 5 and run['layout'] == 'per-node':
            measured['realtime5_p99_ms'] = run['p99_ms_max']
            measured['realtime5_missed'] = run['missed_steps'] + run['late_steps']
        if run['uhs'] == 20:
            key = (run['missed_steps'] + run['late_steps'], run['p99_ms_max'])
            best = key if best is None or key < best else best
    if best is not None:
        measured['realtime20_best_missed'], measured['realtime20_best_p99_ms'] = best
    if 'campaign' in results:
        measured['campaign_efficiency'] = results['campaign']['efficiency']
        measured['campaign_1000_runs_s'] = results['campaign']['time_for_1000_runs_s']
    out = []
    for key, text, target, cmp in GOALS:
        value = measured.get(key)
        met = None
        if value is not None:
            met = {'>=': value >= target, '<': value < target, '<=': value <= target}[cmp]
        out.append((key, text, target, cmp, value, met))
    return out
