"""The safety filter: the smallest change of the outer loop's ``u_p`` that keeps helicopters apart.

A layer outside the control law (docs/safety.md). It takes the law's designed acceleration ``u_p``
(m/s^2, inertial frame, z up; docs/control_law.md#outer-loop), the UH's own position and velocity,
and the positions and velocities of the UHs its proximity input reports (within the sensing radius),
and returns the acceleration closest to ``u_p`` that satisfies, for every reported UH j:

* **the pair barrier** (docs/safety.md#the-barrier). With ``dp = p_i - p_j``, ``d = |dp|``,
  ``n = dp / d``, ``dv = v_i - v_j``, ``D_s`` the minimum separation and ``A = 2 a_b`` the braking
  acceleration of the pair (each UH brakes with ``a_b``)::

      h   = sqrt(2 A (d - D_s)) + n.dv            (m/s; h >= 0: the pair can still stop apart)
      h'  = n.(a_i - a_j) + (|dv|^2 - (n.dv)^2) / d + A (n.dv) / sqrt(2 A (d - D_s))
      h' >= -gamma h                                (exponential barrier, gamma = barrier_gain, 1/s)

  The pair shares the constraint (Wang, Ames and Egerstedt's decentralised barrier certificates):
  UH i takes half, ``-n.a_i <= b / 2`` with ``b = gamma h + (|dv|^2 - (n.dv)^2) / d + A (n.dv) /
  sqrt(2 A (d - D_s))``, and UH j the other half from its side. ``a_i = u + f_nom(v_i)``, the
  designed acceleration plus the known drag ``f_nom(v) = -(D_v,nom / m) v``.
* **the tilt cone**, as an inscribed polygon: the horizontal part of ``a = u + g e3`` at most
  ``tan(tilt_limit) cos(pi / K) a_z`` along each of K directions, and ``a_z >= min_vertical_accel``,
  so that the attitude extraction realises the filtered acceleration without scaling it.

The pair constraints carry one slack ``s >= 0`` with cost ``slack_weight s^2``, so the problem is
always feasible: when no acceleration keeps every barrier, the filter brakes as hard as the cone
allows. The quadratic programme

    minimise |u - u_nom|^2 + slack_weight s^2   subject to   G [u; s] <= g

is a least-distance programme, solved exactly by Lawson and Hanson's NNLS (*Solving Least Squares
Problems*, 1974, ch. 23; :func:`least_distance`): finite, no tolerance on the answer beyond round-off.

When ``u_p``, saturated by the cone as the attitude extraction would, keeps every barrier, the filter
returns ``u_p`` itself, bit for bit (it is *inactive*). Otherwise, for each pair whose barrier ``u_p``
breaks and that ``u_p`` pushes straight at (within ``HEAD_ON_COS``), a sidestep of ``sidestep_accel``
to the right of the line to j is added to the nominal: the two UHs of a head-on pair step to opposite
sides and pass, where the projection alone would stop them nose to nose (docs/safety.md#deadlocks).
"""
from __future__ import annotations

import math
import time

import numpy as np

from uh_core import compiled_kernels as _compiled_kernels
from uh_core import kernel_cache as _kernel_cache
from uh_core.compiled_kernels import njit

from . import impairments as _impairments
from .impairments import hash_uniform

__all__ = ['SF_MIN_SEPARATION', 'SF_SENSING_RADIUS', 'SF_BARRIER_GAIN', 'SF_BRAKE_ACCEL', 'SF_SLACK_WEIGHT',
           'SF_SIDESTEP_ACCEL', 'SF_DRAG_PER_MASS', 'SF_GRAVITY', 'SF_TILT_LIMIT', 'SF_MIN_VERTICAL_ACCEL',
           'SAFETY_PARAMS_SIZE', 'PROXIMITY_COLUMNS', 'CONE_SIDES', 'HEAD_ON_COS', 'SO_ACTIVE', 'SO_SLACK',
           'SO_CLOSEST_DISTANCE', 'SO_CLOSEST_ROW', 'SO_PAIRS', 'SAFETY_OUT_SIZE', 'nnls', 'least_distance',
           'pair_barrier', 'safety_filter', 'proximity_rows', 'compile_safety_kernels', 'SF_PROXIMITY_DELAY',
           'SF_PROXIMITY_LOSS', 'SF_PROXIMITY_NOISE_P', 'SF_PROXIMITY_NOISE_V', 'SF_PROXIMITY_SEED',
           'PROXIMITY_STREAM', 'proximity_lost', 'degrade_proximity']

