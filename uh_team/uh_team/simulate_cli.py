"""``uh-simulate``: the in-process reference simulation of a team (docs/scenario.md, docs/metrics.md).

Runs every UH's plant and controller in one process (the same controller objects the distributed
nodes use) and writes ``DIR/metrics.json`` (docs/metrics.md) and ``DIR/timeseries.npz`` (time,
states, commands, reference, true and estimated lumped faults, designed accelerations, consensus
errors, saturation flags and formation/containment errors per UH; see
:class:`uh_team.team_simulation.TeamRun`).

Exit status: 0 success, 1 the simulation diverged, 2 bad input (scenario, gains, arguments, output
directory), 130 interrupted.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

import numpy as np

from uh_controller_node.delay_margin import margin_lines
from uh_controller_node.gains import CASES, scenario_gains
from uh_runtime.command_line import ArgumentParser, directory_argument, unwritable_reason
from uh_topology.errors import ScenarioError
from uh_topology.safety import add_safety_argument, overlap_line, safety_override
from uh_topology.scenario import duration_steps, load_scenario

from .metric_registry import summary_keys
from .metrics import LUMPED_FAULTS, NOT_MEANINGFUL_MARK, metrics_from_arrays, nrmse_below_floor
from .team_simulation import SimulationError, run_team_simulation

__all__ = ['main', 'build_parser']

PROG = 'uh-simulate'


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``uh-simulate``."""
    p = ArgumentParser(
        prog=PROG,
        description='Run a UH team scenario in one process with the per-UH composite-learning '
                    'inverse-optimal fault-tolerant controllers and write DIR/metrics.json and '
                    'DIR/timeseries.npz.',
        epilog='Example: uh-simulate --scenario paper --case proposed --out runs/proposed')
    p.add_argument('--scenario', default='paper', metavar='FILE|NAME',
                   help="scenario YAML file, or the name of a bundled scenario (default: paper)")
    p.add_argument('--case', default='proposed', choices=CASES,
                   help='controller case of docs/control_law.md#comparison-cases (default: proposed)')
    p.add_argument('--out', required=True, type=directory_argument, metavar='DIR',
                   help='output directory (created; must be empty unless --force)')
    p.add_argument('--duration', type=float, metavar='S',
                   help='simulated time in seconds (default: the scenario duration)')
    p.add_argument('--force', action='store_true',
                   help='write into a non-empty output directory, replacing metrics.json and timeseries.npz')
    add_safety_argument(p)
    return p


class _Progress:
    """A one-line progress bar on stderr (only used when stderr is a terminal)."""

    def __init__(self, stream, label: str, width: int = 40):
        self.stream, self.label, self.width = stream, label, width
        self._last = -1

    def __call__(self, k: int, total: int) -> None:
        pct = int(100 * k / total) if total else 100
        if pct == self._last:
            return
        self._last = pct
        filled = self.width * pct // 100
        self.stream.write(f'\r{self.label} [{"#" * filled}{"." * (self.width - filled)}] {pct:3d}%')
        if k >= total:
            self.stream.write('\n')
        self.stream.flush()


def _fail(message: str, status: int = 2) -> int:
    print(f'{PROG}: error: {message}', file=sys.stderr)
    return status


def _check_out_dir(out: Path, force: bool):
    """Make ``out`` a writable directory before anything runs; return what is wrong with it, or None."""
    if out.exists() and not out.is_dir():
        return f'--out {str(out)!r} exists and is not a directory'
    if out.is_dir() and any(out.iterdir()) and not force:
        return f'--out {str(out)!r} is not empty; choose a new directory or pass --force to overwrite'
    reason = unwritable_reason(out)
    if reason is not None:
        return f'--out {str(out)!r}: cannot write there ({reason}); choose a directory you can write to'
    return None


def _number(value, spec: str = '.4g') -> str:
    return 'n/a' if value is None else format(value, spec)


def _fault_lines(metrics: dict) -> list[str]:
    """Console lines of the fault metrics (docs/metrics.md).

    The false fault estimate's maximum over the UHs against its threshold, then the absolute RMS error and NRMSE of
    every scored vector (``n/m`` below the NRMSE floor).
    """
    false_estimate = metrics['false_fault_estimate']
    lines = [f'  {"false estimate " + v.symbol:22s} max over UHs {_number(false_estimate["max"][v.key])} {v.unit} '
             f'(threshold {false_estimate["threshold"][v.key]:g})' for v in LUMPED_FAULTS]
    for uh, entry in metrics['fault_estimation'].items():
        for v in LUMPED_FAULTS:
            if v.key not in entry:
                continue
            scores = entry[v.key]
            nrmse = NOT_MEANINGFUL_MARK if nrmse_below_floor(scores) else _number(scores['nrmse'], '.3f')
            lines.append(f'  {"fault " + uh + " " + v.symbol:22s} RMS error {_number(scores["rms_error"])} {v.unit}, '
                         f'NRMSE {nrmse}')
    return lines


