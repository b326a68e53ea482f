"""Clock advancement of a team run, without ROS: which ``/clock`` step comes next, and when.

:class:`ClockAdvancer` is the decision part of the clock node
(:class:`uh_sim_node.clock_node.ClockNode`); the node discovers the team, feeds it the commands and
the recorder's progress, publishes the steps it returns and runs the timers it asks for (clock
modes: docs/architecture.md, "Clock modes"; realtime start and end: docs/reliability.md section 2).

- ``lockstep``: after step 0, step k+1 is released only when every UH has commanded step k and, if
  a recorder is expected, the recorder has written everything up to step
  k - ``recorder_lag_steps``. After the last step K the run is complete once the recorder has
  written step K (at once without a recorder).
- ``realtime``: after step 0 the clock waits until every UH has commanded step 0 (the team is live),
  at most ``start_wait`` wall seconds, then the node's timer calls :meth:`ClockAdvancer.tick` every
  :attr:`ClockAdvancer.tick_period` = dt / rate wall seconds, each tick releasing the next step
  whatever the commands. After the last tick the run is complete once the recorder confirms step K,
  or when the node gives up waiting (:meth:`ClockAdvancer.give_up`).

Units: steps are control steps (t_k = k dt simulated seconds); wall time (the start-up wait, the
progress and completion lines' wall time and real-time factor) is read from the injectable
``now()`` in seconds, so tests run it on a fake clock. Log lines go to ``logger`` (``info``,
``warning``).
"""
from __future__ import annotations

import time
from typing import Callable

from uh_wire import topics

__all__ = ['ClockAdvancer', 'REALTIME_START_WAIT_S', 'REALTIME_FINAL_WAIT_S']

#: realtime: how long after the last tick the clock waits for the recorder to confirm the last step
REALTIME_FINAL_WAIT_S = 5.0
#: realtime: how long the clock waits at step 0 for every UH's first command before ticking anyway
REALTIME_START_WAIT_S = 10.0


