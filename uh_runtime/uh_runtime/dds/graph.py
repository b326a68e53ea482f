"""The ROS graph seen through DDS discovery, as rmw_dds_common's graph cache builds it.

Sources: the DDS builtin topics (``DCPSParticipant``, ``DCPSPublication``,
``DCPSSubscription``: every endpoint's GUID, topic, type, QoS and USER_DATA) and
``ros_discovery_info`` (which node owns which reader/writer GID). ROS topics are the DDS topics
starting with ``rt/``; an endpoint whose GID no ``ros_discovery_info`` lists belongs to node
``_CREATED_BY_BARE_DDS_APP_``, as in ROS 2. Used by the ``uh`` CLI, the DDS backend's graph
queries (``count_subscribers`` ...) and the tests.

A Fast DDS participant (rclpy on ROS 2's default RMW) sends its ``ros_discovery_info`` to a new reader
only after a heartbeat the reader answers: one when it matches the reader, which a reader that does not
know the writer yet ignores, then every 3 s (Fast DDS's heartbeat period). A new participant learns the
writer about a second after it starts, so its first reader got the sample 3.0 s after the start, every
time (docs/ros2.md#node-tables-from-fast-dds). :meth:`Graph.settle` therefore renews the reader when a
writer's sample has not come :data:`INFO_GRACE` s after the writer was discovered (and again every
:data:`INFO_RETRY` s while it has not); the renewed reader, matched by a writer it knows, has the sample
within tens of milliseconds.
"""
import time
import uuid
from dataclasses import dataclass

from .. import messages as _messages
from ..names import ROS_PREFIXES, ROS_TOPIC_PREFIX
from .qos import (
    DDS_INFINITY,
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    from_dds_qos,
    to_dds_qos,
)
from .security import create_participant
from .signals import sigint_deferred, wake_on_signals

__all__ = ['Graph', 'EndpointInfo', 'BARE_DDS_NODE', 'INFO_GRACE', 'INFO_RETRY', 'format_gid', 'user_data_value',
           'full_node_name']

BARE_DDS_NODE = '_CREATED_BY_BARE_DDS_APP_'
#: DDS topic of the node tables (rmw_dds_common's ``ParticipantEntitiesInfo``).
_INFO_TOPIC = 'ros_discovery_info'
#: How long after a ``ros_discovery_info`` writer is discovered its sample may take before
#: :meth:`Graph.settle` renews the reader, s. A Cyclone DDS writer's sample comes with the writer.
INFO_GRACE = 0.2
#: How long after a renewal a sample still missing renews the reader again, s (a lost datagram).
INFO_RETRY = 1.0
#: What the DDS topics of the ROS graph start with: ``rt/``, ``rq/``, ``rr/``.
_ROS_PREFIXES_SLASH = tuple(prefix + '/' for prefix in ROS_PREFIXES)
_TOPIC_PREFIX_SLASH = ROS_TOPIC_PREFIX + '/'


def format_gid(gid: bytes) -> str:
    """GID as ``ros2 topic info -v`` prints it: dot-separated hex bytes."""
    return '.'.join(f'{b:02x}' for b in gid)


def full_node_name(name: str, namespace: str) -> str:
    """Return the fully qualified name of a node, as ``ros2 node list`` prints it (``/uh1/sim``)."""
    return f"{namespace.rstrip('/')}/{name}"


def user_data_value(qos, key: str) -> str | None:
    """Value of ``key`` in a ``key=value;`` USER_DATA QoS (e.g. ``typehash``), or None."""
    from cyclonedds.qos import Policy
    data = b''
    for policy in qos or ():
        if isinstance(policy, Policy.Userdata):
            data = policy.data
    for part in data.decode('utf-8', 'replace').split(';'):
        if part.startswith(key + '='):
            return part[len(key) + 1:]
    return None


@dataclass
class EndpointInfo:
    """One reader or writer of a ROS topic (like ``rclpy.topic_endpoint_info.TopicEndpointInfo``)."""

    node_name: str
    node_namespace: str
    topic_name: str
    topic_type: str
    topic_type_hash: str
    endpoint_type: str  # 'PUBLISHER' or 'SUBSCRIPTION'
    gid: bytes
    qos_profile: QoSProfile
    dds_qos: object
    participant_gid: bytes

    @property
    def endpoint_gid(self) -> bytes:
        """Return :attr:`gid` (``endpoint_gid`` is rclpy's name of it)."""
        return self.gid


