"""Per-UH controller (docs/graph.md, docs/control_law.md).

The tests cover gains and cases, filters, thrust/attitude extraction, consensus errors, input checks, equilibrium and
determinism.
"""
import copy
import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from uh_controller_node.control_kernels import (
    CP_MIN_VERTICAL_ACCEL,
    CP_TILT_LIMIT,
    M_F_HAT_P,
    M_F_HAT_W,
    control_parameters,
    filter_advance,
    filter_gain,
    filter_rate,
    thrust_and_attitude,
    wrap_angle,
)
from uh_controller_node.controller import ControllerError, UHController
from uh_controller_node.gains import CASES, ControllerGains, GainsError
from uh_controller_node.nominal_model import nominal_model
from uh_core.airframe import load_helicopter_params

ROOT = Path(__file__).resolve().parents[1]
GAINS_FILE = ROOT / 'uh_topology' / 'uh_topology' / 'config' / 'paper_gains.yaml'

# the bundled airframe (docs/model.md#parameters)
PARAMS = load_helicopter_params()
MODEL = nominal_model(PARAMS, 0.9)


def paper_gains():
    return yaml.safe_load(GAINS_FILE.read_text())


class FakeScenario:
    """The Scenario attributes the controller reads, for a graph given as {i: {j: a_ij}} (j = 0: reference)."""

    name = 'test'
    model_mismatch = 0.9
    helicopter = 'helicopter'

    def __init__(self, edges, leaders, followers, offsets, gains=None):
        self.edges, self.leaders, self.followers = edges, tuple(leaders), tuple(followers)
        self.offsets = {i: np.asarray(h, float) for i, h in offsets.items()}
        self.gains = paper_gains() if gains is None else gains

    @property
    def ids(self):
        return self.leaders + self.followers

    def neighbours(self, i):
        return tuple(sorted(j for j in self.edges.get(i, {}) if j != 0))

    def weight(self, i, j):
        return float(self.edges.get(i, {}).get(j, 0.0))

    def leader_link(self, i):
        return self.weight(i, 0)


def paper_like():
    r = 3.0
    offsets = {i: [r * math.cos(2 * math.pi * (i - 1) / 3), r * math.sin(2 * math.pi * (i - 1) / 3), 0.0]
               for i in (1, 2, 3)}
    edges = {1: {0: 1.0, 3: 1.0}, 2: {1: 1.0}, 3: {2: 1.0}, 4: {1: 1.0, 2: 1.0, 5: 1.0}, 5: {3: 1.0, 4: 1.0}}
    return FakeScenario(edges, (1, 2, 3), (4, 5), offsets)


def reference(position, velocity=(0.0, 0.0, 0.0), yaw=0.0):
    return SimpleNamespace(position=np.asarray(position, float), velocity=np.asarray(velocity, float),
                           acceleration=np.zeros(3), yaw=yaw, yaw_rate=0.0)


def state(p=(0.0, 0.0, 0.0), v=(0.0, 0.0, 0.0), euler=(0.0, 0.0, 0.0), omega=(0.0, 0.0, 0.0)):
    return np.concatenate([p, v, euler, omega]).astype(float)


# ---------------------------------------------------------------------------------------------
# gains and cases

def _flat(gains):
    return {k: v for k, v in _walk(dataclasses.asdict(gains))}


def _walk(d, prefix=''):
    for k, v in d.items():
        if isinstance(v, dict):
            yield from _walk(v, f'{prefix}{k}.')
        else:
            yield f'{prefix}{k}', v


def test_cases_differ_only_in_the_parameters_design_2_6_names():
    base = _flat(ControllerGains.from_mapping(paper_gains(), 'proposed'))
    assert base['beta'] >= 2.0     # Lemma 2
    diffs = {}
    for case in CASES[1:]:
        other = _flat(ControllerGains.from_mapping(paper_gains(), case))
        diffs[case] = {k: other[k] for k in base if other[k] != base[k] and k != 'case'}
    assert diffs['case1'] == {'beta': 1.0}
    changed = set(diffs['case2'])
    assert changed <= {f'{loop}.{k}' for loop in ('outer', 'inner') for k in ('gamma', 'gamma_F', 'kappa')}
    assert all(v == 0.0 for v in diffs['case2'].values())
    # the proposed gains use the prediction error in both loops, so case2 really removes it
    assert {'outer.kappa', 'inner.kappa', 'outer.gamma_F', 'inner.gamma_F'} <= changed


