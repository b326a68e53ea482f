"""What both sides of a helicopter share, free of any middleware (docs/architecture.md).

``layout``: state, input/channel and reference layouts; ``airframe``: helicopter parameters;
``records``: the ``Reference`` and ``FaultSpec`` records; ``frames``: frame conversions;
``diagnostics``: health windows and their levels; ``checks``: input checks; ``kernel_cache``:
the numba cache guard. The simulator (``uh_sim_node``) and the controller (``uh_controller_node``)
both depend on this package and never on each other; their messages are in :mod:`uh_wire`.
"""
