"""What ``ros2 launch uh_bringup formation.launch.py`` does around the team's nodes, ROS-free.

docs/ros2.md#launching-the-team says it for users.

The launch file is thin: it declares :data:`ARGUMENTS` and turns what :class:`LaunchRun` decides
into launch actions. A launch goes through these steps, so that it leaves what
``scripts/run_formation.sh`` leaves (``run.json``, ``metrics.json``, ``report/index.html``):

1. **Compile the kernels** (:func:`compile_command`, ``python -m uh_team.compile_kernels``) before
   any node starts. On a fresh install numba's cache is empty, and a dozen node processes each
   compiling the model and the control law on their own took longer than the clock's startup
   timeout; compiled once here, the nodes load them from the cache (about a second when it is warm).
2. **Run the team**: the nodes of :func:`uh_bringup.team_nodes.node_specs`, and ``OUT/run.json``
   (:func:`write_launch_record`) saying what was run.
3. **The clock ends** with status 0: the run is complete; the recorder is stopped (it finalises
   the bag) while the other nodes wait.
4. **The recorder has ended**: ``python -m uh_bringup.launch_run OUT`` (:func:`after_run_command`,
   :func:`main`) computes ``metrics.json`` and writes the report with the functions
   ``run_formation.sh`` uses (:mod:`uh_bringup.run_outcome`), and completes ``run.json``.
5. **That has ended**: the launch shuts down ('run complete'), with status 1 if the metrics could
   not be computed.

A failed clock, a dead recorder, or in lockstep any node that fails, ends the launch with status
1 (:class:`RunFailed`), as does a launch in which no node could start at all.
"""
from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

from uh_bringup.run_outcome import (
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    recover_bag_if_needed,
    write_metrics,
    write_run_json,
)
from uh_controller_node.gains import CASES
from uh_runtime.command_line import ArgumentParser, unwritable_reason
from uh_runtime.scheduling import DEFAULT_PRIORITY, MAX_PRIORITY
from uh_topology.safety import SAFETY_CHOICES, safety_override
from uh_topology.scenario import load_scenario
from uh_wire.run_defaults import BACKENDS, CLOCK_MODES, DEFAULT_STALE_TIMEOUT, DEFAULT_STARTUP_TIMEOUT

__all__ = ['ARGUMENTS', 'LaunchOptions', 'check_arguments', 'compile_command', 'after_run_command', 'Step',
           'LaunchRun', 'RunFailed', 'write_launch_record', 'update_launch_record', 'main']

#: ``(name, default, description)`` of every launch argument (``ros2 launch ... --show-args``)
ARGUMENTS = (
    ('scenario', 'paper', 'scenario YAML or "paper"'),
    ('case', 'proposed', 'proposed | case1 | case2'),
    ('safety', '', "on | off: the collision-avoidance filter (docs/safety.md); empty: the scenario's safety.enabled"),
    ('clock_mode', 'realtime', 'lockstep | realtime'),
    ('rate', '1.0', 'realtime factor'),
    ('duration', '', "simulated s (default: the scenario's)"),
    ('out', '', 'run directory: OUT/bag, OUT/run.json, OUT/metrics.json, OUT/report (default runs/launch_<timestamp>)'),
    ('metrics', 'true', 'compute OUT/metrics.json from the bag after the run (false: no metrics and no report)'),
    ('report', 'true', "write the run's report OUT/report/index.html: metrics, errors, XY snapshots "
                       '(false: like run_formation.sh --no-report)'),
    ('visualization', 'true', 'start the visualisation node'),
    ('standard_views', 'true', 'publish /tf, /uhN/odom and /diagnostics (docs/visualization.md)'),
    ('backend', 'rclpy', 'rclpy: the team on rclpy (recorder, visualisation on the DDS backend); dds: every node '
                         'on the Cyclone DDS backend (for realtime on small machines, docs/performance.md)'),
    ('startup_timeout', str(DEFAULT_STARTUP_TIMEOUT),
     's to wait for all nodes (counted once the kernels are compiled)'),
    ('stale_timeout', str(DEFAULT_STALE_TIMEOUT), 'realtime: simulated s after which a neighbour is stale'),
    ('realtime_priority', str(DEFAULT_PRIORITY),
     'realtime: SCHED_FIFO priority of the clock, simulators, controllers and virtual leader (needs CAP_SYS_NICE '
     '(root has it) or an rtprio limit; each node logs whether it got it); 0: normal scheduling '
     '(docs/performance.md)'),
)

