"""The control-law kernels and their Python wrapper (docs/graph.md, docs/control_law.md).

The tests cover array layouts, the parameter vector, the documented way of calling the per-UH kernel from njit code, the
degraded step, input checks that leave the controller unchanged, and the signatures the cache is warmed for.
"""
import dataclasses
import math

import numpy as np
import pytest
from numba import njit

from uh_controller_node import control_kernels as ck
from uh_controller_node.controller import ControllerError, ControllerStatusData, UHController
from uh_controller_node.fault_isolation import IsolationStatus
from uh_core.layout import STATUS_FIELDS, STATUS_FLAG, STATUS_VECTOR3
from uh_core.reference import VirtualLeaderReference


def _inputs(paper, k):
    """States of every UH and the reference at step k of a smooth made-up flight (deterministic)."""
    t = k * paper.dt
    ref = VirtualLeaderReference(paper.reference).at(t)
    states = {}
    for i in paper.ids:
        x = np.zeros(12)
        x[0:3] = ref.position + 0.4 * np.array([np.sin(t + i), np.cos(2 * t + i), 0.1 * i])
        x[3:6] = ref.velocity + 0.3 * np.array([np.cos(3 * t + i), -np.sin(2 * t), 0.2 * np.cos(t)])
        x[6:9] = [0.05 * np.sin(t + i), -0.04 * np.cos(t), 0.1 * t + 0.02 * i]
        x[9:12] = [0.3 * np.sin(4 * t), 0.2 * np.cos(3 * t + i), 0.1]
        states[i] = x
    return states, ref


def _reference_vector(ref):
    return np.r_[ref.position, ref.velocity, ref.yaw]


def _status_fields(st):
    return {f.name: getattr(st, f.name) for f in dataclasses.fields(st)}


def _assert_same_status(a, b):
    for name, value in _status_fields(a).items():
        other = getattr(b, name)
        if isinstance(value, np.ndarray):
            assert np.array_equal(value, other), name
        elif isinstance(value, float) and math.isnan(value):   # closest_distance with the filter off
            assert isinstance(other, float) and math.isnan(other), name
        else:
            assert value == other, name


# ---------------------------------------------------------------------------------------------
# layouts

def test_wrap_angle_is_the_ieee_remainder_bit_for_bit():
    rng = np.random.default_rng(5)
    values = [0.0, -0.0, math.pi, -math.pi, 2 * math.pi, -3 * math.pi, 5 * math.pi, 1e-300, 7.0, -7.0]
    values += list(rng.uniform(-10.0, 10.0, 500)) + list(rng.uniform(-1e6, 1e6, 500))
    for a in values:
        w = math.remainder(a, 2 * math.pi)
        expected = math.pi if w == -math.pi else w
        assert ck.wrap_angle(a) == expected, a
    assert ck.wrap_angle(-math.pi) == math.pi       # the interval is (-pi, pi]


def test_status_and_memory_layouts_are_consistent():
    vectors = [ck.S_Z1, ck.S_Z2, ck.S_Z3, ck.S_Z4, ck.S_F_HAT_P, ck.S_F_HAT_W, ck.S_ZN_P, ck.S_ZN_W, ck.S_U_P,
               ck.S_EULER_D]
    # every scalar field of the registry, at the index the kernels write it (STATUS.<field>)
    scalars = [getattr(ck.STATUS, f.name) for f in STATUS_FIELDS if f.kind != STATUS_VECTOR3]
    slots = sorted([i for s in vectors for i in range(s, s + 3)] + scalars)
    assert slots == list(range(ck.STATUS_SIZE))            # every slot used once
    assert len(vectors) == ck.STATUS_VECTORS and max(vectors) + 3 == 3 * ck.STATUS_VECTORS
    # ControllerStatusData.from_vector relies on the vectors being in field order
    fields = [f.name for f in dataclasses.fields(ControllerStatusData)][3:3 + ck.STATUS_VECTORS]
    assert fields[0] == 'z1' and fields[-1] == 'euler_desired' and vectors == sorted(vectors)
    rows = [ck.M_ALPHA_F, ck.M_V_HAT, ck.M_F_HAT_P, ck.M_THETA_DF, ck.M_ALPHA_WF, ck.M_OMEGA_HAT,
            ck.M_F_HAT_W, ck.M_FLAGS]
    assert sorted(rows) == list(range(ck.MEMORY_ROWS))