def _reconfiguration_lines(metrics: dict) -> list:
    """Give one line per loss event of ``metrics['reconfiguration']`` (docs/resilience.md)."""
    events = metrics.get('reconfiguration') or ()
    lines = ['  (the metrics above score the scenario\'s team, lost UHs included; each loss is scored against '
             'its new team in metrics.json\'s reconfiguration)'] if events else []
    for event in events:
        times = ', '.join(f'{what} {_number(event[key], ".2f")} s' for what, key in (
            ('detected', 'detected_at_s'), ('agreed', 'agreed_at_s'), ('re-formed', 'reformed_at_s')))
        promoted = ''.join(f', UH{uh} promoted to slot {slot}' for slot, uh in event['promoted'].items())
        holding = ''.join(f', UH{uh} holds ({why})' for uh, why in event['holding'].items())
        lines.append(f'  UH{event["uh"]} lost at {event["time_s"]:g} s ({event["on_loss"]}): {times}; leaders '
                     f'{event["leaders"]}, followers {event["followers"]}{promoted}{holding}; closest approach '
                     f'{_number(event["min_separation_m"], ".2f")} m')
    return lines


def main(argv=None) -> int:
    """Entry point of ``uh-simulate``; returns the exit status (see module docstring)."""
    try:
        return _main(argv)
    except BrokenPipeError:
        # stdout closed early (e.g. piped into `head`): the files are written; stay quiet
        try:
            sys.stdout = open(os.devnull, 'w')
        except OSError:
            pass
        return 0


def _main(argv) -> int:
    args = build_parser().parse_args(argv)
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0.0):
        return _fail(f'--duration must be a finite number of seconds > 0, got {args.duration!r}')
    try:
        scenario = load_scenario(args.scenario, safety=safety_override(args.safety))
        scenario_gains(scenario, args.case)    # the gains file, checked before anything is written
    except ScenarioError as exc:
        return _fail(f'invalid scenario: {exc}')
    if args.duration is not None:
        try:
            duration_steps(args.duration, scenario.dt)
        except ValueError as exc:
            return _fail(f'--duration {exc}')
    problem = _check_out_dir(args.out, args.force)
    if problem:
        return _fail(problem)
    for issue in scenario.separation_warnings:
        print(f'{PROG}: warning: {issue.text()}: closer than the minimum separation (docs/safety.md)', file=sys.stderr)
    for line in margin_lines(scenario, args.case):
        print(f'{PROG}: {line}', file=sys.stderr)
    progress = _Progress(sys.stderr, f'{scenario.name}/{args.case}') if sys.stderr.isatty() else None
    try:
        run = run_team_simulation(scenario, args.case, duration=args.duration, progress=progress)
    except SimulationError as exc:
        diverged = 'non-finite' in str(exc)
        return _fail(str(exc), status=1 if diverged else 2)
    except KeyboardInterrupt:
        if progress is not None:
            sys.stderr.write('\n')
        return _fail('interrupted', status=130)
    except ScenarioError as exc:     # the gains (named by their file and line)
        return _fail(str(exc))
    except ValueError as exc:        # scenario content the plant or controller rejects (own types)
        return _fail(f'{type(exc).__name__}: {exc}')

    metrics = metrics_from_arrays(run.arrays(), scenario, args.case, wall_time_s=run.wall_time)
    try:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / 'metrics.json').write_text(json.dumps(metrics, indent=2) + '\n')
        np.savez(args.out / 'timeseries.npz', **run.arrays())
    except OSError as exc:
        return _fail(f'cannot write to {str(args.out)!r}: {exc.strerror or exc}')

    if run.stuck_uhs:
        print(f'{PROG}: warning: stuck actuator (rho = 0) on UH(s) {list(run.stuck_uhs)}: outside what '
              'the controller can compensate', file=sys.stderr)
    if not run.all_finite():
        return _fail('the run produced NaN or infinite values', status=1)
    print(f'{scenario.name} / {args.case}: {metrics["sim_time_s"]:g} s simulated in {run.wall_time:.2f} s')
    for key in summary_keys():
        print(f'  {key:22s} {_number(metrics[key])}')
    for line in _fault_lines(metrics):
        print(line)
    for line in _reconfiguration_lines(metrics):
        print(line)
    isolation = metrics['fault_isolation']
    if isolation is not None:
        summary = isolation['summary']
        print(f'  {"fault isolation":22s} false isolations {summary["false_isolations"]}, missed '
              f'{summary["missed"]}, max delay {_number(summary["max_delay"], ".2f")} s')
    print(f'wrote {args.out / "metrics.json"} and {args.out / "timeseries.npz"}')
    sys.stdout.flush()          # a closed pipe shows up here, inside main()'s handler
    overlap = overlap_line(metrics, scenario.safety.enabled)
    if overlap:
        print(f'{PROG}: warning: {overlap}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
