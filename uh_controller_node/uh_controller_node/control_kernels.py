"""Native kernels of the control law of one UH.

They compute the consensus errors, the outer and inner loops, and the learning and fault observers
(docs/graph.md, docs/control_law.md, with its anti-windup and projections).

These functions *are* the controller. They are compiled with numba (``@njit(cache=True)``, no
fastmath, no parallelism, so results are deterministic and follow IEEE double arithmetic), take
only float64 arrays and scalars, and can be called from Python or from other ``@njit`` code (e.g. a
fused team kernel that loops over the UHs). :class:`uh_controller_node.controller.UHController`
checks the inputs, holds the arrays below and calls :func:`uh_control_step` once per step.

Frames, units and the per-step order
------------------------------------
Inertial frame z-up; ZYX Euler angles ``Theta = (phi, theta, psi)`` rad with
``R = Rz(psi) Ry(theta) Rx(phi)`` (body -> inertial); body rates ``omega = (p, q, r)`` rad/s.
Outer-loop vectors are inertial, one entry per axis x, y, z; inner-loop vectors per roll, pitch,
yaw axis (``z3`` in Euler angles, the rest in the body frame). Per step the order is fixed:
consensus error (:func:`consensus_errors`) -> outer law (:func:`outer_law`) -> thrust and attitude
(:func:`thrust_and_attitude`, tilt and collective limits) -> inner law (:func:`inner_law`, cyclic
and pedal limits) -> explicit-Euler advance of every internal state from t_k to t_{k+1}
(:func:`outer_advance`, :func:`inner_advance`), all right-hand sides taken at t_k.

Arrays
------
* state ``x`` (STATE_SIZE = 12,) = ``[p (3) m, v (3) m/s, Theta (3) rad, omega (3) rad/s]``; first
  index of each block ``X_P``, ``X_V``, ``X_THETA``, ``X_OMEGA``.
* command ``u`` (INPUT_SIZE = 4,) rad = ``(theta_col, theta_tr, delta_lat, delta_lon)`` at
  ``U_COL``, ``U_TR``, ``U_LAT``, ``U_LON``. The inner loop's moment inputs are
  ``u_m = (delta_lat, delta_lon, theta_tr)``.
* ``params`` (CONTROL_PARAMS_SIZE,) the nominal model and the gains, built by
  :func:`control_parameters`. Model entries ``CP_*`` (SI units, listed below); the gains of each
  loop are a block starting at ``CP_OUTER`` or ``CP_INNER`` with entries at the offsets ``L_*``
  (``params[CP_INNER + L_KAPPA]`` is kappa_w).
* ``reference`` (REFERENCE_SIZE = 7,) = ``[p_0 (3) m, v_0 (3) m/s, psi_0 rad]`` at ``R_P``,
  ``R_V``, ``R_YAW``; read only when ``leader_link > 0``.
* mutable state of one controller:

  - ``weights_p`` (mu_p, 3) W_p and ``weights_w`` (mu_w, 3) W_w (column a = axis a; mu = RBF nodes);
  - ``memory`` (MEMORY_ROWS = 8, 3): rows ``M_ALPHA_F`` alpha_f m/s, ``M_V_HAT`` vhat m/s,
    ``M_F_HAT_P`` Fhat_p m/s^2, ``M_THETA_DF`` Theta_df rad, ``M_ALPHA_WF`` alpha_wf rad/s,
    ``M_OMEGA_HAT`` omegahat rad/s, ``M_F_HAT_W`` Fhat_w rad/s^2, and ``M_FLAGS`` whose column
    ``FLAG_STARTED`` is 1.0 once the first step has initialised the filters and estimation models
    (all zeros = a fresh controller).

* outputs: ``u`` (4,) and ``status`` (STATUS_SIZE = 37,), laid out by
  :data:`uh_core.layout.STATUS_LAYOUT` (the fields of ``ControllerStatus.msg``): 3-vectors starting
  at ``S_Z1``, ``S_Z2``, ``S_Z3``, ``S_Z4``, ``S_F_HAT_P``, ``S_F_HAT_W`` (estimates used this
  step), ``S_ZN_P``, ``S_ZN_W`` (prediction errors), ``S_U_P``, ``S_EULER_D`` (attitude command
  before its filter); scalars ``S_THRUST`` (T_c before the collective limit, N), ``S_W_NORM_P``,
  ``S_W_NORM_W`` (Frobenius norms after the update), ``S_SAT_TILT``, ``S_SAT_COLLECTIVE``,
  ``S_SAT_CYCLIC`` (1.0 when that limit was active, else 0.0), ``S_COST_RATE``
  (``|z1|^2 + |u_p|^2``).

Calling the per-UH kernel from njit code
----------------------------------------
``UHController.kernel_arrays()`` returns a :class:`ControlArrays` with ``params``, ``offset``,
``neighbour_weights``, ``neighbour_offsets``, ``leader_link``, ``weights_p``, ``weights_w`` and
``memory`` of one controller (its live arrays: copy them to stack them). For a team of ``n`` UHs,
stack them (``np.stack``; the neighbour arrays padded to the largest in-degree) and pass row
views, gathering each UH's neighbour states in ascending id order, as :meth:`UHController.step`
does. :func:`uh_team.team_kernel.team_arrays` does that stacking and
:func:`uh_team.team_kernel.run_team_steps` is such a loop (with the plants), bit-identical
to the controllers (``tests/test_reference_simulation.py``; ``tests/test_control_kernels.py`` checks
a control-only loop, status vectors included).
The degraded steps of :meth:`UHController.step_degraded` are the same call on fewer neighbours
(and ``leader_link = 0`` without the reference); holding a point ``p_hold`` with yaw ``psi_h`` is
the call with no neighbours, ``leader_link = 1`` and ``reference = [p_hold - h_i, 0, 0, 0, psi_h]``.

The kernels do not check shapes (the Python wrapper does); wrong shapes read or write out of
bounds. They check only that the states are finite (:func:`uh_control_step` returns which one is
not, before it changes anything). Division by zero raises ``ZeroDivisionError`` (numba's Python
error model), as the same expression would in Python.

Compilation and the on-disk cache
---------------------------------
The first call compiles a kernel (seconds) and stores it in numba's cache (``__pycache__`` next to
this file, or ``NUMBA_CACHE_DIR``); later processes load it. :func:`compile_control_kernels`
compiles :func:`uh_control_step` (with everything it calls) for the one signature
:class:`UHController` uses, for install scripts that warm the cache. numba invalidates a cached
kernel only when *its own* source file changes: a kernel in another file that calls these (a team
kernel) keeps its cached copy of the old control law after this file is edited, so clear that
file's cache (or touch it) whenever this file changes. The same holds for ``gains.py``, whose
declarations lay out the gains' part of ``params`` (the ``CP_*`` and ``L_*`` constants); this
file's own cache is emptied when ``gains.py`` or ``uh_core/layout.py`` change.
"""
from __future__ import annotations

