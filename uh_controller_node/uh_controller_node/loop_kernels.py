"""Kernels of the law's two loops: command filters, the outer (position) and the inner (attitude) loop.

Per step, :mod:`.control_kernels` calls :func:`outer_law` -> :func:`thrust_and_attitude` ->
:func:`inner_law`, then advances both loops' internal states from t_k to t_{k+1}
(:func:`achieved_acceleration`, :func:`outer_advance`, :func:`inner_advance`; the learning states
through :mod:`.learning_kernels`), all right-hand sides taken at t_k (docs/control_law.md#outer-loop,
#thrust-and-attitude, #inner-loop). The nominal model's known parts are those of
docs/model.md#control-oriented-model. The arrays and their indices are :mod:`.control_layout`'s.

Compiled with numba as :mod:`.control_kernels` describes (no fastmath: IEEE double arithmetic, in
the order written), and ahead of time with the other kernel modules (docs/performance.md#memory).
"""
from __future__ import annotations

import math

import numpy as np

from uh_core import compiled_kernels as _compiled_kernels
from uh_core import kernel_cache as _kernel_cache
from uh_core import layout as _layout
from uh_core.compiled_kernels import njit
from uh_core.layout import U_COL, U_LAT, U_LON, U_TR, YAW

from . import control_layout as _control_layout
from . import gains as _gains
from . import learning_kernels as _learning_kernels
from .control_layout import LOOP, M_ALPHA_F, M_ALPHA_WF, M_F_HAT_P, M_F_HAT_W, M_OMEGA_HAT, M_THETA_DF, M_V_HAT, PARAM
from .learning_kernels import estimator_advance, in_learning_phase, rbf_activations, rbf_output

__all__ = ['wrap_angle', 'filter_gain', 'filter_rate', 'filter_advance', 'outer_law', 'thrust_and_attitude',
           'achieved_acceleration', 'outer_advance', 'euler_rate_inverse', 'euler_rate_transpose', 'inner_drift',
           'control_effectiveness', 'inner_law', 'inner_advance']

_MOMENT_CHANNELS = (U_LAT, U_LON, U_TR)         # command channels of u_m = (delta_lat, delta_lon, theta_tr)
_PI = math.pi
_TWO_PI = 2.0 * math.pi


# =============================================================================================
# Angles and command filters (docs/control_law.md#outer-loop step 1 and #inner-loop steps 1-2)


@njit(cache=True)
def wrap_angle(angle):
    """``angle`` rad wrapped to (-pi, pi] (IEEE remainder by 2 pi; -pi maps to pi).

    ``fmod`` is exact and keeps the sign of ``angle``; moving a result outside [-pi, pi] by 2 pi is
    exact too (Sterbenz), so this equals ``math.remainder(angle, 2 pi)`` bit for bit.
    """
    w = np.fmod(angle, _TWO_PI)
    if w > _PI:
        w -= _TWO_PI
    elif w < -_PI:
        w += _TWO_PI
    if w == -_PI:
        w = _PI
    return w


@njit(cache=True)
def filter_gain(tau, dt):
    """Gain ``1 - exp(-dt / tau)`` of the exact zero-order-hold step of ``tau y' = u - y``."""
    return -math.expm1(-dt / tau)


@njit(cache=True)
def filter_rate(u, y, tau, wrap_last, out):
    """Output rate of the command filter ``tau y' = u - y``, written to ``out`` (3,).

    A command filter turns a virtual control ``u`` into a smooth ``y`` and its derivative ``y'``
    without differentiating ``u`` analytically. With ``wrap_last`` the last axis is an angle: its
    difference ``u - y`` is wrapped to (-pi, pi] so a yaw command crossing +-pi is followed the
    short way (the filter state itself stays continuous).

    Parameters
    ----------
    u, y : ndarray (3,)
        Filter input and output (state).
    tau : float
        Time constant, s (> 0).
    wrap_last : bool
    out : ndarray (3,)
        ``y'``, input unit per s.
    """
    inv = 1.0 / tau
    for a in range(3):
        d = u[a] - y[a]
        if wrap_last and a == YAW:
            d = wrap_angle(d)
        out[a] = inv * d


