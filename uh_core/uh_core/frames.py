"""ROS frames of the team and the state's pose and twist in them (docs/visualization.md#frames).

The model's inertial frame (x east, y north, z up) is REP 103's ENU ``world``; its body frame
(x forward along the roll axis, y left, z up along the rotor shaft) is REP 103's FLU
``uhN/base_link``. So the transform ``world -> uhN/base_link`` is the state's position and the
rotation ``R(Theta) = Rz(psi) Ry(theta) Rx(phi)`` (docs/model.md#frames-and-conventions), and the
odometry twist in ``base_link`` is ``R^T v`` with the body rates ``omega`` as they are.
Pure numpy: no ROS imports.
"""
from __future__ import annotations

import math

import numpy as np

from .layout import X_OMEGA, X_P, X_THETA, X_V

__all__ = ['WORLD_FRAME', 'VIRTUAL_LEADER_FRAME', 'base_link', 'quaternion_from_euler_zyx',
           'rotation_from_euler_zyx', 'pose_of_state', 'body_twist_of_state']

#: REP 105's fixed world frame; the model's inertial frame (ENU).
WORLD_FRAME = 'world'
#: Frame of the virtual leader's reference (position and yaw, no roll or pitch).
VIRTUAL_LEADER_FRAME = 'virtual_leader'


def base_link(uh_id: int) -> str:
    """Body frame (FLU) of UH ``uh_id``: ``uhN/base_link`` (a tf2 frame id has no leading slash)."""
    return f'uh{int(uh_id)}/base_link'


def quaternion_from_euler_zyx(phi: float, theta: float, psi: float) -> tuple[float, float, float, float]:
    """Return the unit quaternion ``(x, y, z, w)`` of ``R = Rz(psi) Ry(theta) Rx(phi)`` (rad).

    It is the product ``q_z(psi) q_y(theta) q_x(phi)`` of the three half-angle rotations; ``w >= 0`` is not enforced
    (the sign follows the angles, as tf2's ``Quaternion.setRPY`` does).
    """
    cr, sr = math.cos(0.5 * phi), math.sin(0.5 * phi)
    cp, sp = math.cos(0.5 * theta), math.sin(0.5 * theta)
    cy, sy = math.cos(0.5 * psi), math.sin(0.5 * psi)
    return (sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def rotation_from_euler_zyx(phi: float, theta: float, psi: float) -> np.ndarray:
    """``R(Theta) = Rz(psi) Ry(theta) Rx(phi)``, body to inertial (3, 3)."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cs, ss = math.cos(psi), math.sin(psi)
    return np.array([[cs * ct, cs * st * sf - ss * cf, cs * st * cf + ss * sf],
                     [ss * ct, ss * st * sf + cs * cf, ss * st * cf - cs * sf],
                     [-st, ct * sf, ct * cf]])


def pose_of_state(x) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """Position (m, ``world``) and orientation quaternion ``(x, y, z, w)`` of state ``x`` (12,)."""
    p, euler = x[X_P:X_P + 3], x[X_THETA:X_THETA + 3]
    return ((float(p[0]), float(p[1]), float(p[2])),
            quaternion_from_euler_zyx(float(euler[0]), float(euler[1]), float(euler[2])))


def body_twist_of_state(x) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Return the twist of ``nav_msgs/Odometry`` of state ``x`` (12,).

    Linear velocity ``R^T v`` (m/s) and angular velocity ``omega`` (rad/s), both in ``uhN/base_link``.
    """
    euler = x[X_THETA:X_THETA + 3]
    v_body = rotation_from_euler_zyx(float(euler[0]), float(euler[1]), float(euler[2])).T @ np.asarray(
        x[X_V:X_V + 3], dtype=float)
    w = x[X_OMEGA:X_OMEGA + 3]
    return ((float(v_body[0]), float(v_body[1]), float(v_body[2])),
            (float(w[0]), float(w[1]), float(w[2])))