import math
import operator
import time
from typing import NamedTuple

import numpy as np
from uh_core import compiled_kernels as _compiled_kernels
from uh_core.compiled_kernels import njit

from uh_core import kernel_cache as _kernel_cache
from uh_core import layout as _layout
from uh_core.layout import (INPUT_SIZE, R_P, R_V, R_YAW, REFERENCE_SIZE, S_COST_RATE, S_EULER_D, S_F_HAT_P,
                            S_F_HAT_W, S_SAT_COLLECTIVE, S_SAT_CYCLIC, S_SAT_TILT, S_THRUST, S_U_P, S_W_NORM_P,
                            S_W_NORM_W, S_Z1, S_Z2, S_Z3, S_Z4, S_ZN_P, S_ZN_W, STATE_SIZE, STATUS_SIZE,
                            STATUS_VECTORS, U_COL, U_LAT, U_LON, U_TR, X_OMEGA, X_P, X_THETA, X_V, YAW)

from . import gains as _gains
from .gains import GAIN_SLOTS, LOOP_GAIN_SLOTS

__all__ = [
    'STATE_SIZE', 'INPUT_SIZE', 'X_P', 'X_V', 'X_THETA', 'X_OMEGA', 'YAW', 'U_COL', 'U_TR', 'U_LAT', 'U_LON',
    'CP_MASS', 'CP_GRAVITY', 'CP_J_X', 'CP_J_Y', 'CP_J_Z', 'CP_C_M1', 'CP_C_M2', 'CP_K_BETA', 'CP_H_M',
    'CP_B_LAT', 'CP_A_LON', 'CP_TAU_F', 'CP_K_TR', 'CP_D_R', 'CP_C_Q', 'CP_D_V', 'CP_LOWER', 'CP_UPPER',
    'CP_BETA', 'CP_TILT_LIMIT', 'CP_MIN_VERTICAL_ACCEL', 'CP_OUTER', 'CP_INNER', 'CONTROL_PARAMS_SIZE',
    'L_K', 'L_R', 'L_TAU_COMMAND', 'L_TAU_RATE', 'L_KAPPA', 'L_LEARNING_RATE', 'L_GAMMA', 'L_GAMMA_F',
    'L_SIGMA', 'L_LAMBDA', 'L_SIGMA_F', 'L_FAULT_BOUND', 'L_WEIGHT_BOUND', 'L_RBF_LOW', 'L_RBF_HIGH',
    'L_RBF_WIDTH', 'LOOP_GAINS_SIZE', 'R_P', 'R_V', 'R_YAW', 'REFERENCE_SIZE',
    'M_ALPHA_F', 'M_V_HAT', 'M_F_HAT_P', 'M_THETA_DF', 'M_ALPHA_WF', 'M_OMEGA_HAT', 'M_F_HAT_W',
    'M_FLAGS', 'FLAG_STARTED', 'FLAG_TIME', 'MEMORY_ROWS', 'CP_LEARNING_PHASE', 'L_LATE_LEARNING_RATE',
    'L_LATE_SIGMA', 'MODEL_ENTRIES', 'GAIN_ENTRIES', 'LOOP_GAIN_ENTRIES', 'MODEL_INDEX', 'GAIN_INDEX',
    'LOOP_GAIN_OFFSET',
    'S_Z1', 'S_Z2', 'S_Z3', 'S_Z4', 'S_F_HAT_P', 'S_F_HAT_W', 'S_ZN_P', 'S_ZN_W', 'S_U_P', 'S_EULER_D',
    'S_THRUST', 'S_W_NORM_P', 'S_W_NORM_W', 'S_SAT_TILT', 'S_SAT_COLLECTIVE', 'S_SAT_CYCLIC',
    'S_COST_RATE', 'STATUS_SIZE', 'STATUS_VECTORS', 'STEP_DONE', 'PROJECTION_TOLERANCE',
    'ControlArrays', 'control_parameters', 'wrap_angle', 'filter_gain', 'filter_rate', 'filter_advance',
    'rbf_centre', 'rbf_activations', 'rbf_output', 'project_columns', 'composite_weight_update',
    'fault_observer_update', 'estimator_advance', 'consensus_errors', 'outer_law', 'thrust_and_attitude',
    'achieved_acceleration', 'outer_advance', 'euler_rate_inverse', 'euler_rate_transpose', 'inner_drift',
    'control_effectiveness', 'inner_law', 'inner_advance', 'frobenius_norm', 'first_non_finite_state',
    'uh_control_step', 'compile_control_kernels',
]

# -- state, input and reference layout: uh_core.layout ------------------------------------------
_MOMENT_CHANNELS = (U_LAT, U_LON, U_TR)         # command channels of u_m = (delta_lat, delta_lon, theta_tr)

