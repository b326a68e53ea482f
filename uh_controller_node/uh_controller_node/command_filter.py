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

    Works on plain Python floats (the vectors are short and the controller steps them tens of
    thousands of times per scenario; numpy's per-call overhead would dominate).

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
    value : list of float (size,)
        Filter output ``y``, updated in place by :meth:`advance`.
    initialised : bool
        False until :meth:`reset` is called.
    """

    def __init__(self, tau: float, size: int = 3, angle_axes: tuple = ()):
        if isinstance(tau, bool) or not (isinstance(tau, (int, float)) and math.isfinite(tau) and tau > 0.0):
            raise FilterError(f'filter time constant must be a finite number > 0 s, got {tau!r}')
        self.tau = float(tau)
        self.size = int(size)
        self.value = [0.0] * self.size
        self.angle_axes = tuple(int(a) for a in angle_axes)
        self.initialised = False
        self._dt = None
        self._gain = 0.0

    def reset(self, value) -> None:
        """Set the output to ``value`` (size,), e.g. the first input, so the filter starts at rest."""
        self.value = [float(v) for v in value]
        self.initialised = True

    def difference(self, u) -> list:
        """``u - y`` (angle axes wrapped), list of floats."""
        d = [float(a) - b for a, b in zip(u, self.value)]
        for a in self.angle_axes:
            d[a] = wrap_angle(d[a])
        return d

    def derivative(self, u) -> list:
        """``y' = (u - y) / tau`` for input ``u``, list of floats."""
        inv = 1.0 / self.tau
        return [inv * d for d in self.difference(u)]

    def advance(self, u, dt: float) -> None:
        """Move the output over one step ``dt`` s with ``u`` held: ``y += (1 - e^(-dt/tau)) (u - y)``."""
        if not self.initialised:
            raise FilterError('filter advanced before reset(); call reset() with the first input')
        if dt != self._dt:
            if not dt > 0.0:
                raise FilterError(f'filter step must be > 0 s, got {dt!r}')
            self._dt = dt
            self._gain = -math.expm1(-dt / self.tau)
        g = self._gain
        self.value = [y + g * d for y, d in zip(self.value, self.difference(u))]
