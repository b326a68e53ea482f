"""The worker side of a campaign: one task (the cases of one resolved scenario) run in a worker.

Owns what a worker process runs (:func:`run_task`), its one-time warm-up (the numba kernels
loaded, the import graph frozen) and the text of a failed run's reason (:func:`failure_reason`).
The executors of :mod:`uh_campaign.runner` send it tasks; the main process never runs them itself.
"""
from __future__ import annotations

import gc
import os
import signal
import time

from uh_team import campaign_store as store
from uh_team.compile_kernels import compile_all
from uh_team.metrics import metrics_from_arrays
from uh_team.team_simulation import SimulationError, run_team_simulation
from uh_topology.scenario import parse_scenario

__all__ = ['run_task', 'init_local_worker', 'failure_reason']


_WARM = False


def _warm_up() -> None:
    """Once per process: load the numba kernels (from the cache, or compile them), then freeze.

    What a run imports is imported with this module (its imports are at the top), so it is alive
    here and frozen with the rest: ``gc.freeze()`` everything alive (as the nodes do at start-up,
    ``uh_runtime.runner``; ``UH_GC_FREEZE=0`` keeps the default). The imports and the kernels'
    dispatchers are a large, permanent object graph that every full collection would walk again:
    frozen, a 60 s run of the paper scenario takes about 0.39 s instead of 0.47 s.
    """
    global _WARM
    if _WARM:
        return
    compile_all()
    if os.environ.get('UH_GC_FREEZE', '1').strip() not in ('0', 'false', 'no'):
        gc.collect()
        gc.freeze()
    _WARM = True


def init_local_worker() -> None:
    """Initialise a local worker process: SIGINT ignored (the main process handles it), then warmed up."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the main process's to handle
    _warm_up()


def run_task(task: dict) -> list:
    """Run the cases of one resolved scenario (in a worker); one row per case.

    ``task``: ``draw``, ``sweep_index``, ``sweep_value``, ``scenario_file`` (relative to the
    campaign directory, for messages and the row), ``scenario_text`` (its YAML) and ``cases``.
    The rows hold every :data:`~uh_team.campaign_store.RUN_COLUMNS` column but ``success``.
    """
    _warm_up()
    key = {'draw': task['draw'], 'sweep_index': task['sweep_index'], 'sweep_value': task['sweep_value'],
           'scenario_file': task['scenario_file']}
    try:
        scenario = parse_scenario(task['scenario_text'], source=task['scenario_file'])
    except Exception as exc:   # noqa: BLE001 - any error of the scenario is the runs' outcome
        return [dict(key, case_name=case, status='failed', reason=failure_reason(exc), wall_time_s=0.0)
                for case in task['cases']]
    rows = []
    for case in task['cases']:
        start = time.perf_counter()
        row = dict(key, case_name=case, status='ok', reason=None)
        try:
            run = run_team_simulation(scenario, case, duration=scenario.duration)
            row.update(store.metric_row(metrics_from_arrays(run.arrays(), scenario, case)))
        except SimulationError as exc:
            row.update(status='diverged' if 'non-finite' in str(exc) else 'failed', reason=failure_reason(exc))
        except Exception as exc:   # noqa: BLE001 - recorded, the campaign goes on
            row.update(status='failed', reason=failure_reason(exc))
        row['wall_time_s'] = time.perf_counter() - start
        rows.append(row)
    return rows


def failure_reason(exc: BaseException) -> str:
    """Return the reason of a failed run: ``'<exception type>: <message>'``."""
    return f'{type(exc).__name__}: {exc}'
