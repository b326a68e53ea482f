"""The whole team in one process (docs/architecture.md).

It holds the in-process reference simulation, the stacked team kernel, the metrics of a run and
the ``uh-simulate`` command.

It sits above both the simulator (``uh_sim_node``) and the controller (``uh_controller_node``)
and runs the very kernels their nodes call, so a distributed lockstep run reproduces it bit for bit.
"""
