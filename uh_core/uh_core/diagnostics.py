"""Health of the simulators and controllers as ``diagnostic_msgs`` reports (docs/visualization.md#diagnostics).

Each node gathers what happened since its last report in a window (a few per second of simulated
time) and turns it into one :class:`Diagnostic` with the levels of ``diagnostic_msgs/DiagnosticStatus``:

=========  ==========================================================================================
level      raised by
=========  ==========================================================================================
ERROR      controller: holding position (the remaining graph has no path from the virtual leader),
           or a step it could not compute; simulator: a stuck actuator (rho = 0) active, or no
           command for longer than the staleness timeout
WARN       controller: a stale neighbour or reference, rejected input messages, saturation, a fault
           isolated on a channel, inputs lagging the own state; simulator: late or rejected
           commands, rejected fault injections, an actuator fault active (simulation truth)
OK         none of the above in the window
=========  ==========================================================================================

The message lists every reason, most severe first; the key-values carry the numbers. Pure Python.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .layout import CHANNEL_NAMES

__all__ = ['OK', 'WARN', 'ERROR', 'STALE', 'LEVEL_NAMES', 'Diagnostic', 'ControllerWindow',
           'SimulatorWindow', 'controller_diagnostic', 'simulator_diagnostic']

#: ``diagnostic_msgs/DiagnosticStatus`` levels (byte constants of the message).
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR', STALE: 'STALE'}


@dataclass
class Diagnostic:
    """One ``DiagnosticStatus``: level, name (``uhN/controller``), message, hardware id, values."""

    level: int
    name: str
    message: str
    hardware_id: str
    values: dict = field(default_factory=dict)


@dataclass
class ControllerWindow:
    """What a controller saw since its last report (reset after each report)."""

    steps: int = 0
    last_step: int = -1
    not_computed: int = 0
    rejected_inputs: int = 0
    saturated_steps: int = 0
    max_input_lag: int = 0
    stale_neighbours: tuple = ()
    holding: bool = False
    fault_isolated: tuple = (False, False, False, False)
    fault_estimate_position: float = 0.0
    fault_estimate_attitude: float = 0.0
    #: ``(label, mean s, max s)`` per neighbour: age of its state used over the last simulated second
    neighbour_ages: tuple = ()
    #: the safety filter runs (docs/safety.md); then the steps it changed u_p, and the closest UH at the report
    safety: bool = False
    safety_active_steps: int = 0
    closest_uh: int = 0
    closest_distance: float = math.nan
    #: the team's delay margin, s (docs/delay.md#delay-margin), when the window's ages reach beyond it; else NaN
    delay_margin_s: float = math.nan
    #: the UHs the controller knows to be lost and its role in the team it flies (docs/resilience.md; '' without)
    lost_uhs: tuple = ()
    role: str = ''


@dataclass
class SimulatorWindow:
    """What a simulator saw since its last report (reset after each report)."""

    last_step: int = -1
    late_commands: int = 0
    rejected_commands: int = 0
    rejected_faults: int = 0
    command_stale: bool = False
    fault_active: bool = False
    stuck: bool = False


def _channels(flags) -> str:
    return ', '.join(name for name, on in zip(CHANNEL_NAMES, flags, strict=False) if on)


def _report(name: str, hardware_id: str, errors: list, warnings: list, values: dict) -> Diagnostic:
    level = ERROR if errors else WARN if warnings else OK
    message = '; '.join(errors + warnings) or 'OK'
    return Diagnostic(level, name, message, hardware_id, {k: str(v) for k, v in values.items()})


def controller_diagnostic(uh_id: int, w: ControllerWindow) -> Diagnostic:
    """Return the report of controller ``uh_id`` over window ``w``."""
    errors, warnings = [], []
    if w.holding:
        errors.append('holding position: no path from the virtual leader')
    if w.not_computed:
        errors.append(f'{w.not_computed} step(s) not computed')
    if w.stale_neighbours:
        warnings.append('stale: ' + ', '.join(w.stale_neighbours))
    if w.rejected_inputs:
        warnings.append(f'{w.rejected_inputs} input message(s) rejected')
    if w.saturated_steps:
        warnings.append(f'saturated in {w.saturated_steps} of {w.steps} step(s)')
    if any(w.fault_isolated):
        warnings.append('fault isolated: ' + _channels(w.fault_isolated))
    if w.max_input_lag > 0:
        warnings.append(f'inputs up to {w.max_input_lag} step(s) behind the own state')
    values = {'step': w.last_step, 'steps in window': w.steps, 'stale inputs': ' '.join(w.stale_neighbours),
              'rejected inputs': w.rejected_inputs, 'saturated steps': w.saturated_steps,
              'max input lag (steps)': w.max_input_lag, 'holding position': w.holding,
              'fault isolated': _channels(w.fault_isolated),
              '|Fhat_p| (m/s^2)': f'{w.fault_estimate_position:.4g}',
              '|Fhat_w| (rad/s^2)': f'{w.fault_estimate_attitude:.4g}',
              'steps not computed': w.not_computed}
    if w.safety:
        if w.safety_active_steps:
            warnings.append(f'safety filter active in {w.safety_active_steps} of {w.steps} step(s)')
        values.update({'safety filter active steps': w.safety_active_steps,
                       'closest UH': f'uh{w.closest_uh}' if w.closest_uh else 'none sensed',
                       'closest distance (m)': f'{w.closest_distance:.3f}'})
    for label, mean, worst in w.neighbour_ages:
        values[f'age of {label}, mean over 1 s (s)'] = f'{mean:.4g}'
        values[f'age of {label}, max over 1 s (s)'] = f'{worst:.4g}'
    if w.role:
        values.update({'role': w.role, 'lost UHs': ' '.join(f'uh{j}' for j in w.lost_uhs)})
        if w.lost_uhs:
            warnings.append(f'team lost {", ".join(f"uh{j}" for j in w.lost_uhs)}; flying as {w.role}')
        if w.role.startswith('holding'):
            errors.append(w.role)
    if math.isfinite(w.delay_margin_s):
        values['delay margin (s)'] = f'{w.delay_margin_s:.4g}'
        beyond = [(worst, label) for label, _, worst in w.neighbour_ages if worst > w.delay_margin_s + 1e-9]
        if beyond:
            worst, label = max(beyond)
            warnings.append(f'{label} state up to {worst * 1000:.0f} ms old, beyond the delay margin of '
                            f'{w.delay_margin_s * 1000:.0f} ms (docs/delay.md#delay-margin)')
    return _report(f'uh{uh_id}/controller', f'uh{uh_id}', errors, warnings, values)


def simulator_diagnostic(uh_id: int, w: SimulatorWindow) -> Diagnostic:
    """Return the report of simulator ``uh_id`` over window ``w``."""
    errors, warnings = [], []
    if w.stuck:
        errors.append('an actuator is stuck (rho = 0): not compensable')
    if w.command_stale:
        errors.append('no command within the staleness timeout: holding the last one')
    if w.late_commands:
        warnings.append(f'{w.late_commands} late command(s)')
    if w.rejected_commands:
        warnings.append(f'{w.rejected_commands} command(s) rejected')
    if w.rejected_faults:
        warnings.append(f'{w.rejected_faults} fault injection(s) rejected')
    if w.fault_active and not w.stuck:
        warnings.append('actuator fault active (simulation truth)')
    values = {'step': w.last_step, 'late commands': w.late_commands, 'rejected commands': w.rejected_commands,
              'rejected fault injections': w.rejected_faults, 'command stale': w.command_stale,
              'fault active': w.fault_active, 'actuator stuck': w.stuck}
    return _report(f'uh{uh_id}/sim', f'uh{uh_id}', errors, warnings, values)
