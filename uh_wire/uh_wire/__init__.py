"""What a node puts on and takes off the ROS graph (docs/architecture.md, docs/topics.md).

``topics``: the registry of topic names, types and QoS; ``wire``: conversions between the core's
arrays and ``uh_msgs`` messages, with the checks every receiver applies; ``standard_msgs``: the
views for generic tools (``/tf``, ``/uhN/odom``, ``/diagnostics``); ``run_config``: the run
parameters every node declares. The pure layouts these follow are in :mod:`uh_core`.
"""
