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

:class:`TeamArrays` stacks the per-UH arrays of the controllers and plants
(``UHController.kernel_arrays()``, ``HelicopterPlant.kernel_arrays()``); neighbour lists are
padded to the largest in-degree.

numba re-validates a cached kernel against its own source file only, so a cached
:func:`run_team_steps` would keep an old control law, model or layout after ``control_kernels.py``,
``plant_kernels.py``, ``faults.py`` or ``uh_core/layout.py`` changed. :func:`refresh_cache` (run on
import, through :func:`uh_core.kernel_cache.refresh_cache`) keeps a digest of those files next to
the cache and empties this kernel's cache index when they differ.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numba import njit

from uh_core import kernel_cache as _kernel_cache
from uh_core import layout as _layout
from uh_sim_node import faults as _faults
from uh_sim_node import plant_kernels as _plant
from uh_sim_node.plant_kernels import lumped_faults, plant_step

from uh_controller_node import control_kernels as _ctl
from uh_controller_node import impairments as _impairments
from uh_controller_node.impairments import add_noise, delivered_step
from uh_controller_node.control_kernels import (
    S_F_HAT_P, S_F_HAT_W, S_SAT_COLLECTIVE, S_SAT_CYCLIC, S_SAT_TILT, S_U_P, S_Z1, STATE_SIZE,
    STATUS_SIZE, STEP_DONE, uh_control_step,
)

__all__ = ['TeamArrays', 'team_arrays', 'run_team_steps', 'refresh_cache', 'compile_team_kernel',
           'TEAM_DONE']

#: :func:`run_team_steps` returns this when every step ran; otherwise the step at which a state
#: was found non-finite (its row of ``states`` is recorded, nothing after it).
TEAM_DONE = -1


class TeamArrays(NamedTuple):
    """Stacked per-UH arrays of a team of ``n`` UHs (UH axis in the order of ``ids``).

    Attributes
    ----------
    x : ndarray (n, 12)
        Plant states, updated in place.
    hears : ndarray (n, max_nb) int64
        Rows (UH indices) of the neighbours of each UH, ascending id; padding unused.
    count : ndarray (n,) int64
        In-degrees (neighbours heard).
    links : ndarray (n,)
        a_i0 (0 for a UH that does not hear the virtual leader).
    control_params, offsets, nb_weights, nb_offsets : ndarray
        (n, CONTROL_PARAMS_SIZE), (n, 3), (n, max_nb), (n, max_nb, 3).
    weights_p, weights_w, memory : ndarray
        (n, mu_p, 3), (n, mu_w, 3), (n, MEMORY_ROWS, 3): controller state, updated in place.
    plant_params, faults, disturbance : ndarray
        (n, PARAMS_SIZE), (n, NUM_CHANNELS, FAULT_FIELDS), (n, 3, DISTURBANCE_FIELDS).
    substeps : int
        RK4 substeps per control period (one value for the team).
    ids : ndarray (n,) int64
        UH ids of the rows.
    impaired : bool
        Whether the scenario has impairments (docs/campaigns.md#impairments); when False the
        fields below are not read.
    impairment_seed : int
    delay, loss : ndarray (n, max_nb) int64, (n, max_nb)
        Per link (row, neighbour slot): delay in steps, loss probability.
    drop_step : ndarray (n,) int64
        Per sender row: first step whose state no other UH receives.
    noise : ndarray (12,)
        Standard deviation of the noise on every received state, per component.
    """

    x: np.ndarray
    hears: np.ndarray
    count: np.ndarray
    links: np.ndarray
    control_params: np.ndarray
    offsets: np.ndarray
    nb_weights: np.ndarray
    nb_offsets: np.ndarray
    weights_p: np.ndarray
    weights_w: np.ndarray
    memory: np.ndarray
    plant_params: np.ndarray
    faults: np.ndarray
    disturbance: np.ndarray
    substeps: int
    ids: np.ndarray
    impaired: bool
    impairment_seed: int
    delay: np.ndarray
    loss: np.ndarray
    drop_step: np.ndarray
    noise: np.ndarray


