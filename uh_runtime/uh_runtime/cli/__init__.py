"""The ``uh`` command: inspect a running UH stack over DDS discovery, without ROS (:mod:`.uh`).

:mod:`.uh` holds the commands (``uh topic|node|param ...``, output shaped like ``ros2``'s); :mod:`.node_table`
is a run's node table (``UH_RUN_NODES`` in its ``env.sh``, written by ``uh_bringup``), the nodes a listing
waits for. The commands read the graph with the Cyclone DDS backend's :mod:`uh_runtime.dds.graph`.

Each name below is imported from its module when first asked for (:mod:`uh_runtime.lazy_exports`), so
``uh --help`` loads neither Cyclone DDS nor the message types.
"""
from ..lazy_exports import lazy_exports

__all__, __getattr__ = lazy_exports(__name__, {
    'uh': ('main', 'build_parser'),
    'node_table': ('RUN_NODES_VARIABLE', 'export_line', 'run_nodes', 'report_missing'),
})
