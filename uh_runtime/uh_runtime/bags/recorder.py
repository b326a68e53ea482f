"""Recorder node (``recorder``): records topics to a rosbag2 MCAP bag (:mod:`uh_runtime.bags.bag`).

Like ``ros2 bag record -a -s mcap``: it discovers every topic in the DDS domain (or the ones given
in ``topics``; ``/parameter_events`` and ``/rosout`` included, so a bag shows when a gain changed
and what the nodes logged), subscribes with QoS compatible with what the publishers offer (transient-local
when they all offer it, so nothing published before the subscription matched is missed) and
stores the CDR payloads exactly as they arrive (raw subscriptions, no decode/re-encode).

Topics that may only ever see a short-lived publisher (a fault injected with ``ros2 topic pub
--once``, which publishes one volatile message and leaves) are named in ``expected_topics``
(``name=pkg/msg/Type``): the recorder subscribes to them at start, reliable and volatile, so the
message finds a matched reader whenever it comes, instead of a recorder that discovers the topic
only after the publisher has gone.

Log times are simulation times: the message's own stamp when its first field is a
``std_msgs/Header`` or a ``builtin_interfaces/Time`` (every uh_msgs type, ``/clock``), otherwise
the latest ``/clock``. With ``sim_time`` (a run on simulated time: the run supervisor and the launch
file set it), a stamp more than :data:`STAMP_WINDOW_NS` away from the latest ``/clock`` (0 before
the first) is not the run's time (a message stamped with wall-clock time: a fault sent from rclpy,
``/rosout`` of an rclpy node): the message is logged at the latest ``/clock`` instead, its bytes
unchanged, so it never stretches the bag's time range; the recorder logs how many were.

With ``progress_topics`` set, it publishes on ``/recorder/progress`` the sim
time up to which every one of those topics has been written (every :data:`PROGRESS_EVERY` steps,
and within :data:`PROGRESS_FLUSH_S` s of an advance); the lockstep clock waits on it, so a
lockstep run loses nothing however slow the disk.

SIGINT/SIGTERM finalise the bag (summary and ``metadata.yaml``). Every ``FLUSH_PERIOD_S`` the
chunk being filled is closed and written, so a SIGKILL leaves an MCAP file readable up to its last
complete chunk, losing less than :data:`uh_runtime.bags.bag.CHUNK_SIZE` bytes and at most
:data:`uh_runtime.bags.bag.FLUSH_PERIOD_S` of recording; :func:`uh_runtime.bags.bag.recover_bag` completes it.
"""
from __future__ import annotations

import dataclasses
import struct

import uh_runtime as rt
from uh_runtime import messages as m
from uh_runtime.bags.bag import FLUSH_PERIOD_S, BagWriter
from uh_runtime.bags.bag_reader import BagError
from uh_runtime.dds.arguments import InvalidNameError, validate_full_topic_name
from uh_runtime.dds.qos import QoSWords, merge_offered, profile_from_words, qos_profile_yaml, words_of
from uh_runtime.names import RECORDER_PROGRESS_TOPIC

__all__ = ['RecorderNode', 'LogClock', 'RecordedProgress', 'STAMP_WINDOW_NS', 'PROGRESS_EVERY', 'PROGRESS_FLUSH_S',
           'main', 'stamp_of', 'stamped_first', 'new_topics']

_STAMPED_FIRST = {'rosgraph_msgs/msg/Clock', 'builtin_interfaces/msg/Time'}
_TIME = struct.Struct('<iI')
#: Keep-last depth of the recorder's subscriptions.
_RECORD_DEPTH = 10000
#: ``/recorder/progress`` is published every this many advances of the recorded step, and the rest
#: within :data:`PROGRESS_FLUSH_S` wall seconds: the lockstep clock only needs the recorder within
#: ``RECORDER_LAG_STEPS`` (40) steps, and the last step confirmed at the end, and one message per
#: step was 13 % of the recorder's CPU and one of the clock's six receptions per step.
PROGRESS_EVERY = 10
PROGRESS_FLUSH_S = 0.02


def stamped_first(type_name: str) -> bool:
    """Return True when the CDR payload of ``type_name`` starts with a Time (own stamp, or a Header's)."""
    if type_name in _STAMPED_FIRST:
        return True
    store = m.typestore()
    fields = store.fielddefs.get(type_name, ((), ()))[1]
    return bool(fields) and fields[0][1][0].name == 'NAME' and fields[0][1][1] == 'std_msgs/msg/Header'


def stamp_of(data: bytes) -> int:
    """Nanoseconds of the Time at the start of a little-endian CDR payload (after the 4-byte header)."""
    sec, nanosec = _TIME.unpack_from(data, 4)
    return sec * 1_000_000_000 + nanosec


#: With ``sim_time``, the farthest a stamp may lie from the latest ``/clock`` and still be a log time
#: (ns of simulated time). Messages of a step reach the recorder within a few steps of the ``/clock``
#: of that step (the lockstep clock waits on the recorder; in real time they are 10 ms apart), and a
#: wall-clock stamp is decades away.
STAMP_WINDOW_NS = 10_000_000_000


