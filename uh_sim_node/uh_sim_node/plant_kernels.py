"""Native kernels of the helicopter model: dynamics, RK4, actuator faults, lumped faults.

The model is that of docs/model.md ("Helicopter dynamics", "Inputs and limits", "Integration",
"Lumped faults"), the actuator faults those of docs/faults.md ("Fault model", "Onset").

These functions *are* the simulator's model. They are compiled with numba (``@njit(cache=True)``, no
fastmath, no parallelism, so results are deterministic and follow IEEE double arithmetic), take
only float64 arrays and scalars, and can be called from Python or from other ``@njit`` code (e.g. a
fused team kernel that loops over the UHs). :class:`uh_sim_node.helicopter.HelicopterPlant` is a
thin wrapper that holds the arrays below and calls these kernels.

Frames, units, state and inputs
-------------------------------
Inertial frame z-up; ZYX Euler angles ``Theta = (phi, theta, psi)`` rad with
``R = Rz(psi) Ry(theta) Rx(phi)`` (body -> inertial); body rates ``omega = (p, q, r)`` rad/s.

* state ``x`` (12,) float64 = ``[p (3) m, v (3) m/s, Theta (3) rad, omega (3) rad/s]``
  (index constants ``X_P``, ``X_V``, ``X_THETA``, ``X_OMEGA`` give the first index of each block);
* inputs ``u`` (4,) float64 rad = ``(theta_col, theta_tr, delta_lat, delta_lon)``
  (``U_COL``, ``U_TR``, ``U_LAT``, ``U_LON``), also the fault channels 0..3.

Model (docs/model.md, "Helicopter dynamics")::

    p' = v
    m v' = -m g e3 + T_M R e3 - D_v v + d_p(t)
    Theta' = H(Theta) omega
    J omega' = -omega x J omega + Gamma,            J = diag(J_x, J_y, J_z)
    T_M = c_M1 theta_col + c_M2
    b_1s = B_lat delta_lat - tau_f p ,  a_1s = A_lon delta_lon - tau_f q
    Gamma = [(K_beta + T_M h_M) b_1s, (K_beta + T_M h_M) a_1s, K_tr theta_tr - D_r r - c_Q T_M]

Input chain and actuator faults (paper eq. 6; docs/faults.md, "Fault model"), per channel ``i``::

    u_cmd_i = clip_i(u_i)                                                    position limits
    u_act_i = clip_i(rho_i u_cmd_i + b_i(t))   if the fault of channel i acts, else u_cmd_i
    b_i(t)  = bias_constant_i + bias_amplitude_i sin(bias_frequency_i t)     absolute time t

A fault acts when its switch time ``t_s >= onset_time - ONSET_TOLERANCE``
(:data:`uh_sim_node.faults.ONSET_TOLERANCE`, 1 ns; the table column ``F_ACTS_FROM``); stuck
actuators are ``rho = 0``.

Integration: the command is held over ``[t, t + dt)``; classical RK4 with ``substeps`` equal
substeps of length ``h = dt / substeps``. Substep ``s`` spans ``[t + s h, t + (s + 1) h]``; the
faults' activity is decided once per substep at its start ``t + s h`` (a fault switches on at a
substep boundary, so the inputs are smooth inside every substep and RK4 keeps its fourth order);
the bias sinusoids and the force disturbance are evaluated at the RK4 stage times ``t + s h``,
``t + (s + 1/2) h`` (stages 2 and 3) and ``t + (s + 1) h``.

True lumped faults (docs/model.md, "Lumped faults"), the dynamics with the actual inputs minus
those with the commanded inputs at the same state::

    F_p = (T_M(u_act) - T_M(u_cmd)) / m  R e3                       m/s^2, inertial   (3,)
    F_w = J^-1 (Gamma(omega, u_act) - Gamma(omega, u_cmd))          rad/s^2, body     (3,)

Arrays describing one plant
---------------------------
``params`` (``PARAMS_SIZE`` = 24,) float64, built by :func:`params_vector` from a
``HelicopterParams`` as the table :data:`PARAMS_ENTRIES` lays it out; entries at the ``P_*`` indices::

    P_MASS kg, P_GRAVITY m/s^2, P_D_V N s/m, P_C_M1 N/rad, P_C_M2 N, P_K_BETA N m/rad, P_H_M m,
    P_B_LAT, P_A_LON rad/rad, P_TAU_F s, P_K_TR N m/rad, P_D_R N m s, P_C_Q m,
    P_J_X, P_J_Y, P_J_Z kg m^2,
    P_LOWER .. P_LOWER + 3, P_UPPER .. P_UPPER + 3   input position limits, rad (channel order)

``faults`` (``NUM_CHANNELS`` = 4, ``FAULT_FIELDS`` = 6) float64, built by :func:`fault_table` from a
``FaultSchedule``; row = channel, columns ``F_PRESENT`` (1.0 when the channel has a fault, else
0.0; the other fields of an absent row are ignored), ``F_RHO``, ``F_BIAS_CONSTANT`` rad,
``F_BIAS_AMPLITUDE`` rad, ``F_BIAS_FREQUENCY`` rad/s, ``F_ACTS_FROM`` s
(:attr:`~uh_sim_node.faults.ActuatorFault.acts_from`: the onset time less
:data:`~uh_sim_node.faults.ONSET_TOLERANCE`, computed in Python so that the kernels hold no copy
of that constant).

``disturbance`` (3, ``DISTURBANCE_FIELDS`` = 3) float64, built by :func:`disturbance_table` from a
``SinusoidalDisturbance`` (or ``None``: all zeros, no force); row = inertial axis x, y, z, columns
``D_AMPLITUDE`` N, ``D_FREQUENCY`` rad/s, ``D_PHASE`` rad: ``d_p,a(t) = A_a sin(w_a t + phase_a)``.

For a plant the arrays come ready from ``HelicopterPlant.kernel_arrays()`` (a :class:`PlantArrays`
with ``params``, ``faults``, ``disturbance`` and ``substeps``; fresh copies). Faults injected later
(``plant.faults.add(...)``) bump ``plant.faults.revision``; rebuild the fault table when it changes.

Calling the kernels from njit code
----------------------------------
All array arguments are C-contiguous float64; ``t``, ``dt`` float64; ``substeps`` int64. For a
team of ``n`` UHs stack the per-plant arrays (``np.stack``) and pass row views::

    from numba import njit
    from uh_sim_node.plant_kernels import plant_step, lumped_faults

    @njit(cache=True)
    def team_plant_step(states, commands, t, dt, substeps, params, faults, disturbance, f_p, f_w):
        # states (n, 12), commands (n, 4), params (n, 24), faults (n, 4, 6), disturbance (n, 3, 3),
        # f_p, f_w (n, 3) outputs
        for c in range(states.shape[0]):
            lumped_faults(states[c], commands[c], t, params[c], faults[c], f_p[c], f_w[c])
            plant_step(states[c], commands[c], t, dt, substeps, params[c], faults[c], disturbance[c])

``plant_step`` advances ``states[c]`` in place; ``lumped_faults`` evaluated before the step gives the
faults at the start of the control period (the simulator's order).

The kernels do not check shapes or values (that is done once by the Python wrapper); wrong shapes
read or write out of bounds.

Compilation: the first call compiles a kernel (seconds) and stores it in numba's on-disk cache
(``__pycache__`` next to this file, or ``NUMBA_CACHE_DIR``); later processes load it (milliseconds).
:func:`compile_plant_kernels` compiles all kernels with the signatures the wrapper uses, for install
scripts that warm the cache. Besides the constants of this file the kernels read the index
constants of :mod:`uh_core.layout` at compile time; numba re-validates its cache against this file
alone, so :func:`uh_core.kernel_cache.refresh_cache` (run on import) flushes the cache of every
kernel here when ``uh_core/layout.py`` changed.
"""
from __future__ import annotations