def test_plain_mapping_equals_ros_parameter_layout():
    mapping = paper_gains()
    plain = mapping['/**']['ros__parameters']
    assert ControllerGains.from_mapping(plain) == ControllerGains.from_mapping(mapping)


@pytest.mark.parametrize('edit, match', [
    (lambda g: g.update(bogus=1), r"unknown key\(s\) \['bogus'\]"),
    (lambda g: g.pop('beta'), r"missing key\(s\) \['beta'\]"),
    (lambda g: g['outer'].update(k=-1.0), 'outer: k must be > 0, got -1.0'),
    (lambda g: g['inner'].update(kappa='fast'), "inner: kappa must be a number, got 'fast'"),
    (lambda g: g['outer'].update(tau_rate=0.02), r"outer: unknown key\(s\) \['tau_rate'\]"),
    (lambda g: g['inner'].update(rbf_nodes=2.5), 'inner: rbf_nodes must be an integer >= 1, got 2.5'),
    (lambda g: g.update(tilt_limit_deg=95.0), 'tilt_limit_deg must be < 90'),
    (lambda g: g['inner'].update(tau_rate=0.0), 'inner: tau_rate must be > 0, got 0.0'),
    (lambda g: g['outer'].update(rbf_width=0.0), 'outer: rbf_width must be > 0, got 0.0'),
    (lambda g: g['outer'].update(rbf_low=4.0), 'outer: rbf_low must be < rbf_high, got 4.0 and 4.0'),
    (lambda g: g.update(learning_phase=-1.0), 'learning_phase must be >= 0, got -1.0'),
    (lambda g: g['inner'].update(late_sigma=math.nan), 'inner: late_sigma must be finite, got nan'),
    (lambda g: g['outer'].update(late_learning_rate=-0.1), 'outer: late_learning_rate must be >= 0, got -0.1'),
])
def test_invalid_gains_are_rejected_with_the_offending_key(edit, match):
    gains = copy.deepcopy(paper_gains()['/**']['ros__parameters'])
    edit(gains)
    with pytest.raises(GainsError, match=match):
        ControllerGains.from_mapping(gains, source='gains.yaml')


def test_learning_phase_keys_are_optional_and_default_to_no_phase():
    """Without the keys the law is the one of before the learning phase existed.

    There is no phase, and the network's gains are unchanged afterwards.
    """
    gains = copy.deepcopy(paper_gains()['/**']['ros__parameters'])
    del gains['learning_phase']
    for loop in ('outer', 'inner'):
        gains[loop].pop('late_learning_rate', None)
        gains[loop].pop('late_sigma', None)
    parsed = ControllerGains.from_mapping(gains)
    assert parsed.learning_phase == 0.0
    for loop in (parsed.outer, parsed.inner):
        assert (loop.late_learning_rate, loop.late_sigma) == (loop.learning_rate, loop.sigma)
    paper = ControllerGains.from_mapping(paper_gains())
    assert paper.learning_phase > 0 and paper.inner.late_sigma == 0.0 < paper.inner.late_learning_rate


def test_unknown_case_is_rejected():
    with pytest.raises(GainsError, match="unknown controller case 'case3'; allowed: proposed, case1, case2"):
        ControllerGains.from_mapping(paper_gains(), 'case3')


# ---------------------------------------------------------------------------------------------
# command filter

def test_filter_matches_the_exact_solution_for_a_held_input():
    y = np.array([1.0, -2.0, 0.0])
    u = np.array([3.0, 3.0, 3.0])
    gain = filter_gain(0.05, 0.01)
    for _ in range(7):
        filter_advance(u, y, gain, False)
    expected = u + (np.array([1.0, -2.0, 0.0]) - u) * math.exp(-0.07 / 0.05)
    assert np.allclose(y, expected, rtol=1e-13)
    rate = np.empty(3)
    filter_rate(u, y, 0.05, False, rate)
    assert np.allclose(rate, (u - y) / 0.05)


