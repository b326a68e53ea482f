"""Native kernels of the control law of one UH: the consensus errors and the step that runs the law.

The law computes the consensus errors, the outer and inner loops, and the learning and fault
observers (docs/graph.md, docs/control_law.md, with its anti-windup and projections). Its kernels
are in three modules, and what its arrays hold in a fourth:

* this one: the consensus errors (:func:`consensus_errors`) and the step of one UH
  (:func:`uh_control_step`), which calls the others in the order below;
* :mod:`.loop_kernels`: the command filters and the outer (position) and inner (attitude) loops;
* :mod:`.learning_kernels`: the RBF networks, composite learning and the fault observers;
* :mod:`.control_layout`: the layout of ``params``, ``memory`` and ``status`` (no kernels).

This module re-exports the public names of the other three: ``control_kernels`` is the law's one
name for its callers.

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
* ``reference`` (REFERENCE_SIZE = 7,) = ``[p_0 (3) m, v_0 (3) m/s, psi_0 rad]`` at ``R_P``,
  ``R_V``, ``R_YAW``; read only when ``leader_link > 0``.
* ``params`` (CONTROL_PARAMS_SIZE,), the nominal model and the gains; the mutable state of one
  controller, ``weights_p`` (mu_p, 3) W_p, ``weights_w`` (mu_w, 3) W_w (column a = axis a; mu =
  RBF nodes) and ``memory`` (MEMORY_ROWS, 3); and the output ``status`` (STATUS_SIZE,): laid out
  as :mod:`.control_layout` says. The kernels index them through its ``PARAM``, ``LOOP`` and
  ``STATUS`` tables. For Python callers the indices are also constants here: the model entries
  ``CP_*`` (``CP_MASS``, ``CP_J_X`` ... ``CP_UPPER``), the loops' blocks ``CP_OUTER`` and
  ``CP_INNER``, one constant per gain slot named after it (``CP_BETA``, ``L_KAPPA``:
  ``params[CP_INNER + L_KAPPA]`` is kappa_w; made from the gains' registry, so a new gain needs no
  line here) and the status fields ``S_*`` of :mod:`uh_core.layout`.

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
its file, or ``NUMBA_CACHE_DIR``); later processes load it. :func:`compile_control_kernels`
compiles :func:`uh_control_step` (with everything it calls) for the one signature
:class:`UHController` uses, for install scripts that warm the cache. numba invalidates a cached
kernel only when *its own* source file changes, so each kernel module empties its cache when a
file it compiles in changes (:func:`uh_core.kernel_cache.refresh_cache`): ``uh_core/layout.py``,
``gains.py`` and ``control_layout.py`` (the tables), and the kernel modules it calls (this one:
``loop_kernels.py`` and ``learning_kernels.py``). A kernel in another package that calls these
(the team kernel) lists all of them for the same reason.
"""
from __future__ import annotations

import math
import re
import time

import numpy as np

from uh_core import compiled_kernels as _compiled_kernels
from uh_core import kernel_cache as _kernel_cache
from uh_core import layout as _layout
from uh_core.compiled_kernels import njit
from uh_core.layout import (
    INPUT_SIZE,
    R_P,
    R_V,
    R_YAW,
    REFERENCE_SIZE,
    S_COST_RATE,
    S_EULER_D,
    S_F_HAT_P,
    S_F_HAT_W,
    S_SAT_COLLECTIVE,
    S_SAT_CYCLIC,
    S_SAT_TILT,
    S_THRUST,
    S_U_P,
    S_W_NORM_P,
    S_W_NORM_W,
    S_Z1,
    S_Z2,
    S_Z3,
    S_Z4,
    S_ZN_P,
    S_ZN_W,
    STATE_SIZE,
    STATUS_SIZE,
    STATUS_VECTORS,
    U_COL,
    U_LAT,
    U_LON,
    U_TR,
    X_OMEGA,
    X_P,
    X_THETA,
    X_V,
    YAW,
)

