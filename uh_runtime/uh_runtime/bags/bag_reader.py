"""Reading rosbag2 bags in MCAP storage, and the one error type of bags (:class:`BagError`).

The reader of every part of the project that reads a bag: the player (:mod:`uh_runtime.bags.replay`),
the recovery of a bag a killed recorder left (:func:`uh_runtime.bags.bag.recover_bag`), the metrics and
the report of a run (``uh_bringup``). It plays the part of rosbag2's readers (``rosbag2_py``'s
``SequentialReader``); the MCAP records are read with the ``mcap`` library.

* :func:`find_bag_files` / :func:`bag_file`: the MCAP files of a run directory, a bag directory
  (``metadata.yaml``'s ``relative_file_paths``, else every ``*.mcap``) or one ``.mcap`` file.
* :func:`open_bag`: a complete bag, checked before use (magic, footer, summary, every chunk's CRC
  or record structure) and described (:class:`BagInfo`: topics with type, offered QoS and message
  count; time span); :func:`iter_bag_messages` then yields its messages in log-time order.
* :func:`read_messages`: a bag file record by record, complete or not: a file cut short (a writer
  killed mid-chunk) or damaged after some point is read up to its last complete chunk, and the
  :class:`ReadResult` says where and why it stopped.

Every problem is a :class:`BagError` naming the file and what is wrong: a missing or empty
directory, a file that is not MCAP, a file cut short (no footer: the recorder was killed), a
damaged summary or chunk (CRC mismatch), unusable QoS metadata.
"""
from __future__ import annotations

import heapq
import io
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from ..dds.qos import QoSWords, parse_offered_qos

__all__ = ['BagError', 'MCAP_MAGIC', 'find_bag_files', 'bag_file', 'BagTopic', 'BagInfo', 'open_bag',
           'iter_bag_messages', 'ReadResult', 'read_messages']

#: First and last 8 bytes of every MCAP file.
MCAP_MAGIC = b'\x89MCAP0\r\n'


class BagError(RuntimeError):
    """A bag cannot be written or read; the message names the file and what is wrong."""


# ----------------------------------------------------------------------------------------------
# Finding the files of a bag
# ----------------------------------------------------------------------------------------------
def find_bag_files(path) -> tuple[Path, list]:
    """``(bag directory, [MCAP files])`` of a run directory, a bag directory or one ``.mcap`` file.

    A run directory of ``scripts/run_formation.sh`` holds the bag in ``bag/``. In a bag directory
    the files are those listed in ``metadata.yaml`` (``relative_file_paths``), else every
    ``*.mcap`` in it.

    Raises
    ------
    BagError
        The path does not exist, holds no bag, or ``metadata.yaml`` is unreadable or names a
        missing file.
    """
    import yaml
    path = Path(path)
    if not path.exists():
        raise BagError(f'{path}: no such file or directory')
    if path.is_file():
        return path.parent, [path]
    if (path / 'bag').is_dir() and not (path / 'metadata.yaml').exists() and not any(path.glob('*.mcap')):
        path = path / 'bag'
    metadata = path / 'metadata.yaml'
    if metadata.exists():
        try:
            info = yaml.safe_load(metadata.read_text(errors='replace'))
            info = info['rosbag2_bagfile_information']
            names = list(info.get('relative_file_paths') or [])
            storage = info.get('storage_identifier', 'mcap')
        except (yaml.YAMLError, TypeError, KeyError, AttributeError) as exc:
            raise BagError(f'{metadata}: not a rosbag2 metadata file ({type(exc).__name__}: {exc})') from None
        if storage not in ('mcap', None):
            raise BagError(f'{metadata}: storage is {storage!r}; only MCAP bags can be read '
                           '(record with "ros2 bag record -s mcap")')
        files = [path / name for name in names]
        missing = [str(f) for f in files if not f.exists()]
        if missing:
            raise BagError(f'{metadata}: lists {", ".join(missing)}, which does not exist')
        if files:
            return path, files
    files = sorted(path.glob('*.mcap'))
    if not files:
        contents = sorted(p.name for p in path.iterdir())
        raise BagError(f'{path}: no MCAP bag here (no *.mcap file, no bag/ directory); '
                       f'it holds {contents if contents else "nothing"}')
    return path, files