class LogClock:
    """Log time of a raw message.

    Its own stamp (or its Header's) when its type starts with one (:func:`stamped_first`), else the
    simulation time of the latest ``/clock``, 0 before any. With ``sim_time``, a stamp more than
    :data:`STAMP_WINDOW_NS` from the latest ``/clock`` is replaced by it (counted in ``replaced``).
    """

    def __init__(self, sim_time: bool = False):
        self.clock_ns = 0
        self.sim_time = sim_time
        self.replaced = 0

    def of(self, topic: str, data: bytes, stamped: bool) -> int:
        """Return the log time (ns) of the payload ``data`` of ``topic``."""
        if not stamped:
            return self.clock_ns
        log_ns = stamp_of(data)
        if topic == '/clock':
            self.clock_ns = log_ns
        elif self.sim_time and abs(log_ns - self.clock_ns) > STAMP_WINDOW_NS:
            self.replaced += 1
            return self.clock_ns
        return log_ns


class RecordedProgress:
    """The sim time up to which every per-step topic has been written, and when to publish it.

    Parameters
    ----------
    topics : iterable of str
        The per-step topics (``progress_topics``); the progress is the oldest of their newest log
        times, ns, once each has been written at least once.
    every : int
        :meth:`written` asks for a publication at every ``every``-th advance; the node publishes
        the others from a timer (:meth:`take`).
    """

    def __init__(self, topics, every: int = PROGRESS_EVERY):
        self.topics = frozenset(topics)
        self.every = every
        self.latest: dict[str, int] = {}
        self.progress_ns = -1        # -1: not every topic written yet
        self.published_ns = -1
        self.advances = 0
        self.at_minimum = 0          # topics whose newest log time is progress_ns

    def written(self, topic: str, log_ns: int) -> bool:
        """Note that a message of ``topic`` logged at ``log_ns`` was written; True: publish now.

        A topic's newest log time never goes back (a replayed older message does not un-write the
        later ones). The minimum is recomputed only when the last topic that held it advanced, so a
        step of n topics costs O(n), not O(n^2) (160 topics in a team of 40 UHs).
        """
        if topic not in self.topics:
            return False
        old = self.latest.get(topic, -1)
        if log_ns <= old:
            return False
        self.latest[topic] = log_ns
        if len(self.latest) < len(self.topics):
            return False
        if self.progress_ns >= 0 and old != self.progress_ns:
            return False          # the minimum is held by other topics
        self.at_minimum -= 1
        if self.at_minimum > 0:
            return False
        progress = min(self.latest.values())
        self.at_minimum = sum(1 for value in self.latest.values() if value == progress)
        self.progress_ns = progress
        self.advances += 1
        return self.advances % self.every == 0

    def take(self) -> int | None:
        """Return the progress, ns, when it advanced since the last call that returned it, else None."""
        if self.progress_ns <= self.published_ns:
            return None
        self.published_ns = self.progress_ns
        return self.progress_ns


def new_topics(node, followed, wanted=(), skip=()):
    """Return the topics in ``node``'s graph that have a publisher and are not ``followed`` yet.

    The result is ``[(name, type, [offered QoSWords of each publisher]), ...]``; only ``wanted`` topics if
    given; never hidden topics, ``ros_discovery_info`` or ``skip``.
    """
    found = []
    for name, types in node.get_topic_names_and_types():
        if name in followed or name in skip or (wanted and name not in wanted):
            continue
        if name.startswith('/_') or name == '/ros_discovery_info':
            continue
        infos = node.get_publishers_info_by_topic(name)
        if infos:
            found.append((name, types[0], [words_of(info.qos_profile) for info in infos]))
    return found


