"""The context of the Cyclone DDS backend: init/shutdown state, arguments, the process's DDS participant.

Mirrors ``rclpy.context`` (``Context``) and the module functions of ``rclpy`` and
``rclpy.utilities`` that act on a context (``init``, ``ok``, ``shutdown``, ``try_shutdown``,
``get_default_context``). One DDS participant per context (process), USER_DATA ``enclave=/;``, as
rmw_cyclonedds_cpp creates it; the context publishes ``ros_discovery_info``
(``rmw_dds_common/msg/ParticipantEntitiesInfo``; reliable, transient-local, keep-last 1): each
node's name and namespace with the GIDs of its readers and writers, a GID being the 16-byte DDS
GUID of the entity (``dds_get_guid``), which is what rmw_cyclonedds_cpp's ``convert_guid_to_gid``
copies.
"""
import os
import sys
import threading
import weakref

from .. import messages as _messages
from ..names import ROS_TOPIC_PREFIX
from ..network import MAX_DOMAIN_ID
from . import arguments as _args
from . import intra_process as _intra
from .logger import set_logger_level
from .qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, to_dds_qos
from .security import create_participant
from .signals import restore_sigterm, shut_down_on_sigterm

__all__ = ['Context', 'NotInitializedException', 'get_default_context', 'init', 'ok', 'shutdown',
           'try_shutdown', 'typehash_user_data', 'DISCOVERY_TOPIC', 'ROS_TOPIC_PREFIX']

#: DDS topic of the ROS graph information (rmw_dds_common).
DISCOVERY_TOPIC = 'ros_discovery_info'


class NotInitializedException(Exception):
    """A node is created before ``init()`` or after shutdown; ``what`` names what was attempted."""

    def __init__(self, what='cannot create node'):
        super().__init__(f'{what}: init() has not been called or the context was shut down')