@njit(cache=True)
def filter_advance(u, y, gain, wrap_last):
    """Advance the filter output ``y`` (3,) in place over one step with ``u`` held.

    ``y <- y + (1 - exp(-dt / tau)) (u - y)`` (``gain`` from :func:`filter_gain`): the exact
    solution for a held input, stable and free of overshoot for every ``dt > 0`` (forward Euler
    would need ``dt < 2 tau``). ``wrap_last`` as in :func:`filter_rate`.
    """
    for a in range(3):
        d = u[a] - y[a]
        if wrap_last and a == YAW:
            d = wrap_angle(d)
        y[a] = y[a] + gain * d


# =============================================================================================
# Outer (position) loop (docs/control_law.md#outer-loop)


@njit(cache=True)
def outer_law(params, degree, z1, feedforward, v, started, memory, weights, activations,
              alpha_v, alpha_rate, net, drift, z2, zn, u_p):
    """Compute the designed acceleration of the outer loop at t_k.

    The law is steps 1-7 of docs/control_law.md#outer-loop::

        alpha_v = (f - k1 z1) / d                                   virtual velocity, m/s
        tau_1 alpha_f' = alpha_v - alpha_f                          command filter
        z2 = v - alpha_f ,  z_n = v - vhat                          tracking and prediction errors
        u_p = alpha_f' - f_nom(v) - d z1 - W^T S(v) - Fhat - (beta / (2 r_p)) z2

    with ``f_nom(v) = -(D_v,nom / m) v`` the known drag. ``u_p`` is the inverse-optimal law of
    Lemma 2 (beta >= 2): it minimises ``J = int( l(z) + r_p |u_s|^2 ) dt`` for the feedback part
    ``u_s = -(beta / (2 r_p)) z2``. On the first step (``started`` False) the filter starts at
    rest at ``alpha_v`` and the SPEM at ``v``.

    Parameters
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    degree : float
        d.
    z1, feedforward, v : ndarray (3,)
        Consensus error m, f m/s, own velocity m/s (inertial).
    started : bool
    memory : ndarray (MEMORY_ROWS, 3)
        Reads alpha_f, vhat, Fhat_p (sets alpha_f, vhat when not started).
    weights : ndarray (mu_p, 3)
        W_p.
    activations : ndarray (mu_p, 3)
        Output: S(v).
    alpha_v, alpha_rate, net, drift, z2, zn, u_p : ndarray (3,)
        Outputs: alpha_v m/s, alpha_f' m/s^2, W^T S m/s^2, f_nom m/s^2, z2 m/s, z_n m/s,
        u_p m/s^2.
    """
    k1 = params[PARAM.outer + LOOP.k]
    k2 = params[PARAM.beta] / (2.0 * params[PARAM.outer + LOOP.r])   # inverse-optimal gain of z2, 1/s
    inv_d = 1.0 / degree
    for a in range(3):
        alpha_v[a] = (feedforward[a] - k1 * z1[a]) * inv_d
    alpha_f, vhat, fhat = memory[M_ALPHA_F], memory[M_V_HAT], memory[M_F_HAT_P]
    if not started:
        for a in range(3):
            alpha_f[a] = alpha_v[a]
            vhat[a] = v[a]
    filter_rate(alpha_v, alpha_f, params[PARAM.outer + LOOP.tau_command], False, alpha_rate)
    rbf_activations(v, params[PARAM.outer + LOOP.rbf_low], params[PARAM.outer + LOOP.rbf_high],
                    params[PARAM.outer + LOOP.rbf_width], activations)
    rbf_output(weights, activations, net)
    drag = params[PARAM.D_v] / params[PARAM.mass]
    for a in range(3):
        z2[a] = v[a] - alpha_f[a]
        zn[a] = v[a] - vhat[a]
        drift[a] = -drag * v[a]
        u_p[a] = alpha_rate[a] - drift[a] - degree * z1[a] - net[a] - fhat[a] - k2 * z2[a]


