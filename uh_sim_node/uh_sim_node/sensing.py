"""The plant side's proximity sensing, free of middleware (docs/safety.md#what-the-filter-knows).

A real helicopter knows where the others are from onboard sensing or a broadcast beacon, not from
the control graph. The team's sensing node (:mod:`uh_sim_node.sensing_node`) stands for that: it
hears every UH's state and serves each UH the states of the others within the safety filter's
``sensing_radius``, one message per UH per step (O(N) messages per step for the team, where every
simulator hearing every other would be O(N^2)). :class:`ProximitySensing` decides what each message
holds and when it is due:

- ``lockstep``: once the states of step k of every UH are in, the proximity of every UH for step k,
  from those states: what the in-process team loop gives its filters (so the runs are equal bit for
  bit);
- ``realtime``: when UH i's state k arrives, UH i's proximity for step k from the newest state of
  every other UH (step k or the one before: the sims publish at the same tick).

A UH whose state stops (its simulator died, its beacon failed) stays an obstacle at its last
reported state for the rest of the run, never aged out: a dead process may still be a helicopter in
the air. A UH never heard is not reported (nothing is known of it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from uh_core.layout import STATE_SIZE, X_P

__all__ = ['ProximitySensing', 'ProximityReport', 'within_radius']


def within_radius(positions, own: int, sensing_radius: float) -> list[int]:
    """Return the rows of ``positions`` (n, 3; m, inertial frame) within ``sensing_radius`` m of row ``own``.

    Row ``own`` is left out; rows keep their order. The test is that of the filter's kernel
    (:func:`uh_controller_node.safety_kernels.proximity_rows`, the in-process team loop's sensing)
    with the same floating-point operations in the same order (elementwise, each correctly
    rounded), so both select the same rows.
    """
    p = np.asarray(positions, dtype=float)
    diff = p - p[own]
    d2 = diff[:, 0] * diff[:, 0]
    d2 = d2 + diff[:, 1] * diff[:, 1]
    d2 = d2 + diff[:, 2] * diff[:, 2]
    inside = np.sqrt(d2) <= sensing_radius
    inside[own] = False
    return np.flatnonzero(inside).tolist()


@dataclass(frozen=True)
class ProximityReport:
    """One proximity message: what UH ``uh_id`` senses at step ``step``.

    ``ids`` (ascending), ``steps`` (the step each state is of), ``states`` (m, 12) and
    ``payloads`` (what was offered with each state, e.g. the received message) of every other UH
    within the sensing radius.
    """

    uh_id: int
    step: int
    ids: tuple
    steps: tuple
    states: np.ndarray
    payloads: tuple = ()


class ProximitySensing:
    """What each UH senses of the others, and when its proximity message is due (module docstring).

    Parameters
    ----------
    ids : sequence of int
        The team's UHs.
    sensing_radius : float
        m, hub to hub (the scenario's ``safety.sensing_radius``).
    lockstep : bool
        The clock mode (True: lockstep, False: realtime).
    last_step : int
        Index K of the run's last step; later states are ignored.
    """

    def __init__(self, ids, sensing_radius: float, lockstep: bool, last_step: int):
        self.ids = tuple(sorted(int(i) for i in ids))
        self.row = {uh: r for r, uh in enumerate(self.ids)}
        self.sensing_radius, self.lockstep, self.last_step = float(sensing_radius), bool(lockstep), int(last_step)
        self.states = np.zeros((len(self.ids), STATE_SIZE))
        self.steps = np.full(len(self.ids), -1, dtype=np.int64)   # -1: never heard
        self.payloads: list = [None] * len(self.ids)              # what came with each UH's state held
        self.next_step = 0                                        # lockstep: the next step to serve
        self._pending: dict[int, dict] = {}                       # lockstep: step -> {uh: (state, payload)}

    def offer(self, uh_id: int, k: int, state, payload=None) -> list[ProximityReport]:
        """Take UH ``uh_id``'s valid state (12,) of step ``k``; return the proximity messages now due, in order.

        ``payload`` (anything, e.g. the message the state came in) is handed back with the state in
        the reports that hold it.
        """
        if uh_id not in self.row:
            raise ValueError(f'uh{uh_id} is not in the team ({", ".join(f"uh{i}" for i in self.ids)})')
        if k > self.last_step:
            return []
        if not self.lockstep:
            r = self.row[uh_id]
            if k <= self.steps[r]:
                return []   # older than, or a repeat of, the state held (reordered, or history after a restart)
            self.states[r], self.steps[r], self.payloads[r] = state, k, payload
            return [self.report(uh_id, k)]
        if k >= self.next_step:
            self._pending.setdefault(k, {})[uh_id] = (np.asarray(state, dtype=float), payload)
        out = []
        while len(self._pending.get(self.next_step, ())) == len(self.ids):
            for uh, (x, held) in self._pending.pop(self.next_step).items():
                r = self.row[uh]
                self.states[r], self.steps[r], self.payloads[r] = x, self.next_step, held
            out += [self.report(uh, self.next_step) for uh in self.ids]
            self.next_step += 1
        return out

    def report(self, uh_id: int, k: int) -> ProximityReport:
        """Return UH ``uh_id``'s proximity message for step ``k`` from the states held now."""
        heard = [r for r in range(len(self.ids)) if self.steps[r] >= 0 or r == self.row[uh_id]]
        own = heard.index(self.row[uh_id])
        rows = [heard[j] for j in within_radius(self.states[heard, X_P:X_P + 3], own, self.sensing_radius)]
        return ProximityReport(int(uh_id), int(k), tuple(self.ids[r] for r in rows),
                               tuple(int(self.steps[r]) for r in rows), self.states[rows].copy(),
                               tuple(self.payloads[r] for r in rows))
