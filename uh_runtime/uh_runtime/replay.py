"""``replay_node`` (behind ``scripts/replay.sh``): republish a recorded rosbag2 MCAP bag over DDS.

Like ``ros2 bag play --clock``: every message of the bag (or of the topics chosen) is published
again on its topic, with its recorded type, with the QoS its publishers offered when it was
recorded (the ``offered_qos_profiles`` of the bag's channel metadata), at its recorded log time
scaled by a rate factor, and with its payload bytes exactly as recorded (raw CDR, no decode and
re-encode). ``/clock`` is always published: the bag's own ``/clock`` messages when it has that
topic, otherwise a ``rosgraph_msgs/msg/Clock`` holding the log time, published just before the
first message of each new log time. So ``uh topic echo`` or ``ros2 topic echo``, RViz2, Foxglove
and nodes with ``use_sim_time`` see the run again.

Timing: message ``m`` is due at ``t_start + (log_time(m) - log_time(first)) / rate`` on the
monotonic clock; messages are sent in log-time order, ties in the order they are stored in the
file (the order they were recorded in). Log times of this project's bags are simulation times
(see :mod:`uh_runtime.recorder`); those of ``ros2 bag record`` are receive times.

Bags are checked before anything is published (:func:`open_bag`): a missing or empty directory,
a file that is not MCAP, a file cut short (no footer: the recorder was killed), a damaged summary
or chunk (CRC mismatch) and unusable QoS metadata are reported as :class:`BagReadError` naming
the file and what is wrong.

Exit status: 0 done, 1 nobody subscribed in time (``--wait-for-subscribers``), 2 bad arguments or
an unreadable bag, 130 interrupted (Ctrl-C, SIGTERM).
"""
from __future__ import annotations

import argparse
import heapq
import io
import math
import os
import signal
import sys
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import uh_runtime as rt
from uh_runtime import messages
from uh_runtime.bag import BagError
from uh_runtime.network import MAX_DOMAIN_ID, loopback_environment

__all__ = ['BagReadError', 'ReplayQoS', 'BagTopic', 'BagInfo', 'MCAP_MAGIC', 'find_bag_files',
           'parse_offered_qos', 'open_bag', 'iter_bag_messages', 'ReplayNode', 'build_parser', 'main']

PROG = 'replay'

#: First and last 8 bytes of every MCAP file.
MCAP_MAGIC = b'\x89MCAP0\r\n'

#: QoS of a topic whose bag entry has no offered profile: the ROS 2 default (reliable, volatile, keep last 10).
DEFAULT_DEPTH = 10

#: How long ``--wait-for-subscribers`` waits for every replayed topic to have a subscriber, s.
WAIT_FOR_SUBSCRIBERS_TIMEOUT = 60.0


class BagReadError(BagError):
    """A bag cannot be replayed or read: the message names the file and what is wrong with it."""


# ----------------------------------------------------------------------------------------------
# Reading and checking a bag
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ReplayQoS:
    """QoS to publish a replayed topic with (from the bag's ``offered_qos_profiles``).

    Attributes
    ----------
    reliability : str
        ``'reliable'`` or ``'best_effort'``.
    durability : str
        ``'transient_local'`` or ``'volatile'``.
    history : str
        ``'keep_last'`` or ``'keep_all'``.
    depth : int
        History depth (keep_last).
    """

    reliability: str = 'reliable'
    durability: str = 'volatile'
    history: str = 'keep_last'
    depth: int = DEFAULT_DEPTH

    def profile(self):
        """The facade's ``QoSProfile`` (rclpy's on the rclpy backend)."""
        return rt.QoSProfile(
            history=getattr(rt.HistoryPolicy, self.history.upper()), depth=max(1, int(self.depth)),
            reliability=getattr(rt.ReliabilityPolicy, self.reliability.upper()),
            durability=getattr(rt.DurabilityPolicy, self.durability.upper()))

    def describe(self) -> str:
        hist = f'keep_last {self.depth}' if self.history == 'keep_last' else 'keep_all'
        return f'{self.reliability}, {hist}, {self.durability}'


@dataclass
class BagTopic:
    """One topic (MCAP channel) of a bag."""

    name: str
    type: str
    qos: ReplayQoS
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
        return max(0, self.end_ns - self.start_ns) * 1e-9


