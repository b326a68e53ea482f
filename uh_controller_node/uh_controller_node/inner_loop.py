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

    Call :meth:`command` then :meth:`advance` once per control step. The 3-vector algebra runs on
    Python floats; the network uses numpy.

    Attributes
    ----------
    weights : ndarray (mu, 3)
        W_w.
    fault_estimate : list of 3 float
        Fhat_w, rad/s^2, body frame.
    rate_estimate : list of 3 float
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
        self.fault_estimate = [0.0, 0.0, 0.0]
        self.rate_estimate = [0.0, 0.0, 0.0]
        lower, upper = model.input_lower, model.input_upper
        # u_m = (delta_lat, delta_lon, theta_tr) = input channels (2, 3, 1)
        self._lower = (lower[2], lower[3], lower[1])
        self._upper = (upper[2], upper[3], upper[1])
        self._started = False
        self._euler_d = self._alpha = self._z4 = self._zn = self._net = self._fnom = None
        self._act = self._applied = None

    def command(self, euler, omega, euler_d, thrust: float):
        """Limited moment inputs of this step.

        Parameters
        ----------
        euler : sequence of 3 float
            Measured (phi, theta, psi), rad.
        omega : sequence of 3 float
            Measured body rates, rad/s.
        euler_d : sequence of 3 float
            Attitude command (phi_d, theta_d, psi_d), rad.
        thrust : float
            Main-rotor thrust of the limited collective, N (enters G and f_nom).

        Returns
        -------
        u_m : list of 3 float
            (delta_lat, delta_lon, theta_tr) after the limits, rad.
        z3, z4, z_n : list of 3 float
            Attitude error rad, rate error rad/s, prediction error rad/s.
        saturated : bool
            A cyclic or the tail-rotor limit was active.
        """
        omega = [float(w) for w in omega]
        if not self._started:
            self.attitude_filter.reset(euler_d)
        theta_d_dot = self.attitude_filter.derivative(euler_d)
        z3 = [float(a) - b for a, b in zip(euler, self.attitude_filter.value)]
        z3[2] = wrap_angle(z3[2])
        phi, theta = float(euler[0]), float(euler[1])
        cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
        tt = st / ct
        k3 = self.k3
        e0, e1, e2 = (d - k3 * z for d, z in zip(theta_d_dot, z3))
        # H^-1 (Euler rates -> body rates) applied to -k3 z3 + Theta_df'
        alpha = [e0 - st * e2, cf * e1 + sf * ct * e2, -sf * e1 + cf * ct * e2]
        if not self._started:
            self.rate_filter.reset(alpha)
            self.rate_estimate = list(omega)
            self._started = True
        alpha_dot = self.rate_filter.derivative(alpha)
        z4 = [a - b for a, b in zip(omega, self.rate_filter.value)]
        zn = [a - b for a, b in zip(omega, self.rate_estimate)]
        net = self.rbf.evaluate(self.weights, omega)
        self._act = self.rbf.activations_buffer
        fnom = self.model.inner_drift(omega, thrust)
        g = self.model.control_effectiveness(thrust)
        a0, a1, a2 = z3
        ht_z3 = (a0, sf * tt * a0 + cf * a1 + sf / ct * a2, cf * tt * a0 - sf * a1 + cf / ct * a2)
        k4 = self.k4
        u_m = [(ad - fn - hz - nt - fh - k4 * z) / gi
               for ad, fn, hz, nt, fh, z, gi in zip(alpha_dot, fnom, ht_z3, net, self.fault_estimate, z4, g)]
        limited = [min(max(u, lo), hi) for u, lo, hi in zip(u_m, self._lower, self._upper)]
        saturated = limited != u_m
        self._euler_d, self._alpha, self._z4, self._zn = euler_d, alpha, z4, zn
        self._net, self._fnom = net, fnom
        self._applied = [gi * u for gi, u in zip(g, limited)]
        return limited, z3, z4, zn, saturated

    def advance(self, dt: float) -> None:
        """Integrate the SPEM, the weights, the fault estimate and both filters over ``dt`` s."""
        lg = self.gains
        fhat, zn, z4 = self.fault_estimate, self._zn, self._z4
        kappa = lg.kappa
        self.rate_estimate = [
            wh + dt * (fn + nt + a + fh + kappa * e)
            for wh, fn, nt, a, fh, e in zip(self.rate_estimate, self._fnom, self._net, self._applied,
                                            fhat, zn)]
        composite_weight_update(self.weights, self._act, z4, zn, lg.learning_rate, lg.gamma,
                                lg.sigma, dt, lg.weight_bound)
        gain, gf, sf, bound = dt * lg.lambda_, lg.gamma_F, lg.sigma_F, lg.fault_bound
        self.fault_estimate = [min(max(fh + gain * (z + gf * e - sf * fh), -bound), bound)
                               for fh, z, e in zip(fhat, z4, zn)]
        self.attitude_filter.advance(self._euler_d, dt)
        self.rate_filter.advance(self._alpha, dt)