def test_angle_axis_takes_the_short_way_and_stays_continuous():
    y = np.array([0.0, 0.0, 3.1])
    target = np.array([0.0, 0.0, -3.1])        # 0.083 rad away through +-pi
    rate = np.empty(3)
    filter_rate(target, y, 0.05, True, rate)
    assert rate[2] == pytest.approx((2 * math.pi - 6.2) / 0.05)
    gain = filter_gain(0.05, 0.01)
    for _ in range(200):
        filter_advance(target, y, gain, True)
    assert y[2] == pytest.approx(2 * math.pi - 3.1)   # unwrapped, same heading as -3.1
    assert wrap_angle(math.pi) == math.pi and wrap_angle(-math.pi) == math.pi
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)


# ---------------------------------------------------------------------------------------------
# thrust and attitude extraction (docs/control_law.md#thrust-and-attitude)

def _rotation_e3(phi, theta, psi):
    cf, sf, ct, st, cp, sp = (math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta),
                              math.cos(psi), math.sin(psi))
    return np.array([cp * st * cf + sp * sf, sp * st * cf - cp * sf, ct * cf])


def attitude(u_p, psi):
    """Return thrust_and_attitude of the kernels as a record.

    It is evaluated with MODEL, a 30 deg tilt limit and 2 m/s^2 minimum vertical acceleration.
    """
    params = control_parameters(ControllerGains.from_mapping(paper_gains()), MODEL)
    params[CP_TILT_LIMIT] = math.radians(30)
    params[CP_MIN_VERTICAL_ACCEL] = 2.0
    out = thrust_and_attitude(params, np.asarray(u_p, float), psi)
    return SimpleNamespace(**dict(zip(('phi', 'theta', 'thrust', 'theta_col', 'thrust_achieved',
                                       'saturated_tilt', 'saturated_collective'), out, strict=False)))


def test_hover_demand_gives_level_attitude_and_hover_collective():
    att = attitude(np.zeros(3), 0.7)
    assert att.phi == 0.0 and att.theta == 0.0
    assert att.thrust == pytest.approx(8.2 * 9.81)
    assert att.theta_col == pytest.approx((8.2 * 9.81 - 10.0) / 700.0)
    assert not (att.saturated_tilt or att.saturated_collective)


def test_attitude_and_thrust_realise_the_demanded_acceleration():
    rng = np.random.default_rng(11)
    for _ in range(50):
        u_p = rng.uniform(-3.0, 3.0, size=3)
        psi = rng.uniform(-math.pi, math.pi)
        att = attitude(u_p, psi)
        assert not att.saturated_tilt
        achieved = att.thrust / MODEL.mass * _rotation_e3(att.phi, att.theta, psi) - [0, 0, MODEL.gravity]
        assert np.allclose(achieved, u_p, atol=1e-12)


def test_tilt_limit_keeps_the_vertical_demand_and_collective_limit_is_flagged():
    att = attitude([20.0, 0.0, 1.0], 0.0)
    assert att.saturated_tilt
    tilt = math.acos(math.cos(att.phi) * math.cos(att.theta))
    assert tilt == pytest.approx(math.radians(30))
    vertical = att.thrust / MODEL.mass * math.cos(att.phi) * math.cos(att.theta)
    assert vertical == pytest.approx(MODEL.gravity + 1.0)
    big = attitude([0.0, 0.0, 30.0], 0.0)
    assert big.saturated_collective and big.theta_col == 0.3
    assert big.thrust_achieved == pytest.approx(700.0 * 0.3 + 10.0)


# ---------------------------------------------------------------------------------------------
# the per-UH controller

def test_hover_at_the_target_is_an_equilibrium_of_the_law():
    scn = FakeScenario({1: {0: 1.0}}, (1,), (), {1: [1.0, 2.0, 0.0]})
    ctl = UHController(1, scn, helicopter_params=PARAMS)
    x = state(p=(1.0, 2.0, 5.0))
    ref = reference((0.0, 0.0, 5.0))
    mg = 8.2 * 9.81
    for k in range(5):
        u, st = ctl.step(k, x, {}, ref, 0.01)
        # collective for T = m g; tail rotor balances the nominal torque reaction 0.9 c_Q m g
        assert u == pytest.approx([(mg - 10.0) / 700.0, 0.9 * 0.02 * mg / 30.0, 0.0, 0.0], abs=1e-12)
        for vec in (st.z1, st.z2, st.z3, st.z4, st.u_p, st.fault_estimate_position,
                    st.fault_estimate_attitude, st.prediction_error_position):
            assert np.allclose(vec, 0.0, atol=1e-12)
    assert st.cost_rate == pytest.approx(0.0, abs=1e-20) and not st.saturated