_POLICY_VALUES = {
    'reliability': {'reliable': 'reliable', 'best_effort': 'best_effort', 'system_default': 'reliable',
                    '1': 'reliable', '2': 'best_effort', '0': 'reliable'},
    'durability': {'transient_local': 'transient_local', 'volatile': 'volatile', 'system_default': 'volatile',
                   '1': 'transient_local', '2': 'volatile', '0': 'volatile'},
    'history': {'keep_last': 'keep_last', 'keep_all': 'keep_all', 'system_default': 'keep_last',
                '1': 'keep_last', '2': 'keep_all', '0': 'keep_last'},
}


def parse_offered_qos(text: str | None, where: str) -> ReplayQoS:
    """The QoS to replay a topic with, from its rosbag2 ``offered_qos_profiles`` YAML.

    The text is a YAML list with one profile per publisher that was recorded (the layout of
    :func:`uh_runtime.bag.qos_profile_yaml`; rosbag2 writes the same). As ``ros2 bag play`` does,
    the replay is reliable only if every publisher was, transient-local only if every publisher
    was, and keeps the largest depth. An empty or missing entry gives the ROS 2 default
    (reliable, volatile, keep_last 10).

    Raises
    ------
    BagReadError
        The text is not YAML, not a list of mappings, or has a policy value rosbag2 does not write;
        ``where`` (file and topic) is in the message.
    """
    import yaml
    if text is None or not str(text).strip():
        return ReplayQoS()
    try:
        profiles = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise BagReadError(f'{where}: offered_qos_profiles is not valid YAML ({exc})') from None
    if profiles in (None, []):
        return ReplayQoS()
    if isinstance(profiles, dict):
        profiles = [profiles]
    if not isinstance(profiles, list) or not all(isinstance(p, dict) for p in profiles):
        raise BagReadError(f'{where}: offered_qos_profiles must be a list of QoS mappings, got {text[:80]!r}')
    values = {key: [] for key in _POLICY_VALUES}
    depths = []
    for profile in profiles:
        for key, allowed in _POLICY_VALUES.items():
            raw = str(profile.get(key, 'system_default')).strip().lower()
            if raw not in allowed:
                choices = ', '.join(k for k in allowed if not k.isdigit())
                raise BagReadError(f'{where}: offered_qos_profiles has {key}: {raw!r}; allowed: {choices}')
            values[key].append(allowed[raw])
        try:
            depth = int(profile.get('depth', DEFAULT_DEPTH) or 0)
        except (TypeError, ValueError):
            raise BagReadError(f'{where}: offered_qos_profiles has depth {profile.get("depth")!r}; '
                               'expected a whole number') from None
        depths.append(depth if depth > 0 else DEFAULT_DEPTH)
    return ReplayQoS(
        reliability='reliable' if all(v == 'reliable' for v in values['reliability']) else 'best_effort',
        durability='transient_local' if all(v == 'transient_local' for v in values['durability']) else 'volatile',
        history='keep_all' if any(v == 'keep_all' for v in values['history']) else 'keep_last',
        depth=max(depths))


def find_bag_files(path) -> tuple[Path, list]:
    """``(bag directory, [MCAP files])`` of a run directory, a bag directory or one ``.mcap`` file.

    A run directory of ``scripts/run_formation.sh`` holds the bag in ``bag/``. In a bag directory
    the files are those listed in ``metadata.yaml`` (``relative_file_paths``), else every
    ``*.mcap`` in it.

    Raises
    ------
    BagReadError
        The path does not exist, holds no bag, or ``metadata.yaml`` is unreadable or names a
        missing file.
    """
    import yaml
    path = Path(path)
    if not path.exists():
        raise BagReadError(f'{path}: no such file or directory')
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
            raise BagReadError(f'{metadata}: not a rosbag2 metadata file ({type(exc).__name__}: {exc})') from None
        if storage not in ('mcap', None):
            raise BagReadError(f'{metadata}: storage is {storage!r}; only MCAP bags can be replayed '
                               '(record with "ros2 bag record -s mcap")')
        files = [path / name for name in names]
        missing = [str(f) for f in files if not f.exists()]
        if missing:
            raise BagReadError(f'{metadata}: lists {", ".join(missing)}, which does not exist')
        if files:
            return path, files
    files = sorted(path.glob('*.mcap'))
    if not files:
        contents = sorted(p.name for p in path.iterdir())
        raise BagReadError(f'{path}: no MCAP bag here (no *.mcap file, no bag/ directory); '
                           f'it holds {contents if contents else "nothing"}')
    return path, files


