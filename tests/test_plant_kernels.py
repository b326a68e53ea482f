"""Compiled kernels of the helicopter model and the guard of their on-disk cache.

The kernels are uh_sim_node.plant_kernels (docs/model.md, docs/faults.md); the guard is uh_core.kernel_cache.

The reference here is independent of the kernels: the numpy matrix form of the dynamics and its
written-out lumped faults (``model_oracle``), textbook RK4 on whole vectors, and eq. 6 evaluated by
``ActuatorFault.apply`` in Python.
"""
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from model_oracle import lumped_faults, reference_step, state_derivative
from numba import njit

from uh_core import kernel_cache, layout
from uh_core.airframe import load_helicopter_params
from uh_core.layout import NUM_CHANNELS
from uh_sim_node import plant_kernels as K
from uh_sim_node.faults import ONSET_TOLERANCE, ActuatorFault, FaultError, FaultSchedule
from uh_sim_node.helicopter import HelicopterPlant, SinusoidalDisturbance, hover_trim

P = load_helicopter_params()
DT = 0.01
SUBSTEPS = 5
X0 = np.concatenate([[1.0, 2.0, 12.0], [0.8, -0.4, 0.3], [0.12, -0.08, 0.9], [0.3, -0.25, 0.4]])
U = hover_trim(P) + np.array([0.02, -0.01, 0.01, -0.015])  # inside the limits
DIST = SinusoidalDisturbance([0.3, 0.3, 0.2], [0.5, 4.0, 3.0], [0.0, 1.0, 2.0])


def _arrays(faults=(), dist=None):
    return K.params_vector(P), K.fault_table(FaultSchedule(faults)), K.disturbance_table(dist)


# ------------------------------------------------------------------------------------------------
# Array layout


def test_params_vector_puts_each_parameter_at_its_named_index():
    vec = K.params_vector(P)
    assert vec.shape == (K.PARAMS_SIZE,) and vec.dtype == np.float64
    named = {K.P_MASS: P.mass, K.P_GRAVITY: P.gravity, K.P_D_V: P.D_v, K.P_C_M1: P.c_M1, K.P_C_M2: P.c_M2,
             K.P_K_BETA: P.K_beta, K.P_H_M: P.h_M, K.P_B_LAT: P.B_lat, K.P_A_LON: P.A_lon,
             K.P_TAU_F: P.tau_f, K.P_K_TR: P.K_tr, K.P_D_R: P.D_r, K.P_C_Q: P.c_Q,
             K.P_J_X: P.inertia[0], K.P_J_Y: P.inertia[1], K.P_J_Z: P.inertia[2]}
    for index, value in named.items():
        assert vec[index] == value
    np.testing.assert_array_equal(vec[K.P_LOWER:K.P_LOWER + 4], P.input_lower)
    np.testing.assert_array_equal(vec[K.P_UPPER:K.P_UPPER + 4], P.input_upper)
    # every slot is named exactly once
    assert sorted(list(named) + list(range(K.P_LOWER, K.P_UPPER + 4))) == list(range(K.PARAMS_SIZE))


def test_fault_and_disturbance_tables():
    table = K.fault_table(FaultSchedule([ActuatorFault(3, 0.75, -0.005, 0.01, 0.5, 10.0)]))
    assert table.shape == (NUM_CHANNELS, K.FAULT_FIELDS)
    np.testing.assert_array_equal(table[3, [K.F_PRESENT, K.F_RHO, K.F_BIAS_CONSTANT, K.F_BIAS_AMPLITUDE,
                                            K.F_BIAS_FREQUENCY, K.F_ACTS_FROM]],
                                  [1.0, 0.75, -0.005, 0.01, 0.5, 10.0 - ONSET_TOLERANCE])
    np.testing.assert_array_equal(table[:3], 0.0)  # channels without fault: not present
    dist = K.disturbance_table(DIST)
    np.testing.assert_array_equal(dist[:, K.D_AMPLITUDE], DIST.amplitude)
    np.testing.assert_array_equal(dist[:, K.D_FREQUENCY], DIST.frequency)
    np.testing.assert_array_equal(dist[:, K.D_PHASE], DIST.phase)
    np.testing.assert_array_equal(K.disturbance_table(None), 0.0)
    out = np.empty(3)
    K.force_disturbance(dist, 2.0, out)
    np.testing.assert_array_equal(out, DIST(2.0))  # same libm sin, same formula


