"""Metrics of docs/metrics.md against closed-form cases."""
import math

import numpy as np
import pytest

from uh_team.metrics import (
    FALSE_ESTIMATE_START,
    FALSE_ESTIMATE_THRESHOLD_P,
    FALSE_ESTIMATE_THRESHOLD_W,
    FAULT_WINDOW_DELAY,
    METRIC_KEYS,
    NRMSE_FLOOR_P,
    NRMSE_FLOOR_W,
    NRMSE_TARGET,
    FaultedUH,
    MetricsError,
    compute_metrics,
    containment_errors,
    faulted_uhs,
    hull_distance,
    nrmse_below_floor,
    point_segment_distance,
    point_triangle_distance,
)

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
    assert m['fault_estimation']['uh3'].keys() == {'window', 'w'}
    assert nrmse_below_floor(m['fault_estimation']['uh3']['w'])


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


# ----------------------------------------------------------------------------------------------
# fault estimation metrics against hand-computed series (docs/metrics.md)
# ----------------------------------------------------------------------------------------------
K_FAULT, DT_FAULT = 400, 0.1        # 40 s run: steps t_k = 0.0 .. 39.9 s
STEP_TIME = np.arange(K_FAULT) * DT_FAULT


def _fault_metrics(faulted, est_p=None, est_w=None, true_p=None, true_w=None):
    """Run compute_metrics on the 4-UH team of :func:`_team_run` with the given lumped-fault arrays (K, 4, 3).

    UHs 1, 2, 3 are leaders, 4 a follower; the arrays not given are zero.
    """
    time, p0, offsets, pos, w = _team_run(K_FAULT, DT_FAULT)
    arrays = [np.zeros((K_FAULT, 4, 3)) if a is None else a for a in (est_p, est_w, true_p, true_w)]
    zeros = np.zeros((K_FAULT, 4, 3))
    return compute_metrics(case='proposed', time=time, positions=pos, reference_positions=p0,
                           leaders=(1, 2, 3), followers=(4,), offsets=offsets, containment_weights=w,
                           z1=zeros, u_p=zeros, saturated=np.zeros((K_FAULT, 4), bool),
                           fault_est_p=arrays[0], fault_est_w=arrays[1], fault_true_p=arrays[2],
                           fault_true_w=arrays[3], faulted=faulted)


def test_floors_follow_from_the_false_estimate_thresholds_and_the_nrmse_target():
    assert (FALSE_ESTIMATE_THRESHOLD_P, FALSE_ESTIMATE_THRESHOLD_W, NRMSE_TARGET) == (0.05, 0.1, 0.25)
    assert NRMSE_FLOOR_P == pytest.approx(0.2) and NRMSE_FLOOR_W == pytest.approx(0.4)
    assert FALSE_ESTIMATE_START == 5.0 and FAULT_WINDOW_DELAY == 5.0


def test_false_fault_estimate_of_a_constant_estimate_on_a_healthy_uh():
    est_p, est_w = np.zeros((K_FAULT, 4, 3)), np.zeros((K_FAULT, 4, 3))
    est_p[:, 0] = [0.3, 0.0, 0.0]            # UH1: |Fhat_p| = 0.3 m/s^2 at every step
    est_w[:, 0] = [0.0, 0.6, 0.8]            # UH1: |Fhat_w| = 1.0 rad/s^2
    est_p[:, 3, 2] = np.where(np.arange(K_FAULT) % 2, 0.4, 0.3)   # UH4 alternates 0.3 / 0.4 m/s^2
    m = _fault_metrics({}, est_p=est_p, est_w=est_w)
    false = m['false_fault_estimate']
    assert false['uh1'] == {'p': pytest.approx(0.3), 'w': pytest.approx(1.0), 'window': [5.0, 39.9]}
    assert false['uh4']['p'] == pytest.approx(math.sqrt((0.3 ** 2 + 0.4 ** 2) / 2))   # RMS, not the mean
    assert false['uh2'] == {'p': 0.0, 'w': 0.0, 'window': [5.0, 39.9]}
    assert false['max'] == {'p': pytest.approx(math.sqrt(0.125)), 'w': pytest.approx(1.0)}
    assert false['threshold'] == {'p': 0.05, 'w': 0.1}
    assert m['fault_estimation'] == {} and m['fault_nrmse'] == {}