def _check_mcap_file(path: Path, check_chunks: bool):
    """Summary of one MCAP file after checking its magic, footer, summary and chunk CRCs."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap.records import Chunk, Message
    from mcap.stream_reader import breakup_chunk
    from mcap.data_stream import ReadDataStream

    size = path.stat().st_size
    if size == 0:
        raise BagReadError(f'{path}: empty file (0 bytes), not an MCAP bag file')
    with open(path, 'rb') as f:
        head = f.read(len(MCAP_MAGIC))
        if head != MCAP_MAGIC:
            raise BagReadError(f'{path}: not an MCAP file (it starts with {head!r}; an MCAP file starts '
                               f'with {MCAP_MAGIC!r})')
        f.seek(max(0, size - len(MCAP_MAGIC)))
        if size < 2 * len(MCAP_MAGIC) or f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise BagReadError(f'{path}: truncated: the file ({size} bytes) does not end with the MCAP '
                               'footer and magic, so it was not closed (the recorder was killed or the '
                               'copy is incomplete)')
        f.seek(0)
        try:
            reader = make_reader(f)
            summary = reader.get_summary()
        except (McapError, ValueError, EOFError, OSError, UnicodeDecodeError, IndexError) as exc:
            raise BagReadError(f'{path}: corrupted MCAP summary section ({type(exc).__name__}: {exc})') from None
        if summary is None:
            raise BagReadError(f'{path}: the MCAP file has no summary section (no channel list); '
                               'rosbag2 and the recorder always write one')
        if not check_chunks:
            return summary
        for index in summary.chunk_indexes:
            where = f'{path}: chunk at byte {index.chunk_start_offset}'
            if index.chunk_start_offset + index.chunk_length > size:
                raise BagReadError(f'{where} runs past the end of the file ({size} bytes): truncated')
            try:
                f.seek(index.chunk_start_offset + 1 + 8, io.SEEK_SET)
                chunk = Chunk.read(ReadDataStream(f))
                if chunk.compression == '' and chunk.uncompressed_crc:
                    # the writer stored a CRC: one C-speed pass over the bytes checks everything
                    if zlib.crc32(chunk.data) != chunk.uncompressed_crc:
                        raise BagReadError(f'{where} is corrupted (CRC mismatch)')
                    continue
                # no CRC (rosbag2 on Jazzy writes none) or compressed: check the record structure
                for record in breakup_chunk(chunk, validate_crc=True):
                    if isinstance(record, Message):
                        if record.channel_id not in summary.channels:
                            raise BagReadError(f'{where} is corrupted (a message of unknown channel '
                                               f'{record.channel_id})')
                        if not chunk.message_start_time <= record.log_time <= chunk.message_end_time:
                            raise BagReadError(f'{where} is corrupted (a message log time outside the '
                                               "chunk's time range)")
            except BagReadError:
                raise
            except Exception as exc:  # CRCValidationError, EndOfFile, struct.error, decompression errors
                raise BagReadError(f'{where} is corrupted ({type(exc).__name__}: {exc})') from None
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
    BagReadError
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
                raise BagReadError(f'{file}: topic {channel.topic} is encoded as {channel.message_encoding!r}; '
                                   'only ROS 2 CDR messages can be replayed')
            if schema is None or not schema.name:
                raise BagReadError(f'{file}: topic {channel.topic} has no message type (schema)')
            count = (summary.statistics.channel_message_counts.get(channel.id, 0)
                     if summary.statistics else 0)
            topic = info.topics.get(channel.topic)
            if topic is None:
                qos = parse_offered_qos(channel.metadata.get('offered_qos_profiles'),
                                        f'{file}: topic {channel.topic}')
                info.topics[channel.topic] = BagTopic(
                    channel.topic, schema.name, qos, count,
                    schema.data.decode(errors='replace') if schema.data else '')
            elif topic.type != schema.name:
                raise BagReadError(f'{file}: topic {channel.topic} has type {schema.name} here and '
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
    BagReadError
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
                    raise BagReadError(f'{file}: cannot read message {seq + 1} '
                                       f'({type(exc).__name__}: {exc})') from None
                _, channel, message = item
                yield message.log_time, rank, seq, channel.topic, message.data
                seq += 1

    streams = [one_file(rank, file) for rank, file in enumerate(info.files)]
    for log_time, _rank, _seq, topic, data in heapq.merge(*streams):
        yield topic, log_time, data


def _register_types_from_bag(info: BagInfo, names) -> None:
    """Make types the runtime does not know (not uh_msgs, not a Jazzy standard type) known from the
    bag's own ``ros2msg`` schemas (Cyclone DDS backend only; rclpy imports installed types)."""
    from rosbags.typesys import get_types_from_msg

    store = messages.typestore()
    for name in names:
        topic = info.topics[name]
        if topic.type in store.fielddefs:
            continue
        if not topic.definition.strip():
            raise BagReadError(f'{info.files[0]}: topic {name} has type {topic.type}, which this runtime '
                               'does not know, and the bag holds no definition of it')
        try:
            types = get_types_from_msg(topic.definition, topic.type)
            store.register({k: v for k, v in types.items() if k not in store.fielddefs})
        except Exception as exc:  # rosbags raises its own parse errors
            raise BagReadError(f'{info.files[0]}: the definition of {topic.type} (topic {name}) in the bag '
                               f'cannot be parsed ({type(exc).__name__}: {exc})') from None


