"""ROS 2 launch file of a team (ROS 2 Jazzy machines): the nodes ``scripts/run_formation.sh`` starts.

    ros2 launch uh_bringup formation.launch.py scenario:=paper case:=proposed clock_mode:=lockstep
    ros2 launch uh_bringup formation.launch.py backend:=dds     # every node on the Cyclone DDS backend

The node list comes from :func:`uh_bringup.team_nodes.node_specs`, the same function the run script
uses: a recorder (bag in ``out``), one simulator and one controller per helicopter, the
visualisation node (``visualization:=false`` leaves it out), the virtual leader and the clock;
``standard_views:=false`` switches off /tf, /uhN/odom and /diagnostics; in realtime the control loop's
nodes run under SCHED_FIFO priority ``realtime_priority`` (default 20, 0 = normal scheduling) where
the user may (docs/performance.md#real-time-scheduling). The recorder and the visualisation run on
the Cyclone DDS backend when its Python binding is installed (``uh_bringup.team_nodes.backend_environment``).

Around the nodes, :mod:`uh_bringup.launch_run` decides (docs/ros2.md#launching-the-team): the
kernels are compiled before any node starts; when the clock completes the run, the recorder
finalises the bag and ``OUT/metrics.json`` and ``OUT/report`` are written as after
``run_formation.sh`` (``metrics:=false``, ``report:=false`` switch them off); then the launch ends.
It exits with status 1 when the clock, the recorder, (in lockstep) any node or the metrics failed.
"""
import os
import sys

from launch import LaunchDescription
from launch.actions import (
    DeclareLaunchArgument,
    EmitEvent,
    ExecuteProcess,
    LogInfo,
    OpaqueFunction,
    RegisterEventHandler,
)
from launch.event_handlers import OnProcessExit, OnShutdown
from launch.events import Shutdown, matches_action
from launch.events.process import ShutdownProcess
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from uh_bringup.launch_run import ARGUMENTS, LaunchRun, check_arguments, compile_command, write_launch_record
from uh_bringup.team_nodes import NODES, backend_environment, node_specs
from uh_runtime.network import apply_network_default
from uh_team.departures import scenario_departures
from uh_topology.scenario import load_scenario


def _team(context):
    options = check_arguments({name: LaunchConfiguration(name).perform(context) for name, _, _ in ARGUMENTS})
    scenario = load_scenario(options.scenario, safety=options.safety)
    specs = node_specs(scenario, options.scenario, options.case, options.clock_mode, options.rate, options.duration,
                       f'{options.out}/bag', options.startup_timeout, options.stale_timeout,
                       visualization=options.visualization, standard_views=options.standard_views,
                       realtime_priority=options.realtime_priority)
    write_launch_record(options, options.duration if options.duration is not None else scenario.duration,
                        scenario.safety.enabled, departures=scenario_departures(scenario, options.case))
    run = LaunchRun(options, sys.executable)
    # the runs' discovery settings (uh_runtime.network.apply_network_default), which rclpy on Fast DDS
    # and the Cyclone DDS nodes meet on whatever the user has or has not set
    network = {key: value for key, value in apply_network_default(dict(os.environ)).items()
               if key in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'CYCLONEDDS_URI')}
    nodes, team = {}, []
    for name, kind, ros_args in specs:
        # the namespace and parameters are in ros_args (--ros-args ...), as the run script passes them
        # backend:=dds: every node on the Cyclone DDS backend; else the recorder and the visualisation
        # there (where it is installed) and the team's nodes on rclpy
        env = {**network, **({'UH_BACKEND': 'dds'} if options.backend == 'dds'
                             else backend_environment(kind, os.environ))}
        nodes[name] = Node(package=NODES[kind].package, executable=NODES[kind].executable, arguments=ros_args,
                           output='both', additional_env=env)
        team.append(nodes[name])
        if kind in ('clock', 'recorder') or options.clock_mode == 'lockstep':
            team.append(_on_exit(nodes[name], lambda event, context, name=name, kind=kind: run.node_ended(
                name, kind, event.returncode, context.is_shutdown), run, nodes))

    compiling = ExecuteProcess(cmd=compile_command(sys.executable), name='compile_kernels', output='both')

    def compiled(event, context):
        return team if run.kernels_compiled(event.returncode, context.is_shutdown) else []
    return [LogInfo(msg='compiling the numba kernels before the nodes start (a minute or more after an install or '
                        'an update, about a second from the cache)'),
            compiling, RegisterEventHandler(OnProcessExit(target_action=compiling, on_exit=compiled)),
            RegisterEventHandler(OnShutdown(on_shutdown=lambda event, context: run.launch_shut_down(
                event.reason, event.due_to_sigint)))]


def _on_exit(action, decide, run, nodes):
    """Register ``decide(event, context)`` (a :class:`uh_bringup.launch_run.Step`) for the end of ``action``."""
    def on_exit(event, context):
        step = decide(event, context)
        if step.what == 'shutdown':
            return [EmitEvent(event=Shutdown(reason=step.detail))]
        if step.what == 'stop':
            return [EmitEvent(event=ShutdownProcess(process_matcher=matches_action(nodes[step.detail])))]
        if step.what == 'run':
            after_run = ExecuteProcess(cmd=step.detail, name='metrics', output='both')
            return [after_run, _on_exit(after_run, lambda ended, _: run.after_run_ended(ended.returncode), run, nodes)]
        return []
    return RegisterEventHandler(OnProcessExit(target_action=action, on_exit=on_exit))


def generate_launch_description():
    """Return the launch description: the launch arguments (:data:`uh_bringup.launch_run.ARGUMENTS`) and the team.

    The team's actions are made once the arguments are known (an ``OpaqueFunction``): the kernels are
    compiled first, then the nodes start.
    """
    return LaunchDescription([DeclareLaunchArgument(name, default_value=default, description=description)
                              for name, default, description in ARGUMENTS] + [OpaqueFunction(function=_team)])
