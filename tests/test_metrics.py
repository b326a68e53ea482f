"""Metrics of docs/metrics.md against closed-form cases."""
import math

import numpy as np
import pytest

from uh_team.metrics import (METRIC_KEYS, FaultedUH, MetricsError, compute_metrics,
                                        containment_errors, faulted_uhs, hull_distance,
                                        point_segment_distance, point_triangle_distance)

A, B, C = np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])


@pytest.mark.parametrize('p, expected', [
    ((0.2, 0.2, 0.3), 0.3),                 # above the interior: plane distance
    ((0.2, 0.2, -0.05), 0.05),              # below
    ((0.25, 0.25, 0.0), 0.0),               # inside, in plane
    ((2.0, 0.0, 0.0), 1.0),                 # beyond vertex B
    ((0.5, -1.0, 0.0), 1.0),                # beside edge AB
    ((1.0, 1.0, 1.0), math.sqrt(1.5)),      # beyond the hypotenuse, off plane: nearest (0.5, 0.5, 0)
    ((-1.0, -1.0, 0.0), math.sqrt(2.0)),    # beyond vertex A
])
def test_point_triangle_distance_closed_form(p, expected):
    assert point_triangle_distance(np.array(p), A, B, C) == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_point_triangle_distance_matches_dense_sampling():
    rng = np.random.default_rng(7)
    tri = rng.normal(size=(3, 3))
    points = rng.normal(scale=2.0, size=(50, 3))
    exact = point_triangle_distance(points, tri[0], tri[1], tri[2])
    # dense barycentric grid of the filled triangle
    n = 200
    u, v = np.meshgrid(np.arange(n + 1) / n, np.arange(n + 1) / n)
    keep = (u + v) <= 1.0
    grid = tri[0] + u[keep, None] * (tri[1] - tri[0]) + v[keep, None] * (tri[2] - tri[0])
    sampled = np.min(np.linalg.norm(points[:, None, :] - grid[None], axis=-1), axis=1)
    # exact distance is a lower bound; the grid misses the true nearest point by at most one cell
    cell = max(np.linalg.norm(tri[1] - tri[0]), np.linalg.norm(tri[2] - tri[0])) / n
    assert np.all(exact <= sampled + 1e-12)
    assert np.all(sampled - exact <= 2 * cell)


def test_degenerate_triangle_is_its_segment():
    a, b, c = np.zeros(3), np.array([1.0, 0, 0]), np.array([2.0, 0, 0])
    assert point_triangle_distance(np.array([1.0, 1.0, 0.0]), a, b, c) == pytest.approx(1.0)
    assert point_triangle_distance(np.array([3.0, 0.0, 0.0]), a, b, c) == pytest.approx(1.0)
    assert point_segment_distance(np.array([0.5, 2.0, 0.0]), a, a) == pytest.approx(math.hypot(0.5, 2.0))


def test_hull_distance_of_a_tetrahedron_and_fewer_vertices():
    verts = np.array([A, B, C, [0.0, 0.0, 1.0]])
    assert hull_distance(np.array([0.1, 0.1, 0.1]), verts) == 0.0                  # inside
    assert hull_distance(np.array([0.1, 0.1, -0.4]), verts) == pytest.approx(0.4)  # below face ABC
    # beyond the slanted face x + y + z = 1: plane distance (1.5 - 1) / sqrt(3)
    assert hull_distance(np.array([0.5, 0.5, 0.5]), verts) == pytest.approx(0.5 / math.sqrt(3))
    assert hull_distance(np.array([0.5, 2.0, 0.0]), verts[:2]) == pytest.approx(2.0)
    assert hull_distance(np.array([3.0, 4.0, 0.0]), verts[:1]) == pytest.approx(5.0)