class Context:
    """``rclpy.context.Context``: init/shutdown state, arguments, and the process's DDS participant."""

    def __init__(self):
        self._lock = threading.RLock()
        self._ok = False
        self._args = _args.ParsedArguments()
        self._raw_args = []
        self._domain_id = 0
        self._dp = None
        self._pub = None
        self._sub = None
        self._guard = None
        self._topics = {}
        self._nodes = []
        self._discovery_writer = None
        self._executors = weakref.WeakSet()
        self._on_shutdown = []
        self._initialised = False
        self._torn_down = False
        # in-process delivery between the nodes of this process (uh_runtime.dds.intra_process)
        self._intra = _intra.IntraProcess(self.wake) if _intra.enabled() else None

    # -- lifecycle --------------------------------------------------------------------------
    def init(self, args=None, *, domain_id=None):
        """Initialise the context, as rclpy's ``Context.init`` does.

        ``args`` (``sys.argv`` when None) give the ``--ros-args`` (log levels are applied now); the domain
        is ``domain_id``, else ``ROS_DOMAIN_ID``, else 0. SIGTERM then shuts the context down, as in rclpy.
        Raise RuntimeError when already initialised and ValueError for a domain outside 0..MAX_DOMAIN_ID.
        """
        with self._lock:
            if self._ok:
                raise RuntimeError('Context.init() must only be called once')
            argv = list(sys.argv if args is None else args)
            self._raw_args = argv
            self._args = _args.parse_ros_args(argv)
            env_domain = os.environ.get('ROS_DOMAIN_ID', '').strip()
            if domain_id is None:
                domain_id = int(env_domain) if env_domain else 0
            if not 0 <= int(domain_id) <= MAX_DOMAIN_ID:
                raise ValueError(f'domain id {domain_id} is outside 0..{MAX_DOMAIN_ID}')
            self._domain_id = int(domain_id)
            for logger, level in self._args.log_levels.items():
                set_logger_level(logger, level)
            self._ok = True
            self._initialised = True
        shut_down_on_sigterm(self)

    def ok(self) -> bool:
        """Return whether the context is initialised and not shut down, as rclpy's ``Context.ok`` does."""
        return self._ok

    def shutdown(self):
        """Shut down: run the on-shutdown callbacks, destroy the nodes and delete the DDS participant.

        As rclpy's ``Context.shutdown``: RuntimeError when the context is not running.
        """
        with self._lock:
            if not self._ok:
                raise RuntimeError('Context must be initialized before it can be shutdown')
            self._shutdown()

    def try_shutdown(self):
        """Shut down unless already done (also completes a shutdown a SIGTERM requested)."""
        with self._lock:
            if self._initialised and not self._torn_down:
                self._shutdown()

    def _request_shutdown(self):
        self._ok = False
        restore_sigterm()
        self.wake()

    def _shutdown(self):
        self._ok = False
        self._torn_down = True
        restore_sigterm()
        for callback in self._on_shutdown:
            callback()
        for node in list(self._nodes):
            node.destroy_node()
        self.wake()
        dp, self._dp = self._dp, None
        self._topics.clear()
        self._discovery_writer = None
        if dp is not None:
            dp.__del__()  # delete the participant now, so peers see it leave

    def on_shutdown(self, callback):
        """Register ``callback()`` to run at shutdown, as rclpy's ``Context.on_shutdown`` does."""
        self._on_shutdown.append(callback)

    def get_domain_id(self) -> int:
        """Return the DDS domain id, as rclpy's ``Context.get_domain_id`` does."""
        return self._domain_id

    @property
    def arguments(self) -> _args.ParsedArguments:
        """The parsed ROS arguments of :meth:`init` (remaps, parameters, log levels, enclave)."""
        return self._args

    # -- DDS entities -----------------------------------------------------------------------
    @property
    def participant(self):
        """The process's DDS participant, created on first use with its publisher, subscriber and guard condition.

        Raise :class:`NotInitializedException` when the context is not running.
        """
        with self._lock:
            if self._dp is None:
                if not self._ok:
                    raise NotInitializedException('cannot use DDS')
                from cyclonedds.core import GuardCondition
                from cyclonedds.pub import Publisher as DdsPublisher
                from cyclonedds.sub import Subscriber as DdsSubscriber
                # secure when ROS_SECURITY_ENABLE=true (dds/security.py); else USER_DATA enclave=/; alone
                self._dp = create_participant(self._domain_id, self._args.enclave)
                self._pub = DdsPublisher(self._dp)
                self._sub = DdsSubscriber(self._dp)
                self._guard = GuardCondition(self._dp)
                self._gid = self._dp.get_guid().bytes
                self._create_discovery_writer()
            return self._dp

    def _create_discovery_writer(self):
        from cyclonedds.pub import DataWriter
        cls = _messages.dds_message('rmw_dds_common/msg/ParticipantEntitiesInfo')
        profile = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        topic = self.topic(DISCOVERY_TOPIC, cls)
        self._discovery_writer = DataWriter(
            self._pub, topic, qos=to_dds_qos(profile, typehash_user_data(cls)))

    def topic(self, dds_name, cls):
        """Return the (cached) DDS topic ``dds_name`` of type ``cls`` in this participant."""
        from cyclonedds.topic import Topic
        with self._lock:
            known = self._topics.get(dds_name)
            if known is not None:
                if known.data_type is not cls:
                    raise TypeError(
                        f'topic {dds_name!r} is already used with type '
                        f'{_messages.ros_type_name(known.data_type)} in this process; '
                        f'cannot use it with {_messages.ros_type_name(cls)}')
                return known
            topic = Topic(self.participant, dds_name, cls)
            self._topics[dds_name] = topic
            return topic

    @property
    def gid(self) -> bytes:
        """The participant's 16-byte GUID (creates the participant if needed)."""
        _ = self.participant   # the property creates the participant and its GUID
        return self._gid

    @property
    def guard(self):
        """The guard condition that wakes executors waiting on this context (creates the participant if needed)."""
        _ = self.participant   # the property creates the participant and its guard condition
        return self._guard

    def wake(self):
        """Trigger the guard condition so that waiting executors re-check their entities (no-op before DDS is up)."""
        guard = self._guard
        if guard is not None:
            try:
                guard.set(True)
            except Exception:  # participant already deleted
                pass

    def _add_node(self, node):
        with self._lock:
            self._nodes.append(node)
        self.publish_discovery_info()

    def _remove_node(self, node):
        with self._lock:
            if node in self._nodes:
                self._nodes.remove(node)
        if self._ok:
            self.publish_discovery_info()

    def discovery_info(self):
        """Return the ``ParticipantEntitiesInfo`` message describing this process's nodes."""
        info_cls = _messages.dds_message('rmw_dds_common/msg/ParticipantEntitiesInfo')
        node_cls = _messages.dds_message('rmw_dds_common/msg/NodeEntitiesInfo')
        gid_cls = _messages.dds_message('rmw_dds_common/msg/Gid')
        info = info_cls()
        info.gid = gid_cls(data=list(self.gid))
        for node in list(self._nodes):
            entry = node_cls()
            entry.node_namespace = node.get_namespace()
            entry.node_name = node.get_name()
            entry.reader_gid_seq = [gid_cls(data=list(s.gid)) for s in (*node.subscriptions, *node.services)]
            rosout = [node._rosout] if getattr(node, '_rosout', None) is not None else []
            entry.writer_gid_seq = [gid_cls(data=list(p.gid)) for p in (*node.publishers, *rosout)] + \
                [gid_cls(data=list(s.writer_gid)) for s in node.services]
            info.node_entities_info_seq.append(entry)
        return info

    def publish_discovery_info(self):
        """Write :meth:`discovery_info` on ``ros_discovery_info`` while the context runs."""
        with self._lock:
            if self._ok and self._discovery_writer is not None:
                self._discovery_writer.write(self.discovery_info())


def typehash_user_data(cls) -> bytes:
    """USER_DATA of a reader or writer of type ``cls``: ``typehash=RIHS01_<hex>;`` (REP-2011)."""
    return f'typehash={_messages.type_hash(cls)};'.encode()


_default_context = Context()


def get_default_context() -> Context:
    """Return the process's default :class:`Context`, as ``rclpy.utilities.get_default_context`` does."""
    return _default_context


def init(*, args=None, context=None, domain_id=None, signal_handler_options=None):
    """``rclpy.init``: initialise the context (returns ``None`` as on Jazzy)."""
    (context or _default_context).init(args, domain_id=domain_id)


def ok(*, context=None) -> bool:
    """Return whether ``context`` (the default one if None) runs, as ``rclpy.ok`` does."""
    return (context or _default_context).ok()


def shutdown(*, context=None):
    """Shut down ``context`` (the default one if None), as ``rclpy.shutdown`` does."""
    (context or _default_context).shutdown()


def try_shutdown(*, context=None):
    """Shut down ``context`` (the default one if None) unless already done, as ``rclpy.try_shutdown`` does."""
    (context or _default_context).try_shutdown()