def team_arrays(ids, controllers, plants, impairments=None, dt: float | None = None) -> TeamArrays:
    """Stack the kernel arrays of ``controllers`` and ``plants`` (both in the order of ``ids``),
    with the scenario's ``impairments`` (an ``ImpairmentSpec`` or None) on control period ``dt``.

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
    for c, (controller, arrays) in enumerate(zip(controllers, ctl)):
        m = len(controller.neighbours)
        count[c] = m
        hears[c, :m] = [row[int(j)] for j in controller.neighbours]
        nb_weights[c, :m] = arrays.neighbour_weights
        nb_offsets[c, :m] = arrays.neighbour_offsets
    delay = np.zeros((n, max_nb), dtype=np.int64)
    loss = np.zeros((n, max_nb))
    drop_step = np.zeros(n, dtype=np.int64)
    noise = np.zeros(STATE_SIZE)
    if impairments is not None:
        if dt is None:
            raise ValueError('team kernel: impairments need the control period dt (for the dropout steps)')
        for c, controller in enumerate(controllers):
            i = int(ids[c])
            drop_step[c] = impairments.drop_step(i, dt)
            for slot, j in enumerate(controller.neighbours):
                delay[c, slot] = impairments.delays[(i, int(j))]
                loss[c, slot] = impairments.losses[(i, int(j))]
        noise[:] = impairments.noise
    return TeamArrays(
        x=np.stack([p.x for p in plants]), hears=hears, count=count,
        links=np.array([a.leader_link for a in ctl], dtype=float),
        control_params=np.stack([a.params for a in ctl]), offsets=np.stack([a.offset for a in ctl]),
        nb_weights=nb_weights, nb_offsets=nb_offsets,
        weights_p=np.stack([a.weights_p for a in ctl]), weights_w=np.stack([a.weights_w for a in ctl]),
        memory=np.stack([a.memory for a in ctl]),
        plant_params=np.stack([p.params for p in plant]), faults=np.stack([p.faults for p in plant]),
        disturbance=np.stack([p.disturbance for p in plant]), substeps=substeps.pop(),
        ids=np.array([int(i) for i in ids], dtype=np.int64), impaired=impairments is not None,
        impairment_seed=int(impairments.seed) if impairments is not None else 0,
        delay=delay, loss=loss, drop_step=drop_step, noise=noise)


@njit(cache=True)
def run_team_steps(k0, k1, last, dt, references, x, hears, count, links, control_params, offsets,
                   nb_weights, nb_offsets, weights_p, weights_w, memory, plant_params, faults,
                   disturbance, substeps, ids, impaired, impairment_seed, delay, loss, drop_step, noise,
                   states, commands, fault_true_p, fault_true_w, fault_est_p, fault_est_w, u_p, z1,
                   saturated):
    """Steps ``k0 .. k1-1`` of the team (see :mod:`uh_team.team_simulation` for the order).

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
    x ... noise
        The :class:`TeamArrays` fields; ``x``, ``weights_p``, ``weights_w`` and ``memory`` are
        updated in place. With ``impaired``, every controller receives its own and its neighbours'
        states as :mod:`uh_controller_node.impairments` defines (neighbours' from ``states``, the
        recorded history).
    states ... saturated
        Output rows of :class:`~uh_team.team_simulation.TeamRun`, written for the steps run:
        (K+1, n, 12), (K+1, n, 4), five (K+1, n, 3) and (K+1, n) bool.

    Returns
    -------
    int
        :data:`TEAM_DONE`, or the step at which a state was not finite (its states are recorded).
    """
    n = x.shape[0]
    u = np.empty(4)
    status = np.empty(STATUS_SIZE)
    out_p = np.empty(3)
    out_w = np.empty(3)
    own = np.empty(STATE_SIZE)
    for k in range(k0, k1):
        t = k * dt
        finite = True
        for c in range(n):
            for i in range(STATE_SIZE):
                v = x[c, i]
                states[k, c, i] = v
                if not np.isfinite(v):
                    finite = False
        if not finite:
            return k
        reference = references[k]
        # 1. every controller on the states at t_k (its own and its neighbours', ascending id)
        for c in range(n):
            m = count[c]
            nb = np.empty((m, STATE_SIZE))
            received = x[c]   # the own state as the controller receives it
            if impaired:
                add_noise(x[c], noise, impairment_seed, ids[c], ids[c], k, own)
                received = own
                for j in range(m):
                    r = hears[c, j]
                    s = delivered_step(k, delay[c, j], loss[c, j], drop_step[r], impairment_seed, ids[c], ids[r])
                    add_noise(states[s, r], noise, impairment_seed, ids[c], ids[r], s, nb[j])
            else:
                for j in range(m):
                    nb[j] = x[hears[c, j]]
            done = uh_control_step(control_params[c], received, nb, nb_weights[c, :m], nb_offsets[c, :m],
                                   offsets[c], links[c], reference, dt, weights_p[c], weights_w[c],
                                   memory[c], commands[k, c], status)
            if done != STEP_DONE:
                return k
            for i in range(3):
                fault_est_p[k, c, i] = status[S_F_HAT_P + i]
                fault_est_w[k, c, i] = status[S_F_HAT_W + i]
                u_p[k, c, i] = status[S_U_P + i]
                z1[k, c, i] = status[S_Z1 + i]
            saturated[k, c] = (status[S_SAT_TILT] != 0.0 or status[S_SAT_COLLECTIVE] != 0.0
                               or status[S_SAT_CYCLIC] != 0.0)
        # 2. the true lumped faults for that command; 3. every plant holds it over [t_k, t_k+1)
        for c in range(n):
            for i in range(4):
                u[i] = commands[k, c, i]
            lumped_faults(x[c], u, t, plant_params[c], faults[c], out_p, out_w)
            for i in range(3):
                fault_true_p[k, c, i] = out_p[i]
                fault_true_w[k, c, i] = out_w[i]
            if k < last:
                plant_step(x[c], u, t, dt, substeps, plant_params[c], faults[c], disturbance[c])
    return TEAM_DONE


#: Files whose contents are compiled into :func:`run_team_steps` besides this one.
_DEPENDENCIES = (Path(_ctl.__file__), Path(_plant.__file__), Path(_faults.__file__), Path(_layout.__file__),
                 Path(_impairments.__file__))


def refresh_cache() -> bool:
    """Empty :func:`run_team_steps`' numba cache index if the files it depends on
    (:data:`_DEPENDENCIES`: ``control_kernels.py``, ``plant_kernels.py``, ``faults.py``,
    ``uh_core/layout.py``, ``impairments.py``) changed since it was cached; the digest is kept next to the cache in
    ``team_kernel.dependencies.sha256``. Returns True when the cache was emptied
    (:func:`uh_core.kernel_cache.refresh_cache`).
    """
    return _kernel_cache.refresh_cache([run_team_steps], _DEPENDENCIES, 'team_kernel.dependencies.sha256')


refresh_cache()


def compile_team_kernel() -> float:
    """Compile :func:`run_team_steps` for the signature :mod:`.team_simulation` uses (fills numba's
    on-disk cache); returns the seconds spent.
    """
    start = time.perf_counter()
    n, steps = 1, 1
    i64 = np.zeros((n, 1), dtype=np.int64)
    params = np.ones((n, _ctl.CONTROL_PARAMS_SIZE))
    params[:, _ctl.CP_LOWER:_ctl.CP_LOWER + 4] = -1.0
    plant_params = np.ones((n, _plant.PARAMS_SIZE))
    vec3 = np.zeros((steps, n, 3))
    run_team_steps(0, 0, 0, 0.01, np.zeros((steps, _ctl.REFERENCE_SIZE)), np.zeros((n, STATE_SIZE)), i64,
                   np.zeros(n, dtype=np.int64), np.ones(n), params, np.zeros((n, 3)), np.zeros((n, 1)),
                   np.zeros((n, 1, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3, 3)),
                   np.zeros((n, _ctl.MEMORY_ROWS, 3)), plant_params,
                   np.zeros((n, _plant.NUM_CHANNELS, _plant.FAULT_FIELDS)),
                   np.zeros((n, 3, _plant.DISTURBANCE_FIELDS)), 1, np.ones(n, dtype=np.int64), False, 0,
                   np.zeros((n, 1), dtype=np.int64), np.zeros((n, 1)), np.zeros(n, dtype=np.int64),
                   np.zeros(STATE_SIZE), np.zeros((steps, n, STATE_SIZE)),
                   np.zeros((steps, n, 4)), vec3, vec3.copy(), vec3.copy(), vec3.copy(), vec3.copy(), vec3.copy(),
                   np.zeros((steps, n), dtype=np.bool_))
    return time.perf_counter() - start