# the filter's parameter vector (uh_controller_node.safety.safety_parameters builds it)
SF_MIN_SEPARATION = 0        # D_s, hub to hub, m
SF_SENSING_RADIUS = 1        # the proximity input reports UHs within this distance, m
SF_BARRIER_GAIN = 2          # gamma, 1/s
SF_BRAKE_ACCEL = 3           # a_b, the deceleration each UH of a pair is assumed to give, m/s^2
SF_SLACK_WEIGHT = 4          # weight of the squared slack, (m/s^2)^-2 relative to |u - u_nom|^2
SF_SIDESTEP_ACCEL = 5        # the head-on sidestep, m/s^2
SF_DRAG_PER_MASS = 6         # D_v,nom / m, 1/s
SF_GRAVITY = 7               # g, m/s^2
SF_TILT_LIMIT = 8            # rad
SF_MIN_VERTICAL_ACCEL = 9    # m/s^2
SF_PROXIMITY_DELAY = 10      # steps the proximity input arrives late (a whole number)
SF_PROXIMITY_LOSS = 11       # probability that a step's proximity input is lost
SF_PROXIMITY_NOISE_P = 12    # standard deviation of the noise on a reported position, m
SF_PROXIMITY_NOISE_V = 13    # ... on a reported velocity, m/s
SF_PROXIMITY_SEED = 14       # seed of the losses and the noise (a whole number)
SAFETY_PARAMS_SIZE = 15

#: First hash stream of the proximity input's impairments (loss; noise: the next 12), clear of the links' streams.
PROXIMITY_STREAM = 1000

#: Columns of a proximity row: ``[p (3), v (3)]`` of a reported UH, m and m/s, inertial frame.
PROXIMITY_COLUMNS = 6
#: Sides of the polygon inscribed in the tilt cone.
CONE_SIDES = 8
#: Cosine of the largest angle between ``u_p`` and the line to j that counts as pushing straight at j.
HEAD_ON_COS = math.cos(math.radians(20.0))
#: Smallest ``d - D_s`` the barrier's square root is taken of, m (keeps it finite inside D_s).
_GAP_FLOOR = 1e-3

# the filter's outputs
SO_ACTIVE = 0                # 1.0 when the filter changed u_p, else 0.0
SO_SLACK = 1                 # the slack s of the solution (0: every barrier kept), m/s^2
SO_CLOSEST_DISTANCE = 2      # distance to the closest reported UH (inf: none), m
SO_CLOSEST_ROW = 3           # its row in the proximity input (-1: none)
SO_PAIRS = 4                 # number of reported UHs within the sensing radius
SAFETY_OUT_SIZE = 5

_NNLS_TOL = 1e-12


@njit(cache=True)
def _solve_passive(a, b, passive, n_passive, out):
    """Least squares on the passive columns of ``a``: ``out[passive] = argmin |a_P z - b|``, else 0.

    Householder QR of the ``rows x n_passive`` submatrix (``n_passive <= rows``: the columns NNLS
    keeps passive are independent).
    """
    rows = a.shape[0]
    q = np.empty((rows, n_passive))
    for k in range(n_passive):
        for r in range(rows):
            q[r, k] = a[r, passive[k]]
    rhs = b.copy()
    for k in range(n_passive):
        norm = 0.0
        for r in range(k, rows):
            norm += q[r, k] * q[r, k]
        norm = math.sqrt(norm)
        if norm == 0.0:
            continue
        alpha = -norm if q[k, k] >= 0.0 else norm
        v0 = q[k, k] - alpha
        vnorm2 = v0 * v0
        for r in range(k + 1, rows):
            vnorm2 += q[r, k] * q[r, k]
        if vnorm2 == 0.0:
            continue
        for c in range(k, n_passive):
            dot = v0 * q[k, c]
            for r in range(k + 1, rows):
                dot += q[r, k] * q[r, c]
            f = 2.0 * dot / vnorm2
            q[k, c] -= f * v0
            for r in range(k + 1, rows):
                if c != k:
                    q[r, c] -= f * q[r, k]
        dot = v0 * rhs[k]
        for r in range(k + 1, rows):
            dot += q[r, k] * rhs[r]
        f = 2.0 * dot / vnorm2
        rhs[k] -= f * v0
        for r in range(k + 1, rows):
            rhs[r] -= f * q[r, k]
        q[k, k] = alpha
        for r in range(k + 1, rows):
            q[r, k] = 0.0
    z = np.zeros(n_passive)
    for k in range(n_passive - 1, -1, -1):
        acc = rhs[k]
        for c in range(k + 1, n_passive):
            acc -= q[k, c] * z[c]
        z[k] = acc / q[k, k] if q[k, k] != 0.0 else 0.0
    out[:] = 0.0
    for k in range(n_passive):
        out[passive[k]] = z[k]


