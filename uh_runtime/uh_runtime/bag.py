"""rosbag2 bags in MCAP storage, written with the ``mcap`` library.

A bag is a directory holding ``<name>_0.mcap`` and ``metadata.yaml``, laid out exactly as
``ros2 bag record -s mcap`` on ROS 2 Jazzy does it (checked against a bag recorded by Jazzy:
``tests/data/ros2_jazzy_sample``):

- MCAP header profile ``ros2``; one schema per message type with encoding ``ros2msg`` and the full
  message definition (the type's own text followed by every dependency after a line of 80 ``=``
  and ``MSG: pkg/Type``); one channel per topic with message encoding ``cdr`` and channel metadata
  ``offered_qos_profiles`` (YAML) and ``topic_type_hash`` (``RIHS01_...``);
- payloads are the CDR bytes as received (4-byte encapsulation header included);
- a ``rosbag2`` metadata record with ``serialized_metadata`` written when the bag is opened and
  again, complete, when it is closed; the same text in ``metadata.yaml`` (rosbag2 version 9).

Chunks are written uncompressed (the rosbag2 default) and kept small, so a recorder killed with
SIGKILL loses at most the chunk being filled (``CHUNK_SIZE`` bytes) and an MCAP reader still opens
everything written before it.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path

from mcap.writer import CompressionType, Writer

__all__ = ['BagWriter', 'BagError', 'TopicInfo', 'qos_profile_yaml', 'message_definition', 'CHUNK_SIZE']

#: MCAP chunk size in bytes: the most a SIGKILL of the recorder can lose (the chunk being filled).
CHUNK_SIZE = 64 * 1024

_SEPARATOR = '=' * 80
_INFINITE = {'sec': 9223372036, 'nsec': 854775807}


class BagError(RuntimeError):
    """A bag cannot be written or read; the message names the file and what is wrong."""


def qos_profile_yaml(reliability: str, durability: str, history: str, depth: int) -> str:
    """Return the rosbag2 ``offered_qos_profiles`` YAML for one writer's QoS.

    ``reliability`` is ``reliable``/``best_effort``, ``durability`` ``volatile``/``transient_local``,
    ``history`` ``keep_last``/``keep_all``; deadline, lifespan and lease are infinite as in ROS 2's
    defaults. The layout is the one rosbag2 on Jazzy writes (see the module docstring).
    """
    inf = f"sec: {_INFINITE['sec']}\n    nsec: {_INFINITE['nsec']}"
    return (
        f'- history: {history}\n  depth: {int(depth)}\n  reliability: {reliability}\n'
        f'  durability: {durability}\n  deadline:\n    {inf}\n  lifespan:\n    {inf}\n'
        f'  liveliness: automatic\n  liveliness_lease_duration:\n    {inf}\n'
        '  avoid_ros_namespace_conventions: false'
    )


def _msg_directory() -> Path:
    # TODO(runtime): use the message-file lookup of uh_runtime.messages once it exists.
    import sys
    for candidate in (Path(sys.prefix) / 'share/uh_msgs/msg', Path(__file__).resolve().parents[2] / 'uh_msgs/msg'):
        if candidate.is_dir():
            return candidate
    raise BagError('cannot find the uh_msgs .msg files')


@functools.lru_cache(maxsize=None)
def _typestore():
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    store = get_typestore(Stores.ROS2_JAZZY)
    texts = {}
    for path in sorted(_msg_directory().glob('*.msg')):
        name = f'uh_msgs/msg/{path.stem}'
        texts[name] = path.read_text()
        store.register(get_types_from_msg(texts[name], name))
    return store, texts


def message_definition(type_name: str) -> tuple[str, str]:
    """Return ``(ros2msg definition text, RIHS01 type hash)`` of ``type_name`` (``pkg/msg/Type``).

    The project's own types keep their ``.msg`` text (with the unit comments); dependencies and
    standard types come from rosbags' Jazzy type store.
    """
    store, texts = _typestore()
    if type_name not in store.fielddefs:
        raise BagError(f'unknown message type {type_name!r}: not a uh_msgs type nor a ROS 2 Jazzy standard type')
    generated, _ = store.generate_msgdef(type_name, ros_version=2)
    if type_name in texts:
        own, _, deps = generated.partition(_SEPARATOR)
        generated = texts[type_name].rstrip('\n') + '\n' + (_SEPARATOR + deps if deps else '')
    return generated, store.hash_rihs01(type_name)


@dataclass
class TopicInfo:
    """One topic of a bag: name, type, offered QoS (rosbag2 YAML) and bookkeeping."""

    name: str
    type: str
    offered_qos_profiles: str
    type_hash: str
    channel_id: int = -1
    message_count: int = 0
    first_ns: int | None = None
    last_ns: int | None = None


@dataclass
class BagWriter:
    """Write a rosbag2 MCAP bag into ``directory`` (created; must not exist or be empty).

    Use :meth:`add_topic` once per topic, :meth:`write` per message, :meth:`close` at the end
    (also called by the context manager). Times are nanoseconds.
    """

    directory: Path
    topics: dict[str, TopicInfo] = field(default_factory=dict)

    def __post_init__(self):
        self.directory = Path(self.directory)
        if self.directory.exists() and any(self.directory.iterdir()):
            raise BagError(f'bag directory {self.directory} exists and is not empty; refusing to overwrite it')
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self.file_name = f'{self.directory.name}_0.mcap'
            self._stream = open(self.directory / self.file_name, 'wb')
        except OSError as exc:
            raise BagError(f'cannot create bag in {self.directory}: {exc.strerror}') from exc
        self._writer = Writer(self._stream, chunk_size=CHUNK_SIZE, compression=CompressionType.NONE)
        self._writer.start(profile='ros2', library='uh_runtime bag writer (mcap python)')
        self._schemas: dict[str, int] = {}
        self._closed = False
        self._writer.add_metadata('rosbag2', {'serialized_metadata': self._metadata_yaml(indent=0)})

    def add_topic(self, name: str, type_name: str, offered_qos_profiles: str) -> TopicInfo:
        """Register topic ``name`` of ``type_name`` with its offered QoS (see :func:`qos_profile_yaml`)."""
        if name in self.topics:
            return self.topics[name]
        definition, type_hash = message_definition(type_name)
        if type_name not in self._schemas:
            self._schemas[type_name] = self._writer.register_schema(type_name, 'ros2msg', definition.encode())
        info = TopicInfo(name, type_name, offered_qos_profiles, type_hash)
        info.channel_id = self._writer.register_channel(
            topic=name, message_encoding='cdr', schema_id=self._schemas[type_name],
            metadata={'offered_qos_profiles': offered_qos_profiles, 'topic_type_hash': type_hash})
        self.topics[name] = info
        return info

    def write(self, topic: str, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        """Append one message of ``topic`` (CDR bytes with encapsulation header)."""
        info = self.topics[topic]
        self._writer.add_message(channel_id=info.channel_id, log_time=int(log_time_ns),
                                 publish_time=int(log_time_ns if publish_time_ns is None else publish_time_ns),
                                 data=bytes(data), sequence=info.message_count)
        info.message_count += 1
        if info.first_ns is None or log_time_ns < info.first_ns:
            info.first_ns = int(log_time_ns)
        if info.last_ns is None or log_time_ns > info.last_ns:
            info.last_ns = int(log_time_ns)

    def flush(self) -> None:
        """Push buffered bytes to the file (completed chunks only; MCAP appends)."""
        self._stream.flush()

    def close(self) -> None:
        """Finish the MCAP file (summary, final rosbag2 metadata record) and write ``metadata.yaml``."""
        if self._closed:
            return
        self._closed = True
        self._writer.add_metadata('rosbag2', {'serialized_metadata': self._metadata_yaml(indent=0)})
        self._writer.finish()
        self._stream.close()
        (self.directory / 'metadata.yaml').write_text(self._metadata_yaml(indent=1) + '\n')

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- rosbag2 metadata (version 9, the layout Jazzy writes) --------------------------------------
    def _metadata_yaml(self, indent: int) -> str:
        starts = [t.first_ns for t in self.topics.values() if t.first_ns is not None]
        ends = [t.last_ns for t in self.topics.values() if t.last_ns is not None]
        start = min(starts) if starts else 9223372036854775807
        duration = (max(ends) - start) if ends else 0
        count = sum(t.message_count for t in self.topics.values())
        lines = ['version: 9', 'storage_identifier: mcap', 'duration:', f'  nanoseconds: {duration}',
                 'starting_time:', f'  nanoseconds_since_epoch: {start}', f'message_count: {count}',
                 'topics_with_message_count:']
        if not self.topics:
            lines.append('  []')
        for info in self.topics.values():
            qos = '\n'.join('        ' + line for line in info.offered_qos_profiles.splitlines())
            lines += ['  - topic_metadata:', f'      name: {info.name}', f'      type: {info.type}',
                      '      serialization_format: cdr', '      offered_qos_profiles:', qos,
                      f'      type_description_hash: {info.type_hash}', f'    message_count: {info.message_count}']
        lines += ['compression_format: ""', 'compression_mode: ""', 'relative_file_paths:',
                  f'  - {self.file_name}', 'files:', f'  - path: {self.file_name}', '    starting_time:',
                  f'      nanoseconds_since_epoch: {start}', '    duration:', f'      nanoseconds: {duration}',
                  f'    message_count: {count}', 'custom_data: ~', 'ros_distro: jazzy']
        if indent:
            return 'rosbag2_bagfile_information:\n' + '\n'.join('  ' + line for line in '\n'.join(lines).splitlines())
        return '\n'.join(lines)
