"""Native kernels of the fault isolator of one UH (docs/faults.md#isolation-and-identification).

These functions *are* the isolator's arithmetic: :class:`uh_controller_node.fault_isolation.FaultIsolator`
calls :func:`isolation_step` once per control step (online, in every controller), and
:func:`uh_controller_node.isolation_runs.isolate_run` calls :func:`isolation_run`, which loops over
every step of a run calling the same :func:`isolation_step`; so the online and the offline isolator
are one code and give the same bits. They are compiled with numba (``@njit(cache=True)``, no
fastmath, no parallelism: IEEE double arithmetic, in the order of operations of the formulas in
:mod:`uh_controller_node.fault_isolation`), and give exactly the numbers of the pure-Python
isolator they replaced (``tests/isolation_oracle.py``; Python's ``min``, ``max`` and ``abs`` of
floats are reproduced as they are, NaN included).

Arrays
------
* ``params`` (ISO_PARAMS_SIZE,) built once by ``FaultIsolator``: the nominal constants of
  ``input_deviation`` at ``IP_MASS`` .. ``IP_C_Q`` (kg, kg m^2, N/rad, N, N m/rad, m, -, -, s,
  N m/rad, -), the input limits ``IP_LOWER`` and ``IP_UPPER`` (4 each, rad), the constant thresholds
  ``IP_THRESHOLDS``, healthy noise RMS ``IP_NOISE_RMS`` and residual limits ``IP_RESIDUAL_MAX`` (4
  each, rad), and the scalars ``IP_LEARNING_PHASE`` (s), ``IP_CONFIRMATION`` (s), ``IP_ALPHA`` (the
  filter's ``1 - exp(-dt / filter_tau)``, -), ``IP_CQ_ERROR`` (``|1/mismatch - 1|``, -),
  ``IP_FORGETTING`` (-), ``IP_DT`` (s), ``IP_RHO_TOLERANCE`` (-), ``IP_BIAS_TOLERANCE`` (rad),
  ``IP_MIN_FIT_TIME`` (s).
* ``state`` (ISO_STATE_SIZE + window,) of one isolator, all zeros but the NaNs set by
  :func:`new_isolation_state`: per channel (4 each) the filtered deviation ``IS_Y`` (rad), the
  filtered coupling allowance ``IS_E`` (rad), the time since which ``|y|`` is above its threshold
  ``IS_ABOVE`` (s, NaN when it is not), ``IS_ISOLATED`` (1.0 once isolated), ``IS_DETECTION`` (s,
  NaN while not isolated), the last step's deviation ``IS_D`` (rad) and its limited command ``IS_U``
  (rad); the least-squares fit of channel c at ``IS_FIT + FIT_SIZE c`` with entries ``F_W`` (sum of
  weights), ``F_MU``, ``F_MD`` (weighted means of u and d, rad), ``F_SUU``, ``F_SUD``, ``F_SDD``
  (weighted centred sums, rad^2), ``F_T0``, ``F_T1`` (first and last time, s; NaN while empty);
  then the window of recent thrust deviations (N): a ring of ``state.size - IS_WINDOW`` entries
  holding ``IS_WINDOW_COUNT`` values, the next written at ``IS_WINDOW_NEXT``.
* ``verdict`` (VERDICT_SIZE,) from :func:`isolation_verdict`: ``V_CODE`` (the identification code as
  a float), ``V_RHO`` (-), ``V_BIAS`` (rad), ``V_FIT_TIME`` (s), ``V_STD_U``, ``V_STD_A``,
  ``V_RESIDUAL`` (rad), ``V_RHO_BOUND`` (-), ``V_BIAS_BOUND`` (rad).
* ``out`` (STATUS_ROWS, 4) from :func:`isolation_status`: the published status, rows ``O_*``.

The kernels do not check shapes (the Python wrapper does). Division by zero raises
``ZeroDivisionError`` (numba's Python error model), as the same expression did in Python.

Compilation and the on-disk cache
---------------------------------
As for :mod:`uh_controller_node.control_kernels`: the first call compiles (seconds) into numba's
cache next to this file; :func:`compile_isolation_kernels` compiles the signatures the isolator
uses, for install scripts that warm the cache.
"""
from __future__ import annotations

import math
import time

import numpy as np

from uh_core import compiled_kernels as _compiled_kernels
from uh_core import kernel_cache as _kernel_cache
from uh_core import layout as _layout
from uh_core.compiled_kernels import njit
from uh_core.layout import X_OMEGA, X_THETA

