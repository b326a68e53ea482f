"""What a team run checks before anything starts: options, scenario, team, environment, output directory.

Bad input is reported as one line naming the option, the value and what is allowed
(:class:`UsageError`, exit status 2); a bad scenario, gains, airframe, fault or reference file raises
the error of the node that would read it (:data:`CONFIG_ERRORS`, also exit status 2).
"""
from __future__ import annotations

import datetime
import shutil
import sys
from pathlib import Path

from uh_bringup import netns, run_secure
from uh_controller_node.controller import ControllerError, UHController
from uh_controller_node.delay_margin import margin_lines
from uh_controller_node.gains import scenario_gains
from uh_core.airframe import HelicopterParamsError, load_helicopter_params
from uh_core.reference import ReferenceParameterError, VirtualLeaderReference
from uh_runtime import scheduling
from uh_runtime.bags import live_view
from uh_runtime.network import MAX_DOMAIN_ID, default_cyclonedds_uri
from uh_sim_node.faults import FaultError
from uh_sim_node.helicopter import plant_from_scenario
from uh_topology.errors import ScenarioError
from uh_topology.safety import safety_override
from uh_topology.scenario import bundled_scenarios, duration_steps, load_scenario

__all__ = ['UsageError', 'CONFIG_ERRORS', 'HOSTS', 'LAYOUTS', 'check_args', 'validate_team',
           'prepare_out', 'check_run']

HOSTS = ('local', 'netns')
LAYOUTS = ('per-node', 'per-uh', 'workers', 'single')

#: errors of a team's configuration (scenario and gains, airframe, faults, reference): exit status 2
CONFIG_ERRORS = (ScenarioError, ControllerError, HelicopterParamsError, FaultError, ReferenceParameterError)


class UsageError(Exception):
    """Bad command-line input; printed as one line, exit status 2."""


def check_args(args) -> None:
    """Check the options of ``run_formation.sh`` against each other; raise :class:`UsageError`."""
    if not 0.01 <= args.rate <= 1000:
        raise UsageError(f'--rate {args.rate}: allowed 0.01 .. 1000 (simulated seconds per wall second)')
    if args.duration is not None and not 0 < args.duration <= 1e6:
        raise UsageError(f'--duration {args.duration}: allowed > 0 .. 1e6 s')
    if args.domain_id is not None and not 0 <= args.domain_id <= MAX_DOMAIN_ID:
        raise UsageError(f'--domain-id {args.domain_id}: allowed 0..{MAX_DOMAIN_ID}')
    if not 0 < args.startup_timeout <= 3600:
        raise UsageError(f'--startup-timeout {args.startup_timeout}: allowed > 0 .. 3600 s')
    if not 0 < args.stale_timeout <= 60:
        raise UsageError(f'--stale-timeout {args.stale_timeout}: allowed > 0 .. 60 s (simulated)')
    if not 0 <= args.realtime_priority <= scheduling.MAX_PRIORITY:
        raise UsageError(f'--realtime-priority {args.realtime_priority}: allowed 0 (normal scheduling) .. '
                         f'{scheduling.MAX_PRIORITY}')
    if not 0 <= args.loss <= 100:
        raise UsageError(f'--loss {args.loss}: allowed 0 .. 100 (percent)')
    if args.loss > 0 and args.hosts != 'netns':
        raise UsageError(f'--loss {args.loss:g} needs --hosts netns (loss is applied on the links between '
                         'network namespaces)')
    if args.respawn and args.clock != 'realtime':
        raise UsageError('--respawn needs --clock realtime: a lockstep run cannot go on without the steps a '
                         'restarted controller missed')
    if args.respawn and args.processes != 'per-node':
        raise UsageError(f'--respawn needs --processes per-node (with {args.processes} a controller shares '
                         'its process with its simulator, which cannot be restarted)')
    workers = getattr(args, 'workers', None)
    if workers is not None and workers < 1:
        raise UsageError(f'--workers {workers}: allowed 1 or more (processes holding the UHs)')
    if workers is not None and args.processes != 'workers':
        raise UsageError(f'--workers needs --processes workers (the layout is {args.processes})')
    if args.hosts == 'netns' and args.processes == 'single':
        raise UsageError('--hosts netns cannot run --processes single (one process cannot be in several '
                         'network namespaces)')
    try:
        run_secure.check_secure_args(args)
    except run_secure.SecureRunError as exc:
        raise UsageError(str(exc)) from None