from . import control_layout as _control_layout
from . import gains as _gains
from . import learning_kernels as _learning_kernels
from . import loop_kernels as _loop_kernels
from . import safety_kernels as _safety_kernels
from .control_layout import (
    CONTROL_PARAMS_SIZE,
    FLAG_STARTED,
    FLAG_TIME,
    GAIN_ENTRIES,
    GAIN_INDEX,
    LOOP,
    LOOP_GAIN_ENTRIES,
    LOOP_GAIN_OFFSET,
    LOOP_GAINS_SIZE,
    M_ALPHA_F,
    M_ALPHA_WF,
    M_F_HAT_P,
    M_F_HAT_W,
    M_FLAGS,
    M_OMEGA_HAT,
    M_THETA_DF,
    M_V_HAT,
    MEMORY_ROWS,
    MODEL_ENTRIES,
    MODEL_INDEX,
    PARAM,
    STATUS,
    ControlArrays,
    control_parameters,
)
from .learning_kernels import (
    PROJECTION_TOLERANCE,
    composite_weight_update,
    estimator_advance,
    fault_observer_update,
    frobenius_norm,
    in_learning_phase,
    project_columns,
    rbf_activations,
    rbf_centre,
    rbf_output,
)
from .loop_kernels import (
    achieved_acceleration,
    control_effectiveness,
    euler_rate_inverse,
    euler_rate_transpose,
    filter_advance,
    filter_gain,
    filter_rate,
    inner_advance,
    inner_drift,
    inner_law,
    outer_advance,
    outer_law,
    thrust_and_attitude,
    wrap_angle,
)
from .safety_kernels import (
    PROXIMITY_COLUMNS,
    SAFETY_OUT_SIZE,
    SAFETY_PARAMS_SIZE,
    SO_ACTIVE,
    SO_CLOSEST_DISTANCE,
    SO_PAIRS,
    safety_filter,
)

__all__ = [
    'STATE_SIZE', 'INPUT_SIZE', 'X_P', 'X_V', 'X_THETA', 'X_OMEGA', 'YAW', 'U_COL', 'U_TR', 'U_LAT', 'U_LON',
    'CP_MASS', 'CP_GRAVITY', 'CP_J_X', 'CP_J_Y', 'CP_J_Z', 'CP_C_M1', 'CP_C_M2', 'CP_K_BETA', 'CP_H_M',
    'CP_B_LAT', 'CP_A_LON', 'CP_TAU_F', 'CP_K_TR', 'CP_D_R', 'CP_C_Q', 'CP_D_V', 'CP_LOWER', 'CP_UPPER',
    'CP_OUTER', 'CP_INNER', 'CONTROL_PARAMS_SIZE', 'LOOP_GAINS_SIZE', 'R_P', 'R_V', 'R_YAW', 'REFERENCE_SIZE',
    'M_ALPHA_F', 'M_V_HAT', 'M_F_HAT_P', 'M_THETA_DF', 'M_ALPHA_WF', 'M_OMEGA_HAT', 'M_F_HAT_W',
    'M_FLAGS', 'FLAG_STARTED', 'FLAG_TIME', 'MEMORY_ROWS', 'MODEL_ENTRIES', 'GAIN_ENTRIES', 'LOOP_GAIN_ENTRIES',
    'MODEL_INDEX', 'GAIN_INDEX', 'LOOP_GAIN_OFFSET', 'PARAM', 'LOOP', 'STATUS', 'GAIN_CONSTANTS',
    'S_Z1', 'S_Z2', 'S_Z3', 'S_Z4', 'S_F_HAT_P', 'S_F_HAT_W', 'S_ZN_P', 'S_ZN_W', 'S_U_P', 'S_EULER_D',
    'S_THRUST', 'S_W_NORM_P', 'S_W_NORM_W', 'S_SAT_TILT', 'S_SAT_COLLECTIVE', 'S_SAT_CYCLIC',
    'S_COST_RATE', 'STATUS_SIZE', 'STATUS_VECTORS', 'STEP_DONE', 'PROJECTION_TOLERANCE',
    'ControlArrays', 'control_parameters', 'wrap_angle', 'filter_gain', 'filter_rate', 'filter_advance',
    'rbf_centre', 'rbf_activations', 'rbf_output', 'project_columns', 'composite_weight_update',
    'fault_observer_update', 'in_learning_phase', 'estimator_advance', 'consensus_errors', 'outer_law',
    'thrust_and_attitude', 'achieved_acceleration', 'outer_advance', 'euler_rate_inverse', 'euler_rate_transpose',
    'inner_drift', 'control_effectiveness', 'inner_law', 'inner_advance', 'frobenius_norm',
    'first_non_finite_state', 'uh_control_step', 'compile_control_kernels',
]