class Graph:
    """Discovery state of one DDS domain, refreshed by :meth:`update` / :meth:`wait`.

    Parameters
    ----------
    participant : cyclonedds.domain.DomainParticipant, optional
        Participant to read discovery through (its own endpoints are included). Without it a
        participant is created on ``domain_id`` and its own entities are left out.
    domain_id : int, optional
        Domain of the created participant (default: ``ROS_DOMAIN_ID`` or 0).
    info_topic : cyclonedds.topic.Topic, optional
        The ``ros_discovery_info`` topic to read, when the participant already has it (a node's
        context does); default: created here.
    """

    def __init__(self, participant=None, domain_id=None, info_topic=None):
        import os

        from cyclonedds.builtin import (
            BuiltinDataReader,
            BuiltinTopicDcpsParticipant,
            BuiltinTopicDcpsPublication,
            BuiltinTopicDcpsSubscription,
        )
        from cyclonedds.core import (
            GuardCondition,
            InstanceState,
            ReadCondition,
            SampleState,
            ViewState,
            WaitSet,
        )
        from cyclonedds.sub import DataReader
        from cyclonedds.topic import Topic
        self._own = participant is None
        if participant is None:
            if domain_id is None:
                domain_id = int(os.environ.get('ROS_DOMAIN_ID', '0') or 0)
            # secure with ROS_SECURITY_ENABLE=true (its identity: ROS_SECURITY_ENCLAVE_OVERRIDE), as a node's
            participant = create_participant(int(domain_id))
        self.participant = participant
        self.own_key = participant.get_guid()
        self._participants_reader = BuiltinDataReader(participant, BuiltinTopicDcpsParticipant)
        self._pub_reader = BuiltinDataReader(participant, BuiltinTopicDcpsPublication)
        self._sub_reader = BuiltinDataReader(participant, BuiltinTopicDcpsSubscription)
        info_cls = _messages.dds_message('rmw_dds_common/msg/ParticipantEntitiesInfo')
        # like rmw_cyclonedds' own reader of this topic: keep-all, since the topic is keyless
        profile = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        user_data = f'typehash={_messages.type_hash(info_cls)};'.encode()
        self._info_topic = info_topic or Topic(participant, _INFO_TOPIC, info_cls)
        self._info_qos = to_dds_qos(profile, user_data)
        self._new_info_reader = lambda: DataReader(participant, self._info_topic, qos=self._info_qos)
        self._info_reader = self._new_info_reader()
        self._read_mask = SampleState.NotRead | ViewState.Any | InstanceState.Any
        self._read_condition = lambda reader: ReadCondition(reader, self._read_mask)
        self._waitset = WaitSet(participant)
        self._conditions = []
        for reader in (self._participants_reader, self._pub_reader, self._sub_reader,
                       self._info_reader):
            cond = self._read_condition(reader)
            self._conditions.append(cond)
            self._waitset.attach(cond)
        self._guard = GuardCondition(participant)
        self._waitset.attach(self._guard)
        self.participants = {}   # participant key (uuid) -> qos
        self.writers = {}        # endpoint key (uuid) -> DcpsEndpoint
        self.readers = {}
        self.infos = {}          # participant gid (bytes) -> ParticipantEntitiesInfo
        self.version = 0
        self._topics_cache = None
        self._info_writers = {}  # ros_discovery_info writer key (uuid) -> when discovered (time.monotonic())
        self._info_reader_since = time.monotonic()
        self.info_reader_renewals = 0
        wake_on_signals(self)

    def close(self):
        """Delete the participant if this graph created it."""
        if self._own and self.participant is not None:
            self.participant.__del__()
            self.participant = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- refresh ---------------------------------------------------------------------------
    @staticmethod
    def _alive(sample) -> bool:
        from cyclonedds.core import InstanceState
        return sample.sample_info.valid_data and sample.sample_info.instance_state == InstanceState.Alive

    @staticmethod
    def _take_builtin(reader) -> list:
        # cyclonedds builds builtin samples through a Python callback: Ctrl-C must not land in it
        with sigint_deferred():
            return reader.take(N=1000)

    def update(self) -> bool:
        """Take everything discovery has delivered; True if anything changed.

        Only readers whose read condition is triggered are taken from (a take allocates room for
        1000 samples, and nodes such as the recorder ask many times a second).
        """
        changed = False
        cond_part, cond_pub, cond_sub, cond_info = self._conditions
        if cond_part.is_triggered():
            for sample in self._take_builtin(self._participants_reader):
                changed = True
                if self._alive(sample):
                    self.participants[sample.key] = sample.qos
                else:
                    self.participants.pop(sample.key, None)
                    self.infos.pop(sample.key.bytes, None)
        for cond, reader, table in ((cond_pub, self._pub_reader, self.writers),
                                    (cond_sub, self._sub_reader, self.readers)):
            if not cond.is_triggered():
                continue
            for sample in self._take_builtin(reader):
                changed = True
                if self._alive(sample):
                    table[sample.key] = sample
                    if table is self.writers and sample.topic_name == _INFO_TOPIC:
                        self._info_writers.setdefault(sample.key, time.monotonic())
                else:
                    table.pop(sample.key, None)
                    self._info_writers.pop(sample.key, None)
        if cond_info.is_triggered():
            for msg in self._info_reader.take(N=1000):
                if getattr(msg.sample_info, 'valid_data', True) and hasattr(msg, 'gid'):
                    changed = True
                    self.infos[bytes(msg.gid.data)] = msg
        if changed:
            self.version += 1
        return changed

    def wait_until(self, until, timeout_sec=None) -> bool:
        """Refresh until ``until(self)`` is true (True) or ``timeout_sec`` has passed (False).

        Blocks in a wait set on the discovery readers; ``timeout_sec=None`` waits for ever.
        """
        end = None if timeout_sec is None else time.monotonic() + timeout_sec
        while True:
            self.update()
            if until(self):
                return True
            now = time.monotonic()
            if end is not None and now >= end:
                return False
            self._waitset.wait(DDS_INFINITY if end is None else max(0, int((end - now) * 1e9)))
            self._guard.take()

    def complete(self) -> bool:
        """Return True once the other participants and their ROS endpoints are known.

        That is, once other participants are known and, for each participant with ROS endpoints
        (``rt/``, ``rq/``, ``rr/`` topics), its ``ros_discovery_info`` and every reader and writer
        listed there. (A participant without ROS endpoints, e.g. another ``uh`` command, never
        publishes ``ros_discovery_info``.)
        """
        others = [key for key in self.participants if key != self.own_key]
        if not others:
            return False
        writers = {key.bytes for key in self.writers}
        readers = {key.bytes for key in self.readers}
        ros = {sample.participant_key for table in (self.writers, self.readers)
               for sample in table.values() if sample.topic_name[:3] in _ROS_PREFIXES_SLASH}
        for key in others:
            if key not in ros:
                continue
            info = self.infos.get(key.bytes)
            if info is None:
                return False
            for node in info.node_entities_info_seq:
                if any(bytes(g.data) not in writers for g in node.writer_gid_seq) or \
                        any(bytes(g.data) not in readers for g in node.reader_gid_seq):
                    return False
        return True

    def nodes_seen(self) -> set:
        """Return the fully qualified names of the nodes whose every reader and writer is known.

        A node counts once its participant's ``ros_discovery_info`` names it and discovery has
        delivered each endpoint listed for it (its topics are then in :meth:`topic_names_and_types`).
        """
        live = self._live_participant_gids()
        writers = {key.bytes for key in self.writers}
        readers = {key.bytes for key in self.readers}
        return {full_node_name(node.node_name, node.node_namespace)
                for pgid, info in self.infos.items() if pgid in live
                for node in info.node_entities_info_seq
                if all(bytes(g.data) in writers for g in node.writer_gid_seq)
                and all(bytes(g.data) in readers for g in node.reader_gid_seq)}

    def _info_overdue(self) -> float | None:
        """Return when the reader of ``ros_discovery_info`` is to be renewed (None: not needed).

        That is for each writer whose participant's sample has not come: :data:`INFO_GRACE` s after it
        was discovered if that was after the reader's creation, else :data:`INFO_RETRY` s after the
        reader's creation (it had its chance with this reader); the earliest of these.
        """
        since = self._info_reader_since
        times = [seen + INFO_GRACE if seen >= since else since + INFO_RETRY
                 for key, seen in self._info_writers.items()
                 if self.writers[key].participant_key != self.own_key
                 and self.writers[key].participant_key.bytes not in self.infos]
        return min(times) if times else None

    def _renew_info_reader(self):
        """Replace the reader of ``ros_discovery_info``; the samples taken so far stay in :attr:`infos`."""
        old, old_cond = self._info_reader, self._conditions[3]
        self._info_reader_since = time.monotonic()
        self._info_reader = self._new_info_reader()
        self._conditions[3] = self._read_condition(self._info_reader)
        self._waitset.attach(self._conditions[3])
        self._waitset.detach(old_cond)
        old_cond.__del__()
        old.__del__()
        self.info_reader_renewals += 1

    def settle(self, spin_time: float, quiet: float = 0.2, expected=()) -> list:
        """Collect discovery for at most ``spin_time`` s (what ``ros2 ... --spin-time`` waits for).

        Return early once the graph is :meth:`complete` and nothing changed for ``quiet`` s, or, when
        ``expected`` names nodes (fully qualified), as soon as every one of them is in
        :meth:`nodes_seen`. Returns the sorted names of ``expected`` not seen (empty when all were).
        The reader of ``ros_discovery_info`` is renewed when a writer's sample is overdue (module
        docstring).
        """
        expected = set(expected)
        end = time.monotonic() + spin_time
        last_change = time.monotonic()
        while True:
            if self.update():
                last_change = time.monotonic()
            now = time.monotonic()
            renew = self._info_overdue()
            if renew is not None and now >= renew:
                self._renew_info_reader()
                renew = self._info_overdue()
            missing = expected - self.nodes_seen()
            if expected and not missing:
                return []
            done = not expected and self.complete()
            if now >= end or (done and now - last_change >= quiet):
                return sorted(missing)
            deadline = min(end, last_change + quiet) if done else end
            if renew is not None:
                deadline = min(deadline, renew)
            self._waitset.wait(max(0, int((deadline - now) * 1e9)))
            self._guard.take()

    def wake(self):
        """Make a blocked :meth:`wait_until` return (used on signals); nothing once closed."""
        if self.participant is None:   # closed: its guard condition went with the participant
            return
        self._guard.set(True)

    # -- queries ---------------------------------------------------------------------------
    def _live_participant_gids(self):
        gids = {key.bytes for key in self.participants}
        gids.discard(self.own_key.bytes) if self._own else None
        return gids

    def _node_of(self, gid: bytes, writer: bool):
        for _pgid, info in self.infos.items():
            for node in info.node_entities_info_seq:
                seq = node.writer_gid_seq if writer else node.reader_gid_seq
                if any(bytes(g.data) == gid for g in seq):
                    return node.node_name, node.node_namespace
        return BARE_DDS_NODE, '/'

    def node_names_and_namespaces(self):
        """Sorted (name, namespace) of every node of the live participants (other than ours)."""
        live = self._live_participant_gids()
        nodes = set()
        for pgid, info in self.infos.items():
            if pgid in live:
                for node in info.node_entities_info_seq:
                    nodes.add((node.node_name, node.node_namespace))
        return sorted(nodes, key=lambda n: (n[1], n[0]))

    def full_node_names(self) -> list:
        """Return the fully qualified names of :meth:`node_names_and_namespaces`, in its order."""
        return [full_node_name(name, namespace) for name, namespace in self.node_names_and_namespaces()]

    def _ros_endpoints(self, writers: bool):
        table = self.writers if writers else self.readers
        for key, sample in table.items():
            if self._own and sample.participant_key == self.own_key:
                continue
            if sample.topic_name.startswith(_TOPIC_PREFIX_SLASH):
                yield key, sample

    def topic_names_and_types(self):
        """Sorted [(ros topic name, [ros type names])] of every ROS topic with a reader or writer.

        Cached until discovery changes (:attr:`version`): a recorder asks for it many times a second.
        """
        cached = self._topics_cache
        if cached is not None and cached[0] == self.version:
            return [(name, list(types)) for name, types in cached[1]]
        topics = {}
        for writers in (True, False):
            for _, sample in self._ros_endpoints(writers):
                topics.setdefault(sample.topic_name[len(ROS_TOPIC_PREFIX):], set()).add(
                    _messages.ros_type_from_dds(sample.type_name))
        result = [(name, sorted(types)) for name, types in sorted(topics.items())]
        self._topics_cache = (self.version, result)
        return [(name, list(types)) for name, types in result]

    def count(self, topic: str, writers: bool) -> int:
        """Return the number of writers (or readers) of ROS topic ``topic``."""
        dds_name = ROS_TOPIC_PREFIX + topic
        return sum(1 for _, sample in self._ros_endpoints(writers) if sample.topic_name == dds_name)

    def endpoints(self, topic: str, writers: bool):
        """Readers or writers of ROS topic ``topic`` as :class:`EndpointInfo`."""
        result = []
        for key, sample in self._ros_endpoints(writers):
            if sample.topic_name != ROS_TOPIC_PREFIX + topic:
                continue
            name, namespace = self._node_of(key.bytes, writers)
            result.append(EndpointInfo(
                node_name=name, node_namespace=namespace, topic_name=topic,
                topic_type=_messages.ros_type_from_dds(sample.type_name),
                topic_type_hash=user_data_value(sample.qos, 'typehash') or '',
                endpoint_type='PUBLISHER' if writers else 'SUBSCRIPTION', gid=key.bytes,
                qos_profile=from_dds_qos(sample.qos), dds_qos=sample.qos,
                participant_gid=sample.participant_key.bytes))
        return sorted(result, key=lambda e: (e.node_namespace, e.node_name, e.gid))


def guid_bytes(value) -> bytes:
    """16 GUID bytes of a ``uuid.UUID`` or bytes-like."""
    return value.bytes if isinstance(value, uuid.UUID) else bytes(value)