def test_hull_of_five_coplanar_points_is_exact():
    # a pentagon in z = 0: any point above its interior is at its height, outside the nearest edge
    ang = 2 * np.pi * np.arange(5) / 5
    verts = np.stack([np.cos(ang), np.sin(ang), np.zeros(5)], axis=1)
    assert hull_distance(np.array([0.1, -0.2, 0.7]), verts) == pytest.approx(0.7)
    apothem = math.cos(math.pi / 5)
    mid = 0.5 * (verts[0] + verts[1])
    outside = mid / np.linalg.norm(mid) * (apothem + 0.3)
    assert hull_distance(outside, verts) == pytest.approx(0.3)


def test_containment_errors_closed_form():
    leaders = np.array([[[0.0, 0, 0], [3.0, 0, 0], [0.0, 3, 0]]])
    w = np.array([[0.4, 0.4, 0.2]])
    target = 0.4 * leaders[0, 0] + 0.4 * leaders[0, 1] + 0.2 * leaders[0, 2]
    fol = (target + np.array([0.0, 0.0, 0.25]))[None, None, :]
    assert containment_errors(fol, leaders, w)[0, 0] == pytest.approx(0.25)


class _Spec:
    def __init__(self, channel, onset):
        self.channel, self.onset_time = channel, onset


def test_faulted_uhs_from_scenario_faults():
    scenario = type('S', (), {'faults': {1: (), 2: (_Spec(2, 12.0), _Spec(0, 10.0)), 3: (_Spec(3, 10.0),),
                                         4: ({'channel': 0, 'onset_time': 4.0},)}})()
    assert faulted_uhs(scenario) == {2: FaultedUH(10.0, True), 3: FaultedUH(10.0, False),
                                     4: FaultedUH(4.0, True)}


def _team_run(K=400, dt=0.1):
    """Two leaders + one follower with chosen constant errors (closed-form metrics)."""
    time = np.arange(K + 1) * dt
    p0 = np.stack([time, np.zeros(K + 1), np.full(K + 1, 10.0)], axis=1)
    offsets = {1: np.array([0.0, 2.0, 0.0]), 2: np.array([0.0, -2.0, 0.0]), 3: np.array([2.0, 0.0, 0.0])}
    pos = np.zeros((K + 1, 4, 3))
    pos[:, 0] = p0 + offsets[1]
    pos[:, 1] = p0 + offsets[2]
    pos[:, 2] = p0 + offsets[3] + np.array([0.0, 0.0, 0.3])   # leader 3 formation error 0.3 m
    w = np.array([[0.25, 0.25, 0.5]])
    target = 0.25 * pos[:, 0] + 0.25 * pos[:, 1] + 0.5 * pos[:, 2]
    pos[:, 3] = target + np.array([0.0, 0.0, 0.04])            # follower 0.04 m above its target
    pos[time < 20.0, 3, 2] += 5.0                                  # large error before settling only
    return time, p0, offsets, pos, w


