"""What the controller knows of its helicopter (DESIGN.md 2.1 "What the controller knows", 2.2).

The nominal model holds the airframe constants the controller may use: mass, inertia, gravity,
thrust map, flapping and tail-rotor gains, rotor damping, and the drag ``D_v`` and torque reaction
``c_Q`` scaled by the scenario's model mismatch (default 0.9: the controller believes 90 % of the
true values). It never contains the disturbance or the faults. From it follow the known parts of
the control-oriented model of DESIGN.md 2.2::

    outer:  v' = f_p,nom(v) + u_p + [f_p - f_p,nom] + F_p,        f_p,nom(v) = -(D_v / m) v
    inner:  omega' = f_w,nom(omega, T) + G(T) u_m + [f_w - f_w,nom] + F_w
            f_w,nom = J^-1 ( -omega x J omega + [-(K_beta + T h_M) tau_f p,
                                                   -(K_beta + T h_M) tau_f q,
                                                   -D_r r - c_Q T] )
            G(T) = J^-1 diag((K_beta + T h_M) B_lat, (K_beta + T h_M) A_lon, K_tr),
            u_m = (delta_lat, delta_lon, theta_tr)

The bracketed residuals are what the RBF networks learn; F_p and F_w what the observers estimate.
The control law evaluates ``f_p,nom``, ``f_w,nom`` and ``G`` in its kernels
(:func:`~uh_controller_node.control_kernels.outer_law`,
:func:`~uh_controller_node.control_kernels.inner_drift`,
:func:`~uh_controller_node.control_kernels.control_effectiveness`) from the entries ``CP_*`` of the
parameter vector that :func:`~uh_controller_node.control_kernels.control_parameters` builds from
this record.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ['NominalModel']


@dataclass(frozen=True)
class NominalModel:
    """Nominal helicopter constants used by the controller (SI units, angles in rad).

    Attributes
    ----------
    mass : float
        kg.
    inertia : tuple of 3 float
        (J_x, J_y, J_z), kg m^2.
    gravity : float
        m/s^2.
    c_M1, c_M2 : float
        Thrust map ``T = c_M1 theta_col + c_M2``: N/rad and N.
    K_beta, h_M, B_lat, A_lon, tau_f : float
        Hub stiffness N m/rad, hub height m, flapping gains rad/rad, flapping lag s.
    K_tr, D_r : float
        Tail-rotor gain N m/rad, yaw damping N m s.
    c_Q, D_v : float
        Torque reaction m and drag N s/m, after the model mismatch.
    input_lower, input_upper : tuple of 4 float
        Limits of ``(theta_col, theta_tr, delta_lat, delta_lon)``, rad.
    """

    mass: float
    inertia: tuple
    gravity: float
    c_M1: float
    c_M2: float
    K_beta: float
    h_M: float
    B_lat: float
    A_lon: float
    tau_f: float
    K_tr: float
    D_r: float
    c_Q: float
    D_v: float
    input_lower: tuple
    input_upper: tuple

    @classmethod
    def from_params(cls, params, mismatch: float = 1.0) -> 'NominalModel':
        """Nominal model from helicopter parameters (any object with the ``HelicopterParams``
        attributes), with ``D_v`` and ``c_Q`` multiplied by ``mismatch`` (DESIGN.md 2.1)."""
        if not (isinstance(mismatch, (int, float)) and math.isfinite(mismatch) and mismatch > 0.0):
            raise ValueError(f'model mismatch factor must be a finite number > 0, got {mismatch!r}')
        f = float
        return cls(
            mass=f(params.mass), inertia=tuple(f(v) for v in params.inertia), gravity=f(params.gravity),
            c_M1=f(params.c_M1), c_M2=f(params.c_M2), K_beta=f(params.K_beta), h_M=f(params.h_M),
            B_lat=f(params.B_lat), A_lon=f(params.A_lon), tau_f=f(params.tau_f), K_tr=f(params.K_tr),
            D_r=f(params.D_r), c_Q=f(params.c_Q) * mismatch, D_v=f(params.D_v) * mismatch,
            input_lower=tuple(f(v) for v in params.input_lower),
            input_upper=tuple(f(v) for v in params.input_upper))