# -- the indices of params as named constants, for Python callers (the kernels read PARAM and LOOP) ------
CP_MASS = PARAM.mass
CP_GRAVITY = PARAM.gravity
CP_J_X = PARAM.inertia
CP_J_Y = CP_J_X + 1
CP_J_Z = CP_J_X + 2
CP_C_M1 = PARAM.c_M1
CP_C_M2 = PARAM.c_M2
CP_K_BETA = PARAM.K_beta
CP_H_M = PARAM.h_M
CP_B_LAT = PARAM.B_lat
CP_A_LON = PARAM.A_lon
CP_TAU_F = PARAM.tau_f
CP_K_TR = PARAM.K_tr
CP_D_R = PARAM.D_r
CP_C_Q = PARAM.c_Q
CP_D_V = PARAM.D_v
CP_LOWER = PARAM.input_lower
CP_UPPER = PARAM.input_upper
CP_OUTER = PARAM.outer      # first entry of the outer loop's gains block
CP_INNER = PARAM.inner      # first entry of the inner loop's gains block


def _constant_name(slot: str) -> str:
    """Name a slot's constant after its prefix: ``'rbf.low'`` -> ``'RBF_LOW'``, ``'lambda_'`` -> ``'LAMBDA'``."""
    return re.sub(r'\W', '_', slot).strip('_').upper()


#: One constant per gain slot, named after it: ``CP_<GAIN>`` (its index in ``params``) for a gain of
#: the top level, ``L_<GAIN>`` (its offset in a loop's block) for a loop gain. Made from the gains'
#: registry, so a gain declared in ``gains.py`` has its constant without a line here.
GAIN_CONSTANTS = {**{'CP_' + _constant_name(slot): index for slot, index in GAIN_INDEX.items()},
                  **{'L_' + _constant_name(slot): offset for slot, offset in LOOP_GAIN_OFFSET.items()}}
globals().update(GAIN_CONSTANTS)
__all__ += list(GAIN_CONSTANTS)

#: Return value of :func:`uh_control_step` when the step was taken.
STEP_DONE = -1

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


# =============================================================================================
# Consensus errors (docs/graph.md)