def test_compute_metrics_closed_form():
    K, dt = 400, 0.1
    time, p0, offsets, pos, w = _team_run(K, dt)
    z1 = np.zeros((K, 4, 3))
    z1[:, :, 0] = 0.5
    u_p = np.zeros((K, 4, 3))
    u_p[:, :, 2] = 1.0
    sat = np.zeros((K, 4), dtype=bool)
    sat[:40, 3] = True
    f_true_p = np.zeros((K, 4, 3))
    f_true_w = np.zeros((K, 4, 3))
    f_true_p[:, 1, 2] = -2.0
    f_true_w[:, 1] = [1.0, 0.0, 0.0]
    f_est_p = 0.8 * f_true_p                    # 20 % error
    f_est_w = f_true_w + [0.0, 0.5, 0.0]        # error 0.5 against |F| = 1
    f_est_w[:150, 1] = 99.0                     # garbage before onset + 5 s must be ignored
    m = compute_metrics(case='proposed', time=time, positions=pos, reference_positions=p0,
                        leaders=(1, 2, 3), followers=(4,), offsets=offsets, containment_weights=w,
                        z1=z1, u_p=u_p, saturated=sat, fault_true_p=f_true_p, fault_true_w=f_true_w,
                        fault_est_p=f_est_p, fault_est_w=f_est_w,
                        faulted={2: FaultedUH(10.0, True)}, wall_time=1.5)
    assert tuple(m) == METRIC_KEYS
    assert m['case'] == 'proposed' and m['wall_time_s'] == 1.5 and m['settle_time_s'] == 20.0
    assert m['sim_time_s'] == pytest.approx(K * dt)
    # one of three leaders off by 0.3 m: RMS sqrt(0.09 / 3), MSE 0.09 / 3 over the whole run
    assert m['formation_rms_m'] == pytest.approx(math.sqrt(0.03))
    assert m['mse_formation'] == pytest.approx(0.03)
    assert m['containment_rms_m'] == pytest.approx(0.04)
    # leaders all at z = z0 except leader 3 at +0.3: the triangle tilts; the follower sits at
    # 0.04 m above a point of the triangle, so its distance to the tilted plane is 0.04 cos(tilt)
    tri = pos[-1, :3]
    n = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    expected_hull = abs(np.dot(n / np.linalg.norm(n), pos[-1, 3] - tri[0]))
    assert m['hull_distance_max_m'] == pytest.approx(expected_hull, rel=1e-9)
    assert expected_hull < 0.04
    before = time < 20.0
    mse_c = (np.sum(before) * (5.04 ** 2) + np.sum(~before) * 0.04 ** 2) / (K + 1)
    assert m['mse_containment'] == pytest.approx(mse_c)
    # CPI: integral over K steps of 4 UHs x (0.25 + 1.0)
    assert m['cpi'] == pytest.approx(K * dt * 4 * 1.25)
    assert m['fault_nrmse'] == {'uh2': {'F_p': pytest.approx(0.2), 'F_w': pytest.approx(0.5)}}
    assert m['saturation_fraction'] == pytest.approx(40 / (4 * K))


def test_fault_nrmse_skips_f_p_without_a_collective_fault_and_reports_undefined_as_none():
    K, dt = 400, 0.1
    time, p0, offsets, pos, w = _team_run(K, dt)
    zeros = np.zeros((K, 4, 3))
    m = compute_metrics(case='case1', time=time, positions=pos, reference_positions=p0,
                        leaders=(1, 2, 3), followers=(4,), offsets=offsets, containment_weights=w,
                        z1=zeros, u_p=zeros, saturated=np.zeros((K, 4), bool),
                        fault_true_w=zeros, fault_est_w=zeros, faulted={3: FaultedUH(10.0, False)})
    assert m['fault_nrmse'] == {'uh3': {'F_w': None}}    # a zero true fault has no NRMSE


def test_shape_errors_name_the_array():
    K, dt = 10, 0.1
    time, p0, offsets, pos, w = _team_run(K, dt)
    with pytest.raises(MetricsError, match=r'z1 must have shape \(10, 4, 3\), got \(9, 4, 3\)'):
        compute_metrics(case='x', time=time, positions=pos, reference_positions=p0, leaders=(1, 2, 3),
                        followers=(4,), offsets=offsets, containment_weights=w,
                        z1=np.zeros((9, 4, 3)), u_p=np.zeros((10, 4, 3)), saturated=np.zeros((10, 4), bool))
    with pytest.raises(MetricsError, match='UH 2 is faulted but the true or estimated lumped faults are missing'):
        compute_metrics(case='x', time=time, positions=pos, reference_positions=p0, leaders=(1, 2, 3),
                        followers=(4,), offsets=offsets, containment_weights=w,
                        z1=np.zeros((10, 4, 3)), u_p=np.zeros((10, 4, 3)),
                        saturated=np.zeros((10, 4), bool), faulted={2: FaultedUH(1.0, False)})


def test_hull_distance_is_zero_for_every_convex_combination():
    rng = np.random.default_rng(3)
    verts = rng.normal(size=(3, 3))
    for wts in rng.dirichlet(np.ones(3), size=20):
        assert hull_distance(wts @ verts, verts) < 1e-12
