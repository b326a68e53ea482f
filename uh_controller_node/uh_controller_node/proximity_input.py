"""The safety filter's proximity input as a controller node holds it (docs/safety.md#what-the-filter-knows).

The node receives ``/uhN/proximity`` (:func:`uh_wire.wire.msg_to_proximity`: the ids and ``[p, v]``
rows of the UHs within the sensing radius), gives the rows to the filter
(:meth:`~uh_controller_node.controller.UHController.set_proximity`) and names the closest UH in its
status and ``/diagnostics``. The control law never reads it.
"""
from __future__ import annotations

import numpy as np

from uh_core.layout import X_P

__all__ = ['ProximityInput']


class ProximityInput:
    """The newest proximity input a controller node gave its safety filter."""

    def __init__(self):
        self.ids: tuple = ()
        self.rows = np.empty((0, 6))

    def use(self, controller, proximity) -> None:
        """Give ``controller`` the rows of ``proximity`` (``(ids, rows)``; None: keep the newest held)."""
        if proximity is not None:
            self.ids, self.rows = proximity
            controller.set_proximity(self.rows)

    def closest(self, own) -> int:
        """Return the id of the reported UH closest to the own state ``own`` (12,), hub to hub; 0 if none."""
        if not self.ids:
            return 0
        d = np.linalg.norm(self.rows[:, :3] - np.asarray(own)[X_P:X_P + 3], axis=1)
        return int(self.ids[int(np.argmin(d))])
