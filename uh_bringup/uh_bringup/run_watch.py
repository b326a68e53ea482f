"""Watching a running team: the progress line, and what a node's death means for the run.

- lockstep: every step needs every node, so any death ends the run;
- realtime: the clock, the virtual leader and the recorder are essential (the run ends); a
  simulator's death loses that helicopter, whose neighbours report it stale and fly on without it; a
  controller is restarted with ``--respawn`` (up to :data:`MAX_RESPAWNS` times) and rejoins the
  running team, otherwise its helicopter flies on with the last command it got; the visualisation
  and the live view are not needed.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

__all__ = ['MAX_RESPAWNS', 'RunProgress', 'RunWatcher', 'neighbours_of']

#: how often --respawn restarts one controller before giving up on it
MAX_RESPAWNS = 3


class RunProgress:
    """Progress line on stderr from the clock's log ('step k/K ...' lines), redrawn in place on a tty."""

    def __init__(self, log_path: Path):
        self.log_path, self.offset, self.last = log_path, 0, ''
        self.team_complete = False
        self.tty = sys.stderr.isatty()

    def update(self) -> None:
        """Read what the clock logged since the last look; print its newest progress line."""
        try:
            with open(self.log_path, errors='replace') as f:
                f.seek(self.offset)
                chunk = f.read()
                self.offset = f.tell()
        except OSError:
            return
        for line in chunk.splitlines():
            if 'team complete' in line:
                self.team_complete = True
            if 'step ' in line or 'team complete' in line or 'run complete' in line:
                self.last = line.split(']: ')[-1]
                print(('\r\033[K' if self.tty else '') + f'[run] {self.last}', end='' if self.tty else '\n',
                      file=sys.stderr, flush=True)

    def close(self) -> None:
        """End the progress line redrawn in place."""
        if self.tty and self.last:
            print(file=sys.stderr)


def neighbours_of(scenario, uh_id: int) -> list:
    """Return the UHs whose controllers hear ``uh_id``."""
    return [i for i in scenario.ids if uh_id in scenario.neighbours(i)]


class RunWatcher:
    """Watches a running team and decides what a node's death means (see the module docstring).

    ``args`` are the run's options (clock mode, rate, stale timeout, ``--respawn``), ``scenario`` its
    team, ``sup`` its :class:`~uh_bringup.supervisor.Supervisor`, ``progress`` its :class:`RunProgress`;
    ``on_change()`` is called after every node death (to rewrite ``run.json``).
    """

    def __init__(self, args, scenario, sup, progress, on_change=lambda: None):
        self.args, self.scenario, self.sup, self.progress = args, scenario, sup, progress
        self.on_change = on_change
        self.failures: list = []     # every node death: dicts for run.json
        self.fatal = None            # the NodeProcess whose death ended the run
        self.team_started = None     # wall time of the clock's 'team complete'

    def sim_time(self) -> str:
        """Return about when in the run it is, for the failure report."""
        if self.args.clock == 'realtime' and self.team_started is not None:
            return f'sim t ~ {(time.monotonic() - self.team_started) * self.args.rate:.1f} s'
        return self.progress.last or 'before the team was complete'

    def handle(self, node) -> None:
        """Report the death of ``node``, record it and act on it (stop, respawn or go on)."""
        what = node.describe()
        entry = {'node': node.name, 'kind': node.kind, 'how': what, 'returncode': node.returncode,
                 'wall_s': round(time.monotonic() - self.started, 2), 'when': self.sim_time()}
        action, note = self.decide(node)
        entry['action'] = action
        self.failures.append(entry)
        print(f'\n[run] node {node.name} {what} ({entry["when"]}); log {node.log_path}:\n{node.log_tail(8)}',
              file=sys.stderr)
        print(f'[run] {note}', file=sys.stderr)
        if action == 'stop':
            self.fatal = node
        elif action == 'respawn':
            self.sup.respawn(node)
        self.on_change()

    def decide(self, node) -> tuple[str, str]:
        """Return what the death of ``node`` means: ``(stop | respawn | continue, the reason)``."""
        kind = node.kind
        if kind == 'live_view':  # a viewer never stops the team, in either clock mode
            return 'continue', 'the live view is not needed by the team; the run goes on without it'
        if self.args.clock == 'lockstep':
            return 'stop', 'lockstep: every step needs every node; stopping the run'
        if kind in ('clock', 'virtual_leader', 'recorder'):
            return 'stop', f'the {kind.replace("_", " ")} is essential to the run; stopping it'
        if kind == 'visualization':
            return 'continue', 'the visualisation is not needed by the team; the run goes on without markers'
        uh = int(node.name[2:].split('_')[0])
        if kind == 'sim' and self.scenario.resilience is not None:
            spec = self.scenario.resilience
            return 'continue', (f'UH{uh} is lost; the UHs that hear it declare it lost after {spec.lost_timeout:g} s '
                                f'and the team {"re-forms" if spec.on_loss == "reform" else "holds"} '
                                '(docs/resilience.md); the run goes on')
        if kind == 'sim':
            hearers = ', '.join(f'uh{i}' for i in neighbours_of(self.scenario, uh)) or 'no UH'
            return 'continue', (f'UH{uh} is lost; {hearers} hear it and report it stale after '
                                f'{self.args.stale_timeout:g} s (status.stale_neighbours), then fly on without it '
                                'or hold position; the run goes on')
        if kind == 'controller':
            if self.args.respawn and node.restarts < MAX_RESPAWNS:
                return 'respawn', (f'restarting {node.name} ({node.restarts + 1}/{MAX_RESPAWNS}); it rejoins the '
                                   'running team at the current step')
            why = f'it was restarted {MAX_RESPAWNS} times already' if self.args.respawn else 'no --respawn'
            return 'continue', (f'UH{uh} flies on with its last command ({why}); the run goes on')
        return 'stop', 'stopping the run'

    def watch(self, interrupted: list) -> None:
        """Follow the run until the clock ends, a death stops it or ``interrupted`` gets a signal."""
        clock = self.sup.nodes[-1]
        self.started = time.monotonic()
        while not interrupted:
            self.progress.update()
            if self.team_started is None and self.progress.team_complete:
                self.team_started = time.monotonic()
            if clock.poll() is not None:
                break
            for node in self.sup.exited(ignore=(clock.name,)):
                self.handle(node)
            if self.fatal is not None:
                return
            time.sleep(0.1)
        self.progress.update()
        if not interrupted and clock.poll() not in (None, 0):
            self.handle(clock)
            self.fatal = clock
