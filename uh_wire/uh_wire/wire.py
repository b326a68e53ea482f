"""Conversions between uh_msgs messages and the numpy arrays of the control core.

Every receiver checks what it takes off the wire: a message carrying NaN or inf, or an id that is
not the expected one, raises :class:`WireError`, and the node logs the reason and keeps its last
valid input. The functions work on both node backends (rosidl classes on rclpy, IdlStruct classes
on Cyclone DDS): they only read and set attributes.
"""
from __future__ import annotations

import math

import numpy as np

from uh_core.layout import STATUS_FLAG, STATUS_FLOAT, STATUS_LAYOUT, STATUS_VECTOR3
from uh_core.records import Reference
from uh_runtime import messages as m

__all__ = [
    'WireError', 'stamp', 'stamp_seconds', 'state_to_msg', 'msg_to_state', 'received_states_to_msg',
    'proximity_to_msg', 'msg_to_proximity',
    'command_to_msg', 'msg_to_command', 'reference_to_msg', 'msg_to_reference', 'fault_truth_to_msg',
    'status_to_msg', 'vector3', 'clock_msg', 'clock_step', 'set_lost', 'msg_lost',
]

FRAME_ID = 'world'


class WireError(ValueError):
    """A received message is unusable (non-finite values, wrong id, wrong step)."""


def stamp(t: float):
    """``builtin_interfaces/Time`` for simulation time ``t`` (s), rounded to the nanosecond."""
    ns = int(round(t * 1e9))
    # built with keyword arguments (both backends accept them): no default field objects made and replaced
    return m.Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


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


def _header(t: float):
    return m.Header(stamp=stamp(t), frame_id=FRAME_ID)


def _floats(values) -> list:
    """Python floats of a numpy array (one ``tolist``) or of any sequence of numbers."""
    return values.tolist() if isinstance(values, np.ndarray) else [float(v) for v in values]


def vector3(values) -> object:
    """Return a ``geometry_msgs/Vector3`` of the first three values of a numpy array or sequence."""
    if isinstance(values, np.ndarray):
        values = values.tolist()
    return m.Vector3(x=float(values[0]), y=float(values[1]), z=float(values[2]))


def _values(*vectors) -> list:
    return [c for v in vectors for c in (v.x, v.y, v.z)]


def _array(*vectors) -> np.ndarray:
    return np.array(_values(*vectors), dtype=float)


def _check_finite(values, what: str) -> None:
    """``values``: a list of Python floats (cheapest) or an array."""
    if not all(map(math.isfinite, values if isinstance(values, list) else np.ravel(values).tolist())):
        raise WireError(f'{what} carries a non-finite value (NaN or inf): {np.ravel(values).tolist()}')


def state_to_msg(uh_id: int, k: int, t: float, x: np.ndarray, lost=None):
    """``UHState`` of UH ``uh_id`` at step ``k`` (time ``t``) from state vector ``x`` (12,).

    ``lost``: ``{uh: step declared}``, the lost set it carries (docs/resilience.md); None or empty: none.
    """
    v = _floats(x)
    vec = m.Vector3
    msg = m.UHState(header=_header(t), uh_id=int(uh_id), step=int(k),
                    position=vec(x=v[0], y=v[1], z=v[2]), velocity=vec(x=v[3], y=v[4], z=v[5]),
                    euler=vec(x=v[6], y=v[7], z=v[8]), body_rates=vec(x=v[9], y=v[10], z=v[11]))
    if lost:
        set_lost(msg, lost)
    return msg


def set_lost(msg, lost: dict) -> None:
    """Write the lost set ``{uh: step declared}`` into a ``UHState`` or ``ActuatorCommand`` (ascending ids)."""
    ids = sorted(lost)
    msg.lost_uhs = [int(j) for j in ids]
    msg.lost_steps = [int(lost[j]) for j in ids]


def msg_lost(msg) -> dict:
    """Give the lost set ``{uh: step declared}`` a ``UHState`` or ``ActuatorCommand`` carries; raise if malformed."""
    ids, steps = list(msg.lost_uhs), list(msg.lost_steps)
    if len(ids) != len(steps) or len(set(ids)) != len(ids):
        raise WireError(f'uh{msg.uh_id} step {msg.step}: lost set {ids} with steps {steps}: one step per UH, each '
                        'UH once')
    return {int(j): int(s) for j, s in zip(ids, steps, strict=True)}


