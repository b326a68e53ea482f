"""Performance metrics of a formation-containment run: one definition for every consumer (docs/metrics.md).

The in-process reference simulation, the distributed run (arrays read back from the MCAP bag),
the tests and the benchmarks all call :func:`compute_metrics` (or :func:`metrics_from_arrays`). Its
result is the content of ``metrics.json``: the keys :data:`METRIC_KEYS`, each declared with its
computation, unit and meaning in :data:`uh_team.metric_registry.METRICS`. Undefined values (no
followers, an empty window, a true fault below the NRMSE floor) are ``None`` (JSON ``null``).

This module is the public face of the metrics; their parts live by concern in
:mod:`uh_team.metric_registry` (each metric declared once), :mod:`uh_team.hull_geometry` (distances
to the leaders' hull), :mod:`uh_team.error_metrics` (formation, containment and consensus errors),
:mod:`uh_team.fault_metrics` (scoring of the fault estimates) and :mod:`uh_team.isolation_metrics`
(scoring of the fault isolation); the arrays of a run are those of :mod:`uh_team.run_arrays`.
"""
from __future__ import annotations

import numpy as np

from uh_core.layout import X_P_SLICE

from .error_metrics import consensus_errors, containment_errors, formation_errors
from .fault_metrics import (
    FALSE_ESTIMATE_START,
    FALSE_ESTIMATE_THRESHOLD_P,
    FALSE_ESTIMATE_THRESHOLD_W,
    FAULT_WINDOW_DELAY,
    LUMPED_FAULTS,
    NOT_MEANINGFUL_MARK,
    NRMSE_FLOOR_P,
    NRMSE_FLOOR_W,
    NRMSE_TARGET,
    FaultedUH,
    LumpedFault,
    MetricsError,
    faulted_uhs,
    nrmse_below_floor,
    rms_norm,
)
from .hull_geometry import hull_distance, point_segment_distance, point_triangle_distance
from .isolation_metrics import ISOLATION_ARRAYS, fault_isolation_metrics
from .metric_registry import RunValues, json_keys, json_metrics
from .run_arrays import RUN_REF_POSITION

__all__ = ['MetricsError', 'FaultedUH', 'LumpedFault', 'LUMPED_FAULTS', 'FAULT_WINDOW_DELAY',
           'FALSE_ESTIMATE_START', 'FALSE_ESTIMATE_THRESHOLD_P', 'FALSE_ESTIMATE_THRESHOLD_W',
           'NRMSE_TARGET', 'NRMSE_FLOOR_P', 'NRMSE_FLOOR_W', 'METRIC_KEYS', 'formation_errors',
           'containment_errors', 'consensus_errors', 'point_segment_distance',
           'point_triangle_distance', 'hull_distance', 'faulted_uhs', 'rms_norm', 'nrmse_below_floor',
           'NOT_MEANINGFUL_MARK', 'ISOLATION_ARRAYS', 'compute_metrics', 'fault_isolation_metrics',
           'metrics_from_arrays', 'run_values', 'evaluate', 'RunValues']

#: Keys of :func:`compute_metrics`' result, in order (those of :data:`uh_team.metric_registry.METRICS`).
METRIC_KEYS = json_keys()


def _shape(name, arr, shape):
    arr = np.asarray(arr, dtype=float)
    if arr.shape != shape:
        raise MetricsError(f'{name} must have shape {shape}, got {arr.shape}')
    return arr