__all__ = ['ISO_PARAMS_SIZE', 'ISO_STATE_SIZE', 'VERDICT_SIZE', 'TRACE_COLUMNS', 'STATUS_ROWS', 'new_isolation_state',
           'input_deviations', 'isolation_step', 'isolation_run', 'isolation_verdict', 'isolation_status',
           'unable_channel', 'first_unable_step', 'UNABLE_BOUNDS',
           'compile_isolation_kernels',
           'O_ISOLATED', 'O_DETECTION', 'O_DEVIATION', 'O_THRESHOLD', 'O_RHO', 'O_BIAS', 'O_CODE', 'O_SPREAD',
           'IP_MASS', 'IP_C_Q', 'IP_LOWER', 'IP_UPPER', 'IP_THRESHOLDS', 'IP_NOISE_RMS', 'IP_RESIDUAL_MAX',
           'IP_LEARNING_PHASE', 'IP_CONFIRMATION', 'IP_ALPHA', 'IP_CQ_ERROR', 'IP_FORGETTING', 'IP_DT',
           'IP_RHO_TOLERANCE', 'IP_BIAS_TOLERANCE', 'IP_MIN_FIT_TIME',
           'IS_Y', 'IS_E', 'IS_ABOVE', 'IS_ISOLATED', 'IS_DETECTION', 'IS_D', 'IS_U', 'IS_FIT', 'IS_WINDOW_COUNT',
           'IS_WINDOW_NEXT', 'IS_WINDOW', 'FIT_SIZE', 'F_W', 'F_MU', 'F_MD', 'F_SUU', 'F_SUD', 'F_SDD', 'F_T0', 'F_T1',
           'V_CODE', 'V_RHO', 'V_BIAS', 'V_FIT_TIME', 'V_STD_U', 'V_STD_A', 'V_RESIDUAL', 'V_RHO_BOUND', 'V_BIAS_BOUND']

_N = 4  # channels

# params: the nominal constants (IP_MASS .. IP_C_Q), in the order of fault_isolation._constants
(IP_MASS, IP_JX, IP_JY, IP_JZ, IP_C_M1, IP_C_M2, IP_K_BETA, IP_H_M, IP_B_LAT, IP_A_LON, IP_TAU_F, IP_K_TR,
 IP_C_Q) = range(13)
IP_LOWER, IP_UPPER, IP_THRESHOLDS, IP_NOISE_RMS, IP_RESIDUAL_MAX = 13, 17, 21, 25, 29
(IP_LEARNING_PHASE, IP_CONFIRMATION, IP_ALPHA, IP_CQ_ERROR, IP_FORGETTING, IP_DT, IP_RHO_TOLERANCE,
 IP_BIAS_TOLERANCE, IP_MIN_FIT_TIME) = range(33, 42)
ISO_PARAMS_SIZE = 42

# state
IS_Y, IS_E, IS_ABOVE, IS_ISOLATED, IS_DETECTION, IS_D, IS_U = 0, 4, 8, 12, 16, 20, 24
IS_FIT = 28
F_W, F_MU, F_MD, F_SUU, F_SUD, F_SDD, F_T0, F_T1 = range(8)
FIT_SIZE = 8
IS_WINDOW_COUNT = IS_FIT + _N * FIT_SIZE
IS_WINDOW_NEXT = IS_WINDOW_COUNT + 1
IS_WINDOW = IS_WINDOW_NEXT + 1
ISO_STATE_SIZE = IS_WINDOW

# verdict
V_CODE, V_RHO, V_BIAS, V_FIT_TIME, V_STD_U, V_STD_A, V_RESIDUAL, V_RHO_BOUND, V_BIAS_BOUND = range(9)
VERDICT_SIZE = 9
# verdict codes (uh_controller_node.fault_isolation's, checked equal by a test)
_FIT_TOO_SHORT, _BIAS_NOT_CONSTANT, _CONFOUNDED, _IDENTIFIABLE = 1, 2, 3, 4

# isolation_status
O_ISOLATED, O_DETECTION, O_DEVIATION, O_THRESHOLD, O_RHO, O_BIAS, O_CODE, O_SPREAD = range(8)
STATUS_ROWS = 8

#: Columns of :func:`isolation_run`'s trace: filtered deviations (4, rad), thresholds (4, rad), deviations (4, rad).
TRACE_COLUMNS = 3 * _N