class ClockAdvancer:
    """The step sequence of one run (see the module docstring).

    Parameters
    ----------
    ids : sequence of int
        The UHs of the team (each commands every step).
    mode : {'lockstep', 'realtime'}
    dt : float
        Control period, simulated seconds.
    last_step : int
        Index K of the last step.
    logger
        Receives the progress and completion lines (``info``, ``warning``).
    rate : float
        realtime: simulated seconds per wall second.
    expect_recorder : bool
        Whether the run is complete only once the recorder has written the last step (and, in
        lockstep, whether the clock waits for the recorder to stay within ``recorder_lag_steps``).
    recorder_lag_steps : int
        lockstep: steps the recorder may lag behind the clock.
    start_wait : float
        realtime: wall seconds to wait at step 0 for every UH's first command.
    now : callable() -> float
        Wall clock, seconds (default :func:`time.monotonic`).

    Attributes
    ----------
    step : int
        The step last released (-1 before :meth:`start`).
    recorded_step : int
        The newest step the recorder confirmed (-1: none).
    ticking : bool
        realtime: the ticks have started.
    done : bool
        The run is complete (or was stopped with :meth:`stop`).
    """

    def __init__(self, ids, *, mode: str, dt: float, last_step: int, logger, rate: float = 1.0,
                 expect_recorder: bool = False, recorder_lag_steps: int = topics.RECORDER_LAG_STEPS,
                 start_wait: float = REALTIME_START_WAIT_S, now: Callable[[], float] = time.monotonic):
        if mode not in ('lockstep', 'realtime'):
            raise ValueError(f'clock mode {mode!r}; allowed: lockstep, realtime')
        self.ids, self.lockstep = tuple(ids), mode == 'lockstep'
        self.dt, self.last_step, self.rate = float(dt), int(last_step), float(rate)
        self.expect_recorder, self.recorder_lag_steps = bool(expect_recorder), int(recorder_lag_steps)
        self.start_wait, self.now, self.logger = float(start_wait), now, logger
        self.step = -1
        self.commands: dict[int, set[int]] = {}   # step -> UHs that commanded it
        self.recorded_step = -1
        self.started_wall = None    # wall s when the stepping started (the real-time factor's origin)
        self.live_deadline = None   # realtime: wall s until which the ticks wait for step 0's commands
        self.ticking = False
        self.done = False

    @property
    def tick_period(self) -> float:
        """realtime: wall seconds between two ticks, dt / rate."""
        return self.dt / self.rate

    def start(self) -> list:
        """Release step 0 now that the team is complete (returns ``[0]``)."""
        self.started_wall = self.now()
        if not self.lockstep:
            self.live_deadline = self.started_wall + self.start_wait
        return [self._release(0)]

    def stop(self) -> None:
        """End the run without completing it (the team never came up)."""
        self.done = True

    # -- inputs ------------------------------------------------------------------------------------
    def on_command(self, uh_id: int, k: int) -> list:
        """Note that UH ``uh_id`` commanded step ``k``; return the steps now released (lockstep), in order.

        realtime: only the commands of step 0 before the ticks start count (see :meth:`start_ticking`).
        """
        if self.lockstep:
            self.commands.setdefault(k, set()).add(uh_id)
            return self._advance()
        if not self.ticking and k == 0:
            self.commands.setdefault(0, set()).add(uh_id)
        return []

    def on_progress(self, recorded_step: int) -> list:
        """Note that the recorder has written everything up to ``recorded_step``; return the steps now released."""
        self.recorded_step = recorded_step
        if self.lockstep:
            return self._advance()
        if self.step >= self.last_step:
            self.finish_when_recorded()
        return []

    # -- lockstep ----------------------------------------------------------------------------------
    def _advance(self) -> list:
        out = []
        n = len(self.ids)
        while self.step >= 0 and not self.done and len(self.commands.get(self.step, ())) == n:
            if self.step == self.last_step:
                self.finish_when_recorded()
                break
            if self.expect_recorder and self.recorded_step < self.step - self.recorder_lag_steps:
                break  # the recorder is behind; on_progress retries
            self.commands.pop(self.step, None)
            out.append(self._release(self.step + 1))
        return out

    # -- realtime ----------------------------------------------------------------------------------
    def start_ticking(self) -> bool:
        """Return whether the realtime ticks start now.

        They start when every UH commanded step 0, or the start-up wait is over (logged). True once;
        False in lockstep, before :meth:`start` and when done.
        """
        if self.lockstep or self.ticking or self.done or self.live_deadline is None:
            return False
        answered = self.commands.get(0, set())
        if len(answered) < len(self.ids):
            if self.now() < self.live_deadline:
                return False
            missing = sorted(set(self.ids) - answered)
            self.logger.warning(f'no command of step 0 from uh{", uh".join(map(str, missing))} after '
                                f'{self.start_wait:g} s: starting the realtime ticks anyway')
        self.commands.pop(0, None)
        self.started_wall = self.now()   # the real-time factor counts the ticking loop
        self.ticking = True
        return True

    def tick(self) -> int | None:
        """Return the next step to publish (realtime timer), or None after the last one.

        After the last one the ticks end; the run completes when the recorder confirms the last
        step, or on :meth:`give_up`.
        """
        if self.step < self.last_step:
            return self._release(self.step + 1)
        self.finish_when_recorded()
        return None

    def give_up(self, waited: float = REALTIME_FINAL_WAIT_S) -> None:
        """realtime: the recorder did not confirm the last step within ``waited`` wall seconds; end the run."""
        if not self.done:
            self.logger.warning(f'the recorder did not confirm the last step within {waited} s '
                                f'(recorded up to step {self.recorded_step}); ending the run')
            self.finish_when_recorded(force=True)

    # -- steps and completion ----------------------------------------------------------------------
    def _release(self, k: int) -> int:
        """Make ``k`` the current step; log progress every tenth of the run."""
        self.step = k
        if k and k % max(1, self.last_step // 10) == 0:
            wall = self.now() - self.started_wall
            self.logger.info(f'step {k}/{self.last_step}: sim {k * self.dt:.2f} s, wall {wall:.2f} s, '
                             f'real-time factor {k * self.dt / max(wall, 1e-9):.2f}')
        return k

    def finish_when_recorded(self, force: bool = False) -> None:
        """Complete the run if the recorder (when expected) has the last step, or ``force``."""
        if self.done or (self.expect_recorder and self.recorded_step < self.last_step and not force):
            return
        wall = self.now() - self.started_wall
        self.logger.info(f'run complete: {self.last_step} steps, sim {self.last_step * self.dt:.2f} s '
                         f'in {wall:.2f} s wall (real-time factor {self.last_step * self.dt / max(wall, 1e-9):.2f})')
        self.done = True