def test_false_fault_estimate_window_leaves_out_the_start_up_and_everything_from_the_onset():
    est_p, est_w = np.full((K_FAULT, 4, 3), 99.0), np.full((K_FAULT, 4, 3), 99.0)
    in_window = (STEP_TIME >= 5.0) & (STEP_TIME < 10.0)          # UH2 faulted from 10 s
    est_p[in_window, 1] = [0.0, 0.2, 0.0]
    est_w[in_window, 1] = [0.0, 0.0, -0.05]
    est_p[STEP_TIME >= 5.0, 0] = [0.1, 0.0, 0.0]                 # UH1 healthy: 99 only before 5 s
    est_w[STEP_TIME >= 5.0, 0] = [0.0, 0.02, 0.0]
    est_w[200, 0] = np.nan                                       # a step a real-time run lost
    faulted = {2: FaultedUH(10.0, True), 3: FaultedUH(3.0, False), 4: FaultedUH(5.0, False)}
    m = _fault_metrics(faulted, est_p=est_p, est_w=est_w)
    false = m['false_fault_estimate']
    assert false['uh2'] == {'p': pytest.approx(0.2), 'w': pytest.approx(0.05), 'window': [5.0, 9.9]}
    assert false['uh1'] == {'p': pytest.approx(0.1), 'w': pytest.approx(0.02), 'window': [5.0, 39.9]}
    # UH3 (onset 3 s) and UH4 (onset 5 s) have no step in [5 s, onset): left out
    assert set(false) == {'uh1', 'uh2', 'max', 'threshold'}
    assert false['max'] == {'p': pytest.approx(0.2), 'w': pytest.approx(0.05)}


def test_false_fault_estimate_of_a_run_shorter_than_the_start_up_is_null():
    time, p0, offsets, pos, w = _team_run(40, 0.1)           # 4 s
    zeros = np.zeros((40, 4, 3))
    m = compute_metrics(case='x', time=time, positions=pos, reference_positions=p0, leaders=(1, 2, 3),
                        followers=(4,), offsets=offsets, containment_weights=w, z1=zeros, u_p=zeros,
                        saturated=np.zeros((40, 4), bool), fault_est_p=zeros, fault_est_w=zeros)
    assert m['false_fault_estimate'] == {'max': {'p': None, 'w': None}, 'threshold': {'p': 0.05, 'w': 0.1}}


def test_fault_estimation_absolute_error_of_a_known_offset_and_its_window():
    true_p, true_w = np.zeros((K_FAULT, 4, 3)), np.zeros((K_FAULT, 4, 3))
    after_onset = STEP_TIME >= 10.0
    true_p[after_onset, 1] = [2.0, 0.0, 0.0]                     # |F_p| = 2 m/s^2 from the onset
    true_w[after_onset, 1] = [0.0, 0.0, 4.0]                     # |F_w| = 4 rad/s^2
    est_p = true_p + [0.0, 0.3, 0.4]                             # offset of norm 0.5 m/s^2
    est_w = true_w + [1.0, 0.0, 0.0]                             # offset of norm 1 rad/s^2
    est_p[STEP_TIME < 15.0, 1] = 50.0                            # before onset + 5 s: not scored
    m = _fault_metrics({2: FaultedUH(10.0, True)}, est_p=est_p, est_w=est_w, true_p=true_p, true_w=true_w)
    entry = m['fault_estimation']['uh2']
    assert entry['window'] == [15.0, 39.9]
    assert entry['p'] == {'rms_error': pytest.approx(0.5), 'truth_rms': pytest.approx(2.0),
                          'nrmse': pytest.approx(0.25), 'nrmse_note': None}
    assert entry['w'] == {'rms_error': pytest.approx(1.0), 'truth_rms': pytest.approx(4.0),
                          'nrmse': pytest.approx(0.25), 'nrmse_note': None}
    assert m['fault_nrmse'] == {'uh2': {'F_p': pytest.approx(0.25), 'F_w': pytest.approx(0.25)}}