# ----------------------------------------------------------------------------------------------
# The node
# ----------------------------------------------------------------------------------------------
class _Progress:
    """One status line on stderr, redrawn in place at most 4 times per second (terminal only)."""

    def __init__(self, stream, total_messages: int, duration_s: float, rate: float):
        self.stream, self.total, self.duration, self.rate = stream, total_messages, duration_s, rate
        self.tty = stream.isatty()
        self.last = 0.0

    def update(self, sent: int, bag_s: float, loop: int, force: bool = False) -> None:
        if not self.tty:
            return
        now = time.monotonic()
        if not force and now - self.last < 0.25:
            return
        self.last = now
        loop_text = f'  loop {loop}' if loop > 1 else ''
        self.stream.write(f'\r\033[K[replay] {bag_s:8.2f} / {self.duration:.2f} s bag time  '
                          f'{sent}/{self.total} messages  x{self.rate:g}{loop_text}')
        self.stream.flush()

    def close(self) -> None:
        if self.tty:
            self.stream.write('\n')
            self.stream.flush()


class ReplayNode(rt.Node):
    """The ``replay`` node: one publisher per replayed topic (and ``/clock``), then :meth:`play`.

    Parameters
    ----------
    info : BagInfo
        From :func:`open_bag`.
    topics : iterable of str, optional
        Topics to replay (``/clock`` is added when ``clock`` is true and the bag has it).
    clock : bool
        Publish ``/clock`` (the bag's, or synthesised from the log times if it has none).
    **node_kwargs
        Passed to ``Node`` (e.g. ``context``).

    Raises
    ------
    BagReadError
        A requested topic is not in the bag, or a type cannot be built.
    """

    def __init__(self, info: BagInfo, topics=None, clock: bool = True, **node_kwargs):
        wanted = list(info.topics) if not topics else list(dict.fromkeys(topics))
        unknown = [t for t in wanted if t not in info.topics]
        if unknown:
            raise BagReadError(f'{info.directory}: topic(s) {", ".join(unknown)} not in the bag; it has '
                               f'{", ".join(sorted(info.topics))}')
        if clock and '/clock' in info.topics and '/clock' not in wanted:
            wanted.append('/clock')
        if rt.BACKEND != 'rclpy':
            _register_types_from_bag(info, wanted)
        super().__init__('replay', **node_kwargs)
        self.bag_info = info
        self.replay_topics = wanted
        self.publishers_by_topic = {}
        for name in wanted:
            topic = info.topics[name]
            try:
                msg_type = messages.get_message(topic.type)
            except messages.MessageError as exc:
                raise BagReadError(f'{info.files[0]}: topic {name}: {exc}') from None
            self.publishers_by_topic[name] = self.create_publisher(msg_type, name, topic.qos.profile())
        self.synth_clock = None
        if clock and '/clock' not in info.topics:
            self.synth_clock = self.create_publisher(messages.get_message('rosgraph_msgs/msg/Clock'), '/clock',
                                                     ReplayQoS().profile())
        self.sent = 0

    # -- waiting ------------------------------------------------------------------------
    def all_publishers(self) -> dict:
        pubs = dict(self.publishers_by_topic)
        if self.synth_clock is not None:
            pubs['/clock'] = self.synth_clock
        return pubs

    def wait_for_subscribers(self, timeout: float) -> list:
        """Wait until every publisher has a matched subscription; return the topics without one."""
        deadline = time.monotonic() + timeout
        while True:
            lonely = [t for t, p in self.all_publishers().items() if p.get_subscription_count() < 1]
            if not lonely or time.monotonic() >= deadline or not rt.ok():
                return lonely
            time.sleep(0.02)

    def _sleep_until(self, due: float, on_tick) -> bool:
        """Sleep until ``due`` (monotonic s) in short slices; False if the context shut down."""
        while True:
            if not rt.ok():
                return False
            remaining = due - time.monotonic()
            if remaining <= 0:
                return True
            on_tick()
            time.sleep(min(remaining, 0.05))

    def _publish_clock(self, ns: int) -> None:
        msg = self.synth_clock.msg_type()
        msg.clock.sec, msg.clock.nanosec = ns // 1_000_000_000, ns % 1_000_000_000
        self.synth_clock.publish(msg)

    # -- playing ------------------------------------------------------------------------
    def play(self, rate: float = 1.0, loop: bool = False, progress: _Progress | None = None) -> bool:
        """Publish the bag with its timing scaled by ``rate``; True when it ran to the end.

        Returns False when the context was shut down (SIGTERM) before the end; Ctrl-C raises
        ``KeyboardInterrupt`` out of it.
        """
        selected = list(self.replay_topics)
        loops = 0
        while True:
            loops += 1
            start_wall = None
            first_ns = None
            last_clock = None
            for topic, log_ns, data in iter_bag_messages(self.bag_info, selected):
                if start_wall is None:
                    start_wall, first_ns = time.monotonic(), log_ns
                due = start_wall + (log_ns - first_ns) * 1e-9 / rate
                tick = (lambda: progress.update(self.sent, (log_ns - self.bag_info.start_ns) * 1e-9, loops)) \
                    if progress else (lambda: None)
                if not self._sleep_until(due, tick):
                    return False
                if self.synth_clock is not None and log_ns != last_clock:
                    self._publish_clock(log_ns)
                    last_clock = log_ns
                self.publishers_by_topic[topic].publish(data)
                self.sent += 1
                if progress:
                    tick()
            if progress:
                progress.update(self.sent, self.bag_info.duration_s, loops, force=True)
            if not loop or start_wall is None:
                return True

    def flush(self, timeout: float = 2.0) -> None:
        """Wait until reliable subscribers acknowledged what was sent, ``timeout`` s at most in all."""
        deadline = time.monotonic() + timeout
        for pub in self.all_publishers().values():
            left = max(0.0, deadline - time.monotonic())
            try:
                if rt.BACKEND == 'rclpy':
                    pub.wait_for_all_acked(rt.Duration(seconds=left))
                else:
                    pub.wait_for_all_acked(left)
            except Exception:  # a best-effort topic or a backend without acks: nothing to wait for
                pass


