"""rclpy backend: re-exports of ROS 2 Jazzy's own rclpy objects under the facade's names.

Nothing is wrapped: ``rt.Node`` *is* ``rclpy.node.Node``, ``rt.init`` *is* ``rclpy.init`` (which
returns ``None`` on Jazzy; there is no ``with rclpy.init():`` there). Only imported when
:func:`uh_runtime.backend.select_backend` chose rclpy.
"""
import rclpy
from rcl_interfaces.msg import (
    FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult,
)
from rclpy.clock import Clock, ClockType, ROSClock
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.exceptions import (
    InvalidParameterTypeException, InvalidParameterValueException,
    ParameterAlreadyDeclaredException, ParameterException, ParameterNotDeclaredException,
    ParameterUninitializedException,
)
from rclpy.executors import (
    Executor, ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor,
)
from rclpy.logging import get_logger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.qos import (
    DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy,
    qos_profile_sensor_data, qos_profile_system_default,
)
from rclpy.subscription import Subscription
from rclpy.time import Time
from rclpy.timer import Timer
from rclpy.utilities import get_default_context, remove_ros_args

init = rclpy.init
ok = rclpy.ok
shutdown = rclpy.shutdown
try_shutdown = rclpy.try_shutdown
spin = rclpy.spin
spin_once = rclpy.spin_once
spin_until_future_complete = rclpy.spin_until_future_complete
get_global_executor = rclpy.get_global_executor
ParameterType = Parameter.Type
NotInitializedException = rclpy.exceptions.NotInitializedException

__all__ = [
    'Clock', 'ClockType', 'Context', 'Duration', 'Executor', 'ExternalShutdownException',
    'MultiThreadedExecutor', 'Node', 'NotInitializedException', 'Publisher', 'ROSClock',
    'SingleThreadedExecutor', 'Subscription', 'Time', 'Timer', 'get_default_context',
    'get_global_executor', 'init', 'ok', 'shutdown', 'spin', 'spin_once',
    'spin_until_future_complete', 'try_shutdown', 'get_logger', 'FloatingPointRange',
    'IntegerRange', 'InvalidParameterTypeException', 'InvalidParameterValueException',
    'Parameter', 'ParameterAlreadyDeclaredException', 'ParameterDescriptor',
    'ParameterException', 'ParameterNotDeclaredException', 'ParameterType',
    'ParameterUninitializedException', 'SetParametersResult', 'DurabilityPolicy',
    'HistoryPolicy', 'LivelinessPolicy', 'QoSProfile', 'ReliabilityPolicy',
    'qos_profile_sensor_data', 'qos_profile_system_default', 'remove_ros_args',
]
