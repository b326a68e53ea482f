"""The markdown tables of a benchmark's results (what ``scripts/bench.sh`` prints).

Owns :func:`markdown`: one table per section of :func:`uh_bench.suite.run_suite` that ran, in the
order of the suite, then the node processes that exited abnormally and the goals.
"""
from __future__ import annotations

from .results import all_runs, node_kind_costs

__all__ = ['markdown']


def markdown(results) -> str:
    """Return the results as markdown tables (what ``scripts/bench.sh`` prints)."""
    paper = results.get('paper')
    lines = _header(results)
    lines += _transport_table(results.get('transport'))
    lines += _paper_table(paper)
    lines += _node_kind_table((paper or {}).get('lockstep', {}).get('per-node'))
    lines += _campaign_table(results.get('campaign'))
    lines += _components_table(results.get('components'))
    lines += _scaling_table(results.get('scaling'))
    lines += _realtime_table(results.get('realtime'))
    lines += _backends_table(results.get('backends'))
    lines += _memory_table(results.get('memory', {}).get('paper_per_node_max_kb'))
    lines += _abnormal_exits(results)
    lines += _goals_table(results.get('goals'))
    return '\n'.join(lines)


def _f(value, fmt='{:.2f}', none='—'):
    """Format ``value`` with ``fmt``, or ``none`` for a figure that was not measured."""
    return none if value is None else fmt.format(value)


def _header(results) -> list:
    """Return the title and the machine line."""
    m = results['machine']
    lines = [f'## Benchmark ({results["mode"]}, {results["date"]}, commit {m.get("commit") or "?"})', '',
             f'Machine: {m.get("cpu_model")}, {m.get("nproc")} cores, {m.get("memory_mb")} MB; load average '
             f'{", ".join(f"{x:.1f}" for x in m["loadavg"])} at start, '
             f'{", ".join(f"{x:.1f}" for x in m.get("loadavg_end", m["loadavg"]))} at the end. '
             f'Suite wall time {results.get("wall_s", 0):.0f} s.', '']
    return lines


def _transport_table(tr) -> list:
    """Return the cost-of-one-message table (none without a transport section)."""
    if not tr:
        return []
    lines = ['### Cost of one message (ping-pong of a 132-byte UHState)', '',
             '| path | CPU us per message (receiving and answering side) | round trip us |', '|---|---|---|',
             f'| loopback UDP between two processes (kernel only) | {tr["udp"]["echo_cpu_us_per_message"]:.1f} | '
             f'{tr["udp"]["round_trip_us"]:.0f} |',
             f'| node runtime + Cyclone DDS, another process | {tr["dds"]["echo_cpu_us_per_message"]:.1f} | '
             f'{tr["dds"]["round_trip_us"]:.0f} |',
             f'| node runtime + Cyclone DDS, same process (publish + spin_once) | '
             f'{tr["inprocess"]["cpu_us_per_message"]:.1f} | — |', '']
    fan = tr.get('fanout_cpu_us_per_publish')
    if fan:
        lines += ['| subscriber processes | ' + ' | '.join(str(k) for k in fan) + ' |',
                  '|---|' + '---|' * len(fan),
                  '| publishing thread CPU us per publish (with a 0.5 ms sleep between publishes) | ' +
                  ' | '.join(f'{v:.1f}' for v in fan.values()) + ' |', '']
    return lines


def _paper_table(paper) -> list:
    """Return the paper-scenario table: the in-process reference and every lockstep layout."""
    if not paper:
        return []
    ref = paper['inprocess']
    lines = [f'### Paper scenario ({paper["duration_s"]:g} s simulated)', '',
             '| run | processes | real-time factor | ratio to in-process | CPU s of the node processes '
             '(start-up + run) | run CPU ms per step |',
             '|---|---|---|---|---|---|',
             f'| in-process reference | 1 | {_f(ref["rtf"], "{:.1f}")} | 1 | — | '
             f'{_f(1000 * ref["wall_s"] / (paper["duration_s"] / 0.01), "{:.2f}")} (wall) |']

    def lockstep_row(label, run, ratio):
        steps = run['steps'] or paper['duration_s'] / 0.01
        return (f'| {label} | {run["n_processes"]} | {_f(run["rtf"])} | {ratio} | {run["cpu_s"]:.1f} '
                f'({run["cpu_startup_s"]:.1f} + {run["cpu_run_s"]:.1f}) | {1000 * run["cpu_run_s"] / steps:.2f} |')
    for layout, run in paper['lockstep'].items():
        lines.append(lockstep_row(f'lockstep, {layout}', run, _f(run['ratio_to_inprocess'], '{:.3f}')))
    views = paper.get('standard_views')
    if views:
        lines.append(lockstep_row('lockstep, per-node, `--no-standard-views`', views['without'], '—'))
        lines.append(f'\n/tf, odom and /diagnostics: real-time factor with / without '
                     f'{_f(views["rtf_ratio"], "{:.3f}")}, '
                     f'run CPU with / without {_f(views["cpu_ratio"], "{:.3f}")}')
    safety = paper.get('safety')
    if safety:
        lines.append(lockstep_row('lockstep, per-node, `--safety on`', safety['on'], '—'))
        lines.append(lockstep_row('lockstep, per-node, `--safety off`', safety['off'], '—'))
        lines.append(f'\nThe safety filter with its sensing node (docs/safety.md#cost): real-time factor on / off '
                     f'{_f(safety["rtf_ratio"], "{:.3f}")} (goal: at least 0.85), '
                     f'run CPU on / off {_f(safety["cpu_ratio"], "{:.3f}")}')
    lines.append('')
    return lines