# -- control parameters: the one table of what params holds, in order ----------------------------
#: Entries from the nominal model (docs/model.md#what-the-controller-knows), a ``HelicopterParams``:
#: ``(field, number of entries)``. SI units: kg, m/s^2, kg m^2 (J_x, J_y, J_z), N/rad and N (thrust
#: map T = c_M1 theta_col + c_M2), N m/rad (hub stiffness), m (hub height), rad/rad (flapping gains),
#: s (flapping lag per body rate), N m/rad (tail rotor), N m s (yaw damping), m (torque reaction per
#: thrust) and N s/m (drag), both after the model mismatch; input limits in command order (U_*), rad.
MODEL_ENTRIES = (('mass', 1), ('gravity', 1), ('inertia', 3), ('c_M1', 1), ('c_M2', 1), ('K_beta', 1), ('h_M', 1),
                 ('B_lat', 1), ('A_lon', 1), ('tau_f', 1), ('K_tr', 1), ('D_r', 1), ('c_Q', 1), ('D_v', 1),
                 ('input_lower', INPUT_SIZE), ('input_upper', INPUT_SIZE))
#: Entries from the gains of the case (docs/control_law.md), a ``ControllerGains``, after the model's,
#: then one block per loop (a ``LoopGains``; dotted: a field of its ``rbf``) at offsets 0, 1, ...:
#: the gains with a slot, in the order of their declaration (``uh_controller_node.gains.GAINS``,
#: which gives their units). The outer loop has no ``tau_rate`` (None: 0).
GAIN_ENTRIES = GAIN_SLOTS
LOOP_GAIN_ENTRIES = LOOP_GAIN_SLOTS


def _first_indices(entries, start=0):
    """``{name: first index}`` of ``entries`` (names, or ``(name, count)``) laid end to end from ``start``."""
    out = {}
    for entry in entries:
        name, count = entry if isinstance(entry, tuple) else (entry, 1)
        out[name] = start
        start += count
    return out


MODEL_INDEX = _first_indices(MODEL_ENTRIES)
GAIN_INDEX = _first_indices(GAIN_ENTRIES, start=sum(count for _, count in MODEL_ENTRIES))
LOOP_GAIN_OFFSET = _first_indices(LOOP_GAIN_ENTRIES)
# the indices the kernels use (plain ints: numba reads them as compile-time constants)
CP_MASS = MODEL_INDEX['mass']
CP_GRAVITY = MODEL_INDEX['gravity']
CP_J_X = MODEL_INDEX['inertia']
CP_J_Y = CP_J_X + 1
CP_J_Z = CP_J_X + 2
CP_C_M1 = MODEL_INDEX['c_M1']
CP_C_M2 = MODEL_INDEX['c_M2']
CP_K_BETA = MODEL_INDEX['K_beta']
CP_H_M = MODEL_INDEX['h_M']
CP_B_LAT = MODEL_INDEX['B_lat']
CP_A_LON = MODEL_INDEX['A_lon']
CP_TAU_F = MODEL_INDEX['tau_f']
CP_K_TR = MODEL_INDEX['K_tr']
CP_D_R = MODEL_INDEX['D_r']
CP_C_Q = MODEL_INDEX['c_Q']
CP_D_V = MODEL_INDEX['D_v']
CP_LOWER = MODEL_INDEX['input_lower']
CP_UPPER = MODEL_INDEX['input_upper']
CP_BETA = GAIN_INDEX['beta']
CP_TILT_LIMIT = GAIN_INDEX['tilt_limit']
CP_MIN_VERTICAL_ACCEL = GAIN_INDEX['min_vertical_accel']
CP_LEARNING_PHASE = GAIN_INDEX['learning_phase']
CP_OUTER = GAIN_INDEX[GAIN_ENTRIES[0]] + len(GAIN_ENTRIES)   # first entry of the outer loop's gains block
# offsets inside one loop's block (each named after its slot: a test checks they match)
L_K = LOOP_GAIN_OFFSET['k']
L_R = LOOP_GAIN_OFFSET['r']
L_TAU_COMMAND = LOOP_GAIN_OFFSET['tau_command']
L_TAU_RATE = LOOP_GAIN_OFFSET['tau_rate']
L_KAPPA = LOOP_GAIN_OFFSET['kappa']
L_LEARNING_RATE = LOOP_GAIN_OFFSET['learning_rate']
L_GAMMA = LOOP_GAIN_OFFSET['gamma']
L_GAMMA_F = LOOP_GAIN_OFFSET['gamma_F']
L_SIGMA = LOOP_GAIN_OFFSET['sigma']
L_LAMBDA = LOOP_GAIN_OFFSET['lambda_']
L_SIGMA_F = LOOP_GAIN_OFFSET['sigma_F']
L_FAULT_BOUND = LOOP_GAIN_OFFSET['fault_bound']
L_WEIGHT_BOUND = LOOP_GAIN_OFFSET['weight_bound']
L_RBF_LOW = LOOP_GAIN_OFFSET['rbf.low']
L_RBF_HIGH = LOOP_GAIN_OFFSET['rbf.high']
L_RBF_WIDTH = LOOP_GAIN_OFFSET['rbf.width']
L_LATE_LEARNING_RATE = LOOP_GAIN_OFFSET['late_learning_rate']
L_LATE_SIGMA = LOOP_GAIN_OFFSET['late_sigma']
LOOP_GAINS_SIZE = len(LOOP_GAIN_ENTRIES)
CP_INNER = CP_OUTER + LOOP_GAINS_SIZE
CONTROL_PARAMS_SIZE = CP_INNER + LOOP_GAINS_SIZE

# -- memory: the internal states of one controller, one 3-vector per row ------------------------
M_ALPHA_F = 0               # filtered virtual velocity alpha_f, m/s, inertial
M_V_HAT = 1                 # outer SPEM state vhat, m/s
M_F_HAT_P = 2               # outer fault estimate Fhat_p, m/s^2, inertial
M_THETA_DF = 3              # filtered attitude command Theta_df, rad (continuous, not wrapped)
M_ALPHA_WF = 4              # filtered virtual body rate alpha_wf, rad/s
M_OMEGA_HAT = 5             # inner SPEM state omegahat, rad/s
M_F_HAT_W = 6               # inner fault estimate Fhat_w, rad/s^2, body
M_FLAGS = 7                 # flags and clock: columns FLAG_STARTED, FLAG_TIME
FLAG_STARTED = 0            # 1.0 after the first step
FLAG_TIME = 1               # simulated time t_k of the step being computed, s (set by the caller on
                            # the first step, k dt; advanced by dt per step): ends the learning phase