# ------------------------------------------------------------------------------------------------
# Dynamics and integration against the independent reference


def test_state_derivative_kernel_equals_matrix_form():
    rng = np.random.default_rng(7)
    params = K.params_vector(P)
    out = np.empty(12)
    for _ in range(10):
        x = np.concatenate([rng.normal(size=6), rng.uniform(-0.8, 0.8, 3), rng.normal(size=3)])
        u = rng.uniform(P.input_lower, P.input_upper)
        d = rng.normal(size=3)
        K.state_derivative(x, u, d, params, out)
        # differences of O(100) terms in another order: a few ulps of 100
        np.testing.assert_allclose(out, state_derivative(P, x, u, d), rtol=0, atol=1e-12)


def test_plant_step_equals_textbook_rk4_with_faults_disturbance_and_onset():
    schedule = FaultSchedule([ActuatorFault(0, 0.8, 0.0, 0.01, 0.5, onset_time=0.05),
                              ActuatorFault(2, 0.85, 0.002, 0.003, 7.0, onset_time=0.0),
                              ActuatorFault(1, 0.0, 0.02, onset_time=0.07)])     # stuck tail rotor
    params, faults, dist = _arrays(schedule.faults, DIST)
    x = X0.copy()
    ref = X0.copy()
    for k in range(12):  # across both onsets
        t = k * DT
        K.plant_step(x, U, t, DT, SUBSTEPS, params, faults, dist)
        ref = reference_step(P, ref, U, t, DT, SUBSTEPS, schedule, DIST)
        # same arithmetic in another order on O(10) numbers, propagated over 12 steps
        np.testing.assert_allclose(x, ref, rtol=0, atol=1e-12)


def test_hover_trim_stays_trimmed_in_the_kernel():
    params, faults, dist = _arrays()
    x0 = np.concatenate([[1.0, -2.0, 10.0], [0, 0, 0], [0, 0, 0.7], [0, 0, 0]])
    x = x0.copy()
    u = hover_trim(P)
    for k in range(1000):  # 10 s
        K.plant_step(x, u, k * DT, DT, SUBSTEPS, params, faults, dist)
    # residual acceleration of rounding size (1e-14 m/s^2) moves the helicopter ~5e-13 m in 10 s
    np.testing.assert_allclose(x, x0, rtol=0, atol=1e-9)


def test_a_fault_switches_on_at_the_first_substep_start_after_its_onset():
    """With dt = 10 ms and 5 substeps of 2 ms from t = 10 ms, substeps start at 10, 12, 14, 16, 18 ms."""
    params, _, dist = _arrays()

    def step(onset):
        faults = K.fault_table([ActuatorFault(0, 0.7, 0.01, onset_time=onset)])
        x = X0.copy()
        K.plant_step(x, U, 0.01, DT, SUBSTEPS, params, faults, dist)
        return x

    mid = step(0.013)
    np.testing.assert_array_equal(mid, step(0.014))           # acts from the substep at 14 ms
    assert np.max(np.abs(mid - step(0.012))) > 1e-7          # one more substep of fault: 2 ms x ~10 m/s^2
    assert np.max(np.abs(mid - step(0.05))) > 1e-7           # and the fault does act within the step
    schedule = FaultSchedule([ActuatorFault(0, 0.7, 0.01, onset_time=0.013)])
    np.testing.assert_allclose(mid, reference_step(P, X0, U, 0.01, DT, SUBSTEPS, schedule),
                               rtol=0, atol=1e-12)


def test_kernel_onset_test_is_the_schedules_within_the_tolerance():
    """An onset a fraction of ONSET_TOLERANCE after the switch time still acts, two tolerances after it does not.

    A fraction of a tolerance late is a k*dt time that rounding put just short of the onset. This is the same answer as
    ActuatorFault.started, whose tolerance the fault table carries into the kernels.
    """
    params = K.params_vector(load_helicopter_params())
    uc, ua = np.zeros(4), np.zeros(4)
    u = np.full(4, 0.01)
    for shift, acts in ((0.5 * ONSET_TOLERANCE, True), (2.0 * ONSET_TOLERANCE, False), (0.0, True)):
        fault = ActuatorFault(0, 0.5, 0.0, onset_time=10.0 + shift)
        assert fault.started(10.0) is acts
        K.actual_inputs(u, 10.0, 10.0, params, K.fault_table([fault]), uc, ua)
        assert bool(ua[0] == 0.5 * uc[0]) is acts and ua[0] != 0.0, shift


