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
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

__all__ = ['MetricsError', 'FaultedUH', 'LumpedFault', 'LUMPED_FAULTS', 'FAULT_WINDOW_DELAY',
           'FALSE_ESTIMATE_START', 'FALSE_ESTIMATE_THRESHOLD_P', 'FALSE_ESTIMATE_THRESHOLD_W',
           'NRMSE_TARGET', 'NRMSE_FLOOR_P', 'NRMSE_FLOOR_W', 'METRIC_KEYS', 'formation_errors',
           'containment_errors', 'consensus_errors', 'point_segment_distance',
           'point_triangle_distance', 'hull_distance', 'faulted_uhs', 'rms_norm', 'nrmse_below_floor',
           'NOT_MEANINGFUL_MARK', 'ISOLATION_ARRAYS', 'compute_metrics', 'fault_isolation_metrics',
           'metrics_from_arrays']

#: Delay after a UH's fault onset before its fault estimate is scored, s (docs/metrics.md).
FAULT_WINDOW_DELAY = 5.0

#: Start-up left out of the false fault estimate, s: the observers start at zero and their first
#: seconds hold transients unrelated to any fault (docs/metrics.md#false-fault-estimate).
FALSE_ESTIMATE_START = 5.0

#: Acceptance threshold of the false fault estimate of ``Fhat_p`` (maximum over the UHs), m/s^2;
#: also the estimator's resolution on a healthy UH, from which :data:`NRMSE_FLOOR_P` follows.
FALSE_ESTIMATE_THRESHOLD_P = 0.05

#: Acceptance threshold of the false fault estimate of ``Fhat_w`` (maximum over the UHs), rad/s^2;
#: also the estimator's resolution on a healthy UH, from which :data:`NRMSE_FLOOR_W` follows.
FALSE_ESTIMATE_THRESHOLD_W = 0.1

#: Fault NRMSE the estimator is asked to reach (-).
NRMSE_TARGET = 0.25

#: Smallest RMS of the true ``F_p`` for which the NRMSE is reported, m/s^2: resolution / target.
#: Below it the ratio measures the smallness of the truth, not the estimator (docs/metrics.md).
NRMSE_FLOOR_P = FALSE_ESTIMATE_THRESHOLD_P / NRMSE_TARGET      # 0.2

#: Smallest RMS of the true ``F_w`` for which the NRMSE is reported, rad/s^2: resolution / target.
NRMSE_FLOOR_W = FALSE_ESTIMATE_THRESHOLD_W / NRMSE_TARGET      # 0.4

#: What tables and console output show instead of an NRMSE withheld below the floor.
NOT_MEANINGFUL_MARK = 'n/m'

#: Keys of :func:`compute_metrics`' result, in order.
METRIC_KEYS = ('case', 'sim_time_s', 'wall_time_s', 'settle_time_s', 'formation_rms_m',
               'containment_rms_m', 'hull_distance_max_m', 'mse_formation', 'mse_containment', 'cpi',
               'fault_estimation', 'false_fault_estimate', 'fault_nrmse', 'saturation_fraction',
               'fault_isolation')

#: Arrays the fault isolation needs (``uh_controller_node.fault_isolation.isolate_run``).
ISOLATION_ARRAYS = ('time', 'states', 'commands', 'fault_est_p', 'fault_est_w')


class MetricsError(ValueError):
    """Arrays of inconsistent shape or missing data handed to the metrics."""


@dataclass(frozen=True)
class FaultedUH:
    """Which lumped faults of one UH are scored (docs/metrics.md).

    Attributes
    ----------
    onset : float
        Earliest fault onset of the UH, s.
    collective : bool
        The collective (channel 0) is faulted, so ``F_p`` is scored too.
    """

    onset: float
    collective: bool

    def scored_vectors(self) -> tuple:
        """The :data:`LUMPED_FAULTS` scored for this UH: ``F_p`` only with a collective fault (only
        the collective acts on the position loop), ``F_w`` always (every channel moves the rotor
        moments).
        """
        return tuple(v for v in LUMPED_FAULTS if v.key == 'w' or self.collective)


