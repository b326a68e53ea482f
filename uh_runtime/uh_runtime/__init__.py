"""Node runtime of the UH stack: one rclpy-shaped facade, two backends (DESIGN.md section 1).

``import uh_runtime as rt`` and write node code as with rclpy::

    rt.init(args=args)
    node = rt.Node('sim', namespace='/uh1')
    pub = node.create_publisher(UHState, 'state', rt.QoSProfile(depth=10))
    rt.spin(node)

With rclpy importable (a sourced ROS 2 Jazzy) and ``UH_BACKEND`` not ``dds``, every name here is
rclpy's own object. Otherwise they come from :mod:`uh_runtime.dds_backend`, which talks Cyclone
DDS with ROS 2's wire conventions. ``rt.BACKEND`` says which one is active. Messages:
:mod:`uh_runtime.messages`.
"""
from .backend import BackendError, select_backend
from .runner import check_parameter_overrides, run_node

BACKEND = select_backend()

if BACKEND == 'rclpy':
    from .rclpy_backend import *  # noqa: F401,F403
    from .rclpy_backend import __all__ as _backend_names
else:
    from .dds_backend import (  # noqa: F401
        Clock, ClockType, Context, Duration, Executor, ExternalShutdownException,
        MultiThreadedExecutor, Node, NotInitializedException, Publisher, ROSClock,
        SingleThreadedExecutor, Subscription, Time, Timer, get_default_context,
        get_global_executor, init, ok, shutdown, spin, spin_once, spin_until_future_complete,
        try_shutdown,
    )
    from .dds_backend import get_logger  # noqa: F401
    from .parameters import (  # noqa: F401
        FloatingPointRange, IntegerRange, InvalidParameterTypeException,
        InvalidParameterValueException, Parameter, ParameterAlreadyDeclaredException,
        ParameterDescriptor, ParameterException, ParameterNotDeclaredException, ParameterType,
        ParameterUninitializedException, SetParametersResult,
    )
    from .qos import (  # noqa: F401
        DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy,
        qos_profile_sensor_data, qos_profile_system_default,
    )
    from .arguments import remove_ros_args  # noqa: F401
    _backend_names = [
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

from .parameters import UnknownParameterOverrideError  # noqa: E402,F401

__all__ = sorted(set(_backend_names) | {
    'BACKEND', 'BackendError', 'select_backend', 'run_node', 'check_parameter_overrides',
    'UnknownParameterOverrideError',
})
