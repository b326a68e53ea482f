"""When each UH learns of each loss, worked out in advance for an in-process run (docs/resilience.md).

A lost UH sends nothing from its event step ``e`` on (its helicopter hovers where it was). Every UH
measures the age ``k - s`` of the newest state it has from each UH it receives (declared and standby
edges), ``s`` the step that state was sent at
(:func:`~uh_controller_node.impairments.delivered_step`, the links' impairments included), and
*declares* the sender lost when the age reaches ``lost_steps`` (``resilience.lost_timeout``). Every
state a UH sends carries the lost set it knew at the step before, and a receiver merges it: UH
``i`` knows of loss ``j`` at its own declaration or at the first step it receives a state sent by a
neighbour after that neighbour knew. The nodes do exactly this step by step
(:class:`~uh_controller_node.loss_tracker.LossTracker`); here the same steps come from a
shortest-arrival relaxation over the graph, so that the team kernel can run in segments between them
(:mod:`uh_team.event_run`).

A UH that *leaves* (docs/resilience.md#leaving-the-team: its fault isolator found a fault it cannot
compensate at step ``s``) declares itself: ``known[(j, j)] = s``; it keeps sending, and its states from
step ``s + 1`` on carry its declaration, which spreads as above. It flies its leave point from ``s + 1`` on.

With ``on_loss: hold`` nothing is merged but a sender's own declaration: a UH leaves a neighbour out
from its own declaration on, or from the first state of a leaving neighbour that carries its declaration.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from uh_controller_node.impairments import delivered_step
from uh_topology.events import silent_events
from uh_topology.losses import NEVER, loss_impairments, row_team

__all__ = ['LossSchedule', 'loss_schedule', 'holds', 'NEVER']


@dataclass(frozen=True)
class LossSchedule:
    """When each UH learns of each loss (steps; :data:`NEVER` when it does not).

    Attributes
    ----------
    lost_at : dict {uh: step}
        The step every lost UH left the team: its ``lost`` event's, or its own declaration's.
    declared : dict {(i, j): step}
        UH ``i`` declares ``j`` lost itself (``j``'s newest state is ``lost_steps`` old).
    known : dict {(i, j): step}
        UH ``i`` knows ``j`` is lost (its own declaration or a merged lost set); with ``hold``, its
        own declaration.
    reform : bool
        ``on_loss: reform``.
    leaving : dict {uh: (step, channel)}
        The UHs that declared themselves unable at ``step`` (the channel their isolator found); each
        flies its leave point from ``step + 1`` on (:meth:`leaves_from`).
    """

    lost_at: dict
    declared: dict
    known: dict
    reform: bool
    leaving: dict = field(default_factory=dict)

    def view(self, i: int, k: int) -> tuple:
        """Give ``(silent, lost)`` as UH ``i`` uses them at step ``k`` (see :func:`uh_topology.losses.row_team`)."""
        mine = frozenset(j for (r, j), s in self.known.items() if r == i != j and s <= k)
        return (frozenset(), mine) if self.reform else (mine, frozenset())

    def leaves_from(self, i: int) -> int:
        """Give the step from which UH ``i`` flies its leave point (:data:`NEVER` when it does not leave)."""
        return self.leaving[i][0] + 1 if i in self.leaving else NEVER

    def change_steps(self) -> list:
        """Give the steps at which some UH's view or the set of lost UHs changes, ascending."""
        steps = set(self.lost_at.values()) | set(self.known.values()) | {self.leaves_from(i) for i in self.leaving}
        return sorted(s for s in steps if s < NEVER)

    def agreed_at(self, j: int, alive) -> int:
        """Give the step from which every UH of ``alive`` knows ``j`` is lost (one lost before it knew is not asked)."""
        asked = [i for i in alive if i != j and (self.lost_at.get(i, NEVER) >= NEVER
                                                 or self.known.get((i, j), NEVER) < self.lost_at[i])]
        return max((self.known.get((i, j), NEVER) for i in asked), default=NEVER)


def _first(k0: int, last: int, condition) -> int:
    """Give the first step in ``k0..last`` where ``condition(k)`` holds, or :data:`NEVER`."""
    for k in range(max(k0, 0), last + 1):
        if condition(k):
            return k
    return NEVER


def loss_schedule(scenario, steps: int, leaving: dict | None = None) -> LossSchedule:
    """Work out the :class:`LossSchedule` of ``scenario``'s events over steps ``0..steps``.

    ``leaving``: ``{uh: (step, channel)}`` of the UHs that declare themselves unable (found by
    :func:`uh_team.event_run.run_with_events`).
    """
    spec = scenario.resilience
    links = loss_impairments(scenario)
    lost_steps = spec.lost_steps(float(scenario.dt))
    leaving = dict(leaving or {})
    silent_at = {e.uh: e.step for e in silent_events(scenario.events)}
    lost_at = {**silent_at, **{j: s for j, (s, _) in leaving.items()}}
    receivable = sorted(links.delays)

    def delivered(i, j, k):
        return delivered_step(k, links.delays[(i, j)], links.jitters[(i, j)], links.losses[(i, j)],
                              links.drop_step(j, scenario.dt), links.seed, i, j)

    def alive(i, k):    # it sends its state of step k
        return silent_at.get(i, NEVER) > k

    def last(i):   # a UH learns nothing from its own loss on (its controller stops), nor after it declared itself
        return min(steps, leaving[i][0] if i in leaving else silent_at.get(i, NEVER) - 1)

    declared, known = {}, {}
    for j, e in lost_at.items():
        if j in leaving:    # it declares itself and sends on
            declared[(j, j)] = known[(j, j)] = e
        for (i, src) in receivable:
            if src == j and j not in leaving and alive(i, e):
                declared[(i, j)] = _first(e, last(i), lambda k, i=i, j=j: k - delivered(i, j, k) >= lost_steps)
        known.update({(i, j): declared.get((i, j), NEVER) for i in scenario.ids if i != j})
        changed = True
        while changed:     # relaxation: i learns from m at the first state m sent after it knew
            changed = False
            for (i, m) in receivable:
                km = known.get((m, j), NEVER)
                merged = spec.on_loss == 'reform' or m == j      # with hold, only from the leaving UH itself
                if i == j or (m == j and j not in leaving) or not merged or km >= NEVER or not alive(m, km + 1):
                    continue
                k = _first(km + 1, min(last(i), known[(i, j)] - 1),
                           lambda k, i=i, m=m, km=km: delivered(i, m, k) > km)
                if k < known[(i, j)]:
                    known[(i, j)] = k
                    changed = True
    return LossSchedule(lost_at=lost_at, declared=declared, known=known, reform=spec.on_loss == 'reform',
                        leaving=leaving)


def holds(scenario, schedule, steps: int) -> dict:
    """Give ``{uh: (step, reason)}`` of the UHs holding at step ``steps``, with the step their hold began."""
    teams, out = {}, {}
    for k in [0] + [s for s in schedule.change_steps() if s <= steps]:
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
