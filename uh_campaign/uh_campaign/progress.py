"""What a campaign shows while it runs and at its end: the progress line and the summary.

Owns :class:`Progress` (runs done, failures, rate and ETA on stderr, a bar on a terminal) and the
per-case summary of the results file (:func:`summary_lines`, :func:`success_text`) ``uh-campaign``
prints when the campaign ends.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from uh_team import campaign_store as store

from .spec import CampaignSpec

__all__ = ['Progress', 'summary_lines', 'success_text']


#: Characters of the progress bar drawn on a terminal.
_BAR_WIDTH = 30


class Progress:
    """Progress of a campaign on a stream (stderr).

    Runs done / total, failures, runs/s and ETA. On a terminal a bar on one line rewritten in place (at most 5 times a
    second); otherwise a line at every further 10 % of the runs. ``quiet`` writes nothing.

    ``stream`` defaults to stderr, ``tty`` to whether the stream is a terminal; ``label`` starts each
    line.
    """

    def __init__(self, stream=None, quiet: bool = False, tty: bool | None = None, label: str = 'uh-campaign'):
        self.stream = stream if stream is not None else sys.stderr
        self.quiet = quiet
        self.tty = bool(tty if tty is not None else getattr(self.stream, 'isatty', lambda: False)())
        self.label = label
        self.total = self.first = 0
        self._t0 = time.monotonic()
        self._last_write = 0.0
        self._next_tenth = 1
        self._open_line = False

    def start(self, total: int, done: int) -> None:
        """Start counting: ``total`` runs, ``done`` of them stored before (announced when resuming)."""
        self.total, self.first = total, done
        self._t0 = time.monotonic()
        if done:
            self.note(f'resuming: {done} of {total} runs already stored')
        self._next_tenth = (10 * done) // max(total, 1) + 1

    def note(self, text: str) -> None:
        """Print ``text`` on a line of its own, after the progress line (nothing when ``quiet``)."""
        if not self.quiet:
            self._end_line()
            print(f'{self.label}: {text}', file=self.stream, flush=True)

    def update(self, done: int, failures: int) -> None:
        """Show ``done`` runs and ``failures`` (on a terminal at most 5 times a second, else every 10 %)."""
        if self.quiet:
            return
        now = time.monotonic()
        finished = done >= self.total
        if self.tty:
            if not finished and now - self._last_write < 0.2:
                return
            self._last_write = now
            self.stream.write('\r' + self._line(done, failures, now) + '\x1b[K')
            self._open_line = True
            if finished:
                self._end_line()
            self.stream.flush()
        elif 10 * done >= self._next_tenth * self.total:
            self._next_tenth = (10 * done) // max(self.total, 1) + 1
            print(self._line(done, failures, now), file=self.stream, flush=True)

    def _line(self, done, failures, now) -> str:
        elapsed = max(now - self._t0, 1e-9)
        rate = (done - self.first) / elapsed
        left = self.total - done
        eta = _duration(left / rate) if rate > 0 and left else ('0 s' if not left else '?')
        pct = 100.0 * done / max(self.total, 1)
        filled = int(_BAR_WIDTH * done / max(self.total, 1))
        bar = f'[{"#" * filled}{"." * (_BAR_WIDTH - filled)}] ' if self.tty else ''
        return (f'{self.label}: {bar}{done}/{self.total} runs ({pct:.0f} %), {failures} not ok, '
                f'{rate:.2f} runs/s, ETA {eta}')

    def _end_line(self) -> None:
        if self._open_line:
            self.stream.write('\n')
            self._open_line = False


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    if seconds < 60:
        return f'{seconds} s'
    if seconds < 3600:
        return f'{seconds // 60} min {seconds % 60:02d} s'
    return f'{seconds // 3600} h {seconds % 3600 // 60:02d} min'


def summary_lines(directory, spec: CampaignSpec) -> list:
    """Per case (and sweep value).

    Runs stored, success count and rate, median formation and containment RMS of the ``ok`` runs (from the results
    file).
    """
    runs = store.read_runs(Path(directory) / store.DB_NAME)
    lines = []
    sweep = spec.sweep is not None
    for s, value in enumerate(spec.sweep_values):
        if sweep:
            lines.append(f'{spec.sweep.parameter} = {value}:')
        for case in spec.cases:
            mask = (runs['case_name'] == case) & (runs['sweep_index'] == s)
            n = int(mask.sum())
            ok = mask & (runs['status'] == 'ok')
            wins = int((runs['success'][mask] == 1).sum())
            rate = f'{100.0 * wins / n:.1f} %' if n else 'n/a'

            def median(column, ok=ok):   # called in this iteration: ``ok`` bound explicitly
                values = runs[column][ok]
                values = values[np.isfinite(values)]
                return f'{np.median(values):.4g} m' if values.size else 'n/a'

            bad = n - int(ok.sum())
            lines.append(f'{"  " if sweep else ""}{case:9s} {wins}/{n} succeeded ({rate}), '
                         f'median formation RMS {median("formation_rms_m")}, containment RMS '
                         f'{median("containment_rms_m")}' + (f', {bad} not ok' if bad else '')
                         + (_losses_text(runs, ok) if spec.draws.losses is not None else ''))
    return lines


def _losses_text(runs: dict, ok) -> str:
    """Say how the ``ok`` runs of a campaign with drawn losses came through them: re-formed, worst times, closest."""
    reform, closest = runs['reform_time_s'][ok], runs['loss_min_separation_m'][ok]
    reformed = reform[np.isfinite(reform)]
    text = f'; re-formed {reformed.size}/{reform.size}'
    if reformed.size:
        text += f' (largest {np.max(reformed):.2f} s after the loss)'
    closest = closest[np.isfinite(closest)]
    return text + (f', closest approach after a loss {np.min(closest):.3f} m' if closest.size else '')


def success_text(spec: CampaignSpec) -> str:
    """Return the spec's success criterion in words."""
    return ', '.join(f'{m} <= {t:g}' for m, t in spec.success.items()) or 'status ok'
