"""Helicopter model of docs/model.md: parameters, kinematics, trim, free fall, RK4 integration.

The plant (:class:`uh_sim_node.helicopter.HelicopterPlant` and its kernels) is checked against the
closed-form numpy model of ``model_oracle``; the kinematics tests check that oracle itself.
"""
import math

import numpy as np
import pytest
from model_oracle import (
    clip_inputs,
    euler_rate_matrix,
    reference_step,
    rotation_matrix,
    rotor_moments,
    state_derivative,
    thrust,
)

from uh_controller_node.nominal_model import nominal_model
from uh_core.airframe import HelicopterParams, HelicopterParamsError, default_params_path, load_helicopter_params
from uh_core.layout import INPUT_NAMES
from uh_sim_node import plant_kernels as K
from uh_sim_node.faults import ActuatorFault, FaultSchedule
from uh_sim_node.helicopter import HelicopterPlant, SinusoidalDisturbance, hover_trim

P = load_helicopter_params()
RNG_SEED = 20250603


def _state(p=(0.0, 0.0, 0.0), v=(0.0, 0.0, 0.0), euler=(0.0, 0.0, 0.0), omega=(0.0, 0.0, 0.0)):
    return np.concatenate([p, v, euler, omega]).astype(float)


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _skew(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def _kernel_derivative(x, u_actual, d_p=(0.0, 0.0, 0.0)):
    """Return the kernel's state derivative (12,) for the inputs ``u_actual`` (not limited) and force ``d_p``."""
    out = np.empty(12)
    K.state_derivative(np.asarray(x, dtype=float), np.asarray(u_actual, dtype=float),
                       np.asarray(d_p, dtype=float), K.params_vector(P), out)
    return out


# ------------------------------------------------------------------------------------------------
# Parameters


def test_bundled_parameters_are_those_of_design_2_1():
    assert default_params_path().name == 'helicopter.yaml'
    assert P.mass == 8.2 and P.gravity == 9.81
    np.testing.assert_array_equal(P.inertia, [0.18, 0.34, 0.28])
    assert (P.c_M1, P.c_M2, P.K_beta, P.h_M) == (700.0, 10.0, 54.0, 0.235)
    assert (P.B_lat, P.A_lon, P.tau_f, P.K_tr, P.D_r, P.c_Q, P.D_v) == (1.0, 1.0, 0.1, 30.0, 0.5, 0.02, 0.5)
    np.testing.assert_array_equal(P.input_lower, [-0.1, -0.5, -0.3, -0.3])
    np.testing.assert_array_equal(P.input_upper, [0.3, 0.5, 0.3, 0.3])
    assert INPUT_NAMES == ('theta_col', 'theta_tr', 'delta_lat', 'delta_lon')
    assert load_helicopter_params('helicopter').as_dict() == P.as_dict()  # bundled name


def test_parameters_are_read_only():
    with pytest.raises(ValueError):
        P.inertia[0] = 1.0
    with pytest.raises(AttributeError):
        P.mass = 1.0


def test_nominal_model_mismatch_changes_only_drag_and_torque_reaction():
    nom = nominal_model(P, 0.9)
    assert nom.D_v == pytest.approx(0.45, rel=1e-15) and nom.c_Q == pytest.approx(0.018, rel=1e-15)
    for name, value in P.as_dict().items():
        if name not in ('D_v', 'c_Q'):
            np.testing.assert_array_equal(getattr(nom, name), value, err_msg=name)
    assert P.D_v == 0.5  # original untouched


def _write_params(tmp_path, **changes):
    data = P.as_dict()
    for key, value in changes.items():
        if value is None:
            del data[key]
        else:
            data[key] = value
    import yaml
    path = tmp_path / 'heli.yaml'
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize('changes, message', [
    ({'mass': None}, r"missing key\(s\) \['mass'\]"),
    ({'masss': 8.0}, r"unknown key\(s\) \['masss'\]"),
    ({'mass': 'heavy'}, r"'mass' must be a real number, got 'heavy'"),
    ({'mass': float('nan')}, r"'mass' must be finite"),
    ({'mass': -1.0}, r"'mass' must be > 0"),
    ({'D_v': -0.1}, r"'D_v' must be >= 0"),
    ({'inertia': [0.1, 0.2]}, r"'inertia' must have 3 elements"),
    ({'inertia': [0.1, 0.0, 0.2]}, r'"inertia" must be > 0 on every axis'),
    ({'input_lower': [0.3, -0.5, -0.3, -0.3]}, r"input_lower < input_upper; violated for \['theta_col'\]"),
    ({'input_upper': 'wide'}, r"'input_upper' must be a list of numbers"),
])
def test_invalid_parameter_files_raise_clear_errors(tmp_path, changes, message):
    path = _write_params(tmp_path, **changes)
    with pytest.raises(HelicopterParamsError, match=message):
        load_helicopter_params(path)


def test_parameter_file_errors_name_file_and_line(tmp_path):
    missing = tmp_path / 'none.yaml'
    with pytest.raises(HelicopterParamsError, match='cannot read helicopter parameters .*none.yaml'):
        load_helicopter_params(missing)
    bad = tmp_path / 'bad.yaml'
    bad.write_text('mass: 8.2\ninertia: [0.1, 0.2\ngravity: 9.81\n')
    with pytest.raises(HelicopterParamsError, match=r'YAML syntax error in .*bad.yaml.* at line \d'):
        load_helicopter_params(bad)


def test_an_airframe_file_that_is_not_utf8_is_one_line_naming_the_byte(tmp_path):
    path = tmp_path / 'airframe.yaml'
    data = default_params_path().read_bytes() + b'# \x80\n'
    path.write_bytes(data)
    offset = data.index(b'\x80')
    with pytest.raises(HelicopterParamsError) as info:
        load_helicopter_params(path)
    line = data[:offset].count(b'\n') + 1
    assert str(info.value) == (f'{path}:{line}: not UTF-8 text: byte 0x80 at offset {offset}; '
                               'allowed: a YAML text file in UTF-8')


def test_uh_simulate_with_an_airframe_that_is_not_utf8_exits_2_with_one_line(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    from scenario_texts import paper_yaml
    airframe = tmp_path / 'airframe.yaml'
    airframe.write_bytes(default_params_path().read_bytes() + b'# \x80\n')
    scenario = tmp_path / 'team.yaml'
    text = paper_yaml()
    assert '\nhelicopter: helicopter' in text
    scenario.write_text(text.replace('\nhelicopter: helicopter', f'\nhelicopter: {airframe}'))
    result = subprocess.run([str(Path(sys.executable).with_name('uh-simulate')), '--scenario', str(scenario),
                             '--out', str(tmp_path / 'out')], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2, result.stderr
    assert result.stderr.count('\n') == 1 and 'Traceback' not in result.stderr, result.stderr
    assert 'not UTF-8 text: byte 0x80' in result.stderr


# ------------------------------------------------------------------------------------------------
# Kinematics (the oracle's matrices against their definitions, the kernel against the oracle)


def test_rotation_matrix_is_zyx_and_orthonormal():
    rng = np.random.default_rng(RNG_SEED)
    for _ in range(20):
        e = rng.uniform([-1.2, -1.2, -math.pi], [1.2, 1.2, math.pi])
        R = rotation_matrix(e)
        np.testing.assert_allclose(R, _rz(e[2]) @ _ry(e[1]) @ _rx(e[0]), atol=1e-15)
        # orthonormal to rounding of a product of three rotations (a few ulps)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)


def test_euler_rate_matrix_matches_numeric_derivative_of_R():
    """R' = R [omega]x for body rates; Theta' = H omega must reproduce it."""
    rng = np.random.default_rng(RNG_SEED + 1)
    delta = 1e-6
    for _ in range(20):
        e = rng.uniform([-1.0, -1.0, -math.pi], [1.0, 1.0, math.pi])
        w = rng.uniform(-2.0, 2.0, 3)
        edot = euler_rate_matrix(e) @ w
        numeric = (rotation_matrix(e + delta * edot) - rotation_matrix(e - delta * edot)) / (2 * delta)
        # central difference: truncation ~ delta^2 |R'''| ~ 1e-11, rounding ~ eps / delta ~ 1e-10
        np.testing.assert_allclose(numeric, rotation_matrix(e) @ _skew(w), atol=1e-8)


def test_euler_rate_matrix_closed_form_inverse():
    e = np.array([0.3, -0.4, 1.1])
    phi, th = e[0], e[1]
    h_inv = np.array([[1, 0, -math.sin(th)],
                      [0, math.cos(phi), math.sin(phi) * math.cos(th)],
                      [0, -math.sin(phi), math.cos(phi) * math.cos(th)]])
    np.testing.assert_allclose(euler_rate_matrix(e) @ h_inv, np.eye(3), atol=1e-14)


def test_state_derivative_kinematic_rows():
    x = _state(p=(1, 2, 3), v=(0.5, -1.0, 2.0), euler=(0.2, -0.3, 0.9), omega=(0.4, -0.7, 0.25))
    xdot = HelicopterPlant(P, None, x).derivative(hover_trim(P), 0.0)
    np.testing.assert_array_equal(xdot[0:3], x[3:6])                       # p' = v
    np.testing.assert_allclose(xdot[6:9], euler_rate_matrix(x[6:9]) @ x[9:12], atol=1e-15)


def test_rotor_moments_are_the_flapping_and_tail_rotor_moments_of_docs_model():
    """The oracle's Gamma written term by term (docs/model.md, "Helicopter dynamics")."""
    w, u = np.array([0.4, -0.7, 0.25]), np.array([0.12, 0.05, -0.02, 0.03])
    T = P.c_M1 * 0.12 + P.c_M2
    assert thrust(P, u[0]) == T
    np.testing.assert_allclose(rotor_moments(P, w, u),
                               [(P.K_beta + T * P.h_M) * (P.B_lat * -0.02 - P.tau_f * 0.4),
                                (P.K_beta + T * P.h_M) * (P.A_lon * 0.03 - P.tau_f * -0.7),
                                P.K_tr * 0.05 - P.D_r * 0.25 - P.c_Q * T], rtol=0, atol=1e-13)


def test_plant_derivative_matches_the_vector_form_of_docs_model():
    """The plant's derivative (input chain, disturbance and rates in the kernels) against the oracle's matrix form.

    The matrix form is that of m v' and J omega'; they are compared at generic states, inputs and times.
    """
    rng = np.random.default_rng(RNG_SEED + 2)
    dist = SinusoidalDisturbance([0.3, 0.3, 0.2], [0.5, 4.0, 3.0], [0.0, 1.0, 2.0])
    for _ in range(10):
        x = _state(p=rng.normal(size=3), v=rng.normal(size=3), euler=rng.uniform(-0.8, 0.8, 3),
                   omega=rng.normal(size=3))
        u = rng.uniform(P.input_lower, P.input_upper)
        t = rng.uniform(0.0, 20.0)
        xdot = HelicopterPlant(P, None, x, disturbance=dist).derivative(u, t)
        np.testing.assert_allclose(xdot, state_derivative(P, x, u, dist(t)), rtol=0, atol=1e-12)


# ------------------------------------------------------------------------------------------------
# Trim, free fall, limits


@pytest.mark.parametrize('yaw', [0.0, 0.7, -2.5])
def test_hover_trim_is_an_equilibrium(yaw):
    """One trim holds at every heading: the model is symmetric in yaw."""
    u = hover_trim(P)
    np.testing.assert_array_equal(clip_inputs(P, u), u)  # inside the limits
    assert thrust(P, u[0]) == pytest.approx(P.mass * P.gravity, rel=1e-14)
    x0 = _state(p=(1.0, -2.0, 10.0), euler=(0.0, 0.0, yaw))
    # exact equilibrium up to the rounding of (m g - c_M2) / c_M1 (relative 1e-16 of 80 N)
    plant = HelicopterPlant(P, None, x0, substeps=5)
    np.testing.assert_allclose(plant.derivative(u, 0.0), np.zeros(12), atol=1e-13)
    for k in range(1000):  # 10 s at dt = 0.01
        plant.step(u, k * 0.01, 0.01)
    # a residual acceleration of 1e-14 m/s^2 moves the helicopter 5e-13 m in 10 s; 1e-9 m leaves
    # four orders of margin and still catches any real imbalance (1e-6 m/s^2 would move 5e-5 m)
    np.testing.assert_allclose(plant.x, x0, atol=1e-9)


def test_free_fall_with_zero_thrust():
    """theta_col = -c_M2/c_M1 gives T_M = 0: v' = -g e3 - (D_v/m) v + d_p/m, no rotor moments."""
    u0 = -P.c_M2 / P.c_M1
    assert thrust(P, u0) == pytest.approx(0.0, abs=1e-13)
    v = np.array([1.0, -2.0, 3.0])
    d = np.array([0.2, -0.1, 0.3])
    x = _state(p=(0, 0, 50), v=v, euler=(0.3, -0.2, 1.0))  # attitude irrelevant without thrust
    xdot = _kernel_derivative(x, [u0, 0.0, 0.0, 0.0], d)
    np.testing.assert_allclose(xdot[3:6], -P.gravity * np.array([0, 0, 1.0]) - P.D_v / P.mass * v + d / P.mass,
                               atol=1e-14)
    np.testing.assert_allclose(xdot[9:12], 0.0, atol=1e-15)  # K_beta b_1s = 0 at zero rates and cyclics


def test_free_fall_trajectory_matches_closed_form():
    """Zero thrust (inside the limits here) and linear drag: v(t) = v_inf + (v0 - v_inf) e^{-kt}."""
    u = np.array([-P.c_M2 / P.c_M1, 0.0, 0.0, 0.0])
    k = P.D_v / P.mass
    v0 = np.array([2.0, -1.0, 3.0])
    p0 = np.array([0.0, 0.0, 100.0])
    plant = HelicopterPlant(P, None, _state(p=p0, v=v0), substeps=5)
    t_end, dt = 3.0, 0.01
    for i in range(300):
        plant.step(u, i * dt, dt)
    v_inf = np.array([0.0, 0.0, -P.gravity / k])
    e = math.exp(-k * t_end)
    v_exact = v_inf + (v0 - v_inf) * e
    p_exact = p0 + v_inf * t_end + (v0 - v_inf) * (1 - e) / k
    # RK4 global error ~ (k h)^4 |v| t with k h = 1.2e-4: far below 1e-9
    np.testing.assert_allclose(plant.x[3:6], v_exact, atol=1e-9)
    np.testing.assert_allclose(plant.x[0:3], p_exact, atol=1e-9)
    np.testing.assert_allclose(plant.x[6:12], 0.0, atol=1e-15)


def test_commands_are_limited_before_they_act():
    lo, hi = P.input_lower, P.input_upper
    u = np.array([0.5, -0.9, 0.31, -1.0])
    np.testing.assert_array_equal(clip_inputs(P, u), [hi[0], lo[1], hi[2], lo[3]])
    x0 = _state(p=(0, 0, 10), omega=(0.1, 0.0, -0.1))
    a = HelicopterPlant(P, None, x0)
    b = HelicopterPlant(P, None, x0)
    a.step(u, 0.0, 0.01)
    b.step(clip_inputs(P, u), 0.0, 0.01)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.actual_inputs(u, 0.0), clip_inputs(P, u))


# ------------------------------------------------------------------------------------------------
# Integration


def _maneuver():
    faults = FaultSchedule([ActuatorFault(0, 0.8, 0.0, 0.01, 0.5, 0.05),
                            ActuatorFault(2, 0.85, 0.002, 0.003, 7.0, 0.0)])
    dist = SinusoidalDisturbance([0.3, 0.3, 0.2], [0.5, 4.0, 3.0], [0.0, 1.0, 2.0])
    x0 = _state(p=(1, 2, 10), v=(1.0, -0.5, 0.3), euler=(0.1, -0.05, 0.4), omega=(0.3, -0.2, 0.5))
    u = hover_trim(P) + np.array([0.01, 0.02, 0.002, -0.003])
    return faults, dist, x0, u


def test_step_equals_textbook_rk4_with_faults_and_disturbance():
    faults, dist, x0, u = _maneuver()
    plant = HelicopterPlant(P, faults, x0, substeps=5, disturbance=dist)
    x = x0.copy()
    for k in range(20):  # across the onset at 0.05 s
        t = k * 0.01
        x = reference_step(P, x, u, t, 0.01, 5, faults, dist)
        plant.step(u, t, 0.01)
        # same arithmetic in a different order: agreement to rounding of O(10) numbers
        np.testing.assert_allclose(plant.x, x, rtol=0, atol=1e-12)


def test_rk4_converges_with_order_four():
    """Halving the substep divides the error by ~16, also with time-varying faults/disturbance.

    They are evaluated at the stage times; a zero-order hold per substep would give order 1.
    """
    faults, dist, x0, u = _maneuver()
    t_end = 0.5

    def run(n):
        plant = HelicopterPlant(P, faults, x0, substeps=n, disturbance=dist)
        return plant.step(u, 0.0, t_end)

    # the fault onset at 0.05 s is a jump of u_actual; it sits on a substep boundary for every n
    # below (n multiple of 10) and switches there, so the inputs are smooth within each substep
    # roll-rate damping (K_beta + T h_M) tau_f / J_x ~ 40 1/s: substeps h <= 12.5 ms keep h lambda
    # <= 0.5, inside the asymptotic range; the reference has errors ~1e-4 of the coarsest
    ref = run(2560)
    errs = [np.max(np.abs(run(n) - ref)) for n in (40, 80, 160)]
    orders = [math.log2(errs[i] / errs[i + 1]) for i in range(2)]
    for order in orders:
        assert 3.6 < order < 4.4, (errs, orders)


def test_step_rejects_bad_construction():
    with pytest.raises(ValueError, match='substeps must be an int >= 1'):
        HelicopterPlant(P, None, None, substeps=0)
    with pytest.raises(ValueError, match='12 finite numbers'):
        HelicopterPlant(P, None, np.zeros(11))
    with pytest.raises(ValueError, match='12 finite numbers'):
        HelicopterPlant(P, None, np.full(12, np.nan))


@pytest.mark.parametrize('disturbance', [lambda t: (0.0, 0.0, 0.1), (0.3, 0.2, 0.1), 0.3])
def test_a_disturbance_must_be_a_sinusoid_or_none(disturbance):
    """The kernels evaluate the sinusoid themselves; they cannot call a Python function."""
    kind = type(disturbance).__name__
    with pytest.raises(ValueError, match=f'disturbance must be a SinusoidalDisturbance or None, got {kind}'):
        HelicopterPlant(P, None, None, disturbance=disturbance)
    plant = HelicopterPlant(P, None, None, disturbance=SinusoidalDisturbance([0.1] * 3, [1.0] * 3))
    with pytest.raises(ValueError, match='disturbance must be a SinusoidalDisturbance or None'):
        plant.disturbance = disturbance
    assert isinstance(plant.disturbance, SinusoidalDisturbance)   # the old one is kept
    plant.disturbance = None
    np.testing.assert_array_equal(plant.kernel_arrays().disturbance, 0.0)


def test_state_property_is_a_copy():
    plant = HelicopterPlant(P, None, _state(p=(0, 0, 5)))
    x = plant.x
    x[2] = 99.0
    assert plant.x[2] == 5.0
    assert isinstance(plant, HelicopterPlant) and isinstance(P, HelicopterParams)


# ------------------------------------------------------------------------------------------------
# Disturbance and construction from a scenario


def test_sinusoidal_disturbance_moves_the_helicopter():
    """At the hover trim (an equilibrium without force) the sinusoid alone moves the helicopter."""
    sinus = SinusoidalDisturbance([0.3, 0.2, 0.1], [0.5, 0.4, 0.3], [0.0, 1.0, 2.0])
    x0 = _state(p=(0, 0, 10))
    a = HelicopterPlant(P, None, x0, disturbance=sinus)
    u = hover_trim(P)
    for k in range(100):
        a.step(u, k * 0.01, 0.01)
    # the disturbance moves the helicopter: d/m t^2 / 2 ~ 0.3 / 8.2 / 2 ~ 0.02 m in 1 s
    assert np.linalg.norm(a.x[0:3] - x0[0:3]) > 1e-3
    np.testing.assert_allclose(sinus(2.0), [0.3 * math.sin(1.0), 0.2 * math.sin(1.8), 0.1 * math.sin(2.6)],
                               atol=1e-16)


def test_plant_from_the_paper_scenario():
    from uh_sim_node.helicopter import disturbance_from_spec, plant_from_scenario
    from uh_topology.scenario import load_scenario

    s = load_scenario('paper')
    for i in s.ids:
        plant = plant_from_scenario(s, i, P)
        np.testing.assert_array_equal(plant.x, s.initial_states[i])
        assert plant.substeps == s.substeps
        assert [f.channel for f in plant.faults.faults] == [f.channel for f in s.faults[i]]
        assert not plant.fault_active(9.99) and plant.fault_active(10.0) == bool(s.faults[i])
        d = plant.disturbance
        expected_phase = np.asarray(s.disturbance.phase) + i * s.disturbance.phase_per_id
        np.testing.assert_allclose(d.phase, expected_phase, atol=1e-15)
    assert disturbance_from_spec(None, 1) is None