# ----------------------------------------------------------------------------------------------
# Entry point
# ----------------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description='Republish a recorded rosbag2 MCAP bag over DDS with its original timing scaled by '
                    '--rate, its recorded QoS and its payload bytes as recorded, and /clock.',
        epilog='Example: scripts/replay.sh runs/proposed --rate 2 --topics /markers /uh1/state')
    p.add_argument('bag', metavar='RUN_DIR|BAG_DIR',
                   help='a run directory of run_formation.sh (its bag/), a rosbag2 MCAP bag directory, or an .mcap file')
    p.add_argument('--rate', type=float, default=1.0,
                   help='bag seconds per wall second (default 1; 0.01 .. 1000)')
    p.add_argument('--loop', action='store_true', help='start again at the end (until Ctrl-C)')
    p.add_argument('--topics', nargs='+', metavar='T', default=None,
                   help='replay only these topics (and /clock); default: every topic of the bag')
    p.add_argument('--no-clock', action='store_true', help='do not publish /clock')
    p.add_argument('--domain-id', type=int, default=None,
                   help=f'DDS domain id 0..{MAX_DOMAIN_ID} (default: ROS_DOMAIN_ID, else 0)')
    p.add_argument('--delay', type=float, default=0.5,
                   help='s to wait after creating the publishers before the first message, so that '
                        'running subscribers discover them (default 0.5)')
    p.add_argument('--wait-for-subscribers', action='store_true',
                   help=f'start only once every replayed topic has a subscriber (at most '
                        f'{WAIT_FOR_SUBSCRIBERS_TIMEOUT:g} s, then exit 1)')
    p.add_argument('--no-check', action='store_true',
                   help='skip the CRC check of every chunk before playing (faster start on huge bags)')
    return p