MEMORY_ROWS = 8

# -- status vector: uh_core.layout (S_*, STATUS_SIZE, STATUS_VECTORS), the fields of ControllerStatus.msg --

#: Return value of :func:`uh_control_step` when the step was taken.
STEP_DONE = -1

#: Relative slack of the column-norm test of :func:`project_columns`: a column scaled onto the
#: sphere may round to a hair above it, and that counts as inside.
PROJECTION_TOLERANCE = 1e-12

_PI = math.pi
_TWO_PI = 2.0 * math.pi
_TINY_NORM = 1e-300         # guards the division by a zero column norm in the projection

# -- per-step scratch rows of uh_control_step (intermediate 3-vectors, not kept) -----------------
_W_FEEDFORWARD = 0          # sum_j a_j v_j + a_0 v_0, m/s
_W_ALPHA_V = 1              # virtual velocity alpha_v, m/s
_W_ALPHA_V_RATE = 2         # alpha_f', m/s^2
_W_NET_P = 3                # W_p^T S(v), m/s^2
_W_DRIFT_P = 4              # f_p,nom(v), m/s^2
_W_ACCEL = 5                # acceleration the limited thrust delivers, m/s^2
_W_THETA_DF_RATE = 6        # Theta_df', rad/s
_W_ALPHA_W = 7              # virtual body rate alpha_w, rad/s
_W_ALPHA_W_RATE = 8         # alpha_wf', rad/s^2
_W_NET_W = 9                # W_w^T S(omega), rad/s^2
_W_DRIFT_W = 10             # f_w,nom(omega, T), rad/s^2
_W_EFFECTIVENESS = 11       # diagonal of G(T), rad/s^2 per rad
_W_U_M = 12                 # limited (delta_lat, delta_lon, theta_tr), rad
_W_APPLIED = 13             # G u_m after the limits, rad/s^2
_WORK_ROWS = 14


class ControlArrays(NamedTuple):
    """The arrays of one controller that :func:`uh_control_step` reads or updates (see module doc).

    Attributes
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    offset : ndarray (3,)
        Own formation offset h_i, m (zero for followers).
    neighbour_weights : ndarray (n_nb,)
        a_ij of the UHs heard, ascending id.
    neighbour_offsets : ndarray (n_nb, 3)
        Their formation offsets h_j, m (zero for followers).
    leader_link : float
        a_i0.
    weights_p : ndarray (mu_p, 3)
    weights_w : ndarray (mu_w, 3)
    memory : ndarray (MEMORY_ROWS, 3)
    """

    params: np.ndarray
    offset: np.ndarray
    neighbour_weights: np.ndarray
    neighbour_offsets: np.ndarray
    leader_link: float
    weights_p: np.ndarray
    weights_w: np.ndarray
    memory: np.ndarray


def control_parameters(gains, model) -> np.ndarray:
    """Pack ``params`` (CONTROL_PARAMS_SIZE,) float64 from the gains of one case and the nominal model.

    The entries follow :data:`MODEL_ENTRIES`, :data:`GAIN_ENTRIES` and, per loop, :data:`LOOP_GAIN_ENTRIES`.

    Parameters
    ----------
    gains : uh_controller_node.gains.ControllerGains
    model : uh_core.airframe.HelicopterParams
    """
    out = np.zeros(CONTROL_PARAMS_SIZE)
    for name, count in MODEL_ENTRIES:
        at = MODEL_INDEX[name]
        out[at:at + count] = getattr(model, name)
    for name in GAIN_ENTRIES:
        out[GAIN_INDEX[name]] = getattr(gains, name)
    for base, loop in ((CP_OUTER, gains.outer), (CP_INNER, gains.inner)):
        for path in LOOP_GAIN_ENTRIES:
            value = operator.attrgetter(path)(loop)
            out[base + LOOP_GAIN_OFFSET[path]] = 0.0 if value is None else value   # outer tau_rate: None
    return out


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
# Gaussian RBF networks, composite learning, fault observers
# (docs/control_law.md#learning-and-estimation and #anti-windup-and-projection)


@njit(cache=True)
def rbf_centre(i, nodes, low, high):
    """Return the centre c_i of node ``i`` of ``nodes`` evenly spaced on ``[low, high]``.

    The spacing is that of ``np.linspace``; one node sits at ``(low + high) / 2``.
    """
    if nodes == 1:
        return 0.5 * (low + high)
    if i == nodes - 1:
        return high
    return i * ((high - low) / (nodes - 1)) + low


@njit(cache=True)
def rbf_activations(x, low, high, width, out):
    """Gaussian activations of one scalar network per axis, all with the same centres.

    Each axis ``a`` of a 3-vector input ``x`` has its own scalar network (the per-direction form
    of the paper, "the design processes of three directions are similar")::

        S_i(x_a) = exp(-(x_a - c_i)^2 / b^2),   i = 1..mu,   c_i evenly spaced on [low, high]

    Parameters
    ----------
    x : ndarray (3,)
        Network input (velocity m/s or body rate rad/s).
    low, high, width : float
        First and last centre, width b > 0 (unit of ``x``).
    out : ndarray (mu, 3)
        ``S[i, a] = S_i(x_a)``; mu is ``out.shape[0]``.
    """
    nodes = out.shape[0]
    neg_inv_b2 = -1.0 / (width * width)
    for i in range(nodes):
        c = rbf_centre(i, nodes, low, high)
        for a in range(3):
            s = x[a] - c
            out[i, a] = math.exp(s * s * neg_inv_b2)


@njit(cache=True)
def rbf_output(weights, activations, out):
    """Network output per axis ``fhat_a = sum_i W[i, a] S[i, a]`` (i.e. ``W^T S``), to ``out`` (3,).

    ``weights`` and ``activations`` are (mu, 3); the sum runs over i in ascending order.
    """
    for a in range(3):
        acc = 0.0
        for i in range(weights.shape[0]):
            acc += weights[i, a] * activations[i, a]
        out[a] = acc


