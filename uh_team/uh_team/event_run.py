"""The team kernel run in segments between the steps at which an event changes what a UH flies (docs/resilience.md).

:func:`run_with_events` runs :func:`~uh_team.team_kernel.run_team_steps` from one change step of the
:class:`~uh_team.team_events.LossSchedule` to the next; before each segment every row gets the team
its UH flies then (:func:`~uh_topology.losses.row_team`): neighbours, weights, offsets, reference
link, or a hold at the position it had when it began to hold; a lost UH's row is frozen from its event
step (its failsafe, :func:`~uh_topology.losses.failsafe_step`); a leaving UH holds its leave point
(:func:`~uh_topology.losses.leave_reference`); a ``stuck`` event's actuator is stuck from its step on
where the command before left it (:func:`~uh_sim_node.plant_kernels.stuck_position`). The links always
go through the impaired path with :func:`~uh_topology.losses.loss_impairments`, so that a lost UH's
last state is the last its neighbours receive.

A UH leaves when its controller's fault isolator finds a channel it cannot compensate
(:meth:`~uh_controller_node.fault_isolation.FaultIsolator.unable`), which depends on the run itself.
The run is therefore flown again until no new such finding comes: after each pass the isolator runs
over the pass's arrays (the same kernels the controllers run online), and the earliest finding joins
the schedule. The run before that step is the same in both passes (the law is causal), so the last
pass is the run in which every controller acted on its isolator, as the nodes do.
"""
from __future__ import annotations

import numpy as np

from uh_controller_node.isolation_runs import first_unable
from uh_sim_node.faults import ActuatorFault
from uh_sim_node.plant_kernels import fault_table, stuck_position
from uh_topology.losses import NEVER, hold_reference, leave_reference, loss_impairments, predicting, row_team

from .team_events import loss_schedule
from .team_kernel import TEAM_DONE, TeamArrays, TeamImpairments, TeamRecord, TeamState, run_team_steps

__all__ = ['run_with_events']


def _links(scenario, ids, max_nb: int) -> tuple:
    """Give the links' arrays for ``max_nb`` neighbour slots (filled per segment) and the links' spec."""
    n, spec = len(ids), loss_impairments(scenario)
    predict, motion = predicting(spec)
    links = TeamImpairments(True, int(spec.seed), np.zeros((n, max_nb), dtype=np.int64), np.zeros((n, max_nb)),
                            np.array([spec.drop_step(i, scenario.dt) for i in ids], dtype=np.int64),
                            np.array(spec.noise, dtype=float), np.zeros((n, max_nb), dtype=np.int64), predict, motion)
    return links, spec


def _stick(scenario, ids, k0, cfg, commands):
    """Stick the actuators of the ``stuck`` events of step ``k0`` in ``cfg.faults``, in place."""
    for event in scenario.events:
        if event.kind == 'stuck' and event.step == k0:
            c, t = ids.index(event.uh), k0 * float(scenario.dt)
            position = stuck_position(cfg.plant_params[c], cfg.faults[c], event.channel, commands[k0 - 1, c], t)
            cfg.faults[c, event.channel] = fault_table([ActuatorFault.stuck_at(event.channel, position, t)])[
                event.channel]


def _segment(scenario, ids, schedule, k0, arrays, links, spec, holds, teams):
    """Give the team configuration of the segment from step ``k0``: every row's team as its UH sees it then."""
    col = {i: c for c, i in enumerate(ids)}
    cfg, x = arrays.config, arrays.state.x
    n, max_nb = cfg.hears.shape
    hears = np.zeros((n, max_nb), dtype=np.int64)
    count = np.zeros(n, dtype=np.int64)
    weights, nb_offsets = np.zeros((n, max_nb)), np.zeros((n, max_nb, 3))
    offsets, leader_links = np.zeros((n, 3)), np.zeros(n)
    frozen, holding, hold = np.zeros(n, dtype=np.bool_), np.zeros(n, dtype=np.bool_), cfg.hold.copy()
    for c, i in enumerate(ids):
        if i not in schedule.leaving and schedule.lost_at.get(i, NEVER) <= k0:   # lost: its failsafe from its event on
            frozen[c] = True
            continue
        if schedule.leaves_from(i) <= k0:     # it leaves: its leave point, fixed when it began to leave
            holding[c], leader_links[c] = True, 1.0
            hold[c] = holds.setdefault(('leave', i), leave_reference(x[c], scenario.resilience.leave_climb))
            continue
        row = row_team(scenario, i, *schedule.view(i, k0), teams)
        if row.hold_reason is not None:
            holding[c] = True
            if i not in holds:
                holds[i] = hold_reference(x[c])
            hold[c] = holds[i]
            leader_links[c] = 1.0
            continue
        holds.pop(i, None)
        m = len(row.neighbours)
        count[c] = m
        hears[c, :m] = [col[j] for j in row.neighbours]
        weights[c, :m] = row.weights
        nb_offsets[c, :m] = np.reshape(row.neighbour_offsets, (m, 3))
        offsets[c], leader_links[c] = row.offset, row.leader_link
        for slot, j in enumerate(row.neighbours):
            links.delay[c, slot], links.jitter[c, slot] = spec.delays[(i, j)], spec.jitters[(i, j)]
            links.loss[c, slot] = spec.losses[(i, j)]
    return cfg._replace(hears=hears, count=count, nb_weights=weights, nb_offsets=nb_offsets, offsets=offsets,
                        links=leader_links, frozen=frozen, holding=holding, hold=hold)


