"""Actuator faults of paper eq. 6 (docs/faults.md) and the true lumped faults (docs/model.md, "Lumped faults").

The plant is checked against the closed-form numpy model of ``model_oracle``.
"""
import math

import numpy as np
import pytest
from model_oracle import clip_inputs, lumped_faults, state_derivative

from uh_core.airframe import load_helicopter_params
from uh_sim_node.faults import ONSET_TOLERANCE, ActuatorFault, FaultError, FaultSchedule
from uh_sim_node.helicopter import HelicopterPlant, hover_trim

P = load_helicopter_params()
X = np.concatenate([[1.0, 2.0, 12.0], [0.8, -0.4, 0.3], [0.12, -0.08, 0.9], [0.3, -0.25, 0.4]])
U = hover_trim(P) + np.array([0.02, -0.01, 0.01, -0.015])  # inside the limits


# ------------------------------------------------------------------------------------------------
# Validation


@pytest.mark.parametrize('kwargs, message', [
    ({'channel': 4, 'rho': 0.5}, r'channel must be an int in 0..3 .*got 4'),
    ({'channel': -1, 'rho': 0.5}, r'channel must be an int in 0..3 .*got -1'),
    ({'channel': 1.0, 'rho': 0.5}, r'channel must be an int in 0..3 .*got 1.0'),
    ({'channel': True, 'rho': 0.5}, r'channel must be an int in 0..3 .*got True'),
    ({'channel': 0, 'rho': 1.2}, r'rho \(effectiveness\) must be in \[0, 1\], got 1.2 on channel 0 \(theta_col\)'),
    ({'channel': 3, 'rho': -0.1}, r'rho \(effectiveness\) must be in \[0, 1\], got -0.1 on channel 3 \(delta_lon\)'),
    ({'channel': 0, 'rho': float('nan')}, r"'rho' must be finite"),
    ({'channel': 0, 'rho': 0.5, 'bias_amplitude': float('inf')}, r"'bias_amplitude' must be finite"),
    ({'channel': 0, 'rho': 0.5, 'bias_constant': '0.1'}, r"'bias_constant' must be a real number"),
    ({'channel': 2, 'rho': 0.5, 'onset_time': -1.0}, r'onset_time must be >= 0 s, got -1.0 on channel 2'),
])
def test_invalid_faults_are_rejected(kwargs, message):
    with pytest.raises(FaultError, match=message):
        ActuatorFault(**kwargs)


def test_schedule_accepts_only_faults():
    with pytest.raises(FaultError, match='expects an ActuatorFault, got dict'):
        FaultSchedule().add({'channel': 0, 'rho': 0.5})


# ------------------------------------------------------------------------------------------------
# eq. 6 on one channel

CASES = {
    # name: (fault kwargs, closed form of u_actual(u, t) after onset)
    'loss_of_effectiveness': ({'rho': 0.7}, lambda u, t: 0.7 * u),
    'bias_constant': ({'rho': 1.0, 'bias_constant': 0.01}, lambda u, t: u + 0.01),
    'bias_sinusoid': ({'rho': 1.0, 'bias_constant': -0.002, 'bias_amplitude': 0.01, 'bias_frequency': 0.5},
                      lambda u, t: u - 0.002 + 0.01 * math.sin(0.5 * t)),
    'both': ({'rho': 0.8, 'bias_amplitude': 0.01, 'bias_frequency': 0.5},
             lambda u, t: 0.8 * u + 0.01 * math.sin(0.5 * t)),
    'stuck': ({'rho': 0.0, 'bias_constant': 0.03}, lambda u, t: 0.03),
}


@pytest.mark.parametrize('case', sorted(CASES))
@pytest.mark.parametrize('channel', range(4))
def test_each_fault_case_changes_the_input_as_eq6_says(case, channel):
    kwargs, closed_form = CASES[case]
    fault = ActuatorFault(channel=channel, onset_time=2.0, **kwargs)
    sched = FaultSchedule([fault])
    for t in (0.0, 1.0, 1.99):
        # before the onset: rho = 1, b = 0 on every channel
        np.testing.assert_array_equal(sched.apply(U, t), U)
        assert not sched.active(t) and not sched.stuck(t)
    for t in (2.0, 3.3, 17.0):
        expected = U.copy()
        expected[channel] = closed_form(U[channel], t)
        np.testing.assert_allclose(sched.apply(U, t), expected, rtol=0, atol=1e-16)
        assert sched.active(t)
        assert sched.stuck(t) == (case == 'stuck')
        assert sched.active_channels(t) == (channel,)