import math
import time
from typing import NamedTuple

import numpy as np

from uh_core import compiled_kernels as _compiled_kernels
from uh_core import kernel_cache as _kernel_cache
from uh_core import layout as _layout
from uh_core.compiled_kernels import njit
from uh_core.layout import INPUT_SIZE, NUM_CHANNELS, STATE_SIZE, U_COL, U_LAT, U_LON, U_TR, X_OMEGA, X_P, X_THETA, X_V

__all__ = [
    'STATE_SIZE', 'INPUT_SIZE', 'X_P', 'X_V', 'X_THETA', 'X_OMEGA', 'U_COL', 'U_TR', 'U_LAT', 'U_LON',
    'P_MASS', 'P_GRAVITY', 'P_D_V', 'P_C_M1', 'P_C_M2', 'P_K_BETA', 'P_H_M', 'P_B_LAT', 'P_A_LON',
    'P_TAU_F', 'P_K_TR', 'P_D_R', 'P_C_Q', 'P_J_X', 'P_J_Y', 'P_J_Z', 'P_LOWER', 'P_UPPER', 'PARAMS_SIZE',
    'PARAMS_ENTRIES', 'PARAMS_INDEX',
    'F_PRESENT', 'F_RHO', 'F_BIAS_CONSTANT', 'F_BIAS_AMPLITUDE', 'F_BIAS_FREQUENCY', 'F_ACTS_FROM',
    'FAULT_FIELDS', 'D_AMPLITUDE', 'D_FREQUENCY', 'D_PHASE', 'DISTURBANCE_FIELDS', 'PlantArrays',
    'params_vector', 'fault_table', 'disturbance_table', 'stuck_position',
    'state_derivative', 'actual_inputs', 'force_disturbance', 'lumped_faults_of_inputs', 'lumped_faults',
    'plant_step', 'compile_plant_kernels',
]


