"""``scripts/compare.sh``: the proposed law, Case I and Case II on one scenario, and one report comparing them.

Runs each case (docs/control_law.md#comparison-cases) with ``scripts/run_formation.sh`` (lockstep
clock, one process per node, recorded to MCAP) or, with ``--simulate``, with ``uh-simulate`` (the
in-process reference simulation), one after the other, into ``DIR/proposed``, ``DIR/case1`` and
``DIR/case2``, then ``uh-report`` of the three into ``DIR/report``.

Everything is checked before the first run: the scenario and its gains (for every case),
``--duration`` (a whole number of control periods) and ``--out`` (new or empty, and writable).

Exit status: 0 written; 2 bad input (nothing ran); otherwise the status of the run or report that
failed (the runs before it are kept in DIR); 130 interrupted.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

from uh_controller_node.gains import CASES
from uh_runtime.command_line import ArgumentParser
from uh_topology.errors import ScenarioError
from uh_topology.safety import add_safety_argument, safety_override
from uh_topology.scenario import duration_steps, load_scenario

from .run_checks import UsageError, prepare_out, validate_team

__all__ = ['main', 'build_parser', 'PROG']

PROG = 'compare.sh'


def _text(what: str):
    """Return an argparse type that refuses an empty value of ``what``."""
    def parse(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"'': give {what}")
        return text
    return parse


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``scripts/compare.sh``."""
    p = ArgumentParser(
        prog=PROG,
        description='Run the proposed law, Case I and Case II on a scenario and write one report comparing '
                    'them (the paper\'s Figures 10-12 and the metrics table side by side).',
        epilog='Output: DIR/proposed, DIR/case1, DIR/case2 (the runs) and DIR/report/ (report.md, index.html, '
               'metrics_table.csv, figures). Exit status: 0 done, 2 bad input (nothing ran), else the status '
               'of the step that failed.')
    p.add_argument('--out', type=_text('a directory'), default=None, metavar='DIR',
                   help='new or empty output directory (default: runs/compare-<date>-<time> in the repository)')
    p.add_argument('--duration', type=float, default=None, metavar='S',
                   help='simulated time of each run, s (default: the scenario\'s); a whole number of control periods')
    p.add_argument('--scenario', type=_text('a scenario file or a bundled name'), default='paper',
                   metavar='FILE|NAME', help='scenario YAML file or bundled name (default: paper)')
    p.add_argument('--simulate', action='store_true',
                   help='in-process reference simulation (uh-simulate) instead of the distributed stack: same '
                        'controllers, same numbers, a few seconds per case')
    add_safety_argument(p)
    p.add_argument('--default-root', type=Path, default=Path('runs'), help=argparse.SUPPRESS)
    return p


def _check(args) -> Path:
    """Check the scenario, its gains, --duration and --out before anything runs; return the output directory."""
    try:
        scenario = load_scenario(args.scenario, safety=safety_override(args.safety))
        for case in CASES:
            validate_team(scenario, case)
    except ScenarioError as exc:
        raise UsageError(str(exc)) from None
    except ValueError as exc:     # what the plant or the controller rejects, in their own words
        raise UsageError(f'scenario {args.scenario!r}: {exc}') from None
    if args.duration is not None:
        try:
            duration_steps(args.duration, scenario.dt)
        except ValueError as exc:
            raise UsageError(f'--duration {exc}') from None
    out = Path(args.out) if args.out else args.default_root / f'compare-{time.strftime("%Y%m%d-%H%M%S")}'
    if out.is_dir() and any(out.iterdir()):
        raise UsageError(f'--out {out}: exists and is not empty; choose a new or empty directory')
    prepare_out(out, force=False)
    return out


def _commands(args, out: Path) -> list:
    """Return the ``(label, argv)`` of every step: the three runs, then the report."""
    python = [sys.executable, '-P', '-m']
    extra = ['--duration', repr(args.duration)] if args.duration is not None else []
    if args.safety is not None:
        extra += ['--safety', args.safety]
    steps = []
    for case in CASES:
        if args.simulate:
            argv = python + ['uh_team.simulate_cli', '--scenario', args.scenario]
        else:
            # the combined report below replaces the per-run ones
            argv = python + ['uh_bringup.run_formation', '--scenario', args.scenario, '--clock', 'lockstep',
                             '--no-report']
        steps.append((case, argv + ['--case', case, '--out', str(out / case), *extra]))
    steps.append(('report', python + ['uh_report.report', *(str(out / case) for case in CASES),
                                      '--scenario', args.scenario, '--out', str(out / 'report')]))
    return steps


def main(argv=None) -> int:
    """Entry point of ``scripts/compare.sh``; returns the exit status (see the module docstring)."""
    args = build_parser().parse_args(argv)
    try:
        out = _check(args)
    except UsageError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    try:
        for label, command in _commands(args, out):
            print(f'[compare] {label}', file=sys.stderr, flush=True)
            status = subprocess.call(command)
            if status != 0:
                print(f'{PROG}: error: {label} ended with exit status {status}; what is done so far is in {out}',
                      file=sys.stderr)
                return status
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted; what is done so far is in {out}', file=sys.stderr)
        return 130
    print(f'[compare] report: {out / "report" / "report.md"} and {out / "report" / "index.html"}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