@dataclass(frozen=True)
class LumpedFault:
    """One lumped-fault vector as the metrics, the report and the CLI name it.

    Attributes
    ----------
    key : str
        Key in ``metrics.json`` (``'p'`` or ``'w'``).
    symbol : str
        ``'F_p'`` or ``'F_w'`` (the key of the ``fault_nrmse`` layout).
    loop : str
        ``'position'`` or ``'attitude'``.
    unit : str
        ``'m/s^2'`` or ``'rad/s^2'``.
    true_array, estimate_array : str
        Keys of the true and estimated vectors in a run's arrays (``fault_true_p``, ``fault_est_p``).
    false_estimate_threshold : float
        Acceptance threshold of the false fault estimate, ``unit``.
    nrmse_floor : float
        Smallest true RMS for which the NRMSE is reported, ``unit``.
    """

    key: str
    symbol: str
    loop: str
    unit: str
    true_array: str
    estimate_array: str
    false_estimate_threshold: float
    nrmse_floor: float


#: The two lumped-fault vectors, position loop first.
LUMPED_FAULTS = (
    LumpedFault('p', 'F_p', 'position', 'm/s^2', 'fault_true_p', 'fault_est_p',
                FALSE_ESTIMATE_THRESHOLD_P, NRMSE_FLOOR_P),
    LumpedFault('w', 'F_w', 'attitude', 'rad/s^2', 'fault_true_w', 'fault_est_w',
                FALSE_ESTIMATE_THRESHOLD_W, NRMSE_FLOOR_W),
)


# ----------------------------------------------------------------------------------------------
# geometry

def _dot(a, b):
    return np.einsum('...i,...i->...', a, b)


def point_segment_distance(p, a, b) -> np.ndarray:
    """Distance from points ``p`` to segments ``[a, b]``; all (..., 3) broadcastable, m.

    A degenerate segment (``a == b``) is the point ``a``.
    """
    p, a, b = (np.asarray(x, dtype=float) for x in (p, a, b))
    ab = b - a
    denom = _dot(ab, ab)
    t = np.clip(_dot(p - a, ab) / np.where(denom > 0.0, denom, 1.0), 0.0, 1.0)
    t = np.where(denom > 0.0, t, 0.0)
    closest = a + t[..., None] * ab
    return np.linalg.norm(p - closest, axis=-1)


def point_triangle_distance(p, a, b, c) -> np.ndarray:
    """Exact distance from points ``p`` to the filled triangles ``(a, b, c)``; (..., 3) broadcastable.

    If the orthogonal projection of ``p`` on the triangle's plane lies inside the triangle, the
    distance is ``|n . (p - a)| / |n|``; otherwise the closest point is on an edge and the distance
    is the smallest point-segment distance. Degenerate (collinear) triangles reduce to their edges.
    """
    p, a, b, c = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (p, a, b, c)))
    ab, ac, ap = b - a, c - a, p - a
    n = np.cross(ab, ac)
    nn = _dot(n, n)
    scale = np.maximum(_dot(ab, ab), _dot(ac, ac))
    flat = nn <= 1e-24 * np.maximum(scale * scale, 1e-300)   # collinear or coincident vertices
    safe = np.where(flat, 1.0, nn)
    # barycentric coordinates of the projection (Lagrange: d00 d11 - d01^2 = |n|^2)
    d00, d01, d11 = _dot(ab, ab), _dot(ab, ac), _dot(ac, ac)
    d20, d21 = _dot(ap, ab), _dot(ap, ac)
    v = (d11 * d20 - d01 * d21) / safe
    w = (d00 * d21 - d01 * d20) / safe
    inside = (~flat) & (v >= 0.0) & (w >= 0.0) & (v + w <= 1.0)
    plane = np.abs(_dot(n, ap)) / np.sqrt(safe)
    edges = np.minimum(np.minimum(point_segment_distance(p, a, b), point_segment_distance(p, b, c)),
                       point_segment_distance(p, c, a))
    return np.where(inside, plane, edges)


