"""Bags: rosbag2 bags in MCAP storage, and the nodes that record, replay and show a run's topics.

:mod:`.bag` writes a bag and recovers one a killed recorder left (``python -m uh_runtime.bags.bag
check|recover DIR``); :mod:`.bag_reader` is the one reader of bags, with their one error type
:class:`BagError`; :mod:`.recorder` is the recorder node (``recorder_node``), :mod:`.replay` the player
(``replay_node``, ``scripts/replay.sh``) and :mod:`.live_view` the live view node (``live_view_node``:
the topics over the Foxglove WebSocket protocol, as the recorder follows them). The nodes run on the
facade (``import uh_runtime as rt``), on either backend.

Each name below is imported from its module when first asked for (:mod:`uh_runtime.lazy_exports`), so
``python -m uh_runtime.bags.replay`` loads only what the player imports.
"""
from ..lazy_exports import lazy_exports

__all__, __getattr__ = lazy_exports(__name__, {
    'bag': ('BagWriter', 'TopicInfo', 'message_definition', 'recover_bag', 'CHUNK_SIZE', 'FLUSH_PERIOD_S'),
    'bag_reader': ('BagError', 'BagInfo', 'BagTopic', 'ReadResult', 'MCAP_MAGIC', 'bag_file', 'find_bag_files',
                   'iter_bag_messages', 'open_bag', 'read_messages'),
    'recorder': ('RecorderNode', 'LogClock', 'RecordedProgress'),
    'replay': ('ReplayNode',),
    'live_view': ('LiveViewNode', 'LiveViewError'),
})
