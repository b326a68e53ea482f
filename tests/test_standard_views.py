"""The standard views for generic tools (docs/visualization.md).

Checked: frames and quaternions against closed forms and an independent implementation, odometry twist, message
builders, and every diagnostics level raised by the event that should raise it.
"""
import math

import numpy as np
import pytest

from uh_core import diagnostics as D
from uh_core import frames
from uh_wire.standard_msgs import diagnostic_array_msg, level_of, odometry_msg, tf_msg, transform_msg


@pytest.mark.parametrize('angle', [0.0, 0.3, -1.2, math.pi, 5.0])
def test_single_axis_quaternions_are_the_closed_forms(angle):
    s, c = math.sin(angle / 2), math.cos(angle / 2)
    assert frames.quaternion_from_euler_zyx(angle, 0, 0) == pytest.approx((s, 0, 0, c), abs=1e-15)
    assert frames.quaternion_from_euler_zyx(0, angle, 0) == pytest.approx((0, s, 0, c), abs=1e-15)
    assert frames.quaternion_from_euler_zyx(0, 0, angle) == pytest.approx((0, 0, s, c), abs=1e-15)


def test_quaternion_and_rotation_match_scipy_and_the_models_matrix():
    Rotation = pytest.importorskip('scipy.spatial.transform').Rotation
    rng = np.random.default_rng(7)
    for phi, theta, psi in rng.uniform([-1.4, -1.4, -6], [1.4, 1.4, 6], size=(200, 3)):
        q = frames.quaternion_from_euler_zyx(phi, theta, psi)
        # scipy's intrinsic 'ZYX' with (psi, theta, phi) is Rz(psi) Ry(theta) Rx(phi)
        expected = Rotation.from_euler('ZYX', [psi, theta, phi])
        # tolerance: a few ulps of float64 trigonometry
        assert np.allclose(Rotation.from_quat(q).as_matrix(), expected.as_matrix(), atol=1e-14)
        assert math.isclose(sum(v * v for v in q), 1.0, abs_tol=1e-15)
        R = frames.rotation_from_euler_zyx(phi, theta, psi)
        # docs/model.md's R written out: third row (-s_theta, c_theta s_phi, c_theta c_phi)
        assert np.allclose(R[2], [-math.sin(theta), math.cos(theta) * math.sin(phi),
                                  math.cos(theta) * math.cos(phi)], atol=1e-15)
        assert np.allclose(R, expected.as_matrix(), atol=1e-14)


def test_odometry_twist_is_in_the_body_frame():
    x = np.zeros(12)
    x[0:3] = (1.0, 2.0, 3.0)
    x[3:6] = (1.0, 0.0, 0.5)           # flying east and climbing
    x[6:9] = (0.0, 0.0, math.pi / 2)   # nose north
    x[9:12] = (0.1, -0.2, 0.3)
    linear, angular = frames.body_twist_of_state(x)
    # nose north (body x = north, body y = west): east is -y in the body frame (FLU)
    assert linear == pytest.approx((0.0, -1.0, 0.5), abs=1e-15)
    assert angular == (0.1, -0.2, 0.3)
    position, q = frames.pose_of_state(x)
    assert position == (1.0, 2.0, 3.0) and q == pytest.approx((0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)))
    msg = odometry_msg(3, 1.5, x)
    assert msg.header.frame_id == 'world' and msg.child_frame_id == 'uh3/base_link'
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1, 500_000_000)
    assert (msg.twist.twist.linear.y, msg.pose.pose.position.z) == (linear[1], 3.0)
    assert list(msg.pose.covariance) == [0.0] * 36


def test_tf_message_names_the_frames_by_ros_conventions():
    msg = tf_msg([transform_msg(0.25, frames.WORLD_FRAME, frames.base_link(4), (1, 2, 3), (0, 0, 0, 1))])
    (tr,) = msg.transforms
    assert (tr.header.frame_id, tr.child_frame_id) == ('world', 'uh4/base_link')
    assert (tr.transform.translation.z, tr.transform.rotation.w) == (3, 1)


def _levels(report):
    msg = diagnostic_array_msg(2.0, [report])
    (status,) = msg.status
    return level_of(status), status.message, {kv.key: kv.value for kv in status.values}


def test_a_quiet_window_is_ok():
    assert _levels(D.controller_diagnostic(1, D.ControllerWindow(steps=50, last_step=100)))[:2] == (D.OK, 'OK')
    assert _levels(D.simulator_diagnostic(1, D.SimulatorWindow(last_step=100)))[:2] == (D.OK, 'OK')


@pytest.mark.parametrize('event, level, words', [
    (dict(holding=True), D.ERROR, 'holding position'),
    (dict(not_computed=2), D.ERROR, '2 step(s) not computed'),
    (dict(stale_neighbours=('uh3',)), D.WARN, 'stale: uh3'),
    (dict(rejected_inputs=4), D.WARN, '4 input message(s) rejected'),
    (dict(saturated_steps=7), D.WARN, 'saturated in 7 of 50'),
    (dict(fault_isolated=(True, False, False, True)), D.WARN, 'fault isolated: collective, longitudinal'),
    (dict(max_input_lag=3), D.WARN, 'up to 3 step(s) behind'),
])
def test_each_controller_event_raises_its_level(event, level, words):
    got, message, values = _levels(D.controller_diagnostic(2, D.ControllerWindow(steps=50, **event)))
    assert got == level and words in message
    assert values['steps in window'] == '50'


@pytest.mark.parametrize('event, level, words', [
    (dict(stuck=True, fault_active=True), D.ERROR, 'stuck'),
    (dict(command_stale=True), D.ERROR, 'no command'),
    (dict(late_commands=3), D.WARN, '3 late command(s)'),
    (dict(rejected_commands=1), D.WARN, '1 command(s) rejected'),
    (dict(rejected_faults=1), D.WARN, '1 fault injection(s) rejected'),
    (dict(fault_active=True), D.WARN, 'actuator fault active'),
])
def test_each_simulator_event_raises_its_level(event, level, words):
    got, message, _ = _levels(D.simulator_diagnostic(5, D.SimulatorWindow(**event)))
    assert got == level and words in message


def test_an_error_outranks_warnings_and_both_are_listed():
    got, message, _ = _levels(D.controller_diagnostic(1, D.ControllerWindow(
        steps=10, holding=True, stale_neighbours=('uh3', 'reference'))))
    assert got == D.ERROR and message.index('holding') < message.index('stale: uh3, reference')
