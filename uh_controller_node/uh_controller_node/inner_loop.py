"""Inner (attitude) loop of one UH: DESIGN.md 2.5, with the anti-windup and projection of 2.5a.

Per step, with the attitude command ``Theta_d`` from the outer loop and the collective thrust
``T`` (N) it will fly with::

    tau_2 Theta_df' = Theta_d - Theta_df                       command filter (yaw difference wrapped)
    z3 = Theta - Theta_df   (yaw wrapped to (-pi, pi])         attitude error, rad
    alpha_w = H(Theta)^-1 (-k3 z3 + Theta_df')                  virtual body rate, rad/s
    tau_w alpha_wf' = alpha_w - alpha_wf                        rate command filter
    z4 = omega - alpha_wf ,  z_n = omega - omegahat
    G u_m = alpha_wf' - f_nom(omega, T) - H^T z3 - W^T S(omega) - Fhat - (beta / (2 r_w)) z4

``u_m = (delta_lat, delta_lon, theta_tr)`` is then limited. With ``V = |z3|^2/2 + |z4|^2/2`` the
``H^T z3`` term cancels the cross term of ``z3' = -k3 z3 + H z4``. Over the step (explicit Euler)::

    omegahat' = f_nom + W^T S + G u_m,lim + Fhat + kappa z_n    SPEM fed with the limited input
    W'        = Gamma [ S (z4 + gamma z_n)^T - sigma W ]         then projection
    Fhat'     = lambda [ z4 + gamma_F z_n - sigma_F Fhat ]       then projection

``f_nom`` and ``G`` are the nominal model's (:class:`~uh_controller_node.nominal_model.NominalModel`).
"""
from __future__ import annotations

import math

import numpy as np

from .command_filter import FirstOrderFilter, wrap_angle
from .gains import ControllerGains
from .nominal_model import NominalModel
from .rbf import GaussianRBF, composite_weight_update

__all__ = ['euler_rate_matrix', 'InnerLoop']


def euler_rate_matrix(euler) -> np.ndarray:
    """``H(Theta)`` (3, 3) with ``Theta' = H omega`` (ZYX Euler angles, body rates), DESIGN.md 2."""
    phi, theta = float(euler[0]), float(euler[1])
    cf, sf, ct, tt = math.cos(phi), math.sin(phi), math.cos(theta), math.tan(theta)
    return np.array([[1.0, sf * tt, cf * tt], [0.0, cf, -sf], [0.0, sf / ct, cf / ct]])


class InnerLoop:
    """Attitude loop state and law of one UH (DESIGN.md 2.5).

    Call :meth:`command` then :meth:`advance` once per control step.

    Attributes
    ----------
    weights : ndarray (mu, 3)
        W_w.
    fault_estimate : ndarray (3,)
        Fhat_w, rad/s^2, body frame.
    rate_estimate : ndarray (3,)
        omegahat of the SPEM, rad/s.
    """

    def __init__(self, gains: ControllerGains, model: NominalModel):
        lg = gains.inner
        self.gains = lg
        self.model = model
        self.k3 = lg.k
        self.k4 = gains.beta / (2.0 * lg.r)       # inverse-optimal feedback gain of z4, 1/s
        self.attitude_filter = FirstOrderFilter(lg.tau_command, angle_axes=(2,))
        self.rate_filter = FirstOrderFilter(lg.tau_rate)
        self.rbf = GaussianRBF(lg.rbf.nodes, lg.rbf.low, lg.rbf.high, lg.rbf.width)
        self.weights = np.zeros((self.rbf.nodes, 3))
        self.fault_estimate = np.zeros(3)
        self.rate_estimate = np.zeros(3)
        lower, upper = model.input_lower, model.input_upper
        # u_m = (delta_lat, delta_lon, theta_tr) = input channels (2, 3, 1)
        self._lower = np.array([lower[2], lower[3], lower[1]])
        self._upper = np.array([upper[2], upper[3], upper[1]])
        self._started = False
        self._euler_d = self._alpha = self._z4 = self._zn = self._net = self._fnom = None
        self._act = self._applied = None

    def command(self, euler, omega, euler_d, thrust: float):
        """Limited moment inputs of this step.

        Parameters
        ----------
        euler : ndarray (3,)
            Measured (phi, theta, psi), rad.
        omega : ndarray (3,)
            Measured body rates, rad/s.
        euler_d : ndarray (3,)
            Attitude command (phi_d, theta_d, psi_d), rad.
        thrust : float
            Main-rotor thrust of the limited collective, N (enters G and f_nom).

        Returns
        -------
        u_m : ndarray (3,)
            (delta_lat, delta_lon, theta_tr) after the limits, rad.
        z3, z4, z_n : ndarray (3,)
            Attitude error rad, rate error rad/s, prediction error rad/s.
        saturated : bool
            A cyclic or the tail-rotor limit was active.
        """
        if not self._started:
            self.attitude_filter.reset(euler_d)
        theta_d_dot = self.attitude_filter.derivative(euler_d)
        z3 = euler - self.attitude_filter.value
        z3[2] = wrap_angle(z3[2])
        phi, theta = float(euler[0]), float(euler[1])
        cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
        tt = st / ct
        # H^-1: Euler rates -> body rates
        e0, e1, e2 = theta_d_dot - self.k3 * z3
        alpha = np.array([e0 - st * e2, cf * e1 + sf * ct * e2, -sf * e1 + cf * ct * e2])
        if not self._started:
            self.rate_filter.reset(alpha)
            self.rate_estimate[:] = omega
            self._started = True
        alpha_dot = self.rate_filter.derivative(alpha)
        z4 = omega - self.rate_filter.value
        zn = omega - self.rate_estimate
        act = self.rbf.activations(omega)
        net = self.rbf.output(self.weights, act)
        fnom = self.model.inner_drift(omega, thrust)
        g = self.model.control_effectiveness(thrust)
        a0, a1, a2 = float(z3[0]), float(z3[1]), float(z3[2])
        # H^T z3
        ht_z3 = np.array([a0, sf * tt * a0 + cf * a1 + sf / ct * a2, cf * tt * a0 - sf * a1 + cf / ct * a2])
        demand = alpha_dot - fnom - ht_z3 - net - self.fault_estimate - self.k4 * z4
        u_m = demand / g
        limited = np.minimum(np.maximum(u_m, self._lower), self._upper)
        saturated = bool(np.any(limited != u_m))
        self._euler_d, self._alpha, self._z4, self._zn = euler_d, alpha, z4, zn
        self._net, self._fnom, self._act, self._applied = net, fnom, act, g * limited
        return limited, z3, z4, zn, saturated

    def advance(self, dt: float) -> None:
        """Integrate the SPEM, the weights, the fault estimate and both filters over ``dt`` s."""
        lg = self.gains
        fhat = self.fault_estimate
        zn = self._zn
        self.rate_estimate += dt * (self._fnom + self._net + self._applied + fhat + lg.kappa * zn)
        composite_weight_update(self.weights, self._act, self._z4, zn, lg.learning_rate, lg.gamma,
                                lg.sigma, dt, lg.weight_bound)
        fhat += (dt * lg.lambda_) * (self._z4 + lg.gamma_F * zn - lg.sigma_F * fhat)
        np.clip(fhat, -lg.fault_bound, lg.fault_bound, out=fhat)
        self.attitude_filter.advance(self._euler_d, dt)
        self.rate_filter.advance(self._alpha, dt)
