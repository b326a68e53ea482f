"""One run as the report sees it (:class:`RunData`), read from a run directory (:func:`load_run`).

Owns the kinds of run directory :mod:`uh_report.report` accepts (a ``run_formation.sh`` run with its
bag, a bare bag, a ``uh-simulate`` directory with ``timeseries.npz``), the checks that they fit their
scenario, :data:`CASE_LABELS` and :class:`ReportError`, the error of an input the report cannot use.
"""
from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from uh_core.layout import X_P_SLICE
from uh_runtime.bags.bag_reader import BagError, open_bag
from uh_team.metrics import MetricsError, metrics_from_arrays
from uh_topology.errors import ScenarioError, ScenarioNotFoundError
from uh_topology.scenario import load_scenario

from .bag_metrics import BagContentError, read_team_bag

__all__ = ['ReportError', 'RunData', 'CASE_LABELS', 'load_run', 'run_of_arrays']


#: Display names of the controller cases (docs/control_law.md#comparison-cases).
CASE_LABELS = {'proposed': 'proposed', 'case1': 'Case I (β = 1)', 'case2': 'Case II (no SPEM)'}


class ReportError(ValueError):
    """A run directory, bag or output directory that cannot be used; the message says which and why."""


@dataclass
class RunData:
    """One run as the report sees it.

    Attributes
    ----------
    directory : Path
        The run directory given on the command line.
    name : str
        Short unique name (sub-directory of the per-run figures).
    label : str
        Legend and table heading.
    source : str
        ``'bag'`` (distributed run, read from MCAP) or ``'timeseries'`` (``uh-simulate``).
    case : str
    scenario : uh_topology.scenario.Scenario
    arrays : dict
        ``time`` (K+1,), ``states`` (K+1, n, 12), ``reference`` (K+1, 5), true and estimated
        lumped faults (K+1, n, 3), ``u_p``, ``saturated``; UH axis in ``scenario.ids`` order.
    metrics : dict
        Content of ``metrics.json`` (or computed, see ``metrics_source``).
    metrics_source : str
        ``'metrics.json'`` or ``'computed'``.
    clock : str
        ``'lockstep'`` or ``'realtime'`` (``run.json``'s), ``''`` for an in-process run.
    """

    directory: Path
    name: str
    label: str
    source: str
    case: str
    scenario: object
    arrays: dict
    metrics: dict
    metrics_source: str = 'metrics.json'
    figures: dict = field(default_factory=dict)
    clock: str = ''


def _read_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ReportError(f'{path}: not valid JSON ({exc})') from None
    except OSError as exc:
        raise ReportError(f'{path}: cannot read it ({exc.strerror})') from None
    if not isinstance(data, dict):
        raise ReportError(f'{path}: expected a JSON object, got {type(data).__name__}')
    return data


def _load_scenario(name, run_dir: Path, where: str, safety: bool | None = None):
    candidates = [name]
    if not Path(str(name)).is_absolute() and name != 'paper':
        candidates.append(run_dir / str(name))
    problems = []
    for candidate in candidates:
        try:
            return load_scenario(candidate, safety=safety)
        except ScenarioError as exc:
            problems.append(exc)
    # what is wrong with a file that exists, else that the name as given (relative to here) names none
    found = [exc for exc in problems if not isinstance(exc, ScenarioNotFoundError)]
    raise ReportError(f'{where}: scenario {name!r}: {(found or problems)[0]}')


def _bag_dir(run_dir: Path) -> Path | None:
    if (run_dir / 'bag').is_dir():
        return run_dir / 'bag'
    if (run_dir / 'metadata.yaml').is_file() or any(run_dir.glob('*.mcap')):
        return run_dir
    return None