def _tetra_distance(p, v0, v1, v2, v3):
    # 0 inside a non-degenerate tetrahedron, else the nearest face (exact; a flat tetrahedron is
    # the union of its four faces)
    faces = np.minimum(np.minimum(point_triangle_distance(p, v0, v1, v2), point_triangle_distance(p, v0, v1, v3)),
                       np.minimum(point_triangle_distance(p, v0, v2, v3), point_triangle_distance(p, v1, v2, v3)))
    e1, e2, e3 = v1 - v0, v2 - v0, v3 - v0
    vol = _dot(np.cross(e1, e2), e3)
    q = p - v0
    safe = np.where(vol != 0.0, vol, 1.0)
    l1 = _dot(np.cross(q, e2), e3) / safe
    l2 = _dot(np.cross(e1, q), e3) / safe
    l3 = _dot(np.cross(e1, e2), q) / safe
    inside = (vol != 0.0) & (l1 >= 0) & (l2 >= 0) & (l3 >= 0) & (l1 + l2 + l3 <= 1.0)
    return np.where(inside, 0.0, faces)


def hull_distance(points, vertices) -> np.ndarray:
    """Distance from ``points`` (..., 3) to the convex hull of ``vertices`` (..., N, 3), m (0 inside).

    Exact for any N >= 1: a point, a segment, a triangle (N = 3, the paper's three leaders), or for
    N >= 4 the smallest distance to any tetrahedron of four vertices (Caratheodory: the hull is the
    union of those tetrahedra).
    """
    points = np.asarray(points, dtype=float)
    vertices = np.asarray(vertices, dtype=float)
    n = vertices.shape[-2]
    vs = [vertices[..., i, :] for i in range(n)]
    if n == 1:
        return np.linalg.norm(points - vs[0], axis=-1)
    if n == 2:
        return point_segment_distance(points, vs[0], vs[1])
    if n == 3:
        return point_triangle_distance(points, vs[0], vs[1], vs[2])
    best = None
    for i, j, k, m in itertools.combinations(range(n), 4):
        d = _tetra_distance(points, vs[i], vs[j], vs[k], vs[m])
        best = d if best is None else np.minimum(best, d)
    return best


# ----------------------------------------------------------------------------------------------
# errors

def formation_errors(positions, reference_positions, offsets) -> np.ndarray:
    """``|p_i - h_i - p_0|`` (K, N) of the leaders, m.

    ``positions`` (K, N, 3) of the leaders in order, ``reference_positions`` (K, 3), ``offsets``
    (N, 3) in the same leader order.
    """
    dev = np.asarray(positions) - np.asarray(offsets)[None, :, :] - np.asarray(reference_positions)[:, None, :]
    return np.linalg.norm(dev, axis=-1)


def containment_errors(follower_positions, leader_positions, weights) -> np.ndarray:
    """``|p_k - sum_j w_kj p_j|`` (K, M), m; ``weights`` (M, N) = ``-L1^-1 L2``."""
    target = np.einsum('mn,knc->kmc', np.asarray(weights), np.asarray(leader_positions))
    return np.linalg.norm(np.asarray(follower_positions) - target, axis=-1)


def consensus_errors(positions, reference_positions, scenario) -> np.ndarray:
    """Consensus errors z1 (K, n, 3) of docs/graph.md from positions (K, n, 3) in ``scenario.ids`` order.

    ``z1_i = sum_j a_ij [(p_i - h_i) - (p_j - h_j)] + a_i0 [(p_i - h_i) - p_0]`` with the formation
    offsets ``h`` for a leader's errors and ``h = 0`` for a follower's: the same quantity the
    controllers compute from their neighbours' data, recomputed here from the recorded positions so
    that the CPI has one definition whatever produced the arrays.
    """
    positions = np.asarray(positions, dtype=float)
    p0 = np.asarray(reference_positions, dtype=float)
    ids = tuple(scenario.ids)
    leaders = set(scenario.leaders)
    col = {i: c for c, i in enumerate(ids)}
    out = np.zeros(positions.shape)
    for i in ids:
        h = (lambda j: np.asarray(scenario.offsets[j], dtype=float)) if i in leaders else (lambda j: 0.0)
        rel = positions[:, col[i]] - h(i)
        for j in scenario.neighbours(i):
            out[:, col[i]] += scenario.weight(i, j) * (rel - (positions[:, col[j]] - h(j)))
        a0 = scenario.leader_link(i)
        if a0 > 0.0:
            out[:, col[i]] += a0 * (rel - p0)
    return out