@njit(cache=True)
def _independent(a, column, passive, n_passive, scratch):
    """Whether column ``column`` of ``a`` is independent of the passive columns (to 1e-9 of its norm)."""
    if n_passive >= a.shape[0]:
        return False
    target = a[:, column].copy()
    _solve_passive(a, target, passive, n_passive, scratch)
    norm = 0.0
    left = 0.0
    for r in range(a.shape[0]):
        acc = target[r]
        for k in range(n_passive):
            acc -= a[r, passive[k]] * scratch[passive[k]]
        left += acc * acc
        norm += target[r] * target[r]
    return left > 1e-18 * norm


@njit(cache=True)
def _enter(a, b, w, passive, n_passive, in_passive, s, scratch):
    """Add to the passive set the column of largest ``w > 0`` that is independent and enters positive.

    Lawson and Hanson's safeguards: a column (nearly) in the span of the passive ones, or whose
    least-squares coefficient is not positive, is passed over for this step. Returns the new count,
    ``n_passive`` itself when no column enters (then NNLS is done); ``s`` holds the least-squares
    solution on the new passive set.
    """
    cols = a.shape[1]
    skipped = np.zeros(cols, np.bool_)
    while True:
        best, best_w = -1, _NNLS_TOL
        for c in range(cols):
            if not in_passive[c] and not skipped[c] and w[c] > best_w:
                best, best_w = c, w[c]
        if best < 0:
            return n_passive
        skipped[best] = True
        if not _independent(a, best, passive, n_passive, scratch):
            continue
        passive[n_passive] = best
        _solve_passive(a, b, passive, n_passive + 1, s)
        if s[best] > 0.0:
            in_passive[best] = True
            return n_passive + 1


@njit(cache=True)
def nnls(a, b, x):
    """Non-negative least squares, Lawson and Hanson's active-set method: ``x = argmin |a x - b|, x >= 0``.

    Parameters
    ----------
    a : ndarray (rows, cols)
    b : ndarray (rows,)
    x : ndarray (cols,)
        Output.

    Returns
    -------
    int
        Least-squares solves of the inner loop; at most ``3 cols`` are run.
    """
    rows, cols = a.shape
    x[:] = 0.0
    passive = np.empty(cols, np.int64)
    in_passive = np.zeros(cols, np.bool_)
    n_passive = 0
    s, scratch, w = np.zeros(cols), np.zeros(cols), np.empty(cols)
    residual = b.copy()
    iterations = 0
    while iterations < 3 * cols:
        for c in range(cols):          # w = a^T (b - a x), the negative gradient
            acc = 0.0
            for r in range(rows):
                acc += a[r, c] * residual[r]
            w[c] = acc
        entered = _enter(a, b, w, passive, n_passive, in_passive, s, scratch)
        if entered == n_passive:
            break
        n_passive = entered
        while True:                    # s is the least-squares solution on the passive set
            iterations += 1
            step = 1.0
            for k in range(n_passive):
                c = passive[k]
                if s[c] <= 0.0:
                    step = min(step, x[c] / (x[c] - s[c]))
            if step >= 1.0:
                break
            for k in range(n_passive):
                c = passive[k]
                x[c] += step * (s[c] - x[c])
            kept = 0                   # columns whose x reached zero leave the passive set
            for k in range(n_passive):
                c = passive[k]
                if x[c] > _NNLS_TOL:
                    passive[kept] = c
                    kept += 1
                else:
                    x[c] = 0.0
                    in_passive[c] = False
            n_passive = kept
            if n_passive == 0 or iterations >= 3 * cols:
                break
            _solve_passive(a, b, passive, n_passive, s)
        for k in range(n_passive):
            x[passive[k]] = s[passive[k]]
        for r in range(rows):
            acc = b[r]
            for c in range(cols):
                acc -= a[r, c] * x[c]
            residual[r] = acc
    return iterations


