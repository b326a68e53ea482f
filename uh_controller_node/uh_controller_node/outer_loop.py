"""Outer (position) loop of one UH: DESIGN.md 2.4, with the anti-windup and projection of 2.5a.

Per step, with the consensus error ``z1`` (m), the degree ``d`` and the velocity feed-forward
``f = sum_j a_j v_j + a_0 v_0`` (m/s) from :mod:`uh_controller_node.controller`::

    alpha_v = (f - k1 z1) / d                                   virtual velocity, m/s
    tau_1 alpha_f' = alpha_v - alpha_f                          command filter
    z2 = v - alpha_f ,  z_n = v - vhat                          tracking and prediction errors
    u_p = alpha_f' - f_nom(v) - d z1 - W^T S(v) - Fhat - (beta / (2 r_p)) z2

and, integrated over the step with explicit Euler (all right-hand sides at ``t_k``)::

    vhat'  = f_nom(v) + W^T S(v) + a_ach + Fhat + kappa z_n     serial-parallel estimation model
    W'     = Gamma [ S (z2 + gamma z_n)^T - sigma W ]           composite learning, then projection
    Fhat'  = lambda [ z2 + gamma_F z_n - sigma_F Fhat ]         fault observer, then projection

``a_ach = (T_ach / m) R(Theta) e3 - g e3`` is the acceleration the plant receives from the thrust
the limits let through, at the measured attitude (anti-windup: the SPEM never learns an
acceleration that was demanded but not delivered). ``f_nom(v) = -(D_v,nom / m) v`` is the known
drag (:class:`~uh_controller_node.nominal_model.NominalModel`).

:func:`thrust_and_attitude` is Remark 4 / DESIGN.md 2.4 step 8.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .command_filter import FirstOrderFilter
from .gains import ControllerGains
from .nominal_model import NominalModel
from .rbf import GaussianRBF, composite_weight_update

__all__ = ['AttitudeCommand', 'thrust_and_attitude', 'OuterLoop']


@dataclass(frozen=True)
class AttitudeCommand:
    """Thrust and attitude that realise a designed acceleration (DESIGN.md 2.4 step 8).

    Attributes
    ----------
    phi, theta : float
        Desired roll and pitch, rad.
    thrust : float
        T_c before the collective limit, N.
    theta_col : float
        Collective after its limits, rad.
    thrust_achieved : float
        ``c_M1 theta_col + c_M2`` with the limited collective, N.
    saturated_tilt : bool
        The tilt limit or the minimum vertical acceleration changed the demand.
    saturated_collective : bool
        The collective limit was active.
    """

    phi: float
    theta: float
    thrust: float
    theta_col: float
    thrust_achieved: float
    saturated_tilt: bool
    saturated_collective: bool


def thrust_and_attitude(u_p, psi_d: float, model: NominalModel, tilt_limit: float,
                        min_vertical_accel: float) -> AttitudeCommand:
    """Thrust and roll/pitch commands for the designed acceleration ``u_p`` (DESIGN.md 2.4 step 8).

    ``a = u_p + g e3`` (specific thrust, m/s^2, inertial). Its vertical part is kept at least
    ``min_vertical_accel``; its horizontal part is scaled down so the tilt from vertical is at most
    ``tilt_limit`` (the vertical demand is kept, so ``T_c = m a_z / (cos phi cos theta)``). Then::

        theta_d = atan2(a_x cos psi + a_y sin psi, a_z)
        phi_d   = asin((a_x sin psi - a_y cos psi) / |a|)
        theta_col = (T_c - c_M2) / c_M1, limited

    which solve ``(T_c / m) R(phi_d, theta_d, psi_d) e3 = a``.

    Parameters
    ----------
    u_p : array_like (3,)
        Designed acceleration, m/s^2, inertial frame z-up.
    psi_d : float
        Desired yaw, rad.
    model : NominalModel
    tilt_limit : float
        rad, in (0, pi/2).
    min_vertical_accel : float
        m/s^2, > 0.
    """
    g = model.gravity
    ax, ay, az = float(u_p[0]), float(u_p[1]), float(u_p[2]) + g
    sat_tilt = False
    if az < min_vertical_accel:
        az = min_vertical_accel
        sat_tilt = True
    horizontal = math.hypot(ax, ay)
    horizontal_max = az * math.tan(tilt_limit)
    if horizontal > horizontal_max:
        scale = horizontal_max / horizontal
        ax *= scale
        ay *= scale
        sat_tilt = True
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    cp, sp = math.cos(psi_d), math.sin(psi_d)
    theta = math.atan2(ax * cp + ay * sp, az)
    phi = math.asin(max(-1.0, min(1.0, (ax * sp - ay * cp) / norm)))
    thrust = model.mass * norm
    theta_col = (thrust - model.c_M2) / model.c_M1
    lo, hi = model.input_lower[0], model.input_upper[0]
    sat_col = not lo <= theta_col <= hi
    theta_col = min(max(theta_col, lo), hi)
    return AttitudeCommand(phi, theta, thrust, theta_col, model.thrust(theta_col), sat_tilt, sat_col)


class OuterLoop:
    """Position loop state and law of one UH (DESIGN.md 2.4).

    Call :meth:`command` then :meth:`advance` once per control step. The 3-vector algebra runs on
    Python floats (cheaper than numpy calls for vectors this short); the network uses numpy.

    Attributes
    ----------
    weights : ndarray (mu, 3)
        W_p.
    fault_estimate : list of 3 float
        Fhat_p, m/s^2, inertial.
    velocity_estimate : list of 3 float
        vhat of the SPEM, m/s.
    """

    def __init__(self, gains: ControllerGains, model: NominalModel):
        lg = gains.outer
        self.gains = lg
        self.model = model
        self.k1 = lg.k
        self.k2 = gains.beta / (2.0 * lg.r)       # inverse-optimal feedback gain of z2, 1/s
        self.filter = FirstOrderFilter(lg.tau_command)
        self.rbf = GaussianRBF(lg.rbf.nodes, lg.rbf.low, lg.rbf.high, lg.rbf.width)
        self.weights = np.zeros((self.rbf.nodes, 3))
        self.fault_estimate = [0.0, 0.0, 0.0]
        self.velocity_estimate = [0.0, 0.0, 0.0]
        self._drag = model.D_v / model.mass
        self._started = False
        # values of the current step kept for advance()
        self._alpha = self._z2 = self._zn = self._net = self._fnom = None
        self._act = None

    def command(self, z1, degree: float, feedforward, v):
        """Designed acceleration of this step.

        Parameters
        ----------
        z1 : sequence of 3 float
            Consensus error e, m.
        degree : float
            d = sum_j a_j + a_0 (> 0).
        feedforward : sequence of 3 float
            ``sum_j a_j v_j + a_0 v_0``, m/s.
        v : sequence of 3 float
            Own velocity, m/s, inertial.

        Returns
        -------
        u_p, z2, z_n : list of 3 float
            Designed acceleration m/s^2, velocity error m/s, prediction error m/s.
        """
        k1, inv_d = self.k1, 1.0 / degree
        alpha = [(f - k1 * e) * inv_d for f, e in zip(feedforward, z1)]
        v = [float(x) for x in v]
        if not self._started:
            self.filter.reset(alpha)
            self.velocity_estimate = list(v)
            self._started = True
        alpha_dot = self.filter.derivative(alpha)
        z2 = [a - b for a, b in zip(v, self.filter.value)]
        zn = [a - b for a, b in zip(v, self.velocity_estimate)]
        net = self.rbf.evaluate(self.weights, v)
        self._act = self.rbf.activations_buffer
        drag, k2 = self._drag, self.k2
        fnom = [-drag * x for x in v]
        u_p = [ad - fn - degree * e - nt - fh - k2 * z
               for ad, fn, e, nt, fh, z in zip(alpha_dot, fnom, z1, net, self.fault_estimate, z2)]
        self._alpha, self._z2, self._zn, self._net, self._fnom = alpha, z2, zn, net, fnom
        return u_p, z2, zn

    def advance(self, accel_achieved, dt: float) -> None:
        """Integrate the SPEM, the weights, the fault estimate and the filter over ``dt`` s.

        ``accel_achieved`` (3 floats, m/s^2) is the acceleration the limited thrust produces at
        the measured attitude, ``(T_ach / m) R(Theta) e3 - g e3``.
        """
        lg = self.gains
        fhat, zn, z2 = self.fault_estimate, self._zn, self._z2
        kappa = lg.kappa
        self.velocity_estimate = [
            vh + dt * (fn + nt + a + fh + kappa * e)
            for vh, fn, nt, a, fh, e in zip(self.velocity_estimate, self._fnom, self._net,
                                            accel_achieved, fhat, zn)]
        composite_weight_update(self.weights, self._act, z2, zn, lg.learning_rate, lg.gamma,
                                lg.sigma, dt, lg.weight_bound)
        gain, gf, sf, bound = dt * lg.lambda_, lg.gamma_F, lg.sigma_F, lg.fault_bound
        self.fault_estimate = [min(max(fh + gain * (z + gf * e - sf * fh), -bound), bound)
                               for fh, z, e in zip(fhat, z2, zn)]
        self.filter.advance(self._alpha, dt)
