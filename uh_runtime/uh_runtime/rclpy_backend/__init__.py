"""rclpy backend: re-exports of ROS 2 Jazzy's own rclpy objects under the facade's names.

One addition: ``StaticSingleThreadedExecutor`` (:mod:`.executors`), the executor the
project's nodes spin in. Nothing is wrapped: ``rt.Node`` *is* ``rclpy.node.Node``, ``rt.init`` *is*
``rclpy.init`` (which returns ``None`` on Jazzy; there is no ``with rclpy.init():`` there). Only
imported when :func:`uh_runtime.backend.select_backend` chose rclpy.
"""
import rclpy
from rcl_interfaces.msg import (  # noqa: F401
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.context import Context  # noqa: F401
from rclpy.duration import Duration  # noqa: F401
from rclpy.exceptions import NotInitializedException  # noqa: F401
from rclpy.executors import (  # noqa: F401
    ExternalShutdownException,
    MultiThreadedExecutor,
    SingleThreadedExecutor,
)
from rclpy.node import Node  # noqa: F401
from rclpy.parameter import Parameter  # noqa: F401
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: F401
from rclpy.utilities import remove_ros_args  # noqa: F401

from ..backend import FACADE_NAMES
from .executors import StaticSingleThreadedExecutor  # noqa: F401

init = rclpy.init
ok = rclpy.ok
try_shutdown = rclpy.try_shutdown
spin = rclpy.spin
spin_once = rclpy.spin_once
ParameterType = Parameter.Type

__all__ = list(FACADE_NAMES)