def bag_file(bag_dir) -> Path:
    """Return the one MCAP file of a bag (see :func:`find_bag_files`; ``bag_dir`` may also be the file).

    Raises
    ------
    BagError
        As :func:`find_bag_files`, or the bag has several MCAP files.
    """
    directory, files = find_bag_files(bag_dir)
    if len(files) != 1:
        raise BagError(f'{directory}: expected one .mcap file in the bag directory, found {len(files)}')
    return files[0]


def _open_mcap(path: Path):
    """``(binary stream, size)`` of the MCAP file ``path``, after checking that it starts like one."""
    try:
        size = path.stat().st_size
        stream = open(path, 'rb')
    except OSError as exc:
        raise BagError(f'cannot open {path}: {exc.strerror}') from None
    head = stream.read(len(MCAP_MAGIC))
    if head != MCAP_MAGIC:
        stream.close()
        if size == 0:
            raise BagError(f'{path}: empty file (0 bytes), not an MCAP bag file')
        raise BagError(f'{path} is not an MCAP file (it starts with {head!r}; an MCAP file starts '
                       f'with {MCAP_MAGIC!r})')
    stream.seek(0)
    return stream, size


def _crc_mismatch(chunk) -> bool | None:
    """Return whether an uncompressed chunk's bytes differ from the CRC its writer stored.

    One C-speed pass checks everything. None if there is nothing to compare (no CRC, as rosbag2 on Jazzy
    writes it, or compressed).
    """
    if chunk.compression != '' or not chunk.uncompressed_crc:
        return None
    return zlib.crc32(chunk.data) != chunk.uncompressed_crc


# ----------------------------------------------------------------------------------------------
# A complete bag: checked, described, read in log-time order
# ----------------------------------------------------------------------------------------------
@dataclass
class BagTopic:
    """One topic (MCAP channel) of a bag."""

    name: str
    type: str
    qos: QoSWords
    message_count: int = 0
    definition: str = ''


@dataclass
class BagInfo:
    """A checked bag: its MCAP files, topics and time span (log times, ns)."""

    directory: Path
    files: list
    topics: dict = field(default_factory=dict)
    start_ns: int = 0
    end_ns: int = 0
    message_count: int = 0

    @property
    def duration_s(self) -> float:
        """Time from the first to the last log time, s (0 for an empty bag)."""
        return max(0, self.end_ns - self.start_ns) * 1e-9


def _recover_hint(path: Path) -> str:
    """Return the sentence that ends the error of a cut or damaged MCAP file: how to recover its bag."""
    return (f'; `python -m uh_runtime.bags.bag recover {path.parent}` restores the bag up to its last complete '
            'chunk (the damaged file is kept beside it)')