def test_consensus_errors_use_offsets_for_leaders_only():
    scn = paper_like()
    xs = {i: state(p=np.array([i, 2.0 * i, 10.0 + i])) for i in scn.ids}
    xs = {i: x + np.r_[np.zeros(3), [0.1 * i, 0, 0], np.zeros(6)] for i, x in xs.items()}
    h = scn.offsets
    _, st2 = UHController(2, scn, helicopter_params=PARAMS).step(0, xs[2], {1: xs[1]}, None, 0.01)
    assert np.allclose(st2.z1, (xs[2][:3] - h[2]) - (xs[1][:3] - h[1]))
    ref = reference((0.5, 0.5, 9.0), velocity=(1.0, 0.0, 0.0))
    _, st1 = UHController(1, scn, helicopter_params=PARAMS).step(0, xs[1], {3: xs[3]}, ref, 0.01)
    assert np.allclose(st1.z1, ((xs[1][:3] - h[1]) - (xs[3][:3] - h[3])) + ((xs[1][:3] - h[1]) - ref.position))
    _, st4 = UHController(4, scn, helicopter_params=PARAMS).step(0, xs[4], {j: xs[j] for j in (1, 2, 5)}, None, 0.01)
    assert np.allclose(st4.z1, sum(xs[4][:3] - xs[j][:3] for j in (1, 2, 5)))


def test_followers_track_the_weighted_mean_yaw_the_short_way():
    scn = paper_like()
    x5 = state(p=(0, 0, 10), euler=(0.0, 0.0, 3.0))
    x3 = state(p=(1, 0, 10), euler=(0.0, 0.0, -3.0))       # 0.283 rad ahead through +-pi
    x4 = state(p=(0, 1, 10), euler=(0.0, 0.0, 3.0))
    _, st = UHController(5, scn, helicopter_params=PARAMS).step(0, x5, {3: x3, 4: x4}, None, 0.01)
    assert st.euler_desired[2] == pytest.approx(3.0 + (2 * math.pi - 6.0) / 2)


@pytest.mark.parametrize('uh, neighbours, ref, match', [
    (4, (1, 2), None,
     r'UH 4 controller: missing state of neighbour\(s\) \[5\]; expected exactly the neighbours \[1, 2, 5\]'),
    (2, (1, 3), None, r'unexpected state of UH\(s\) \[3\] that UH 2 does not hear'),
    (1, (3,), None, r'UH 1 hears the virtual leader \(a_10 = 1\): a reference is required'),
    (2, (1,), 'ref', 'UH 2 does not hear the virtual leader: reference must be None'),
])
def test_step_rejects_inputs_that_do_not_match_the_graph(uh, neighbours, ref, match):
    ctl = UHController(uh, paper_like(), helicopter_params=PARAMS)
    r = reference((0, 0, 10)) if ref else None
    with pytest.raises(ControllerError, match=match):
        ctl.step(0, state(), {j: state() for j in neighbours}, r, 0.01)


def test_step_rejects_bad_states_and_construction_errors():
    scn = paper_like()
    ctl = UHController(2, scn, helicopter_params=PARAMS)
    with pytest.raises(ControllerError,
                       match=r'UH 2 own state must be a state vector of shape \(12,\), got shape \(9,\)'):
        ctl.step(0, np.zeros(9), {1: state()}, None, 0.01)
    bad = state()
    bad[4] = np.nan
    with pytest.raises(ControllerError, match='state of neighbour UH 1 contains NaN'):
        ctl.step(0, state(), {1: bad}, None, 0.01)
    with pytest.raises(ControllerError, match=r'unknown UH id 9; the scenario has UHs \[1, 2, 3, 4, 5\]'):
        UHController(9, scn, helicopter_params=PARAMS)
    lonely = FakeScenario({1: {0: 1.0}, 2: {}}, (1, 2), (), {1: [0, 0, 0], 2: [1, 0, 0]})
    with pytest.raises(ControllerError, match='UH 2 hears neither a neighbour nor the virtual leader'):
        UHController(2, lonely, helicopter_params=PARAMS)


