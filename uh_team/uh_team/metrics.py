"""Performance metrics of a formation-containment run: one definition for every consumer (docs/metrics.md).

The in-process reference simulation, the distributed run (arrays read back from the MCAP bag),
the tests and the benchmarks all call :func:`compute_metrics`. Keys of the result (the content of
``metrics.json``):

``case``
    Controller case (``proposed``, ``case1``, ``case2``).
``sim_time_s``, ``wall_time_s``
    Simulated time span and, if given, the wall-clock time it took, s.
``settle_time_s``
    Samples with ``t >= settle_time`` enter the after-settle metrics (default 20 s).
``formation_rms_m``
    RMS over leaders and samples after settle of ``|p_i - h_i - p_0|``, m.
``containment_rms_m``
    RMS over followers and samples after settle of ``|p_k - sum_j w_kj p_j|``, ``w = -L1^-1 L2``, m.
``hull_distance_max_m``
    Largest distance after settle from a follower to the convex hull of the leaders' current
    positions (0 inside), m. Three leaders span a planar triangle, so an altitude error counts.
``mse_formation``, ``mse_containment``
    Mean over all samples (from t = 0) and UHs of the squared formation / containment errors, m^2.
``cpi``
    ``integral_0^T sum_UH (|z1|^2 + |u_p|^2) dt`` with the consensus error z1 (m) and the designed
    acceleration u_p (m/s^2) of each control step, held over the step (rectangle rule).
``fault_estimation``
    ``{"uh<i>": {"window": [t0, t1], "p": {...}, "w": {...}}}`` for every faulted UH, scored on the
    steps with ``t >= onset + 5 s`` (onset = the UH's earliest fault): per lumped-fault vector
    ``rms_error`` (RMS of ``|Fhat - F|``), ``truth_rms`` (RMS of ``|F|``), both m/s^2 (``p``) or
    rad/s^2 (``w``), and ``nrmse`` = ``rms_error / truth_rms`` only when ``truth_rms`` is at least
    the vector's floor (:data:`NRMSE_FLOOR_P`, :data:`NRMSE_FLOOR_W`), else ``None`` with the
    reason in ``nrmse_note``. ``p`` only when the collective (channel 0) is faulted; ``w``
    whenever any channel is.
``false_fault_estimate``
    ``{"uh<i>": {"p": ..., "w": ..., "window": [t0, t1]}, "max": {"p": ..., "w": ...},
    "threshold": {"p": 0.05, "w": 0.1}}``: RMS of ``|Fhat|`` where no fault acts, on every healthy
    UH over ``[5 s, end]`` and on every faulted UH over ``[5 s, onset)`` (left out if empty), m/s^2
    (``p``) and rad/s^2 (``w``); ``max`` over the UHs is checked against ``threshold``.
``fault_nrmse``
    ``{"uh<i>": {"F_p": ..., "F_w": ...}}``: the ``nrmse`` values of ``fault_estimation`` in the
    layout of earlier versions (``None`` below the floor).
``saturation_fraction``
    Fraction of (step, UH) samples with any input limit active (tilt, collective, cyclic/pedal).
``fault_isolation``
    The verdicts of the causal isolator every controller runs (``uh_controller_node.fault_isolation``),
    scored against the scenario's faults (:func:`fault_isolation_metrics`): from a bag, what each
    controller published on its last ``ControllerStatus``; in-process, the same isolator run over
    the arrays. ``{"uh<i>": {channel name: {...}}, "summary": {"false_isolations", "missed",
    "max_delay", "source"}}``; ``None`` when the arrays lack what it needs (the commands) or do
    not match the scenario.

Undefined values (no followers, an empty window, a true fault below the NRMSE floor) are ``None``
(JSON ``null``).

This module is the public face of the metrics; their parts live by concern in
:mod:`uh_team.hull_geometry` (distances to the leaders' hull), :mod:`uh_team.error_metrics`
(formation, containment and consensus errors), :mod:`uh_team.fault_metrics` (scoring of the fault
estimates) and :mod:`uh_team.isolation_metrics` (scoring of the fault isolation); the arrays of a
run are those of :mod:`uh_team.run_arrays`.
"""
from __future__ import annotations

import numpy as np

from uh_core.layout import X_P_SLICE

from .error_metrics import consensus_errors, containment_errors, formation_errors
from .fault_metrics import (FALSE_ESTIMATE_START, FALSE_ESTIMATE_THRESHOLD_P, FALSE_ESTIMATE_THRESHOLD_W,
                            FAULT_WINDOW_DELAY, LUMPED_FAULTS, NOT_MEANINGFUL_MARK, NRMSE_FLOOR_P, NRMSE_FLOOR_W,
                            NRMSE_TARGET, FaultedUH, LumpedFault, MetricsError, false_fault_estimate,
                            fault_estimation, fault_list, faulted_uhs, none_if_nan, nrmse_below_floor, rms_norm)
from .hull_geometry import hull_distance, point_segment_distance, point_triangle_distance
from .isolation_metrics import ISOLATION_ARRAYS, fault_isolation_metrics
from .run_arrays import RUN_REF_POSITION