@njit(cache=True)
def project_columns(weights, bound):
    """Scale in place every column of ``weights`` (mu, 3) whose Euclidean norm exceeds ``bound``.

    The discrete counterpart of the projection operator (docs/control_law.md#anti-windup-and-projection):
    each column is projected onto the ball of radius ``bound``, its direction kept. Returns True if any
    column was scaled.
    Columns within ``bound (1 + PROJECTION_TOLERANCE)`` are left unchanged.
    """
    limit = bound * bound * (1.0 + PROJECTION_TOLERANCE)
    scaled = False
    for a in range(3):
        norm2 = 0.0
        for i in range(weights.shape[0]):
            norm2 += weights[i, a] * weights[i, a]
        if norm2 > limit:
            scale = bound / max(math.sqrt(norm2), _TINY_NORM)
            for i in range(weights.shape[0]):
                weights[i, a] *= scale
            scaled = True
    return scaled


@njit(cache=True)
def composite_weight_update(weights, activations, z, zn, learning_rate, gamma, sigma, dt, bound):
    """Advance ``weights`` by one explicit-Euler step of the composite learning law, in place.

    The law is step 5 of docs/control_law.md#outer-loop::

        W' = Gamma [ S (z + gamma z_n)^T - sigma W ]        then the column projection

    per axis: column ``a`` of W moves by ``dt Gamma (S[:, a] (z[a] + gamma z_n[a]) - sigma W[:, a])``,
    i.e. ``W <- (1 - dt Gamma sigma) W + dt Gamma S diag(z + gamma z_n)``; then
    :func:`project_columns` with ``bound``.

    Parameters
    ----------
    weights : ndarray (mu, 3)
        W, updated in place.
    activations : ndarray (mu, 3)
        S(X) at t_k.
    z, zn : ndarray (3,)
        Tracking error (z2 or z4) and SPEM prediction error z_n at t_k.
    learning_rate, gamma, sigma : float
        Gamma 1/s, gamma (-), sigma (-).
    dt : float
        Step, s.
    bound : float
        Projection radius of each column.
    """
    step = dt * learning_rate
    leak = 1.0 - step * sigma
    for a in range(3):
        drive = step * (z[a] + gamma * zn[a])
        for i in range(weights.shape[0]):
            w = weights[i, a]
            if sigma != 0.0:
                w = w * leak
            weights[i, a] = w + activations[i, a] * drive
    project_columns(weights, bound)


@njit(cache=True)
def fault_observer_update(fhat, z, zn, lambda_, gamma_f, sigma_f, dt, bound):
    """Advance ``fhat`` by one explicit-Euler step of the fault estimation observer, in place.

    The observer is step 6 of docs/control_law.md#outer-loop::

        Fhat' = lambda [ z + gamma_F z_n - sigma_F Fhat ]     then |Fhat_a| <= bound per component

    ``fhat``, ``z``, ``zn`` (3,); ``lambda_`` 1/s, ``gamma_f``, ``sigma_f`` (-), ``dt`` s.
    """
    gain = dt * lambda_
    for a in range(3):
        f = fhat[a] + gain * (z[a] + gamma_f * zn[a] - sigma_f * fhat[a])
        fhat[a] = min(max(f, -bound), bound)


@njit(cache=True)
def _learning(params, memory):
    """Return True while the step's simulated time (``FLAG_TIME``) is within the learning phase.

    The learning phase (``CP_LEARNING_PHASE``) is counted from step 0 of the run.
    """
    return memory[M_FLAGS, FLAG_TIME] < params[CP_LEARNING_PHASE]


@njit(cache=True)
def estimator_advance(params, base, dt, learning, drift, net, applied, z, zn, activations, estimate, weights, fhat):
    """Advance the learning states of one loop from t_k to t_{k+1}.

    Explicit Euler (docs/control_law.md#outer-loop steps 4-6 and 2.5 step 3), all right-hand sides at t_k::

        xhat' = f_nom + W^T S + a_applied + Fhat + kappa z_n      serial-parallel estimation model
        W'    = Gamma [ S (z + gamma z_n)^T - sigma W ]            composite learning, projection
        Fhat' = lambda [ z + gamma_F z_n - sigma_F Fhat ]          fault observer, projection

    ``a_applied`` is what the limits let through (anti-windup,
    docs/control_law.md#anti-windup-and-projection): the SPEM never learns an acceleration that was
    demanded but not delivered.

    During the learning phase (``learning``) the network learns with Gamma and sigma and the fault
    observer holds Fhat (zero from the start): what the nominal model misses goes into W. After it,
    the network goes on with the late Gamma and sigma, and the observer runs
    (docs/control_law.md#learning-phase).

    Parameters
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    base : int
        ``CP_OUTER`` (xhat = vhat, z = z2) or ``CP_INNER`` (xhat = omegahat, z = z4).
    dt : float
        s.
    learning : bool
        True during the learning phase.
    drift, net, applied : ndarray (3,)
        f_nom, W^T S and a_applied at t_k (m/s^2 or rad/s^2).
    z, zn : ndarray (3,)
        Tracking and prediction errors at t_k.
    activations : ndarray (mu, 3)
        S at t_k.
    estimate, weights, fhat : ndarray (3,), (mu, 3), (3,)
        xhat, W, Fhat, updated in place.
    """
    kappa = params[base + L_KAPPA]
    for a in range(3):
        estimate[a] = estimate[a] + dt * (drift[a] + net[a] + applied[a] + fhat[a] + kappa * zn[a])
    if learning:
        composite_weight_update(weights, activations, z, zn, params[base + L_LEARNING_RATE],
                                params[base + L_GAMMA], params[base + L_SIGMA], dt,
                                params[base + L_WEIGHT_BOUND])
        return
    composite_weight_update(weights, activations, z, zn, params[base + L_LATE_LEARNING_RATE],
                            params[base + L_GAMMA], params[base + L_LATE_SIGMA], dt,
                            params[base + L_WEIGHT_BOUND])
    fault_observer_update(fhat, z, zn, params[base + L_LAMBDA], params[base + L_GAMMA_F],
                          params[base + L_SIGMA_F], dt, params[base + L_FAULT_BOUND])