def test_control_parameters_hold_every_model_constant_and_gain(paper):
    ctl = UHController(1, paper)
    mapping = ctl.gains
    # distinct values everywhere, so a swapped index shows
    loops = {}
    for n, name in enumerate(('outer', 'inner')):
        loop = getattr(mapping, name)
        values = {f.name: 1.0 + 0.01 * (k + 20 * n) for k, f in enumerate(dataclasses.fields(loop))
                  if f.name not in ('rbf',)}
        rbf = dataclasses.replace(loop.rbf, low=-3.0 - n, high=2.0 + n, width=0.7 + n)
        loops[name] = dataclasses.replace(loop, rbf=rbf, **values)
    gains = dataclasses.replace(mapping, beta=2.5, tilt_limit=0.4, min_vertical_accel=1.5, learning_phase=4.5,
                                feedforward_weight=0.75, **loops)
    params = ck.control_parameters(gains, ctl.model)
    assert params.shape == (ck.CONTROL_PARAMS_SIZE,) and params.dtype == np.float64
    m = ctl.model
    expected = {ck.CP_MASS: m.mass, ck.CP_GRAVITY: m.gravity, ck.CP_J_X: m.inertia[0],
                ck.CP_J_Y: m.inertia[1], ck.CP_J_Z: m.inertia[2], ck.CP_C_M1: m.c_M1, ck.CP_C_M2: m.c_M2,
                ck.CP_K_BETA: m.K_beta, ck.CP_H_M: m.h_M, ck.CP_B_LAT: m.B_lat, ck.CP_A_LON: m.A_lon,
                ck.CP_TAU_F: m.tau_f,
                ck.CP_K_TR: m.K_tr, ck.CP_D_R: m.D_r, ck.CP_C_Q: m.c_Q, ck.CP_D_V: m.D_v,
                ck.CP_BETA: 2.5, ck.CP_TILT_LIMIT: 0.4, ck.CP_MIN_VERTICAL_ACCEL: 1.5, ck.CP_LEARNING_PHASE: 4.5,
                ck.CP_FEEDFORWARD_WEIGHT: 0.75}
    for c in range(ck.INPUT_SIZE):
        expected[ck.CP_LOWER + c] = m.input_lower[c]
        expected[ck.CP_UPPER + c] = m.input_upper[c]
    offsets = {'k': ck.L_K, 'r': ck.L_R, 'tau_command': ck.L_TAU_COMMAND, 'tau_rate': ck.L_TAU_RATE,
               'kappa': ck.L_KAPPA, 'learning_rate': ck.L_LEARNING_RATE, 'gamma': ck.L_GAMMA,
               'gamma_F': ck.L_GAMMA_F, 'sigma': ck.L_SIGMA, 'lambda_': ck.L_LAMBDA, 'sigma_F': ck.L_SIGMA_F,
               'fault_bound': ck.L_FAULT_BOUND, 'weight_bound': ck.L_WEIGHT_BOUND,
               'late_learning_rate': ck.L_LATE_LEARNING_RATE, 'late_sigma': ck.L_LATE_SIGMA}
    for base, loop in ((ck.CP_OUTER, gains.outer), (ck.CP_INNER, gains.inner)):
        for name, offset in offsets.items():
            expected[base + offset] = getattr(loop, name)
        expected[base + ck.L_RBF_LOW] = loop.rbf.low
        expected[base + ck.L_RBF_HIGH] = loop.rbf.high
        expected[base + ck.L_RBF_WIDTH] = loop.rbf.width
    assert sorted(expected) == list(range(ck.CONTROL_PARAMS_SIZE))
    for index, value in expected.items():
        assert params[index] == value, index


# ---------------------------------------------------------------------------------------------
# the per-UH kernel, from Python and from njit code

@njit(cache=True)
def _team_control_step(states, reference, dt, hears, count, params, offsets, nb_weights, nb_offsets, links,
                       weights_p, weights_w, memory, u, status):
    """Run a control-only team loop: the per-UH kernel on stacked arrays, as team_kernel.run_team_steps calls it."""
    for c in range(states.shape[0]):
        m = count[c]
        nb = np.empty((m, ck.STATE_SIZE))
        for j in range(m):
            nb[j] = states[hears[c, j]]
        done = ck.uh_control_step(params[c], states[c], nb, nb_weights[c, :m], nb_offsets[c, :m], offsets[c],
                                  links[c], reference, dt, weights_p[c], weights_w[c], memory[c], u[c],
                                  status[c], np.empty(0), np.empty((0, 6)))
        if done != ck.STEP_DONE:
            return c
    return -1


