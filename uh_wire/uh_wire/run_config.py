"""Parameters every node of a run declares, validated in one place.

``scenario`` (file or ``paper``), ``safety`` (``on`` | ``off`` | empty = the scenario's
``safety.enabled``: the collision-avoidance filter, docs/safety.md), ``clock_mode`` (``lockstep``
| ``realtime``), ``duration`` (s, 0 = the scenario's), ``realtime_priority`` (realtime mode: the
SCHED_FIFO priority of the node's process, 0 = normal scheduling;
docs/performance.md#real-time-scheduling) and, for per-UH nodes, ``uh_id``. A bad value raises
:class:`RunConfigError` naming the parameter and what is allowed; the node entry point turns it into
a one-line error and a non-zero exit.
"""
from __future__ import annotations

from dataclasses import dataclass

import uh_runtime as rt
from uh_runtime import scheduling
from uh_topology.safety import SAFETY_CHOICES, safety_override
from uh_topology.scenario import load_scenario
from uh_topology.scenario_keys import STALE_TIMEOUT

__all__ = ['RunConfig', 'RunConfigError', 'ViewConfig', 'declare_run_parameters', 'declare_view_parameters',
           'declare_standard_views', 'declare_float_parameter', 'CLOCK_MODES', 'DEFAULT_STALE_TIMEOUT']

CLOCK_MODES = ('lockstep', 'realtime')
#: realtime: simulated seconds a neighbour's state, the reference or a simulator's command may lag
#: before it is stale (parameter ``stale_timeout`` of the controllers and simulators,
#: ``--stale-timeout`` of the run, launch argument ``stale_timeout``; docs/reliability.md).
DEFAULT_STALE_TIMEOUT = STALE_TIMEOUT


class RunConfigError(ValueError):
    """A run parameter has a value the node cannot use."""


@dataclass(frozen=True)
class RunConfig:
    """The run parameters of a node, as :func:`declare_run_parameters` reads them.

    ``scenario`` (the loaded :class:`uh_topology.scenario.Scenario`), ``clock_mode`` (``lockstep`` or
    ``realtime``), ``dt`` (control period, s), ``last_step`` (index K of the last step: states and
    commands 0..K) and ``uh_id`` (None for a node that is not one UH's).
    """

    scenario: object        # uh_topology.scenario.Scenario
    clock_mode: str
    dt: float               # control period, s
    last_step: int          # index K of the last step: states 0..K, commands 0..K
    uh_id: int | None


def _describe(text: str, **kwargs):
    return rt.ParameterDescriptor(description=text, **kwargs)


def declare_float_parameter(node, name: str, default: float, upper: float, description: str) -> float:
    """Declare read-only float parameter ``name`` of ``node`` (0 .. ``upper``) and return its value."""
    node.declare_parameter(name, default, _describe(
        description, read_only=True,
        floating_point_range=[rt.FloatingPointRange(from_value=0.0, to_value=upper, step=0.0)]))
    return float(node.get_parameter(name).value)


def declare_run_parameters(node, per_uh: bool = True) -> RunConfig:
    """Declare and read the run parameters of ``node``; load and validate the scenario."""
    node.declare_parameter('scenario', 'paper', _describe(
        'scenario YAML file, or "paper" for the bundled paper scenario', read_only=True))
    # dynamically typed: ``-p safety:=on`` arrives as a bool (YAML 1.1, as rcl parses it)
    node.declare_parameter('safety', '', _describe(
        'the collision-avoidance filter (docs/safety.md): on/true or off/false overrides the scenario\'s '
        'safety.enabled; empty keeps it', read_only=True, dynamic_typing=True))
    node.declare_parameter('clock_mode', 'lockstep', _describe(
        'lockstep (deterministic, as fast as possible) or realtime (wall-clock ticks)', read_only=True))
    node.declare_parameter('duration', 0.0, _describe(
        'run length in s; 0 takes the scenario duration', read_only=True,
        floating_point_range=[rt.FloatingPointRange(from_value=0.0, to_value=1e6, step=0.0)]))
    uh_id = None
    if per_uh:
        node.declare_parameter('uh_id', 1, _describe(
            'index of this helicopter in the scenario (leaders first, then followers)', read_only=True,
            integer_range=[rt.IntegerRange(from_value=1, to_value=10000, step=1)]))
        uh_id = int(node.get_parameter('uh_id').value)
    mode = str(node.get_parameter('clock_mode').value)
    if mode not in CLOCK_MODES:
        raise RunConfigError(f"parameter 'clock_mode' is {mode!r}; allowed: {', '.join(CLOCK_MODES)}")
    node.declare_parameter('realtime_priority', 0, _describe(
        'realtime mode: SCHED_FIFO priority of this process, so the control loop keeps its period on a '
        'busy machine (needs CAP_SYS_NICE (root has it) or an rtprio limit; docs/performance.md); '
        '0 = the operating system\'s normal scheduling', read_only=True,
        integer_range=[rt.IntegerRange(from_value=0, to_value=scheduling.MAX_PRIORITY, step=1)]))
    priority = int(node.get_parameter('realtime_priority').value)
    if mode == 'realtime' and priority > 0:
        why_not = scheduling.set_realtime_priority(priority)
        if why_not is None:
            node.get_logger().info(f'real-time scheduling: SCHED_FIFO priority {priority}')
        else:
            node.get_logger().warn(f'real-time scheduling not used, the node runs at normal priority: {why_not}')
    scenario = load_scenario(str(node.get_parameter('scenario').value),
                             safety=_safety_parameter(node.get_parameter('safety').value))
    if per_uh and uh_id not in scenario.ids:
        raise RunConfigError(f"parameter 'uh_id' is {uh_id}, but scenario {scenario.name!r} has UHs "
                             f"{', '.join(map(str, scenario.ids))}")
    duration = float(node.get_parameter('duration').value) or float(scenario.duration)
    last_step = int(round(duration / scenario.dt))
    return RunConfig(scenario, mode, float(scenario.dt), last_step, uh_id)