def _check_mcap_file(path: Path, check_chunks: bool):
    """Summary of one MCAP file after checking its magic, footer, summary and chunk CRCs."""
    from mcap.data_stream import ReadDataStream
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap.records import Chunk, Message
    from mcap.stream_reader import breakup_chunk

    f, size = _open_mcap(path)
    with f:
        f.seek(max(0, size - len(MCAP_MAGIC)))
        if size < 2 * len(MCAP_MAGIC) or f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise BagError(f'{path}: truncated: the file ({size} bytes) does not end with the MCAP '
                           'footer and magic, so it was not closed (the recorder was killed or the '
                           f'copy is incomplete){_recover_hint(path)}')
        f.seek(0)
        try:
            reader = make_reader(f)
            summary = reader.get_summary()
        except (McapError, ValueError, EOFError, OSError, UnicodeDecodeError, IndexError) as exc:
            raise BagError(f'{path}: corrupted MCAP summary section ({type(exc).__name__}: {exc})') from None
        if summary is None:
            raise BagError(f'{path}: the MCAP file has no summary section (no channel list); '
                           'rosbag2 and the recorder always write one')
        if not check_chunks:
            return summary
        for index in summary.chunk_indexes:
            where = f'{path}: chunk at byte {index.chunk_start_offset}'
            if index.chunk_start_offset + index.chunk_length > size:
                raise BagError(f'{where} runs past the end of the file ({size} bytes): truncated'
                               f'{_recover_hint(path)}')
            try:
                f.seek(index.chunk_start_offset + 1 + 8, io.SEEK_SET)
                chunk = Chunk.read(ReadDataStream(f))
                mismatch = _crc_mismatch(chunk)
                if mismatch:
                    raise BagError(f'{where} is corrupted (CRC mismatch){_recover_hint(path)}')
                if mismatch is None:
                    # no CRC (rosbag2 on Jazzy writes none) or compressed: check the record structure
                    for record in breakup_chunk(chunk, validate_crc=True):
                        if not isinstance(record, Message):
                            continue
                        if record.channel_id not in summary.channels:
                            raise BagError(f'{where} is corrupted (a message of unknown channel '
                                           f'{record.channel_id})')
                        if not chunk.message_start_time <= record.log_time <= chunk.message_end_time:
                            raise BagError(f'{where} is corrupted (a message log time outside the '
                                           "chunk's time range)")
            except BagError:
                raise
            except Exception as exc:  # CRCValidationError, EndOfFile, struct.error, decompression errors
                raise BagError(f'{where} is corrupted ({type(exc).__name__}: {exc})') from None
        return summary


def open_bag(path, check_chunks: bool = True) -> BagInfo:
    """Find and check a bag (see :func:`find_bag_files`) and list its topics.

    Parameters
    ----------
    path : path-like
        Run directory, bag directory or ``.mcap`` file.
    check_chunks : bool
        Also check every chunk: its CRC when the writer stored one (this project's bags; about
        10 ms per MB), otherwise its record structure (channel ids, log times in the chunk's range).
        Damage inside a payload of a chunk without CRC cannot be seen by any reader.

    Raises
    ------
    BagError
        Named file and what is wrong with it (see module docstring).
    """
    directory, files = find_bag_files(path)
    info = BagInfo(directory=directory, files=files)
    starts, ends = [], []
    for file in files:
        summary = _check_mcap_file(file, check_chunks)
        for channel in summary.channels.values():
            schema = summary.schemas.get(channel.schema_id)
            if channel.message_encoding != 'cdr':
                raise BagError(f'{file}: topic {channel.topic} is encoded as {channel.message_encoding!r}; '
                               'only ROS 2 CDR messages can be replayed')
            if schema is None or not schema.name:
                raise BagError(f'{file}: topic {channel.topic} has no message type (schema)')
            count = (summary.statistics.channel_message_counts.get(channel.id, 0)
                     if summary.statistics else 0)
            topic = info.topics.get(channel.topic)
            if topic is None:
                try:
                    qos = parse_offered_qos(channel.metadata.get('offered_qos_profiles'))
                except ValueError as exc:
                    raise BagError(f'{file}: topic {channel.topic}: {exc}') from None
                info.topics[channel.topic] = BagTopic(
                    channel.topic, schema.name, qos, count,
                    schema.data.decode(errors='replace') if schema.data else '')
            elif topic.type != schema.name:
                raise BagError(f'{file}: topic {channel.topic} has type {schema.name} here and '
                               f'{topic.type} in another file of the bag')
            else:
                topic.message_count += count
        if summary.statistics and summary.statistics.message_count:
            starts.append(summary.statistics.message_start_time)
            ends.append(summary.statistics.message_end_time)
            info.message_count += summary.statistics.message_count
    info.start_ns = min(starts) if starts else 0
    info.end_ns = max(ends) if ends else 0
    return info