@pytest.mark.parametrize('case', sorted(CASES))
def test_plant_dynamics_use_the_faulted_input(case):
    """plant.derivative == state_derivative at clip(eq. 6 (clip(u_cmd)))."""
    kwargs, closed_form = CASES[case]
    for channel in range(4):
        plant = HelicopterPlant(P, FaultSchedule([ActuatorFault(channel, onset_time=5.0, **kwargs)]), X)
        for t in (4.0, 6.5):
            expected_u = U.copy()
            if t >= 5.0:
                expected_u[channel] = closed_form(U[channel], t)
            expected_u = clip_inputs(P, expected_u)
            np.testing.assert_allclose(plant.actual_inputs(U, t), expected_u, atol=1e-16)
            np.testing.assert_allclose(plant.derivative(U, t), state_derivative(P, X, expected_u), atol=1e-13)
            assert plant.fault_active(t) == (t >= 5.0)
            assert plant.stuck(t) == (case == 'stuck' and t >= 5.0)


def test_faulted_plant_equals_healthy_plant_driven_by_the_actual_input():
    """A constant fault (LOE + constant bias) is the same as a healthy plant with u_actual = rho u + b.

    Integrating the faulty plant with u_cmd is the same as integrating a healthy plant with u_actual = rho u + b.
    """
    faults = FaultSchedule([ActuatorFault(0, 0.8, 0.01), ActuatorFault(3, 0.75, -0.005)])
    faulty = HelicopterPlant(P, faults, X)
    healthy = HelicopterPlant(P, None, X)
    u_actual = U.copy()
    u_actual[0] = 0.8 * U[0] + 0.01
    u_actual[3] = 0.75 * U[3] - 0.005
    for k in range(100):
        faulty.step(U, k * 0.01, 0.01)
        healthy.step(u_actual, k * 0.01, 0.01)
    # identical arithmetic except for rho u + b rounding (1e-17 rad) propagated over 1 s
    np.testing.assert_allclose(faulty.x, healthy.x, atol=1e-12)
    nominal = HelicopterPlant(P, None, X)
    for k in range(100):
        nominal.step(U, k * 0.01, 0.01)
    assert np.max(np.abs(faulty.x - nominal.x)) > 1e-3  # and the fault matters


def test_stuck_actuator_ignores_the_command():
    faults = FaultSchedule([ActuatorFault(0, 0.0, 0.11, onset_time=0.0)])
    a = HelicopterPlant(P, faults, X)
    b = HelicopterPlant(P, FaultSchedule(faults.faults), X)
    u_low, u_high = U.copy(), U.copy()
    u_low[0], u_high[0] = -0.05, 0.25
    for k in range(50):
        a.step(u_low, k * 0.01, 0.01)
        b.step(u_high, k * 0.01, 0.01)
    np.testing.assert_array_equal(a.x, b.x)
    assert a.stuck(0.0) and a.actual_inputs(u_low, 0.3)[0] == 0.11


def test_faulted_input_is_limited_again():
    """A bias cannot push an actuator beyond its travel: limits apply after the fault."""
    faults = FaultSchedule([ActuatorFault(2, 1.0, 0.2), ActuatorFault(1, 0.5, -0.4)])
    plant = HelicopterPlant(P, faults, X)
    u = np.array([0.1, -0.3, 0.25, 0.0])
    ua = plant.actual_inputs(u, 0.0)
    assert ua[2] == P.input_upper[2]          # 0.25 + 0.2 -> 0.3
    assert ua[1] == P.input_lower[1]          # 0.5 * -0.3 - 0.4 = -0.55 -> -0.5
    # the command itself is limited first: 0.9 -> 0.3, then 0.3 + 0.2 -> 0.3
    assert plant.actual_inputs([0.1, 0.0, 0.9, 0.0], 0.0)[2] == P.input_upper[2]


def test_onset_on_the_step_grid_switches_at_that_step():
    fault = ActuatorFault(0, 0.8, onset_time=10.0)
    k_dt = 1000 * 0.01
    assert fault.started(k_dt) and fault.started(10.0 - 0.5 * ONSET_TOLERANCE)
    assert not fault.started(10.0 - 1e-6)


# ------------------------------------------------------------------------------------------------
# Schedule bookkeeping


def test_add_replaces_the_fault_of_the_same_channel_and_nominal_clears_it():
    sched = FaultSchedule([ActuatorFault(0, 0.5), ActuatorFault(2, 0.9)])
    assert len(sched) == 2
    sched.add(ActuatorFault(0, 0.8, 0.01))
    assert sched.fault(0).rho == 0.8 and len(sched) == 2
    sched.add(ActuatorFault(0, 1.0))         # nominal: rho = 1, no bias
    assert sched.fault(0) is None and len(sched) == 1
    np.testing.assert_allclose(sched.apply(U, 1.0), [U[0], U[1], 0.9 * U[2], U[3]], atol=1e-16)
    sched.clear()
    assert len(sched) == 0 and not sched.active(100.0)