# -- params vector: the one table of what params holds, in order -------------------------------
#: ``(HelicopterParams field, number of entries)``: m kg, g m/s^2, translational drag D_v N s/m,
#: thrust gain c_M1 N/rad and offset c_M2 N, rotor hub spring stiffness K_beta N m/rad, hub height
#: above the centre of gravity h_M m, flapping gains B_lat and A_lon rad/rad, flapping lag per body
#: rate tau_f s, tail-rotor yaw moment gain K_tr N m/rad, yaw damping D_r N m s, torque reaction per
#: thrust c_Q m, principal moments of inertia (J_x, J_y, J_z) kg m^2, input limits (channel order) rad.
PARAMS_ENTRIES = (('mass', 1), ('gravity', 1), ('D_v', 1), ('c_M1', 1), ('c_M2', 1), ('K_beta', 1), ('h_M', 1),
                  ('B_lat', 1), ('A_lon', 1), ('tau_f', 1), ('K_tr', 1), ('D_r', 1), ('c_Q', 1), ('inertia', 3),
                  ('input_lower', INPUT_SIZE), ('input_upper', INPUT_SIZE))
#: ``{field: first index}`` of :data:`PARAMS_ENTRIES`.
PARAMS_INDEX = {name: sum(count for _, count in PARAMS_ENTRIES[:i]) for i, (name, _) in enumerate(PARAMS_ENTRIES)}
# the indices the kernels use (plain ints: numba reads them as compile-time constants)
P_MASS = PARAMS_INDEX['mass']
P_GRAVITY = PARAMS_INDEX['gravity']
P_D_V = PARAMS_INDEX['D_v']
P_C_M1 = PARAMS_INDEX['c_M1']
P_C_M2 = PARAMS_INDEX['c_M2']
P_K_BETA = PARAMS_INDEX['K_beta']
P_H_M = PARAMS_INDEX['h_M']
P_B_LAT = PARAMS_INDEX['B_lat']
P_A_LON = PARAMS_INDEX['A_lon']
P_TAU_F = PARAMS_INDEX['tau_f']
P_K_TR = PARAMS_INDEX['K_tr']
P_D_R = PARAMS_INDEX['D_r']
P_C_Q = PARAMS_INDEX['c_Q']
P_J_X = PARAMS_INDEX['inertia']
P_J_Y = P_J_X + 1
P_J_Z = P_J_X + 2
P_LOWER = PARAMS_INDEX['input_lower']
P_UPPER = PARAMS_INDEX['input_upper']
PARAMS_SIZE = sum(count for _, count in PARAMS_ENTRIES)

# -- fault table (one row per channel) --------------------------------------------------------
F_PRESENT = 0         # 1.0 when the channel carries a fault
F_RHO = 1             # effectiveness, [0, 1]
F_BIAS_CONSTANT = 2   # rad
F_BIAS_AMPLITUDE = 3  # rad
F_BIAS_FREQUENCY = 4  # rad/s
F_ACTS_FROM = 5       # s: ActuatorFault.acts_from = onset_time - ONSET_TOLERANCE
FAULT_FIELDS = 6