@njit(cache=True)
def least_distance(g, h, y):
    """Find the point of ``{y: g y <= h}`` nearest the origin, by NNLS (Lawson and Hanson, ch. 23).

    Parameters
    ----------
    g : ndarray (m, n)
    h : ndarray (m,)
    y : ndarray (n,)
        Output: the nearest point; zeros when the set is empty.

    Returns
    -------
    bool
        Whether the set is non-empty.
    """
    m, n = g.shape
    # min |y| s.t. e y >= f with e = -g, f = -h: nnls of [e^T; f^T] u ~ [0, ..., 0, 1]
    a = np.empty((n + 1, m))
    for r in range(m):
        for c in range(n):
            a[c, r] = -g[r, c]
        a[n, r] = -h[r]
    b = np.zeros(n + 1)
    b[n] = 1.0
    u = np.empty(m)
    nnls(a, b, u)
    last = -1.0
    for r in range(m):
        last += a[n, r] * u[r]
    if abs(last) < 1e-12:
        y[:] = 0.0
        return False
    for c in range(n):
        acc = 0.0
        for r in range(m):
            acc += a[c, r] * u[r]
        y[c] = -acc / last
    return True


@njit(cache=True)
def pair_barrier(params, position, velocity, other_position, other_velocity, normal):
    """UH i's half of the barrier of the pair (i, j): ``-normal . a_i <= bound`` (module doc).

    Parameters
    ----------
    params : ndarray (SAFETY_PARAMS_SIZE,)
    position, velocity, other_position, other_velocity : ndarray (3,)
        p_i, v_i, p_j, v_j; m, m/s.
    normal : ndarray (3,)
        Output: ``n = (p_i - p_j) / d``.

    Returns
    -------
    (float, float, float)
        ``bound`` (m/s^2), ``h`` (m/s), ``d`` (m).
    """
    d2 = 0.0
    for a in range(3):
        normal[a] = position[a] - other_position[a]
        d2 += normal[a] * normal[a]
    distance = math.sqrt(d2)
    if distance == 0.0:                # coincident: any direction is away; take +x
        normal[:] = 0.0
        normal[0] = 1.0
    else:
        for a in range(3):
            normal[a] /= distance
    closing = 0.0
    speed2 = 0.0
    for a in range(3):
        dv = velocity[a] - other_velocity[a]
        closing += normal[a] * dv
        speed2 += dv * dv
    brake = 2.0 * params[SF_BRAKE_ACCEL]
    root = math.sqrt(2.0 * brake * max(distance - params[SF_MIN_SEPARATION], _GAP_FLOOR))
    barrier = root + closing
    curvature = (speed2 - closing * closing) / max(distance, _GAP_FLOOR)
    bound = params[SF_BARRIER_GAIN] * barrier + curvature + brake * closing / root
    return 0.5 * bound, barrier, distance


@njit(cache=True)
def _cone_saturated(params, u_p, out):
    """``u_p`` after the attitude extraction's limits: ``a_z >= min_vertical_accel``, tilt <= tilt_limit."""
    g = params[SF_GRAVITY]
    az = max(u_p[2] + g, params[SF_MIN_VERTICAL_ACCEL])
    horizontal = math.sqrt(u_p[0] * u_p[0] + u_p[1] * u_p[1])
    largest = az * math.tan(params[SF_TILT_LIMIT])
    scale = largest / horizontal if horizontal > largest else 1.0
    out[0] = u_p[0] * scale
    out[1] = u_p[1] * scale
    out[2] = az - g


@njit(cache=True)
def _constraints(params, velocity, nominal, normals, bounds, n_pairs, g, h):
    """Fill ``g y <= h`` for ``y = [u - nominal, sqrt(slack_weight) s]`` (module doc); return the rows used."""
    root_weight = math.sqrt(params[SF_SLACK_WEIGHT])
    drag = params[SF_DRAG_PER_MASS]
    rows = 0
    for k in range(n_pairs):           # -n.(u + f_nom(v)) - s <= bound
        rhs = bounds[k]
        for a in range(3):
            g[rows, a] = -normals[k, a]
            rhs += normals[k, a] * (nominal[a] - drag * velocity[a])
        g[rows, 3] = -1.0 / root_weight
        h[rows] = rhs
        rows += 1
    gravity = params[SF_GRAVITY]
    side = math.tan(params[SF_TILT_LIMIT]) * math.cos(math.pi / CONE_SIDES)
    for k in range(CONE_SIDES):        # c_k.u_xy - side u_z <= side g
        angle = 2.0 * math.pi * k / CONE_SIDES
        cx, cy = math.cos(angle), math.sin(angle)
        g[rows, 0], g[rows, 1], g[rows, 2], g[rows, 3] = cx, cy, -side, 0.0
        h[rows] = side * gravity - cx * nominal[0] - cy * nominal[1] + side * nominal[2]
        rows += 1
    g[rows, 0], g[rows, 1], g[rows, 2], g[rows, 3] = 0.0, 0.0, -1.0, 0.0   # u_z + g >= min_vertical_accel
    h[rows] = gravity - params[SF_MIN_VERTICAL_ACCEL] + nominal[2]
    rows += 1
    g[rows, 0], g[rows, 1], g[rows, 2], g[rows, 3] = 0.0, 0.0, 0.0, -1.0   # s >= 0
    h[rows] = 0.0
    return rows + 1


