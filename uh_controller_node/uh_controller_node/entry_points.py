"""Console entry point of the controller node: runs the ahead-of-time compiled law where one was built.

``controller_node`` selects the kernels' form (:func:`uh_core.compiled_kernels.prefer_compiled`:
``UH_KERNELS=auto`` unless set) before the node's module imports them, then runs
:func:`uh_controller_node.controller_node.main`.
"""
from __future__ import annotations

import sys

from uh_core import compiled_kernels

__all__ = ['controller_node']


def controller_node(args=None):
    """Run the controller node (``ros2 run uh_controller_node controller_node``) on compiled kernels where built."""
    compiled_kernels.prefer_compiled()
    try:
        from uh_controller_node.controller_node import main
    except compiled_kernels.KernelModeError as exc:   # a bad UH_KERNELS, or compiled kernels asked for and not built
        print(f'controller_node: error: {exc}', file=sys.stderr)
        return 2
    return main(args)