def _drive(ctl, uh, scn, steps, order=1):
    """Feed a controller a deterministic, time-varying set of states; return commands and statuses."""
    out = []
    for k in range(steps):
        t = 0.01 * k
        own = state(p=(0.3 * math.sin(t), 0.1, 9.0 + t), v=(0.2, -0.1, 0.05), euler=(0.02, -0.01, 0.1 * t),
                    omega=(0.01, 0.02, 0.1))
        nbrs = {j: state(p=(j + math.cos(t), -j, 10.0), v=(0.1 * j, 0, 0), euler=(0, 0, 0.05 * j))
                for j in scn.neighbours(uh)[::order]}
        ref = reference((math.sin(t), 0, 10), (math.cos(t), 0, 0.1), 0.1 * t) if scn.leader_link(uh) else None
        u, st = ctl.step(k, own, nbrs, ref, 0.01)
        out.append((u, st))
    return out


def test_controller_is_deterministic_and_independent_of_neighbour_order():
    scn = paper_like()
    # past the learning phase (8 s), so the fault observers run too
    a = _drive(UHController(4, scn, helicopter_params=PARAMS), 4, scn, 1000)
    b = _drive(UHController(4, scn, helicopter_params=PARAMS), 4, scn, 1000, order=-1)
    for (ua, sa), (ub, sb) in zip(a, b, strict=False):
        assert np.array_equal(ua, ub)      # bit-identical, not merely close
        assert np.array_equal(sa.fault_estimate_attitude, sb.fault_estimate_attitude)
    # the inputs are rich enough that the learning states moved
    assert a[-1][1].weight_norm_position > 0.0 and np.any(a[-1][1].fault_estimate_position != 0.0)


def test_commands_stay_within_the_input_limits():
    scn = paper_like()
    ctl = UHController(1, scn, helicopter_params=PARAMS)
    far = state(p=(50.0, -40.0, 0.0), v=(5.0, 5.0, -3.0), euler=(0.4, -0.4, 2.0), omega=(2.0, -2.0, 1.0))
    lo, hi = np.array(PARAMS.input_lower), np.array(PARAMS.input_upper)
    for k in range(50):
        u, st = ctl.step(k, far, {3: state()}, reference((0, 0, 10)), 0.01)
        assert np.all(u >= lo) and np.all(u <= hi)
    assert st.saturated_tilt and st.saturated_cyclic
    assert np.all(np.abs(st.fault_estimate_position) <= 5.0 + 1e-12)    # projection bound (gains file)


def test_learning_phase_is_counted_in_run_time_so_a_late_joiner_estimates_faults_at_once():
    """The learning phase covers the run's first seconds, not a controller's first seconds.

    See docs/control_law.md#learning-phase. A controller started at step 0 holds its fault estimates at zero; one whose
    first step is after the phase (restarted in a running team) runs its observers from its first step.
    """
    scn = paper_like()
    phase = ControllerGains.from_mapping(paper_gains()).learning_phase
    own = state(p=(0.5, 0.2, 9.0), v=(0.3, -0.1, 0.05), euler=(0.02, -0.01, 0.1), omega=(0.01, 0.02, 0.1))
    nbrs = {j: state(p=(j, -j, 10.0)) for j in scn.neighbours(4)}
    fresh, late = UHController(4, scn, helicopter_params=PARAMS), UHController(4, scn, helicopter_params=PARAMS)
    k_late = int(round(phase / 0.01)) + 500
    for n in range(3):
        fresh.step(n, own, nbrs, None, 0.01)
        late.step(k_late + n, own, nbrs, None, 0.01)
    assert not np.any(fresh.kernel_arrays().memory[M_F_HAT_P]) and not np.any(fresh.kernel_arrays().memory[M_F_HAT_W])
    assert np.any(late.kernel_arrays().memory[M_F_HAT_P]) and np.any(late.kernel_arrays().memory[M_F_HAT_W])