__all__ = ['MetricsError', 'FaultedUH', 'LumpedFault', 'LUMPED_FAULTS', 'FAULT_WINDOW_DELAY',
           'FALSE_ESTIMATE_START', 'FALSE_ESTIMATE_THRESHOLD_P', 'FALSE_ESTIMATE_THRESHOLD_W',
           'NRMSE_TARGET', 'NRMSE_FLOOR_P', 'NRMSE_FLOOR_W', 'METRIC_KEYS', 'formation_errors',
           'containment_errors', 'consensus_errors', 'point_segment_distance',
           'point_triangle_distance', 'hull_distance', 'faulted_uhs', 'rms_norm', 'nrmse_below_floor',
           'NOT_MEANINGFUL_MARK', 'ISOLATION_ARRAYS', 'compute_metrics', 'fault_isolation_metrics',
           'metrics_from_arrays']

#: Keys of :func:`compute_metrics`' result, in order.
METRIC_KEYS = ('case', 'sim_time_s', 'wall_time_s', 'settle_time_s', 'formation_rms_m',
               'containment_rms_m', 'hull_distance_max_m', 'mse_formation', 'mse_containment', 'cpi',
               'fault_estimation', 'false_fault_estimate', 'fault_nrmse', 'saturation_fraction',
               'fault_isolation', 'faults')


def _shape(name, arr, shape):
    arr = np.asarray(arr, dtype=float)
    if arr.shape != shape:
        raise MetricsError(f'{name} must have shape {shape}, got {arr.shape}')
    return arr


def compute_metrics(*, case: str, time, positions, reference_positions, leaders, followers, offsets,
                    containment_weights, z1, u_p, saturated, fault_true_p=None, fault_true_w=None,
                    fault_est_p=None, fault_est_w=None, faulted=None, settle_time: float = 20.0,
                    wall_time: float | None = None) -> dict:
    """Metrics of docs/metrics.md from the arrays of one run (see the module docstring for the keys).

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
    leaders = tuple(int(i) for i in leaders)
    followers = tuple(int(i) for i in followers)
    ids = leaders + followers
    n, n_lead, n_fol = len(ids), len(leaders), len(followers)
    time = np.asarray(time, dtype=float).reshape(-1)
    samples = time.shape[0]
    if samples < 2:
        raise MetricsError(f'time must hold at least 2 samples, got {samples}')
    steps = samples - 1
    dt = float(time[1] - time[0])
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

    after = time >= settle_time - 1e-9 * max(dt, 1.0)
    lead_pos, fol_pos = positions[:, :n_lead], positions[:, n_lead:]
    form = formation_errors(lead_pos, p0, h)
    result = dict.fromkeys(METRIC_KEYS)
    result['case'] = str(case)
    result['sim_time_s'] = float(time[-1] - time[0])
    result['wall_time_s'] = None if wall_time is None else float(wall_time)
    result['settle_time_s'] = float(settle_time)
    result['formation_rms_m'] = none_if_nan(np.sqrt(np.nanmean(form[after] ** 2))) if after.any() else None
    result['mse_formation'] = none_if_nan(np.nanmean(form ** 2))
    if n_fol:
        w = _shape('containment_weights', containment_weights, (n_fol, n_lead))
        cont = containment_errors(fol_pos, lead_pos, w)
        result['mse_containment'] = none_if_nan(np.nanmean(cont ** 2))
        if after.any():
            result['containment_rms_m'] = none_if_nan(np.sqrt(np.nanmean(cont[after] ** 2)))
            hull = hull_distance(fol_pos[after], lead_pos[after][:, None, :, :])
            result['hull_distance_max_m'] = none_if_nan(np.nanmax(hull))
    # a step a real-time run did not record (NaN) contributes nothing: the CPI then slightly
    # underestimates; lockstep and in-process runs have every step
    result['cpi'] = none_if_nan(dt * (np.nansum(z1 * z1) + np.nansum(u_p * u_p)))

    step_time = time[:steps]
    tolerance = 1e-9 * max(dt, 1.0)
    faulted = dict(sorted((faulted or {}).items()))
    unknown = [uh for uh in faulted if uh not in ids]
    if unknown:
        raise MetricsError(f'faulted UH {unknown[0]} is not one of the UHs {list(ids)}')
    given = {'fault_true_p': fault_true_p, 'fault_true_w': fault_true_w, 'fault_est_p': fault_est_p,
             'fault_est_w': fault_est_w}
    fault_data = {name: None if arr is None else _shape(name, arr, (steps, n, 3)) for name, arr in given.items()}
    estimation = fault_estimation(step_time, ids, faulted, fault_data, tolerance)
    result['fault_estimation'] = estimation
    result['false_fault_estimate'] = false_fault_estimate(step_time, ids, faulted, fault_data, tolerance)
    result['fault_nrmse'] = {uh: {v.symbol: entry[v.key]['nrmse'] for v in LUMPED_FAULTS if v.key in entry}
                             for uh, entry in estimation.items()}
    result['saturation_fraction'] = float(np.mean(saturated)) if saturated.size else 0.0
    return result


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

    result = compute_metrics(
        case=case, time=time, positions=positions, reference_positions=p0,
        leaders=scenario.leaders, followers=scenario.followers, offsets=scenario.offsets,
        containment_weights=scenario.containment_weights, z1=z1, u_p=per_step('u_p'),
        saturated=per_step('saturated'), fault_true_p=per_step('fault_true_p'),
        fault_true_w=per_step('fault_true_w'), fault_est_p=per_step('fault_est_p'),
        fault_est_w=per_step('fault_est_w'), faulted=faulted_uhs(scenario, arrays),
        settle_time=float(scenario.settle_time), wall_time=wall_time_s)
    result['fault_isolation'] = fault_isolation_metrics(arrays, scenario, case)
    result['faults'] = fault_list(scenario, arrays)
    return result