def faulted_uhs(scenario) -> dict:
    """``{uh id: FaultedUH}`` of the UHs with at least one scheduled fault in ``scenario.faults``.

    Accepts fault specs as objects or mappings with ``channel`` and ``onset_time``.
    """
    out = {}
    for uh, specs in sorted(scenario.faults.items()):
        specs = tuple(specs)
        if not specs:
            continue
        get = (lambda s, k: s[k]) if isinstance(specs[0], dict) else getattr
        onset = min(float(get(s, 'onset_time')) for s in specs)
        collective = any(int(get(s, 'channel')) == 0 for s in specs)
        out[int(uh)] = FaultedUH(onset=onset, collective=collective)
    return out


def _none_if_nan(x):
    x = float(x)
    return None if not math.isfinite(x) else x


def rms_norm(vectors) -> float | None:
    """RMS of the Euclidean norms of the rows: ``sqrt(mean_k |v_k|^2)``.

    Parameters
    ----------
    vectors : array_like (k, 3)
        One vector per step, in any unit (m/s^2 for ``F_p``, rad/s^2 for ``F_w``).

    Returns
    -------
    float or None
        In the unit of ``vectors``; ``None`` without rows or if not finite.
    """
    vectors = np.asarray(vectors, dtype=float)
    if vectors.shape[0] == 0:
        return None
    return _none_if_nan(math.sqrt(float(np.mean(_dot(vectors, vectors)))))


def _finite_rows(*arrays) -> np.ndarray:
    """(k,) bool: the rows where every array holds finite values; a step a real-time run did not
    record is NaN and is left out of the fault metrics.
    """
    keep = np.ones(arrays[0].shape[0], dtype=bool)
    for arr in arrays:
        keep &= np.isfinite(arr).all(axis=-1)
    return keep


def _step_window(step_time, start: float, end: float | None, tolerance: float) -> np.ndarray:
    """(K,) bool: the steps with ``start <= t_k`` and, if ``end`` is given, ``t_k < end`` (s)."""
    window = step_time >= start - tolerance
    if end is not None:
        window &= step_time < end - tolerance
    return window


def _window_bounds(step_time, window) -> list | None:
    """``[t_first, t_last]`` of the steps in ``window`` (s), ``None`` if it is empty."""
    if not window.any():
        return None
    times = step_time[window]
    return [round(float(times[0]), 9), round(float(times[-1]), 9)]


def _fault_estimation_entry(estimate, truth, vector: LumpedFault) -> dict:
    """``rms_error``, ``truth_rms``, ``nrmse`` and ``nrmse_note`` of one lumped-fault vector.

    Parameters
    ----------
    estimate, truth : ndarray (k, 3)
        ``Fhat`` and ``F`` on the steps of the window, ``vector.unit``.
    vector : LumpedFault

    Returns
    -------
    dict
        ``rms_error`` = RMS of ``|Fhat - F|`` and ``truth_rms`` = RMS of ``|F|`` (``vector.unit``);
        ``nrmse`` = their ratio if ``truth_rms >= vector.nrmse_floor``, else ``None`` with the
        reason in ``nrmse_note`` (``None`` when the NRMSE is a number).
    """
    keep = _finite_rows(estimate, truth)
    estimate, truth = estimate[keep], truth[keep]
    rms_error = rms_norm(estimate - truth)
    truth_rms = rms_norm(truth)
    nrmse, note = None, None
    if rms_error is None or truth_rms is None:
        note = 'no step in the window'
    elif truth_rms < vector.nrmse_floor:
        note = (f'not meaningful: the RMS of the true {vector.symbol}, {truth_rms:.3g} {vector.unit}, is below '
                f'the floor {vector.nrmse_floor:g} {vector.unit}')
    else:
        nrmse = _none_if_nan(rms_error / truth_rms)
    return {'rms_error': rms_error, 'truth_rms': truth_rms, 'nrmse': nrmse, 'nrmse_note': note}


def nrmse_below_floor(entry) -> bool:
    """Whether a ``fault_estimation`` vector entry withholds its NRMSE because the true RMS is
    below the floor (``nrmse`` null, ``truth_rms`` a number), as opposed to an empty window.

    Parameters
    ----------
    entry : mapping
        ``metrics["fault_estimation"]["uh<i>"]["p" or "w"]``.

    Returns
    -------
    bool
    """
    return entry.get('nrmse') is None and entry.get('truth_rms') is not None


