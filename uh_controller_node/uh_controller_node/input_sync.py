"""Input synchronisation of one UH's controller, without ROS: which inputs step k is computed from.

:class:`InputSynchroniser` is the part of the controller node
(:class:`uh_controller_node.controller_node.ControllerNode`) that decides *when* step k is computed
and *with what*; the node converts the messages (:mod:`uh_wire.wire`), offers the values here, runs
:class:`~uh_controller_node.controller.UHController` on the :class:`StepInputs` it gets back and
publishes. The behaviour is that of docs/reliability.md section 2 (clock modes:
docs/architecture.md, "Clock modes"):

- ``lockstep``: step k is released once the own state k, every neighbour's state k and (if the UH
  hears the virtual leader) reference k are in, in step order; a value of an older step than the
  next one to compute is ignored, a repeated one replaces the earlier copy.
- ``realtime``: each own state k starts step k. It is released as soon as every input of step k is
  in (inputs already known to be stale are not waited for), else by :meth:`InputSynchroniser.poll`
  ``sync_wait`` wall seconds later with the latest valid values (latest-value semantics). A value
  older than the one held is ignored. An input whose newest step is more than ``stale_timeout``
  (as steps) behind k is *stale*, as is one never heard ``startup_grace`` wall seconds after the
  first own state; stale inputs are left out and, when the remaining graph gives the UH no path
  from the virtual leader (Assumption 1, docs/graph.md "Conditions checked when a scenario is
  loaded"), the UH holds the position and yaw it had then. A synchroniser whose first own state is
  not step 0 (a controller restarted in a running team) skips history until its own state is the
  newest step it knows of.

Units: steps are control steps (t_k = k dt simulated seconds; ``stale_timeout`` is given in
simulated seconds and used as whole steps). Wall time (sync wait, start-up grace, own-state silence,
the rate limit of rejection reports) is read from the injectable ``now()`` in seconds, so tests run
it on a fake clock. Log lines go to ``logger`` (anything with ``info``, ``warning`` and ``error``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

from uh_core.layout import X_P, X_THETA, YAW
from uh_wire import topics
from uh_wire.run_config import DEFAULT_STALE_TIMEOUT

__all__ = ['InputSynchroniser', 'StepInputs', 'LagStats', 'OWN', 'REFERENCE', 'PROXIMITY', 'input_label',
           'REJECT_LOG_PERIOD']

#: Key of the UH's own state; neighbours are keyed by their id (int).
OWN = 'own'
#: Key of the virtual leader's reference.
REFERENCE = 'ref'
#: Key of the safety filter's proximity input (``/uhN/proximity``; not an input of the control law).
PROXIMITY = 'proximity'
#: Wall seconds between two logged rejections of the same input (the count goes on meanwhile).
REJECT_LOG_PERIOD = 1.0
#: Wall seconds (at least; ``startup_grace`` if longer) without an own state before it is reported.
OWN_SILENCE_S = 1.0


def input_label(key) -> str:
    """Name of an input in logs and ``ControllerStatus.stale_neighbours``: ``uhJ`` or ``reference``."""
    return 'reference' if key == REFERENCE else f'uh{key}'


@dataclass(frozen=True)
class StepInputs:
    """What step ``step`` is computed from.

    Attributes
    ----------
    step : int
        Step index k (t_k = k dt simulated seconds).
    own : ndarray (12,)
        The UH's own state of step k.
    neighbours : dict[int, ndarray (12,)]
        Newest valid state of every neighbour that is not stale, ascending id (all neighbours
        unless ``stale``).
    reference : Reference or None
        The virtual leader's newest valid sample; None when the UH does not hear it or it is stale.
    stale : tuple
        Keys (neighbour ids, :data:`REFERENCE`) of the inputs left out; empty: the full law.
    hold : tuple (ndarray (3,) m, float rad) or None
        Position and yaw to hold while the remaining graph breaks Assumption 1.
    proximity : object or None
        The newest proximity input (the safety filter's; lockstep: that of step k); None when the
        UH has none or none has come yet.
    """

    step: int
    own: object
    neighbours: dict
    reference: object = None
    stale: tuple = ()
    hold: tuple | None = None
    proximity: object = None

    @property
    def stale_labels(self) -> list:
        """:func:`input_label` of every stale input, in ``stale`` order."""
        return [input_label(key) for key in self.stale]


@dataclass
class LagStats:
    """How many steps an input's newest valid value was behind the own state, over computed steps."""

    total: int = 0
    count: int = 0
    worst: int = 0
    last: int = 0

    def add(self, behind: int) -> None:
        """Count one computed step at which the input was ``behind`` steps behind the own state."""
        self.last = behind
        self.total += behind
        self.count += 1
        self.worst = max(self.worst, behind)

    @property
    def mean(self) -> float:
        """Mean lag over the counted steps, steps (0 before any)."""
        return self.total / max(self.count, 1)


class InputSynchroniser:
    """Assembles the inputs of each control step of UH ``uh_id`` (see the module docstring).

    Parameters
    ----------
    uh_id : int
    neighbours : sequence of int
        The UHs heard (a_ij != 0), ascending.
    linked : bool
        Whether the UH hears the virtual leader (a_i0 != 0).
    mode : {'lockstep', 'realtime'}
    dt : float
        Control period, simulated seconds.
    last_step : int
        Index K of the run's last step; nothing later is released.
    reachable : callable(set of int) -> bool
        Whether the UH still has a path from the virtual leader without the given UHs (0 = the
        reference), e.g. :meth:`UHController.reachable_without`.
    sensed : bool
        The UH has a proximity input (:data:`PROXIMITY`, its safety filter is on). Lockstep waits
        for that of step k like any input; realtime waits for it like a neighbour's state but never
        counts it stale or leaves it out: the filter keeps the newest it has (docs/safety.md).
    stale_timeout : float
        Simulated seconds an input may lag the own state before it is stale (at least one step).
    sync_wait : float
        realtime: wall seconds to wait for same-step data before using the latest.
    startup_grace : float
        realtime: wall seconds after the first own state before an input never heard is stale.
    now : callable() -> float
        Wall clock, seconds (default :func:`time.monotonic`).
    logger
        Receives the log lines (``info``, ``warning``, ``error``).

    Attributes
    ----------
    stale : tuple
        realtime: keys of the inputs stale at the last released step.
    hold : tuple or None
        realtime: the (position, yaw) held, while the remaining graph breaks Assumption 1.
    rejected : dict[str, int]
        Messages rejected per input name (:meth:`reject`).
    lag : dict[key, LagStats]
        realtime: lag of each input behind the own state at the released steps.
    """

    def __init__(self, uh_id: int, neighbours, linked: bool, *, mode: str, dt: float, last_step: int,
                 reachable: Callable[[set], bool], logger, sensed: bool = False,
                 stale_timeout: float = DEFAULT_STALE_TIMEOUT,
                 sync_wait: float = 0.004, startup_grace: float = 1.0,
                 now: Callable[[], float] = time.monotonic):
        if mode not in ('lockstep', 'realtime'):
            raise ValueError(f'clock mode {mode!r}; allowed: lockstep, realtime')
        self.uh_id, self.neighbours, self.linked = int(uh_id), tuple(neighbours), bool(linked)
        self.lockstep, self.dt, self.last_step = mode == 'lockstep', float(dt), int(last_step)
        self.reachable, self.logger, self.now = reachable, logger, now
        self.sync_wait, self.startup_grace = float(sync_wait), float(startup_grace)
        self.stale_steps = max(1, int(round(float(stale_timeout) / self.dt)))
        self.input_keys = (*self.neighbours, *((REFERENCE,) if self.linked else ()))
        self.sensed = bool(sensed)
        self.next_step = 0                   # lockstep: the next step to release
        self._pending: dict[int, dict] = {}  # lockstep: step -> {key: value}
        self.latest: dict = {}               # realtime: key -> (step, newest valid value)
        self.waiting = None                  # realtime: (step, wall deadline) of the step being assembled
        self.newest_step = -1                # realtime: newest step of any valid input
        self.joined = False                  # realtime: a step has been released
        self.rejoining = False               # realtime: the first own state was of a running team (k > 0)
        self.first_own_wall = self.last_own_wall = None
        self.own_silent_reported = False
        self.stale: tuple = ()
        self.hold = None
        self.rejected: dict[str, int] = {}
        self._reject_logged: dict[str, float] = {}
        self.lag: dict = {}

    # -- inputs ------------------------------------------------------------------------------------
    def offer(self, key, k: int, value) -> list:
        """Take in a valid input value for step ``k``; return the :class:`StepInputs` now released, in order.

        ``key`` names the input: :data:`OWN`, a neighbour id or :data:`REFERENCE`.
        """
        if key != OWN and key not in self.input_keys and not (key == PROXIMITY and self.sensed):
            raise ValueError(f'uh{self.uh_id} does not hear {input_label(key)}')
        if self.lockstep:
            if k >= self.next_step:
                self._pending.setdefault(k, {})[key] = value
            return self._ready_steps()
        held = self.latest.get(key)
        if held is not None and k < held[0]:
            return []  # older than what is held (reordered, or history replayed after a restart)
        self.latest[key] = (k, value)
        self.newest_step = max(self.newest_step, k)
        if key == OWN and not self._own_arrived(k):
            return []
        if self.rejoining and not self.joined:
            # a controller joining a running team (restarted) first receives the transient-local
            # history of every input, topic by topic as its writers are matched; releasing a step
            # as soon as one old step's inputs were complete would compute commands for steps long
            # gone. Its first step is released by the timer (poll), sync_wait after the newest own
            # state: once the backlog is in.
            return []
        return self._assemble(from_timer=False)

    def poll(self) -> list:
        """Release the step waited for once its sync wait is over; report a silent own state.

        The realtime timer (nothing in lockstep). Call it after every message already received has
        been offered, so a backlog (a process that was not scheduled for a while) is taken in before
        anything counts as stale.
        """
        return [] if self.lockstep else self._assemble(from_timer=True)

    def reject(self, what: str, reason) -> None:
        """Count a rejected message of input ``what`` and log why.

        It logs at most once per :data:`REJECT_LOG_PERIOD` wall seconds per input; the last valid
        value is kept.
        """
        count = self.rejected[what] = self.rejected.get(what, 0) + 1
        now = self.now()
        last = self._reject_logged.get(what)
        if last is None or now - last >= REJECT_LOG_PERIOD:
            self._reject_logged[what] = now
            self.logger.error(f'rejected {what}: {reason}; keeping the last valid one ({count} rejected so far)')

    # -- lockstep ----------------------------------------------------------------------------------
    def _ready_steps(self) -> list:
        out = []
        needed = 1 + len(self.input_keys) + int(self.sensed)
        while self.next_step <= self.last_step and len(self._pending.get(self.next_step, ())) == needed:
            inputs = self._pending.pop(self.next_step)
            out.append(StepInputs(self.next_step, inputs[OWN], {j: inputs[j] for j in self.neighbours},
                                  inputs.get(REFERENCE), proximity=inputs.get(PROXIMITY)))
            self.next_step += 1
        return out

    # -- realtime ----------------------------------------------------------------------------------
    def _own_arrived(self, k: int) -> bool:
        """Book an own state of step k; whether it starts step k (False: history to skip)."""
        now = self.now()
        self.last_own_wall = now
        if self.first_own_wall is None:
            self.first_own_wall = now
            if k > 0:
                self.rejoining = True
                self.logger.info(f'joining a running team at step {k} or later')
        if self.own_silent_reported:
            self.own_silent_reported = False
            self.logger.info(f'own state arrives again (step {k})')
        if not self.joined and k < self.newest_step - 1:
            return False  # history of a running team: wait for the current step
        self.waiting = (k, now + self.sync_wait)
        return True

    def _assemble(self, from_timer: bool) -> list:
        now = self.now()
        if self.waiting is None:
            self._check_own_silence(now)
            return []
        k, deadline = self.waiting
        if k > self.last_step:
            self.waiting = None
            return []
        steps = {key: self.latest[key][0] for key in self.input_keys if key in self.latest}
        unheard = [key for key in self.input_keys if key not in steps]
        if unheard and now - self.first_own_wall < self.startup_grace:
            return []  # waits for the first message of every input
        still_stale = [key for key in self.stale if key in unheard or steps[key] < k - self.stale_steps]
        if all(key in still_stale or (key in steps and steps[key] >= k) for key in self.input_keys) \
                and self._proximity_in(k):
            pass  # every input of step k is in, except those already known to be stale: no waiting for them
        elif not from_timer or now < deadline:
            return []  # late or stale data is judged by the timer only (see poll)
        self.waiting = None
        for key, s in steps.items():
            self.lag.setdefault(key, LagStats()).add(max(0, k - s))
        stale = tuple(key for key in self.input_keys if key in unheard or steps[key] < k - self.stale_steps)
        self._update_stale(stale, k)
        self.joined = True
        latest = self.latest
        return [StepInputs(k, latest[OWN][1], {j: latest[j][1] for j in self.neighbours if j not in stale},
                           latest[REFERENCE][1] if self.linked and REFERENCE not in stale else None,
                           stale, self.hold, latest[PROXIMITY][1] if PROXIMITY in latest else None)]

    def _proximity_in(self, k: int) -> bool:
        """realtime: whether step k need not wait for the proximity input.

        True without one, when that of step k is in, or when the newest is more than the staleness
        timeout old (the sensing node is silent: the filter goes on with the newest it has).
        """
        if not self.sensed:
            return True
        newest = self.latest.get(PROXIMITY, (-1,))[0]
        return newest >= k or (newest < k - self.stale_steps and self.now() - self.first_own_wall >= self.startup_grace)

    def _check_own_silence(self, now: float) -> None:
        """Log once when the own state stops arriving (the UH's simulator is gone or cut off)."""
        if (self.last_own_wall is not None and not self.own_silent_reported
                and now - self.last_own_wall > max(OWN_SILENCE_S, self.startup_grace)
                and self.latest[OWN][0] < self.last_step):
            self.own_silent_reported = True
            self.logger.warning(f'no own state for {now - self.last_own_wall:.1f} s (newest step '
                                f'{self.latest[OWN][0]}): is {topics.uh_namespace(self.uh_id)}/sim running? '
                                'No command is computed until it comes back')

    def _update_stale(self, stale: tuple, k: int) -> None:
        """Log the inputs that became stale or fresh at step k; enter or leave the position hold."""
        if stale == self.stale:
            return
        for key in stale:
            if key not in self.stale:
                newest = self.latest[key][0] if key in self.latest else None
                self.logger.warning(
                    f'{input_label(key)} is stale at step {k}: '
                    + (f'newest valid step {newest}' if newest is not None else 'never heard')
                    + f' (timeout {self.stale_steps} steps = {self.stale_steps * self.dt:g} s)')
        for key in self.stale:
            if key not in stale:
                self.logger.info(f'{input_label(key)} is fresh again at step {k}')
        self.stale = stale
        lost = {0 if key == REFERENCE else key for key in stale}
        if stale and not self.reachable(lost):
            if self.hold is None:
                own = self.latest[OWN][1]
                self.hold = (own[X_P:X_P + 3].copy(), float(own[X_THETA + YAW]))
                p = self.hold[0]
                self.logger.warning(
                    f'without {" and ".join(map(input_label, stale))}, uh{self.uh_id} has no path from the '
                    f'virtual leader (Assumption 1): holding position ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m, '
                    f'yaw {self.hold[1]:.3f} rad')
        elif self.hold is not None:
            self.hold = None
            self.logger.info('the graph gives a path from the virtual leader again: following the team')
        elif stale:
            left = [input_label(key) for key in self.input_keys if key not in stale]
            self.logger.warning(f'continuing with {", ".join(left)} (the remaining graph satisfies Assumption 1)')

    # -- summaries ---------------------------------------------------------------------------------
    def rejected_summary(self) -> str:
        """``'state of uh2 3, reference 1'``: messages rejected per input ('' if none)."""
        return ', '.join(f'{what} {n}' for what, n in self.rejected.items())

    def lag_summary(self) -> str:
        """One log line of the mean/max lag of every input behind the own state ('' if none)."""
        if not self.lag:
            return ''
        return 'input lag behind the own state (steps, mean/max): ' + ', '.join(
            f'{input_label(key)} {stats.mean:.2f}/{stats.worst}' for key, stats in self.lag.items())