@pytest.mark.parametrize('key, floor', [('p', NRMSE_FLOOR_P), ('w', NRMSE_FLOOR_W)])
@pytest.mark.parametrize('factor, meaningful', [(0.99, False), (1.01, True)])
def test_nrmse_is_null_with_a_reason_below_the_floor_and_a_number_above(key, floor, factor, meaningful):
    truth = np.zeros((K_FAULT, 4, 3))
    truth[:, 2] = [0.0, factor * floor, 0.0]                     # UH3: constant truth, RMS factor * floor
    estimate = truth + [0.02, 0.0, 0.0]                          # absolute error 0.02 either way
    arrays = {f'true_{key}': truth, f'est_{key}': estimate}
    m = _fault_metrics({3: FaultedUH(10.0, True)}, **arrays)
    entry = m['fault_estimation']['uh3'][key]
    assert entry['rms_error'] == pytest.approx(0.02)
    assert entry['truth_rms'] == pytest.approx(factor * floor)
    if meaningful:
        assert entry['nrmse'] == pytest.approx(0.02 / (factor * floor)) and entry['nrmse_note'] is None
        assert not nrmse_below_floor(entry)
    else:
        assert entry['nrmse'] is None and 'below the floor' in entry['nrmse_note']
        assert nrmse_below_floor(entry)
    symbol = {'p': 'F_p', 'w': 'F_w'}[key]
    assert m['fault_nrmse']['uh3'][symbol] == entry['nrmse']


def test_fault_estimation_of_a_run_ending_before_onset_plus_delay_is_null():
    m = _fault_metrics({2: FaultedUH(36.0, False)})              # window from 41 s: past the end (39.9 s)
    assert m['fault_estimation'] == {'uh2': {'window': None, 'w': {
        'rms_error': None, 'truth_rms': None, 'nrmse': None, 'nrmse_note': 'no step in the window'}}}
    assert not nrmse_below_floor(m['fault_estimation']['uh2']['w'])


@pytest.fixture(scope='module')
def paper_run():
    from uh_team.team_simulation import run_team_simulation
    from uh_topology.scenario import load_scenario
    scenario = load_scenario('paper')
    return scenario, run_team_simulation(scenario, 'proposed').arrays()


def test_fault_isolation_of_the_paper_run_isolates_every_fault_in_time_and_nothing_else(paper_run):
    from uh_core.layout import CHANNEL_NAMES
    from uh_team.metrics import metrics_from_arrays
    scenario, arrays = paper_run
    metrics = metrics_from_arrays(arrays, scenario, 'proposed')
    assert list(metrics) == list(METRIC_KEYS)
    isolation = metrics['fault_isolation']
    summary = isolation['summary']
    assert summary['false_isolations'] == 0 and summary['missed'] == 0
    assert 0.0 < summary['max_delay'] < 2.0
    # the UHs with a fault, every channel named, the truth copied from the scenario
    assert set(isolation) - {'summary'} == {f'uh{uh}' for uh in faulted_uhs(scenario)}
    for uh, specs in scenario.faults.items():
        for spec in specs:
            entry = isolation[f'uh{uh}'][CHANNEL_NAMES[spec.channel]]
            assert entry['faulty'] and entry['isolated']
            assert entry['delay'] == pytest.approx(entry['detected_at'] - spec.onset_time, abs=1e-9)
            assert entry['rho_true'] == spec.rho and entry['bias_constant_true'] == spec.bias_constant
            # steady turns: nothing identifiable (docs/faults.md), and then no number is reported
            assert entry['identifiable'] is False and entry['rho'] is None and entry['bias'] is None
            assert entry['reason'] != 'identifiable'
    for channels in (v for k, v in isolation.items() if k != 'summary'):
        assert set(channels) == set(CHANNEL_NAMES)
        for entry in channels.values():
            if not entry['faulty']:
                assert not entry['isolated'] and entry['delay'] is None and entry['rho_true'] == 1.0


def test_fault_isolation_is_null_without_commands(paper_run):
    from uh_team.metrics import metrics_from_arrays
    scenario, arrays = paper_run
    short = {k: v[:200] for k, v in arrays.items() if k not in ('commands', 'ids')}
    assert metrics_from_arrays(short, scenario, 'proposed')['fault_isolation'] is None