def _node_kind_table(per_node) -> list:
    """Return where the CPU goes per node kind of the per-node paper run (none without one)."""
    if not per_node or not per_node.get('steps'):
        return []
    lines = ['### Where the CPU goes, one process per node (paper scenario, lockstep)', '',
             '| node | processes | run CPU us per step (each) | start-up CPU s (each) | peak RSS MB (each) |',
             '|---|---|---|---|---|']
    for kind, (n, run_us, start, rss) in node_kind_costs(per_node).items():
        lines.append(f'| {kind} | {n} | {run_us:.0f} | {start:.2f} | {rss:.1f} |')
    lines.append('')
    return lines


def _campaign_table(camp) -> list:
    """Return the campaign-throughput table (none without a campaign section)."""
    if not camp:
        return []
    lines = [f'### Campaign throughput ({camp["runs"]} paper-scenario runs of {camp["duration_s"]:g} s, '
             f'{camp["workers"]} local workers)', '',
             '| one run in process (s) | ideal runs/s (cores / one run) | campaign runs/s (cold start) | '
             'efficiency | 1,000 runs at this rate (s) |', '|---|---|---|---|---|',
             f'| {camp["one_run_s"]:.3f} | {camp["ideal_runs_per_s"]:.2f} | {camp["runs_per_s"]:.2f} | '
             f'{camp["efficiency"]:.2f} | {camp["time_for_1000_runs_s"]:.0f} |', '']
    return lines


def _components_table(comp) -> list:
    """Return the per-step costs in process (none without a components section)."""
    if not comp:
        return []
    c = comp['paper']
    lines = [f'### Per-step cost in process (paper scenario, {c["steps"]} steps x {c["uhs"]} UHs)', '',
             '| part | mean us per UH-step | median us |', '|---|---|---|']
    for key, label in (('controller', 'controller (UHController.step)'),
                       ('model', f'model (HelicopterPlant.step, RK4 x {c["substeps"]})'),
                       ('fault_truth', 'true lumped faults (lumped_faults)')):
        lines.append(f'| {label} | {c[key]["mean_us"]:.1f} | {c[key]["median_us"]:.1f} |')
    total = sum(c[k]['mean_us'] for k in ('controller', 'model', 'fault_truth'))
    lines += [f'| sum (floor of one UH-step) | {total:.1f} | |']
    s = comp.get('paper_safety')
    if s:
        with_filter = s['controller']['mean_us'] + s['model']['mean_us'] + s['fault_truth']['mean_us']
        lines += [f'| controller with the safety filter and its proximity input | {s["controller"]["mean_us"]:.1f} | '
                  f'{s["controller"]["median_us"]:.1f} |',
                  f'| sum with the safety filter (x {with_filter / total:.2f} of the sum without) | '
                  f'{with_filter:.1f} | |']
    return lines + ['']


def _scaling_table(scaling) -> list:
    """Return the lockstep scaling table of the generated teams (none without a scaling section)."""
    if not scaling:
        return []
    d = scaling[0]['duration_s']
    lines = [f'### Scaling, lockstep ({d:g} s simulated, generated teams)', '',
             '| UHs | leaders:followers | layout | processes | real-time factor | CPU s of the node processes '
             '(start-up + run) | run CPU ms per step | per UH-step | peak RSS MB (sum over processes) | '
             'in-process RTF | ratio |',
             '|---|---|---|---|---|---|---|---|---|---|---|']
    for row in scaling:
        for layout, run in row['lockstep'].items():
            steps = run['steps'] or d / 0.01
            per_step = 1000 * run['cpu_run_s'] / steps
            lines.append(
                f'| {row["uhs"]} | {row["leaders"]}:{row["followers"]} | {layout} | {run["n_processes"]} | '
                f'{_f(run["rtf"])} | {run["cpu_s"]:.1f} ({run["cpu_startup_s"]:.1f} + {run["cpu_run_s"]:.1f}) | '
                f'{per_step:.2f} | {per_step / row["uhs"]:.3f} | {run["memory"]["total_kb"] / 1024:.0f} | '
                f'{_f(row["inprocess"]["rtf"], "{:.1f}")} | '
                f'{_f(run["ratio_to_inprocess"], "{:.3f}")} |')
    lines.append('')
    return lines


