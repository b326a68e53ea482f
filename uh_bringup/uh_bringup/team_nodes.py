"""The one table of a team's nodes, and the node list of a run built from it (docs/architecture.md).

Every way of starting a team reads this module, so they cannot drift apart:

* ``scripts/run_formation.sh`` (:mod:`uh_bringup.run_formation`) starts each node through its
  entry point (``ros2 run PACKAGE EXECUTABLE`` on a ROS 2 machine), or several in one process;
* :mod:`uh_bringup.composed` builds the node classes of one process from ``NODES[kind].node_class``;
* ``ros2 launch uh_bringup formation.launch.py`` starts the same node list as the run script;
* a test checks that every package's ``setup.py`` declares the entry point named here.

ROS-free: no launch or rclpy import.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

from uh_wire import topics

__all__ = ['NodeKind', 'NODES', 'node_class', 'node_specs', 'backend_environment']


@dataclass(frozen=True)
class NodeKind:
    """One kind of node of a team.

    Attributes
    ----------
    package : str
        ROS 2 package that installs it.
    executable : str
        Its console-script entry point (``ros2 run PACKAGE EXECUTABLE``).
    node_class : str
        ``module:Class`` of its node class, for composition in one process.
    per_uh : bool
        One per helicopter (in namespace ``/uhN``) rather than one per team.
    infrastructure : bool
        Moves data for people, not for the control loop (the recorder, the visualisation): runs on
        the Cyclone DDS backend wherever that is installed, also on a ROS 2 machine, where rclpy's
        per-message cost would take the CPU the team needs (:func:`backend_environment`).
    entry : str
        ``module:function`` its console script runs, when not the node module's ``main`` (the
        simulator and the controller choose their kernels' form first: docs/performance.md#memory).
    """

    package: str
    executable: str
    node_class: str
    per_uh: bool = False
    infrastructure: bool = False
    entry: str = ''

    @property
    def entry_point(self) -> str:
        """``module:function`` of its console script (``setup.py``)."""
        return self.entry or f'{self.module}:main'

    @property
    def module(self) -> str:
        """The module of its node class (and of the ``main()`` that runs it alone)."""
        return self.node_class.split(':')[0]


#: node kind -> how it is packaged, started and composed
NODES = {
    'recorder': NodeKind('uh_runtime', 'recorder_node', 'uh_runtime.bags.recorder:RecorderNode', infrastructure=True),
    'sim': NodeKind('uh_sim_node', 'sim_node', 'uh_sim_node.sim_node:SimNode', per_uh=True,
                    entry='uh_sim_node.entry_points:sim_node'),
    'controller': NodeKind('uh_controller_node', 'controller_node',
                           'uh_controller_node.controller_node:ControllerNode', per_uh=True,
                           entry='uh_controller_node.entry_points:controller_node'),
    'visualization': NodeKind('uh_sim_node', 'visualization_node',
                              'uh_sim_node.visualization_node:VisualizationNode', infrastructure=True),
    'virtual_leader': NodeKind('uh_sim_node', 'virtual_leader_node',
                               'uh_sim_node.virtual_leader_node:VirtualLeaderNode'),
    'sensing': NodeKind('uh_sim_node', 'sensing_node', 'uh_sim_node.sensing_node:SensingNode'),
    'clock': NodeKind('uh_sim_node', 'lockstep_clock_node', 'uh_sim_node.clock_node:ClockNode'),
    'live_view': NodeKind('uh_runtime', 'live_view_node', 'uh_runtime.bags.live_view:LiveViewNode',
                          infrastructure=True),
}


def backend_environment(kind: str, env) -> dict:
    """Return the extra environment of a node of ``kind``.

    ``UH_BACKEND=dds`` for an infrastructure node when the user has not chosen a backend
    (``UH_BACKEND`` unset in ``env``) and the Cyclone DDS Python binding is installed; nothing
    otherwise (the node then takes rclpy where it exists).
    """
    import importlib.util
    if NODES[kind].infrastructure and not env.get('UH_BACKEND') and importlib.util.find_spec('cyclonedds'):
        return {'UH_BACKEND': 'dds'}
    return {}


def node_class(kind: str):
    """Return the node class of a node kind (imported on demand)."""
    try:
        module, cls = NODES[kind].node_class.split(':')
    except KeyError:
        raise ValueError(f'unknown node kind {kind!r}; allowed: {", ".join(NODES)}') from None
    return getattr(importlib.import_module(module), cls)


def node_specs(scenario, scenario_arg: str, case: str, clock: str, rate: float, duration: float | None,
               bag_dir: Path, startup_timeout: float, stale_timeout: float | None = None,
               visualization: bool = True, standard_views: bool = True,
               live_view: tuple | None = None, realtime_priority: int = 0) -> list[tuple[str, str, list]]:
    """Return ``[(name, node kind, ros args), ...]`` of every node of a run, recorder first and clock last.

    The sensing node only if the scenario's safety filter is on (``scenario`` is loaded with the
    run's ``--safety``; every node gets that setting as its ``safety`` parameter). The visualisation
    node only if ``visualization``; ``standard_views=False`` switches /tf, odom
    and /diagnostics off, docs/visualization.md; ``live_view=(host, port)`` adds the Foxglove live
    view after the recorder. In realtime, ``realtime_priority`` > 0 runs the control loop's nodes
    (every kind that is not infrastructure) under SCHED_FIFO at that priority
    (docs/performance.md#real-time-scheduling).
    """
    # the safety filter's setting the run resolved (scenario or --safety), the same for every node
    common = ['-p', f'scenario:={scenario_arg}', '-p', f'clock_mode:={clock}',
              '-p', f'safety:={"on" if scenario.safety.enabled else "off"}']
    loop = (['-p', f'realtime_priority:={int(realtime_priority)}']
            if clock == 'realtime' and realtime_priority > 0 else [])
    views = [] if standard_views else ['-p', 'standard_views:=false']
    stale = ['-p', f'stale_timeout:={float(stale_timeout)}'] if stale_timeout is not None else []
    if duration is not None:
        common += ['-p', f'duration:={float(duration)}']
    per_step = [name for name, spec in topics.team_topics(scenario.ids, **topics.scenario_flags(scenario))
                if spec.per_step]
    # injections may come from a publisher that lives a moment (ros2 topic pub --once)
    injections = [f'{topics.uh_topic(i, topics.FAULT)}={topics.FAULT.type}' for i in scenario.ids]
    specs = [('recorder', 'recorder', ['--ros-args', '-p', f'output:={bag_dir}', '-p', 'sim_time:=true',
                                       '-p', f'progress_topics:=[{",".join(per_step)}]',
                                       '-p', f'expected_topics:=[{",".join(injections)}]'])]
    if live_view is not None:
        specs.append(('live_view', 'live_view', ['--ros-args', '-p', f'host:={live_view[0]}',
                                                 '-p', f'port:={int(live_view[1])}']))
    for i in scenario.ids:
        ns = ['-r', f'__ns:={topics.uh_namespace(i)}', '-p', f'uh_id:={i}']
        specs.append((f'uh{i}_sim', 'sim', ['--ros-args', *ns, *common, *loop, *stale, *views]))
        specs.append((f'uh{i}_controller', 'controller', ['--ros-args', *ns, *common, *loop, *stale, *views,
                                                          '-p', f'case:={case}']))
    if visualization:
        specs.append(('visualization', 'visualization', ['--ros-args', *common]))
    specs.append(('virtual_leader', 'virtual_leader', ['--ros-args', *common, *loop, *views]))
    if scenario.safety.enabled:    # each UH's proximity input (docs/safety.md#what-the-filter-knows)
        specs.append(('sensing', 'sensing', ['--ros-args', *common, *loop]))
    specs.append(('clock', 'clock', ['--ros-args', *common, *loop, *views, '-p', f'rate:={float(rate)}',
                                     '-p', 'expect_recorder:=true',
                                     '-p', f'expect_visualization:={str(bool(visualization)).lower()}',
                                     '-p', f'startup_timeout:={float(startup_timeout)}']))
    return specs