def _fault_estimation(step_time, ids, faulted, fault_data, tolerance: float) -> dict:
    """``fault_estimation`` of docs/metrics.md: each faulted UH's scored vectors over
    ``[onset + FAULT_WINDOW_DELAY, end]``; ``fault_data`` maps array names to (K, n, 3) or ``None``.
    """
    out = {}
    for uh, info in faulted.items():
        vectors = info.scored_vectors()
        if any(fault_data[name] is None for v in vectors for name in (v.true_array, v.estimate_array)):
            raise MetricsError(f'UH {uh} is faulted but the true or estimated lumped faults are missing')
        col = ids.index(uh)
        window = _step_window(step_time, info.onset + FAULT_WINDOW_DELAY, None, tolerance)
        entry = {'window': _window_bounds(step_time, window)}
        for v in vectors:
            entry[v.key] = _fault_estimation_entry(fault_data[v.estimate_array][window, col],
                                                   fault_data[v.true_array][window, col], v)
        out[f'uh{uh}'] = entry
    return out


def _false_fault_estimate(step_time, ids, faulted, fault_data, tolerance: float) -> dict:
    """``false_fault_estimate`` of docs/metrics.md: RMS of ``|Fhat|`` of every UH over
    ``[FALSE_ESTIMATE_START, end]`` if healthy, ``[FALSE_ESTIMATE_START, onset)`` if faulted (left
    out if empty), the maximum over the UHs and the thresholds it is checked against.
    """
    per_uh = {}
    for col, uh in enumerate(ids):
        end = faulted[uh].onset if uh in faulted else None
        window = _step_window(step_time, FALSE_ESTIMATE_START, end, tolerance)
        if not window.any():
            continue
        entry = {}
        for v in LUMPED_FAULTS:
            estimate = fault_data[v.estimate_array]
            rows = None if estimate is None else estimate[window, col]
            entry[v.key] = None if rows is None else rms_norm(rows[_finite_rows(rows)])
        entry['window'] = _window_bounds(step_time, window)
        per_uh[f'uh{uh}'] = entry
    largest = {v.key: max((e[v.key] for e in per_uh.values() if e[v.key] is not None), default=None)
               for v in LUMPED_FAULTS}
    return {**per_uh, 'max': largest, 'threshold': {v.key: v.false_estimate_threshold for v in LUMPED_FAULTS}}


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
    result['formation_rms_m'] = _none_if_nan(np.sqrt(np.nanmean(form[after] ** 2))) if after.any() else None
    result['mse_formation'] = _none_if_nan(np.nanmean(form ** 2))
    if n_fol:
        w = _shape('containment_weights', containment_weights, (n_fol, n_lead))
        cont = containment_errors(fol_pos, lead_pos, w)
        result['mse_containment'] = _none_if_nan(np.nanmean(cont ** 2))
        if after.any():
            result['containment_rms_m'] = _none_if_nan(np.sqrt(np.nanmean(cont[after] ** 2)))
            hull = hull_distance(fol_pos[after], lead_pos[after][:, None, :, :])
            result['hull_distance_max_m'] = _none_if_nan(np.nanmax(hull))
    # a step a real-time run did not record (NaN) contributes nothing: the CPI then slightly
    # underestimates; lockstep and in-process runs have every step
    result['cpi'] = _none_if_nan(dt * (np.nansum(z1 * z1) + np.nansum(u_p * u_p)))

    step_time = time[:steps]
    tolerance = 1e-9 * max(dt, 1.0)
    faulted = dict(sorted((faulted or {}).items()))
    unknown = [uh for uh in faulted if uh not in ids]
    if unknown:
        raise MetricsError(f'faulted UH {unknown[0]} is not one of the UHs {list(ids)}')
    given = {'fault_true_p': fault_true_p, 'fault_true_w': fault_true_w, 'fault_est_p': fault_est_p,
             'fault_est_w': fault_est_w}
    fault_data = {name: None if arr is None else _shape(name, arr, (steps, n, 3)) for name, arr in given.items()}
    estimation = _fault_estimation(step_time, ids, faulted, fault_data, tolerance)
    result['fault_estimation'] = estimation
    result['false_fault_estimate'] = _false_fault_estimate(step_time, ids, faulted, fault_data, tolerance)
    result['fault_nrmse'] = {uh: {v.symbol: entry[v.key]['nrmse'] for v in LUMPED_FAULTS if v.key in entry}
                             for uh, entry in estimation.items()}
    result['saturation_fraction'] = float(np.mean(saturated)) if saturated.size else 0.0
    return result


