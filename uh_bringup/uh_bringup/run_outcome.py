"""What a team run leaves behind: ``run.json``, the exit status, the recovered bag, ``metrics.json``, the report.

Exit status: :data:`EXIT_OK` success; :data:`EXIT_FAILED` the run failed; :data:`EXIT_USAGE` bad
input (nothing was started); :data:`EXIT_DEGRADED` the run completed but nodes failed during it;
:data:`EXIT_INTERRUPTED` interrupted (Ctrl-C, SIGTERM).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from uh_report.bag_metrics import write_metrics_from_bag
from uh_report.report import ReportError, run_of_arrays, write_report
from uh_runtime.bags.bag import recover_bag
from uh_runtime.bags.bag_reader import BagError
from uh_topology.safety import overlap_line

__all__ = ['EXIT_OK', 'EXIT_FAILED', 'EXIT_USAGE', 'EXIT_DEGRADED', 'EXIT_INTERRUPTED', 'RunRecord',
           'run_info', 'write_run_json', 'recover_bag_if_needed', 'exit_status', 'write_metrics', 'overlap_notice',
           'write_run_report', 'RUN_REPORT_FIGURES']

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_DEGRADED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130

#: The figures of the report a run writes when it ends: the quick ones (about a second); the others
#: (states, 3-D trajectory, fault estimates) take several seconds more and come with ``uh-report``.
RUN_REPORT_FIGURES = ('errors', 'xy_snapshots')


def run_info(args, duration: float, domain: int, priority: int, safety: bool, departures: dict | None = None) -> dict:
    """Return what was run, as ``run.json`` starts it (``exit_status`` None until the end).

    ``safety``: whether the safety filter ran (the scenario's ``safety.enabled`` or ``--safety``),
    recorded as ``'on'``/``'off'``; ``departures``: the departures from the paper the scenario makes
    (``uh_team.departures.scenario_departures``; docs/delay.md#remedies).
    """
    return {'command': sys.argv, 'scenario': args.scenario, 'case': args.case, 'clock': args.clock,
            'rate': args.rate, 'processes': args.processes, 'visualization': not args.no_visualization,
            'standard_views': not args.no_standard_views, 'duration_s': duration, 'domain_id': domain,
            'foxglove': None if args.foxglove is None else f'ws://{args.foxglove_host}:{args.foxglove}',
            'hosts': args.hosts, 'loss_pct': args.loss, 'respawn': args.respawn, 'realtime_priority': priority,
            'safety': 'on' if safety else 'off', 'departures': dict(departures or {}), 'exit_status': None}


def write_run_json(out: Path, info: dict) -> None:
    """Write ``info`` to ``out/run.json`` atomically (a reader never sees half a file)."""
    tmp = out / 'run.json.tmp'
    tmp.write_text(json.dumps(info, indent=2) + '\n')
    tmp.replace(out / 'run.json')


class RunRecord:
    """``run.json`` of a run in directory ``out``.

    Written when the nodes have started (status "running", their pids), after every node failure
    and at the end; ``info`` is what :func:`run_info` gives, updated at the end; ``sup`` is the
    run's :class:`~uh_bringup.supervisor.Supervisor`.
    """

    def __init__(self, out: Path, info: dict, sup):
        self.out, self.info, self.sup = out, info, sup
        self.watcher = None     # the run's RunWatcher once the nodes have started

    def write(self) -> None:
        """Write ``run.json`` with the processes' pids, respawns and failures so far (atomically)."""
        sup = self.sup
        self.info.update(pids={n.name: n.proc.pid for n in sup.nodes if n.proc},
                         all_pids={n.name: n.pids for n in sup.nodes},
                         respawns={n.name: n.restarts for n in sup.nodes if n.restarts},
                         node_failures=self.watcher.failures if self.watcher else [])
        write_run_json(self.out, self.info)


def recover_bag_if_needed(bag_dir: Path) -> dict | None:
    """Complete a bag the recorder did not finalise (it was killed); report what was kept."""
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


def exit_status(interrupted: bool, fatal, failures: list, out: Path) -> int:
    """Return the run's exit status from how it ended, and say it on stderr.

    ``fatal`` is the node whose death ended the run (or None), ``failures`` every node death.
    """
    if interrupted:
        print(f'\n[run] interrupted: every node stopped, bag finalised in {out / "bag"}', file=sys.stderr)
        return EXIT_INTERRUPTED
    if fatal is not None:
        print(f'[run] FAILED: node {fatal.name} {fatal.describe()}; log {fatal.log_path}', file=sys.stderr)
        return EXIT_FAILED
    if failures:
        print('[run] completed with node failures: ' + '; '.join(f'{f["node"]} {f["how"]} ({f["action"]})'
                                                                 for f in failures), file=sys.stderr)
        return EXIT_DEGRADED
    return EXIT_OK


def write_metrics(out: Path, scenario, case: str, wall: float, report: bool = False) -> str | None:
    """Compute ``out/metrics.json`` from the bag (docs/metrics.md) and print the scalar metrics.

    With ``report``, also write the run's report (:data:`RUN_REPORT_FIGURES`) into ``out/report``.
    Returns None, or why the metrics cannot be computed (the bag cannot be read, or what it holds
    does not make a run the metrics can score); that is printed too, and no ``metrics.json`` is written.
    """
    try:
        metrics, arrays = write_metrics_from_bag(out / 'bag', scenario, case, out / 'metrics.json', wall_time_s=wall)
    except (BagError, ValueError) as exc:    # BagContentError and MetricsError are ValueErrors
        print(f'[run] metrics: cannot be computed: {exc}', file=sys.stderr)
        return str(exc)
    print('[run] metrics: ' + ', '.join(f'{k} {v:.4g}' for k, v in metrics.items()
                                        if isinstance(v, float)), file=sys.stderr)
    if report:
        write_run_report(out, scenario, case, arrays, metrics)
    return None


def overlap_notice(metrics_path: Path, enabled: bool) -> str | None:
    """Return the one line a run ends with when its rotor disks overlapped (docs/safety.md), else None."""
    try:
        metrics = json.loads(metrics_path.read_text())
    except (OSError, ValueError):
        return None
    return overlap_line(metrics, enabled)


def write_run_report(out: Path, scenario, case: str, arrays: dict, metrics: dict) -> Path | None:
    """Write the report of a run that just ended into ``out/report``; return its ``index.html`` (None if it failed).

    The report (:mod:`uh_report.report`) has the metrics and fault isolation tables and the figures
    :data:`RUN_REPORT_FIGURES`; ``uh-report out`` redraws it with every figure. A report that cannot
    be written is said on stderr and leaves the run's result as it is.
    """
    import matplotlib  # a file-only backend before any figure: runs draw without a display
    matplotlib.use('Agg')
    try:
        write_report([run_of_arrays(out, scenario, case, arrays, metrics)], out / 'report', RUN_REPORT_FIGURES,
                     hint=f'This report shows the errors and the XY snapshots; `uh-report {out}` adds the states, '
                          'the 3-D trajectory and the fault estimates.')
    except (ReportError, OSError, ValueError) as exc:
        print(f'[run] report: not written: {exc}', file=sys.stderr)
        return None
    index = out / 'report' / 'index.html'
    print(f'[run] report: {index} (every figure: uh-report {out})', file=sys.stderr)
    return index