# -- disturbance table (one row per inertial axis) --------------------------------------------
D_AMPLITUDE = 0     # N
D_FREQUENCY = 1     # rad/s
D_PHASE = 2         # rad
DISTURBANCE_FIELDS = 3


# =============================================================================================
# Building the arrays (plain Python, called when a plant is built or its faults change)


class PlantArrays(NamedTuple):
    """Everything a kernel needs to know about one plant besides its state and command.

    Attributes
    ----------
    params : ndarray (PARAMS_SIZE,)
    faults : ndarray (NUM_CHANNELS, FAULT_FIELDS)
    disturbance : ndarray (3, DISTURBANCE_FIELDS)
    substeps : int
        RK4 substeps per control period.
    """

    params: np.ndarray
    faults: np.ndarray
    disturbance: np.ndarray
    substeps: int


def params_vector(params) -> np.ndarray:
    """``params`` (PARAMS_SIZE,) float64 from a ``HelicopterParams`` (or any object with its fields)."""
    out = np.zeros(PARAMS_SIZE)
    for name, count in PARAMS_ENTRIES:
        at = PARAMS_INDEX[name]
        out[at:at + count] = getattr(params, name)
    return out


def fault_table(faults) -> np.ndarray:
    """Build ``faults`` (NUM_CHANNELS, FAULT_FIELDS) float64 from a schedule or an iterable of faults.

    The schedule is a ``FaultSchedule``; the faults are ``ActuatorFault`` (a later fault of a
    channel replaces an earlier one).
    """
    out = np.zeros((NUM_CHANNELS, FAULT_FIELDS))
    for f in getattr(faults, 'faults', faults):
        row = out[f.channel]
        row[F_PRESENT] = 1.0
        row[F_RHO] = f.rho
        row[F_BIAS_CONSTANT] = f.bias_constant
        row[F_BIAS_AMPLITUDE] = f.bias_amplitude
        row[F_BIAS_FREQUENCY] = f.bias_frequency
        row[F_ACTS_FROM] = f.acts_from
    return out


def disturbance_table(disturbance) -> np.ndarray:
    """Build ``disturbance`` (3, DISTURBANCE_FIELDS) float64 from a ``SinusoidalDisturbance``.

    Any object with ``amplitude``, ``frequency``, ``phase`` of 3 numbers will do; ``None`` gives
    zeros (no force).
    """
    out = np.zeros((3, DISTURBANCE_FIELDS))
    if disturbance is not None:
        out[:, D_AMPLITUDE] = disturbance.amplitude
        out[:, D_FREQUENCY] = disturbance.frequency
        out[:, D_PHASE] = disturbance.phase
    return out


# =============================================================================================
# Model pieces (inlined by LLVM into the public kernels; tuples keep everything in registers)


@njit(cache=True)
def _clip(params, channel, u):
    """Input ``u`` rad of ``channel`` limited to its position limits (NaN passes through)."""
    lo = params[P_LOWER + channel]
    hi = params[P_UPPER + channel]
    if u < lo:
        return lo
    if u > hi:
        return hi
    return u


@njit(cache=True)
def _clip_command(params, u_cmd):
    """Commanded inputs (4,) -> tuple of 4 limited inputs, rad."""
    return (_clip(params, U_COL, u_cmd[U_COL]), _clip(params, U_TR, u_cmd[U_TR]),
            _clip(params, U_LAT, u_cmd[U_LAT]), _clip(params, U_LON, u_cmd[U_LON]))


@njit(cache=True)
def _actual_channel(params, faults, channel, u, t, t_switch):
    """Actual input of ``channel``, rad, for the limited command ``u`` (paper eq. 6, then limits).

    The fault acts when ``t_switch >= onset_time - ONSET_TOLERANCE``; the bias uses ``t``.
    """
    f = faults[channel]
    if f[F_PRESENT] == 0.0 or t_switch < f[F_ACTS_FROM]:
        return u
    # one evaluation order everywhere: (rho u + c) + A sin(w t)
    ua = f[F_RHO] * u + f[F_BIAS_CONSTANT]
    if f[F_BIAS_AMPLITUDE] != 0.0:
        ua = ua + f[F_BIAS_AMPLITUDE] * math.sin(f[F_BIAS_FREQUENCY] * t)
    # a biased actuator still cannot leave its mechanical travel
    return _clip(params, channel, ua)