def test_injected_fault_acts_on_an_existing_plant():
    plant = HelicopterPlant(P, None, X)
    assert not plant.fault_active(0.0)
    plant.faults.add(ActuatorFault(3, 0.5, onset_time=0.0))
    assert plant.fault_active(0.0)
    assert plant.actual_inputs(U, 0.0)[3] == pytest.approx(0.5 * U[3], abs=1e-17)


# ------------------------------------------------------------------------------------------------
# Lumped faults (docs/model.md, "Lumped faults")


def test_lumped_faults_are_zero_without_faults_and_before_onset():
    plant = HelicopterPlant(P, FaultSchedule([ActuatorFault(0, 0.8, 0.01, onset_time=3.0)]), X)
    for t in (0.0, 2.9):
        f_p, f_w = plant.lumped_faults(U, t)
        np.testing.assert_array_equal(f_p, 0.0)
        np.testing.assert_array_equal(f_w, 0.0)
    f_p, f_w = HelicopterPlant(P, None, X).lumped_faults(U, 5.0)
    np.testing.assert_array_equal(f_p, 0.0)
    np.testing.assert_array_equal(f_w, 0.0)


@pytest.mark.parametrize('faults', [
    [ActuatorFault(0, 0.8, 0.0, 0.01, 0.5)],                                  # collective: F_p and F_w
    [ActuatorFault(2, 0.85, 0.005)],                                          # lateral cyclic
    [ActuatorFault(3, 0.75, -0.005), ActuatorFault(1, 0.8, 0.01)],           # UH3 of the paper
    [ActuatorFault(0, 0.85, -0.01), ActuatorFault(2, 0.8, 0.0, 0.005, 0.3)],  # UH5 of the paper
    [ActuatorFault(0, 0.0, 0.05)],                                            # stuck collective
])
def test_lumped_faults_equal_the_difference_of_the_dynamics(faults):
    """F_p = v'(u_actual) - v'(u_cmd), F_w = omega'(u_actual) - omega'(u_cmd) at the same state."""
    plant = HelicopterPlant(P, FaultSchedule(faults), X)
    t = 3.7
    u_cmd = clip_inputs(P, U)
    u_act = plant.actual_inputs(U, t)
    diff = state_derivative(P, X, u_act) - state_derivative(P, X, u_cmd)
    f_p, f_w = plant.lumped_faults(U, t)
    # both sides are differences of O(10) quantities: agreement to ~1e-14
    np.testing.assert_allclose(f_p, diff[3:6], atol=1e-12)
    np.testing.assert_allclose(f_w, diff[9:12], atol=1e-12)
    np.testing.assert_array_equal(diff[0:3], 0.0)
    np.testing.assert_array_equal(diff[6:9], 0.0)
    # the written-out closed form: F_p the thrust change along the rotor axis, F_w term by term
    closed_p, closed_w = lumped_faults(P, X, u_cmd, u_act)
    np.testing.assert_allclose(f_p, closed_p, atol=1e-12)
    np.testing.assert_allclose(f_w, closed_w, atol=1e-12)
    assert np.linalg.norm(f_p) + np.linalg.norm(f_w) > 1e-3  # the fault does something


def test_lumped_faults_match_a_finite_difference_of_the_integrated_state():
    """Over a short step the faulty and healthy plants differ by F dt in the velocities."""
    faults = FaultSchedule([ActuatorFault(0, 0.8, 0.01), ActuatorFault(2, 0.85, 0.005)])
    dt = 1e-5
    faulty = HelicopterPlant(P, faults, X, substeps=1)
    healthy = HelicopterPlant(P, None, X, substeps=1)
    f_p, f_w = faulty.lumped_faults(U, 0.0)
    dv = (faulty.step(U, 0.0, dt) - healthy.step(U, 0.0, dt)) / dt
    # the trajectories separate, and the separation feeds back through the rotor damping
    # (~40 1/s on the roll rate): the slope is F (1 - O(20 dt)) = F (1 - 2e-4); rounding of the
    # velocity difference is ~eps |v| / dt ~ 1e-11
    np.testing.assert_allclose(dv[3:6], f_p, rtol=1e-3, atol=1e-6)
    np.testing.assert_allclose(dv[9:12], f_w, rtol=1e-3, atol=1e-5)