def received_states_to_msg(uh_id: int, k: int, dt: float, own, neighbours: dict, sample_steps: dict):
    """Build the ``ReceivedStates`` of UH ``uh_id`` at step ``k``.

    It holds its ``own`` state (sent at k) and the ``neighbours`` states ``{j: x}`` it used, each
    stamped with the step it was sent at (``sample_steps[j]``, time ``step * dt``).
    """
    states = [state_to_msg(uh_id, k, k * dt, own)]
    states += [state_to_msg(j, sample_steps[j], sample_steps[j] * dt, neighbours[j]) for j in sorted(neighbours)]
    return m.ReceivedStates(header=_header(k * dt), uh_id=int(uh_id), step=int(k), states=states)


def proximity_to_msg(report, dt: float, sensing_radius: float):
    """Build the ``Proximity`` of a :class:`uh_sim_node.sensing.ProximityReport` (step times ``step * dt``).

    The report's payloads are used as its states where they are ``UHState`` messages (the ones
    received: no copy); otherwise each state is built from its vector.
    """
    if report.payloads and all(p is not None for p in report.payloads):
        states = list(report.payloads)
    else:
        states = [state_to_msg(j, s, s * dt, x)
                  for j, s, x in zip(report.ids, report.steps, report.states, strict=True)]
    return m.Proximity(header=_header(report.step * dt), uh_id=int(report.uh_id), step=int(report.step),
                       sensing_radius=float(sensing_radius), states=states)


def msg_to_proximity(msg, expected_id: int) -> tuple[int, tuple, np.ndarray]:
    """Return ``(step, ids, rows)`` of a ``Proximity`` for UH ``expected_id``: its step, the UHs, their ``[p, v]``.

    Rows in the message's order (ascending id), inertial frame, m and m/s: the safety filter's
    input (:meth:`uh_controller_node.controller.UHController.set_proximity`). Raises
    :class:`WireError` for another UH's message, a state of the UH itself, a repeated UH or a
    non-finite value.
    """
    if int(msg.uh_id) != expected_id:
        raise WireError(f'proximity message carries uh_id {msg.uh_id}, expected {expected_id}')
    ids = tuple(int(s.uh_id) for s in msg.states)
    if expected_id in ids or len(set(ids)) != len(ids):
        raise WireError(f'proximity message of step {msg.step} reports UHs {list(ids)}: each other UH at most once, '
                        f'never uh{expected_id} itself')
    values = [c for s in msg.states for c in _values(s.position, s.velocity)]
    _check_finite(values, f'proximity of uh{expected_id} at step {msg.step}')
    return int(msg.step), ids, np.array(values, dtype=float).reshape(len(ids), 6)


def msg_to_state(msg, expected_id: int | None = None) -> np.ndarray:
    """State vector (12,) of a ``UHState``; raises :class:`WireError` if unusable."""
    if expected_id is not None and int(msg.uh_id) != expected_id:
        raise WireError(f'state message carries uh_id {msg.uh_id}, expected {expected_id}')
    values = _values(msg.position, msg.velocity, msg.euler, msg.body_rates)
    _check_finite(values, f'state of uh{msg.uh_id} at step {msg.step}')
    return np.array(values)


def command_to_msg(uh_id: int, k: int, t: float, u: np.ndarray, lost=None):
    """``ActuatorCommand`` (theta_col, theta_tr, delta_lat, delta_lon) = ``u`` for step ``k``.

    ``lost``: as in :func:`state_to_msg`.
    """
    col, tr, lat, lon = _floats(u)
    msg = m.ActuatorCommand(header=_header(t), uh_id=int(uh_id), step=int(k), theta_col=col, theta_tr=tr,
                            delta_lat=lat, delta_lon=lon)
    if lost:
        set_lost(msg, lost)
    return msg


def msg_to_command(msg, expected_id: int | None = None) -> np.ndarray:
    """Input vector (4,) of an ``ActuatorCommand``; raises :class:`WireError` if unusable."""
    if expected_id is not None and int(msg.uh_id) != expected_id:
        raise WireError(f'command message carries uh_id {msg.uh_id}, expected {expected_id}')
    values = [msg.theta_col, msg.theta_tr, msg.delta_lat, msg.delta_lon]
    _check_finite(values, f'command of uh{msg.uh_id} at step {msg.step}')
    return np.array(values, dtype=float)


