"""The team kernel run in segments between the steps at which a loss changes what a UH flies (docs/resilience.md).

:func:`run_with_events` runs :func:`~uh_team.team_kernel.run_team_steps` from one change step of the
:class:`~uh_team.team_events.LossSchedule` to the next; before each segment every row gets the team
its UH flies then (:func:`~uh_topology.losses.row_team`): neighbours, weights, offsets, reference
link, or a hold at the position it had when it began to hold; a lost UH's row is frozen from its event
step (its failsafe, :func:`~uh_topology.losses.failsafe_step`). The links always go through the
impaired path with :func:`~uh_topology.losses.loss_impairments`, so that a lost UH's last state is
the last its neighbours receive.
"""
from __future__ import annotations

import numpy as np

from uh_topology.losses import NEVER, hold_reference, loss_impairments, predicting, row_team

from .team_events import loss_schedule
from .team_kernel import TEAM_DONE, TeamArrays, TeamImpairments, TeamRecord, run_team_steps

__all__ = ['run_with_events']


def _links(scenario, ids, max_nb: int) -> tuple:
    """Give the links' arrays for ``max_nb`` neighbour slots (filled per segment) and the links' spec."""
    n, spec = len(ids), loss_impairments(scenario)
    predict, motion = predicting(spec)
    links = TeamImpairments(True, int(spec.seed), np.zeros((n, max_nb), dtype=np.int64), np.zeros((n, max_nb)),
                            np.array([spec.drop_step(i, scenario.dt) for i in ids], dtype=np.int64),
                            np.array(spec.noise, dtype=float), np.zeros((n, max_nb), dtype=np.int64), predict, motion)
    return links, spec


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
        if schedule.lost_at.get(i, NEVER) <= k0:   # lost: its failsafe from its event step on
            frozen[c] = True
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


def run_with_events(scenario, K: int, dt: float, ids, arrays: TeamArrays, references, out: dict, every: int,
                    progress, on_failure):
    """Run steps ``0..K`` of a scenario with ``events`` (see the module docstring); give its :class:`LossSchedule`.

    ``out`` holds the run's arrays (:func:`~uh_team.run_arrays.new_run_arrays`); ``on_failure(step)``
    raises for a non-finite state.
    """
    n = len(ids)
    max_nb = max(n - 1, 1)
    cfg = arrays.config._replace(hears=np.zeros((n, max_nb), dtype=np.int64), nb_weights=np.zeros((n, max_nb)),
                                 nb_offsets=np.zeros((n, max_nb, 3)), brake_accel=float(scenario.safety.brake_accel))
    arrays = TeamArrays(cfg, arrays.impairments, arrays.state)
    schedule = loss_schedule(scenario, K)
    record = TeamRecord(**{name: out[name] for name in TeamRecord._fields})
    links, spec = _links(scenario, ids, max_nb)
    bounds = sorted({0, K + 1} | {s for s in schedule.change_steps() if 0 < s <= K})
    holds, teams = {}, {}
    for k0, k1 in zip(bounds[:-1], bounds[1:], strict=True):
        config = _segment(scenario, ids, schedule, k0, arrays, links, spec, holds, teams)
        for a in range(k0, k1, every):
            b = min(k1, a + every)
            failed = run_team_steps(a, b, K, dt, references, config, links, arrays.state, record)
            if failed != TEAM_DONE:
                on_failure(failed)
            if progress is not None:
                progress(b - 1, K)
    return schedule
