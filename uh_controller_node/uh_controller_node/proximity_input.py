"""The safety filter's proximity input as a controller takes it in (docs/safety.md#what-the-filter-knows).

A controller receives, each step, the proximity report of the plant side's sensing (the node:
``/uhN/proximity``, :func:`uh_wire.wire.msg_to_proximity`; in process: the true states): the ids and
``[p, v]`` rows of the UHs within the sensing radius. :class:`ProximityInput` turns the reports into
the filter's input (:meth:`~uh_controller_node.controller.UHController.set_proximity`) under the
scenario's degraded sensing (docs/safety.md#degraded-sensing): the input of step k is the newest
report sent at or before ``k - proximity_delay_steps`` that was not lost
(:func:`~uh_controller_node.safety_kernels.proximity_lost`), with its noise, predicted to step k
(:func:`~uh_controller_node.safety_kernels.degrade_proximity`). The same kernels degrade the input
of the in-process team loop, so every engine gives the same bits. It also names the closest UH for
the status and ``/diagnostics``. The control law never reads it.
"""
from __future__ import annotations

import numpy as np

from uh_core.layout import X_P

from .safety_kernels import (
    PROXIMITY_COLUMNS,
    SF_PROXIMITY_DELAY,
    SF_PROXIMITY_LOSS,
    SF_PROXIMITY_NOISE_P,
    SF_PROXIMITY_NOISE_V,
    degrade_proximity,
    proximity_lost,
)

__all__ = ['ProximityInput']


class ProximityInput:
    """The proximity reports a controller has received and the input they give its filter.

    Parameters
    ----------
    uh_id : int
        The controller's UH.
    params : ndarray
        Its filter's parameter vector (:func:`uh_controller_node.safety.safety_parameters`; empty
        when the filter is off).
    dt : float
        Control period, s.
    """

    def __init__(self, uh_id: int, params, dt: float):
        self.uh_id, self.dt = int(uh_id), float(dt)
        self.params = np.ascontiguousarray(params, dtype=float)
        on = self.params.shape[0] > 0
        self.delay = int(self.params[SF_PROXIMITY_DELAY]) if on else 0
        self.degraded = on and (self.delay > 0 or self.params[SF_PROXIMITY_LOSS] > 0.0
                                or self.params[SF_PROXIMITY_NOISE_P] > 0.0
                                or self.params[SF_PROXIMITY_NOISE_V] > 0.0)
        self.history: dict[int, tuple] = {}     # sent step -> (ids, rows), degraded sensing only
        self.ids: tuple = ()
        self.rows = np.empty((0, PROXIMITY_COLUMNS))

    def use(self, controller, proximity, k: int) -> None:
        """Take the report ``proximity`` (``(sent step, ids, rows)`` or None); give the input of step ``k``.

        Without degraded sensing the newest report is the input as it is (None: the newest held
        stays); with it, the input of step k as the module docstring says.
        """
        if proximity is not None:
            step, ids, rows = proximity
            if not self.degraded:
                self.ids, self.rows = tuple(ids), rows
                controller.set_proximity(rows)
                return
            self.history[int(step)] = (tuple(ids), rows)
        if not self.degraded:
            return
        due = k - self.delay
        chosen = next((s for s in sorted(self.history, reverse=True)
                       if s <= due and not proximity_lost(self.params, self.uh_id, s)), None)
        if chosen is None:
            self.ids, self.rows = (), np.empty((0, PROXIMITY_COLUMNS))
        else:
            for old in [s for s in self.history if s < chosen]:   # never the input again: older than chosen
                del self.history[old]
            ids, sent = self.history[chosen]
            rows = np.array(sent, dtype=float, order='C')
            degrade_proximity(rows, len(ids), np.array(ids, dtype=np.int64), self.uh_id, chosen, int(k), self.dt,
                              self.params)
            self.ids, self.rows = ids, rows
        controller.set_proximity(self.rows)

    def closest(self, own) -> int:
        """Return the id of the reported UH closest to the own state ``own`` (12,), hub to hub; 0 if none."""
        if not self.ids:
            return 0
        d = np.linalg.norm(self.rows[:, :3] - np.asarray(own)[X_P:X_P + 3], axis=1)
        return int(self.ids[int(np.argmin(d))])