def _pass(scenario, K, dt, ids, arrays, references, record, schedule, every, progress, on_failure):
    """Fly steps ``0..K`` once with ``schedule`` from ``arrays``' state (changed in place)."""
    links, spec = _links(scenario, ids, max(len(ids) - 1, 1))
    bounds = sorted({0, K + 1} | {s for s in schedule.change_steps() if 0 < s <= K}
                    | {e.step for e in scenario.events if e.kind == 'stuck' and e.step <= K})
    holds, teams = {}, {}
    for k0, k1 in zip(bounds[:-1], bounds[1:], strict=True):
        _stick(scenario, ids, k0, arrays.config, record.commands)
        config = _segment(scenario, ids, schedule, k0, arrays, links, spec, holds, teams)
        for a in range(k0, k1, every):
            b = min(k1, a + every)
            failed = run_team_steps(a, b, K, dt, references, config, links, arrays.state, record)
            if failed != TEAM_DONE:
                on_failure(failed)
            if progress is not None:
                progress(b - 1, K)


def _unable(scenario, case: str, out: dict, ids, schedule) -> dict:
    """Give ``{uh: (step, channel)}`` of the earliest new finding of a fault its controller cannot compensate, or {}.

    A UH lost before its finding is not asked (its controller stopped at its event step).
    """
    candidates = [i for i in ids if i not in schedule.lost_at]
    arrays = dict(out, time=np.arange(len(out['states'])) * float(scenario.dt))   # the steps' run times, k dt
    spec = scenario.resilience
    found = first_unable(arrays, scenario, case, spec.unable_rho, spec.unable_spread, candidates)
    found = {i: f for i, f in found.items() if f[0] < schedule.lost_at.get(i, NEVER)}
    first = min((step for step, _ in found.values()), default=None)
    return {i: f for i, f in found.items() if f[0] == first}


def run_with_events(scenario, case: str, K: int, dt: float, ids, arrays: TeamArrays, references, out: dict,
                    every: int, progress, on_failure):
    """Run steps ``0..K`` of a scenario with ``events`` (see the module docstring); give its :class:`LossSchedule`.

    ``case`` is the controller case (its learning phase is the isolator's); ``out`` holds the run's arrays
    (:func:`~uh_team.run_arrays.new_run_arrays`); ``on_failure(step)`` raises for a non-finite state.
    """
    n = len(ids)
    max_nb = max(n - 1, 1)
    cfg = arrays.config._replace(hears=np.zeros((n, max_nb), dtype=np.int64), nb_weights=np.zeros((n, max_nb)),
                                 nb_offsets=np.zeros((n, max_nb, 3)), brake_accel=float(scenario.safety.brake_accel))
    record = TeamRecord(**{name: out[name] for name in TeamRecord._fields})
    leaving = {}
    while True:
        schedule = loss_schedule(scenario, K, leaving)
        state = TeamState(*(np.array(a, copy=True) for a in arrays.state))
        fresh = TeamArrays(cfg._replace(faults=cfg.faults.copy()), arrays.impairments, state)
        _pass(scenario, K, dt, ids, fresh, references, record, schedule, every, progress, on_failure)
        new = _unable(scenario, case, out, ids, schedule) if scenario.resilience.leaves else {}
        if not new:
            return schedule
        leaving.update(new)
