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

Crash safety. Chunks are written uncompressed (the rosbag2 default) and kept small, straight to the
file with unbuffered writes (a completed chunk is in the operating system's hands as soon as it is
written), and :meth:`BagWriter.flush` closes the chunk being filled (the recorder calls it every
``FLUSH_PERIOD_S``). A process killed with SIGKILL therefore loses at most the chunk being filled:
fewer than ``CHUNK_SIZE`` bytes of messages plus the message that would have completed it, and no
more than ``FLUSH_PERIOD_S`` seconds of recording. What is on disk is readable up to its last
complete chunk with :func:`uh_runtime.bags.bag_reader.read_messages` (the ``mcap`` stream reader,
stopping cleanly at the damage), and :func:`recover_bag` turns it into a complete bag again
(summary, ``metadata.yaml``) that ``ros2 bag`` and rosbags open: ``python -m uh_runtime.bags.bag recover
BAG_DIR``. A bag closed normally (SIGINT/SIGTERM of the recorder) is complete.

Reading bags, and the error type :class:`~uh_runtime.bags.bag_reader.BagError` of both writing and
reading, are :mod:`uh_runtime.bags.bag_reader`; the ``offered_qos_profiles`` YAML is
:func:`uh_runtime.dds.qos.qos_profile_yaml`.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

from mcap.writer import CompressionType, Writer

from ..command_line import ArgumentParser
from ..dds.qos import qos_profile_yaml
from ..messages import type_hash, typestore, uh_msg_texts
from .bag_reader import BagError, ReadResult, bag_file, read_messages

__all__ = ['BagWriter', 'TopicInfo', 'message_definition', 'CHUNK_SIZE', 'FLUSH_PERIOD_S', 'recover_bag']

#: MCAP chunk size in bytes: a SIGKILL of the recorder loses at most the chunk being filled (fewer
#: than CHUNK_SIZE bytes of messages, plus the one message that would have completed it).
CHUNK_SIZE = 64 * 1024
#: The recorder closes the chunk being filled at least this often (s), bounding the loss in time.
FLUSH_PERIOD_S = 1.0

_SEPARATOR = '=' * 80


def message_definition(type_name: str) -> tuple[str, str]:
    """Return ``(ros2msg definition text, RIHS01 type hash)`` of ``type_name`` (``pkg/msg/Type``).

    The project's own types keep their ``.msg`` text (with the unit comments); dependencies and
    standard types come from rosbags' Jazzy type store.
    """
    store, texts = typestore(), uh_msg_texts()
    if type_name not in store.fielddefs:
        raise BagError(f'unknown message type {type_name!r}: not a uh_msgs type nor a ROS 2 Jazzy standard type')
    generated, _ = store.generate_msgdef(type_name, ros_version=2)
    if type_name in texts:
        own, _, deps = generated.partition(_SEPARATOR)
        generated = texts[type_name].rstrip('\n') + '\n' + (_SEPARATOR + deps if deps else '')
    return generated, type_hash(type_name)


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


class _DirectFile:
    """A write-only binary file without a user-space buffer.

    Every ``write`` is handed to the operating system at once (so what the MCAP writer wrote survives a SIGKILL
    of the process).
    """

    def __init__(self, path: Path):
        self._raw = open(path, 'wb', buffering=0)

    def write(self, data) -> int:
        view = memoryview(data)
        while view:
            written = self._raw.write(view)
            view = view[written:]
        return len(data)

    def tell(self) -> int:
        return self._raw.tell()

    def flush(self) -> None:
        pass

    def close(self) -> None:
        self._raw.close()