@njit(cache=True)
def thrust_and_attitude(params, u_p, psi_d):
    """Compute the thrust and roll/pitch that realise the designed acceleration ``u_p``.

    See docs/control_law.md#thrust-and-attitude and Remark 4.

    ``a = u_p + g e3`` (specific thrust, m/s^2, inertial). Its vertical part is kept at least
    ``min_vertical_accel``; its horizontal part is scaled down so the tilt from vertical is at most
    ``tilt_limit`` (Assumption 3; the vertical demand is kept, so ``T_c = m a_z / (cos phi cos
    theta)``). Then::

        theta_d = atan2(a_x cos psi + a_y sin psi, a_z)
        phi_d   = asin((a_x sin psi - a_y cos psi) / |a|)
        T_c = m |a| ,   theta_col = (T_c - c_M2) / c_M1, limited

    which solve ``(T_c / m) R(phi_d, theta_d, psi_d) e3 = a``.

    Parameters
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    u_p : ndarray (3,)
        Designed acceleration, m/s^2, inertial.
    psi_d : float
        Desired yaw, rad.

    Returns
    -------
    phi_d, theta_d : float
        rad.
    thrust : float
        T_c before the collective limit, N.
    theta_col : float
        Collective after its limits, rad.
    thrust_achieved : float
        ``c_M1 theta_col + c_M2`` with the limited collective, N.
    saturated_tilt, saturated_collective : bool
    """
    g = params[PARAM.gravity]
    ax, ay, az = u_p[0], u_p[1], u_p[2] + g
    sat_tilt = False
    if az < params[PARAM.min_vertical_accel]:
        az = params[PARAM.min_vertical_accel]
        sat_tilt = True
    horizontal = math.hypot(ax, ay)
    horizontal_max = az * math.tan(params[PARAM.tilt_limit])
    if horizontal > horizontal_max:
        scale = horizontal_max / horizontal
        ax *= scale
        ay *= scale
        sat_tilt = True
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    cp, sp = math.cos(psi_d), math.sin(psi_d)
    theta_d = math.atan2(ax * cp + ay * sp, az)
    phi_d = math.asin(max(-1.0, min(1.0, (ax * sp - ay * cp) / norm)))
    thrust = params[PARAM.mass] * norm
    theta_col = (thrust - params[PARAM.c_M2]) / params[PARAM.c_M1]
    lo, hi = params[PARAM.input_lower + U_COL], params[PARAM.input_upper + U_COL]
    sat_col = not lo <= theta_col <= hi
    theta_col = min(max(theta_col, lo), hi)
    thrust_achieved = params[PARAM.c_M1] * theta_col + params[PARAM.c_M2]
    return phi_d, theta_d, thrust, theta_col, thrust_achieved, sat_tilt, sat_col


@njit(cache=True)
def achieved_acceleration(params, euler, thrust, out):
    """Compute ``(T / m) R(Theta) e3 - g e3`` (3,) m/s^2, the acceleration of the limited thrust, to ``out``.

    It is the acceleration the limited thrust ``T`` (N) gives at the measured attitude ``euler``
    (rad), the outer SPEM's input (anti-windup, docs/control_law.md#anti-windup-and-projection).
    """
    cf, sf = math.cos(euler[0]), math.sin(euler[0])
    ct, st = math.cos(euler[1]), math.sin(euler[1])
    cp, sp = math.cos(euler[2]), math.sin(euler[2])
    tm = thrust / params[PARAM.mass]
    out[0] = tm * (cp * st * cf + sp * sf)
    out[1] = tm * (sp * st * cf - cp * sf)
    out[2] = tm * ct * cf - params[PARAM.gravity]