# =============================================================================================
# Consensus errors (docs/graph.md)


@njit(cache=True)
def consensus_errors(own_state, offset, nb_states, nb_weights, nb_offsets, leader_link, reference,
                     z1, feedforward):
    """Consensus position error, velocity feed-forward, degree and yaw target of one UH.

    With ``h`` the formation offsets (leaders) or zero (followers)::

        leader i:    z1 = sum_{j in N_i} a_ij [(p_i - h_i) - (p_j - h_j)] + a_i0 [(p_i - h_i) - p_0]
        follower k:  z1 = sum_{j in N_k} a_kj (p_k - p_j)
        d = sum_j a_ij + a_i0 ,   feed-forward velocity f = sum_j a_ij v_j + a_i0 v_0

    Yaw: a UH that hears the virtual leader (``leader_link > 0``) tracks ``psi_0``; every other UH
    tracks the a-weighted mean of its neighbours' yaw, ``psi_i + sum_j a_ij wrap(psi_j - psi_i) /
    sum_j a_ij``, so the mean is taken the short way around the circle.

    Parameters
    ----------
    own_state : ndarray (12,)
    offset : ndarray (3,)
        h_i, m.
    nb_states : ndarray (n_nb, 12)
        States of the UHs heard, in ascending id order (the order of the sums).
    nb_weights : ndarray (n_nb,)
        a_ij.
    nb_offsets : ndarray (n_nb, 3)
        h_j, m.
    leader_link : float
        a_i0 (0: the reference is not read).
    reference : ndarray (7,)
        ``[p_0, v_0, psi_0]``.
    z1, feedforward : ndarray (3,)
        Outputs: z1 m, f m/s.

    Returns
    -------
    degree : float
        d (> 0 for a valid graph).
    psi_d : float
        Yaw target, rad.
    """
    psi = own_state[X_THETA + YAW]
    degree = 0.0
    yaw_sum = 0.0
    for a in range(3):
        z1[a] = 0.0
        feedforward[a] = 0.0
    for n in range(nb_states.shape[0]):
        w = nb_weights[n]
        degree += w
        for a in range(3):
            rel = own_state[X_P + a] - offset[a]
            z1[a] += w * (rel - (nb_states[n, X_P + a] - nb_offsets[n, a]))
            feedforward[a] += w * nb_states[n, X_V + a]
        yaw_sum += w * wrap_angle(nb_states[n, X_THETA + YAW] - psi)
    degree += leader_link
    if leader_link > 0.0:
        for a in range(3):
            rel = own_state[X_P + a] - offset[a]
            z1[a] += leader_link * (rel - reference[R_P + a])
            feedforward[a] += leader_link * reference[R_V + a]
        psi_d = reference[R_YAW]
    else:
        psi_d = psi + yaw_sum / degree
    return degree, psi_d


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
    k1 = params[CP_OUTER + L_K]
    k2 = params[CP_BETA] / (2.0 * params[CP_OUTER + L_R])   # inverse-optimal gain of z2, 1/s
    inv_d = 1.0 / degree
    for a in range(3):
        alpha_v[a] = (feedforward[a] - k1 * z1[a]) * inv_d
    alpha_f, vhat, fhat = memory[M_ALPHA_F], memory[M_V_HAT], memory[M_F_HAT_P]
    if not started:
        for a in range(3):
            alpha_f[a] = alpha_v[a]
            vhat[a] = v[a]
    filter_rate(alpha_v, alpha_f, params[CP_OUTER + L_TAU_COMMAND], False, alpha_rate)
    rbf_activations(v, params[CP_OUTER + L_RBF_LOW], params[CP_OUTER + L_RBF_HIGH],
                    params[CP_OUTER + L_RBF_WIDTH], activations)
    rbf_output(weights, activations, net)
    drag = params[CP_D_V] / params[CP_MASS]
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
    g = params[CP_GRAVITY]
    ax, ay, az = u_p[0], u_p[1], u_p[2] + g
    sat_tilt = False
    if az < params[CP_MIN_VERTICAL_ACCEL]:
        az = params[CP_MIN_VERTICAL_ACCEL]
        sat_tilt = True
    horizontal = math.hypot(ax, ay)
    horizontal_max = az * math.tan(params[CP_TILT_LIMIT])
    if horizontal > horizontal_max:
        scale = horizontal_max / horizontal
        ax *= scale
        ay *= scale
        sat_tilt = True
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    cp, sp = math.cos(psi_d), math.sin(psi_d)
    theta_d = math.atan2(ax * cp + ay * sp, az)
    phi_d = math.asin(max(-1.0, min(1.0, (ax * sp - ay * cp) / norm)))
    thrust = params[CP_MASS] * norm
    theta_col = (thrust - params[CP_C_M2]) / params[CP_C_M1]
    lo, hi = params[CP_LOWER + U_COL], params[CP_UPPER + U_COL]
    sat_col = not lo <= theta_col <= hi
    theta_col = min(max(theta_col, lo), hi)
    thrust_achieved = params[CP_C_M1] * theta_col + params[CP_C_M2]
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
    tm = thrust / params[CP_MASS]
    out[0] = tm * (cp * st * cf + sp * sf)
    out[1] = tm * (sp * st * cf - cp * sf)
    out[2] = tm * ct * cf - params[CP_GRAVITY]


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
    estimator_advance(params, CP_OUTER, dt, _learning(params, memory), drift, net, accel, z2, zn, activations,
                      memory[M_V_HAT], weights, memory[M_F_HAT_P])
    filter_advance(alpha_v, memory[M_ALPHA_F], filter_gain(params[CP_OUTER + L_TAU_COMMAND], dt), False)


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
    jx, jy, jz = params[CP_J_X], params[CP_J_Y], params[CP_J_Z]
    k = params[CP_K_BETA] + thrust * params[CP_H_M]
    tau_f = params[CP_TAU_F]
    out[0] = ((jy - jz) * q * r - k * tau_f * p) / jx
    out[1] = ((jz - jx) * r * p - k * tau_f * q) / jy
    out[2] = ((jx - jy) * p * q - params[CP_D_R] * r - params[CP_C_Q] * thrust) / jz


