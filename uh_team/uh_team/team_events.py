"""Losses in an in-process run: who learns of a loss when, and which team each UH flies (docs/resilience.md).

A scenario's ``events`` lose helicopters; its ``resilience`` says how the others answer. This
module turns both into a :class:`LossSchedule` (for every surviving UH, the steps at which it leaves a
silent neighbour out as *stale*, at which it *declares* it lost itself, and at which it *knows* of
every loss) and runs the team kernel in segments between those steps, each UH flying the team its own
knowledge gives (:func:`row_team`).

Detection and agreement (docs/resilience.md#detection-and-agreement):

* A lost UH sends nothing from its event step ``e`` on; its plant hovers where it was.
* A UH that receives a neighbour (declared or standby edge) measures the age ``k - s`` of the newest
  state it has from it, ``s`` the step it was sent at (:func:`~uh_controller_node.impairments.delivered_step`,
  the links' impairments included). At age ``stale_steps`` it leaves it out of the law; at age
  ``lost_steps`` (``resilience.lost_timeout``) it declares it lost.
* Every state a UH sends carries its lost set (a bitmask with the step of each loss); a receiver merges it.
  So UH ``i`` knows of loss ``j`` at the first step it receives a state sent after one of its neighbours
  knew, or at its own declaration: the agreement is a shortest-arrival problem over the graph, solved
  here by relaxation.

With ``on_loss: hold`` nothing is declared: a UH leaves the silent neighbour out and holds its position
when it has no path from the virtual leader without it (what a team does without this layer).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from uh_controller_node.impairments import delivered_step
from uh_core.layout import R_P, R_YAW, REFERENCE_SIZE, X_OMEGA, X_P, X_THETA, X_V
from uh_topology.graph import reachable_from
from uh_topology.impairments import NO_DROPOUT, PREDICTING
from uh_topology.scenario_keys import STALE_TIMEOUT

__all__ = ['LossSchedule', 'RowTeam', 'loss_schedule', 'row_team', 'NEVER', 'link_impairments', 'drop_steps',
           'freeze', 'hold_reference', 'predicting', 'holds']

#: A step that never comes.
NEVER = 1 << 62


@dataclass(frozen=True)
class LossSchedule:
    """When each UH learns of each loss (steps; :data:`NEVER` when it does not).

    Attributes
    ----------
    lost_at : dict {uh: step}
        The event step of every lost UH.
    stale : dict {(i, j): step}
        UH ``i`` leaves its silent neighbour ``j`` out of the law.
    declared : dict {(i, j): step}
        UH ``i`` declares ``j`` lost itself (``j``'s state is ``lost_steps`` old).
    known : dict {(i, j): step}
        UH ``i`` knows ``j`` is lost (its own declaration or a merged lost set).
    reform : bool
        ``on_loss: reform`` (otherwise the UHs only leave silent neighbours out and hold).
    """

    lost_at: dict
    stale: dict
    declared: dict
    known: dict
    reform: bool

    def view(self, i: int, k: int) -> tuple:
        """Give ``(stale, lost)`` as UH ``i`` sees them at step ``k`` (frozensets of ids)."""
        stale = frozenset(j for (r, j), s in self.stale.items() if r == i and s <= k)
        lost = frozenset(j for (r, j), s in self.known.items() if r == i and s <= k) if self.reform else frozenset()
        return stale, lost

    def change_steps(self) -> list:
        """Give the steps at which some UH's view or the frozen set changes, ascending."""
        steps = set(self.lost_at.values()) | set(self.stale.values())
        if self.reform:
            steps |= set(self.known.values())
        return sorted(s for s in steps if s < NEVER)

    def agreed_at(self, j: int, alive) -> int:
        """Give the step from which every UH of ``alive`` knows ``j`` is lost."""
        return max((self.known.get((i, j), NEVER) for i in alive if i != j), default=NEVER)


@dataclass(frozen=True)
class RowTeam:
    """What one UH's controller flies: its neighbours and weights, its offset and reference link, or a hold."""

    neighbours: tuple
    weights: tuple
    neighbour_offsets: tuple
    offset: np.ndarray
    leader_link: float
    hold_reason: str | None = None


def link_impairments(scenario, i: int, j: int) -> tuple:
    """``(delay, jitter, loss)`` of the link ``i`` hears ``j``; a standby link gets the worst declared one."""
    imp = scenario.impairments
    if imp is None:
        return 0, 0, 0.0
    if (i, j) in imp.delays:
        return imp.delays[(i, j)], imp.jitters[(i, j)], imp.losses[(i, j)]
    return (max(imp.delays.values(), default=0), max(imp.jitters.values(), default=0),
            max(imp.losses.values(), default=0.0))


def drop_steps(scenario) -> dict:
    """``{uh: first step nobody receives its state}``: a lost UH's event step, or its dropout's."""
    imp = scenario.impairments
    out = {i: (imp.drop_step(i, scenario.dt) if imp is not None else NO_DROPOUT) for i in scenario.ids}
    for event in scenario.events:
        out[event.uh] = min(out[event.uh], event.step)
    return out


def _first(k0: int, last: int, condition) -> int:
    """Give the first step in ``k0..last`` where ``condition(k)`` holds, or :data:`NEVER`."""
    for k in range(max(k0, 0), last + 1):
        if condition(k):
            return k
    return NEVER


def loss_schedule(scenario, steps: int) -> LossSchedule:
    """Work out the :class:`LossSchedule` of ``scenario``'s events over steps ``0..steps``."""
    spec = scenario.resilience
    dt = float(scenario.dt)
    seed = scenario.impairments.seed if scenario.impairments is not None else 0
    lost_at = {e.uh: e.step for e in scenario.events}
    drops = drop_steps(scenario)
    receivable = {(i, j) for (i, j) in scenario.receivable_edges() if j != 0}
    stale_steps = math.ceil(round(STALE_TIMEOUT / dt, 9))
    lost_steps = spec.lost_steps(dt)

    def delivered(i, j, k):
        delay, jitter, loss = link_impairments(scenario, i, j)
        return delivered_step(k, delay, jitter, loss, drops[j], seed, i, j)

    def alive(i, k):
        return lost_at.get(i, NEVER) > k

    stale, declared, known = {}, {}, {}
    for j, e in lost_at.items():
        for (i, src) in sorted(receivable):
            if src != j or not alive(i, e):
                continue
            stale[(i, j)] = _first(e, steps, lambda k, i=i, j=j: k - delivered(i, j, k) >= stale_steps)
            declared[(i, j)] = _first(e, steps, lambda k, i=i, j=j: k - delivered(i, j, k) >= lost_steps)
        known.update({(i, j): declared.get((i, j), NEVER) for i in scenario.ids if i != j})
        changed = True
        while changed:     # relaxation: i learns from m at the first state m sent after it knew
            changed = False
            for (i, m) in sorted(receivable):
                km = known.get((m, j), NEVER)
                if m == j or i == j or km >= NEVER or not alive(m, km + 1):
                    continue
                k = _first(km + 1, min(steps, known[(i, j)] - 1), lambda k, i=i, m=m, km=km: delivered(i, m, k) > km)
                if k < known[(i, j)]:
                    known[(i, j)] = k
                    changed = True
    return LossSchedule(lost_at=lost_at, stale=stale, declared=declared, known=known,
                        reform=spec.on_loss == 'reform')


def row_team(scenario, i: int, stale, lost, teams: dict) -> RowTeam:
    """Give the team UH ``i`` flies when it sees ``stale`` and ``lost`` (``teams``: a cache of reformed teams)."""
    if lost not in teams:
        teams[lost] = scenario.reformed(lost)
    team = teams[lost]
    zero = np.zeros(3)
    if i in team.holding:
        return RowTeam((), (), (), zero, 1.0, team.holding[i])
    gone = set(stale) | set(lost)
    size = max(scenario.ids) + 1
    adjacency = np.zeros((size, size))
    for (r, j), w in team.edges.items():
        adjacency[r, j] = w
    if i not in reachable_from(adjacency, (0,), allowed=set(team.ids) - gone):
        return RowTeam((), (), (), zero, 1.0, 'no path from the virtual leader without the silent UHs '
                       f'{sorted(gone)}')
    neighbours = tuple(j for j in team.neighbours(i) if j not in gone)
    leader = i in team.leaders
    offsets = tuple(team.offsets[j] if leader else zero for j in neighbours)
    return RowTeam(neighbours, tuple(team.weight(i, j) for j in neighbours), offsets,
                   team.offsets[i] if leader else zero, team.leader_link(i))


def holds(scenario, schedule) -> dict:
    """Give ``{uh: (step, reason)}`` of the UHs holding at the end of ``schedule``, with the step their hold began."""
    teams, out = {}, {}
    for k in [0] + schedule.change_steps():
        for i in scenario.ids:
            if schedule.lost_at.get(i, NEVER) <= k:
                out.pop(i, None)
                continue
            reason = row_team(scenario, i, *schedule.view(i, k), teams).hold_reason
            if reason is None:
                out.pop(i, None)
            elif i not in out:
                out[i] = (k, reason)
    return out


def freeze(x_row: np.ndarray) -> None:
    """Make a lost UH's state a hover where it is: zero velocity and body rates (in place)."""
    x_row[X_V:X_V + 3] = 0.0
    x_row[X_OMEGA:X_OMEGA + 3] = 0.0


def hold_reference(x_row: np.ndarray) -> np.ndarray:
    """Give the pseudo virtual leader of a hold at the UH's position and yaw now (offset zero)."""
    ref = np.zeros(REFERENCE_SIZE)
    ref[R_P:R_P + 3] = x_row[X_P:X_P + 3]
    ref[R_YAW] = x_row[X_THETA + 2]     # psi, the third Euler angle
    return ref


def predicting(scenario) -> tuple:
    """Give ``(predict, reference_motion)`` of the scenario's delay compensation (the default's without impairments)."""
    comp = scenario.impairments.compensation if scenario.impairments is not None else 'predict'
    return comp in PREDICTING, comp == 'reference_motion'