def _safety_parameter(value) -> bool | None:
    """Return the ``safety`` parameter as :func:`load_scenario` takes it: True, False or None (the scenario's)."""
    if isinstance(value, bool):
        return value
    if value in ('', *SAFETY_CHOICES):
        return safety_override(value or None)
    raise RunConfigError(f"parameter 'safety' is {value!r}; allowed: {', '.join(SAFETY_CHOICES)}, true, false or "
                         "empty (the scenario's safety.enabled)")


@dataclass(frozen=True)
class ViewConfig:
    """The standard views a node publishes for generic tools (docs/visualization.md)."""

    enabled: bool           # /tf, odom, /diagnostics at all
    pose_every: int         # steps between two /tf and odom messages
    diagnostics_every: int  # steps between two /diagnostics reports

    def diagnostics_phase(self, ids, uh_id: int, controller: bool) -> int:
        """Return the step within each ``diagnostics_every`` period at which a UH reports on /diagnostics.

        The reporter is UH ``uh_id``'s simulator (or controller, with ``controller``). The team's
        reports are spread evenly over the period, not sent in one burst. A reader with a short
        history (``ros2 topic echo`` keeps 5) that reads after the burst would keep only its last
        reports (docs/visualization.md#diagnostics).
        """
        ids = list(ids)
        slot = 2 * ids.index(uh_id) + int(controller)
        return (slot * self.diagnostics_every) // (2 * len(ids))


def declare_standard_views(node) -> bool:
    """Declare ``standard_views`` on ``node`` and return it: whether the run publishes /tf, odom and /diagnostics."""
    node.declare_parameter('standard_views', True, _describe(
        'publish /tf, odom and /diagnostics for RViz2, tf2, Foxglove and rqt (off for benchmarks)',
        read_only=True))
    return bool(node.get_parameter('standard_views').value)


def declare_view_parameters(node, dt: float) -> ViewConfig:
    """Declare the standard views' parameters on ``node`` and return them as steps.

    The parameters are ``standard_views`` (bool, :func:`declare_standard_views`), ``pose_rate`` and
    ``diagnostics_rate`` (Hz of simulated time); ``dt`` is the node's control period in s.
    """
    enabled = declare_standard_views(node)
    # what a person watches is decimated (docs/visualization.md): 25 Hz is smooth in a 3-D view
    node.declare_parameter('pose_rate', 25.0, _describe(
        'Hz of simulated time of /tf and odom; 0 = every step', read_only=True,
        floating_point_range=[rt.FloatingPointRange(from_value=0.0, to_value=1e6, step=0.0)]))
    node.declare_parameter('diagnostics_rate', 2.0, _describe(
        'Hz of simulated time of /diagnostics', read_only=True,
        floating_point_range=[rt.FloatingPointRange(from_value=0.001, to_value=1e6, step=0.0)]))

    def every(rate: float) -> int:
        return 1 if rate <= 0.0 else max(1, int(round(1.0 / (rate * dt))))
    return ViewConfig(enabled,
                      every(float(node.get_parameter('pose_rate').value)),
                      every(float(node.get_parameter('diagnostics_rate').value)))
