"""Checks of numbers at the boundary, shared by the records that validate their fields."""
from __future__ import annotations

import math
import numbers

__all__ = ['finite_real']


def finite_real(value, what: str, error: type[Exception]) -> float:
    """``value`` as a float if it is a finite real number (not a bool), else ``error`` naming ``what``.

    ``what`` names the value for the message, e.g. ``"fault parameter 'rho'"``.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise error(f'{what} must be a real number, got {value!r} of type {type(value).__name__}')
    value = float(value)
    if not math.isfinite(value):
        raise error(f'{what} must be finite, got {value!r}')
    return value
