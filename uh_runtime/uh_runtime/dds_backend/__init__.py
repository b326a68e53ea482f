"""Cyclone DDS backend of the node facade: the rclpy (Jazzy) subset the UH nodes use (docs/runtime.md).

Wire conventions are those of ROS 2 Jazzy with rmw_cyclonedds_cpp, so ROS 2 tools and nodes on the
same DDS domain interoperate:

* one DDS participant per context (process), USER_DATA ``enclave=/;``;
* ROS topic ``/uh1/state`` -> DDS topic ``rt/uh1/state``; type ``uh_msgs::msg::dds_::UHState_``;
  XCDR1 little-endian payload (the ROS 2 CDR bytes);
* reader/writer QoS mapped like rmw_cyclonedds (see :mod:`uh_runtime.qos`), USER_DATA
  ``typehash=RIHS01_<hex>;``;
* ``ros_discovery_info`` (``rmw_dds_common/msg/ParticipantEntitiesInfo``; reliable,
  transient-local, keep-last 1) lists each node's name and namespace with the GIDs of its readers
  and writers.

The modules follow rclpy's: :mod:`.clock` (``rclpy.time``, ``rclpy.duration``, ``rclpy.clock``),
:mod:`.logger` (``rclpy.logging``), :mod:`.context` (``rclpy.context``, ``init``/``ok``/``shutdown``),
:mod:`.endpoints` (``rclpy.publisher``, ``rclpy.subscription``, ``rclpy.timer``), :mod:`.node`
(``rclpy.node``) and :mod:`.executors` (``rclpy.executors``, ``spin``). Signal wake-up is
:mod:`uh_runtime.signals`, parameters :mod:`uh_runtime.parameters`, QoS :mod:`uh_runtime.qos`,
``--ros-args`` :mod:`uh_runtime.arguments`.

This package exports the same names as :mod:`uh_runtime.rclpy_backend`; ``import uh_runtime as rt``
re-exports the active backend's.
"""
from ..arguments import remove_ros_args  # noqa: F401
from ..backend import FACADE_NAMES
from ..parameters import (  # noqa: F401
    FloatingPointRange, IntegerRange, InvalidParameterTypeException, InvalidParameterValueException,
    Parameter, ParameterAlreadyDeclaredException, ParameterDescriptor, ParameterException,
    ParameterNotDeclaredException, ParameterType, ParameterUninitializedException, SetParametersResult,
)
from ..qos import (  # noqa: F401
    DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy,
    qos_profile_sensor_data, qos_profile_system_default,
)
from .clock import Clock, ClockType, Duration, ROSClock, Time  # noqa: F401
from .context import (  # noqa: F401
    Context, NotInitializedException, get_default_context, init, ok, shutdown, try_shutdown,
)
from .endpoints import Publisher, Subscription, Timer  # noqa: F401
from .executors import (  # noqa: F401
    Executor, ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor,
    StaticSingleThreadedExecutor, get_global_executor, spin, spin_once, spin_until_future_complete,
)
from .logger import get_logger  # noqa: F401
from .node import Node  # noqa: F401

__all__ = list(FACADE_NAMES)
