"""Console entry point of the simulator node: runs the ahead-of-time compiled model where one was built.

``sim_node`` selects the kernels' form (:func:`uh_core.compiled_kernels.prefer_compiled`: ``UH_KERNELS=auto``
unless set) before the node's module imports them, then runs :func:`uh_sim_node.sim_node.main`.
"""
from __future__ import annotations

import sys

from uh_core import compiled_kernels

__all__ = ['sim_node']


def sim_node(args=None):
    """Run the simulator node (``ros2 run uh_sim_node sim_node``) on compiled kernels where they were built."""
    compiled_kernels.prefer_compiled()
    try:
        from uh_sim_node.sim_node import main
    except compiled_kernels.KernelModeError as exc:   # a bad UH_KERNELS, or compiled kernels asked for and not built
        print(f'sim_node: error: {exc}', file=sys.stderr)
        return 2
    return main(args)
