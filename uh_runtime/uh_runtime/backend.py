"""Choice of the node backend: real ``rclpy`` or the Cyclone DDS backend (docs/runtime.md).

``rclpy`` is used when it is importable and ``UH_BACKEND`` is not ``dds``. ``UH_BACKEND=rclpy``
demands rclpy and fails with :class:`BackendError` when it is missing; ``UH_BACKEND=dds`` forces
the Cyclone DDS backend even on a ROS 2 machine.
"""
import importlib
import os

__all__ = ['BackendError', 'select_backend', 'BACKENDS', 'FACADE_NAMES']

#: The backends this package knows.
BACKENDS = ('rclpy', 'dds')

#: The names every backend exports (its ``__all__``) and ``import uh_runtime as rt`` re-exports: the part of
#: rclpy's API the project's nodes, tools and tests use.
FACADE_NAMES = (
    'Context', 'Duration', 'ExternalShutdownException', 'MultiThreadedExecutor', 'Node', 'NotInitializedException',
    'SingleThreadedExecutor', 'StaticSingleThreadedExecutor', 'init', 'ok', 'spin', 'spin_once', 'try_shutdown',
    'FloatingPointRange', 'IntegerRange', 'Parameter', 'ParameterDescriptor', 'ParameterType',
    'SetParametersResult', 'DurabilityPolicy', 'HistoryPolicy', 'QoSProfile', 'ReliabilityPolicy',
    'remove_ros_args',
)


class BackendError(ImportError):
    """The requested node backend cannot be used."""


def _rclpy_importable(importer) -> bool:
    try:
        importer('rclpy')
    except ImportError:
        return False
    return True


def select_backend(environ=None, importer=importlib.import_module) -> str:
    """Return ``'rclpy'`` or ``'dds'`` for this process.

    Parameters
    ----------
    environ : mapping, optional
        Environment to read ``UH_BACKEND`` from (default ``os.environ``).
    importer : callable, optional
        ``importlib.import_module`` or a stand-in (tests inject one).

    Raises
    ------
    BackendError
        ``UH_BACKEND`` names an unknown backend, or asks for rclpy and rclpy is not importable.
    """
    env = os.environ if environ is None else environ
    wanted = env.get('UH_BACKEND', '').strip().lower()
    if wanted not in ('', *BACKENDS):
        raise BackendError(
            f"UH_BACKEND={env.get('UH_BACKEND')!r} is not a known backend; allowed: "
            "'rclpy', 'dds' or unset (rclpy when importable, otherwise dds)")
    if wanted == 'dds':
        return 'dds'
    if _rclpy_importable(importer):
        return 'rclpy'
    if wanted == 'rclpy':
        raise BackendError(
            'UH_BACKEND=rclpy but rclpy cannot be imported: source a ROS 2 Jazzy installation '
            '(source /opt/ros/jazzy/setup.bash) or unset UH_BACKEND to use the Cyclone DDS backend')
    return 'dds'