def _fail(message: str, status: int = 2) -> int:
    print(f'{PROG}: error: {message}', file=sys.stderr)
    return status


def main(args=None) -> int:
    """Entry point of ``replay_node`` / ``scripts/replay.sh``; returns the exit status."""

    argv = list(sys.argv if args is None else args)

    opts = build_parser().parse_args(rt.remove_ros_args(argv)[1:])
    if not (math.isfinite(opts.rate) and 0.01 <= opts.rate <= 1000):
        return _fail(f'--rate {opts.rate:g}: allowed 0.01 .. 1000 (bag seconds per wall second)')
    if not (math.isfinite(opts.delay) and opts.delay >= 0):
        return _fail(f'--delay {opts.delay:g}: must be >= 0 s')
    domain = opts.domain_id
    if domain is None:
        env_domain = os.environ.get('ROS_DOMAIN_ID', '').strip()
        domain = int(env_domain) if env_domain.isdigit() else 0
    if not 0 <= domain <= MAX_DOMAIN_ID:
        return _fail(f'--domain-id {domain}: allowed 0..{MAX_DOMAIN_ID}')
    try:
        info = open_bag(opts.bag, check_chunks=not opts.no_check)
    except BagReadError as exc:
        return _fail(str(exc))
    if info.message_count == 0:
        return _fail(f'{info.files[0]}: the bag holds no messages')
    # same network set-up as run_formation.sh: loopback unless the user chose a CYCLONEDDS_URI
    os.environ.update(loopback_environment(domain))
    # Ctrl-C stops the replay also when a shell started it in the background (which ignores SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)

    try:
        rt.init(args=argv)
    except Exception as exc:  # bad --ros-args
        return _fail(str(exc))
    node = None
    status = 0
    progress = None
    try:
        node = ReplayNode(info, opts.topics, clock=not opts.no_clock)
        selected = node.replay_topics
        count = sum(info.topics[t].message_count for t in selected)
        clock_note = ('/clock from the bag' if '/clock' in selected else
                      'no /clock' if opts.no_clock else '/clock synthesised from log times')
        print(f'[replay] {info.directory}: {count} messages on {len(selected)} topics, '
              f'{info.duration_s:.2f} s of bag time at x{opts.rate:g} ({clock_note}), DDS domain {domain}',
              file=sys.stderr, flush=True)
        if opts.wait_for_subscribers:
            lonely = node.wait_for_subscribers(WAIT_FOR_SUBSCRIBERS_TIMEOUT)
            if lonely and rt.ok():
                status = _fail(f'no subscriber within {WAIT_FOR_SUBSCRIBERS_TIMEOUT:g} s on {", ".join(lonely)}', 1)
                return status
        deadline = time.monotonic() + opts.delay
        while rt.ok() and time.monotonic() < deadline:
            time.sleep(min(0.05, max(0.0, deadline - time.monotonic())))
        progress = _Progress(sys.stderr, count, info.duration_s, opts.rate)
        started = time.monotonic()
        finished = rt.ok() and node.play(opts.rate, opts.loop, progress)
        progress.close()
        progress = None
        if finished:
            node.flush()
            print(f'[replay] done: {node.sent} messages in {time.monotonic() - started:.2f} s wall',
                  file=sys.stderr, flush=True)
        else:
            print(f'[replay] stopped after {node.sent} messages', file=sys.stderr, flush=True)
            status = 130
    except BagReadError as exc:
        if progress:
            progress.close()
        status = _fail(str(exc))
    except (KeyboardInterrupt, rt.ExternalShutdownException):
        if progress:
            progress.close()
        print(f'[replay] interrupted after {node.sent if node else 0} messages', file=sys.stderr, flush=True)
        status = 130
    finally:
        if node is not None:
            node.destroy_node()
        rt.try_shutdown()
    return status


if __name__ == '__main__':
    sys.exit(main())
