"""Conversions between uh_msgs messages and the numpy arrays of the control core.

Every receiver checks what it takes off the wire: a message carrying NaN or inf, or an id that is
not the expected one, raises :class:`WireError`, and the node logs the reason and keeps its last
valid input. The functions work on both node backends (rosidl classes on rclpy, IdlStruct classes
on Cyclone DDS): they only read and set attributes.
"""
from __future__ import annotations

import math

import numpy as np

from uh_runtime import messages as m

__all__ = [
    'WireError', 'stamp', 'stamp_seconds', 'step_of', 'state_to_msg', 'msg_to_state',
    'command_to_msg', 'msg_to_command', 'reference_to_msg', 'msg_to_reference', 'fault_truth_to_msg',
    'status_to_msg', 'vector3', 'clock_msg', 'clock_step',
]

FRAME_ID = 'world'


class WireError(ValueError):
    """A received message is unusable (non-finite values, wrong id, wrong step)."""


def stamp(t: float):
    """``builtin_interfaces/Time`` for simulation time ``t`` (s), rounded to the nanosecond."""
    ns = int(round(t * 1e9))
    msg = m.Time()
    msg.sec, msg.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
    return msg


def stamp_seconds(time_msg) -> float:
    """Seconds of a ``builtin_interfaces/Time``."""
    return time_msg.sec + time_msg.nanosec * 1e-9


def clock_msg(t: float):
    """``rosgraph_msgs/Clock`` for simulation time ``t``."""
    msg = m.Clock()
    msg.clock = stamp(t)
    return msg


def clock_step(msg, dt: float) -> int:
    """Step index k of a ``/clock`` message (t_k = k dt, stamps rounded to the nanosecond)."""
    return int(round(stamp_seconds(msg.clock) / dt))


def step_of(msg) -> int:
    return int(msg.step)


def _header(t: float):
    header = m.Header()
    header.stamp = stamp(t)
    header.frame_id = FRAME_ID
    return header


def vector3(values) -> object:
    vec = m.Vector3()
    vec.x, vec.y, vec.z = float(values[0]), float(values[1]), float(values[2])
    return vec


def _array(*vectors) -> np.ndarray:
    out = np.array([c for v in vectors for c in (v.x, v.y, v.z)], dtype=float)
    return out


def _check_finite(values, what: str) -> None:
    if not all(math.isfinite(float(v)) for v in np.ravel(values)):
        raise WireError(f'{what} carries a non-finite value (NaN or inf): {np.ravel(values).tolist()}')


def state_to_msg(uh_id: int, k: int, t: float, x: np.ndarray):
    """``UHState`` of UH ``uh_id`` at step ``k`` (time ``t``) from state vector ``x`` (12,)."""
    msg = m.UHState()
    msg.header = _header(t)
    msg.uh_id, msg.step = int(uh_id), int(k)
    msg.position, msg.velocity = vector3(x[0:3]), vector3(x[3:6])
    msg.euler, msg.body_rates = vector3(x[6:9]), vector3(x[9:12])
    return msg


def msg_to_state(msg, expected_id: int | None = None) -> np.ndarray:
    """State vector (12,) of a ``UHState``; raises :class:`WireError` if unusable."""
    if expected_id is not None and int(msg.uh_id) != expected_id:
        raise WireError(f'state message carries uh_id {msg.uh_id}, expected {expected_id}')
    x = _array(msg.position, msg.velocity, msg.euler, msg.body_rates)
    _check_finite(x, f'state of uh{msg.uh_id} at step {msg.step}')
    return x


def command_to_msg(uh_id: int, k: int, t: float, u: np.ndarray):
    """``ActuatorCommand`` (theta_col, theta_tr, delta_lat, delta_lon) = ``u`` for step ``k``."""
    msg = m.ActuatorCommand()
    msg.header = _header(t)
    msg.uh_id, msg.step = int(uh_id), int(k)
    msg.theta_col, msg.theta_tr, msg.delta_lat, msg.delta_lon = (float(v) for v in u)
    return msg


def msg_to_command(msg, expected_id: int | None = None) -> np.ndarray:
    """Input vector (4,) of an ``ActuatorCommand``; raises :class:`WireError` if unusable."""
    if expected_id is not None and int(msg.uh_id) != expected_id:
        raise WireError(f'command message carries uh_id {msg.uh_id}, expected {expected_id}')
    u = np.array([msg.theta_col, msg.theta_tr, msg.delta_lat, msg.delta_lon], dtype=float)
    _check_finite(u, f'command of uh{msg.uh_id} at step {msg.step}')
    return u


def reference_to_msg(k: int, t: float, ref):
    """``Reference`` from a core reference sample (position, velocity, acceleration, yaw, yaw_rate)."""
    msg = m.Reference()
    msg.header = _header(t)
    msg.step = int(k)
    msg.position, msg.velocity = vector3(ref.position), vector3(ref.velocity)
    msg.acceleration = vector3(ref.acceleration)
    msg.yaw, msg.yaw_rate = float(ref.yaw), float(ref.yaw_rate)
    return msg


def msg_to_reference(msg):
    """Core reference sample of a ``Reference`` message; raises :class:`WireError` if unusable."""
    from uh_sim_node.reference import Reference

    p, v, a = _array(msg.position), _array(msg.velocity), _array(msg.acceleration)
    _check_finite(np.concatenate([p, v, a, [msg.yaw, msg.yaw_rate]]), f'reference at step {msg.step}')
    return Reference(position=p, velocity=v, acceleration=a, yaw=float(msg.yaw), yaw_rate=float(msg.yaw_rate))


def fault_truth_to_msg(uh_id: int, k: int, t: float, f_p, f_w, u_actual, active: bool, stuck: bool):
    """``FaultTruth`` of UH ``uh_id`` at step ``k``."""
    msg = m.FaultTruth()
    msg.header = _header(t)
    msg.uh_id, msg.step = int(uh_id), int(k)
    msg.lumped_fault_position, msg.lumped_fault_attitude = vector3(f_p), vector3(f_w)
    msg.actual_inputs = [float(v) for v in u_actual]
    msg.fault_active, msg.stuck = bool(active), bool(stuck)
    return msg


_STATUS_VECTORS = ('z1', 'z2', 'z3', 'z4', 'fault_estimate_position', 'fault_estimate_attitude',
                   'prediction_error_position', 'prediction_error_attitude', 'u_p', 'euler_desired')
_STATUS_SCALARS = ('thrust_command', 'weight_norm_position', 'weight_norm_attitude', 'cost_rate')
_STATUS_FLAGS = ('saturated_tilt', 'saturated_collective', 'saturated_cyclic')


def status_to_msg(uh_id: int, k: int, t: float, status, stale_neighbours=()):
    """``ControllerStatus`` from the controller core's status record (same field names)."""
    msg = m.ControllerStatus()
    msg.header = _header(t)
    msg.uh_id, msg.step = int(uh_id), int(k)
    for name in _STATUS_VECTORS:
        setattr(msg, name, vector3(getattr(status, name)))
    for name in _STATUS_SCALARS:
        setattr(msg, name, float(getattr(status, name)))
    for name in _STATUS_FLAGS:
        setattr(msg, name, bool(getattr(status, name)))
    msg.stale_neighbours = [str(s) for s in stale_neighbours]
    return msg
