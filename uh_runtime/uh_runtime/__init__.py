"""Node runtime of the UH stack: one rclpy-shaped facade, two backends (docs/runtime.md).

``import uh_runtime as rt`` and write node code as with rclpy::

    rt.init(args=args)
    node = rt.Node('sim', namespace='/uh1')
    pub = node.create_publisher(UHState, 'state', rt.QoSProfile(depth=10))
    rt.spin(node)

With rclpy importable (a sourced ROS 2 Jazzy) and ``UH_BACKEND`` not ``dds``, every name here is
rclpy's own object (:mod:`uh_runtime.rclpy_backend`). Otherwise they come from :mod:`uh_runtime.dds`,
the backend that talks Cyclone DDS with ROS 2's wire conventions. ``rt.BACKEND`` says which one is
active (:mod:`uh_runtime.facade` makes the choice). Messages: :mod:`uh_runtime.messages`.

The package, by kind: here, what every node uses whichever backend runs (the facade, the backend
choice, messages, the names on the wire, the runner, real-time scheduling, the DDS network set-up,
process statistics, the commands' argument parser); :mod:`uh_runtime.dds` and
:mod:`uh_runtime.rclpy_backend`, the two backends; :mod:`uh_runtime.bags`, the bags and the nodes that
record, replay and show them; :mod:`uh_runtime.cli`, the ``uh`` command.
"""
from .backend import FACADE_NAMES
from .facade import *  # noqa: F401,F403
from .facade import BACKEND
from .runner import check_parameter_overrides, log_on_exit, run_node

# The names imported above, re-exported: a literal list first so that linters see them, then with the facade's.
__all__ = ['BACKEND', 'run_node', 'log_on_exit', 'check_parameter_overrides']
__all__ = sorted({*FACADE_NAMES, *__all__})
