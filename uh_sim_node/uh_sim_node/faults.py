"""Actuator fault model of the unmanned helicopter (paper eq. 6; docs/faults.md, "Fault model").

Each of the four input channels ``(theta_col, theta_tr, delta_lat, delta_lon)`` (indices 0..3,
the order of :mod:`uh_core.layout`, also that of the ``CHANNEL_*`` constants of
``uh_msgs/ActuatorFault``) may carry one fault::

    u_actual(t) = rho * u(t) + b(t),   b(t) = bias_constant + bias_amplitude * sin(bias_frequency * t)

from ``onset_time`` on; before the onset ``rho = 1`` and ``b = 0``. The sinusoid uses the absolute
simulation time ``t`` (not ``t - onset_time``), as the paper writes ``b(t)``. Cases:

* no fault: ``rho = 1, b = 0``;
* loss of effectiveness only: ``0 < rho < 1, b = 0``;
* bias only: ``rho = 1, b != 0``;
* both: ``0 < rho < 1, b != 0``;
* stuck: ``rho = 0`` -- the actuator sits at ``b(t)`` whatever is commanded. It is simulated, but it
  is outside what the controller compensates, so :meth:`FaultSchedule.stuck` reports it.

Onset: a fault acts at times ``t >= onset_time - ONSET_TOLERANCE`` (1 ns), so an onset given on the
step grid (``10.0`` s) switches on exactly at the step whose time ``k * dt`` rounds to just below it.
The integrator decides the activity once per substep, at the substep's start time (``switch_time``),
and evaluates the bias at the RK4 stage times: the fault then switches on at the first substep
boundary at or after the onset (exact for onsets on the grid, at most one substep late otherwise)
and the input is smooth inside every substep, which keeps RK4 fourth order.

This module is pure Python (no ROS); the physical input limits are applied by the plant
(:class:`uh_sim_node.helicopter.HelicopterPlant`), not here. The plant evaluates eq. 6 in its
native kernels (:mod:`uh_sim_node.plant_kernels`) from a table built from the schedule, with the
same arithmetic as :meth:`ActuatorFault.apply`; :attr:`FaultSchedule.revision` tells it when the
schedule changed.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterable

from uh_core.checks import finite_real
from uh_core.layout import INPUT_NAMES, NUM_CHANNELS
from uh_core.records import FaultSpec

if TYPE_CHECKING:
    import numpy as np

__all__ = ['FaultError', 'ActuatorFault', 'FaultSchedule', 'ONSET_TOLERANCE', 'inject']

#: A time this close before the onset counts as past it, s (absorbs the rounding of ``k * dt``).
ONSET_TOLERANCE = 1e-9


class FaultError(ValueError):
    """An actuator fault with an invalid channel or parameter."""


@dataclass(frozen=True)
class ActuatorFault(FaultSpec):
    """One actuator fault on one channel (paper eq. 6).

    A :class:`~uh_core.records.FaultSpec`, validated, with the arithmetic of the fault model.

    Parameters
    ----------
    channel : int
        Input channel 0..3: 0 = main-rotor collective ``theta_col``, 1 = tail-rotor collective
        ``theta_tr``, 2 = lateral cyclic ``delta_lat``, 3 = longitudinal cyclic ``delta_lon``.
    rho : float
        Effectiveness factor in [0, 1]; 1 = fully effective, 0 = stuck.
    bias_constant, bias_amplitude : float
        Constant part and sinusoid amplitude of the bias ``b(t)``, rad.
    bias_frequency : float
        Angular frequency of the bias sinusoid, rad/s.
    onset_time : float
        Simulation time from which the fault acts, s (>= 0).

    Raises
    ------
    FaultError
        If the channel is not an int in 0..3, ``rho`` is outside [0, 1], ``onset_time`` is
        negative or any number is not finite.
    """

    def __post_init__(self):
        ch = self.channel
        if isinstance(ch, bool) or not isinstance(ch, numbers.Integral) or not 0 <= ch < NUM_CHANNELS:
            raise FaultError(f'fault channel must be an int in 0..3 '
                             f'(0 theta_col, 1 theta_tr, 2 delta_lat, 3 delta_lon), got {ch!r}')
        object.__setattr__(self, 'channel', int(ch))
        for name in ('rho', 'bias_constant', 'bias_amplitude', 'bias_frequency', 'onset_time'):
            object.__setattr__(self, name, finite_real(getattr(self, name), f'fault parameter {name!r}', FaultError))
        if not 0.0 <= self.rho <= 1.0:
            raise FaultError(f'fault rho (effectiveness) must be in [0, 1], got {self.rho!r} '
                             f'on channel {self.channel} ({INPUT_NAMES[self.channel]})')
        if self.onset_time < 0.0:
            raise FaultError(f'fault onset_time must be >= 0 s, got {self.onset_time!r} '
                             f'on channel {self.channel} ({INPUT_NAMES[self.channel]})')

    @classmethod
    def from_spec(cls, spec) -> 'ActuatorFault':
        """Build from any object with the six fault attributes (e.g. a scenario's ``FaultSpec``)."""
        return cls(spec.channel, spec.rho, spec.bias_constant, spec.bias_amplitude,
                   spec.bias_frequency, spec.onset_time)

    @classmethod
    def stuck_at(cls, channel: int, position: float, time: float) -> 'ActuatorFault':
        """Give actuator ``channel`` stuck at ``position`` rad from ``time`` s on: ``rho = 0``, that constant bias."""
        return cls(channel, rho=0.0, bias_constant=position, onset_time=time)

    @property
    def is_nominal(self) -> bool:
        """True when the fault changes nothing (``rho = 1`` and zero bias): it removes a fault."""
        return self.rho == 1.0 and self.bias_constant == 0.0 and self.bias_amplitude == 0.0

    @property
    def is_stuck(self) -> bool:
        """True for ``rho = 0`` (the actuator ignores its command)."""
        return self.rho == 0.0

    def bias(self, t: float) -> float:
        """Bias ``b(t)`` in rad at absolute time ``t`` s, ignoring the onset."""
        if self.bias_amplitude == 0.0:
            return self.bias_constant
        return self.bias_constant + self.bias_amplitude * math.sin(self.bias_frequency * t)

    @property
    def acts_from(self) -> float:
        """Earliest time the fault acts, s: ``onset_time - ONSET_TOLERANCE``."""
        return self.onset_time - ONSET_TOLERANCE

    def started(self, t: float) -> bool:
        """Return True when the fault acts at time ``t`` s (``t >= acts_from``)."""
        return t >= self.acts_from

    def apply(self, u: float, t: float, switch_time: float | None = None) -> float:
        """Actual input of this channel, rad, for command ``u`` rad at time ``t`` s.

        Whether the fault acts is decided at ``switch_time`` (default ``t``); the bias uses ``t``.
        """
        if not self.started(t if switch_time is None else switch_time):
            return u
        # one evaluation order everywhere (the plant's fast path uses it too): (rho u + c) + A sin
        if self.bias_amplitude == 0.0:
            return self.rho * u + self.bias_constant
        return (self.rho * u + self.bias_constant) + self.bias_amplitude * math.sin(self.bias_frequency * t)


class FaultSchedule:
    """The faults of one helicopter: at most one :class:`ActuatorFault` per channel.

    Parameters
    ----------
    faults : iterable of ActuatorFault, optional
        Initial faults; a later fault of the same channel replaces an earlier one.
    """

    __slots__ = ('_faults', '_list', '_revision')

    def __init__(self, faults: Iterable[ActuatorFault] = ()):
        self._faults: list = [None] * NUM_CHANNELS
        self._list: tuple = ()
        self._revision = 0
        for fault in faults:
            self.add(fault)

    @classmethod
    def from_specs(cls, specs) -> 'FaultSchedule':
        """Schedule from plain fault specs with the six :class:`ActuatorFault` attributes."""
        return cls(ActuatorFault.from_spec(s) for s in specs)

    def add(self, fault: ActuatorFault) -> None:
        """Set the fault of ``fault.channel``, replacing any earlier fault of that channel.

        A nominal fault (``rho = 1``, no bias) clears the channel at once (its onset is ignored).
        """
        if not isinstance(fault, ActuatorFault):
            raise FaultError(f'FaultSchedule.add expects an ActuatorFault, got {type(fault).__name__}')
        self._faults[fault.channel] = None if fault.is_nominal else fault
        self._changed()

    def clear(self, channel: int | None = None) -> None:
        """Remove the fault of ``channel`` (all faults when ``None``)."""
        if channel is None:
            self._faults = [None] * NUM_CHANNELS
        else:
            self._faults[channel] = None
        self._changed()

    def _changed(self) -> None:
        self._list = tuple(f for f in self._faults if f is not None)
        self._revision += 1

    @property
    def revision(self) -> int:
        """Counter bumped by every :meth:`add` and :meth:`clear`.

        Holders of a derived form of the schedule (the plant's kernel fault table, see
        :mod:`uh_sim_node.plant_kernels`) rebuild it when the revision differs from the one they
        built it from, so faults injected at run time act from the next step on.
        """
        return self._revision

    def fault(self, channel: int) -> ActuatorFault | None:
        """Return the fault of ``channel`` or ``None``."""
        return self._faults[channel]

    @property
    def faults(self) -> tuple:
        """The non-nominal faults, in channel order."""
        return self._list

    def __len__(self) -> int:
        return len(self._list)

    def __repr__(self) -> str:
        return f'FaultSchedule({list(self._list)!r})'

    def apply(self, u, t: float, switch_time: float | None = None) -> np.ndarray:
        """Actual inputs ``u_actual`` (4,) rad for commanded inputs ``u`` (4,) rad at time ``t`` s.

        Physical limits are not applied here. ``switch_time`` as in :meth:`ActuatorFault.apply`.
        """
        import numpy as np
        out = np.array(u, dtype=float)
        for f in self._list:
            out[f.channel] = f.apply(out[f.channel], t, switch_time)
        return out

    def active(self, t: float) -> bool:
        """Return True when any channel is past its onset time at ``t`` s."""
        return any(f.started(t) for f in self._list)

    def stuck(self, t: float) -> bool:
        """Return True when any active channel has ``rho = 0`` (outside what the controller compensates)."""
        return any(f.rho == 0.0 and f.started(t) for f in self._list)

    def active_channels(self, t: float) -> tuple:
        """Return the indices of the channels whose fault acts at ``t`` s."""
        return tuple(f.channel for f in self._list if f.started(t))


def inject(plant, msg, uh_id: int, command, t: float) -> ActuatorFault:
    """Apply a run-time injection ``msg`` (``uh_msgs/ActuatorFault``) to UH ``uh_id``'s ``plant``; give the fault.

    ``stuck_in_place`` sticks the channel where ``command`` (4,) rad holds it at ``t`` s
    (:meth:`uh_sim_node.helicopter.HelicopterPlant.stick`); otherwise the message's fault replaces
    the channel's. Raises :class:`FaultError` for a message meant for another UH or an invalid fault
    (the plant is left as it was).
    """
    if int(msg.uh_id) != uh_id:
        raise FaultError(f'it names uh{msg.uh_id} but arrived on /uh{uh_id}/fault')
    channel = int(msg.channel)
    if getattr(msg, 'stuck_in_place', False):
        if not 0 <= channel < NUM_CHANNELS:
            raise FaultError(f'fault channel must be an int in 0..3, got {channel}')
        return plant.stick(channel, command, t)
    fault = ActuatorFault(channel=channel, rho=float(msg.rho), bias_constant=float(msg.bias_constant),
                          bias_amplitude=float(msg.bias_amplitude), bias_frequency=float(msg.bias_frequency),
                          onset_time=float(msg.onset_time))
    plant.faults.add(fault)
    return fault