def load_run(run_dir, scenario_name: str = 'paper', check_chunks: bool = True) -> RunData:
    """Read one run (see the module docstring for the kinds of directory).

    Raises
    ------
    ReportError
        A missing or empty directory, one that holds no run, a bag that cannot be read (file and
        problem named), arrays that do not fit the scenario, a bad ``run.json``/``metrics.json``.
    """
    run_dir = Path(run_dir)
    if not run_dir.exists():
        raise ReportError(f'{run_dir}: no such run directory')
    if not run_dir.is_dir():
        raise ReportError(f'{run_dir}: not a directory (give the run directory, e.g. runs/proposed)')
    if not any(run_dir.iterdir()):
        raise ReportError(f'{run_dir}: empty directory, not a run (expected bag/ of run_formation.sh '
                          'or timeseries.npz of uh-simulate)')
    run_json = _read_json(run_dir / 'run.json') if (run_dir / 'run.json').is_file() else {}
    metrics = _read_json(run_dir / 'metrics.json') if (run_dir / 'metrics.json').is_file() else None
    # the safety filter's setting the run had (its --safety), recorded in run.json
    safety = {'on': True, 'off': False}.get(run_json.get('safety'))
    scenario = _load_scenario(run_json.get('scenario', scenario_name), run_dir, str(run_dir), safety)
    case = str(run_json.get('case') or (metrics or {}).get('case') or 'proposed')

    bag = _bag_dir(run_dir)
    npz = run_dir / 'timeseries.npz'
    if bag is not None:
        try:
            open_bag(bag, check_chunks=check_chunks)
            arrays = read_team_bag(bag, scenario)
        except (BagError, BagContentError) as exc:
            raise ReportError(str(exc)) from None
        source = 'bag'
    elif npz.is_file():
        arrays = _load_timeseries(npz, scenario)
        source = 'timeseries'
    else:
        contents = sorted(p.name for p in run_dir.iterdir())
        raise ReportError(f'{run_dir}: not a run: no bag/ (run_formation.sh) and no timeseries.npz '
                          f'(uh-simulate); it holds {contents}')
    if not np.isfinite(arrays['states'][..., X_P_SLICE]).any():
        raise ReportError(f'{run_dir}: the {source} holds no finite position')
    metrics_source = 'metrics.json'
    if metrics is None:
        try:
            metrics = metrics_from_arrays(arrays, scenario, case)
        except MetricsError as exc:
            raise ReportError(f'{run_dir}: no metrics.json and the metrics cannot be computed: {exc}') from None
        metrics_source = 'computed'
    return RunData(directory=run_dir, name=run_dir.name, label=CASE_LABELS.get(case, case), source=source,
                   case=case, scenario=scenario, arrays=arrays, metrics=metrics, metrics_source=metrics_source,
                   clock=str(run_json.get('clock') or ''))


def _load_timeseries(path: Path, scenario) -> dict:
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise ReportError(f'{path}: not a readable .npz time series ({type(exc).__name__}: {exc})') from None
    need = ('time', 'states', 'reference', 'fault_true_p', 'fault_true_w', 'fault_est_p', 'fault_est_w')
    missing = [k for k in need if k not in arrays]
    if missing:
        raise ReportError(f'{path}: lacks the arrays {missing} (written by uh-simulate?)')
    n = len(scenario.ids)
    samples = arrays['time'].shape[0]
    if arrays['states'].shape != (samples, n, 12):
        raise ReportError(f'{path}: states have shape {arrays["states"].shape}; the scenario '
                          f'{scenario.name!r} needs ({samples}, {n}, 12) (use --scenario)')
    if 'ids' in arrays and tuple(int(i) for i in arrays['ids']) != tuple(scenario.ids):
        raise ReportError(f'{path}: UH ids {list(arrays["ids"])} differ from those of scenario '
                          f'{scenario.name!r} {list(scenario.ids)} (use --scenario)')
    return arrays


def run_of_arrays(run_dir, scenario, case: str, arrays: dict, metrics: dict) -> RunData:
    """Return the :class:`RunData` of a recorded run whose arrays and metrics are already in hand."""
    run_dir = Path(run_dir)
    return RunData(directory=run_dir, name=run_dir.name, label=CASE_LABELS.get(case, case), source='bag',
                   case=case, scenario=scenario, arrays=arrays, metrics=metrics)