def new_isolation_state(window: int) -> np.ndarray:
    """Return the state of a fresh isolator whose thrust-deviation window holds ``window`` (>= 1) values."""
    state = np.zeros(ISO_STATE_SIZE + int(window))
    state[IS_ABOVE:IS_ABOVE + _N] = math.nan
    state[IS_DETECTION:IS_DETECTION + _N] = math.nan
    for c in range(_N):
        state[IS_FIT + FIT_SIZE * c + F_T0] = math.nan
        state[IS_FIT + FIT_SIZE * c + F_T1] = math.nan
    return state


@njit(cache=True)
def _py_max(a, b):
    """Python's ``max(a, b)`` of floats: ``b`` only if ``b > a``."""
    return b if b > a else a


@njit(cache=True)
def _py_min(a, b):
    """Python's ``min(a, b)`` of floats: ``b`` only if ``b < a``."""
    return b if b < a else a


@njit(cache=True)
def _deviation(params, p, q, u0, u2, u3, phi, theta, psi, fp0, fp1, fp2, fw0, fw1, fw2):
    """Return ``(d_col, d_tr, d_lat, d_lon, dT, kTa)`` (rad, N, N m/rad): fault_isolation.input_deviation."""
    m, jx, jy, jz = params[IP_MASS], params[IP_JX], params[IP_JY], params[IP_JZ]
    c_m1, c_m2, k_beta, h_m = params[IP_C_M1], params[IP_C_M2], params[IP_K_BETA], params[IP_H_M]
    b_lat, a_lon, tau_f = params[IP_B_LAT], params[IP_A_LON], params[IP_TAU_F]
    k_tr, c_q = params[IP_K_TR], params[IP_C_Q]
    cf, sf, ct, st, cp, sp = (math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta),
                              math.cos(psi), math.sin(psi))
    dT = m * ((cp * st * cf + sp * sf) * fp0 + (sp * st * cf - cp * sf) * fp1 + ct * cf * fp2)
    T = c_m1 * u0 + c_m2
    k_t = k_beta + T * h_m
    k_ta = k_beta + (T + dT) * h_m
    return (dT / c_m1,
            (jz * fw2 + c_q * dT) / k_tr,
            (jx * fw0 - (k_ta - k_t) * (b_lat * u2 - tau_f * p)) / (k_ta * b_lat),
            (jy * fw1 - (k_ta - k_t) * (a_lon * u3 - tau_f * q)) / (k_ta * a_lon),
            dT, k_ta)


@njit(cache=True)
def input_deviations(params, x, u, fhat_p, fhat_w, d):
    """Write the deviations ``d ~ u_act - u`` (4,) rad for state ``x``, command ``u``; return ``dT``, N.

    fault_isolation.input_deviation (``u`` as given, not limited).
    """
    d0, d1, d2, d3, dT, _ = _deviation(params, x[X_OMEGA], x[X_OMEGA + 1], u[0], u[2], u[3], x[X_THETA],
                                       x[X_THETA + 1], x[X_THETA + 2], fhat_p[0], fhat_p[1], fhat_p[2],
                                       fhat_w[0], fhat_w[1], fhat_w[2])
    d[0], d[1], d[2], d[3] = d0, d1, d2, d3
    return dT


@njit(cache=True)
def _window_spread(state, dT):
    """Append ``dT`` to the window (dropping the oldest when full); return its max - min, N.

    Max and min are Python's, over the values oldest first.
    """
    size = state.shape[0] - IS_WINDOW
    count, nxt = int(state[IS_WINDOW_COUNT]), int(state[IS_WINDOW_NEXT])
    state[IS_WINDOW + nxt] = dT
    nxt = (nxt + 1) % size
    if count < size:
        count += 1
    state[IS_WINDOW_COUNT], state[IS_WINDOW_NEXT] = count, nxt
    first = (nxt - count) % size
    hi = lo = state[IS_WINDOW + first]
    for i in range(1, count):
        v = state[IS_WINDOW + (first + i) % size]
        if v > hi:
            hi = v
        if v < lo:
            lo = v
    return hi - lo