def compute_metrics(*, case: str, time, positions, reference_positions, leaders, followers, offsets,
                    containment_weights, z1, u_p, saturated, fault_true_p=None, fault_true_w=None,
                    fault_est_p=None, fault_est_w=None, faulted=None, settle_time: float = 20.0,
                    wall_time: float | None = None) -> dict:
    """Metrics of docs/metrics.md from the arrays of one run: the keys :data:`METRIC_KEYS`, in order.

    Parameters
    ----------
    case : str
        Controller case label.
    time : array_like (K+1,)
        Sample times t_k = k dt of the positions, s.
    positions : array_like (K+1, n, 3)
        Positions of the UHs at ``time``, m, UH order ``leaders + followers``.
    reference_positions : array_like (K+1, 3)
        Virtual leader p_0 at ``time``, m.
    leaders, followers : sequence of int
        UH ids; together they give the UH order of the arrays.
    offsets : mapping {leader id: (3,)}
        Formation offsets h_i, m.
    containment_weights : array_like (M, N)
        ``-L1^-1 L2`` (rows ``followers``, columns ``leaders``).
    z1, u_p : array_like (K, n, 3)
        Consensus error (m) and designed acceleration (m/s^2) of each control step t_0..t_{K-1}.
    saturated : array_like (K, n) of bool
        Any input limit active at the step.
    fault_true_p, fault_true_w, fault_est_p, fault_est_w : array_like (K, n, 3), optional
        True lumped faults and their estimates per step (m/s^2, rad/s^2); the true faults are
        needed for the UHs in ``faulted``, the estimates for those and for the false fault
        estimate (whose values are ``None`` without them).
    faulted : mapping {uh id: FaultedUH}, optional
        The UHs with a fault in the scenario and which vectors to score (:func:`faulted_uhs`);
        every other UH is healthy.
    settle_time : float
        s.
    wall_time : float, optional
        Wall-clock duration of the run, s.

    Returns
    -------
    dict
        Keys :data:`METRIC_KEYS`.

    Raises
    ------
    MetricsError
        Inconsistent array shapes, or fault data missing for a faulted UH.
    """
    values = run_values(case=case, time=time, positions=positions, reference_positions=reference_positions,
                        leaders=leaders, followers=followers, offsets=offsets,
                        containment_weights=containment_weights, z1=z1, u_p=u_p, saturated=saturated,
                        fault_true_p=fault_true_p, fault_true_w=fault_true_w, fault_est_p=fault_est_p,
                        fault_est_w=fault_est_w, faulted=faulted, settle_time=settle_time, wall_time=wall_time)
    return evaluate(values)


def run_values(*, case, time, positions, reference_positions, leaders, followers, offsets, containment_weights,
               z1, u_p, saturated, fault_true_p=None, fault_true_w=None, fault_est_p=None, fault_est_w=None,
               faulted=None, settle_time=20.0, wall_time=None) -> RunValues:
    """Check the arrays of :func:`compute_metrics` (same arguments) and return them as :class:`RunValues`.

    Raises
    ------
    MetricsError
        Inconsistent array shapes, or a faulted UH that is not one of the UHs.
    """
    leaders = tuple(int(i) for i in leaders)
    followers = tuple(int(i) for i in followers)
    ids = leaders + followers
    n, n_lead, n_fol = len(ids), len(leaders), len(followers)
    time = np.asarray(time, dtype=float).reshape(-1)
    samples = time.shape[0]
    if samples < 2:
        raise MetricsError(f'time must hold at least 2 samples, got {samples}')
    steps = samples - 1
    positions = _shape('positions', positions, (samples, n, 3))
    p0 = _shape('reference_positions', reference_positions, (samples, 3))
    missing = [i for i in leaders if i not in offsets]
    if missing:
        raise MetricsError(f'no formation offset for leader(s) {missing}')
    h = np.array([np.asarray(offsets[i], dtype=float).reshape(3) for i in leaders])
    z1 = _shape('z1', z1, (steps, n, 3))
    u_p = _shape('u_p', u_p, (steps, n, 3))
    saturated = np.asarray(saturated, dtype=bool)
    if saturated.shape != (steps, n):
        raise MetricsError(f'saturated must have shape {(steps, n)}, got {saturated.shape}')
    w = _shape('containment_weights', containment_weights, (n_fol, n_lead)) if n_fol else None
    faulted = dict(sorted((faulted or {}).items()))
    unknown = [uh for uh in faulted if uh not in ids]
    if unknown:
        raise MetricsError(f'faulted UH {unknown[0]} is not one of the UHs {list(ids)}')
    given = {'fault_true_p': fault_true_p, 'fault_true_w': fault_true_w, 'fault_est_p': fault_est_p,
             'fault_est_w': fault_est_w}
    fault_data = {name: None if arr is None else _shape(name, arr, (steps, n, 3)) for name, arr in given.items()}
    return RunValues(case=case, time=time, positions=positions, reference_positions=p0, leaders=leaders,
                     followers=followers, offsets=h, containment_weights=w, z1=z1, u_p=u_p, saturated=saturated,
                     fault_data=fault_data, faulted=faulted, settle_time=settle_time, wall_time=wall_time)


