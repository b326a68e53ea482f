"""The controller of one UH and its node (docs/architecture.md, docs/control_law.md).

``controller``: the control law of one UH (:class:`~uh_controller_node.controller.UHController`),
with its ``gains``, ``nominal_model``, ``fault_isolation`` and native kernels; ``input_sync``: which
inputs each step is computed from; ``impairments`` and ``realtime_received``: what the controller
receives under impairments; ``controller_node`` (``controller_node``), ``node_parameters`` and
``controller_diagnostics``: the ROS node around it.
"""