def test_team_kernel_built_from_kernel_arrays_reproduces_the_controllers_bit_for_bit(paper):
    ids = tuple(paper.ids)
    col = {i: c for c, i in enumerate(ids)}
    ctls = [UHController(i, paper) for i in ids]
    arrays = [ctl.kernel_arrays() for ctl in ctls]
    n, max_nb = len(ids), max(len(ctl.neighbours) for ctl in ctls)
    hears = np.zeros((n, max_nb), dtype=np.int64)
    count = np.array([len(ctl.neighbours) for ctl in ctls], dtype=np.int64)
    nb_weights, nb_offsets = np.zeros((n, max_nb)), np.zeros((n, max_nb, 3))
    for c, (ctl, a) in enumerate(zip(ctls, arrays, strict=True)):
        hears[c, :count[c]] = [col[j] for j in ctl.neighbours]
        nb_weights[c, :count[c]] = a.neighbour_weights
        nb_offsets[c, :count[c]] = a.neighbour_offsets
    params = np.stack([a.params for a in arrays])
    offsets = np.stack([a.offset for a in arrays])
    links = np.array([a.leader_link for a in arrays])
    weights_p = np.stack([a.weights_p for a in arrays])       # copies: the controllers run apart
    weights_w = np.stack([a.weights_w for a in arrays])
    memory = np.stack([a.memory for a in arrays])
    u, status = np.empty((n, ck.INPUT_SIZE)), np.empty((n, ck.STATUS_SIZE))
    saturated = False
    steps = int(round(ck.control_parameters(ctls[0].gains, ctls[0].model)[ck.CP_LEARNING_PHASE] / paper.dt)) + 100
    for k in range(steps):   # past the learning phase, so the fault observers run too
        states, ref = _inputs(paper, k)
        x = np.stack([states[i] for i in ids])
        first_bad = _team_control_step(x, _reference_vector(ref), paper.dt, hears, count, params, offsets,
                                       nb_weights, nb_offsets, links, weights_p, weights_w, memory, u, status)
        assert first_bad == -1
        for c, ctl in enumerate(ctls):
            uc, st = ctl.step(k, states[ids[c]], {j: states[j] for j in ctl.neighbours},
                              ref if ctl.leader_link > 0 else None, paper.dt)
            assert np.array_equal(u[c], uc)
            saturated = saturated or st.saturated
            assert np.array_equal(status[c], np.r_[np.concatenate(
                [st.z1, st.z2, st.z3, st.z4, st.fault_estimate_position, st.fault_estimate_attitude,
                 st.prediction_error_position, st.prediction_error_attitude, st.u_p, st.euler_desired]),
                st.thrust_command, st.weight_norm_position, st.weight_norm_attitude, st.saturated_tilt,
                st.saturated_collective, st.saturated_cyclic, st.cost_rate, st.safety_active,
                st.closest_distance], equal_nan=True)   # closest_distance: NaN with the filter off
    for c, a in enumerate(arrays):
        assert np.array_equal(memory[c], a.memory) and np.array_equal(weights_w[c], a.weights_w)
    # the run exercised the learning states (and the limits)
    assert np.all(np.abs(memory[:, ck.M_F_HAT_W]).sum(axis=1) > 0.0)
    assert np.all(np.abs(weights_p).sum(axis=(1, 2)) > 0.0)
    assert np.all(np.abs(weights_w).sum(axis=(1, 2)) > 0.0)
    assert saturated


#: The status fields that are flags (bool in the record).
FLAGS = {f.name for f in STATUS_FIELDS if f.kind == STATUS_FLAG}


