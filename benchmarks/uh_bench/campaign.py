"""Campaign throughput (docs/campaigns.md#speed): runs per second of ``uh-campaign`` against one run.

:func:`measure` times, in one invocation:

- *one run*: what ``uh-simulate`` does for one run of the paper scenario, in this process after
  the kernels are loaded and the imports frozen out of the garbage collector as the campaign's
  workers do (:func:`run_team_simulation` and :func:`metrics_from_arrays`; median of a few runs).
  ``cores / t_one`` is the throughput of perfect parallelism on every core;
- *the campaign*: :func:`uh_campaign.runner.run_campaign` of ``runs`` draws of the paper
  scenario (one case, the paper's own draw: the work of ``runs`` such runs), with ``workers``
  local processes, from a cold start (worker start-up and kernel loading included).

``efficiency = (runs / campaign wall time) / (cores / t_one)``: 1 is every core busy with runs and
nothing else; the goal is at least 0.8.
"""
from __future__ import annotations

import gc
import os
import statistics
import time
from pathlib import Path

from uh_campaign.runner import run_campaign
from uh_campaign.spec import parse_spec
from uh_team.compile_kernels import compile_all
from uh_team.metrics import metrics_from_arrays
from uh_team.team_simulation import run_team_simulation
from uh_topology.scenario import load_scenario

__all__ = ['measure']

_SPEC = """name: bench_paper
scenario: paper
runs: {runs}
seed: 1
duration: {duration}
cases: [proposed]
"""


def _one_run_seconds(duration: float, repeats: int) -> float:
    compile_all()
    scenario = load_scenario('paper')
    gc.collect()
    gc.freeze()   # as the campaign's workers do (uh_campaign.worker._warm_up)
    times = []
    for _ in range(repeats + 1):
        start = time.perf_counter()
        run = run_team_simulation(scenario, 'proposed', duration=duration)
        metrics_from_arrays(run.arrays(), scenario, 'proposed')
        times.append(time.perf_counter() - start)
    gc.unfreeze()
    return statistics.median(times[1:])   # the first: first-call caches


def measure(workdir, runs: int = 200, workers: int | None = None, duration: float = 60.0,
            repeats: int = 5) -> dict:
    """Measure the throughput of a campaign of paper-scenario runs against one run in process.

    The campaign is ``runs`` paper-scenario runs of ``duration`` s on ``workers`` local processes (default: the
    machine's cores); see the module docstring.
    """
    cores = os.cpu_count() or 1
    workers = workers or cores
    t_one = _one_run_seconds(duration, repeats)
    directory = Path(workdir) / 'campaign'
    spec = parse_spec(_SPEC.format(runs=int(runs), duration=float(duration)), source='bench_campaign.yaml')
    start = time.perf_counter()
    outcome = run_campaign(spec, directory, workers=workers)
    wall = time.perf_counter() - start
    rate = outcome.done / wall
    return {'runs': int(runs), 'duration_s': float(duration), 'workers': workers, 'cores': cores,
            'one_run_s': t_one, 'campaign_wall_s': wall, 'runs_per_s': rate,
            'ideal_runs_per_s': cores / t_one, 'efficiency': rate * t_one / cores,
            'failures': outcome.failures, 'time_for_1000_runs_s': 1000.0 / rate}
