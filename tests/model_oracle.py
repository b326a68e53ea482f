"""Closed-form numpy model of the helicopter, the oracle of the tests of the compiled plant kernels.

Written from docs/model.md ("Frames and conventions", "Helicopter dynamics", "Inputs and limits",
"Lumped faults") in matrix form, independently of :mod:`uh_sim_node.plant_kernels` (which works on
scalar tuples in another order of operations): agreement with the kernels is to rounding, not bits.

Frames and units: inertial frame z-up; ZYX Euler angles ``Theta = (phi, theta, psi)`` rad with
``R = Rz(psi) Ry(theta) Rx(phi)`` (body -> inertial); body rates ``omega = (p, q, r)`` rad/s in the
body frame. State ``x`` (12,) = ``[p (3) m, v (3) m/s, Theta (3) rad, omega (3) rad/s]``; inputs
``u`` (4,) rad = ``(theta_col, theta_tr, delta_lat, delta_lon)``. ``params`` is a
``uh_core.airframe.HelicopterParams`` (or any object with its attributes).
"""
import math

import numpy as np
from textbook_rk4 import rk4

E3 = np.array([0.0, 0.0, 1.0])


def rotation_matrix(euler) -> np.ndarray:
    """Body-to-inertial rotation ``R = Rz(psi) Ry(theta) Rx(phi)``, (3, 3).

    Parameters
    ----------
    euler : array_like (3,)
        ``(phi, theta, psi)`` rad.
    """
    phi, th, psi = (float(a) for a in euler[:3])
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(th), math.sin(th)
    cp, sp = math.cos(psi), math.sin(psi)
    return np.array([
        [cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf],
        [sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf],
        [-st, ct * sf, ct * cf],
    ])


def euler_rate_matrix(euler) -> np.ndarray:
    """``H(Theta)``, (3, 3), with ``Theta' = H(Theta) omega`` for ZYX Euler angles.

    Parameters
    ----------
    euler : array_like (3,)
        ``(phi, theta, psi)`` rad; singular at ``theta = +-pi/2``.
    """
    phi, th = float(euler[0]), float(euler[1])
    cf, sf = math.cos(phi), math.sin(phi)
    ct, tt = math.cos(th), math.tan(th)
    return np.array([
        [1.0, sf * tt, cf * tt],
        [0.0, cf, -sf],
        [0.0, sf / ct, cf / ct],
    ])


def clip_inputs(params, u) -> np.ndarray:
    """Return the inputs ``u`` (4,) rad limited to ``[input_lower, input_upper]`` (a new array)."""
    return np.clip(np.asarray(u, dtype=float), params.input_lower, params.input_upper)


def thrust(params, theta_col: float) -> float:
    """Main-rotor thrust ``T_M = c_M1 theta_col + c_M2``, N, for the collective ``theta_col`` rad."""
    return params.c_M1 * float(theta_col) + params.c_M2


def rotor_moments(params, omega, u) -> np.ndarray:
    """Rotor moments ``Gamma(omega, u)``, (3,) N m, body frame.

    ``Gamma = [(K_beta + T_M h_M) b_1s, (K_beta + T_M h_M) a_1s, K_tr theta_tr - D_r r - c_Q T_M]``
    with the flapping ``b_1s = B_lat delta_lat - tau_f p``, ``a_1s = A_lon delta_lon - tau_f q`` rad.

    Parameters
    ----------
    omega : array_like (3,)
        Body rates ``(p, q, r)`` rad/s.
    u : array_like (4,)
        Inputs acting on the airframe, rad.
    """
    p, q, r = (float(w) for w in omega)
    T = thrust(params, u[0])
    k = params.K_beta + T * params.h_M
    return np.array([k * (params.B_lat * u[2] - params.tau_f * p),
                     k * (params.A_lon * u[3] - params.tau_f * q),
                     params.K_tr * u[1] - params.D_r * r - params.c_Q * T])