def _channel_faults(scenario, end: float) -> dict:
    """``{uh id: {channel: (onset, rho, bias_constant)}}`` of the faults of ``scenario.faults``
    whose onset is at or before ``end`` (s); the earliest fault of a channel counts.
    """
    out = {}
    for uh, specs in sorted(scenario.faults.items()):
        for spec in specs:
            get = (lambda k: spec[k]) if isinstance(spec, dict) else (lambda k: getattr(spec, k))
            onset, channel = float(get('onset_time')), int(get('channel'))
            if onset > end:
                continue
            known = out.setdefault(int(uh), {}).get(channel)
            if known is None or onset < known[0]:
                out[int(uh)][channel] = (onset, float(get('rho')), float(get('bias_constant')))
    return {uh: chans for uh, chans in out.items() if chans}


def fault_isolation_metrics(arrays, scenario, case: str) -> dict | None:
    """``fault_isolation`` of docs/metrics.md: the verdicts of the isolator every controller runs
    step by step (docs/faults.md#isolation-and-identification), scored against the scenario's
    faults. The verdicts are those the controllers published when ``arrays`` has an
    ``isolation`` entry for every UH (``uh_report.bag_metrics.read_team_bag``), else
    ``uh_controller_node.fault_isolation.isolate_run`` over the arrays (the same computation).

    Parameters
    ----------
    arrays : mapping
        :data:`ISOLATION_ARRAYS` in the layout of :func:`metrics_from_arrays`. Rows where any of
        them is not finite for any UH (a step a real-time run did not record) are left out.
    scenario : uh_topology.scenario.Scenario
    case : str
        Controller case (its gains give the learning phase).

    Returns
    -------
    dict or None
        ``{"uh<i>": {channel name: entry}}`` for every UH with a faulted or an isolated channel,
        entries with ``faulty``, ``onset`` (s or ``None``), ``isolated``, ``detected_at`` (s),
        ``delay`` (s after the onset; ``None`` unless faulty and isolated), ``rho``, ``bias`` (rad;
        ``None`` unless ``identifiable``), ``identifiable``, ``reason``, ``rho_true``,
        ``bias_constant_true`` (rad; 1 and 0 on a healthy channel); and ``"summary"``:
        ``false_isolations`` (isolated channels that are not faulty, healthy UHs included),
        ``missed`` (faulty channels never isolated), ``max_delay`` (s, ``None`` without an
        isolated faulty channel), ``source`` (``"status"`` or ``"recomputed"``). ``reason`` is the
        verdict's text (``IDENTIFICATION_TEXT``). ``None`` if an array is missing or does not fit
        the scenario. A fault counts as faulty from its onset, if that is within the run.
    """
    from uh_core.layout import CHANNEL_NAMES
    from uh_controller_node.fault_isolation import IDENTIFICATION_TEXT, isolate_run

    if any(key not in arrays for key in ISOLATION_ARRAYS):
        return None
    n = len(tuple(scenario.ids))
    data = {key: np.asarray(arrays[key], dtype=float) for key in ISOLATION_ARRAYS}
    rows = min(v.shape[0] for v in data.values())
    if rows < 2 or any(v.ndim < 2 or v.shape[1] != n for k, v in data.items() if k != 'time'):
        return None
    data = {key: v[:rows] for key, v in data.items()}
    keep = np.isfinite(data['time'])
    for key, v in data.items():
        if key != 'time':
            keep &= np.isfinite(v.reshape(rows, -1)).all(axis=1)
    if keep.sum() < 2:
        return None
    data = {key: v[keep] for key, v in data.items()}
    published = arrays.get('isolation') or {}
    if all(int(uh) in published for uh in scenario.ids):
        # what each controller published on its last status (a recorded run)
        source = 'status'
        verdicts = {int(uh): _published_verdicts(published[int(uh)], CHANNEL_NAMES) for uh in scenario.ids}
    else:
        # the same isolator, recomputed over the arrays (an in-process run)
        source = 'recomputed'
        isolation = isolate_run(data, scenario, case)
        verdicts = {}
        for uh in tuple(scenario.ids):
            verdicts[int(uh)] = {
                name: {'isolated': bool(r['isolated']), 'detection_time': r['detection_time'],
                       'rho': r['rho'], 'bias': r['bias'], 'identifiable': bool(r['identifiable']),
                       'reason': IDENTIFICATION_TEXT[r['identification']]}
                for name, r in isolation[f'uh{uh}']['channels'].items()}
    end = float(data['time'][-1]) + 1e-9 * max(float(scenario.dt), 1.0)
    truth = _channel_faults(scenario, end)
    out, false_isolations, missed, delays = {}, 0, 0, []
    for uh in tuple(scenario.ids):
        reports = verdicts[int(uh)]
        faults = truth.get(int(uh), {})
        if not faults and not any(r['isolated'] for r in reports.values()):
            continue
        entry = {}
        for c, name in enumerate(CHANNEL_NAMES):
            r = reports[name]
            onset, rho_true, bias_true = faults.get(c, (None, 1.0, 0.0))
            faulty = onset is not None
            delay = round(r['detection_time'] - onset, 9) if faulty and r['isolated'] else None
            false_isolations += int(r['isolated'] and not faulty)
            missed += int(faulty and not r['isolated'])
            if delay is not None:
                delays.append(delay)
            entry[name] = {'faulty': faulty, 'onset': onset, 'isolated': bool(r['isolated']),
                           'detected_at': r['detection_time'], 'delay': delay, 'rho': r['rho'],
                           'bias': r['bias'], 'identifiable': bool(r['identifiable']),
                           'reason': r['reason'], 'rho_true': rho_true, 'bias_constant_true': bias_true}
        out[f'uh{uh}'] = entry
    out['summary'] = {'false_isolations': false_isolations, 'missed': missed,
                      'max_delay': max(delays) if delays else None, 'source': source}
    return out


