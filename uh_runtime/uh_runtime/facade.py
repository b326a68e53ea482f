"""The facade's names (``rt.Node``, ``rt.init``, ...) taken from the active backend.

:func:`uh_runtime.backend.select_backend` chooses once per process: rclpy's own objects
(:mod:`uh_runtime.rclpy_backend`) or the Cyclone DDS backend's (:mod:`uh_runtime.dds`).
``import uh_runtime as rt`` re-exports this module; :mod:`uh_runtime.runner` uses it directly, as the
package itself imports the runner.
"""
from .backend import FACADE_NAMES, select_backend

BACKEND = select_backend()

if BACKEND == 'rclpy':
    from .rclpy_backend import *  # noqa: F401,F403
else:
    from .dds import *  # noqa: F401,F403

__all__ = ['BACKEND', *FACADE_NAMES]