@njit(cache=True)
def safety_filter(params, position, velocity, u_p, proximity, u, out):
    """Filter one UH's designed acceleration (module doc).

    Parameters
    ----------
    params : ndarray (SAFETY_PARAMS_SIZE,)
    position, velocity : ndarray (3,)
        The UH's own p (m) and v (m/s), inertial frame.
    u_p : ndarray (3,)
        The law's designed acceleration, m/s^2.
    proximity : ndarray (n, PROXIMITY_COLUMNS)
        ``[p, v]`` of the UHs the proximity input reports (rows beyond the sensing radius are ignored).
    u : ndarray (3,)
        Output: the filtered acceleration, m/s^2 (``u_p`` itself when the filter is inactive).
    out : ndarray (SAFETY_OUT_SIZE,)
        Output: ``SO_*``.
    """
    n_rows = proximity.shape[0]
    normals = np.empty((max(n_rows, 1), 3))
    bounds = np.empty(max(n_rows, 1))
    pushes = np.zeros(max(n_rows, 1), np.bool_)
    saturated = np.empty(3)
    _cone_saturated(params, u_p, saturated)
    drag = params[SF_DRAG_PER_MASS]
    n_pairs, broken = 0, False
    closest, closest_row = math.inf, -1
    for r in range(n_rows):
        bound, _, distance = pair_barrier(params, position, velocity, proximity[r, 0:3], proximity[r, 3:6],
                                          normals[n_pairs])
        if distance > params[SF_SENSING_RADIUS]:
            continue
        if distance < closest:
            closest, closest_row = distance, r
        demand = 0.0                   # -n.(u_sat + f_nom(v))
        for a in range(3):
            demand -= normals[n_pairs, a] * (saturated[a] - drag * velocity[a])
        bounds[n_pairs] = bound
        if demand > bound:
            broken = True
            norm = math.sqrt(u_p[0] * u_p[0] + u_p[1] * u_p[1] + u_p[2] * u_p[2])
            pushes[n_pairs] = norm > 0.0 and \
                -(normals[n_pairs, 0] * u_p[0] + normals[n_pairs, 1] * u_p[1]
                  + normals[n_pairs, 2] * u_p[2]) >= HEAD_ON_COS * norm
        n_pairs += 1
    out[SO_CLOSEST_DISTANCE] = closest
    out[SO_CLOSEST_ROW] = closest_row
    out[SO_PAIRS] = n_pairs
    if not broken:
        u[:] = u_p
        out[SO_ACTIVE] = 0.0
        out[SO_SLACK] = 0.0
        return
    nominal = u_p.copy()
    for k in range(n_pairs):           # head-on: step right of the line to j (docs/safety.md#deadlocks)
        if pushes[k]:
            horizontal = math.sqrt(normals[k, 0] ** 2 + normals[k, 1] ** 2)
            if horizontal > 0.0:
                nominal[0] += params[SF_SIDESTEP_ACCEL] * (-normals[k, 1]) / horizontal
                nominal[1] += params[SF_SIDESTEP_ACCEL] * normals[k, 0] / horizontal
    g = np.empty((n_pairs + CONE_SIDES + 2, 4))
    h = np.empty(n_pairs + CONE_SIDES + 2)
    _constraints(params, velocity, nominal, normals, bounds, n_pairs, g, h)
    y = np.empty(4)
    least_distance(g, h, y)
    for a in range(3):
        u[a] = nominal[a] + y[a]
    out[SO_ACTIVE] = 1.0
    out[SO_SLACK] = y[3] / math.sqrt(params[SF_SLACK_WEIGHT])