@njit(cache=True)
def _fit_add(state, c, lam, t, u, d):
    """Add ``(u, d)`` (rad) at time ``t`` (s) to channel ``c``'s least-squares fit of ``d = theta_1 u + theta_2``.

    The fit in its exact (sufficient-statistics) form: exponentially weighted means and centred
    second moments, updated per sample (West's weighted Welford recursion), forgetting factor
    ``lam``. Equivalent to the covariance form of recursive least squares started with an infinite
    covariance (no prior), which that form only approximates with a large ``P_0``.
    """
    f = IS_FIT + FIT_SIZE * c
    state[f + F_W] *= lam
    state[f + F_SUU] *= lam
    state[f + F_SUD] *= lam
    state[f + F_SDD] *= lam
    state[f + F_W] += 1.0
    w = state[f + F_W]
    du = u - state[f + F_MU]
    dd = d - state[f + F_MD]
    state[f + F_MU] += du / w
    state[f + F_MD] += dd / w
    mu, md = state[f + F_MU], state[f + F_MD]
    state[f + F_SUU] += du * (u - mu)
    state[f + F_SUD] += du * (d - md)
    state[f + F_SDD] += dd * (d - md)
    if math.isnan(state[f + F_T0]):
        state[f + F_T0] = t
    state[f + F_T1] = t


@njit(cache=True)
def _start_fit(state, c):
    """Empty channel ``c``'s fit."""
    f = IS_FIT + FIT_SIZE * c
    for i in range(F_T0):
        state[f + i] = 0.0
    state[f + F_T0] = math.nan
    state[f + F_T1] = math.nan


@njit(cache=True)
def isolation_step(params, state, t, x, u, fhat_p, fhat_w):
    """Process one control step at run time ``t`` (s): FaultIsolator.update, with ``u`` (4,) rad as commanded.

    ``x`` (12,) state, ``fhat_p``, ``fhat_w`` (3,) the estimates used at this step (m/s^2, rad/s^2).
    Nothing changes while ``t`` is below the learning phase.
    """
    if t < params[IP_LEARNING_PHASE] - 1e-9:
        return
    for c in range(_N):
        state[IS_U + c] = _py_min(_py_max(u[c], params[IP_LOWER + c]), params[IP_UPPER + c])
    p, q = x[X_OMEGA], x[X_OMEGA + 1]
    d0, d1, d2, d3, dT, k_ta = _deviation(params, p, q, state[IS_U], state[IS_U + 2], state[IS_U + 3], x[X_THETA],
                                          x[X_THETA + 1], x[X_THETA + 2], fhat_p[0], fhat_p[1], fhat_p[2],
                                          fhat_w[0], fhat_w[1], fhat_w[2])
    state[IS_D], state[IS_D + 1], state[IS_D + 2], state[IS_D + 3] = d0, d1, d2, d3
    spread = _window_spread(state, dT)
    h_m, b_lat, a_lon, tau_f = params[IP_H_M], params[IP_B_LAT], params[IP_A_LON], params[IP_TAU_F]
    k_tr, c_q = params[IP_K_TR], params[IP_C_Q]
    allowance1 = c_q * (params[IP_CQ_ERROR] * abs(dT) + spread) / k_tr
    allowance2 = h_m * spread * abs(b_lat * state[IS_U + 2] - tau_f * p) / (abs(k_ta) * b_lat)
    allowance3 = h_m * spread * abs(a_lon * state[IS_U + 3] - tau_f * q) / (abs(k_ta) * a_lon)
    a = params[IP_ALPHA]
    for c in range(_N):
        allowance = 0.0 if c == 0 else (allowance1 if c == 1 else (allowance2 if c == 2 else allowance3))
        state[IS_Y + c] += a * (state[IS_D + c] - state[IS_Y + c])
        state[IS_E + c] += a * (allowance - state[IS_E + c])
    for c in range(_N):
        if state[IS_ISOLATED + c] != 0.0:
            _fit_add(state, c, params[IP_FORGETTING], t, state[IS_U + c], state[IS_D + c])
            continue
        if abs(state[IS_Y + c]) > params[IP_THRESHOLDS + c] + state[IS_E + c]:
            if math.isnan(state[IS_ABOVE + c]):
                state[IS_ABOVE + c] = t
            if t - state[IS_ABOVE + c] >= params[IP_CONFIRMATION] - 1e-9:
                state[IS_ISOLATED + c] = 1.0
                state[IS_DETECTION + c] = t
                _start_fit(state, c)
        else:
            state[IS_ABOVE + c] = math.nan


@njit(cache=True)
def isolation_run(params, state, times, states, commands, fault_p, fault_w, trace):
    """Call :func:`isolation_step` on every row ``k``: ``times[k]`` s, ``states[k]``, ``commands[k]``, estimates.

    ``trace`` (rows, TRACE_COLUMNS) receives after each step the filtered deviations, the thresholds
    (constant + filtered allowance) and the deviations, rad; pass a (0, TRACE_COLUMNS) array for none.
    """
    keep = trace.shape[0] > 0
    for k in range(times.shape[0]):
        isolation_step(params, state, times[k], states[k], commands[k], fault_p[k], fault_w[k])
        if keep:
            for c in range(_N):
                trace[k, c] = state[IS_Y + c]
                trace[k, _N + c] = params[IP_THRESHOLDS + c] + state[IS_E + c]
                trace[k, 2 * _N + c] = state[IS_D + c]