def state_derivative(params, x, u_actual, d_p=None) -> np.ndarray:
    """State derivative ``x'`` (12,) of docs/model.md, "Helicopter dynamics", in matrix form.

    ``m v' = -m g e3 + T_M R e3 - D_v v + d_p`` and ``J omega' = -omega x J omega + Gamma``, solved
    with ``numpy.linalg.solve`` for ``J = diag(inertia)``.

    Parameters
    ----------
    x : array_like (12,)
        State ``[p m, v m/s, Theta rad, omega rad/s]``.
    u_actual : array_like (4,)
        Inputs acting on the airframe (after faults and limits), rad; not limited here.
    d_p : array_like (3,), optional
        Force disturbance, N, inertial frame (zero when ``None``).

    Returns
    -------
    ndarray (12,)
        ``[v, v', Theta', omega']`` in m/s, m/s^2, rad/s, rad/s^2.
    """
    x = np.asarray(x, dtype=float)
    v, euler, w = x[3:6], x[6:9], x[9:12]
    d = np.zeros(3) if d_p is None else np.asarray(d_p, dtype=float)
    T = thrust(params, u_actual[0])
    m = params.mass
    vdot = (-m * params.gravity * E3 + T * rotation_matrix(euler) @ E3 - params.D_v * v + d) / m
    J = np.diag(params.inertia)
    wdot = np.linalg.solve(J, -np.cross(w, J @ w) + rotor_moments(params, w, u_actual))
    return np.concatenate([v, vdot, euler_rate_matrix(euler) @ w, wdot])


def lumped_faults(params, x, u_cmd, u_actual) -> tuple:
    """Return the true lumped faults written out as in docs/model.md, "Lumped faults".

    With ``DT = c_M1 (theta_col,act - theta_col,cmd)`` and ``T_cmd`` the thrust of ``u_cmd``::

        F_p   = (DT / m) R(Theta) e3
        F_w,x = [(K_beta + T_cmd h_M) B_lat Ddelta_lat + DT h_M (B_lat delta_lat,act - tau_f p)] / J_x
        F_w,y = [(K_beta + T_cmd h_M) A_lon Ddelta_lon + DT h_M (A_lon delta_lon,act - tau_f q)] / J_y
        F_w,z = [K_tr Dtheta_tr - c_Q DT] / J_z

    Parameters
    ----------
    x : array_like (12,)
        State at which they are evaluated.
    u_cmd : array_like (4,)
        Commanded inputs after the limits, rad.
    u_actual : array_like (4,)
        Inputs after faults and limits, rad.

    Returns
    -------
    tuple of ndarray (3,)
        ``F_p`` m/s^2, inertial frame; ``F_w`` rad/s^2, body frame.
    """
    uc, ua = np.asarray(u_cmd, dtype=float), np.asarray(u_actual, dtype=float)
    du = ua - uc
    dT = params.c_M1 * du[0]
    p, q = float(x[9]), float(x[10])
    k_cmd = params.K_beta + thrust(params, uc[0]) * params.h_M
    f_p = dT / params.mass * rotation_matrix(x[6:9]) @ E3
    f_w = np.array([
        k_cmd * params.B_lat * du[2] + dT * params.h_M * (params.B_lat * ua[2] - params.tau_f * p),
        k_cmd * params.A_lon * du[3] + dT * params.h_M * (params.A_lon * ua[3] - params.tau_f * q),
        params.K_tr * du[1] - params.c_Q * dT,
    ]) / np.asarray(params.inertia, dtype=float)
    return f_p, f_w


def reference_step(params, x, u_cmd, t, dt, substeps, schedule, disturbance=None) -> np.ndarray:
    """Take the plant's step from ``t`` to ``t + dt`` s, by textbook RK4 on :func:`state_derivative`.

    The command is limited once; at every stage the faults (``schedule.apply``, paper eq. 6, their
    activity decided at the substep start) and the limits again give the actual inputs; the
    disturbance is evaluated at the stage times (docs/model.md, "Integration").

    Parameters
    ----------
    x : array_like (12,)
        State at ``t``.
    u_cmd : array_like (4,)
        Command held over the step, rad.
    t, dt : float
        Start time and step, s.
    substeps : int
        RK4 substeps.
    schedule : uh_sim_node.faults.FaultSchedule
    disturbance : callable, optional
        ``t -> d_p(t)`` (3,) N, inertial (e.g. a ``SinusoidalDisturbance``); no force when ``None``.

    Returns
    -------
    ndarray (12,)
        State at ``t + dt``.
    """
    uc = clip_inputs(params, u_cmd)

    def f(tt, xx, ts):
        ua = clip_inputs(params, schedule.apply(uc, tt, switch_time=ts))
        return state_derivative(params, xx, ua, None if disturbance is None else disturbance(tt))

    return rk4(f, np.asarray(x, dtype=float), t, dt, substeps)