@dataclass
class BagWriter:
    """Write a rosbag2 MCAP bag into ``directory`` (created; must not exist or be empty).

    Use :meth:`add_topic` once per topic, :meth:`write` per message, :meth:`close` at the end
    (also called by the context manager). Times are nanoseconds.
    """

    directory: Path
    topics: dict[str, TopicInfo] = field(default_factory=dict)
    #: file names that may already be in ``directory`` (used by :func:`recover_bag`)
    keep: tuple = ()
    #: name of the MCAP file; default ``<directory name>_0.mcap`` as rosbag2 names it
    file_name: str = ''

    def __post_init__(self):
        self.directory = Path(self.directory)
        if self.directory.exists() and any(p.name not in self.keep for p in self.directory.iterdir()):
            raise BagError(f'bag directory {self.directory} exists and is not empty; refusing to overwrite it')
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self.file_name = self.file_name or f'{self.directory.name}_0.mcap'
            self._stream = _DirectFile(self.directory / self.file_name)
        except OSError as exc:
            raise BagError(f'cannot create bag in {self.directory}: {exc.strerror}') from exc
        self._writer = Writer(self._stream, chunk_size=CHUNK_SIZE, compression=CompressionType.NONE)
        self._writer.start(profile='ros2', library='uh_runtime bag writer (mcap python)')
        self._schemas: dict[str, int] = {}
        self._closed = False
        self._writer.add_metadata('rosbag2', {'serialized_metadata': self._metadata_yaml(indent=0)})

    def add_topic(self, name: str, type_name: str, offered_qos_profiles: str) -> TopicInfo:
        """Register topic ``name`` of ``type_name`` with its offered QoS.

        ``offered_qos_profiles`` is rosbag2 YAML, see :func:`uh_runtime.dds.qos.qos_profile_yaml`.
        """
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
        """Close the chunk being filled and hand it to the file.

        Everything written so far survives a crash of this process (a chunk with no messages is not written).
        """
        if not self._closed:
            self._writer.flush()

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


# -- completing what a crashed recorder left --------------------------------------------------------
def recover_bag(bag_dir) -> ReadResult:
    """Make the bag in ``bag_dir`` complete again after its writer was killed.

    Every message up to the last complete chunk is copied, with its topic, type, QoS and times, into
    a new ``<dir>_0.mcap`` with summary and ``metadata.yaml``; the damaged file is kept beside it as
    ``<dir>_0.mcap.truncated``. A complete bag is left as it is. Returns what was read.

    Raises
    ------
    BagError
        No MCAP file in ``bag_dir`` (see :func:`uh_runtime.bags.bag_reader.find_bag_files`), or not an
        MCAP file.
    """
    source = bag_file(bag_dir)
    bag_dir = source.parent
    probe = read_messages(source)
    if probe.complete and (bag_dir / 'metadata.yaml').exists():
        return probe
    kept = source.with_name(source.name + '.truncated')
    source.rename(kept)
    writer = BagWriter(bag_dir, keep=(kept.name, 'metadata.yaml'), file_name=source.name)
    (bag_dir / 'metadata.yaml').unlink(missing_ok=True)

    def copy(channel, message):
        if channel.topic not in writer.topics:
            schema = probe.schemas.get(channel.schema_id)
            writer.add_topic(channel.topic, schema.name if schema else '',
                             channel.metadata.get('offered_qos_profiles', qos_profile_yaml(
                                 'reliable', 'volatile', 'keep_last', 10)))
        writer.write(channel.topic, message.data, message.log_time, message.publish_time)

    try:
        result = read_messages(kept, copy)
    finally:
        writer.close()
    return result


def _main(argv=None) -> int:
    parser = ArgumentParser(prog='python -m uh_runtime.bags.bag',
                                     description='Check or recover a bag a killed recorder left behind.')
    sub = parser.add_subparsers(dest='command', required=True)
    for name, text in (('check', 'read the bag up to its last complete chunk and report'),
                       ('recover', 'rewrite the bag complete (summary, metadata.yaml) from what is readable')):
        sub.add_parser(name, help=text).add_argument('bag', help='bag directory or .mcap file')
    args = parser.parse_args(argv)
    if not args.bag.strip():
        parser.error("bag '': give a bag directory or an .mcap file")
    try:
        result = read_messages(bag_file(args.bag)) if args.command == 'check' else recover_bag(args.bag)
    except BagError as exc:
        parser.exit(2, f'{parser.prog}: error: {exc}\n')
    total = sum(result.counts.values())
    state = 'complete' if result.complete else (f'cut short: {result.lost_bytes} bytes after the last complete '
                                                f'chunk are unreadable ({result.problem})')
    print(f'{result.path}: {total} messages on {len(result.counts)} topics; {state}')
    if args.command == 'recover' and not result.complete:
        print(f'recovered into {bag_file(args.bag)} with metadata.yaml')
    return 0


if __name__ == '__main__':
    sys.exit(_main())