_TRUE, _FALSE = ('true', '1'), ('false', '0')


class RunFailed(RuntimeError):
    """The run did not complete: ``ros2 launch`` shuts everything down and exits with status 1.

    (launch turns an exception in an event handler into a shutdown and exit status 1.)
    """


@dataclass(frozen=True)
class LaunchOptions:
    """The checked launch arguments (:func:`check_arguments`)."""

    scenario: str
    case: str
    safety: bool | None      # --safety: True on, False off, None the scenario's
    clock_mode: str
    rate: float
    duration: float | None
    out: Path
    metrics: bool
    report: bool
    visualization: bool
    standard_views: bool
    backend: str
    startup_timeout: float
    stale_timeout: float
    realtime_priority: int


def _bad(name: str, value: str, allowed: str) -> ValueError:
    """Return the error of one launch argument: ``launch argument NAME:='VALUE'; allowed...`` (``allowed`` goes on)."""
    return ValueError(f'launch argument {name}:={value!r}; allowed{allowed}')


def _boolean(values: dict, name: str) -> bool:
    value = values[name]
    if value.lower() in _TRUE + _FALSE:
        return value.lower() in _TRUE
    raise _bad(name, value, ' true or false')


def _number(values: dict, name: str) -> float:
    try:
        number = float(values[name])
    except ValueError:
        number = float('nan')
    if not 0 < number < float('inf'):
        raise _bad(name, values[name], ' a number > 0')
    return number


def check_arguments(values: dict, now=None) -> LaunchOptions:
    """Return the launch arguments ``{name: text}`` (every name of :data:`ARGUMENTS`) checked.

    Raises
    ------
    ValueError
        One line: ``launch argument NAME:='VALUE'; allowed ...`` (also for an ``out`` that
        cannot be written). The scenario is loaded by the caller, with its own errors.
    """
    if values['backend'] not in BACKENDS:
        raise _bad('backend', values['backend'], ': ' + ', '.join(BACKENDS))
    if values['case'] not in CASES:
        raise _bad('case', values['case'], ': ' + ', '.join(CASES))
    if values['safety'] not in ('', *SAFETY_CHOICES):
        raise _bad('safety', values['safety'], ': ' + ', '.join(SAFETY_CHOICES) + " or empty (the scenario's)")
    if values['clock_mode'] not in CLOCK_MODES:
        raise _bad('clock_mode', values['clock_mode'], ': ' + ', '.join(CLOCK_MODES))
    text = values['realtime_priority']
    priority = int(text) if text.strip().isdigit() else -1
    if not 0 <= priority <= MAX_PRIORITY:
        raise _bad('realtime_priority', text, f' an integer 0 (normal scheduling) .. {MAX_PRIORITY}')
    stamp = time.strftime('%Y%m%d_%H%M%S', time.localtime(now))
    out = Path(values['out'] or f'runs/launch_{stamp}')
    problem = unwritable_reason(out)
    if problem is not None:
        raise _bad('out', values['out'], f' a directory that can be written ({out}: {problem})')
    return LaunchOptions(
        scenario=values['scenario'], case=values['case'], safety=safety_override(values['safety'] or None),
        clock_mode=values['clock_mode'],
        rate=_number(values, 'rate'), duration=_number(values, 'duration') if values['duration'] else None,
        out=out, metrics=_boolean(values, 'metrics'), report=_boolean(values, 'report'),
        visualization=_boolean(values, 'visualization'), standard_views=_boolean(values, 'standard_views'),
        backend=values['backend'], startup_timeout=_number(values, 'startup_timeout'),
        stale_timeout=_number(values, 'stale_timeout'), realtime_priority=priority)


def compile_command(python: str) -> list:
    """Return the command of step 1: compile every kernel into numba's cache (``uh_team.compile_kernels``)."""
    return [python, '-m', 'uh_team.compile_kernels']