@njit(cache=True)
def _actual(params, faults, uc, t, t_switch):
    """Return the tuple of 4 actual inputs, rad, for the tuple ``uc`` of limited commands at time ``t`` s.

    The faults' activity is decided at ``t_switch`` s.
    """
    return (_actual_channel(params, faults, U_COL, uc[0], t, t_switch),
            _actual_channel(params, faults, U_TR, uc[1], t, t_switch),
            _actual_channel(params, faults, U_LAT, uc[2], t, t_switch),
            _actual_channel(params, faults, U_LON, uc[3], t, t_switch))


@njit(cache=True)
def _any_fault_acts(faults, t_switch):
    """Return True when some channel's fault acts at ``t_switch`` s."""
    for ch in range(NUM_CHANNELS):
        if faults[ch, F_PRESENT] != 0.0 and t_switch >= faults[ch, F_ACTS_FROM]:
            return True
    return False


@njit(cache=True)
def _sinusoid(disturbance, axis, t):
    """Return ``A sin(w t + phase)`` N of one axis (exactly 0 when the amplitude is 0)."""
    a = disturbance[axis, D_AMPLITUDE]
    if a == 0.0:
        return 0.0
    return a * math.sin(disturbance[axis, D_FREQUENCY] * t + disturbance[axis, D_PHASE])


@njit(cache=True)
def _force(disturbance, t):
    """Force ``d_p`` (tuple of 3, N, inertial) at time ``t`` s from the sinusoid table ``disturbance``."""
    return (_sinusoid(disturbance, 0, t), _sinusoid(disturbance, 1, t), _sinusoid(disturbance, 2, t))


@njit(cache=True)
def _rates(params, y, u, d):
    """Return the derivatives ``(v', Theta', omega')`` (tuple of 9) of docs/model.md ("Helicopter dynamics").

    ``y`` = ``(v (3) m/s, Theta (3) rad, omega (3) rad/s)`` tuple of 9, ``u`` the 4 actual inputs
    rad, ``d`` the force disturbance (3) N inertial. ``p' = v`` is left to the caller.
    """
    vx, vy, vz, phi, th, psi, p, q, r = y
    m = params[P_MASS]
    im = 1.0 / m
    dv = params[P_D_V]
    jx, jy, jz = params[P_J_X], params[P_J_Y], params[P_J_Z]
    cf = math.cos(phi)
    sf = math.sin(phi)
    ct = math.cos(th)
    st = math.sin(th)
    cp = math.cos(psi)
    sp = math.sin(psi)
    T = params[P_C_M1] * u[U_COL] + params[P_C_M2]          # main-rotor thrust T_M, N
    tm = T * im
    stcf = st * cf
    qs = sf * q + cf * r
    k = params[P_K_BETA] + T * params[P_H_M]                 # flapping moment stiffness, N m/rad
    b1s = params[P_B_LAT] * u[U_LAT] - params[P_TAU_F] * p   # lateral flapping, rad
    a1s = params[P_A_LON] * u[U_LON] - params[P_TAU_F] * q   # longitudinal flapping, rad
    return (
        # m v' = T_M R e3 - D_v v + d_p - m g e3; R e3 = (c_psi s_theta c_phi + s_psi s_phi,
        # s_psi s_theta c_phi - c_psi s_phi, c_theta c_phi)
        tm * (cp * stcf + sp * sf) + (d[0] - dv * vx) * im,
        tm * (sp * stcf - cp * sf) + (d[1] - dv * vy) * im,
        tm * ct * cf + (d[2] - dv * vz) * im - params[P_GRAVITY],
        # Theta' = H(Theta) omega
        p + st / ct * qs,
        cf * q - sf * r,
        qs / ct,
        # J omega' = -omega x J omega + Gamma with J diagonal: (J_y - J_z) q r + Gamma_x, ...
        ((jy - jz) * q * r + k * b1s) * (1.0 / jx),
        ((jz - jx) * r * p + k * a1s) * (1.0 / jy),
        ((jx - jy) * p * q + params[P_K_TR] * u[U_TR] - params[P_D_R] * r - params[P_C_Q] * T) * (1.0 / jz),
    )


@njit(cache=True)
def _shift(y, c, k):
    """RK4 stage argument ``y + c k`` (tuples of 9)."""
    return (y[0] + c * k[0], y[1] + c * k[1], y[2] + c * k[2], y[3] + c * k[3], y[4] + c * k[4],
            y[5] + c * k[5], y[6] + c * k[6], y[7] + c * k[7], y[8] + c * k[8])


