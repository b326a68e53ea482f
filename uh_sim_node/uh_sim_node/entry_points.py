"""Console entry point of the simulator node: runs the ahead-of-time compiled model where one was built.

``sim_node`` selects the kernels' form (``UH_KERNELS=auto`` unless set) before the node's module
imports them, then runs :func:`uh_sim_node.sim_node.main` (:func:`uh_core.compiled_kernels.run_node_main`).
"""
from __future__ import annotations

from uh_core import compiled_kernels

__all__ = ['sim_node']


def sim_node(args=None):
    """Run the simulator node (``ros2 run uh_sim_node sim_node``) on compiled kernels where they were built."""
    return compiled_kernels.run_node_main('uh_sim_node.sim_node', 'sim_node', args)