def after_run_command(python: str, options: LaunchOptions, wall_time: float) -> list:
    """Return the command of step 4: metrics, report and ``run.json`` of the run in ``options.out`` (:func:`main`)."""
    return [python, '-m', 'uh_bringup.launch_run', str(options.out), '--wall-time', f'{wall_time:.3f}'] + \
        ([] if options.report else ['--no-report'])


def write_launch_record(options: LaunchOptions, duration: float, safety: bool, environ=None,
                        departures: dict | None = None) -> None:
    """Write ``OUT/run.json`` at the start of the launch: what was run, ``exit_status`` None until the end.

    Its ``scenario``, ``case`` and ``safety`` (whether the safety filter ran, ``'on'``/``'off'``) are
    what ``uh-report OUT`` reads, as for a run of ``run_formation.sh``; ``departures`` are the
    scenario's departures from the paper (docs/delay.md#remedies).
    """
    environ = os.environ if environ is None else environ
    write_run_json(options.out, {
        'command': sys.argv, 'launch': True, 'scenario': options.scenario, 'case': options.case,
        'safety': 'on' if safety else 'off', 'departures': dict(departures or {}),
        'clock': options.clock_mode, 'rate': options.rate, 'processes': 'per-node', 'backend': options.backend,
        'visualization': options.visualization, 'standard_views': options.standard_views, 'duration_s': duration,
        'domain_id': int(environ.get('ROS_DOMAIN_ID') or 0), 'realtime_priority': options.realtime_priority,
        'exit_status': None})


def update_launch_record(out: Path, **fields) -> None:
    """Add ``fields`` to ``OUT/run.json`` (written by :func:`write_launch_record`); nothing if it is missing or bad."""
    try:
        info = json.loads((Path(out) / 'run.json').read_text())
    except (OSError, ValueError):
        return
    info.update(fields)
    write_run_json(Path(out), info)


class Step(NamedTuple):
    """What the launch does next.

    ``what`` is one of:

    - ``'none'``: nothing;
    - ``'stop'``: stop the node named ``detail`` (SIGINT, as at a shutdown);
    - ``'run'``: run the command ``detail`` (a list) and call :meth:`LaunchRun.after_run_ended` when it ends;
    - ``'shutdown'``: shut the launch down, for the reason ``detail``.
    """

    what: str
    detail: object = None


NOTHING = Step('none')