@njit(cache=True)
def consensus_errors(own_state, offset, nb_states, nb_weights, nb_offsets, leader_link, reference,
                     feedforward_weight, z1, feedforward):
    """Consensus position error, velocity feed-forward, degree and yaw target of one UH.

    With ``h`` the formation offsets (leaders) or zero (followers)::

        leader i:    z1 = sum_{j in N_i} a_ij [(p_i - h_i) - (p_j - h_j)] + a_i0 [(p_i - h_i) - p_0]
        follower k:  z1 = sum_{j in N_k} a_kj (p_k - p_j)
        d = sum_j a_ij + a_i0 ,   feed-forward velocity f = w_f sum_j a_ij v_j + a_i0 v_0

    ``w_f`` (``feedforward_weight``) is 1 in the paper; below 1 it is the delay remedy of
    docs/delay.md#remedies (``w_f v_j`` is ``v_j`` to the bit when ``w_f`` is 1).

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
    feedforward_weight : float
        w_f, in (0, 1].
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
            feedforward[a] += w * (feedforward_weight * nb_states[n, X_V + a])
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
# One control step of one UH


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
def filtered_acceleration(safety, own_state, u_p, proximity, status):
    """Return the acceleration the attitude extraction realises: ``u_p``, or the safety filter's answer.

    The filter is a layer outside the law (docs/safety.md): with ``safety`` empty it is off and
    ``u_p`` itself is returned; otherwise :func:`~uh_controller_node.safety_kernels.safety_filter`
    runs on the UH's own position and velocity and its proximity input. Writes the status fields
    ``safety_active`` and ``closest_distance`` (NaN when the filter is off or reports no UH).
    """
    if safety.shape[0] == 0:
        status[STATUS.safety_active] = 0.0
        status[STATUS.closest_distance] = math.nan
        return u_p
    applied = np.empty(3)
    out = np.empty(SAFETY_OUT_SIZE)
    safety_filter(safety, own_state[X_P:X_P + 3], own_state[X_V:X_V + 3], u_p, proximity, applied, out)
    status[STATUS.safety_active] = out[SO_ACTIVE]
    status[STATUS.closest_distance] = out[SO_CLOSEST_DISTANCE] if out[SO_PAIRS] > 0 else math.nan
    return applied


@njit(cache=True)
def uh_control_step(params, own_state, nb_states, nb_weights, nb_offsets, offset, leader_link,
                    reference, dt, weights_p, weights_w, memory, u, status, safety, proximity):
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
    safety : ndarray (SAFETY_PARAMS_SIZE,) or (0,)
        The safety filter's parameters (:mod:`~uh_controller_node.safety_kernels`); empty: the filter
        is off and ``u_p`` goes to the attitude extraction as the law designed it.
    proximity : ndarray (n, PROXIMITY_COLUMNS)
        ``[p, v]`` of the UHs the proximity input reports (read only with the filter on).

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
    z1 = status[STATUS.z1:STATUS.z1 + 3]
    z2 = status[STATUS.z2:STATUS.z2 + 3]
    z3 = status[STATUS.z3:STATUS.z3 + 3]
    z4 = status[STATUS.z4:STATUS.z4 + 3]
    zn_p = status[STATUS.prediction_error_position:STATUS.prediction_error_position + 3]
    zn_w = status[STATUS.prediction_error_attitude:STATUS.prediction_error_attitude + 3]
    u_p = status[STATUS.u_p:STATUS.u_p + 3]
    euler_d = status[STATUS.euler_desired:STATUS.euler_desired + 3]
    # the estimates used at t_k, before the update
    status[STATUS.fault_estimate_position:STATUS.fault_estimate_position + 3] = memory[M_F_HAT_P]
    status[STATUS.fault_estimate_attitude:STATUS.fault_estimate_attitude + 3] = memory[M_F_HAT_W]

    degree, psi_d = consensus_errors(own_state, offset, nb_states, nb_weights, nb_offsets, leader_link,
                                     reference, params[PARAM.feedforward_weight], z1, work[_W_FEEDFORWARD])
    outer_law(params, degree, z1, work[_W_FEEDFORWARD], v, started, memory, weights_p, act_p,
              work[_W_ALPHA_V], work[_W_ALPHA_V_RATE], work[_W_NET_P], work[_W_DRIFT_P], z2, zn_p, u_p)
    applied = filtered_acceleration(safety, own_state, u_p, proximity, status)
    phi_d, theta_d, thrust, theta_col, thrust_achieved, sat_tilt, sat_col = \
        thrust_and_attitude(params, applied, psi_d)
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
    status[STATUS.thrust_command] = thrust
    status[STATUS.weight_norm_position] = frobenius_norm(weights_p)
    status[STATUS.weight_norm_attitude] = frobenius_norm(weights_w)
    status[STATUS.saturated_tilt] = 1.0 if sat_tilt else 0.0
    status[STATUS.saturated_collective] = 1.0 if sat_col else 0.0
    status[STATUS.saturated_cyclic] = 1.0 if sat_cyclic else 0.0
    cost = 0.0
    for a in range(3):
        cost += z1[a] * z1[a]
    effort = 0.0
    for a in range(3):
        effort += u_p[a] * u_p[a]
    status[STATUS.cost_rate] = cost + effort
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
    params[PARAM.input_lower:PARAM.input_lower + INPUT_SIZE] = -1.0
    no_neighbours = 0
    uh_control_step(params, np.zeros(STATE_SIZE), np.zeros((no_neighbours, STATE_SIZE)),
                    np.ones(no_neighbours), np.zeros((no_neighbours, 3)), np.zeros(3), 1.0,
                    np.zeros(REFERENCE_SIZE), 0.01, np.zeros((3, 3)), np.zeros((3, 3)),
                    np.zeros((MEMORY_ROWS, 3)), np.zeros(INPUT_SIZE), np.zeros(STATUS_SIZE),
                    np.ones(SAFETY_PARAMS_SIZE), np.zeros((1, PROXIMITY_COLUMNS)))
    return time.perf_counter() - start


# numba caches each kernel by this file only: empty the cache when a table or a kernel it compiles in changes
_kernel_cache.refresh_cache(_kernel_cache.module_dispatchers(globals()),
                            [_layout.__file__, _gains.__file__, _control_layout.__file__, _learning_kernels.__file__,
                             _loop_kernels.__file__, _safety_kernels.__file__])

# run the ahead-of-time compiled kernels instead where this process asks for them (docs/performance.md#memory)
_compiled_kernels.install(globals())
