"""The simulated world of a team run: helicopters, the virtual leader, the clock (docs/architecture.md).

``helicopter``, ``faults`` and ``plant_kernels``: the helicopter model with actuator faults
(docs/model.md, docs/faults.md); ``reference``: the virtual leader's trajectory; the nodes
``sim_node`` (with ``command_watch``), ``virtual_leader_node``, ``clock_node`` (with
``clock_advance``, the lockstep and realtime clock) and ``visualization_node`` (``/markers``).
"""
