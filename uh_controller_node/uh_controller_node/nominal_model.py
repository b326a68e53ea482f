"""What the controller knows of its helicopter (docs/model.md#what-the-controller-knows).

The nominal model holds the airframe constants the controller may use: mass, inertia, gravity,
thrust map, flapping and tail-rotor gains, rotor damping, and the drag ``D_v`` and torque reaction
``c_Q`` scaled by the scenario's model mismatch (default 0.9: the controller believes 90 % of the
true values). It never contains the disturbance or the faults. From it follow the known parts of
the control-oriented model (docs/model.md#control-oriented-model)::

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

import dataclasses
import math

from uh_core.airframe import HelicopterParams

__all__ = ['nominal_model']


def nominal_model(params: HelicopterParams, mismatch: float = 1.0) -> HelicopterParams:
    """Return the controller's nominal model: ``params`` with its drag and torque reaction scaled.

    It is the airframe ``params`` with the drag ``D_v`` and the torque reaction ``c_Q`` multiplied
    by ``mismatch`` (the scenario's ``model_mismatch``, > 0).

    Raises
    ------
    ValueError
        ``mismatch`` is not a finite number > 0.
    """
    if isinstance(mismatch, bool) or not (isinstance(mismatch, (int, float)) and math.isfinite(mismatch)
                                          and mismatch > 0.0):
        raise ValueError(f'model mismatch factor must be a finite number > 0, got {mismatch!r}')
    return dataclasses.replace(params, D_v=params.D_v * mismatch, c_Q=params.c_Q * mismatch)
