"""What a simulator node keeps track of about the commands it gets, free of middleware.

The step of the command held, how many steps were integrated with an older one (realtime: late
commands), whether the held command is stale (older than ``stale_timeout``), and the counts of
rejected commands and fault injections; from these, the window of its /diagnostics report
(:class:`uh_core.diagnostics.SimulatorWindow`, docs/visualization.md#diagnostics). The log messages
go to the node's logger; the node itself only converts messages and publishes.
"""
from __future__ import annotations

from uh_core.diagnostics import SimulatorWindow

__all__ = ['CommandWatch', 'LATE_COMMAND_REPORTS']

#: Late-command counts at which a warning is logged.
LATE_COMMAND_REPORTS = (1, 10, 100, 1000)


class CommandWatch:
    """The held command's step, its lateness and staleness, and the rejected inputs of one simulator.

    Parameters
    ----------
    uh_id : int
        The simulator's UH.
    dt : float
        Control period, s.
    stale_steps : int
        Steps after which a held command is stale (``stale_timeout`` / dt, at least 1).
    logger
        Where the transitions are logged (``warning`` and ``info``).
    """

    def __init__(self, uh_id: int, dt: float, stale_steps: int, logger):
        self.uh_id, self.dt, self.stale_steps, self.logger = uh_id, dt, stale_steps, logger
        self.command_step = -1        # step the held command was computed for
        self.late_commands = 0        # realtime: steps integrated with an older command
        self.command_stale = False
        self.rejected = 0             # commands rejected (not finite, another UH's id)
        self.rejected_faults = 0      # fault injections rejected
        self._reported = {'late': 0, 'rejected': 0, 'rejected_faults': 0}

    def taken(self, k: int, plant_step: int) -> None:
        """Note that the command of step ``k`` is now held (realtime: log when commands come back)."""
        self.command_step = k
        if self.command_stale:
            self.command_stale = False
            self.logger.info(f'commands arrive again (step {k}, plant at step {plant_step})')

    def integrating(self, plant_step: int) -> None:
        """Note that step ``plant_step`` is integrated with the held command; log a late or stale one."""
        if self.command_step == plant_step or plant_step <= 0:
            return
        self.late_commands += 1
        if self.late_commands in LATE_COMMAND_REPORTS:
            self.logger.warning(f'step {plant_step} integrated with the command of step {self.command_step} '
                             f'({self.late_commands} late command(s) so far)')
        if plant_step - self.command_step > self.stale_steps and not self.command_stale:
            self.command_stale = True
            self.logger.warning(f'no command since step {self.command_step} (plant at step {plant_step}, '
                             f'timeout {self.stale_steps * self.dt:g} s): holding it; is '
                             f'/uh{self.uh_id}/controller running?')

    def window(self, step: int, fault_active, stuck) -> SimulatorWindow:
        """Return the diagnostics window of the report at ``step``: counts since the previous report."""
        seen = {'late': self.late_commands, 'rejected': self.rejected, 'rejected_faults': self.rejected_faults}
        since = {key: seen[key] - self._reported[key] for key in seen}
        self._reported = seen
        return SimulatorWindow(
            last_step=step, late_commands=since['late'], rejected_commands=since['rejected'],
            rejected_faults=since['rejected_faults'], command_stale=self.command_stale,
            fault_active=fault_active, stuck=stuck)
