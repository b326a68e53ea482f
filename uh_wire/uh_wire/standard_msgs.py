"""Standard ROS messages of the team's state for generic tools: ``/tf``, ``/uhN/odom``, ``/diagnostics``.

See docs/visualization.md. Built with the classes of either node backend (:mod:`uh_runtime.messages`).

``UHState`` stays the control interface; these are views of it for RViz2, tf2, PlotJuggler,
Foxglove and rqt_robot_monitor. Frames and the mathematics: :mod:`uh_core.frames`.
"""
from __future__ import annotations

import functools

from uh_core import frames
from uh_runtime import messages as m

from . import topics
from .wire import stamp

__all__ = ['view_publisher', 'transform_msg', 'tf_msg', 'odometry_msg', 'diagnostic_array_msg', 'level_of']


def view_publisher(node, spec):
    """Create ``node``'s publisher of the standard view ``spec``, with its type and QoS from the topic registry.

    ``spec`` is :data:`uh_wire.topics.TF`, ``ODOM`` or ``DIAGNOSTICS``.
    """
    return node.create_publisher(m.get_message(spec.type), spec.name, topics.qos_profile(spec.qos))


@functools.cache
def _level_is_bytes() -> bool:
    return isinstance(m.get_message('diagnostic_msgs/msg/DiagnosticStatus')().level, bytes)


def _level_value(level: int):
    """``DiagnosticStatus.level`` is ``byte``: ``bytes`` of length 1 on rclpy, an int on the DDS backend."""
    return bytes([level]) if _level_is_bytes() else int(level)


def level_of(status) -> int:
    """Return the level of a received ``DiagnosticStatus`` as an int, on either backend."""
    level = status.level
    return level[0] if isinstance(level, (bytes, bytearray)) else int(level)


def transform_msg(t: float, parent: str, child: str, position, quaternion):
    """``geometry_msgs/TransformStamped`` ``parent -> child`` at simulation time ``t`` (s)."""
    msg_type = m.get_message('geometry_msgs/msg/TransformStamped')
    transform = m.get_message('geometry_msgs/msg/Transform')(
        translation=m.Vector3(x=position[0], y=position[1], z=position[2]),
        rotation=m.Quaternion(x=quaternion[0], y=quaternion[1], z=quaternion[2], w=quaternion[3]))
    return msg_type(header=m.Header(stamp=stamp(t), frame_id=parent),
                    child_frame_id=child, transform=transform)


def tf_msg(transforms):
    """``tf2_msgs/TFMessage`` holding ``transforms`` (``TransformStamped``)."""
    return m.get_message('tf2_msgs/msg/TFMessage')(transforms=list(transforms))


def odometry_msg(uh_id: int, t: float, x, pose=None):
    """Return the ``nav_msgs/Odometry`` of UH ``uh_id`` in state ``x`` (12,) at time ``t``.

    Pose in ``world``, twist in ``uhN/base_link`` (REP 105); covariances zero (the simulator's
    state is exact). ``pose``: :func:`uh_core.frames.pose_of_state` of ``x`` if already computed.
    """
    position, q = pose or frames.pose_of_state(x)
    linear, angular = frames.body_twist_of_state(x)
    pose = m.Pose(position=m.Point(x=position[0], y=position[1], z=position[2]),
                  orientation=m.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]))
    twist = m.get_message('geometry_msgs/msg/Twist')(
        linear=m.Vector3(x=linear[0], y=linear[1], z=linear[2]),
        angular=m.Vector3(x=angular[0], y=angular[1], z=angular[2]))
    return m.get_message('nav_msgs/msg/Odometry')(
        header=m.Header(stamp=stamp(t), frame_id=frames.WORLD_FRAME),
        child_frame_id=frames.base_link(uh_id),
        pose=m.get_message('geometry_msgs/msg/PoseWithCovariance')(pose=pose),
        twist=m.get_message('geometry_msgs/msg/TwistWithCovariance')(twist=twist))


def diagnostic_array_msg(t: float, diagnostics):
    """``diagnostic_msgs/DiagnosticArray`` of :class:`uh_core.diagnostics.Diagnostic` records."""
    status_type = m.get_message('diagnostic_msgs/msg/DiagnosticStatus')
    key_value = m.get_message('diagnostic_msgs/msg/KeyValue')
    return m.get_message('diagnostic_msgs/msg/DiagnosticArray')(
        header=m.Header(stamp=stamp(t), frame_id=''),
        status=[status_type(level=_level_value(d.level), name=d.name, message=d.message,
                            hardware_id=d.hardware_id,
                            values=[key_value(key=k, value=v) for k, v in d.values.items()])
                for d in diagnostics])
