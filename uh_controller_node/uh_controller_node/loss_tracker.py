"""Detection and agreement of losses on one UH, step by step, without ROS (docs/resilience.md#detection-and-agreement).

:class:`LossTracker` is what a controller node knows of the team's losses. Each step ``k`` it is
given the sent step of the newest state it has from each UH it receives (declared and standby
edges) and the lost sets those states carried (:meth:`LossTracker.heard`); it

* *declares* a UH lost when the newest state from it is ``lost_steps`` old (``k - s >= lost_steps``);
* with ``on_loss: reform``, *merges* every lost set the newest states carry (the set a sender knew
  at the step before it sent the state).

:meth:`LossTracker.carried` is the set this UH sends on with its next state; :meth:`LossTracker.view`
gives ``(silent, lost)`` for :func:`uh_topology.losses.row_team`. A set that names this UH itself (in
real time, a UH whose states stopped for ``lost_timeout`` and came back) sets
:attr:`LossTracker.excluded`: the team has re-formed without it, so it leaves (holds where it is)
rather than fly a slot another UH took. :meth:`LossTracker.declare_self` puts this UH in its own
lost set (docs/resilience.md#leaving-the-team), which its states then carry to the team. The
in-process run works out the same steps in advance (:func:`uh_team.team_events.loss_schedule`); a
lockstep run equals it bit for bit.
"""
from __future__ import annotations

__all__ = ['LossTracker']


class LossTracker:
    """The losses UH ``uh_id`` knows of (see the module docstring).

    Parameters
    ----------
    uh_id : int
    receivable : sequence of int
        The UHs it receives (declared and standby neighbours).
    lost_steps : int
        Age (steps) at which a silent UH is declared lost.
    reform : bool
        ``on_loss: reform`` (merge and carry lost sets); otherwise only its own declarations count.
    """

    def __init__(self, uh_id: int, receivable, lost_steps: int, reform: bool):
        self.uh_id = int(uh_id)
        self.receivable = tuple(int(j) for j in receivable)
        self.lost_steps = int(lost_steps)
        self.reform = bool(reform)
        self.known = {}        # {uh: step declared}: what this UH knows
        self.declared = {}     # {uh: step}: its own declarations
        self.excluded = None   # the step a received lost set first named this UH (real time: it was silent too long)
        self._sets = {j: {} for j in self.receivable}   # {sender: {sent step: lost set it carried}}

    def heard(self, j: int, sent_step: int, lost: dict) -> None:
        """Keep the lost set ``{uh: step}`` that UH ``j``'s state of ``sent_step`` carried."""
        if lost and j in self._sets and (self.reform or j in lost):
            self._sets[j][int(sent_step)] = dict(lost)

    def update(self, k: int, newest: dict) -> bool:
        """Take step ``k``'s newest sent steps ``{uh: s}``; return whether what this UH knows changed."""
        before = len(self.known)
        for j in self.receivable:
            s = newest.get(j)
            if s is None or j in self.known:
                continue
            if k - s >= self.lost_steps:
                self.declared[j] = k
                self.known[j] = k
        for j in self.receivable:
            s = newest.get(j)
            sets = self._sets[j]
            for step in [t for t in sets if s is not None and t < s]:   # older sets are never used again
                del sets[step]
            for lost, step in (sets.get(s) or {}).items():
                if self.reform or lost == j:     # with hold, only a sender's own declaration (it leaves)
                    if lost != self.uh_id:
                        self.known.setdefault(lost, step)
                    elif self.excluded is None:
                        self.excluded = k
        return len(self.known) != before

    def declare_self(self, k: int) -> None:
        """Declare this UH itself lost at step ``k`` (its isolator found a fault it cannot compensate; it leaves)."""
        self.declared.setdefault(self.uh_id, int(k))
        self.known.setdefault(self.uh_id, int(k))

    def view(self) -> tuple:
        """Give ``(silent, lost)``: with ``reform`` the known lost set, otherwise its declarations as silent."""
        mine = frozenset(self.known)
        return (frozenset(), mine) if self.reform else (mine, frozenset())

    def carried(self) -> dict:
        """Give the lost set this UH sends on (``{uh: step declared}``; with ``hold``, only its own declaration)."""
        if self.reform:
            return dict(self.known)
        return {self.uh_id: self.known[self.uh_id]} if self.uh_id in self.known else {}