def reference_to_msg(k: int, t: float, ref):
    """Build a ``Reference`` from a core reference sample (position, velocity, acceleration, yaw, yaw_rate)."""
    msg = m.Reference()
    msg.header = _header(t)
    msg.step = int(k)
    msg.position, msg.velocity = vector3(ref.position), vector3(ref.velocity)
    msg.acceleration = vector3(ref.acceleration)
    msg.yaw, msg.yaw_rate = float(ref.yaw), float(ref.yaw_rate)
    return msg


def msg_to_reference(msg):
    """Core reference sample of a ``Reference`` message; raises :class:`WireError` if unusable."""
    p, v, a = _array(msg.position), _array(msg.velocity), _array(msg.acceleration)
    _check_finite(np.concatenate([p, v, a, [msg.yaw, msg.yaw_rate]]), f'reference at step {msg.step}')
    return Reference(position=p, velocity=v, acceleration=a, yaw=float(msg.yaw), yaw_rate=float(msg.yaw_rate))


def fault_truth_to_msg(uh_id: int, k: int, t: float, f_p, f_w, u_actual, active: bool, stuck: bool):
    """``FaultTruth`` of UH ``uh_id`` at step ``k``."""
    return m.FaultTruth(header=_header(t), uh_id=int(uh_id), step=int(k), lumped_fault_position=vector3(f_p),
                        lumped_fault_attitude=vector3(f_w), actual_inputs=_floats(u_actual),
                        fault_active=bool(active), stuck=bool(stuck))


# the status record's fields of ControllerStatus.msg, by kind (uh_core.layout.STATUS_LAYOUT)
_STATUS_VECTORS = tuple(name for name, kind in STATUS_LAYOUT if kind == STATUS_VECTOR3)
_STATUS_SCALARS = tuple(name for name, kind in STATUS_LAYOUT if kind == STATUS_FLOAT)
_STATUS_FLAGS = tuple(name for name, kind in STATUS_LAYOUT if kind == STATUS_FLAG)


_NAN4 = (math.nan,) * 4


def status_to_msg(uh_id: int, k: int, t: float, status, stale_neighbours=(), ages=(math.nan, math.nan),
                  closest_uh: int = 0):
    """Build a ``ControllerStatus`` from the controller core's status record.

    The fields of :data:`uh_core.layout.STATUS_LAYOUT` have the record's names; the fault isolation
    fields come from its ``isolation``, or say "nothing isolated" when that is None. ``ages`` is
    ``(mean, max)`` of the neighbours' ages in s
    (:meth:`uh_controller_node.controller_diagnostics.NeighbourAges.overall`); ``closest_uh`` the
    UH at ``status.closest_distance`` (0: none, or the safety filter is off).
    """
    fields = {name: vector3(getattr(status, name)) for name in _STATUS_VECTORS}
    fields.update((name, float(getattr(status, name))) for name in _STATUS_SCALARS)
    fields.update((name, bool(getattr(status, name))) for name in _STATUS_FLAGS)
    iso = getattr(status, 'isolation', None)
    if iso is None:
        fields.update(fault_isolated=[False] * 4, fault_detection_time=list(_NAN4),
                      input_deviation=[0.0] * 4, isolation_threshold=list(_NAN4),
                      identified_effectiveness=list(_NAN4), identified_bias=list(_NAN4),
                      fault_identification=[0] * 4)
    else:
        fields.update(fault_isolated=[bool(v) for v in iso.isolated],
                      fault_detection_time=_floats(iso.detection_time), input_deviation=_floats(iso.deviation),
                      isolation_threshold=_floats(iso.threshold),
                      identified_effectiveness=_floats(iso.effectiveness), identified_bias=_floats(iso.bias),
                      fault_identification=[int(v) for v in iso.identification])
    return m.ControllerStatus(header=_header(t), uh_id=int(uh_id), step=int(k),
                              stale_neighbours=[str(s) for s in stale_neighbours],
                              neighbour_age_mean=float(ages[0]), neighbour_age_max=float(ages[1]),
                              closest_uh=int(closest_uh), lost_uhs=[int(j) for j in getattr(status, 'lost_uhs', ())],
                              role=str(getattr(status, 'role', '')), **fields)