def _realtime_table(realtime) -> list:
    """Return the real-time latency table (none without a realtime section)."""
    if not realtime:
        return []
    d = realtime[0]['duration_s']
    lines = [f'### Real time, rate 1 ({d:g} s simulated = wall)', '',
             '| UHs | layout | latency p50 (median over controllers) ms | worst p99 ms | worst max ms | '
             'late steps | missed steps | controller steps | sims\' late-command log |',
             '|---|---|---|---|---|---|---|---|---|']
    for run in realtime:
        lines.append(f'| {run["uhs"]} | {run["layout"]} | {_f(run["p50_ms_median"], "{:.2f}")} | '
                     f'{_f(run["p99_ms_max"])} | '
                     f'{_f(run["max_ms"])} | {run["late_steps"]} | {run["missed_steps"]} | '
                     f'{run["controller_steps"]} | {run["late_commands_logged"]} |')
    lines.append('')
    return lines


def _backends_table(backends) -> list:
    """Return the backend comparison, executors and busy-machine tables (none without a backends section)."""
    if not backends:
        return []
    lines = ['### Backends: Cyclone DDS and rclpy (paper scenario, one process per node)', '',
             '| backend | lockstep real-time factor | lockstep CPU per step µs | real time p99 ms | '
             'late steps | missed steps | real time CPU per step µs | runs ended with |',
             '|---|---|---|---|---|---|---|---|']
    for name, lock in backends['lockstep'].items():
        rt_run = backends['realtime'][name]
        # a run that failed (e.g. the clock died) has no meaningful latency: say so in the row
        ended = ', '.join(f'{what} exit {run["status"]}' for what, run in
                          (('lockstep', lock), ('real time', rt_run)) if run['status'] != 0) or 'exit 0'
        lines.append(f'| {name} | {_f(lock["rtf"])} | {_f(lock["cpu_us_per_step"], "{:.0f}")} | '
                     f'{_f(rt_run["p99_ms_max"])} | {rt_run["late_steps"]} | {rt_run["missed_steps"]} | '
                     f'{_f(rt_run["cpu_us_per_step"], "{:.0f}")} | {ended} |')
    if set(backends['lockstep']) == {'dds', 'rclpy'}:
        d, r = backends['lockstep']['dds'], backends['lockstep']['rclpy']
        if d['rtf'] and r['rtf']:
            lines.append(f'\nrclpy / DDS backend, lockstep real-time factor: {r["rtf"] / d["rtf"]:.2f}')
    if backends.get('executors'):
        lines += ['', '| executor (5 topics of UHState at 100 Hz each) | backend | CPU per received message µs |',
                  '|---|---|---|']
        lines += [f'| {e["case"]} ({e["executor"]}) | {e["backend"]} | {_f(e["cpu_us_per_message"], "{:.0f}")} |'
                  for e in backends['executors']]
    lines += _contention_table(backends.get('contention'))
    if backends['skipped_rclpy']:
        lines.append(f'\nrclpy not measured: {backends["skipped_rclpy"]}')
    lines.append('')
    return lines


def _contention_table(contention) -> list:
    """Return the real-time runs on a busy machine per control-loop scheduling (none if there were none)."""
    if not contention or not contention['runs']:
        return []
    lines = ['', f'Real time on a busy machine ({contention["busy_processes"]} busy-looping processes at '
             'normal priority during the run; docs/performance.md#real-time-scheduling):', '',
             '| backend | control loop scheduling | late steps | missed steps | late commands (sims) | '
             'p99 ms | runs ended with |', '|---|---|---|---|---|---|---|']
    for key, run in contention['runs'].items():
        backend, _ = key.split('/')
        how = (f'SCHED_FIFO {run["priority"]}' if run['priority_granted'] else
               'normal' if run['priority'] == 0 else f'normal (SCHED_FIFO {run["priority"]} not permitted)')
        lines.append(f'| {backend} | {how} | {run["late_steps"]} | {run["missed_steps"]} | '
                     f'{run["late_commands"]} | {_f(run["p99_ms_max"])} | exit {run["status"]} |')
    return lines


def _memory_table(mem) -> list:
    """Return the peak memory per node process of the per-node paper run (none without one)."""
    if not mem:
        return []
    lines = ['### Peak memory per node process (paper scenario, one process per node)', '',
             '| node | peak RSS MB |', '|---|---|']
    lines += [f'| {k} | {v / 1024:.1f} |' for k, v in mem.items()]
    lines.append('')
    return lines


def _abnormal_exits(results) -> list:
    """Return the line naming node processes that did not exit with status 0 (none if all did)."""
    abnormal = [(key, run['abnormal_exits']) for key, run in all_runs(results) if run.get('abnormal_exits')]
    if not abnormal:
        return []
    lines = ['Node processes that did not exit with status 0 (negative: killed by that signal): ' +
             '; '.join(f'{key}: {codes}' for key, codes in abnormal) + '.', '']
    return lines


def _goals_table(goals) -> list:
    """Return the goals with their targets and measured values (none before they are evaluated)."""
    if not goals:
        return []
    lines = ['### Goals', '', '| goal | target | measured | met |', '|---|---|---|---|']
    for g in goals:
        met = '—' if g['met'] is None else ('yes' if g['met'] else 'no')
        lines.append(f'| {g["description"]} | {g["comparison"]} {g["target"]} | '
                     f'{_f(g["measured"], "{:.3g}")} | {met} |')
    lines.append('')
    return lines