def evaluate(values: RunValues) -> dict:
    """Return the content of ``metrics.json``: every top-level metric of the registry computed on ``values``."""
    return {metric.name: metric.compute(values) for metric in json_metrics()}


def metrics_from_arrays(arrays, scenario, case: str, wall_time_s: float | None = None) -> dict:
    """:func:`compute_metrics` on the arrays of a team run (reference simulation or recorded bag).

    Parameters
    ----------
    arrays : mapping
        ``time`` (K+1,), ``states`` (K+1, n, 12), ``reference`` (K+1, >=3) with p_0 in the first 3
        columns, and per step ``u_p`` (K or K+1, n, 3), ``saturated`` (K or K+1, n),
        ``fault_true_p``, ``fault_true_w``, ``fault_est_p``, ``fault_est_w`` (K or K+1, n, 3), and for
        ``fault_isolation`` ``commands`` (K or K+1, n, 4) rad; UH
        axis in ``scenario.ids`` order (the layout of ``TeamRun.arrays()`` and of
        ``uh_report.bag_metrics.read_team_bag``). Per-step rows beyond K - 1 (a command at t_K that
        is never applied) are ignored.
    scenario : uh_topology.scenario.Scenario
        Graph, offsets, containment weights, faults and settle time.
    case : str
    wall_time_s : float, optional

    Returns
    -------
    dict
        As :func:`compute_metrics`; z1 for the CPI comes from :func:`consensus_errors`,
        ``fault_isolation`` from :func:`fault_isolation_metrics` (``None`` without ``commands``) and
        ``faults`` (the run's scheduled and injected faults) from :func:`~uh_team.fault_metrics.fault_list`.
        The faults scored are the scenario's and those injected during a recorded run
        (``arrays['fault_injections']``, :func:`~uh_team.fault_metrics.injected_faults`).
    """
    missing = [k for k in ('time', 'states', 'reference', 'u_p', 'saturated') if k not in arrays]
    if missing:
        raise MetricsError(f'run arrays lack {missing}')
    time = np.asarray(arrays['time'], dtype=float)
    steps = time.shape[0] - 1
    positions = np.asarray(arrays['states'], dtype=float)[..., X_P_SLICE]
    p0 = np.asarray(arrays['reference'], dtype=float)[:, RUN_REF_POSITION]
    z1 = consensus_errors(positions, p0, scenario)[:steps]

    def per_step(key):
        if key not in arrays:
            return None
        arr = np.asarray(arrays[key])
        if arr.shape[0] not in (steps, steps + 1):
            raise MetricsError(f'{key} must have {steps} or {steps + 1} rows (one per step), got {arr.shape[0]}')
        return arr[:steps]

    values = run_values(
        case=case, time=time, positions=positions, reference_positions=p0,
        leaders=scenario.leaders, followers=scenario.followers, offsets=scenario.offsets,
        containment_weights=scenario.containment_weights, z1=z1, u_p=per_step('u_p'),
        saturated=per_step('saturated'), fault_true_p=per_step('fault_true_p'),
        fault_true_w=per_step('fault_true_w'), fault_est_p=per_step('fault_est_p'),
        fault_est_w=per_step('fault_est_w'), faulted=faulted_uhs(scenario, arrays),
        settle_time=float(scenario.settle_time), wall_time=wall_time_s)
    values.scenario, values.arrays = scenario, arrays
    return evaluate(values)
