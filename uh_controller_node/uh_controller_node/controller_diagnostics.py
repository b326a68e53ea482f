"""The /diagnostics window of a controller node, free of middleware (docs/visualization.md#diagnostics).

Per step only counters are updated; the rest is read when a report is due, every
``diagnostics_every`` steps at the node's phase (:meth:`uh_wire.run_config.ViewConfig.diagnostics_phase`).
"""
from __future__ import annotations

import numpy as np

from uh_core import diagnostics

__all__ = ['ControllerDiagnostics']


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
    """

    def __init__(self, uh_id: int, every: int, phase: int):
        self.uh_id, self.every, self.phase = uh_id, every, phase
        self.window = diagnostics.ControllerWindow()
        self._rejected_reported = 0

    def not_computed(self) -> None:
        """Count a step the law could not compute."""
        self.window.not_computed += 1

    def add(self, k: int, inputs, status, sync) -> diagnostics.Diagnostic | None:
        """Add step ``k`` to the window; return the report if one is due at ``k``, else None.

        ``inputs`` is the step's :class:`~uh_controller_node.input_sync.StepInputs`, ``status`` the
        controller's status of the step and ``sync`` the node's
        :class:`~uh_controller_node.input_sync.InputSynchroniser` (input lags, rejected messages).
        """
        w = self.window
        w.steps += 1
        if status.saturated_tilt or status.saturated_collective or status.saturated_cyclic:
            w.saturated_steps += 1
        for stats in sync.lag.values():
            if stats.last > w.max_input_lag:
                w.max_input_lag = stats.last
        if k % self.every != self.phase:
            return None
        w.last_step = k
        w.stale_neighbours = tuple(inputs.stale_labels)
        w.holding = inputs.hold is not None
        w.fault_isolated = tuple(status.isolation.isolated)
        w.fault_estimate_position = float(np.linalg.norm(status.fault_estimate_position))
        w.fault_estimate_attitude = float(np.linalg.norm(status.fault_estimate_attitude))
        rejected = sum(sync.rejected.values())
        w.rejected_inputs, self._rejected_reported = rejected - self._rejected_reported, rejected
        self.window = diagnostics.ControllerWindow()
        return diagnostics.controller_diagnostic(self.uh_id, w)