def test_fault_isolation_of_a_recorded_run_scores_what_the_controllers_published(paper_run):
    """With an ``isolation`` entry per UH the section is built from those verdicts, not recomputed.

    The entries are read off the last /uhN/status of a bag. A published false isolation on healthy UH1 and an identified
    UH2 collective show up as published.
    """
    from uh_controller_node.fault_isolation import IDENTIFIABLE, NOT_ISOLATED
    from uh_team.metrics import metrics_from_arrays
    scenario, arrays = paper_run
    nan = math.nan
    quiet = {'step': 6000, 'isolated': [False] * 4, 'detection_time': [nan] * 4,
             'effectiveness': [nan] * 4, 'bias': [nan] * 4, 'identification': [NOT_ISOLATED] * 4}
    published = {uh: dict(quiet) for uh in scenario.ids}
    published[1] = dict(quiet, isolated=[False, True, False, False], detection_time=[nan, 20.0, nan, nan])
    published[2] = dict(quiet, isolated=[True, False, False, False], detection_time=[10.5, nan, nan, nan],
                        effectiveness=[0.81, nan, nan, nan], bias=[0.002, nan, nan, nan],
                        identification=[IDENTIFIABLE, 0, 0, 0])
    section = metrics_from_arrays(dict(arrays, isolation=published), scenario, 'proposed')['fault_isolation']
    assert section['summary']['source'] == 'status'
    assert section['summary']['false_isolations'] == 1
    assert section['uh1']['tail_rotor']['isolated'] and section['uh1']['tail_rotor']['detected_at'] == 20.0
    collective = section['uh2']['collective']
    assert collective['delay'] == pytest.approx(0.5) and collective['identifiable']
    assert (collective['rho'], collective['bias'], collective['reason']) == (0.81, 0.002, 'identifiable')
    # the faults nobody published are missed: UH2 lateral, UH3 (2), UH5 (2)
    assert section['summary']['missed'] == 5
    # without an entry for every UH the isolator is recomputed
    partial = {1: published[1]}
    assert metrics_from_arrays(dict(arrays, isolation=partial), scenario,
                               'proposed')['fault_isolation']['summary']['source'] == 'recomputed'


def test_injected_faults_are_those_a_simulator_applies_and_join_the_scheduled_ones():
    from uh_team.fault_metrics import fault_list, injected_faults, run_faults
    from uh_topology.scenario import load_scenario
    scenario = load_scenario('paper')          # UH1 and UH4 healthy, UH2, UH3, UH5 faulted from 10 s
    base = {'channel': 0, 'rho': 0.7, 'bias_constant': 0.0, 'bias_amplitude': 0.0, 'bias_frequency': 0.0}
    arrays = {'fault_injections': [
        {'uh': 1, 'uh_id': 1, **base, 'onset_time': 16.0, 'received_s': 2.5},        # applied, acts from 16 s
        {'uh': 4, 'uh_id': 4, **base, 'channel': 2, 'onset_time': 3.0, 'received_s': 7.25},  # late: acts on arrival
        {'uh': 1, 'uh_id': 2, **base, 'onset_time': 1.0, 'received_s': 3.0},         # names another UH: rejected
        {'uh': 4, 'uh_id': 4, **base, 'rho': 1.5, 'onset_time': 1.0, 'received_s': 3.0},   # invalid rho: rejected
        {'uh': 4, 'uh_id': 4, **base, 'channel': 3, 'rho': 1.0, 'onset_time': 9.0, 'received_s': 8.0},  # clears
    ]}
    applied = injected_faults(arrays)
    assert [(f['uh'], f['channel'], f['onset_time'], f['nominal']) for f in applied] == [
        (1, 0, 16.0, False), (4, 2, 7.25, False), (4, 3, 9.0, True)]
    assert applied[1]['sent_onset_time'] == 3.0 and applied[1]['received_s'] == 7.25
    faults = run_faults(scenario, arrays)
    assert len(faults[1]) == len(scenario.faults.get(1, ())) + 1
    assert len(faults[4]) == len(scenario.faults.get(4, ())) + 1          # the clearing one is not a fault
    faulted = faulted_uhs(scenario, arrays)
    assert faulted[1].onset == 16.0 and faulted[1].collective
    assert faulted[4].onset == 7.25 and not faulted[4].collective
    assert faulted_uhs(scenario) == {uh: f for uh, f in faulted.items() if uh not in (1, 4)}
    listed = fault_list(scenario, arrays)
    assert len(listed['scheduled']) == sum(len(s) for s in scenario.faults.values()) and listed['injected'] == applied
