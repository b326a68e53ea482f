"""Cyclone DDS backend of the node facade: the rclpy (Jazzy) subset the UH nodes use (docs/runtime.md).

Wire conventions are those of ROS 2 Jazzy with rmw_cyclonedds_cpp, so ROS 2 tools and nodes on the
same DDS domain interoperate:

* one DDS participant per context (process), USER_DATA ``enclave=/;``;
* ROS topic ``/uh1/state`` -> DDS topic ``rt/uh1/state``; type ``uh_msgs::msg::dds_::UHState_``;
  XCDR1 little-endian payload (the ROS 2 CDR bytes);
* reader/writer QoS mapped like rmw_cyclonedds (see :mod:`.qos`), USER_DATA
  ``typehash=RIHS01_<hex>;``;
* ``ros_discovery_info`` (``rmw_dds_common/msg/ParticipantEntitiesInfo``; reliable,
  transient-local, keep-last 1) lists each node's name and namespace with the GIDs of its readers
  and writers.

The package owns the backend whole. The modules follow rclpy's: :mod:`.clock` (``rclpy.time``,
``rclpy.duration``, ``rclpy.clock``), :mod:`.logger` (``rclpy.logging``), :mod:`.context`
(``rclpy.context``, ``init``/``ok``/``shutdown``), :mod:`.endpoints` (``rclpy.publisher``,
``rclpy.subscription``, ``rclpy.timer``), :mod:`.node` (``rclpy.node``), :mod:`.services` (the
parameter services, ``rclpy.parameter_service``), :mod:`.executors` (``rclpy.executors``, ``spin``)
and :mod:`.signals` (``rclpy.signals``); parameters are :mod:`.parameters`, QoS :mod:`.qos`, names
and ``--ros-args`` :mod:`.arguments`, the CDR codecs :mod:`.cdr`, the discovery graph :mod:`.graph`
(also read by the ``uh`` CLI), delivery inside a process :mod:`.intra_process`.

This package exports the facade's names (:data:`uh_runtime.backend.FACADE_NAMES`), as
:mod:`uh_runtime.rclpy_backend` does; ``import uh_runtime as rt`` re-exports the active backend's.
Each name is imported from its module when first asked for (:mod:`uh_runtime.lazy_exports`): the
bags, the topic registry and the runner use a few of these modules (the QoS words of :mod:`.qos`,
the name checks of :mod:`.arguments`, :class:`~.parameters.UnknownParameterOverrideError`,
:func:`~.signals.sigint_ignored`) on either backend, without loading the backend itself.
"""
from ..lazy_exports import lazy_exports

__all__, __getattr__ = lazy_exports(__name__, {
    'arguments': ('remove_ros_args',),
    'parameters': ('FloatingPointRange', 'IntegerRange', 'Parameter', 'ParameterDescriptor', 'ParameterType',
                   'SetParametersResult'),
    'qos': ('DurabilityPolicy', 'HistoryPolicy', 'QoSProfile', 'ReliabilityPolicy'),
    'clock': ('Duration',),
    'context': ('Context', 'NotInitializedException', 'init', 'ok', 'try_shutdown'),
    'executors': ('ExternalShutdownException', 'MultiThreadedExecutor', 'SingleThreadedExecutor',
                  'StaticSingleThreadedExecutor', 'spin', 'spin_once'),
    'node': ('Node',),
})