def validate_team(scenario, case: str) -> None:
    """Build what every node would build, so a bad gains or airframe file is reported before any process starts.

    Each UH's controller and plant, and the reference; raises the node's own error.
    """
    # the gains first, named by their file and line
    scenario_gains(scenario, case)
    params = load_helicopter_params(scenario.helicopter)
    for i in scenario.ids:
        UHController(i, scenario, case=case, helicopter_params=params)
        plant_from_scenario(scenario, i, params)
    VirtualLeaderReference(scenario.reference)


def prepare_out(out: Path, force: bool) -> None:
    """Make ``out`` an empty, writable directory (emptied only with ``force``); else :class:`UsageError`."""
    try:
        if out.exists() and not out.is_dir():
            raise UsageError(f'--out {out}: exists and is not a directory; give a directory')
        if out.exists() and any(out.iterdir()):
            if not force:
                raise UsageError(f'--out {out}: exists and is not empty (use --force to replace its content)')
            for child in out.iterdir():
                shutil.rmtree(child) if child.is_dir() and not child.is_symlink() else child.unlink()
        out.mkdir(parents=True, exist_ok=True)
        probe = out / '.write_test'
        probe.write_text('')
        probe.unlink()
    except OSError as exc:
        where = f' ({exc.filename})' if exc.filename and str(exc.filename) != str(out) else ''
        raise UsageError(f'--out {out}: cannot write there: {exc.strerror}{where}; choose a directory you can '
                         'write to') from None


def _check_environment(args) -> None:
    """Check the network settings, the network namespaces and the live view's port before --out is touched."""
    try:
        default_cyclonedds_uri()   # a bad ROS_AUTOMATIC_DISCOVERY_RANGE is refused before --out is touched
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.hosts == 'netns':
        try:
            netns.check_available(args.loss)
        except netns.NetnsError as exc:
            raise UsageError(str(exc)) from None
    if args.foxglove is not None:
        if args.hosts == 'netns':
            raise UsageError('--foxglove with --hosts netns: the live view would live in a network namespace '
                             'no viewer reaches; use one of them')
        try:    # before any node starts: a port in use is the user's to fix
            live_view.check_available(args.foxglove_host, args.foxglove)
        except live_view.LiveViewError as exc:
            raise UsageError(str(exc)) from None


def check_run(args) -> tuple:
    """Check everything a run is given, in order, and prepare its output directory.

    Returns ``(scenario, scenario argument for the nodes, output directory)``; raises
    :class:`UsageError` or one of :data:`CONFIG_ERRORS`.
    """
    check_args(args)
    if args.out is not None and not str(args.out).strip():
        raise UsageError("--out '': give a directory (or leave --out out for runs/<timestamp>)")
    scenario = load_scenario(args.scenario, safety=safety_override(args.safety))
    if args.duration is not None:
        try:
            duration_steps(args.duration, scenario.dt)
        except ValueError as exc:
            raise UsageError(f'--duration {exc}') from None
    if scenario.events and args.clock != 'lockstep':
        raise UsageError(f'--scenario {args.scenario}: its events (a lost helicopter) fly in lockstep or in process; '
                         'in real time kill a node instead (docs/resilience.md)')
    validate_team(scenario, args.case)
    for issue in scenario.separation_warnings:
        print(f'[run] warning: {issue.text()}: closer than the minimum separation (docs/safety.md)', file=sys.stderr)
    for line in margin_lines(scenario, args.case):
        print(f'[run] {line}', file=sys.stderr)
    # the nodes load the scenario themselves: a bundled name as it is, a file by its absolute path
    bundled = args.scenario in bundled_scenarios() and not Path(args.scenario).exists()
    scenario_arg = args.scenario if bundled else str(Path(args.scenario).resolve())
    _check_environment(args)
    try:    # a given keystore against this scenario, and the binding (docs/security.md)
        run_secure.check_secure_run(args, scenario, scenario_arg)
    except run_secure.SecureRunError as exc:
        raise UsageError(str(exc)) from None
    out = Path(args.out or Path('runs') / datetime.datetime.now().strftime('%Y%m%d-%H%M%S')).resolve()
    prepare_out(out, args.force)
    return scenario, scenario_arg, out
