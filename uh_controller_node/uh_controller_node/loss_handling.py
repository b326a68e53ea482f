"""A controller node's part in a team that loses helicopters (docs/resilience.md), without ROS.

:class:`NodeLosses` is built by the controller node when its scenario has ``events`` or ``resilience``. It says what
the node subscribes to (its declared and standby neighbours, the reference if it has or may get a
reference link), how its inputs are received (:func:`~uh_topology.losses.loss_impairments`: a lost
UH dropped from its event step on), and runs each step:

* a lost UH (from its event step on) repeats its last command with a zero status: its helicopter
  hovers, its simulator ignores the command; its messages keep the lockstep clock and the recorder
  going, and no other UH receives its state;
* any other UH updates its :class:`~uh_controller_node.loss_tracker.LossTracker` with the newest
  states it has, flies the row :func:`~uh_topology.losses.row_team` gives for what it knows
  (:meth:`~uh_controller_node.controller.UHController.step_row`), or holds where it was when it began
  to hold, and carries its lost set on its command (its simulator sends it on with the next state);
* with ``resilience.on_unable: leave``, a UH whose fault isolator finds a channel below ``unable_rho``
  (:meth:`~uh_controller_node.fault_isolation.FaultIsolator.unable`) declares itself lost and, from the
  next step on, holds its leave point (:func:`~uh_topology.losses.leave_reference`), learning nothing more.
"""
from __future__ import annotations

import numpy as np

from uh_core.layout import STATUS_SIZE
from uh_core.reference import VirtualLeaderReference
from uh_topology.events import silent_events
from uh_topology.losses import NEVER, RowTeam, hold_reference, leave_reference, loss_impairments, row_team

from .controller_status import status_record
from .fault_isolation import CHANNELS
from .impairments import ReceivedStates, compile_impairment_kernels
from .loss_tracker import LossTracker
from .realtime_received import RealtimeReceivedStates

__all__ = ['NodeLosses']