@njit(cache=True)
def _fit_theta(state, f):
    """``(theta_1, theta_2)`` of the fit at ``f``; NaN while the command has not varied."""
    if state[f + F_W] <= 0.0 or not state[f + F_SUU] > 0.0:
        return math.nan, math.nan
    th1 = state[f + F_SUD] / state[f + F_SUU]
    return th1, state[f + F_MD] - th1 * state[f + F_MU]


@njit(cache=True)
def _fit_stats(state, f):
    """``(std u, std (u + d), residual RMS)`` of the fit at ``f``, rad."""
    w, suu, sud, sdd = state[f + F_W], state[f + F_SUU], state[f + F_SUD], state[f + F_SDD]
    if w <= 0.0:
        return math.nan, math.nan, math.nan
    var_u = _py_max(suu, 0.0) / w
    var_a = _py_max(suu + 2.0 * sud + sdd, 0.0) / w
    if suu > 0.0:
        rss = sdd - sud * sud / suu
    else:
        rss = sdd
    return math.sqrt(var_u), math.sqrt(var_a), math.sqrt(_py_max(rss, 0.0) / w)


@njit(cache=True)
def isolation_verdict(params, state, c, verdict):
    """Write the fit's numbers and verdict code of isolated channel ``c`` to ``verdict`` (VERDICT_SIZE,).

    FaultIsolator._verdict (the class docstring of FaultIsolator).
    """
    f = IS_FIT + FIT_SIZE * c
    fit_time = 0.0 if state[f + F_W] == 0.0 else state[f + F_T1] - state[f + F_T0] + params[IP_DT]
    th1, th2 = _fit_theta(state, f)
    std_u, std_a, resid = _fit_stats(state, f)
    sigma = _py_max(params[IP_NOISE_RMS + c], resid) if not math.isnan(resid) else math.nan
    rho_bound = sigma / (std_a - sigma) if std_a > sigma else math.inf
    bias_bound = sigma + rho_bound * abs(state[f + F_MU]) if math.isfinite(rho_bound) else math.inf
    if fit_time < params[IP_MIN_FIT_TIME] - 1e-9:
        code = _FIT_TOO_SHORT
    elif resid > params[IP_RESIDUAL_MAX + c]:
        code = _BIAS_NOT_CONSTANT
    elif rho_bound > params[IP_RHO_TOLERANCE] or bias_bound > params[IP_BIAS_TOLERANCE]:
        code = _CONFOUNDED
    else:
        code = _IDENTIFIABLE
    verdict[V_CODE], verdict[V_RHO], verdict[V_BIAS], verdict[V_FIT_TIME] = code, 1.0 + th1, th2, fit_time
    verdict[V_STD_U], verdict[V_STD_A], verdict[V_RESIDUAL] = std_u, std_a, resid
    verdict[V_RHO_BOUND], verdict[V_BIAS_BOUND] = rho_bound, bias_bound


@njit(cache=True)
def isolation_status(params, state, verdict, out):
    """Write what a controller publishes each step to ``out`` (STATUS_ROWS, 4), one column per channel.

    Rows: ``O_ISOLATED`` (1.0 or 0.0), ``O_DETECTION`` (s), ``O_DEVIATION`` (filtered, rad),
    ``O_THRESHOLD`` (rad), ``O_RHO`` (-), ``O_BIAS`` (rad), ``O_CODE`` (the verdict code) and
    ``O_SPREAD`` (1.0 when the fit's command has varied, so ``O_RHO`` and ``O_BIAS`` are numbers);
    ``O_RHO``, ``O_BIAS`` NaN and ``O_CODE`` 0 on a channel not isolated. ``verdict``
    (VERDICT_SIZE,) is scratch.
    """
    for c in range(_N):
        out[O_ISOLATED, c] = state[IS_ISOLATED + c]
        out[O_DETECTION, c] = state[IS_DETECTION + c]
        out[O_DEVIATION, c] = state[IS_Y + c]
        out[O_THRESHOLD, c] = params[IP_THRESHOLDS + c] + state[IS_E + c]
        f = IS_FIT + FIT_SIZE * c
        out[O_SPREAD, c] = 1.0 if state[f + F_W] > 0.0 and state[f + F_SUU] > 0.0 else 0.0
        if state[IS_ISOLATED + c] != 0.0:
            isolation_verdict(params, state, c, verdict)
            out[O_RHO, c], out[O_BIAS, c], out[O_CODE, c] = verdict[V_RHO], verdict[V_BIAS], verdict[V_CODE]
        else:
            out[O_RHO, c], out[O_BIAS, c], out[O_CODE, c] = math.nan, math.nan, 0.0