@njit(cache=True)
def control_effectiveness(params, thrust, out):
    """Compute the diagonal of ``G(T) = J^-1 diag((K_beta + T h_M) B_lat, (K_beta + T h_M) A_lon, K_tr)``.

    The diagonal is (3,), rad/s^2 per rad, for ``u_m = (delta_lat, delta_lon, theta_tr)``;
    ``thrust`` T in N.
    """
    k = params[CP_K_BETA] + thrust * params[CP_H_M]
    out[0] = k * params[CP_B_LAT] / params[CP_J_X]
    out[1] = k * params[CP_A_LON] / params[CP_J_Y]
    out[2] = params[CP_K_TR] / params[CP_J_Z]


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
    base = CP_INNER
    theta_df, alpha_wf = memory[M_THETA_DF], memory[M_ALPHA_WF]
    omegahat, fhat = memory[M_OMEGA_HAT], memory[M_F_HAT_W]
    if not started:
        for a in range(3):
            theta_df[a] = euler_d[a]
    filter_rate(euler_d, theta_df, params[base + L_TAU_COMMAND], True, theta_rate)
    for a in range(3):
        z3[a] = euler[a] - theta_df[a]
    z3[YAW] = wrap_angle(z3[YAW])
    k3 = params[base + L_K]
    rate_command = np.empty(3)                  # -k3 z3 + Theta_df', Euler-angle rates, rad/s
    for a in range(3):
        rate_command[a] = theta_rate[a] - k3 * z3[a]
    euler_rate_inverse(euler, rate_command, alpha_w)
    if not started:
        for a in range(3):
            alpha_wf[a] = alpha_w[a]
            omegahat[a] = omega[a]
    filter_rate(alpha_w, alpha_wf, params[base + L_TAU_RATE], False, alpha_rate)
    for a in range(3):
        z4[a] = omega[a] - alpha_wf[a]
        zn[a] = omega[a] - omegahat[a]
    rbf_activations(omega, params[base + L_RBF_LOW], params[base + L_RBF_HIGH],
                    params[base + L_RBF_WIDTH], activations)
    rbf_output(weights, activations, net)
    inner_drift(params, omega, thrust, drift)
    control_effectiveness(params, thrust, effectiveness)
    ht_z3 = np.empty(3)
    euler_rate_transpose(euler, z3, ht_z3)
    k4 = params[CP_BETA] / (2.0 * params[base + L_R])   # inverse-optimal gain of z4, 1/s
    saturated = False
    for a in range(3):
        channel = _MOMENT_CHANNELS[a]
        want = (alpha_rate[a] - drift[a] - ht_z3[a] - net[a] - fhat[a] - k4 * z4[a]) / effectiveness[a]
        got = min(max(want, params[CP_LOWER + channel]), params[CP_UPPER + channel])
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
    estimator_advance(params, CP_INNER, dt, _learning(params, memory), drift, net, applied, z4, zn, activations,
                      memory[M_OMEGA_HAT], weights, memory[M_F_HAT_W])
    filter_advance(euler_d, memory[M_THETA_DF], filter_gain(params[CP_INNER + L_TAU_COMMAND], dt), True)
    filter_advance(alpha_w, memory[M_ALPHA_WF], filter_gain(params[CP_INNER + L_TAU_RATE], dt), False)


# =============================================================================================
# One control step of one UH


@njit(cache=True)
def frobenius_norm(weights):
    """``sqrt(sum_ia W[i, a]^2)`` of a (mu, 3) weight matrix."""
    acc = 0.0
    for i in range(weights.shape[0]):
        for a in range(3):
            acc += weights[i, a] * weights[i, a]
    return math.sqrt(acc)


@njit(cache=True)
def first_non_finite_state(own_state, nb_states):
    """Return the index of the first non-finite state, or ``STEP_DONE`` (-1) when all are finite.

    ``STEP_DONE`` when ``own_state`` (12,) and every row of ``nb_states`` (n_nb, 12) are finite;
    otherwise 0 for the own state or ``1 + n`` for neighbour row ``n`` (the first found).
    """
    for a in range(STATE_SIZE):
        if not math.isfinite(own_state[a]):
            return 0
    for n in range(nb_states.shape[0]):
        for a in range(STATE_SIZE):
            if not math.isfinite(nb_states[n, a]):
                return 1 + n
    return STEP_DONE