class LaunchRun:
    """The course of one launch (module docstring): given what ended, decide the next :class:`Step`.

    Parameters
    ----------
    options : LaunchOptions
        The launch's arguments.
    python : str
        The interpreter of the steps' commands (the launch's own, which imports the project).
    clock : callable
        Monotonic seconds (injectable for tests).
    """

    def __init__(self, options: LaunchOptions, python: str = sys.executable, clock=time.monotonic):
        self.options, self.python, self.clock = options, python, clock
        self.started = None      # when the team's nodes were started (step 2)
        self.wall = None         # the team's wall time, once the clock completed the run
        self.completed = False   # the clock ended with status 0 (step 3)

    def _fail(self, message: str, status: int = EXIT_FAILED, **fields):
        update_launch_record(self.options.out, exit_status=status, **fields)
        raise RunFailed(message)

    def kernels_compiled(self, status: int, shutting_down: bool) -> bool:
        """Return whether to start the team now that step 1 ended with ``status``.

        Raises :class:`RunFailed` if the compilation failed (no node is started).
        """
        if shutting_down:
            return False
        if status != 0:
            self._fail(f'compiling the kernels (python -m uh_team.compile_kernels) failed with status {status}: '
                       'its output is above; no node was started', failed_node='compile_kernels')
        self.started = self.clock()
        return True

    def node_ended(self, name: str, kind: str, status: int, shutting_down: bool) -> Step:
        """Return the step after node ``name`` (of ``kind``) ended with ``status``.

        Called for the clock and the recorder always, and in lockstep for every node (every step
        needs every node). Raises :class:`RunFailed` for a failure that ends the run.
        """
        if kind == 'clock' and status == 0 and not shutting_down and not self.completed:
            self.completed = True
            self.wall = self.clock() - (self.started if self.started is not None else self.clock())
            return Step('stop', 'recorder')    # finalise the bag; the others wait for the metrics
        if kind == 'recorder' and self.completed:
            if not self.options.metrics:
                update_launch_record(self.options.out, exit_status=EXIT_OK, wall_time_s=self.wall)
                return Step('shutdown', 'run complete')
            return Step('run', after_run_command(self.python, self.options, self.wall))
        if shutting_down or self.completed:
            return NOTHING    # stopped by the launch's end; after the clock's completion no node is needed
        if status != 0:
            self._fail(f'{name} exited with status {status}: the run did not complete (its log is above)',
                       failed_node=name)
        why = 'the run needs its recording' if kind == 'recorder' else 'lockstep needs every node'
        return Step('shutdown', f'{name} exited ({why})')

    def after_run_ended(self, status: int) -> Step:
        """Return the step after the after-run command (step 4) ended with ``status``."""
        if status != 0:
            raise RunFailed(f'the run completed, but its metrics were not written (status {status}; why is above)')
        return Step('shutdown', 'run complete')

    def launch_shut_down(self, reason: str, due_to_sigint: bool = False) -> None:
        """Check the launch's shutdown, for ``reason``.

        The launch also ends when nothing is left running ('idle'). That happens without a process
        exit event when no node could be started at all (launch logs the exec error and sends
        none): without the clock's completion, that is a failed run (:class:`RunFailed`). An
        interrupted launch (Ctrl-C) is said in ``run.json`` (``exit_status`` 130).
        """
        if self.completed:
            return
        if due_to_sigint:
            update_launch_record(self.options.out, exit_status=EXIT_INTERRUPTED, interrupted=True)
        elif reason == 'idle':
            self._fail('every process has ended, and the clock never completed the run (a node that could not '
                       'be started is logged above)')


def main(argv=None) -> int:
    """Step 4 of a launch (``python -m uh_bringup.launch_run OUT``): metrics, report, ``run.json``; return the status.

    The run's scenario and case come from ``OUT/run.json``. A bag the recorder did not finalise is
    recovered first; ``metrics.json`` and the report are written by
    :func:`uh_bringup.run_outcome.write_metrics`, as after ``run_formation.sh``. Status 0, 1 when the
    metrics cannot be computed, 2 for bad input (no ``run.json`` of a launch in ``OUT``).
    """
    parser = ArgumentParser(prog='python -m uh_bringup.launch_run',
                            description='After a launch of formation.launch.py: recover the bag if needed, '
                                        'compute OUT/metrics.json, write OUT/report and complete OUT/run.json.')
    parser.add_argument('out', type=Path, help='the run directory of the launch (its out:= argument)')
    parser.add_argument('--wall-time', type=float, default=None, help='wall seconds the team ran')
    parser.add_argument('--no-report', action='store_true', help="do not write the run's report")
    args = parser.parse_args(argv)
    try:
        info = json.loads((args.out / 'run.json').read_text())
        scenario_arg, case = info['scenario'], info['case']
    except (OSError, ValueError, KeyError, TypeError) as exc:
        parser.exit(EXIT_USAGE, f'{parser.prog}: error: {args.out / "run.json"}: not the record of a launch '
                                f'({exc}); give the out:= directory of a launch\n')
    try:
        scenario = load_scenario(scenario_arg, safety={'on': True, 'off': False}.get(info.get('safety')))
    except (OSError, ValueError) as exc:    # the scenario changed or went since the launch checked it
        parser.exit(EXIT_USAGE, f'{parser.prog}: error: {exc}\n')
    recovery = recover_bag_if_needed(args.out / 'bag')
    problem = write_metrics(args.out, scenario, case, args.wall_time, report=not args.no_report)
    status = EXIT_OK if problem is None else EXIT_FAILED
    update_launch_record(args.out, exit_status=status, wall_time_s=args.wall_time, bag_recovery=recovery,
                         **({} if problem is None else {'metrics_error': problem}))
    return status


if __name__ == '__main__':
    sys.exit(main())