@njit(cache=True)
def outer_advance(params, dt, memory, weights, activations, alpha_v, net, drift, accel, z2, zn):
    """Advance the outer loop's internal states from t_k to t_{k+1}.

    Explicit Euler, right-hand sides at t_k::

        vhat'  = f_nom(v) + W^T S(v) + a_ach + Fhat + kappa z_n     serial-parallel estimation model
        W'     = Gamma [ S (z2 + gamma z_n)^T - sigma W ]           composite learning, then projection
        Fhat'  = lambda [ z2 + gamma_F z_n - sigma_F Fhat ]         fault observer, then projection
        alpha_f <- alpha_f + (1 - exp(-dt / tau_1)) (alpha_v - alpha_f)

    ``a_ach = (T_ach / m) R(Theta) e3 - g e3`` (:func:`achieved_acceleration`) is the acceleration
    the plant receives from the thrust the limits let through, at the measured attitude.

    Parameters
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    dt : float
        s.
    memory : ndarray (MEMORY_ROWS, 3)
        alpha_f, vhat, Fhat_p updated in place.
    weights : ndarray (mu_p, 3)
        W_p, updated in place.
    activations : ndarray (mu_p, 3)
        S(v) at t_k.
    alpha_v, net, drift, accel, z2, zn : ndarray (3,)
        At t_k, from :func:`outer_law` and :func:`achieved_acceleration`.
    """
    estimator_advance(params, PARAM.outer, dt, in_learning_phase(params, memory), drift, net, accel, z2, zn,
                      activations, memory[M_V_HAT], weights, memory[M_F_HAT_P])
    filter_advance(alpha_v, memory[M_ALPHA_F], filter_gain(params[PARAM.outer + LOOP.tau_command], dt), False)


# =============================================================================================
# Inner (attitude) loop (docs/control_law.md#inner-loop) and the nominal model's known parts
# (docs/model.md#control-oriented-model)


@njit(cache=True)
def euler_rate_inverse(euler, e, out):
    """``H(Theta)^-1 e`` (Euler-angle rates -> body rates), to ``out`` (3,).

    ``H = [[1, s_phi t_theta, c_phi t_theta], [0, c_phi, -s_phi], [0, s_phi/c_theta, c_phi/c_theta]]``
    (``Theta' = H omega``) has the inverse ``[[1, 0, -s_theta], [0, c_phi, s_phi c_theta],
    [0, -s_phi, c_phi c_theta]]``.
    """
    cf, sf = math.cos(euler[0]), math.sin(euler[0])
    ct, st = math.cos(euler[1]), math.sin(euler[1])
    e0, e1, e2 = e[0], e[1], e[2]
    out[0] = e0 - st * e2
    out[1] = cf * e1 + sf * ct * e2
    out[2] = -sf * e1 + cf * ct * e2


@njit(cache=True)
def euler_rate_transpose(euler, e, out):
    """``H(Theta)^T e`` (3,), the term that cancels the cross term of ``z3' = -k3 z3 + H z4``."""
    cf, sf = math.cos(euler[0]), math.sin(euler[0])
    ct, st = math.cos(euler[1]), math.sin(euler[1])
    tt = st / ct
    e0, e1, e2 = e[0], e[1], e[2]
    out[0] = e0
    out[1] = sf * tt * e0 + cf * e1 + sf / ct * e2
    out[2] = cf * tt * e0 - sf * e1 + cf / ct * e2


@njit(cache=True)
def inner_drift(params, omega, thrust, out):
    """Compute the known rate dynamics ``f_w,nom(omega, T)`` (3,) rad/s^2 of the nominal model.

    The model is that of docs/model.md#control-oriented-model::

        f_w,nom = J^-1 ( -omega x J omega + [-(K_beta + T h_M) tau_f p, -(K_beta + T h_M) tau_f q,
                                              -D_r r - c_Q T] )

    ``omega`` (3,) rad/s body; ``thrust`` T N; ``c_Q`` is the mismatched nominal value.
    """
    p, q, r = omega[0], omega[1], omega[2]
    jx, jy, jz = params[PARAM.inertia], params[PARAM.inertia + 1], params[PARAM.inertia + 2]
    k = params[PARAM.K_beta] + thrust * params[PARAM.h_M]
    tau_f = params[PARAM.tau_f]
    out[0] = ((jy - jz) * q * r - k * tau_f * p) / jx
    out[1] = ((jz - jx) * r * p - k * tau_f * q) / jy
    out[2] = ((jx - jy) * p * q - params[PARAM.D_r] * r - params[PARAM.c_Q] * thrust) / jz