class RecorderNode(rt.Node):
    """The ``recorder`` node (see the module docstring): every wanted topic to the bag ``output``.

    Parameters (ROS, read-only): ``output`` (bag directory to create), ``topics`` (empty: all),
    ``expected_topics``, ``progress_topics``, ``sim_time``. Keyword arguments go to ``Node``
    (e.g. ``parameter_overrides``). Raises ValueError for a bad parameter (one line, exit 2 from
    :func:`main`).
    """

    def __init__(self, **kwargs):
        super().__init__('recorder', **kwargs)
        self.declare_parameter('output', '', rt.ParameterDescriptor(
            description='bag directory to create (must not exist, or be empty)', read_only=True))
        self.declare_parameter('topics', [''], rt.ParameterDescriptor(
            description='topics to record; empty records every topic discovered', read_only=True))
        self.declare_parameter('expected_topics', [''], rt.ParameterDescriptor(
            description='name=pkg/msg/Type of topics to subscribe to at start (reliable, volatile), '
                        'before any publisher appears', read_only=True))
        self.declare_parameter('progress_topics', [''], rt.ParameterDescriptor(
            description='per-step topics whose recorded sim time is published on /recorder/progress',
            read_only=True))
        self.declare_parameter('sim_time', False, rt.ParameterDescriptor(
            description='the run is on simulated time (/clock): a stamp more than 10 s from the latest /clock '
                        '(e.g. wall-clock time) is logged at that /clock instead', read_only=True))
        output = str(self.get_parameter('output').value)
        if not output:
            raise ValueError("parameter 'output' is empty: give the bag directory to create")
        self.wanted = {t for t in self.get_parameter('topics').value if t}
        for topic in sorted(self.wanted):
            try:
                validate_full_topic_name(topic)
            except InvalidNameError as exc:
                raise ValueError(f"parameter 'topics': {exc}") from None
        self.progress_topics = {t for t in self.get_parameter('progress_topics').value if t}
        expected = []
        for entry in (e for e in self.get_parameter('expected_topics').value if e):
            name, sep, type_name = entry.partition('=')
            if not (sep and name.startswith('/') and type_name.count('/') == 2):
                raise ValueError(f"parameter 'expected_topics': {entry!r} is not name=pkg/msg/Type "
                               f"(e.g. /uh1/fault=uh_msgs/msg/ActuatorFault)")
            m.get_message(type_name)   # an unknown type is refused before the bag exists
            expected.append((name, type_name))
        try:
            self.bag = BagWriter(output)
        except BagError as exc:    # a bad 'output' (a ValueError: one line, exit 2, from run_node)
            raise ValueError(f"parameter 'output': {exc}") from None
        self.log_clock = LogClock(sim_time=bool(self.get_parameter('sim_time').value))
        self.progress = RecordedProgress(self.progress_topics)
        self.subscriptions_by_topic = {}
        self.progress_pub = self.create_publisher(m.Time, RECORDER_PROGRESS_TOPIC, 10)
        for name, type_name in expected:
            words = QoSWords('reliable', 'volatile', 'keep_last', _RECORD_DEPTH)
            self._subscribe(name, type_name, words, qos_profile_yaml('reliable', 'volatile', 'keep_last', 10))
        self.create_timer(0.05, self.discover)
        self.create_timer(FLUSH_PERIOD_S, self.bag.flush)
        if self.progress_topics:
            self.create_timer(PROGRESS_FLUSH_S, self.publish_progress)
        self.discover()

    def discover(self) -> None:
        """Subscribe to every wanted topic that has appeared since the last look."""
        for name, type_name, offered in new_topics(self, self.subscriptions_by_topic, self.wanted,
                                                    skip=(RECORDER_PROGRESS_TOPIC,)):
            first = offered[0]
            # reliable and transient-local only when every publisher offers it
            self._subscribe(name, type_name, dataclasses.replace(
                merge_offered(offered), history='keep_last', depth=_RECORD_DEPTH),
                qos_profile_yaml(first.reliability, first.durability, first.history, first.depth))

    def _subscribe(self, name: str, type_name: str, words, offered_yaml: str) -> None:
        """Add ``name`` to the bag and subscribe to it raw with the QoS ``words``."""
        message_class = m.get_message(type_name)
        self.bag.add_topic(name, type_name, offered_yaml)
        stamped = stamped_first(type_name)
        self.subscriptions_by_topic[name] = self.create_subscription(
            message_class, name,
            lambda data, name=name, stamped=stamped: self.on_message(name, data, stamped),
            profile_from_words(words), raw=True)
        self.get_logger().info(f'recording {name} [{type_name}]')

    def on_message(self, topic: str, data: bytes, stamped: bool) -> None:
        """Write the CDR bytes ``data`` of ``topic`` to the bag at its log time; publish the progress when due."""
        log_ns = self.log_clock.of(topic, data, stamped)
        self.bag.write(topic, data, log_ns)
        if self.progress.written(topic, log_ns):
            self.publish_progress()

    def publish_progress(self) -> None:
        """Publish the progress not yet published (every :data:`PROGRESS_EVERY` advances, and by a timer)."""
        progress = self.progress.take()
        if progress is not None:
            msg = m.Time()
            msg.sec, msg.nanosec = progress // 1_000_000_000, progress % 1_000_000_000
            self.progress_pub.publish(msg)

    def destroy_node(self):
        """Close the bag (summary and ``metadata.yaml``), log its per-topic counts, destroy the node."""
        if getattr(self, 'bag', None) is None:   # refused before its bag was created: nothing to close
            return super().destroy_node()
        self.bag.close()
        counts = ', '.join(f'{t.name}: {t.message_count}' for t in self.bag.topics.values())
        rt.log_on_exit(self, f'bag closed: {self.bag.directory} ({counts})')
        if self.log_clock.replaced:
            rt.log_on_exit(self, f'{self.log_clock.replaced} message(s) stamped more than '
                                 f'{STAMP_WINDOW_NS / 1e9:g} s from the simulated time were logged at the '
                                 'latest /clock instead of their stamp')
        return super().destroy_node()


def main(args=None):
    """Console script ``recorder_node``: run :class:`RecorderNode` (:func:`uh_runtime.run_node`)."""
    rt.run_node(RecorderNode, args)


if __name__ == '__main__':
    main()
