"""rclpy backend: re-exports of ROS 2 Jazzy's own rclpy objects under the facade's names.

One addition: ``StaticSingleThreadedExecutor`` (``uh_runtime.rclpy_executor``), the executor the
project's nodes spin in. Nothing is wrapped: ``rt.Node`` *is* ``rclpy.node.Node``, ``rt.init`` *is*
``rclpy.init`` (which returns ``None`` on Jazzy; there is no ``with rclpy.init():`` there). Only
imported when :func:`uh_runtime.backend.select_backend` chose rclpy.
"""
import rclpy
from rcl_interfaces.msg import (  # noqa: F401
    FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult,
)
from rclpy.clock import Clock, ClockType, ROSClock  # noqa: F401
from rclpy.context import Context  # noqa: F401
from rclpy.duration import Duration  # noqa: F401
from rclpy.exceptions import (  # noqa: F401
    InvalidParameterTypeException, InvalidParameterValueException,
    ParameterAlreadyDeclaredException, ParameterException, ParameterNotDeclaredException,
    ParameterUninitializedException,
)
from rclpy.executors import (  # noqa: F401
    Executor, ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor,
)
from rclpy.logging import get_logger  # noqa: F401
from rclpy.node import Node  # noqa: F401
from rclpy.parameter import Parameter  # noqa: F401
from rclpy.publisher import Publisher  # noqa: F401
from rclpy.qos import (  # noqa: F401
    DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy,
    qos_profile_sensor_data, qos_profile_system_default,
)
from rclpy.subscription import Subscription  # noqa: F401
from rclpy.time import Time  # noqa: F401
from rclpy.timer import Timer  # noqa: F401
from rclpy.utilities import get_default_context, remove_ros_args  # noqa: F401

from .backend import FACADE_NAMES
from .rclpy_executor import StaticSingleThreadedExecutor  # noqa: F401

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

__all__ = list(FACADE_NAMES)
