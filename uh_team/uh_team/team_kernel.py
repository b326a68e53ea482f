"""The whole team's step loop as one native kernel, for the in-process reference simulation.

:func:`run_team_steps` runs steps ``k0 .. k1-1`` of :mod:`uh_team.team_simulation` in
numba: per step it records the states, calls :func:`~uh_controller_node.control_kernels.uh_control_step`
for every UH (neighbours in ascending id order), computes the true lumped faults
(:func:`~uh_sim_node.plant_kernels.lumped_faults`) and integrates every plant
(:func:`~uh_sim_node.plant_kernels.plant_step`). These are the very kernels
:class:`~uh_controller_node.controller.UHController` and :class:`~uh_sim_node.helicopter.HelicopterPlant`
call once per step in the distributed nodes, with the same arguments in the same order, so the
in-process run and a distributed run give bit-identical trajectories (no fastmath: IEEE double
arithmetic, whatever the inlining). Only the Python glue around them is gone, which is what made
the in-process run cost ~12 us per UH-step on top of ~5 us of arithmetic.

:func:`team_arrays` stacks the per-UH arrays of the controllers and plants
(``UHController.kernel_arrays()``, ``HelicopterPlant.kernel_arrays()``; neighbour lists padded to
the largest in-degree) into a :class:`TeamArrays` of three groups, each a namedtuple of arrays that
numba passes as one argument: :class:`TeamConfig` (what the run does not change),
:class:`TeamImpairments` (what the links do to the received states) and :class:`TeamState` (what the
steps update in place). The steps write a :class:`TeamRecord` (:func:`empty_record`). A new per-UH
array is one field of its group, filled in :func:`team_arrays` and read in :func:`run_team_steps`.

numba re-validates a cached kernel against its own source file only, so a cached
:func:`run_team_steps` would keep an old control law, model or layout after one of the law's kernel
modules, ``plant_kernels.py``, ``faults.py`` or ``uh_core/layout.py`` changed. :func:`refresh_cache` (run on
import, through :func:`uh_core.kernel_cache.refresh_cache`) keeps a digest of those files next to
the cache and empties this kernel's cache index when they differ.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numba import njit

from uh_controller_node import control_kernels as _ctl
from uh_controller_node import control_layout as _control_layout
from uh_controller_node import gains as _gains
from uh_controller_node import impairments as _impairments
from uh_controller_node import learning_kernels as _learning_kernels
from uh_controller_node import loop_kernels as _loop_kernels
from uh_controller_node import safety_kernels as _safety_kernels
from uh_controller_node.control_kernels import INPUT_SIZE, STATE_SIZE, STATUS, STATUS_SIZE, STEP_DONE, uh_control_step
from uh_controller_node.impairments import (
    add_noise,
    add_reference_motion,
    delivered_step,
    predict_state,
    prediction_age,
)
from uh_controller_node.safety_kernels import (
    PROXIMITY_COLUMNS,
    SF_PROXIMITY_DELAY,
    SF_PROXIMITY_NOISE_P,
    SF_PROXIMITY_NOISE_V,
    SF_SENSING_RADIUS,
    degrade_proximity,
    proximity_lost,
    proximity_rows,
)
from uh_core import compiled_kernels as _compiled_kernels
from uh_core import kernel_cache as _kernel_cache
from uh_core import layout as _layout
from uh_core.layout import X_P, X_V
from uh_sim_node import faults as _faults
from uh_sim_node import plant_kernels as _plant
from uh_sim_node.plant_kernels import lumped_faults, plant_step
from uh_topology import losses as _losses
from uh_topology.impairments import PREDICTING

# this loop calls the kernels from numba code: a process running them compiled cannot import it
_compiled_kernels.require_numba('uh_team.team_kernel')

#: :func:`uh_topology.losses.failsafe_step` compiled into the loop (one home for the simulator node and the kernel)
failsafe_step = njit(cache=True, inline='always')(_losses.failsafe_step)

__all__ = ['TeamConfig', 'TeamImpairments', 'TeamState', 'TeamRecord', 'TeamArrays', 'team_arrays',
           'empty_record', 'run_team_steps', 'record_states', 'impaired_states', 'record_status', 'advance_plants',
           'freeze_row',
           'refresh_cache', 'compile_team_kernel', 'TEAM_DONE']

#: :func:`run_team_steps` returns this when every step ran; otherwise the step at which a state
#: was found non-finite (its row of ``states`` is recorded, nothing after it).
TEAM_DONE = -1


class TeamConfig(NamedTuple):
    """What a team run does not change: its graph, gains, offsets, airframes, faults, disturbances.

    Stacked per UH of a team of ``n`` UHs (UH axis in the order of ``ids``); neighbour lists are
    padded to the largest in-degree ``max_nb``.

    Attributes
    ----------
    hears : ndarray (n, max_nb) int64
        Rows (UH indices) of the neighbours of each UH, ascending id; padding unused.
    count : ndarray (n,) int64
        In-degrees (neighbours heard).
    links : ndarray (n,)
        a_i0 (0 for a UH that does not hear the virtual leader).
    control_params, offsets, nb_weights, nb_offsets : ndarray
        (n, CONTROL_PARAMS_SIZE), (n, 3) m, (n, max_nb), (n, max_nb, 3) m.
    plant_params, faults, disturbance : ndarray
        (n, PARAMS_SIZE), (n, NUM_CHANNELS, FAULT_FIELDS), (n, 3, DISTURBANCE_FIELDS).
    substeps : int
        RK4 substeps per control period (one value for the team).
    ids : ndarray (n,) int64
        UH ids of the rows.
    safety : ndarray (n, SAFETY_PARAMS_SIZE) or (n, 0)
        The safety filter's parameters per UH (docs/safety.md); no columns: the filter is off.
    frozen : ndarray (n,) bool
        A lost UH (docs/resilience.md): its controller does not run (its last command is repeated in
        the record) and its plant flies its failsafe instead of the dynamics: it brakes at
        ``brake_accel`` to a hover (:func:`uh_topology.losses.failsafe_step`).
    brake_accel : float
        The failsafe's deceleration, m/s^2 (``safety.brake_accel``).
    holding : ndarray (n,) bool
        The UH holds a position: its controller follows ``hold`` instead of the virtual leader.
    hold : ndarray (n, REFERENCE_SIZE)
        ``[p_hold, 0, yaw]`` per UH (read where ``holding``, whose row has offset zero): the pseudo virtual
        leader of a hold (:func:`uh_topology.losses.hold_reference`).
    """

    hears: np.ndarray
    count: np.ndarray
    links: np.ndarray
    control_params: np.ndarray
    offsets: np.ndarray
    nb_weights: np.ndarray
    nb_offsets: np.ndarray
    plant_params: np.ndarray
    faults: np.ndarray
    disturbance: np.ndarray
    substeps: int
    ids: np.ndarray
    safety: np.ndarray
    frozen: np.ndarray
    holding: np.ndarray
    hold: np.ndarray
    brake_accel: float


class TeamImpairments(NamedTuple):
    """What the team's links do to the states a controller receives (docs/campaigns.md#impairments).

    Attributes
    ----------
    impaired : bool
        Whether the scenario has impairments; when False the fields below are not read.
    seed : int
    delay, jitter, loss : ndarray (n, max_nb) int64, (n, max_nb) int64, (n, max_nb)
        Per link (row, neighbour slot): delay and largest extra delay in steps, loss probability.
    drop_step : ndarray (n,) int64
        Per sender row: first step whose state no other UH receives.
    noise : ndarray (12,)
        Standard deviation of the noise on every received state, per component.
    predict : bool
        Whether the controllers predict each received state to the current step (docs/delay.md).
    reference_motion : bool
        Whether they also add the virtual leader's motion over the age (``delay_compensation:
        reference_motion``, docs/delay.md#remedies).
    """

    impaired: bool
    seed: int
    delay: np.ndarray
    loss: np.ndarray
    drop_step: np.ndarray
    noise: np.ndarray
    jitter: np.ndarray
    predict: bool
    reference_motion: bool


class TeamState(NamedTuple):
    """What the team's steps update in place: the plants' states and the controllers' internal states.

    Attributes
    ----------
    x : ndarray (n, 12)
        Plant states.
    weights_p, weights_w, memory : ndarray
        (n, mu_p, 3), (n, mu_w, 3), (n, MEMORY_ROWS, 3).
    """

    x: np.ndarray
    weights_p: np.ndarray
    weights_w: np.ndarray
    memory: np.ndarray


class TeamRecord(NamedTuple):
    """What the team's steps write, one row per step (the arrays of :class:`~uh_team.team_simulation.TeamRun`).

    Attributes
    ----------
    states : ndarray (K+1, n, 12)
    commands : ndarray (K+1, n, 4)
    fault_true_p, fault_true_w, fault_est_p, fault_est_w, u_p, z1 : ndarray (K+1, n, 3)
    saturated : ndarray (K+1, n) bool
    safety_active : ndarray (K+1, n) bool
        The safety filter changed the UH's ``u_p`` at that step.
    """

    states: np.ndarray
    commands: np.ndarray
    fault_true_p: np.ndarray
    fault_true_w: np.ndarray
    fault_est_p: np.ndarray
    fault_est_w: np.ndarray
    u_p: np.ndarray
    z1: np.ndarray
    saturated: np.ndarray
    safety_active: np.ndarray


class TeamArrays(NamedTuple):
    """Stacked per-UH arrays of a team: its configuration, its impairments and its mutable state."""

    config: TeamConfig
    impairments: TeamImpairments
    state: TeamState


def team_arrays(ids, controllers, plants, impairments=None, dt: float | None = None) -> TeamArrays:
    """Stack the kernel arrays of ``controllers`` and ``plants`` (both in the order of ``ids``).

    The scenario's ``impairments`` (an ``ImpairmentSpec`` or None) apply on control period ``dt``.

    Raises
    ------
    ValueError
        Plants with different substeps.
    """
    n = len(ids)
    row = {int(i): c for c, i in enumerate(ids)}
    ctl = [c.kernel_arrays() for c in controllers]
    plant = [p.kernel_arrays() for p in plants]
    substeps = {p.substeps for p in plant}
    if len(substeps) != 1:
        raise ValueError(f'team kernel: every plant needs the same RK4 substeps, got {sorted(substeps)}')
    max_nb = max([len(c.neighbours) for c in controllers] + [1])
    hears = np.zeros((n, max_nb), dtype=np.int64)
    count = np.zeros(n, dtype=np.int64)
    nb_weights = np.zeros((n, max_nb))
    nb_offsets = np.zeros((n, max_nb, 3))
    for c, (controller, arrays) in enumerate(zip(controllers, ctl, strict=True)):
        m = len(controller.neighbours)
        count[c] = m
        hears[c, :m] = [row[int(j)] for j in controller.neighbours]
        nb_weights[c, :m] = arrays.neighbour_weights
        nb_offsets[c, :m] = arrays.neighbour_offsets
    config = TeamConfig(
        hears=hears, count=count, links=np.array([a.leader_link for a in ctl], dtype=float),
        control_params=np.stack([a.params for a in ctl]), offsets=np.stack([a.offset for a in ctl]),
        nb_weights=nb_weights, nb_offsets=nb_offsets, plant_params=np.stack([p.params for p in plant]),
        faults=np.stack([p.faults for p in plant]), disturbance=np.stack([p.disturbance for p in plant]),
        substeps=substeps.pop(), ids=np.array([int(i) for i in ids], dtype=np.int64),
        safety=np.stack([a.safety for a in ctl]), frozen=np.zeros(n, dtype=np.bool_),
        holding=np.zeros(n, dtype=np.bool_), hold=np.zeros((n, _ctl.REFERENCE_SIZE)), brake_accel=0.0)
    state = TeamState(x=np.stack([p.x for p in plants]), weights_p=np.stack([a.weights_p for a in ctl]),
                      weights_w=np.stack([a.weights_w for a in ctl]), memory=np.stack([a.memory for a in ctl]))
    return TeamArrays(config, _team_impairments(ids, controllers, impairments, dt, max_nb), state)


def _team_impairments(ids, controllers, impairments, dt, max_nb) -> TeamImpairments:
    """Build the per-link impairments of the team (all zero, ``impaired`` False, when ``impairments`` is None)."""
    n = len(ids)
    delay = np.zeros((n, max_nb), dtype=np.int64)
    jitter = np.zeros((n, max_nb), dtype=np.int64)
    loss = np.zeros((n, max_nb))
    drop_step = np.zeros(n, dtype=np.int64)
    noise = np.zeros(STATE_SIZE)
    if impairments is None:
        return TeamImpairments(False, 0, delay, loss, drop_step, noise, jitter, False, False)
    if dt is None:
        raise ValueError('team kernel: impairments need the control period dt (for the dropout steps)')
    for c, controller in enumerate(controllers):
        i = int(ids[c])
        drop_step[c] = impairments.drop_step(i, dt)
        for slot, j in enumerate(controller.neighbours):
            delay[c, slot] = impairments.delays[(i, int(j))]
            jitter[c, slot] = impairments.jitters[(i, int(j))]
            loss[c, slot] = impairments.losses[(i, int(j))]
    noise[:] = impairments.noise
    return TeamImpairments(True, int(impairments.seed), delay, loss, drop_step, noise, jitter,
                           impairments.compensation in PREDICTING,
                           impairments.compensation == 'reference_motion')


@njit(cache=True)
def run_team_steps(k0, k1, last, dt, references, team, links_impaired, live, record):
    """Run steps ``k0 .. k1-1`` of the team (see :mod:`uh_team.team_simulation` for the order).

    Parameters
    ----------
    k0, k1 : int
        First step and one past the last step to run.
    last : int
        K, the last step of the run: at ``k == last`` the controllers run but the plants are not
        integrated (that command is not applied).
    dt : float
        Control period, s.
    references : ndarray (K+1, 7)
        Virtual leader ``[p_0 m, v_0 m/s, psi_0 rad]`` at every step.
    team : TeamConfig
    links_impaired : TeamImpairments
        With ``impaired``, every controller receives its own and its neighbours' states as
        :mod:`uh_controller_node.impairments` defines (neighbours' from ``record.states``, the
        recorded history).
    live : TeamState
        Updated in place.
    record : TeamRecord
        Written for the steps run.

    Returns
    -------
    int
        :data:`TEAM_DONE`, or the step at which a state was not finite (its states are recorded).
    """
    hears, count, links, ids = team.hears, team.count, team.links, team.ids
    control_params, offsets, nb_weights, nb_offsets = team.control_params, team.offsets, team.nb_weights, \
        team.nb_offsets
    x, weights_p, weights_w, memory = live.x, live.weights_p, live.weights_w, live.memory
    states, commands = record.states, record.commands
    n = x.shape[0]
    safety = team.safety
    filtered = safety.shape[1] > 0
    proximity = np.empty((max(n - 1, 1), PROXIMITY_COLUMNS))
    senders = np.empty(max(n - 1, 1), dtype=np.int64)
    sender_ids = np.empty(max(n - 1, 1), dtype=np.int64)
    sensed = 0
    status = np.empty(STATUS_SIZE)
    own = np.empty(STATE_SIZE)
    sent = np.empty(STATE_SIZE)
    u = np.empty(INPUT_SIZE)
    out_p = np.empty(3)
    out_w = np.empty(3)
    frozen, holding = team.frozen, team.holding
    for k in range(k0, k1):
        if not record_states(k, x, states):
            return k
        # 1. every controller on the states at t_k (its own and its neighbours', ascending id)
        for c in range(n):
            if frozen[c]:   # lost: nothing runs (docs/resilience.md)
                freeze_row(k, c, commands, record.fault_est_p, record.fault_est_w, record.u_p, record.z1,
                           record.saturated, record.safety_active)
                continue
            reference = team.hold[c] if holding[c] else references[k]
            m = count[c]
            nb = np.empty((m, STATE_SIZE))
            received = x[c]   # the own state as the controller receives it
            if links_impaired.impaired:
                received = impaired_states(k, c, dt, x, states, hears[c], ids, links_impaired, own, sent, nb,
                                           references)
            else:
                for j in range(m):
                    nb[j] = x[hears[c, j]]
            if filtered:    # the plant side's sensing: the true states at t_k (docs/safety.md)
                sensed = sense_proximity(k, c, dt, states, ids, safety[c], proximity, senders, sender_ids)
            done = uh_control_step(control_params[c], received, nb, nb_weights[c, :m], nb_offsets[c, :m],
                                   offsets[c], links[c], reference, dt, weights_p[c], weights_w[c],
                                   memory[c], commands[k, c], status, safety[c], proximity[:sensed])
            if done != STEP_DONE:
                return k
            record_status(k, c, status, record.fault_est_p, record.fault_est_w, record.u_p, record.z1,
                          record.saturated, record.safety_active)
        # 2. the true lumped faults for that command; 3. every plant holds it over [t_k, t_k+1)
        advance_plants(k, last, dt, x, commands, team.plant_params, team.faults, team.disturbance, team.substeps,
                       record.fault_true_p, record.fault_true_w, u, out_p, out_w, frozen, team.brake_accel)
    return TEAM_DONE


@njit(cache=True)
def sense_proximity(k, c, dt, states, ids, params, proximity, senders, sender_ids):
    """Write row ``c``'s proximity input of step ``k`` into ``proximity``; return its rows.

    The report of the true states at the newest step ``s <= k - proximity_delay_steps`` that was
    not lost (``states``: the recorded states, step k included), degraded and predicted to step k
    with the kernels the controllers use (docs/safety.md#degraded-sensing); the true states at t_k
    without degraded sensing.
    """
    s = k - int(params[SF_PROXIMITY_DELAY])
    while s > 0 and proximity_lost(params, ids[c], s):
        s -= 1
    if s < 0:
        return 0
    xs = states[s]
    sensed = proximity_rows(xs[:, X_P:X_P + 3], xs[:, X_V:X_V + 3], c, params[SF_SENSING_RADIUS], proximity, senders)
    if s < k or params[SF_PROXIMITY_NOISE_P] > 0.0 or params[SF_PROXIMITY_NOISE_V] > 0.0:
        for r in range(sensed):
            sender_ids[r] = ids[senders[r]]
        degrade_proximity(proximity, sensed, sender_ids, ids[c], s, k, dt, params)
    return sensed


# The parts of a step of run_team_steps. Inlined into it (numba's inline='always': the same
# operations in the same order, without a call per UH and step, which cost 3-5 % of the loop); they
# take arrays, not the groups, so that no group is taken apart again per call. The kernel modules
# compiled ahead of time (uh_core.compiled_kernels) do not use inline='always': with an inlined
# kernel among them, numba.pycc's type inference failed on another kernel of the build.


@njit(cache=True, inline='always')
def record_states(k, x, states):
    """Copy the plants' states ``x`` (n, 12) to row ``k`` of ``states``; return whether they are all finite."""
    finite = True
    for c in range(x.shape[0]):
        for i in range(STATE_SIZE):
            v = x[c, i]
            states[k, c, i] = v
            if not np.isfinite(v):
                finite = False
    return finite


@njit(cache=True, inline='always')
def impaired_states(k, c, dt, x, states, hears, ids, links_impaired, own, sent, nb, references):
    """Return the own state row ``c``'s controller receives at step ``k`` through impaired links; write its neighbours'.

    As :mod:`uh_controller_node.impairments` defines: the own state and each neighbour's state
    noisy, a neighbour's the one it sent at the step its link delivers (from ``states``, the
    recorded history), predicted to step ``k`` when the controllers predict (as ``ReceivedStates`` does).

    Parameters
    ----------
    k, c : int
        Step and the receiving UH's row.
    dt : float
        Control period, s.
    x, states : ndarray (n, 12), (K+1, n, 12)
        The plants' states now and the recorded ones.
    hears, ids : ndarray (max_nb,), (n,) int64
        The rows heard by UH ``c``, and the UH ids of the rows.
    links_impaired : TeamImpairments
    own, sent : ndarray (12,)
        Scratch: the noisy own state (returned), a neighbour's state before its prediction.
    nb : ndarray (n_nb, 12)
        Output: the neighbours' states received, in the order of ``hears``.
    references : ndarray (K+1, 7)
        The virtual leader's ``[p_0, v_0, psi_0]`` per step (read with ``reference_motion``).
    """
    seed, noise = links_impaired.seed, links_impaired.noise
    add_noise(x[c], noise, seed, ids[c], ids[c], k, own)
    for j in range(nb.shape[0]):
        r = hears[j]
        delay, jitter = links_impaired.delay[c, j], links_impaired.jitter[c, j]
        s = delivered_step(k, delay, jitter, links_impaired.loss[c, j], links_impaired.drop_step[r], seed,
                           ids[c], ids[r])
        if links_impaired.predict and s < k:   # the state sent at s, predicted to k
            add_noise(states[s, r], noise, seed, ids[c], ids[r], s, sent)
            age = prediction_age(k, s, delay, jitter, dt)
            predict_state(sent, age, dt, nb[j])
            if links_impaired.reference_motion:
                add_reference_motion(references[s], references[s + age], age * dt, nb[j])
        else:
            add_noise(states[s, r], noise, seed, ids[c], ids[r], s, nb[j])
    return own


@njit(cache=True, inline='always')
def record_status(k, c, status, fault_est_p, fault_est_w, u_p, z1, saturated, safety_active):
    """Write what the record keeps of row ``c``'s status at step ``k``: Fhat_p, Fhat_w, u_p, z1, saturation, safety."""
    for i in range(3):
        fault_est_p[k, c, i] = status[STATUS.fault_estimate_position + i]
        fault_est_w[k, c, i] = status[STATUS.fault_estimate_attitude + i]
        u_p[k, c, i] = status[STATUS.u_p + i]
        z1[k, c, i] = status[STATUS.z1 + i]
    saturated[k, c] = (status[STATUS.saturated_tilt] != 0.0 or status[STATUS.saturated_collective] != 0.0
                       or status[STATUS.saturated_cyclic] != 0.0)
    safety_active[k, c] = status[STATUS.safety_active] != 0.0


@njit(cache=True, inline='always')
def freeze_row(k, c, commands, fault_est_p, fault_est_w, u_p, z1, saturated, safety_active):
    """Write row ``c`` of step ``k`` for a lost UH: its previous command (zero at step 0), zero estimates, no flags."""
    for i in range(commands.shape[2]):
        commands[k, c, i] = commands[k - 1, c, i] if k > 0 else 0.0
    for i in range(3):
        fault_est_p[k, c, i] = 0.0
        fault_est_w[k, c, i] = 0.0
        u_p[k, c, i] = 0.0
        z1[k, c, i] = 0.0
    saturated[k, c] = False
    safety_active[k, c] = False


@njit(cache=True, inline='always')
def advance_plants(k, last, dt, x, commands, plant_params, faults, disturbance, substeps, fault_true_p, fault_true_w,
                   u, out_p, out_w, frozen, brake_accel):
    """Record the true lumped faults of step ``k``'s commands and, unless ``k == last``, integrate every plant.

    Each plant holds its command ``commands[k, c]`` over [t_k, t_k+1) (RK4, ``substeps`` substeps;
    ``plant_params``, ``faults``, ``disturbance`` per row as in :class:`TeamConfig`). ``u`` (4,),
    ``out_p``, ``out_w`` (3,): scratch for the command and the faults' parts. A ``frozen`` row (lost)
    flies its failsafe (:func:`failsafe_step`, ``brake_accel`` m/s^2) and its true faults are zero.
    """
    t = k * dt
    for c in range(x.shape[0]):
        if frozen[c]:
            for i in range(3):
                fault_true_p[k, c, i] = 0.0
                fault_true_w[k, c, i] = 0.0
            if k < last:
                failsafe_step(x[c], dt, brake_accel)
            continue
        for i in range(4):
            u[i] = commands[k, c, i]
        lumped_faults(x[c], u, t, plant_params[c], faults[c], out_p, out_w)
        for i in range(3):
            fault_true_p[k, c, i] = out_p[i]
            fault_true_w[k, c, i] = out_w[i]
        if k < last:
            plant_step(x[c], u, t, dt, substeps, plant_params[c], faults[c], disturbance[c])


#: Files whose contents are compiled into :func:`run_team_steps` besides this one.
_DEPENDENCIES = (Path(_ctl.__file__), Path(_loop_kernels.__file__), Path(_learning_kernels.__file__),
                 Path(_control_layout.__file__), Path(_gains.__file__), Path(_plant.__file__), Path(_faults.__file__),
                 Path(_layout.__file__), Path(_impairments.__file__), Path(_safety_kernels.__file__),
                 Path(_losses.__file__))


def refresh_cache() -> bool:
    """Empty the numba cache index of this file's kernels if the files they depend on changed since they were cached.

    Those files are :data:`_DEPENDENCIES`: the law's kernel modules (``control_kernels.py``,
    ``loop_kernels.py``, ``learning_kernels.py``), ``control_layout.py`` and ``gains.py`` (the layout of
    its arrays, the gains' slots), ``plant_kernels.py``, ``faults.py``, ``uh_core/layout.py``,
    ``impairments.py``, ``safety_kernels.py``, ``uh_topology/losses.py``; the digest is kept next to the cache in
    ``team_kernel.dependencies.sha256``. Returns True when the cache was emptied
    (:func:`uh_core.kernel_cache.refresh_cache`).
    """
    return _kernel_cache.refresh_cache(_kernel_cache.module_dispatchers(globals()), _DEPENDENCIES,
                                       'team_kernel.dependencies.sha256')


refresh_cache()


def compile_team_kernel() -> float:
    """Compile :func:`run_team_steps` for the signature :mod:`.team_simulation` uses.

    Fills numba's on-disk cache; returns the seconds spent.
    """
    start = time.perf_counter()
    n, steps, max_nb = 1, 1, 1
    params = np.ones((n, _ctl.CONTROL_PARAMS_SIZE))
    params[:, _ctl.CP_LOWER:_ctl.CP_LOWER + 4] = -1.0
    team = TeamConfig(
        hears=np.zeros((n, max_nb), dtype=np.int64), count=np.zeros(n, dtype=np.int64), links=np.ones(n),
        control_params=params, offsets=np.zeros((n, 3)), nb_weights=np.zeros((n, max_nb)),
        nb_offsets=np.zeros((n, max_nb, 3)), plant_params=np.ones((n, _plant.PARAMS_SIZE)),
        faults=np.zeros((n, _plant.NUM_CHANNELS, _plant.FAULT_FIELDS)),
        disturbance=np.zeros((n, 3, _plant.DISTURBANCE_FIELDS)), substeps=1, ids=np.ones(n, dtype=np.int64),
        safety=np.zeros((n, 0)), frozen=np.zeros(n, dtype=np.bool_), holding=np.zeros(n, dtype=np.bool_),
        hold=np.zeros((n, _ctl.REFERENCE_SIZE)), brake_accel=0.0)
    links_impaired = TeamImpairments(False, 0, np.zeros((n, max_nb), dtype=np.int64), np.zeros((n, max_nb)),
                                     np.zeros(n, dtype=np.int64), np.zeros(STATE_SIZE),
                                     np.zeros((n, max_nb), dtype=np.int64), False, False)
    live = TeamState(np.zeros((n, STATE_SIZE)), np.zeros((n, 3, 3)), np.zeros((n, 3, 3)),
                     np.zeros((n, _ctl.MEMORY_ROWS, 3)))
    run_team_steps(0, 0, 0, 0.01, np.zeros((steps, _ctl.REFERENCE_SIZE)), team, links_impaired, live,
                   empty_record(steps, n))
    return time.perf_counter() - start


def empty_record(rows: int, n: int) -> TeamRecord:
    """Make a :class:`TeamRecord` of ``rows`` steps of ``n`` UHs, uninitialised (the flags all False)."""
    return TeamRecord(states=np.empty((rows, n, STATE_SIZE)), commands=np.empty((rows, n, INPUT_SIZE)),
                      **{name: np.empty((rows, n, 3)) for name in ('fault_true_p', 'fault_true_w', 'fault_est_p',
                                                                    'fault_est_w', 'u_p', 'z1')},
                      saturated=np.zeros((rows, n), dtype=np.bool_), safety_active=np.zeros((rows, n), dtype=np.bool_))