def _published_verdicts(published: dict, names) -> dict:
    """Per channel name, the verdict entries of :func:`fault_isolation_metrics` from the fault
    isolation fields of a controller's last ``ControllerStatus``
    (``uh_report.bag_metrics.read_team_bag``'s ``isolation``).
    """
    from uh_controller_node.fault_isolation import IDENTIFIABLE, IDENTIFICATION_TEXT

    def finite(value):
        return float(value) if math.isfinite(value) else None

    out = {}
    for c, name in enumerate(names):
        ok = published['identification'][c] == IDENTIFIABLE
        out[name] = {'isolated': bool(published['isolated'][c]),
                     'detection_time': finite(published['detection_time'][c]),
                     'rho': finite(published['effectiveness'][c]) if ok else None,
                     'bias': finite(published['bias'][c]) if ok else None,
                     'identifiable': ok,
                     'reason': IDENTIFICATION_TEXT.get(published['identification'][c], 'unknown verdict')}
    return out


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
        As :func:`compute_metrics`; z1 for the CPI comes from :func:`consensus_errors`, and
        ``fault_isolation`` from :func:`fault_isolation_metrics` (``None`` without ``commands``).
    """
    missing = [k for k in ('time', 'states', 'reference', 'u_p', 'saturated') if k not in arrays]
    if missing:
        raise MetricsError(f'run arrays lack {missing}')
    time = np.asarray(arrays['time'], dtype=float)
    steps = time.shape[0] - 1
    positions = np.asarray(arrays['states'], dtype=float)[..., 0:3]
    p0 = np.asarray(arrays['reference'], dtype=float)[:, 0:3]
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
        fault_est_w=per_step('fault_est_w'), faulted=faulted_uhs(scenario),
        settle_time=float(scenario.settle_time), wall_time=wall_time_s)
    result['fault_isolation'] = fault_isolation_metrics(arrays, scenario, case)
    return result