@njit(cache=True)
def uh_control_step(params, own_state, nb_states, nb_weights, nb_offsets, offset, leader_link,
                    reference, dt, weights_p, weights_w, memory, u, status):
    """Run one control step of one UH at t_k (docs/graph.md, docs/control_law.md).

    The command ``u`` and ``status`` are written out, the internal states advanced to t_{k+1}.

    Order: :func:`consensus_errors` -> :func:`outer_law` -> :func:`thrust_and_attitude` ->
    :func:`inner_law` -> :func:`outer_advance` (its SPEM fed with :func:`achieved_acceleration`)
    -> :func:`inner_advance` (its SPEM fed with ``G u_m`` after the limits). Fhat in ``status``
    is the value used at t_k; the weight norms are those after the update.

    Parameters
    ----------
    params : ndarray (CONTROL_PARAMS_SIZE,)
    own_state : ndarray (12,)
        ``[p, v, Theta, omega]`` at t_k.
    nb_states : ndarray (n_nb, 12)
        States of the UHs heard at t_k, ascending id (n_nb may be 0).
    nb_weights : ndarray (n_nb,)
        a_ij.
    nb_offsets : ndarray (n_nb, 3)
        Formation offsets h_j (zero for followers), m.
    offset : ndarray (3,)
        h_i, m.
    leader_link : float
        a_i0; ``reference`` is read only when > 0. ``sum(nb_weights) + leader_link`` must be > 0.
    reference : ndarray (7,)
        ``[p_0, v_0, psi_0]`` at t_k.
    dt : float
        Control period, s.
    weights_p, weights_w, memory : ndarray (mu_p, 3), (mu_w, 3), (MEMORY_ROWS, 3)
        The controller's internal states, updated in place.
    u : ndarray (4,)
        Output: ``(theta_col, theta_tr, delta_lat, delta_lon)`` rad, within the input limits.
    status : ndarray (STATUS_SIZE,)
        Output (see module doc).

    Returns
    -------
    int
        ``STEP_DONE``; or, when a state is not finite, :func:`first_non_finite_state`'s index and
        nothing (internal states, ``u``, ``status``) is changed.
    """
    bad = first_non_finite_state(own_state, nb_states)
    if bad != STEP_DONE:
        return bad
    work = np.empty((_WORK_ROWS, 3))
    act_p = np.empty(weights_p.shape)
    act_w = np.empty(weights_w.shape)
    v = own_state[X_V:X_V + 3]
    euler = own_state[X_THETA:X_THETA + 3]
    omega = own_state[X_OMEGA:X_OMEGA + 3]
    started = memory[M_FLAGS, FLAG_STARTED] != 0.0
    z1 = status[S_Z1:S_Z1 + 3]
    z2 = status[S_Z2:S_Z2 + 3]
    z3 = status[S_Z3:S_Z3 + 3]
    z4 = status[S_Z4:S_Z4 + 3]
    zn_p = status[S_ZN_P:S_ZN_P + 3]
    zn_w = status[S_ZN_W:S_ZN_W + 3]
    u_p = status[S_U_P:S_U_P + 3]
    euler_d = status[S_EULER_D:S_EULER_D + 3]
    # the estimates used at t_k, before the update
    status[S_F_HAT_P:S_F_HAT_P + 3] = memory[M_F_HAT_P]
    status[S_F_HAT_W:S_F_HAT_W + 3] = memory[M_F_HAT_W]

    degree, psi_d = consensus_errors(own_state, offset, nb_states, nb_weights, nb_offsets, leader_link,
                                     reference, z1, work[_W_FEEDFORWARD])
    outer_law(params, degree, z1, work[_W_FEEDFORWARD], v, started, memory, weights_p, act_p,
              work[_W_ALPHA_V], work[_W_ALPHA_V_RATE], work[_W_NET_P], work[_W_DRIFT_P], z2, zn_p, u_p)
    phi_d, theta_d, thrust, theta_col, thrust_achieved, sat_tilt, sat_col = \
        thrust_and_attitude(params, u_p, psi_d)
    euler_d[0] = phi_d
    euler_d[1] = theta_d
    euler_d[YAW] = psi_d
    sat_cyclic = inner_law(params, euler, omega, euler_d, thrust_achieved, started, memory, weights_w,
                           act_w, work[_W_THETA_DF_RATE], work[_W_ALPHA_W], work[_W_ALPHA_W_RATE],
                           work[_W_NET_W], work[_W_DRIFT_W], work[_W_EFFECTIVENESS], z3, z4, zn_w,
                           work[_W_U_M], work[_W_APPLIED])

    # explicit Euler from t_k to t_{k+1}
    achieved_acceleration(params, euler, thrust_achieved, work[_W_ACCEL])
    outer_advance(params, dt, memory, weights_p, act_p, work[_W_ALPHA_V], work[_W_NET_P], work[_W_DRIFT_P],
                  work[_W_ACCEL], z2, zn_p)
    inner_advance(params, dt, memory, weights_w, act_w, euler_d, work[_W_ALPHA_W], work[_W_NET_W],
                  work[_W_DRIFT_W], work[_W_APPLIED], z4, zn_w)
    memory[M_FLAGS, FLAG_STARTED] = 1.0
    memory[M_FLAGS, FLAG_TIME] += dt

    u_m = work[_W_U_M]
    u[U_COL] = theta_col
    u[U_TR] = u_m[2]
    u[U_LAT] = u_m[0]
    u[U_LON] = u_m[1]
    status[S_THRUST] = thrust
    status[S_W_NORM_P] = frobenius_norm(weights_p)
    status[S_W_NORM_W] = frobenius_norm(weights_w)
    status[S_SAT_TILT] = 1.0 if sat_tilt else 0.0
    status[S_SAT_COLLECTIVE] = 1.0 if sat_col else 0.0
    status[S_SAT_CYCLIC] = 1.0 if sat_cyclic else 0.0
    cost = 0.0
    for a in range(3):
        cost += z1[a] * z1[a]
    effort = 0.0
    for a in range(3):
        effort += u_p[a] * u_p[a]
    status[S_COST_RATE] = cost + effort
    return STEP_DONE


def compile_control_kernels() -> float:
    """Compile :func:`uh_control_step` (and every kernel it calls) and fill numba's on-disk cache.

    The signature compiled is the one :class:`UHController` uses (C-contiguous float64 arrays,
    float scalars).

    Returns the wall time spent, s (compilation on a cold cache, loading on a warm one).
    """
    start = time.perf_counter()
    # a unit airframe with unit gains: any values without a zero divisor compile the same code
    params = np.ones(CONTROL_PARAMS_SIZE)
    params[CP_LOWER:CP_LOWER + INPUT_SIZE] = -1.0
    no_neighbours = 0
    uh_control_step(params, np.zeros(STATE_SIZE), np.zeros((no_neighbours, STATE_SIZE)),
                    np.ones(no_neighbours), np.zeros((no_neighbours, 3)), np.zeros(3), 1.0,
                    np.zeros(REFERENCE_SIZE), 0.01, np.zeros((3, 3)), np.zeros((3, 3)),
                    np.zeros((MEMORY_ROWS, 3)), np.zeros(INPUT_SIZE), np.zeros(STATUS_SIZE))
    return time.perf_counter() - start


# numba caches each kernel by this file only: empty the cache when the layout or the gains' slots it reads change
_kernel_cache.refresh_cache(_kernel_cache.module_dispatchers(globals()), [_layout.__file__, _gains.__file__])

# run the ahead-of-time compiled kernels instead where this process asks for them (docs/performance.md#memory)
_compiled_kernels.install(globals())