@njit(cache=True)
def _rk4_substep(params, x, h, u_start, u_mid, u_end, d_start, d_mid, d_end):
    """One classical RK4 step of length ``h`` s on the state tuple ``x`` (12); returns the new tuple.

    Inputs and force act at the start (stage 1), the midpoint (stages 2, 3) and the end (stage 4).
    """
    h2 = 0.5 * h
    y = (x[3], x[4], x[5], x[6], x[7], x[8], x[9], x[10], x[11])
    a = _rates(params, y, u_start, d_start)
    b = _rates(params, _shift(y, h2, a), u_mid, d_mid)
    c = _rates(params, _shift(y, h2, b), u_mid, d_mid)
    d = _rates(params, _shift(y, h, c), u_end, d_end)
    h6 = h / 6.0
    # p' = v: the stage velocities are v, v + h/2 a_v, v + h/2 b_v, v + h c_v, so
    # (k1 + 2 k2 + 2 k3 + k4)_p = 6 v + h (a_v + b_v + c_v).
    return (
        x[0] + h6 * (6.0 * x[3] + h * (a[0] + b[0] + c[0])),
        x[1] + h6 * (6.0 * x[4] + h * (a[1] + b[1] + c[1])),
        x[2] + h6 * (6.0 * x[5] + h * (a[2] + b[2] + c[2])),
        x[3] + h6 * (a[0] + 2.0 * b[0] + 2.0 * c[0] + d[0]),
        x[4] + h6 * (a[1] + 2.0 * b[1] + 2.0 * c[1] + d[1]),
        x[5] + h6 * (a[2] + 2.0 * b[2] + 2.0 * c[2] + d[2]),
        x[6] + h6 * (a[3] + 2.0 * b[3] + 2.0 * c[3] + d[3]),
        x[7] + h6 * (a[4] + 2.0 * b[4] + 2.0 * c[4] + d[4]),
        x[8] + h6 * (a[5] + 2.0 * b[5] + 2.0 * c[5] + d[5]),
        x[9] + h6 * (a[6] + 2.0 * b[6] + 2.0 * c[6] + d[6]),
        x[10] + h6 * (a[7] + 2.0 * b[7] + 2.0 * c[7] + d[7]),
        x[11] + h6 * (a[8] + 2.0 * b[8] + 2.0 * c[8] + d[8]),
    )


# =============================================================================================
# Public kernels


@njit(cache=True)
def plant_step(x, u_cmd, t, dt, substeps, params, faults, disturbance):
    """Advance one plant from ``t`` to ``t + dt`` holding the command ``u_cmd`` (in place).

    Parameters
    ----------
    x : ndarray (12,) float64
        State ``[p m, v m/s, Theta rad, omega rad/s]`` at ``t``; overwritten with the state at
        ``t + dt``.
    u_cmd : ndarray (4,) float64
        Command ``(theta_col, theta_tr, delta_lat, delta_lon)`` rad; limited, then faulted and
        limited again at each RK4 stage time.
    t, dt : float
        Start time and control period, s.
    substeps : int
        RK4 substeps (>= 1).
    params : ndarray (PARAMS_SIZE,)
    faults : ndarray (NUM_CHANNELS, FAULT_FIELDS)
    disturbance : ndarray (3, DISTURBANCE_FIELDS)
        Sinusoidal force ``d_p(t)`` N, inertial, evaluated at the stage times.
    """
    uc = _clip_command(params, u_cmd)
    h = dt / substeps
    xs = (x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8], x[9], x[10], x[11])
    d_start = _force(disturbance, t)
    for s in range(substeps):
        t_start = t + s * h
        t_mid = t + (s + 0.5) * h
        t_end = t + (s + 1) * h
        # the faults' activity is decided at the substep start; biases at the stage times
        u_start = _actual(params, faults, uc, t_start, t_start)
        u_mid = _actual(params, faults, uc, t_mid, t_start)
        u_end = _actual(params, faults, uc, t_end, t_start)
        d_mid = _force(disturbance, t_mid)
        d_end = _force(disturbance, t_end)
        xs = _rk4_substep(params, xs, h, u_start, u_mid, u_end, d_start, d_mid, d_end)
        d_start = d_end
    for i in range(STATE_SIZE):
        x[i] = xs[i]


