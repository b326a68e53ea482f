"""Console entry point of the controller node: runs the ahead-of-time compiled law where one was built.

``controller_node`` selects the kernels' form (``UH_KERNELS=auto`` unless set) before the node's
module imports them, then runs :func:`uh_controller_node.controller_node.main`
(:func:`uh_core.compiled_kernels.run_node_main`).
"""
from __future__ import annotations

from uh_core import compiled_kernels

__all__ = ['controller_node']


def controller_node(args=None):
    """Run the controller node (``ros2 run uh_controller_node controller_node``) on compiled kernels where built."""
    return compiled_kernels.run_node_main('uh_controller_node.controller_node', 'controller_node', args)
