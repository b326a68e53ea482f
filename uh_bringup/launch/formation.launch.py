"""ROS 2 launch file of a team (ROS 2 Jazzy machines): the same nodes scripts/run_formation.sh starts.

    ros2 launch uh_bringup formation.launch.py scenario:=paper case:=proposed clock_mode:=lockstep

Recording on a ROS 2 machine: start ``ros2 run uh_runtime recorder_node --ros-args -p output:=bag``
(lockstep waits for it with ``expect_recorder:=true``) or use ``ros2 bag record -s mcap -a`` in
real-time mode.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _team(context):
    from uh_topology import topics
    from uh_topology.scenario import load_scenario

    scenario_arg = LaunchConfiguration('scenario').perform(context)
    scenario = load_scenario(scenario_arg)
    common = {'scenario': scenario_arg, 'clock_mode': LaunchConfiguration('clock_mode').perform(context)}
    nodes = []
    for i in scenario.ids:
        ns = topics.uh_namespace(i).lstrip('/')
        nodes.append(Node(package='uh_sim_node', executable='sim_node', name='sim', namespace=ns,
                          parameters=[{**common, 'uh_id': i}], output='screen'))
        nodes.append(Node(package='uh_controller_node', executable='controller_node', name='controller',
                          namespace=ns, output='screen',
                          parameters=[{**common, 'uh_id': i, 'case': LaunchConfiguration('case').perform(context)}]))
    nodes.append(Node(package='uh_sim_node', executable='virtual_leader_node', name='virtual_leader',
                      parameters=[common], output='screen'))
    nodes.append(Node(package='uh_sim_node', executable='lockstep_clock_node', name='clock', output='screen',
                      parameters=[{**common, 'rate': float(LaunchConfiguration('rate').perform(context)),
                                   'expect_recorder': LaunchConfiguration('expect_recorder').perform(context) == 'true'}]))
    return nodes


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('scenario', default_value='paper', description='scenario YAML or "paper"'),
        DeclareLaunchArgument('case', default_value='proposed', description='proposed | case1 | case2'),
        DeclareLaunchArgument('clock_mode', default_value='realtime', description='lockstep | realtime'),
        DeclareLaunchArgument('rate', default_value='1.0', description='realtime factor'),
        DeclareLaunchArgument('expect_recorder', default_value='false',
                              description='lockstep: wait for the recorder node'),
        OpaqueFunction(function=_team),
    ])
