"""The team kernel run in segments between the steps at which a loss changes what a UH flies (docs/resilience.md).

:func:`run_with_events` runs :func:`~uh_team.team_kernel.run_team_steps` from one change step of the
:class:`~uh_team.team_events.LossSchedule` to the next; before each segment every row gets the team
its UH flies then (:func:`~uh_team.team_events.row_team`): neighbours, weights, offsets, reference
link, or a hold at the position it had when it began to hold; a lost UH's row is frozen from its event
step. The links always go through the impaired path, so that a lost UH's last state is the last its
neighbours receive (its sends stop at the event step, as a dropout's).
"""
from __future__ import annotations

import numpy as np

from .team_events import (
    NEVER,
    drop_steps,
    freeze,
    hold_reference,
    link_impairments,
    loss_schedule,
    predicting,
    row_team,
)
from .team_kernel import TEAM_DONE, TeamArrays, TeamImpairments, TeamRecord, run_team_steps

__all__ = ['run_with_events']


def _impairments(scenario, ids, base: TeamImpairments, max_nb: int, drops: dict) -> TeamImpairments:
    """Give the links' arrays for ``max_nb`` neighbour slots (filled per segment), with the events' drop steps."""
    n = len(ids)
    predict, motion = predicting(scenario)
    return TeamImpairments(True, int(base.seed), np.zeros((n, max_nb), dtype=np.int64), np.zeros((n, max_nb)),
                           np.array([drops[i] for i in ids], dtype=np.int64), base.noise.copy(),
                           np.zeros((n, max_nb), dtype=np.int64), predict, motion)


def _segment(scenario, ids, schedule, k0, arrays, links, holds, teams):
    """Give ``(config, links)`` of the segment from step ``k0``: every row's team as its UH sees it then."""
    col = {i: c for c, i in enumerate(ids)}
    cfg, x = arrays.config, arrays.state.x
    n, max_nb = cfg.hears.shape
    hears = np.zeros((n, max_nb), dtype=np.int64)
    count = np.zeros(n, dtype=np.int64)
    weights, nb_offsets = np.zeros((n, max_nb)), np.zeros((n, max_nb, 3))
    offsets, leader_links = np.zeros((n, 3)), np.zeros(n)
    frozen, holding, hold = np.zeros(n, dtype=np.bool_), np.zeros(n, dtype=np.bool_), cfg.hold.copy()
    for c, i in enumerate(ids):
        if schedule.lost_at.get(i, NEVER) <= k0:
            if schedule.lost_at[i] == k0:
                freeze(x[c])        # it hovers where it is from its event step on
            frozen[c] = True
            continue
        row = row_team(scenario, i, *schedule.view(i, k0), teams)
        if row.hold_reason is not None:
            holding[c] = True
            if i not in holds:
                holds[i] = (k0, row.hold_reason, hold_reference(x[c]))
            hold[c] = holds[i][2]
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
            links.delay[c, slot], links.jitter[c, slot], links.loss[c, slot] = link_impairments(scenario, i, j)
    config = cfg._replace(hears=hears, count=count, nb_weights=weights, nb_offsets=nb_offsets, offsets=offsets,
                          links=leader_links, frozen=frozen, holding=holding, hold=hold)
    return config, links


def run_with_events(scenario, K: int, dt: float, ids, arrays: TeamArrays, references, out: dict, every: int,
                    progress, on_failure) -> dict:
    """Run steps ``0..K`` of a scenario with ``events`` (see the module docstring); give what happened.

    ``out`` holds the run's arrays (:func:`~uh_team.run_arrays.new_run_arrays`); ``on_failure(step)``
    raises for a non-finite state. Returns ``{'schedule': LossSchedule, 'holds': {uh: (step, reason)}}``
    (every hold begun during the run, with its first step and reason).
    """
    n = len(ids)
    max_nb = max(n - 1, 1)
    cfg = arrays.config._replace(hears=np.zeros((n, max_nb), dtype=np.int64), nb_weights=np.zeros((n, max_nb)),
                                 nb_offsets=np.zeros((n, max_nb, 3)))
    arrays = TeamArrays(cfg, arrays.impairments, arrays.state)
    schedule = loss_schedule(scenario, K)
    record = TeamRecord(**{name: out[name] for name in TeamRecord._fields})
    links = _impairments(scenario, ids, arrays.impairments, max_nb, drop_steps(scenario))
    bounds = sorted({0, K + 1} | {s for s in schedule.change_steps() if 0 < s <= K})
    holds, began, teams = {}, {}, {}
    for k0, k1 in zip(bounds[:-1], bounds[1:], strict=True):
        config, links = _segment(scenario, ids, schedule, k0, arrays, links, holds, teams)
        for i, (step, reason, _) in holds.items():
            began.setdefault(i, (step, reason))
        for a in range(k0, k1, every):
            b = min(k1, a + every)
            failed = run_team_steps(a, b, K, dt, references, config, links, arrays.state, record)
            if failed != TEAM_DONE:
                on_failure(failed)
            if progress is not None:
                progress(b - 1, K)
    return {'schedule': schedule, 'holds': began, 'teams': teams}
