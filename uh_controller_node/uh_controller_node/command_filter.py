"""First-order command filters of the backstepping design (DESIGN.md 2.4 step 1, 2.5 steps 1-2).

A command filter turns a virtual control ``alpha`` into a smooth signal ``alpha_f`` and its
derivative without differentiating ``alpha`` analytically::

    tau alpha_f' = alpha - alpha_f

Between two control steps the input is held (zero-order hold), so the filter state is advanced
with the exact discretisation ``alpha_f <- alpha_f + (1 - exp(-dt / tau)) (alpha - alpha_f)``:
stable and free of overshoot for every ``dt > 0`` (forward Euler would need ``dt < 2 tau``).
An axis may be declared an angle: its difference ``alpha - alpha_f`` is wrapped to (-pi, pi] so
that a yaw command crossing +-pi is followed the short way; the filter state itself stays
continuous (unwrapped).
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ['FilterError', 'wrap_angle', 'FirstOrderFilter']

_TWO_PI = 2.0 * math.pi


class FilterError(ValueError):
    """Invalid filter parameter or use before initialisation."""


def wrap_angle(angle: float) -> float:
    """``angle`` rad wrapped to (-pi, pi]."""
    w = math.remainder(angle, _TWO_PI)
    return math.pi if w == -math.pi else w


class FirstOrderFilter:
    """Vector first-order filter ``tau y' = u - y`` with exact zero-order-hold stepping.

    Parameters
    ----------
    tau : float
        Time constant, s (> 0).
    size : int
        Length of the filtered vector.
    angle_axes : tuple of int
        Axes whose difference ``u - y`` is wrapped to (-pi, pi] (angles in rad).

    Attributes
    ----------
    value : ndarray (size,)
        Filter output ``y`` (do not keep references across :meth:`advance`; it is updated in place).
    initialised : bool
        False until :meth:`reset` is called.
    """

    def __init__(self, tau: float, size: int = 3, angle_axes: tuple = ()):
        if not (isinstance(tau, (int, float)) and math.isfinite(tau) and tau > 0.0):
            raise FilterError(f'filter time constant must be a finite number > 0 s, got {tau!r}')
        self.tau = float(tau)
        self.value = np.zeros(size)
        self.angle_axes = tuple(int(a) for a in angle_axes)
        self.initialised = False
        self._dt = None
        self._gain = 0.0
        self._diff = np.zeros(size)

    def reset(self, value) -> None:
        """Set the output to ``value`` (size,), e.g. the first input, so the filter starts at rest."""
        self.value[:] = value
        self.initialised = True

    def difference(self, u) -> np.ndarray:
        """``u - y`` (angle axes wrapped); a buffer valid until the next call."""
        d = np.subtract(u, self.value, out=self._diff)
        for a in self.angle_axes:
            d[a] = wrap_angle(d[a])
        return d

    def derivative(self, u) -> np.ndarray:
        """``y' = (u - y) / tau`` for input ``u`` (new array)."""
        return self.difference(u) / self.tau

    def advance(self, u, dt: float) -> None:
        """Move the output over one step ``dt`` s with ``u`` held: ``y += (1 - e^(-dt/tau)) (u - y)``."""
        if not self.initialised:
            raise FilterError('filter advanced before reset(); call reset() with the first input')
        if dt != self._dt:
            if not dt > 0.0:
                raise FilterError(f'filter step must be > 0 s, got {dt!r}')
            self._dt = dt
            self._gain = -math.expm1(-dt / self.tau)
        self.value += self._gain * self.difference(u)
