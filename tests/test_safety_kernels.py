"""The safety filter's kernels (uh_controller_node.safety_kernels, docs/safety.md).

The solver is checked against quadprog (Goldfarb and Idnani's dual method) and scipy's NNLS on
thousands of random problems, and against the optimality (KKT) conditions where quadprog refuses a
degenerate one; the filter on random pair configurations: it keeps every barrier, stays inside the
tilt cone, and returns ``u_p`` itself, bit for bit, when ``u_p`` already keeps every barrier.
"""
import math

import numpy as np
import pytest
import quadprog
import scipy.optimize

from uh_controller_node import safety_kernels as sk

#: Round-off allowance of the solver's answers: the problems' data are O(1-10), so 1e-8 is ~1e7
#: times float64's epsilon and far below any physical meaning (m/s^2); a wrong active set is O(1).
TOL = 1e-8


def _random_polyhedron(rng, n=4):
    """Draw a non-empty ``{y: g y <= h}`` with 1-20 rows; about a third of the rows pass through a point of it."""
    m = int(rng.integers(1, 21))
    g = rng.normal(size=(m, n))
    inside = rng.normal(size=n) * 3.0
    h = g @ inside + rng.exponential(size=m) * (rng.random(m) < 0.7)
    return g, h


def _kkt_residual(g, h, y):
    """Largest violation of the optimality conditions of ``min |y|^2 / 2, g y <= h`` at ``y``.

    The multipliers are the NNLS fit of ``-y = g^T lam`` over the active rows (lam >= 0).
    """
    active = g @ y - h > -1e-7
    lam = scipy.optimize.nnls(g[active].T, -y)[0] if active.any() else np.zeros(0)
    stationarity = np.abs(y + g[active].T @ lam).max() if active.any() else np.abs(y).max()
    return max(stationarity, (g @ y - h).max(), 0.0)


def test_least_distance_agrees_with_quadprog_on_random_problems():
    rng = np.random.default_rng(20261126)
    compared = checked_by_kkt = 0
    for _ in range(4000):
        g, h = _random_polyhedron(rng)
        y = np.zeros(4)
        assert sk.least_distance(g, h, y)
        scale = 1.0 + np.abs(h).max()
        try:
            reference = quadprog.solve_qp(np.eye(4), np.zeros(4), -g.T, -h, 0)[0]
        except ValueError:          # quadprog refuses some degenerate problems (rows active at once)
            assert _kkt_residual(g, h, y) < TOL * scale
            checked_by_kkt += 1
            continue
        assert np.abs(y - reference).max() < TOL * scale
        compared += 1
    assert compared > 3500, 'quadprog answered too few of the problems for the comparison to mean much'
    assert checked_by_kkt >= 0


def test_least_distance_says_when_the_set_is_empty():
    g = np.array([[1.0, 0.0], [-1.0, 0.0]])
    h = np.array([-1.0, -1.0])          # x <= -1 and x >= 1
    y = np.full(2, 7.0)
    assert not sk.least_distance(g, h, y)
    assert np.all(y == 0.0)


def test_nnls_agrees_with_scipy():
    rng = np.random.default_rng(7)
    for _ in range(3000):
        rows, cols = int(rng.integers(2, 7)), int(rng.integers(1, 25))
        a, b = rng.normal(size=(rows, cols)), rng.normal(size=rows)
        x = np.empty(cols)
        sk.nnls(a, b, x)
        reference = scipy.optimize.nnls(a, b)[0]
        assert x.min() >= 0.0
        assert np.linalg.norm(a @ x - b) <= np.linalg.norm(a @ reference - b) + TOL


def _params(**changes):
    values = dict(min_separation=2.0, sensing_radius=12.0, barrier_gain=2.0, brake_accel=2.0, slack_weight=1e4,
                  sidestep_accel=0.5, drag_per_mass=0.1, gravity=9.81, tilt_limit=math.radians(30.0),
                  min_vertical_accel=2.0)
    values.update(changes)
    params = np.empty(sk.SAFETY_PARAMS_SIZE)
    for name, value in values.items():
        params[getattr(sk, 'SF_' + name.upper())] = value
    return params