class NodeLosses:
    """Loss detection, agreement and re-forming for the controller of UH ``uh_id`` (see the module docstring)."""

    def __init__(self, controller, scenario, uh_id: int, dt: float, clock_mode: str):
        self.controller, self.scenario, self.uh_id, self.dt = controller, scenario, int(uh_id), float(dt)
        edges = scenario.receivable_edges()
        self.neighbours = tuple(sorted(j for (i, j) in edges if i == self.uh_id and j != 0))
        self.linked = (self.uh_id, 0) in edges
        self.lost_step = next((e.step for e in silent_events(scenario.events) if e.uh == self.uh_id), NEVER)
        spec = scenario.resilience
        self.tracker = LossTracker(self.uh_id, self.neighbours, spec.lost_steps(self.dt), spec.on_loss == 'reform')
        kind = ReceivedStates if clock_mode == 'lockstep' else RealtimeReceivedStates
        self.received = kind(self.uh_id, self.neighbours, loss_impairments(scenario), self.dt,
                             VirtualLeaderReference(scenario.reference))
        compile_impairment_kernels()   # now, before the node's endpoints exist and the clock can start
        self.teams, self.rows, self.holding, self.last_command = {}, {}, None, None
        self.row = None
        self.unable_rho, self.unable_spread = (spec.unable_rho if spec.leaves else None), spec.unable_spread
        self.leave_from, self.leave_point, self.unable = NEVER, None, None   # from its own finding on
        self.last_heard = {}      # {uh: newest sent step that arrived}: the age of a neighbour left out as stale

    @classmethod
    def of(cls, controller, scenario, uh_id: int, dt: float, clock_mode: str):
        """Give the :class:`NodeLosses` of a scenario with ``events`` or ``resilience``, None for one without."""
        if not scenario.events and scenario.resilience is None:
            return None
        return cls(controller, scenario, uh_id, dt, clock_mode)

    def heard(self, j: int, sent_step: int, lost: dict) -> None:
        """Keep the lost set a state of UH ``j`` carried (:meth:`LossTracker.heard`)."""
        self.last_heard[j] = max(self.last_heard.get(j, -1), int(sent_step))
        self.tracker.heard(j, sent_step, lost)

    def step(self, k: int, inputs, own, neighbours: dict):
        """Run step ``k``; give ``(u, status)``.

        ``inputs`` are the synchroniser's (the own state as sent, the reference, the stale inputs: in
        real time a neighbour is left out as soon as it is stale, before it is declared lost); ``own``
        and ``neighbours`` the states as received.
        """
        if k >= self.lost_step and self.last_command is not None:   # lost: the last command, a zero status
            status = status_record(self.uh_id, k, k * self.dt, np.zeros(STATUS_SIZE))
            status.isolation, status.role = self.controller.isolator.status(), 'lost'
            return self.last_command, status
        if k >= self.leave_from:
            return self._leave(k, inputs, own, neighbours)
        self.tracker.update(k, {**self.last_heard, **self.received.sample_steps})
        silent, lost = self.tracker.view()
        silent = silent | {key for key in inputs.stale if key in self.neighbours}
        if (silent, lost) not in self.rows:   # a view changes only when a loss is learnt: not every step
            self.rows[(silent, lost)] = row_team(self.scenario, self.uh_id, silent, lost, self.teams)
        row = self.rows[(silent, lost)]
        if self.tracker.excluded is not None:   # the team re-formed without this UH: it leaves, holding where it is
            row = RowTeam((), (), (), np.zeros(3), 1.0, 'the team declared this UH lost')
        reference = inputs.reference
        if row.hold_reason is None and row.leader_link > 0.0 and reference is None:   # the reference is stale
            row = RowTeam((), (), (), np.zeros(3), 1.0, "the virtual leader's reference is stale")
        own_raw = inputs.own
        if row.hold_reason is None:
            self.holding = None
            u, status = self.controller.step_row(k, own, neighbours, reference, self.dt, row)
        else:
            if self.holding is None:
                self.holding = hold_reference(np.asarray(own_raw, dtype=float))
            u, status = self.controller.step_row(k, own, neighbours, reference, self.dt, row, hold=self.holding)
        self.row, self.last_command = row, u
        isolator = self.controller.isolator
        channel = -1 if self.unable_rho is None else isolator.unable(self.unable_rho, self.unable_spread)
        if channel >= 0:     # a fault it cannot compensate: it declares itself and leaves from the next step
            self.unable, self.leave_from = channel, k + 1
            self.tracker.declare_self(k)
        status.lost_uhs, status.role = tuple(sorted(self.tracker.known)), self.role()
        return u, status

    def _leave(self, k: int, inputs, own, neighbours):
        """Fly step ``k`` of a UH that left: hold its leave point, fixed at its first leaving step."""
        if self.leave_point is None:
            climb = self.scenario.resilience.leave_climb
            self.leave_point = leave_reference(np.asarray(inputs.own, dtype=float), climb)
        self.row = RowTeam((), (), (), np.zeros(3), 1.0, 'leaving')
        u, status = self.controller.step_row(k, own, neighbours, inputs.reference, self.dt, self.row,
                                             hold=self.leave_point)
        self.last_command = u
        status.lost_uhs, status.role = tuple(sorted(self.tracker.known)), self.role()
        return u, status

    def carried(self) -> dict:
        """Give the lost set to send on with the command (``{uh: step declared}``)."""
        return self.tracker.carried()

    def role(self) -> str:
        """Give this UH's role now: ``lost``, ``holding (why)``, ``leader`` or ``follower`` of the team it flies."""
        if self.row is None:
            return 'starting'
        if self.unable is not None:
            return f'leaving ({CHANNELS[self.unable]} below rho {self.unable_rho:g})'
        if self.row.hold_reason is not None:
            return f'holding ({self.row.hold_reason})'
        lost = self.tracker.view()[1]
        team = self.teams.get(frozenset(lost))
        return 'leader' if team is not None and self.uh_id in team.leaders else 'follower'