def test_input_chain_limits_before_and_after_the_fault():
    params = K.params_vector(P)
    faults = K.fault_table([ActuatorFault(2, 1.0, 0.2), ActuatorFault(1, 0.5, -0.4), ActuatorFault(0, 0.0, 0.11)])
    uc, ua = np.empty(4), np.empty(4)
    K.actual_inputs(np.array([0.25, -0.3, 0.9, 0.0]), 0.0, 0.0, params, faults, uc, ua)
    np.testing.assert_array_equal(uc, [0.25, -0.3, 0.3, 0.0])       # 0.9 -> upper limit 0.3
    np.testing.assert_array_equal(ua, [0.11, -0.5, 0.3, 0.0])       # stuck; -0.55 -> -0.5; 0.5 -> 0.3


# ------------------------------------------------------------------------------------------------
# Lumped faults


def test_lumped_faults_kernel_equals_the_written_out_closed_form():
    schedule = FaultSchedule([ActuatorFault(0, 0.85, -0.01, onset_time=1.0),
                              ActuatorFault(2, 0.8, 0.0, 0.005, 0.3, onset_time=1.0)])
    params, faults, _ = _arrays(schedule.faults)
    f_p, f_w = np.empty(3), np.empty(3)
    K.lumped_faults(X0, U, 0.5, params, faults, f_p, f_w)  # before the onset: exactly zero
    np.testing.assert_array_equal(np.concatenate([f_p, f_w]), 0.0)
    t = 3.7
    K.lumped_faults(X0, U, t, params, faults, f_p, f_w)
    u_cmd = np.clip(U, P.input_lower, P.input_upper)
    u_act = np.clip(schedule.apply(u_cmd, t), P.input_lower, P.input_upper)
    closed_p, closed_w = lumped_faults(P, X0, u_cmd, u_act)
    # differences of O(10) quantities computed in another order
    np.testing.assert_allclose(f_p, closed_p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(f_w, closed_w, rtol=0, atol=1e-12)
    assert np.linalg.norm(f_p) > 1e-2 and np.linalg.norm(f_w) > 1e-2


# ------------------------------------------------------------------------------------------------
# The plant wrapper follows its schedule


def test_fault_table_follows_schedule_changes():
    plant = HelicopterPlant(P, None, X0)
    r0 = plant.faults.revision
    np.testing.assert_array_equal(plant.kernel_arrays().faults, 0.0)
    plant.faults.add(ActuatorFault(2, 0.9, 0.01))
    assert plant.faults.revision > r0
    table = plant.kernel_arrays().faults
    assert table[2, K.F_PRESENT] == 1.0 and table[2, K.F_RHO] == 0.9
    plant.faults.add(ActuatorFault(2, 0.6))                       # replaces channel 2
    assert plant.kernel_arrays().faults[2, K.F_RHO] == 0.6
    plant.faults.add(ActuatorFault(2, 1.0))                       # nominal: clears channel 2
    np.testing.assert_array_equal(plant.kernel_arrays().faults, 0.0)
    plant.faults.add(ActuatorFault(0, 0.5))
    plant.faults.clear()
    np.testing.assert_array_equal(plant.kernel_arrays().faults, 0.0)
    # kernel_arrays hands out copies: writing them does not change the plant
    arrays = plant.kernel_arrays()
    arrays.params[K.P_MASS] = 1.0
    assert plant.kernel_arrays().params[K.P_MASS] == P.mass and arrays.substeps == plant.substeps


def test_fault_injected_after_construction_acts_on_the_next_step():
    injected = HelicopterPlant(P, None, X0, disturbance=DIST)
    built = HelicopterPlant(P, FaultSchedule([ActuatorFault(3, 0.5, 0.01)]), X0, disturbance=DIST)
    healthy = HelicopterPlant(P, None, X0, disturbance=DIST)
    injected.step(U, 0.0, DT)                       # the healthy step happens first in both
    healthy.step(U, 0.0, DT)
    built.reset(injected.x)
    injected.faults.add(ActuatorFault(3, 0.5, 0.01))
    np.testing.assert_array_equal(injected.step(U, DT, DT), built.step(U, DT, DT))
    assert np.max(np.abs(injected.x - healthy.step(U, DT, DT))) > 1e-6
    f_p, f_w = injected.lumped_faults(U, 2 * DT)
    assert np.linalg.norm(f_w) > 1.0                # 0.5 delta_lon change of ~0.02 rad: ~3 rad/s^2


def test_replacing_the_schedule_object_is_followed_too():
    plant = HelicopterPlant(P, None, X0)
    plant.faults = FaultSchedule([ActuatorFault(1, 0.0, 0.1)])
    assert plant.actual_inputs(U, 0.0)[1] == 0.1
    assert plant.kernel_arrays().faults[1, K.F_PRESENT] == 1.0


def test_plant_rejects_bad_faults_disturbance_and_commands():
    with pytest.raises(FaultError, match='faults must be a FaultSchedule or None, got list'):
        HelicopterPlant(P, [ActuatorFault(0, 0.5)], X0)
    with pytest.raises(ValueError, match='disturbance must be a SinusoidalDisturbance or None, got float'):
        HelicopterPlant(P, None, X0, disturbance=0.3)
    plant = HelicopterPlant(P, None, X0)
    with pytest.raises(ValueError, match=r'command u_cmd must have 4 elements .* got shape \(3,\)'):
        plant.step([0.1, 0.0, 0.0], 0.0, DT)
    with pytest.raises(ValueError, match=r'command u_cmd must have 4 elements .* got shape \(5,\)'):
        plant.lumped_faults(np.zeros(5), 0.0)
    with pytest.raises(ValueError, match='disturbance must be a SinusoidalDisturbance or None, got function'):
        HelicopterPlant(P, None, X0, disturbance=lambda t: (0.0, 0.0, 0.1))


# ------------------------------------------------------------------------------------------------
# Use from njit code, and the compile helper


@njit
def _team_step(states, commands, t, dt, substeps, params, faults, disturbance, f_p, f_w):
    for c in range(states.shape[0]):
        K.lumped_faults(states[c], commands[c], t, params[c], faults[c], f_p[c], f_w[c])
        K.plant_step(states[c], commands[c], t, dt, substeps, params[c], faults[c], disturbance[c])


def test_kernels_called_from_njit_code_equal_the_plants():
    """The recipe of the plant_kernels docstring: stacked kernel_arrays, a loop over the UHs."""
    from uh_sim_node.helicopter import plant_from_scenario
    from uh_topology.scenario import load_scenario

    sc = load_scenario('paper')
    plants = [plant_from_scenario(sc, i, P) for i in sc.ids]
    arrays = [p.kernel_arrays() for p in plants]
    params = np.stack([a.params for a in arrays])
    faults = np.stack([a.faults for a in arrays])
    dist = np.stack([a.disturbance for a in arrays])
    states = np.stack([p.x for p in plants])
    commands = np.stack([hover_trim(P) + 0.01 * c for c in range(len(plants))])
    f_p, f_w = np.empty((len(plants), 3)), np.empty((len(plants), 3))
    for k in range(995, 1010):  # across the fault onset at 10 s
        t = k * sc.dt
        _team_step(states, commands, t, sc.dt, sc.substeps, params, faults, dist, f_p, f_w)
        for c, plant in enumerate(plants):
            fp, fw = plant.lumped_faults(commands[c], t)
            plant.step(commands[c], t, sc.dt)
            np.testing.assert_array_equal(f_p[c], fp)
            np.testing.assert_array_equal(f_w[c], fw)
            np.testing.assert_array_equal(states[c], plant.x)
    assert np.any(f_w != 0.0)  # the faults did switch on


def test_compile_plant_kernels_compiles_every_public_kernel():
    assert K.compile_plant_kernels() >= 0.0
    for name in ('plant_step', 'lumped_faults', 'lumped_faults_of_inputs',
                 'state_derivative', 'actual_inputs', 'force_disturbance'):
        assert getattr(K, name).signatures, name


def test_commands_of_any_array_kind_give_the_same_step():
    """Lists, read-only and strided arrays are converted once, to the one kernel signature."""
    ro = U.copy()
    ro.setflags(write=False)
    strided = np.repeat(U, 2)[::2]
    results = [HelicopterPlant(P, None, X0).step(u, 0.0, DT) for u in (U, list(U), ro, strided)]
    for r in results[1:]:
        np.testing.assert_array_equal(r, results[0])
    # no read-only or non-contiguous specialisation was compiled
    for sig in K.plant_step.signatures:
        assert all(arg.mutable and arg.layout == 'C' for arg in sig if hasattr(arg, 'layout')), sig


# ------------------------------------------------------------------------------------------------
# The cache guard: numba re-validates a kernel against its own file only


class _FakeCache:
    """What :func:`uh_core.kernel_cache.refresh_cache` uses of a numba dispatcher's ``_cache``."""

    def __init__(self, path):
        self.cache_path = str(path)
        self.flushes = 0

    def flush(self):
        self.flushes += 1


def _fake_dispatcher(path, module='uh_fake.kernels'):
    return SimpleNamespace(_cache=_FakeCache(path), py_func=SimpleNamespace(__module__=module))


def test_cache_is_flushed_when_a_dependency_changes_and_only_then(tmp_path):
    cache_dir = tmp_path / '__pycache__'
    cache_dir.mkdir()
    deps = [tmp_path / 'layout.py', tmp_path / 'faults.py']
    deps[0].write_text('STATE_SIZE = 12\n')
    deps[1].write_text('ONSET_TOLERANCE = 1e-9\n')
    a, b = _fake_dispatcher(cache_dir), _fake_dispatcher(cache_dir)

    def refresh():
        return kernel_cache.refresh_cache([a, b], deps)   # marker named after the module: kernels.*

    def flushes():
        return a._cache.flushes, b._cache.flushes

    assert refresh() and flushes() == (1, 1)           # no marker yet: whatever is cached is suspect
    marker = cache_dir / 'kernels.dependencies.sha256'
    assert marker.read_text().strip() == kernel_cache.dependency_digest(deps)
    assert not refresh() and flushes() == (1, 1)       # unchanged: the cache is kept
    deps[0].write_text('STATE_SIZE = 12\n')           # rewritten with the same content (new mtime)
    assert not refresh() and flushes() == (1, 1)
    deps[0].write_text('STATE_SIZE = 13\n')           # an edit of a dependency
    assert refresh() and flushes() == (2, 2)
    assert not refresh() and flushes() == (2, 2)
    deps[1].write_text('ONSET_TOLERANCE = 2e-9\n')    # any of them
    assert refresh() and flushes() == (3, 3)
    assert not refresh() and flushes() == (3, 3)


def test_cache_guard_leaves_what_it_cannot_read_or_use_alone(tmp_path):
    dispatcher = _fake_dispatcher(tmp_path)
    assert not kernel_cache.refresh_cache([dispatcher], [tmp_path / 'missing.py'], 'm.sha256')
    assert not kernel_cache.refresh_cache([SimpleNamespace(_cache=object())], [], 'm.sha256')  # caching off
    assert not kernel_cache.refresh_cache([], [], 'm.sha256')
    assert dispatcher._cache.flushes == 0


def test_module_dispatchers_are_the_cached_kernels_defined_in_the_module(tmp_path):
    own, imported = _fake_dispatcher(tmp_path, 'uh_fake.kernels'), _fake_dispatcher(tmp_path, 'uh_fake.other')
    namespace = {'__name__': 'uh_fake.kernels', 'own': own, 'imported': imported, 'constant': 12, 'np': np}
    assert kernel_cache.module_dispatchers(namespace) == [own]
    found = kernel_cache.module_dispatchers(vars(K))
    assert K.plant_step in found and K._rates in found and K._clip in found
    # plant_kernels registered the digest of uh_core/layout.py on import: nothing to flush now
    assert not kernel_cache.refresh_cache(found, [layout.__file__])
    assert (Path(K.plant_step._cache.cache_path) / 'plant_kernels.dependencies.sha256').is_file()