@njit(cache=True)
def control_effectiveness(params, thrust, out):
    """Compute the diagonal of ``G(T) = J^-1 diag((K_beta + T h_M) B_lat, (K_beta + T h_M) A_lon, K_tr)``.

    The diagonal is (3,), rad/s^2 per rad, for ``u_m = (delta_lat, delta_lon, theta_tr)``;
    ``thrust`` T in N.
    """
    k = params[PARAM.K_beta] + thrust * params[PARAM.h_M]
    out[0] = k * params[PARAM.B_lat] / params[PARAM.inertia]
    out[1] = k * params[PARAM.A_lon] / params[PARAM.inertia + 1]
    out[2] = params[PARAM.K_tr] / params[PARAM.inertia + 2]


@njit(cache=True)
def inner_law(params, euler, omega, euler_d, thrust, started, memory, weights, activations,
              theta_rate, alpha_w, alpha_rate, net, drift, effectiveness, z3, z4, zn, u_m, applied):
    """Compute the limited moment inputs of the inner loop at t_k.

    The law is that of docs/control_law.md#inner-loop::

        tau_2 Theta_df' = Theta_d - Theta_df                       command filter (yaw difference wrapped)
        z3 = Theta - Theta_df   (yaw wrapped to (-pi, pi])         attitude error, rad
        alpha_w = H(Theta)^-1 (-k3 z3 + Theta_df')                  virtual body rate, rad/s
        tau_w alpha_wf' = alpha_w - alpha_wf                        rate command filter
        z4 = omega - alpha_wf ,  z_n = omega - omegahat
        G u_m = alpha_wf' - f_nom(omega, T) - H^T z3 - W^T S(omega) - Fhat - (beta / (2 r_w)) z4

    then ``u_m = (delta_lat, delta_lon, theta_tr)`` is limited. With ``V = |z3|^2/2 + |z4|^2/2``
    the ``H^T z3`` term cancels the cross term of ``z3' = -k3 z3 + H z4``:
    ``V' = -k3 |z3|^2 - beta/(2 r_w) |z4|^2 + z4 . (errors)``. On the first step (``started``
    False) both filters start at rest at their inputs and the SPEM at ``omega``.

    Parameters
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    euler, omega : ndarray (3,)
        Measured Theta rad and body rates rad/s.
    euler_d : ndarray (3,)
        Attitude command (phi_d, theta_d, psi_d), rad.
    thrust : float
        Thrust of the limited collective, N (enters G and f_nom).
    started : bool
    memory : ndarray (MEMORY_ROWS, 3)
        Reads Theta_df, alpha_wf, omegahat, Fhat_w (sets the first three when not started).
    weights : ndarray (mu_w, 3)
        W_w.
    activations : ndarray (mu_w, 3)
        Output: S(omega).
    theta_rate, alpha_w, alpha_rate, net, drift, effectiveness, z3, z4, zn, u_m, applied : ndarray (3,)
        Outputs: Theta_df' rad/s, alpha_w rad/s, alpha_wf' rad/s^2, W^T S rad/s^2, f_nom rad/s^2,
        diagonal of G, z3 rad, z4 rad/s, z_n rad/s, limited u_m rad, ``G u_m`` after the limits
        rad/s^2.

    Returns
    -------
    saturated : bool
        A cyclic or the tail-rotor limit was active.
    """
    base = PARAM.inner
    theta_df, alpha_wf = memory[M_THETA_DF], memory[M_ALPHA_WF]
    omegahat, fhat = memory[M_OMEGA_HAT], memory[M_F_HAT_W]
    if not started:
        for a in range(3):
            theta_df[a] = euler_d[a]
    filter_rate(euler_d, theta_df, params[base + LOOP.tau_command], True, theta_rate)
    for a in range(3):
        z3[a] = euler[a] - theta_df[a]
    z3[YAW] = wrap_angle(z3[YAW])
    k3 = params[base + LOOP.k]
    rate_command = np.empty(3)                  # -k3 z3 + Theta_df', Euler-angle rates, rad/s
    for a in range(3):
        rate_command[a] = theta_rate[a] - k3 * z3[a]
    euler_rate_inverse(euler, rate_command, alpha_w)
    if not started:
        for a in range(3):
            alpha_wf[a] = alpha_w[a]
            omegahat[a] = omega[a]
    filter_rate(alpha_w, alpha_wf, params[base + LOOP.tau_rate], False, alpha_rate)
    for a in range(3):
        z4[a] = omega[a] - alpha_wf[a]
        zn[a] = omega[a] - omegahat[a]
    rbf_activations(omega, params[base + LOOP.rbf_low], params[base + LOOP.rbf_high],
                    params[base + LOOP.rbf_width], activations)
    rbf_output(weights, activations, net)
    inner_drift(params, omega, thrust, drift)
    control_effectiveness(params, thrust, effectiveness)
    ht_z3 = np.empty(3)
    euler_rate_transpose(euler, z3, ht_z3)
    k4 = params[PARAM.beta] / (2.0 * params[base + LOOP.r])   # inverse-optimal gain of z4, 1/s
    saturated = False
    for a in range(3):
        channel = _MOMENT_CHANNELS[a]
        want = (alpha_rate[a] - drift[a] - ht_z3[a] - net[a] - fhat[a] - k4 * z4[a]) / effectiveness[a]
        got = min(max(want, params[PARAM.input_lower + channel]), params[PARAM.input_upper + channel])
        if got != want:
            saturated = True
        u_m[a] = got
    for a in range(3):
        applied[a] = effectiveness[a] * u_m[a]
    return saturated


