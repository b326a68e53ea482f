"""ROS 2 launch file of a team (ROS 2 Jazzy machines): the nodes ``scripts/run_formation.sh`` starts.

    ros2 launch uh_bringup formation.launch.py scenario:=paper case:=proposed clock_mode:=lockstep
    ros2 launch uh_bringup formation.launch.py backend:=dds     # every node on the Cyclone DDS backend

The node list comes from :func:`uh_bringup.team_nodes.node_specs`, the same function the run script
uses: a recorder (bag in ``out``), one simulator and one controller per helicopter, the
visualisation node (``visualization:=false`` leaves it out), the virtual leader and the clock;
``standard_views:=false`` switches off /tf, /uhN/odom and /diagnostics; in realtime the control loop's
nodes run under SCHED_FIFO priority ``realtime_priority`` (default 20, 0 = normal scheduling) where
the user may (docs/performance.md#real-time-scheduling).
The launch ends when the clock ends (run complete), and in lockstep also when any node dies (every
step needs every node); it exits with status 1 when the clock or (in lockstep) a node failed. The
recorder and the visualisation run on the Cyclone DDS backend when its Python binding is installed
(``uh_bringup.team_nodes.backend_environment``).
"""
import datetime
import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnProcessExit, OnShutdown
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from uh_bringup.team_nodes import NODES, backend_environment, node_specs
from uh_runtime.network import apply_network_default
from uh_runtime.scheduling import DEFAULT_PRIORITY, MAX_PRIORITY
from uh_topology.scenario import load_scenario
# the default stale timeout from its one home (the nodes' parameter and the run script's option)
from uh_wire.run_config import DEFAULT_STALE_TIMEOUT


def _team(context):
    def arg(name):
        return LaunchConfiguration(name).perform(context)

    scenario_arg, clock_mode, backend = arg('scenario'), arg('clock_mode'), arg('backend')
    if backend not in ('rclpy', 'dds'):
        raise ValueError(f"launch argument backend:={backend!r}; allowed: rclpy, dds")
    try:
        priority = int(arg('realtime_priority'))
    except ValueError:
        priority = -1
    if not 0 <= priority <= MAX_PRIORITY:
        raise ValueError(f"launch argument realtime_priority:={arg('realtime_priority')!r}; allowed an integer "
                         f'0 (normal scheduling) .. {MAX_PRIORITY}')
    out = arg('out') or f'runs/launch_{datetime.datetime.now():%Y%m%d_%H%M%S}'
    duration = float(arg('duration')) if arg('duration') else None
    specs = node_specs(load_scenario(scenario_arg), scenario_arg, arg('case'), clock_mode, float(arg('rate')),
                       duration, f'{out}/bag', float(arg('startup_timeout')), float(arg('stale_timeout')),
                       visualization=arg('visualization') == 'true',
                       standard_views=arg('standard_views') == 'true', realtime_priority=priority)
    actions = []
    completed = []   # the clock's end with status 0: the run is complete
    # the runs' discovery settings (uh_runtime.network.apply_network_default), which rclpy on Fast DDS
    # and the Cyclone DDS nodes meet on whatever the user has or has not set
    network = {key: value for key, value in apply_network_default(dict(os.environ)).items()
               if key in ('ROS_AUTOMATIC_DISCOVERY_RANGE', 'CYCLONEDDS_URI')}
    for name, kind, ros_args in specs:
        # the namespace and parameters are in ros_args (--ros-args ...), as the run script passes them
        # backend:=dds: every node on the Cyclone DDS backend; else the recorder and the visualisation
        # there (where it is installed) and the team's nodes on rclpy
        env = {**network, **({'UH_BACKEND': 'dds'} if backend == 'dds' else backend_environment(kind, os.environ))}
        node = Node(package=NODES[kind].package, executable=NODES[kind].executable, arguments=ros_args,
                    output='both', additional_env=env)
        actions.append(node)
        if kind == 'clock' or clock_mode == 'lockstep':
            actions.append(RegisterEventHandler(OnProcessExit(
                target_action=node, on_exit=_on_exit(name, kind, completed))))
    actions.append(RegisterEventHandler(OnShutdown(on_shutdown=_on_idle(completed))))
    return actions


class RunFailed(RuntimeError):
    """A node the run needs died: ``ros2 launch`` shuts everything down and exits with status 1."""


def _on_exit(name, kind, completed):
    """Build the handler of the end of node ``name``.

    The clock's end with status 0 ends the launch ('run complete'); a failed clock, or a lockstep
    node that fails before the shutdown, ends it with exit status 1 (launch turns an exception in
    an event handler into shutdown and status 1).
    """
    def on_exit(event, context):
        status = event.returncode
        if kind == 'clock' and status == 0:
            completed.append(name)
            return [EmitEvent(event=Shutdown(reason='run complete'))]
        if context.is_shutdown:
            return []
        if status != 0:
            raise RunFailed(f'{name} exited with status {status}: the run did not complete '
                            '(its log is above)')
        return [EmitEvent(event=Shutdown(reason=f'{name} exited (lockstep needs every node)'))]
    return on_exit


def _on_idle(completed):
    """Build the handler of the launch's shutdown when nothing is left running ('idle').

    The launch also ends when nothing is left running ('idle'). That happens without a process
    exit event when no node could be started at all (launch logs the exec error and sends none):
    without the clock's completion, that is a failed run, status 1.
    """
    def on_shutdown(event, context):
        if event.reason == 'idle' and not completed:
            raise RunFailed('every process has ended, and the clock never completed the run (a node that '
                            'could not be started is logged above)')
        return []
    return on_shutdown


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('scenario', default_value='paper', description='scenario YAML or "paper"'),
        DeclareLaunchArgument('case', default_value='proposed', description='proposed | case1 | case2'),
        DeclareLaunchArgument('clock_mode', default_value='realtime', description='lockstep | realtime'),
        DeclareLaunchArgument('rate', default_value='1.0', description='realtime factor'),
        DeclareLaunchArgument('duration', default_value='', description="simulated s (default: the scenario's)"),
        DeclareLaunchArgument('out', default_value='', description='run directory; the bag goes to OUT/bag '
                              '(default runs/launch_<timestamp>)'),
        DeclareLaunchArgument('visualization', default_value='true', description='start the visualisation node'),
        DeclareLaunchArgument('standard_views', default_value='true',
                              description='publish /tf, /uhN/odom and /diagnostics (docs/visualization.md)'),
        DeclareLaunchArgument('backend', default_value='rclpy',
                              description='rclpy: the team on rclpy (recorder, visualisation on the DDS backend); '
                              'dds: every node on the Cyclone DDS backend (for realtime on small machines, '
                              'docs/performance.md)'),
        DeclareLaunchArgument('startup_timeout', default_value='60.0', description='s to wait for all nodes'),
        DeclareLaunchArgument('stale_timeout', default_value=str(DEFAULT_STALE_TIMEOUT),
                              description='realtime: simulated s after which a neighbour is stale'),
        DeclareLaunchArgument('realtime_priority', default_value=str(DEFAULT_PRIORITY),
                              description='realtime: SCHED_FIFO priority of the clock, simulators, controllers and '
                              'virtual leader (needs CAP_SYS_NICE (root has it) or an rtprio limit; each node logs '
                              'whether it got it); 0: normal scheduling (docs/performance.md)'),
        OpaqueFunction(function=_team),
    ])