def _barrier_margins(params, position, velocity, proximity, u):
    """``bound - demand`` of every pair within the sensing radius (>= 0: the barrier is kept)."""
    margins = []
    normal = np.empty(3)
    for row in proximity:
        bound, _, distance = sk.pair_barrier(params, position, velocity, row[:3], row[3:], normal)
        if distance <= params[sk.SF_SENSING_RADIUS]:
            margins.append(bound + normal @ (u - params[sk.SF_DRAG_PER_MASS] * velocity))
    return np.array(margins)


def test_the_filter_keeps_every_barrier_inside_the_tilt_cone_on_random_configurations():
    rng = np.random.default_rng(32)
    params = _params()
    cone = math.tan(params[sk.SF_TILT_LIMIT])
    active = 0
    for _ in range(3000):
        position, velocity = rng.normal(size=3) * 3.0, rng.normal(size=3) * 2.0
        others = int(rng.integers(0, 6))
        proximity = np.hstack([position + rng.normal(size=(others, 3)) * 4.0, rng.normal(size=(others, 3)) * 2.0])
        # pairs that can still stop apart: the barrier is feasible, so the slack must stay 0
        normal = np.empty(3)
        keep = [row for row in proximity
                if sk.pair_barrier(params, position, velocity, row[:3], row[3:], normal)[2] > 2.3]
        proximity = np.array(keep).reshape(-1, 6)
        u_p = rng.normal(size=3) * 3.0
        u, out = np.empty(3), np.empty(sk.SAFETY_OUT_SIZE)
        sk.safety_filter(params, position, velocity, u_p, proximity, u, out)
        if out[sk.SO_ACTIVE] == 0.0:
            assert np.array_equal(u, u_p)
            saturated = np.empty(3)
            sk._cone_saturated(params, u_p, saturated)
            assert (_barrier_margins(params, position, velocity, proximity, saturated) >= 0.0).all()
            continue
        active += 1
        margins = _barrier_margins(params, position, velocity, proximity, u)
        assert (margins >= -1e-6 - out[sk.SO_SLACK]).all()
        horizontal, vertical = math.hypot(u[0], u[1]), u[2] + params[sk.SF_GRAVITY]
        assert vertical >= params[sk.SF_MIN_VERTICAL_ACCEL] - 1e-9
        assert horizontal <= cone * vertical + 1e-9
    assert active > 300, 'too few draws needed the filter for the test to mean much'


def test_an_inactive_filter_returns_u_p_bit_for_bit_and_reports_the_closest():
    params = _params()
    proximity = np.array([[30.0, 0.0, 0.0, 0.0, 0.0, 0.0], [5.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    u_p = np.array([0.1234567891234, -0.3, 0.05])
    u, out = np.empty(3), np.empty(sk.SAFETY_OUT_SIZE)
    sk.safety_filter(params, np.zeros(3), np.zeros(3), u_p, proximity, u, out)
    assert out[sk.SO_ACTIVE] == 0.0 and np.array_equal(u, u_p)
    assert out[sk.SO_PAIRS] == 1                        # the first row is beyond the sensing radius
    assert out[sk.SO_CLOSEST_ROW] == 1 and out[sk.SO_CLOSEST_DISTANCE] == pytest.approx(5.0)


def test_a_head_on_push_is_turned_to_the_right():
    params = _params()
    # UH i at the origin, j 3 m ahead on +x, both still; u_p pushes i straight at j
    proximity = np.array([[3.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    u, out = np.empty(3), np.empty(sk.SAFETY_OUT_SIZE)
    sk.safety_filter(params, np.zeros(3), np.zeros(3), np.array([3.0, 0.0, 0.0]), proximity, u, out)
    assert out[sk.SO_ACTIVE] == 1.0
    assert u[1] < -0.4          # right of +x (z up) is -y: the sidestep, less nothing the barrier needs
    # j sees i from the other side and steps to its own right: the opposite side, so they pass
    mirrored = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    sk.safety_filter(params, np.array([3.0, 0.0, 0.0]), np.zeros(3), np.array([-3.0, 0.0, 0.0]), mirrored, u, out)
    assert u[1] > 0.4
