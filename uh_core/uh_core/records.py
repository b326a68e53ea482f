"""Plain records that cross package boundaries: a virtual-leader sample and an actuator fault.

:class:`Reference` is what the virtual leader publishes and a controller reads
(``uh_core.reference`` makes it, ``uh_wire.wire`` carries it); :class:`FaultSpec` is what a
scenario lists (``uh_topology.scenario``) and the simulator acts on (``uh_sim_node.faults``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

__all__ = ['Reference', 'FaultSpec']


@dataclass(frozen=True, eq=False)
class Reference:
    """Virtual-leader sample at one time.

    Attributes
    ----------
    position, velocity, acceleration : ndarray (3,)
        m, m/s, m/s^2 in the inertial frame (z up).
    yaw : float
        psi0, rad (not wrapped).
    yaw_rate : float
        psi0', rad/s.
    """

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw: float
    yaw_rate: float


@dataclass(frozen=True)
class FaultSpec:
    """One actuator fault (paper eq. 6) as plain data (docs/faults.md).

    What a scenario lists and a fault injection carries. The simulator's
    ``uh_sim_node.faults.ActuatorFault`` is this record, validated, with the fault model's arithmetic.

    ``channel`` 0..3 (theta_col, theta_tr, delta_lat, delta_lon); ``rho`` in [0, 1]; bias
    ``b(t) = bias_constant + bias_amplitude sin(bias_frequency t)`` rad (frequency rad/s);
    ``onset_time`` s.
    """

    channel: int
    rho: float
    bias_constant: float = 0.0
    bias_amplitude: float = 0.0
    bias_frequency: float = 0.0
    onset_time: float = 0.0