@njit(cache=True)
def state_derivative(x, u_actual, d_p, params, out):
    """State derivative ``x'`` (12,) of docs/model.md ("Helicopter dynamics") written into ``out``.

    ``x`` (12,) state, ``u_actual`` (4,) inputs acting on the airframe (rad, not limited here),
    ``d_p`` (3,) force disturbance N inertial. ``out`` = ``[v, v', Theta', omega']`` in m/s, m/s^2,
    rad/s, rad/s^2.
    """
    y = (x[3], x[4], x[5], x[6], x[7], x[8], x[9], x[10], x[11])
    r = _rates(params, y, (u_actual[0], u_actual[1], u_actual[2], u_actual[3]), (d_p[0], d_p[1], d_p[2]))
    out[0] = x[3]
    out[1] = x[4]
    out[2] = x[5]
    for i in range(9):
        out[3 + i] = r[i]


@njit(cache=True)
def actual_inputs(u_cmd, t, t_switch, params, faults, out_cmd, out_actual):
    """Apply the input chain to ``u_cmd`` at time ``t`` s: limits, faults, limits again.

    ``out_cmd`` (4,) = limited command, ``out_actual`` (4,) = faulted (eq. 6, activity decided at
    ``t_switch`` s) and limited again; all rad.
    """
    uc = _clip_command(params, u_cmd)
    ua = _actual(params, faults, uc, t, t_switch)
    for i in range(INPUT_SIZE):
        out_cmd[i] = uc[i]
        out_actual[i] = ua[i]


def stuck_position(params, faults, channel: int, u_cmd, t: float) -> float:
    """Give where actuator ``channel`` is at time ``t`` s, rad: where it sticks (docs/faults.md#stuck-actuators).

    The actual input of ``channel`` (:func:`actual_inputs`, the faults' activity decided at ``t``) for
    the command ``u_cmd`` (4,) rad it held until then, under the faults ``faults`` (NUM_CHANNELS,
    FAULT_FIELDS). The simulator node (:meth:`uh_sim_node.helicopter.HelicopterPlant.stick`) and the
    in-process run (:mod:`uh_team.event_run`) both take it from here, so they give the same bits.
    """
    uc, ua = np.empty(INPUT_SIZE), np.empty(INPUT_SIZE)
    actual_inputs(np.ascontiguousarray(u_cmd, dtype=np.float64), float(t), float(t), params, faults, uc, ua)
    return float(ua[channel])


@njit(cache=True)
def force_disturbance(disturbance, t, out):
    """Sinusoidal force ``d_p(t)`` (3,) N, inertial, at time ``t`` s written into ``out``."""
    for axis in range(3):
        out[axis] = _sinusoid(disturbance, axis, t)


@njit(cache=True)
def _lumped(params, x, uc, ua, out_p, out_w):
    """F_p, F_w of docs/model.md ("Lumped faults") for the tuples ``uc`` (limited command) and ``ua`` (actual)."""
    phi, th, psi = x[6], x[7], x[8]
    p, q, r = x[9], x[10], x[11]
    cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(th), math.sin(th)
    cp, sp = math.cos(psi), math.sin(psi)
    t_act = params[P_C_M1] * ua[U_COL] + params[P_C_M2]      # thrust with the actual inputs, N
    t_cmd = params[P_C_M1] * uc[U_COL] + params[P_C_M2]      # thrust with the commanded inputs, N
    g = (t_act - t_cmd) / params[P_MASS]
    # F_p = (T_act - T_cmd) / m  R e3
    out_p[0] = g * (cp * st * cf + sp * sf)
    out_p[1] = g * (sp * st * cf - cp * sf)
    out_p[2] = g * ct * cf
    # F_w = J^-1 (Gamma(omega, u_act) - Gamma(omega, u_cmd)); the -omega x J omega terms cancel
    k_act = params[P_K_BETA] + t_act * params[P_H_M]
    k_cmd = params[P_K_BETA] + t_cmd * params[P_H_M]
    blat, alon, tauf = params[P_B_LAT], params[P_A_LON], params[P_TAU_F]
    ktr, dr, cq = params[P_K_TR], params[P_D_R], params[P_C_Q]
    out_w[0] = (k_act * (blat * ua[U_LAT] - tauf * p) - k_cmd * (blat * uc[U_LAT] - tauf * p)) / params[P_J_X]
    out_w[1] = (k_act * (alon * ua[U_LON] - tauf * q) - k_cmd * (alon * uc[U_LON] - tauf * q)) / params[P_J_Y]
    out_w[2] = ((ktr * ua[U_TR] - dr * r - cq * t_act) - (ktr * uc[U_TR] - dr * r - cq * t_cmd)) / params[P_J_Z]


