"""Interfaces every side of the stack shares (docs/architecture.md).

``layout``: state, input/channel and reference layouts; ``airframe``: helicopter parameters;
``topics``: the registry of topic names and QoS; ``wire``: conversions between the core's arrays
and ``uh_msgs`` messages. The simulator (``uh_sim_node``) and the controller
(``uh_controller_node``) both depend on this package and never on each other.
"""