def test_status_record_has_the_documented_types(paper):
    ctl = UHController(4, paper)
    states, _ = _inputs(paper, 3)
    u, st = ctl.step(3, states[4], {j: states[j] for j in ctl.neighbours}, None, paper.dt)
    assert u.shape == (4,) and u.dtype == np.float64
    for name, value in _status_fields(st).items():
        if name in ('uh_id', 'step'):
            assert type(value) is int
        elif name in FLAGS:
            assert type(value) is bool, name
        elif name in ('stale_neighbours', 'lost_uhs'):   # filled by the node (docs/resilience.md)
            assert value == ()
        elif name == 'role':
            assert value == ''
        elif name == 'isolation':   # the fault isolator's per-channel tuples (4 entries each)
            assert isinstance(value, IsolationStatus) and all(len(v) == 4 for v in value), value
            assert value.isolated == (False,) * 4           # step 3: within the learning phase
        elif isinstance(value, np.ndarray):
            assert value.shape == (3,) and value.dtype == np.float64, name
        else:
            assert type(value) is float, name
    assert st.stamp == 3 * paper.dt and st.cost_rate == pytest.approx(st.z1 @ st.z1 + st.u_p @ st.u_p)
    assert st.weight_norm_position == pytest.approx(np.linalg.norm(ctl.outer.weights))


@pytest.mark.parametrize('uh', [1, 2, 3, 4, 5])
def test_degraded_step_with_every_input_equals_the_step(paper, uh):
    a, b = UHController(uh, paper), UHController(uh, paper)
    for k in range(60):
        states, ref = _inputs(paper, k)
        nb = {j: states[j] for j in a.neighbours}
        use_ref = ref if a.leader_link > 0 else None
        ua, sa = a.step(k, states[uh], nb, use_ref, paper.dt)
        ub, sb = b.step_degraded(k, states[uh], nb, use_ref, paper.dt)
        assert np.array_equal(ua, ub)
        _assert_same_status(sa, sb)
    assert np.array_equal(a.kernel_arrays().memory, b.kernel_arrays().memory)


def test_a_rejected_step_changes_nothing(paper):
    """A NaN or a bad shape is reported before any internal state moves.

    The next good step is the one a controller that never saw the bad input computes.
    """
    a, b = UHController(5, paper), UHController(5, paper)
    for k in range(20):
        states, _ = _inputs(paper, k)
        nb = {j: states[j] for j in a.neighbours}
        a.step(k, states[5], nb, None, paper.dt)
        b.step(k, states[5], nb, None, paper.dt)
    states, _ = _inputs(paper, 20)
    bad = {3: states[3], 4: np.r_[states[4][:11], np.inf]}
    with pytest.raises(ControllerError, match=r'state of neighbour UH 4 contains NaN or infinity: \[.*inf\]'):
        a.step(20, states[5], bad, None, paper.dt)
    nan_own = states[5].copy()
    nan_own[0] = np.nan
    with pytest.raises(ControllerError, match='UH 5 own state contains NaN'):
        a.step_degraded(20, nan_own, {3: states[3]}, None, paper.dt)
    # the first problem in reading order is reported: the own NaN before the neighbour's bad shape
    with pytest.raises(ControllerError, match='UH 5 own state contains NaN'):
        a.step(20, nan_own, {3: states[3], 4: states[4][:9]}, None, paper.dt)
    with pytest.raises(ControllerError,
                       match=r'state of neighbour UH 4 must be a state vector of shape \(12,\)'):
        a.step(20, list(states[5]), {3: states[3], 4: states[4][:9]}, None, paper.dt)
    nb = {j: states[j] for j in a.neighbours}
    ua, sa = a.step(20, states[5], nb, None, paper.dt)
    # lists work too
    ub, sb = b.step(20, list(states[5]), {j: list(x) for j, x in nb.items()}, None, paper.dt)
    assert np.array_equal(ua, ub)
    _assert_same_status(sa, sb)


def test_warm_up_covers_every_signature_the_controller_uses(paper):
    assert ck.compile_control_kernels() >= 0.0
    before = set(ck.uh_control_step.signatures)
    ctl = UHController(1, paper)
    states, ref = _inputs(paper, 0)
    ctl.step(0, states[1], {3: states[3]}, ref, paper.dt)
    ctl.step_degraded(1, states[1], {}, ref, paper.dt)
    ctl.step_degraded(2, states[1].astype(np.float32), {3: states[3].astype(int)}, None, 0.01)
    ctl.step_degraded(3, states[1], {}, None, 1, hold=(states[1][:3], 0.2))
    assert set(ck.uh_control_step.signatures) == before
