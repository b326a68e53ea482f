"""Node runtime of the UH stack: one rclpy-shaped facade, two backends (docs/runtime.md).

``import uh_runtime as rt`` and write node code as with rclpy::

    rt.init(args=args)
    node = rt.Node('sim', namespace='/uh1')
    pub = node.create_publisher(UHState, 'state', rt.QoSProfile(depth=10))
    rt.spin(node)

With rclpy importable (a sourced ROS 2 Jazzy) and ``UH_BACKEND`` not ``dds``, every name here is
rclpy's own object. Otherwise they come from :mod:`uh_runtime.dds_backend`, which talks Cyclone
DDS with ROS 2's wire conventions. ``rt.BACKEND`` says which one is active (:mod:`uh_runtime.facade`
makes the choice). Messages: :mod:`uh_runtime.messages`.
"""
from .backend import FACADE_NAMES, BackendError, select_backend
from .facade import *  # noqa: F401,F403
from .facade import BACKEND
from .parameters import UnknownParameterOverrideError
from .runner import check_parameter_overrides, log_on_exit, run_node

# The names imported above, re-exported: a literal list first so that linters see them, then with the facade's.
__all__ = ['BACKEND', 'BackendError', 'select_backend', 'run_node', 'log_on_exit', 'check_parameter_overrides',
           'UnknownParameterOverrideError']
__all__ = sorted({*FACADE_NAMES, *__all__})