#: How many worst-case error bounds of the fitted ``rho`` must fit under the effectiveness floor
#: (docs/resilience.md#leaving-the-team: with one, a sinusoidal bias the law cancels in `wide` reads as ``rho`` 0.01
#: with a bound of 0.48, because the actual input is then nearly constant, as a stuck one is).
UNABLE_BOUNDS = 2.0


@njit(cache=True)
def unable_channel(params, state, floor, spread, verdict):
    """Give the first isolated channel whose effectiveness is below ``floor`` beyond the fit's doubt, or -1.

    Beyond doubt (docs/resilience.md#leaving-the-team): the fit spans at least the confirmation time
    (its bound assumes many samples: a fit of a few steps just after a fault's onset can read far too
    low), the command has moved: its standard deviation over the fit exceeds ``spread`` (rad; a law
    cancelling a sinusoidal bias keeps the actual input nearly constant, as a stuck actuator does,
    but moves its command only as far as the bias), and the fitted ``rho`` plus :data:`UNABLE_BOUNDS`
    times its worst-case error bound ``V_RHO_BOUND`` is below ``floor`` (NaN and infinite bounds
    never are). ``verdict`` (VERDICT_SIZE,) is scratch.
    """
    for c in range(_N):
        if state[IS_ISOLATED + c] != 0.0:
            isolation_verdict(params, state, c, verdict)
            if (verdict[V_FIT_TIME] >= params[IP_CONFIRMATION] - 1e-9 and verdict[V_STD_U] > spread
                    and verdict[V_RHO] + UNABLE_BOUNDS * verdict[V_RHO_BOUND] < floor):
                return c
    return -1


@njit(cache=True)
def first_unable_step(params, state, times, states, commands, fault_p, fault_w, floor, spread, verdict):
    """Call :func:`isolation_step` on rows ``k`` until :func:`unable_channel` finds one; give ``(k, channel)``.

    ``(-1, -1)`` when no row does. The rows as in :func:`isolation_run`.
    """
    for k in range(times.shape[0]):
        isolation_step(params, state, times[k], states[k], commands[k], fault_p[k], fault_w[k])
        c = unable_channel(params, state, floor, spread, verdict)
        if c >= 0:
            return k, c
    return -1, -1


def compile_isolation_kernels() -> float:
    """Compile (or load from numba's cache) the isolator's kernels for the signatures it uses; seconds spent.

    C-contiguous float64 arrays, float time, int channel.
    """
    start = time.perf_counter()
    params = np.ones(ISO_PARAMS_SIZE)
    state = new_isolation_state(3)
    x, u, f3 = np.zeros(12), np.zeros(_N), np.zeros(3)
    input_deviations(params, x, u, f3, f3, np.zeros(_N))
    isolation_step(params, state, 1.0, x, u, f3, f3)
    isolation_run(params, state, np.ones(2), np.zeros((2, 12)), np.zeros((2, _N)), np.zeros((2, 3)),
                  np.zeros((2, 3)), np.zeros((0, TRACE_COLUMNS)))
    isolation_verdict(params, state, 0, np.zeros(VERDICT_SIZE))
    isolation_status(params, state, np.zeros(VERDICT_SIZE), np.zeros((STATUS_ROWS, _N)))
    unable_channel(params, state, 0.5, 0.015, np.zeros(VERDICT_SIZE))
    first_unable_step(params, state, np.ones(2), np.zeros((2, 12)), np.zeros((2, _N)), np.zeros((2, 3)),
                      np.zeros((2, 3)), 0.5, 0.015, np.zeros(VERDICT_SIZE))
    return time.perf_counter() - start


# numba caches each kernel by this file only: empty the cache when the layout it reads changes
_kernel_cache.refresh_cache(_kernel_cache.module_dispatchers(globals()), [_layout.__file__])

# run the ahead-of-time compiled kernels instead where this process asks for them (docs/performance.md#memory)
_compiled_kernels.install(globals())