@njit(cache=True)
def proximity_rows(positions, velocities, own, sensing_radius, out, senders):
    """Write the proximity input of UH ``own``: ``[p, v]`` of every other UH within ``sensing_radius``.

    What a UH's sensing reports (docs/safety.md#what-the-filter-knows): the plant side knows every
    UH's true state. Rows follow the order of ``positions``.

    Parameters
    ----------
    positions, velocities : ndarray (n, 3)
        Every UH's p (m) and v (m/s), inertial frame.
    own : int
        Row of the UH the input is for (left out).
    sensing_radius : float
        m.
    out : ndarray (>= n - 1, PROXIMITY_COLUMNS)
        Output rows.
    senders : ndarray (>= n - 1,) int64
        Output: the row of ``positions`` each output row is of.

    Returns
    -------
    int
        Rows written.
    """
    rows = 0
    for j in range(positions.shape[0]):
        if j == own:
            continue
        d2 = 0.0
        for a in range(3):
            diff = positions[j, a] - positions[own, a]
            d2 += diff * diff
        if math.sqrt(d2) <= sensing_radius:
            for a in range(3):
                out[rows, a] = positions[j, a]
                out[rows, 3 + a] = velocities[j, a]
            senders[rows] = j
            rows += 1
    return rows


@njit(cache=True)
def proximity_lost(params, receiver, step):
    """Whether UH ``receiver``'s proximity input of ``step`` is lost (docs/safety.md#degraded-sensing).

    A pure function of ``(proximity_seed, receiver, step)``, so every engine loses the same steps;
    the input of step 0 is never lost.
    """
    loss = params[SF_PROXIMITY_LOSS]
    if loss <= 0.0 or step == 0:
        return False
    return hash_uniform(int(params[SF_PROXIMITY_SEED]), receiver, 0, step, PROXIMITY_STREAM) < loss


@njit(cache=True)
def degrade_proximity(rows, count, sender_ids, receiver, sent_step, step, dt, params):
    """Add the noise to the first ``count`` proximity rows of ``sent_step``, then predict them to ``step``.

    In place (docs/safety.md#degraded-sensing). The noise of a reported UH is keyed by
    ``(proximity_seed, receiver, its id, sent_step)`` (Box-Muller on two hashed uniforms per
    component), so a kept input keeps its noise; each position is then moved by its (noisy)
    velocity over ``(step - sent_step) dt`` s. Nothing changes without noise and for the current step.
    """
    sigma_p, sigma_v = params[SF_PROXIMITY_NOISE_P], params[SF_PROXIMITY_NOISE_V]
    seed = int(params[SF_PROXIMITY_SEED])
    for r in range(count):
        for c in range(PROXIMITY_COLUMNS):
            sigma = sigma_p if c < 3 else sigma_v
            if sigma > 0.0:
                u1 = hash_uniform(seed, receiver, sender_ids[r], sent_step, PROXIMITY_STREAM + 1 + 2 * c)
                u2 = hash_uniform(seed, receiver, sender_ids[r], sent_step, PROXIMITY_STREAM + 2 + 2 * c)
                rows[r, c] += sigma * math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
        if step > sent_step:
            age = (step - sent_step) * dt
            for a in range(3):
                rows[r, a] += rows[r, 3 + a] * age


def compile_safety_kernels() -> float:
    """Compile (or load from numba's cache) the filter's kernels for the signatures it uses; seconds spent."""
    start = time.perf_counter()
    params = np.ones(SAFETY_PARAMS_SIZE)
    three = np.zeros(3)
    safety_filter(params, three, three, three, np.zeros((2, PROXIMITY_COLUMNS)), np.zeros(3),
                  np.zeros(SAFETY_OUT_SIZE))
    least_distance(np.zeros((2, 4)), np.zeros(2), np.zeros(4))
    nnls(np.zeros((2, 3)), np.zeros(2), np.zeros(3))
    pair_barrier(params, three, three, three, three, np.zeros(3))
    proximity_rows(np.zeros((2, 3)), np.zeros((2, 3)), 0, 1.0, np.zeros((1, PROXIMITY_COLUMNS)),
                   np.zeros(1, dtype=np.int64))
    proximity_lost(params, 1, 2)
    degrade_proximity(np.zeros((1, PROXIMITY_COLUMNS)), 1, np.ones(1, dtype=np.int64), 2, 3, 4, 0.01, params)
    return time.perf_counter() - start


# numba caches each kernel by this file only: empty the cache when the hash it calls changes
_kernel_cache.refresh_cache(_kernel_cache.module_dispatchers(globals()), [_impairments.__file__])


# run the ahead-of-time compiled kernels instead where this process asks for them (docs/performance.md#memory)
_compiled_kernels.install(globals())