@njit(cache=True)
def lumped_faults_of_inputs(x, u_cmd_limited, u_actual, params, out_p, out_w):
    """Compute the true lumped faults at state ``x`` (12,) for given inputs (4,) rad.

    The inputs are the limited command and the actual (faulted, limited) inputs. ``out_p`` (3,)
    m/s^2 inertial, ``out_w`` (3,) rad/s^2 body.
    """
    uc = (u_cmd_limited[0], u_cmd_limited[1], u_cmd_limited[2], u_cmd_limited[3])
    ua = (u_actual[0], u_actual[1], u_actual[2], u_actual[3])
    _lumped(params, x, uc, ua, out_p, out_w)


@njit(cache=True)
def lumped_faults(x, u_cmd, t, params, faults, out_p, out_w):
    """Compute the true lumped faults ``F_p``, ``F_w`` of one plant at state ``x`` and time ``t``.

    See docs/model.md, "Lumped faults".

    Parameters
    ----------
    x : ndarray (12,)
        State at ``t``.
    u_cmd : ndarray (4,)
        The controller's command, rad (limited here; faults and limits applied as in the step,
        activity decided at ``t``).
    t : float
        Time, s.
    params, faults : ndarray
        As for :func:`plant_step`.
    out_p : ndarray (3,)
        ``F_p`` m/s^2, inertial frame (written).
    out_w : ndarray (3,)
        ``F_w`` rad/s^2, body frame (written). Both exactly 0 when no fault acts at ``t``.
    """
    if not _any_fault_acts(faults, t):
        for i in range(3):
            out_p[i] = 0.0
            out_w[i] = 0.0
        return
    uc = _clip_command(params, u_cmd)
    ua = _actual(params, faults, uc, t, t)
    _lumped(params, x, uc, ua, out_p, out_w)


# =============================================================================================
# Compilation


def compile_plant_kernels() -> float:
    """Compile every public kernel and fill numba's on-disk cache.

    The signatures compiled are those :class:`HelicopterPlant` uses (C-contiguous float64 arrays,
    float times, int substeps).

    Returns the wall time spent, s (compilation on a cold cache, loading on a warm one).
    """
    start = time.perf_counter()
    params = np.zeros(PARAMS_SIZE)
    params[[P_MASS, P_GRAVITY, P_C_M1, P_K_BETA, P_B_LAT, P_A_LON, P_K_TR, P_J_X, P_J_Y, P_J_Z]] = 1.0
    params[P_LOWER:P_LOWER + INPUT_SIZE] = -1.0
    params[P_UPPER:P_UPPER + INPUT_SIZE] = 1.0
    faults = np.zeros((NUM_CHANNELS, FAULT_FIELDS))
    disturbance = np.zeros((3, DISTURBANCE_FIELDS))
    x = np.zeros(STATE_SIZE)
    u = np.zeros(INPUT_SIZE)
    u2 = np.zeros(INPUT_SIZE)
    v3, w3 = np.zeros(3), np.zeros(3)
    out = np.zeros(STATE_SIZE)
    substeps = 1
    plant_step(x, u, 0.0, 0.01, substeps, params, faults, disturbance)
    lumped_faults(x, u, 0.0, params, faults, v3, w3)
    lumped_faults_of_inputs(x, u, u2, params, v3, w3)
    state_derivative(x, u, v3, params, out)
    actual_inputs(u, 0.0, 0.0, params, faults, u2, u)
    force_disturbance(disturbance, 0.0, v3)
    return time.perf_counter() - start


# numba checks this file only; the layout constants compiled into the kernels live in uh_core/layout.py
_kernel_cache.refresh_cache(_kernel_cache.module_dispatchers(globals()), [_layout.__file__])

# run the ahead-of-time compiled kernels instead where this process asks for them (docs/performance.md#memory)
_compiled_kernels.install(globals())
