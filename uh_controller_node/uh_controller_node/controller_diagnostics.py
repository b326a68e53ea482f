"""The /diagnostics window of a controller node and its neighbours' ages, free of middleware.

Per step only counters are updated; the rest is read when a report is due, every
``diagnostics_every`` steps at the node's phase (:meth:`uh_wire.run_config.ViewConfig.diagnostics_phase`;
docs/visualization.md#diagnostics). :class:`NeighbourAges` keeps the age of each neighbour's state
the law used over the last simulated second, for the status and the reports (docs/topics.md).
"""
from __future__ import annotations

import math
from collections import deque

import numpy as np

from uh_core import diagnostics

__all__ = ['ControllerDiagnostics', 'NeighbourAges']


class NeighbourAges:
    """Age of the state of each neighbour the controller used, mean and max over the last simulated second.

    Parameters
    ----------
    neighbours : sequence of int
        The UHs heard, ascending.
    dt : float
        Control period, s; the window is the last ``round(1 / dt)`` steps (one simulated second).

    The age at step k of neighbour j's state sent at step s is ``k - s`` steps (``(k - s) dt`` s):
    under impairments that of the state delivered (the step each ``/uhN/received`` state carries),
    in real time without them that of the newest state heard (the synchroniser's lag), in lockstep
    without them 0. A neighbour left out as stale adds nothing.
    """

    def __init__(self, neighbours, dt: float):
        self.neighbours, self.dt = tuple(int(j) for j in neighbours), float(dt)
        self.window = max(1, int(round(1.0 / self.dt)))
        self._ages = {j: deque() for j in self.neighbours}   # (step, age in steps), oldest first
        self._sums = dict.fromkeys(self.neighbours, 0)
        self._peaks = {j: deque() for j in self.neighbours}  # the window's running maxima: ages decrease

    def add(self, k: int, used, received=None, lag=None) -> None:
        """Add the ages of step ``k``.

        ``used`` are the neighbours whose state the law used (the keys of the step's neighbour
        states); ``received`` the node's :class:`~uh_controller_node.impairments.ReceivedStates`
        (None without impairments), else ``lag`` the synchroniser's ``{key: LagStats}`` (realtime).
        """
        for j in self.neighbours:
            ages, peaks = self._ages[j], self._peaks[j]
            while ages and ages[0][0] <= k - self.window:
                self._sums[j] -= ages.popleft()[1]
            while peaks and peaks[0][0] <= k - self.window:
                peaks.popleft()
            if j not in used:
                continue
            if received is not None:
                age = k - received.sample_steps[j]
            else:
                age = lag[j].last if lag and j in lag else 0
            ages.append((k, age))
            self._sums[j] += age
            while peaks and peaks[-1][1] <= age:   # O(1) per step on average: the max is peaks[0]
                peaks.pop()
            peaks.append((k, age))

    def summary(self) -> tuple:
        """Return ``(mean, max)``: lists of seconds per neighbour, ascending id; NaN where none in the window."""
        means = [self._sums[j] * self.dt / len(a) if (a := self._ages[j]) else math.nan for j in self.neighbours]
        maxes = [p[0][1] * self.dt if (p := self._peaks[j]) else math.nan for j in self.neighbours]
        return means, maxes

    def overall(self) -> tuple:
        """Return ``(mean, max)`` over every neighbour and the window, s (the status fields); NaN if none."""
        count = sum(len(a) for a in self._ages.values())
        if not count:
            return math.nan, math.nan
        return (sum(self._sums.values()) * self.dt / count,
                max(p[0][1] for p in self._peaks.values() if p) * self.dt)


class ControllerDiagnostics:
    """What controller ``uh_id`` saw since its last report, and the report when one is due.

    Parameters
    ----------
    uh_id : int
        The controller's UH.
    every : int
        Steps between two reports.
    phase : int
        The step within each period at which the report is made.
    safety : bool
        The controller runs the safety filter: the reports say how often it acted and name the closest UH.
    margin : MarginWatch or None
        The team's delay margin (:class:`~uh_controller_node.delay_margin.MarginWatch`): a report whose
        neighbour ages exceed it goes WARN. None: not checked (lockstep).
    """

    def __init__(self, uh_id: int, every: int, phase: int, safety: bool = False, margin=None):
        self.uh_id, self.every, self.phase, self.safety, self.margin = uh_id, every, phase, bool(safety), margin
        self.window = diagnostics.ControllerWindow(safety=self.safety)
        self._rejected_reported = 0

    def not_computed(self) -> None:
        """Count a step the law could not compute."""
        self.window.not_computed += 1

    def add(self, k: int, inputs, status, sync, ages: NeighbourAges | None = None,
            closest_uh: int = 0) -> diagnostics.Diagnostic | None:
        """Add step ``k`` to the window; return the report if one is due at ``k``, else None.

        ``inputs`` is the step's :class:`~uh_controller_node.input_sync.StepInputs`, ``status`` the
        controller's status of the step and ``sync`` the node's
        :class:`~uh_controller_node.input_sync.InputSynchroniser` (input lags, rejected messages);
        ``ages`` the neighbours' ages, reported with their window; ``closest_uh`` the UH the safety
        filter's proximity input puts closest (0: none).
        """
        w = self.window
        w.steps += 1
        w.safety_active_steps += bool(status.safety_active)
        if status.saturated_tilt or status.saturated_collective or status.saturated_cyclic:
            w.saturated_steps += 1
        for stats in sync.lag.values():
            if stats.last > w.max_input_lag:
                w.max_input_lag = stats.last
        if k % self.every != self.phase:
            return None
        w.last_step = k
        w.closest_uh, w.closest_distance = int(closest_uh), float(status.closest_distance)
        w.stale_neighbours = tuple(inputs.stale_labels)
        w.lost_uhs, w.role = tuple(getattr(status, 'lost_uhs', ())), getattr(status, 'role', '')
        w.holding = inputs.hold is not None and not w.role   # with resilience the role says whether it holds
        w.fault_isolated = tuple(status.isolation.isolated)
        w.fault_estimate_position = float(np.linalg.norm(status.fault_estimate_position))
        w.fault_estimate_attitude = float(np.linalg.norm(status.fault_estimate_attitude))
        rejected = sum(sync.rejected.values())
        w.rejected_inputs, self._rejected_reported = rejected - self._rejected_reported, rejected
        if ages is not None:
            w.neighbour_ages = tuple(zip((f'uh{j}' for j in ages.neighbours), *ages.summary(), strict=True))
            if self.margin is not None:
                w.delay_margin_s = self.margin.margin_s(max((m for *_, m in w.neighbour_ages if m == m), default=0.0))
        self.window = diagnostics.ControllerWindow(safety=self.safety)
        return diagnostics.controller_diagnostic(self.uh_id, w)