def iter_bag_messages(info: BagInfo, topics=None):
    """``(topic, log_time_ns, payload bytes)`` of the bag in log-time order (ties: file order).

    Raises
    ------
    BagError
        A chunk cannot be read (named file and the error).
    """
    from mcap.reader import make_reader

    def one_file(rank, file):
        with open(file, 'rb') as f:
            reader = make_reader(f, validate_crcs=True)
            messages = reader.iter_messages(topics=None if topics is None else list(topics), log_time_order=True)
            seq = 0
            while True:
                try:
                    item = next(messages)
                except StopIteration:
                    return
                except Exception as exc:  # a chunk damaged after open_bag checked it
                    raise BagError(f'{file}: cannot read message {seq + 1} '
                                   f'({type(exc).__name__}: {exc})') from None
                _, channel, message = item
                yield message.log_time, rank, seq, channel.topic, message.data
                seq += 1

    streams = [one_file(rank, file) for rank, file in enumerate(info.files)]
    for log_time, _rank, _seq, topic, data in heapq.merge(*streams):
        yield topic, log_time, data


# ----------------------------------------------------------------------------------------------
# Any bag file, record by record, up to its last complete chunk
# ----------------------------------------------------------------------------------------------
@dataclass
class ReadResult:
    """What :func:`read_messages` found.

    Schemas and channels by id, message count per topic, and whether (and where) the file ended early or
    was damaged.
    """

    path: Path
    schemas: dict = field(default_factory=dict)
    channels: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)
    complete: bool = False
    good_bytes: int = 0
    file_bytes: int = 0
    problem: str = ''

    @property
    def lost_bytes(self) -> int:
        """Bytes after the last complete record (the chunk being written when the writer stopped)."""
        return self.file_bytes - self.good_bytes


def read_messages(path, on_message=None) -> ReadResult:
    """Read an MCAP file record by record, up to its end or its last complete chunk.

    Complete files are read entirely; a file cut short (a writer killed mid-chunk) or damaged after
    some point is read up to the last chunk that is complete and passes its CRC, and the result says
    where it stopped and why. ``on_message(channel, message)`` (mcap ``Channel`` and ``Message``
    records) is called for every message in file order.

    Raises
    ------
    BagError
        The file does not exist or does not start like an MCAP file.
    """
    from mcap.exceptions import McapError
    from mcap.records import Channel, Chunk, Footer, Message, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    path = Path(path)
    stream, size = _open_mcap(path)
    result = ReadResult(path, file_bytes=size)
    with stream:
        reader = StreamReader(stream, emit_chunks=True)
        records = reader.records

        def take(record):
            if isinstance(record, Schema):
                result.schemas[record.id] = record
            elif isinstance(record, Channel):
                result.channels[record.id] = record
            elif isinstance(record, Message):
                channel = result.channels.get(record.channel_id)
                if channel is None:
                    raise McapError(f'message on unknown channel {record.channel_id}')
                result.counts[channel.topic] = result.counts.get(channel.topic, 0) + 1
                if on_message is not None:
                    on_message(channel, record)

        try:
            while True:
                try:
                    record = next(records)
                except StopIteration:
                    break
                if isinstance(record, Chunk):
                    if record.compression == '' and len(record.data) != record.uncompressed_size:
                        raise McapError(f'chunk cut short ({len(record.data)} of {record.uncompressed_size} bytes)')
                    if _crc_mismatch(record):
                        raise McapError('chunk CRC mismatch')
                    for inner in breakup_chunk(record, validate_crc=True):
                        take(inner)
                else:
                    take(record)
                result.good_bytes = reader._stream.count
                if isinstance(record, Footer):
                    result.complete = True
                    result.good_bytes = size
        except Exception as exc:  # EndOfFile, struct.error, McapError, CRC errors: damage from here on
            result.problem = f'{type(exc).__name__}: {exc}' if str(exc) else type(exc).__name__
    if not result.complete and not result.problem:
        result.problem = 'the file ends without a footer'
    return result