@njit(cache=True)
def inner_advance(params, dt, memory, weights, activations, euler_d, alpha_w, net, drift, applied, z4, zn):
    """Advance the inner loop's internal states from t_k to t_{k+1}.

    Explicit Euler, right-hand sides at t_k::

        omegahat' = f_nom + W^T S + G u_m,lim + Fhat + kappa z_n    SPEM fed with the limited input
        W'        = Gamma [ S (z4 + gamma z_n)^T - sigma W ]         then projection
        Fhat'     = lambda [ z4 + gamma_F z_n - sigma_F Fhat ]       then projection
        Theta_df <- Theta_df + (1 - exp(-dt / tau_2)) (Theta_d - Theta_df)    (yaw difference wrapped)
        alpha_wf <- alpha_wf + (1 - exp(-dt / tau_w)) (alpha_w - alpha_wf)

    Parameters
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    dt : float
        s.
    memory : ndarray (MEMORY_ROWS, 3)
        Theta_df, alpha_wf, omegahat, Fhat_w updated in place.
    weights : ndarray (mu_w, 3)
        W_w, updated in place.
    activations : ndarray (mu_w, 3)
        S(omega) at t_k.
    euler_d, alpha_w, net, drift, applied, z4, zn : ndarray (3,)
        At t_k, from :func:`inner_law` (``applied`` = G u_m after the limits).
    """
    estimator_advance(params, PARAM.inner, dt, in_learning_phase(params, memory), drift, net, applied, z4, zn,
                      activations, memory[M_OMEGA_HAT], weights, memory[M_F_HAT_W])
    filter_advance(euler_d, memory[M_THETA_DF], filter_gain(params[PARAM.inner + LOOP.tau_command], dt), True)
    filter_advance(alpha_w, memory[M_ALPHA_WF], filter_gain(params[PARAM.inner + LOOP.tau_rate], dt), False)


# numba caches each kernel by this file only: empty the cache when a table or a kernel it compiles in changes
_kernel_cache.refresh_cache(_kernel_cache.module_dispatchers(globals()),
                            [_layout.__file__, _gains.__file__, _control_layout.__file__, _learning_kernels.__file__])

# run the ahead-of-time compiled kernels instead where this process asks for them (docs/performance.md#memory)
_compiled_kernels.install(globals())
