"""Virtual-leader reference trajectory (index 0) of the paper scenario (docs/scenario.md).

A climbing circle with a constant yaw rate, in the inertial frame (z up)::

    p0(t)   = c + [ r sin(w t),  -r cos(w t),  v_z t ]
    v0(t)   =     [ r w cos(w t), r w sin(w t), v_z ]
    a0(t)   =     [ -r w^2 sin(w t), r w^2 cos(w t), 0 ]
    psi0(t) = psi_init + psi_rate t ,   psi0'(t) = psi_rate

With ``c = (0, 10, 10) m``, ``r = 10 m``, ``w = 0.1 rad/s``, ``v_z = 0.1 m/s``, ``psi_rate = 0.1 rad/s``
this is the paper's ``x0 = 10 sin(0.1 t), y0 = 10 - 10 cos(0.1 t), z0 = 10 + 0.1 t, psi0 = 0.1 t``.
The derivatives are analytic. ``psi0`` is not wrapped (it grows with t); consumers wrap yaw errors.
"""
from __future__ import annotations

import math

import numpy as np

from uh_core.layout import R_P_SLICE, R_V_SLICE, R_YAW, REFERENCE_SIZE
from uh_core.records import Reference

__all__ = ['ReferenceParameterError', 'VirtualLeaderReference']

_FIELDS = ('radius', 'angular_rate', 'center', 'climb_rate', 'yaw_rate', 'initial_yaw')


class ReferenceParameterError(ValueError):
    """Invalid virtual-leader trajectory parameters."""


def _get(spec, name):
    if isinstance(spec, dict):
        if name not in spec:
            raise ReferenceParameterError(f'reference parameters lack {name!r}; required: {list(_FIELDS)}')
        return spec[name]
    if not hasattr(spec, name):
        raise ReferenceParameterError(f'reference parameters lack {name!r}; required: {list(_FIELDS)}')
    return getattr(spec, name)


class VirtualLeaderReference:
    """The virtual leader's trajectory from a scenario's reference parameters.

    Parameters
    ----------
    spec : object or mapping
        Anything with ``radius`` m, ``angular_rate`` rad/s, ``center`` (3,) m, ``climb_rate`` m/s,
        ``yaw_rate`` rad/s and ``initial_yaw`` rad (the ``uh_topology`` ``ReferenceSpec``, or a dict).
    """

    def __init__(self, spec):
        try:
            self.radius = float(_get(spec, 'radius'))
            self.angular_rate = float(_get(spec, 'angular_rate'))
            self.climb_rate = float(_get(spec, 'climb_rate'))
            self.yaw_rate = float(_get(spec, 'yaw_rate'))
            self.initial_yaw = float(_get(spec, 'initial_yaw'))
            center = np.array(_get(spec, 'center'), dtype=float).reshape(-1)
        except (TypeError, ValueError) as exc:
            if isinstance(exc, ReferenceParameterError):
                raise
            raise ReferenceParameterError(f'reference parameters must be numbers: {exc}') from None
        if center.shape != (3,):
            raise ReferenceParameterError(f'reference center must have 3 components, got {center.shape}')
        values = (self.radius, self.angular_rate, self.climb_rate, self.yaw_rate, self.initial_yaw)
        if not all(math.isfinite(v) for v in values) or not np.all(np.isfinite(center)):
            raise ReferenceParameterError('reference parameters must be finite')
        if self.radius < 0.0:
            raise ReferenceParameterError(f'reference radius must be >= 0 m, got {self.radius}')
        self.cx, self.cy, self.cz = (float(v) for v in center)

    @property
    def center(self) -> np.ndarray:
        """Centre of the circle at t = 0, (3,) m."""
        return np.array([self.cx, self.cy, self.cz])

    def position(self, t: float) -> np.ndarray:
        """p0(t) (3,) m."""
        wt = self.angular_rate * t
        r = self.radius
        return np.array([self.cx + r * math.sin(wt), self.cy - r * math.cos(wt),
                         self.cz + self.climb_rate * t])

    def row(self, t: float) -> np.ndarray:
        """Give ``[p_0, v_0, psi_0]`` at time ``t`` s in the controllers' layout (``uh_core.layout.R_*``)."""
        r = self.at(t)
        out = np.empty(REFERENCE_SIZE)
        out[R_P_SLICE], out[R_V_SLICE], out[R_YAW] = r.position, r.velocity, r.yaw
        return out

    def at(self, t: float) -> Reference:
        """Position, velocity, acceleration, yaw and yaw rate at time ``t`` s (analytic)."""
        t = float(t)
        w = self.angular_rate
        r = self.radius
        s, c = math.sin(w * t), math.cos(w * t)
        rw, rw2 = r * w, r * w * w
        return Reference(
            position=np.array([self.cx + r * s, self.cy - r * c, self.cz + self.climb_rate * t]),
            velocity=np.array([rw * c, rw * s, self.climb_rate]),
            acceleration=np.array([-rw2 * s, rw2 * c, 0.0]),
            yaw=self.initial_yaw + self.yaw_rate * t,
            yaw_rate=self.yaw_rate,
        )
