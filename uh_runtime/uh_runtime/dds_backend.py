"""Cyclone DDS backend of the node facade: the rclpy (Jazzy) subset the UH nodes use (DESIGN.md 1).

Wire conventions are those of ROS 2 Jazzy with rmw_cyclonedds_cpp, so ROS 2 tools and nodes on the
same DDS domain interoperate:

* one DDS participant per context (process), USER_DATA ``enclave=/;``;
* ROS topic ``/uh1/state`` -> DDS topic ``rt/uh1/state``; type ``uh_msgs::msg::dds_::UHState_``;
  XCDR1 little-endian payload (the ROS 2 CDR bytes);
* reader/writer QoS mapped like rmw_cyclonedds (see :mod:`uh_runtime.qos`), USER_DATA
  ``typehash=RIHS01_<hex>;``;
* ``ros_discovery_info`` (``rmw_dds_common/msg/ParticipantEntitiesInfo``; reliable,
  transient-local, keep-last 1) lists each node's name and namespace with the GIDs of its readers
  and writers; a GID is the 16-byte DDS GUID of the entity (``dds_get_guid``), which is what
  rmw_cyclonedds_cpp's ``convert_guid_to_gid`` copies.

Callbacks run in the thread that spins, never in DDS listener threads. The executor blocks in a
Cyclone ``WaitSet`` on one read condition per subscription and a guard condition (woken for new
entities, shutdown and signals); the wait times out only at the next wall-clock timer deadline.
Each wake-up takes every available sample of a reader in one batch.
"""
import collections
import inspect
import os
import signal
import socket
import sys
import threading
import time
import weakref

from . import arguments as _args
from . import intra_process as _intra
from . import messages as _messages
from .network import MAX_DOMAIN_ID
from .parameters import (
    InvalidParameterTypeException, InvalidParameterValueException, Parameter,
    ParameterAlreadyDeclaredException, ParameterDescriptor, ParameterImmutableException,
    ParameterNotDeclaredException, ParameterType, ParameterUninitializedException,
    SetParametersResult, check_value,
)
from .qos import (
    DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, as_profile, qos_profile_clock,
    to_dds_qos,
)

__all__ = [
    'Context', 'Node', 'Publisher', 'Subscription', 'Timer', 'Clock', 'ROSClock', 'ClockType',
    'Time', 'Duration', 'Executor', 'SingleThreadedExecutor', 'MultiThreadedExecutor',
    'ExternalShutdownException', 'NotInitializedException', 'init', 'shutdown', 'try_shutdown',
    'ok', 'spin', 'spin_once', 'spin_until_future_complete', 'get_default_context',
    'get_global_executor', 'DISCOVERY_TOPIC', 'ROS_TOPIC_PREFIX',
]

#: DDS topic of the ROS graph information (rmw_dds_common).
DISCOVERY_TOPIC = 'ros_discovery_info'
#: Prefix rmw puts in front of a ROS topic name to get the DDS topic name.
ROS_TOPIC_PREFIX = 'rt'
_DDS_INFINITY = 0x7FFFFFFFFFFFFFFF
_TAKE_BATCH = 256
_PAD4 = [b'', b'\0', b'\0\0', b'\0\0\0']


class ExternalShutdownException(Exception):
    """The context was shut down (``try_shutdown``, SIGTERM) while spinning."""


class NotInitializedException(Exception):
    """A node is created before ``init()`` or after shutdown."""

    def __init__(self, what='cannot create node'):
        super().__init__(f'{what}: init() has not been called or the context was shut down')


# ----------------------------------------------------------------------------------------------
# Time
# ----------------------------------------------------------------------------------------------
class ClockType:
    """``rclpy.clock.ClockType``."""

    UNINITIALIZED = 0
    ROS_TIME = 1
    SYSTEM_TIME = 2
    STEADY_TIME = 3


class Duration:
    """``rclpy.duration.Duration(seconds=0, nanoseconds=0)``."""

    __slots__ = ('_ns',)

    def __init__(self, *, seconds=0, nanoseconds=0):
        self._ns = int(round(seconds * 1_000_000_000)) + int(nanoseconds)

    @property
    def nanoseconds(self) -> int:
        return self._ns

    def to_msg(self):
        msg = _messages.dds_message('builtin_interfaces/msg/Duration')()
        msg.sec, msg.nanosec = divmod(self._ns, 1_000_000_000)
        return msg

    @classmethod
    def from_msg(cls, msg):
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec)

    def __eq__(self, other):
        return isinstance(other, Duration) and self._ns == other._ns

    def __lt__(self, other):
        return self._ns < other._ns

    def __le__(self, other):
        return self._ns <= other._ns

    def __hash__(self):
        return hash(self._ns)

    def __repr__(self):
        return f'Duration(nanoseconds={self._ns})'


class Time:
    """``rclpy.time.Time(seconds=0, nanoseconds=0, clock_type=ClockType.SYSTEM_TIME)``."""

    __slots__ = ('_ns', '_clock_type')

    def __init__(self, *, seconds=0, nanoseconds=0, clock_type=ClockType.SYSTEM_TIME):
        ns = int(round(seconds * 1_000_000_000)) + int(nanoseconds)
        if ns < 0:
            raise ValueError(f'time {ns} ns is negative; times must be >= 0')
        self._ns = ns
        self._clock_type = clock_type

    @property
    def nanoseconds(self) -> int:
        return self._ns

    @property
    def clock_type(self):
        return self._clock_type

    def seconds_nanoseconds(self):
        """(seconds, nanoseconds) with 0 <= nanoseconds < 1e9."""
        return divmod(self._ns, 1_000_000_000)

    def to_msg(self):
        msg = _messages.dds_message('builtin_interfaces/msg/Time')()
        msg.sec, msg.nanosec = divmod(self._ns, 1_000_000_000)
        return msg

    @classmethod
    def from_msg(cls, msg, clock_type=ClockType.ROS_TIME):
        return cls(seconds=msg.sec, nanoseconds=msg.nanosec, clock_type=clock_type)

    def _check(self, other):
        if not isinstance(other, Time):
            raise TypeError(f'cannot compare Time with {type(other).__name__}')
        if other._clock_type != self._clock_type:
            raise TypeError("can't compare times with different clock types")

    def __add__(self, other):
        if isinstance(other, Duration):
            return Time(nanoseconds=self._ns + other.nanoseconds, clock_type=self._clock_type)
        return NotImplemented

    __radd__ = __add__

    def __sub__(self, other):
        if isinstance(other, Time):
            self._check(other)
            return Duration(nanoseconds=self._ns - other._ns)
        if isinstance(other, Duration):
            return Time(nanoseconds=self._ns - other.nanoseconds, clock_type=self._clock_type)
        return NotImplemented

    def __eq__(self, other):
        self._check(other)
        return self._ns == other._ns

    def __lt__(self, other):
        self._check(other)
        return self._ns < other._ns

    def __le__(self, other):
        self._check(other)
        return self._ns <= other._ns

    def __gt__(self, other):
        self._check(other)
        return self._ns > other._ns

    def __ge__(self, other):
        self._check(other)
        return self._ns >= other._ns

    def __hash__(self):
        return hash((self._ns, self._clock_type))

    def __repr__(self):
        return f'Time(nanoseconds={self._ns}, clock_type={self._clock_type})'


class Clock:
    """``rclpy.clock.Clock``: system, steady or ROS time."""

    def __init__(self, *, clock_type=ClockType.SYSTEM_TIME):
        self._clock_type = clock_type

    @property
    def clock_type(self):
        return self._clock_type

    def _now_ns(self) -> int:
        if self._clock_type == ClockType.STEADY_TIME:
            return time.monotonic_ns()
        return time.time_ns()

    def now(self) -> Time:
        return Time(nanoseconds=self._now_ns(), clock_type=self._clock_type)


class ROSClock(Clock):
    """ROS time: system time, or the last ``/clock`` value while sim time is active."""

    def __init__(self):
        super().__init__(clock_type=ClockType.ROS_TIME)
        self._override_ns = 0
        self._active = False
        self._listeners = []  # callables run after each sim-time update

    @property
    def ros_time_is_active(self) -> bool:
        return self._active

    def _set_ros_time_is_active(self, active: bool):
        self._active = bool(active)

    def _set_ros_time(self, ns: int):
        self._override_ns = int(ns)

    def _now_ns(self) -> int:
        return self._override_ns if self._active else time.time_ns()


# ----------------------------------------------------------------------------------------------
# Logging (rcutils console format, to stderr)
# ----------------------------------------------------------------------------------------------
_SEVERITY = {'DEBUG': 10, 'INFO': 20, 'WARN': 30, 'ERROR': 40, 'FATAL': 50}
_log_levels = {'': 20}
_log_lock = threading.Lock()


class RcutilsLogger:
    """``rclpy.impl.rcutils_logger.RcutilsLogger`` subset: ``[LEVEL] [t] [name]: message`` on stderr."""

    def __init__(self, name=''):
        self.name = name
        self._once = set()
        self._last = {}

    def get_child(self, name):
        return RcutilsLogger(f'{self.name}.{name}' if self.name else name)

    def set_level(self, level):
        name = level if isinstance(level, str) else {10: 'DEBUG', 20: 'INFO', 30: 'WARN',
                                                      40: 'ERROR', 50: 'FATAL'}[int(level)]
        _log_levels[self.name] = _SEVERITY[name.upper()]

    def get_effective_level(self):
        name = self.name
        while True:
            if name in _log_levels:
                return _log_levels[name]
            if '.' not in name:
                return _log_levels['']
            name = name.rsplit('.', 1)[0]

    def is_enabled_for(self, severity):
        return _SEVERITY[severity] >= self.get_effective_level()

    def log(self, message, severity, *, once=False, throttle_duration_sec=None, skip_first=False, **_):
        severity = 'WARN' if severity == 'WARNING' else severity
        if not self.is_enabled_for(severity):
            return False
        key = inspect.currentframe().f_back.f_back
        key = (key.f_code, key.f_lineno) if key else None
        if once:
            if key in self._once:
                return False
            self._once.add(key)
        if skip_first and key not in self._last:
            self._last[key] = time.monotonic()
            return False
        if throttle_duration_sec:
            now = time.monotonic()
            if key in self._last and now - self._last[key] < throttle_duration_sec:
                return False
            self._last[key] = now
        stamp = time.time()
        with _log_lock:
            sys.stderr.write(f'[{severity}] [{stamp:.9f}] [{self.name}]: {message}\n')
            sys.stderr.flush()
        return True

    def debug(self, message, **kw):
        return self.log(message, 'DEBUG', **kw)

    def info(self, message, **kw):
        return self.log(message, 'INFO', **kw)

    def warning(self, message, **kw):
        return self.log(message, 'WARN', **kw)

    warn = warning

    def error(self, message, **kw):
        return self.log(message, 'ERROR', **kw)

    def fatal(self, message, **kw):
        return self.log(message, 'FATAL', **kw)


def get_logger(name):
    """``rclpy.logging.get_logger``."""
    return RcutilsLogger(name)


# ----------------------------------------------------------------------------------------------
# Context: one DDS participant per process, signal handling, ros_discovery_info
# ----------------------------------------------------------------------------------------------
_wakeup_lock = threading.Lock()
_wakeup_contexts = weakref.WeakSet()
_wakeup_installed = [False]
_wakeup_sockets = []


def _install_signal_wakeup():
    """Wake every context's wait set when a signal arrives, so Ctrl-C/SIGTERM act at once.

    The C-level signal handler writes to a socket (``signal.set_wakeup_fd``) even while the main
    thread is blocked inside the Cyclone wait; a daemon thread reading that socket triggers the
    guard conditions, the wait returns and Python runs the signal handler.
    """
    if _wakeup_installed[0] or threading.current_thread() is not threading.main_thread():
        return
    rsock, wsock = socket.socketpair()
    wsock.setblocking(False)
    try:
        signal.set_wakeup_fd(wsock.fileno(), warn_on_full_buffer=False)
    except ValueError:
        return
    _wakeup_installed[0] = True
    _wakeup_sockets.extend((rsock, wsock))  # keep both open for the life of the process

    def pump():
        while True:
            try:
                data = rsock.recv(64)
            except OSError:
                return
            if not data:
                return
            for ctx in list(_wakeup_contexts):
                ctx.wake()

    threading.Thread(target=pump, name='uh-signal-wakeup', daemon=True).start()


def wake_on_signals(target):
    """Call ``target.wake()`` whenever a signal arrives (main thread only; weakly referenced)."""
    _wakeup_contexts.add(target)
    _install_signal_wakeup()


def _restore_sigterm():
    """Give SIGTERM back its default action once no context is running."""
    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGTERM) is _on_sigterm and not any(
            isinstance(c, Context) and c.ok() for c in list(_wakeup_contexts)):
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _on_sigterm(signum, frame):
    # Runs in the main thread between two bytecodes, possibly inside a callback: only mark the
    # contexts shut down and wake their executors; the DDS entities stay valid until the entry
    # point's ``finally`` destroys the nodes and calls ``try_shutdown`` (nothing is cut off).
    for ctx in list(_wakeup_contexts):
        if isinstance(ctx, Context):
            ctx._request_shutdown()


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
        # in-process delivery between the nodes of this process (uh_runtime.intra_process)
        self._intra = _intra.IntraProcess(self.wake) if _intra.enabled() else None

    # -- lifecycle --------------------------------------------------------------------------
    def init(self, args=None, *, domain_id=None):
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
                _log_levels[logger] = _SEVERITY['WARN' if level == 'WARNING' else level]
            self._ok = True
            self._initialised = True
        _wakeup_contexts.add(self)
        _install_signal_wakeup()
        if threading.current_thread() is threading.main_thread() and \
                signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None):
            # like rclpy: SIGTERM shuts the contexts down (spin raises ExternalShutdownException)
            signal.signal(signal.SIGTERM, _on_sigterm)

    def ok(self) -> bool:
        return self._ok

    def shutdown(self):
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
        _restore_sigterm()
        self.wake()

    def _shutdown(self):
        self._ok = False
        self._torn_down = True
        _restore_sigterm()
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
        self._on_shutdown.append(callback)

    def get_domain_id(self) -> int:
        return self._domain_id

    @property
    def arguments(self) -> _args.ParsedArguments:
        return self._args

    # -- DDS entities -----------------------------------------------------------------------
    @property
    def participant(self):
        with self._lock:
            if self._dp is None:
                if not self._ok:
                    raise NotInitializedException('cannot use DDS')
                from cyclonedds.core import GuardCondition
                from cyclonedds.domain import DomainParticipant
                from cyclonedds.pub import Publisher as DdsPublisher
                from cyclonedds.qos import Policy, Qos
                from cyclonedds.sub import Subscriber as DdsSubscriber
                enclave = self._args.enclave or '/'
                self._dp = DomainParticipant(
                    self._domain_id, qos=Qos(Policy.Userdata(f'enclave={enclave};'.encode())))
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
            self._pub, topic, qos=to_dds_qos(profile, _typehash_user_data(cls)))

    def topic(self, dds_name, cls):
        """The (cached) DDS topic ``dds_name`` of type ``cls`` in this participant."""
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
        self.participant
        return self._gid

    @property
    def guard(self):
        self.participant
        return self._guard

    def wake(self):
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
        """The ``ParticipantEntitiesInfo`` message describing this process's nodes."""
        info_cls = _messages.dds_message('rmw_dds_common/msg/ParticipantEntitiesInfo')
        node_cls = _messages.dds_message('rmw_dds_common/msg/NodeEntitiesInfo')
        gid_cls = _messages.dds_message('rmw_dds_common/msg/Gid')
        info = info_cls()
        info.gid = gid_cls(data=list(self.gid))
        for node in list(self._nodes):
            entry = node_cls()
            entry.node_namespace = node.get_namespace()
            entry.node_name = node.get_name()
            entry.reader_gid_seq = [gid_cls(data=list(s.gid)) for s in node.subscriptions]
            entry.writer_gid_seq = [gid_cls(data=list(p.gid)) for p in node.publishers]
            info.node_entities_info_seq.append(entry)
        return info

    def publish_discovery_info(self):
        with self._lock:
            if self._ok and self._discovery_writer is not None:
                self._discovery_writer.write(self.discovery_info())


def _typehash_user_data(cls) -> bytes:
    return f'typehash={_messages.type_hash(cls)};'.encode()


_default_context = Context()


def get_default_context() -> Context:
    return _default_context


def init(*, args=None, context=None, domain_id=None, signal_handler_options=None):
    """``rclpy.init``: initialise the context (returns ``None`` as on Jazzy)."""
    (context or _default_context).init(args, domain_id=domain_id)


def ok(*, context=None) -> bool:
    return (context or _default_context).ok()


def shutdown(*, context=None):
    (context or _default_context).shutdown()


def try_shutdown(*, context=None):
    (context or _default_context).try_shutdown()


# ----------------------------------------------------------------------------------------------
# Entities
# ----------------------------------------------------------------------------------------------
class Publisher:
    """``rclpy.publisher.Publisher``: ``publish(msg)``, ``topic_name``, ``get_subscription_count()``."""

    def __init__(self, node, msg_type, topic_name, qos_profile, writer):
        self._node = node
        self.msg_type = msg_type
        self.topic_name = topic_name
        self.qos_profile = qos_profile
        self._writer = writer
        self.gid = writer.get_guid().bytes
        from cyclonedds._clayer import ddspy_write

        from .cdr import codec
        self._write = ddspy_write
        self._ref = writer._ref
        self._serialize = codec(msg_type).serialize
        self._intra = node._context._intra
        self._local = []       # subscriptions of this process fed directly (set by IntraProcess)
        # a transient-local publisher keeps its last messages for subscriptions of this process
        # created later, as a DDS writer keeps them for late-joining readers
        self._history = None
        if self._intra is not None and qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
            self._history = collections.deque(
                maxlen=None if qos_profile.history == HistoryPolicy.KEEP_ALL else max(1, qos_profile.depth))

    @property
    def topic(self):
        return self.topic_name

    def publish(self, msg):
        """Publish ``msg`` (an instance of ``msg_type``) or its CDR bytes (with the 4-byte header)."""
        if type(msg) is self.msg_type or isinstance(msg, self.msg_type):
            data = self._serialize(msg)
        elif isinstance(msg, (bytes, bytearray, memoryview)):
            data = bytes(msg)
            msg = None
        else:
            raise TypeError(
                f'expected {_messages.ros_type_name(self.msg_type)} on {self.topic_name}, '
                f'got {type(msg).__name__}')
        if len(data) & 3:  # rmw_cyclonedds pads the payload to a multiple of 4 bytes too
            data += _PAD4[-len(data) & 3]
        ret = self._write(self._ref, data)
        if ret < 0:
            raise RuntimeError(f'publishing on {self.topic_name} failed (DDS error {ret})')
        if self._history is not None:
            self._history.append((msg, data))
        if self._local:
            # the subscriptions of this process get the message object itself (and the bytes)
            self._intra.deliver(self._local, (msg, data))

    def get_subscription_count(self) -> int:
        """Number of matched readers (DDS publication-matched status) plus the subscriptions of
        this process it feeds directly."""
        return len(self._writer.get_matched_subscriptions()) + len(self._local)

    def wait_for_all_acked(self, timeout_sec=None) -> bool:
        ns = _DDS_INFINITY if timeout_sec is None else int(timeout_sec * 1e9)
        try:
            self._writer.wait_for_acks(ns)
            return True
        except Exception:
            return False

    def destroy(self):
        self._node.destroy_publisher(self)


class Subscription:
    """``rclpy.subscription.Subscription``; the callback gets a message (or CDR bytes if ``raw``)."""

    def __init__(self, node, msg_type, topic_name, callback, qos_profile, reader, raw=False):
        from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState
        self._node = node
        self.msg_type = msg_type
        self.topic_name = topic_name
        self.callback = callback
        self.qos_profile = qos_profile
        self.raw = raw
        self._reader = reader
        self._condition = ReadCondition(
            reader, SampleState.NotRead | ViewState.Any | InstanceState.Any)
        self._mask = SampleState.Any | ViewState.Any | InstanceState.Any
        self.gid = reader.get_guid().bytes
        from cyclonedds._clayer import ddspy_take

        from .cdr import codec
        self._take = ddspy_take
        self._codec = codec(msg_type)
        self._deserialize = self._codec.deserialize
        self._inbox = _intra.Inbox(qos_profile)   # messages from publishers of this process

    @property
    def topic(self):
        return self.topic_name

    def get_publisher_count(self) -> int:
        local = self._node._context._intra
        return len(self._reader.get_matched_publications()) + (
            local.local_publisher_count(self) if local is not None else 0)

    def _take_messages(self, from_dds=True):
        """Every available sample in one batch (raw CDR bytes or deserialised messages): those of
        DDS (if ``from_dds``), then those delivered in process."""
        out = []
        if from_dds:
            ret = self._take(self._reader._ref, self._mask, _TAKE_BATCH)
            if isinstance(ret, int):
                raise RuntimeError(f'taking samples from {self.topic_name} failed (DDS error {ret})')
            if self.raw:
                out = [data for data, info in ret if info.valid_data]
            else:
                deserialize = self._deserialize
                out = [deserialize(data) for data, info in ret if info.valid_data]
        if self._inbox.items:
            out += self._inbox.take(self.raw, self._codec.serialize, self._deserialize)
        return out

    def destroy(self):
        self._node.destroy_subscription(self)


class Timer:
    """``rclpy.timer.Timer`` on a node clock (wall or sim time)."""

    def __init__(self, node, callback, period_ns, clock, autostart=True):
        if period_ns <= 0:
            raise ValueError(f'timer period must be > 0 s, got {period_ns * 1e-9} s')
        self._node = node
        self.callback = callback
        self.timer_period_ns = int(period_ns)
        self._clock = clock
        self._canceled = not autostart
        self._next = clock._now_ns() + self.timer_period_ns
        self._last_call = None

    @property
    def clock(self):
        return self._clock

    def _is_sim(self):
        return isinstance(self._clock, ROSClock) and self._clock.ros_time_is_active

    def is_canceled(self):
        return self._canceled

    def is_ready(self):
        return not self._canceled and self._clock._now_ns() >= self._next

    def cancel(self):
        self._canceled = True

    def reset(self):
        self._canceled = False
        self._next = self._clock._now_ns() + self.timer_period_ns
        self._node._changed()

    def time_until_next_call(self):
        if self._canceled:
            return None
        return self._next - self._clock._now_ns()

    def time_since_last_call(self):
        return None if self._last_call is None else self._clock._now_ns() - self._last_call

    def _fire_if_due(self) -> bool:
        if self._canceled:
            return False
        now = self._clock._now_ns()
        if now < self._next:
            return False
        # like rcl: one call, then the next multiple of the period after now
        periods = (now - self._next) // self.timer_period_ns + 1
        self._next += periods * self.timer_period_ns
        self._last_call = now
        self.callback()
        return True

    def _sim_jump(self, now_ns):
        """Sim time moved backwards (a restarted clock): restart the period from now."""
        if now_ns + self.timer_period_ns < self._next - self.timer_period_ns:
            self._next = now_ns + self.timer_period_ns

    def destroy(self):
        self._node.destroy_timer(self)


# ----------------------------------------------------------------------------------------------
# Node
# ----------------------------------------------------------------------------------------------
class Node:
    """``rclpy.node.Node`` on Cyclone DDS (the subset listed in docs/runtime.md)."""

    PARAM_REL_TOL = 1e-6

    def __init__(self, node_name, *, context=None, cli_args=None, namespace=None,
                 use_global_arguments=True, enable_rosout=True, start_parameter_services=True,
                 parameter_overrides=None, allow_undeclared_parameters=False,
                 automatically_declare_parameters_from_overrides=False,
                 enable_logger_service=False):
        self._context = context or _default_context
        if not self._context.ok():
            raise NotInitializedException('cannot create node')
        self.publishers = []
        self.subscriptions = []
        self.timers = []
        self._executors = weakref.WeakSet()
        self._destroyed = False

        local = _args.parse_ros_args(['--ros-args', *cli_args] if cli_args and '--ros-args' not in cli_args
                                     else (cli_args or []))
        parsed = _args.ParsedArguments()
        parsed.extend(local)
        if use_global_arguments:
            glob = self._context.arguments
            parsed.remaps += glob.remaps
            parsed.parameters = glob.parameters + parsed.parameters
            for logger, level in glob.log_levels.items():
                parsed.log_levels.setdefault(logger, level)
        self._arguments = parsed

        _args.validate_node_name(node_name)
        name, ns_override = _args.apply_name_remaps(parsed.remaps, node_name)
        self._name = name
        self._namespace = ns_override or _args.normalise_namespace(namespace)
        logger_name = '.'.join([*filter(None, self._namespace.split('/')), self._name])
        self._logger = RcutilsLogger(logger_name)
        for logger, level in local.log_levels.items():
            _log_levels[logger or logger_name] = _SEVERITY['WARN' if level == 'WARNING' else level]

        # parameters
        self._parameters = {}
        self._descriptors = {}
        self._on_set_callbacks = []
        self._pre_set_callbacks = []
        self._post_set_callbacks = []
        self._allow_undeclared = allow_undeclared_parameters
        fq = self.get_fully_qualified_name()
        overrides = {}
        for pattern, params in parsed.parameters:
            if _args.node_pattern_matches(pattern, fq) or pattern in (name, node_name):
                for pname, value in params.items():
                    overrides[pname] = Parameter(pname, value=value)
        for param in parameter_overrides or []:
            overrides[param.name] = param
        self._parameter_overrides = overrides

        # clock and sim time (rclpy's TimeSource)
        self._clock = ROSClock()
        self._clock_sub = None
        self._context.participant  # create the participant before any entity
        self._context._add_node(self)
        self.declare_parameter('use_sim_time', False)
        self._apply_use_sim_time(self.get_parameter('use_sim_time').value)
        if automatically_declare_parameters_from_overrides:
            for pname, param in overrides.items():
                if pname not in self._parameters:
                    self.declare_parameter(pname, param.value)

    # -- names ------------------------------------------------------------------------------
    @property
    def context(self):
        return self._context

    @property
    def executor(self):
        return next(iter(self._executors), None)

    def get_name(self) -> str:
        return self._name

    def get_namespace(self) -> str:
        return self._namespace

    def get_fully_qualified_name(self) -> str:
        return f"{self._namespace.rstrip('/')}/{self._name}"

    def get_logger(self):
        return self._logger

    def get_clock(self):
        return self._clock

    def resolve_topic_name(self, topic, *, only_expand=False) -> str:
        """Fully qualified ROS name of ``topic`` for this node, after remapping."""
        fq = _args.expand_topic_name(topic, self._name, self._namespace)
        if only_expand:
            return fq
        return _args.remap_topic(self._arguments.remaps, fq, self._name, self._namespace)

    def _changed(self):
        for executor in list(self._executors):
            executor._entities_changed()

    # -- publishers and subscriptions -------------------------------------------------------
    def _check_type(self, msg_type):
        if not hasattr(msg_type, '__ros_typename__'):
            raise TypeError(
                f'{msg_type!r} is not a message class of this backend; use '
                'uh_runtime.messages.get_message("pkg/msg/Type")')

    def create_publisher(self, msg_type, topic, qos_profile, *, callback_group=None,
                         event_callbacks=None, qos_overriding_options=None, publisher_class=None):
        from cyclonedds.pub import DataWriter
        self._check_type(msg_type)
        profile = as_profile(qos_profile)
        name = self.resolve_topic_name(topic)
        dds_topic = self._context.topic(ROS_TOPIC_PREFIX + name, msg_type)
        intra = self._context._intra
        writer = DataWriter(self._context._pub, dds_topic,
                            qos=to_dds_qos(profile, _typehash_user_data(msg_type), ignore_local=intra is not None))
        pub = Publisher(self, msg_type, name, profile, writer)
        self.publishers.append(pub)
        if intra is not None:
            intra.add_publisher(pub)
        self._context.publish_discovery_info()
        return pub

    def create_subscription(self, msg_type, topic, callback, qos_profile, *, callback_group=None,
                            event_callbacks=None, qos_overriding_options=None, raw=False):
        from cyclonedds.sub import DataReader
        self._check_type(msg_type)
        profile = as_profile(qos_profile)
        name = self.resolve_topic_name(topic)
        dds_topic = self._context.topic(ROS_TOPIC_PREFIX + name, msg_type)
        intra = self._context._intra
        reader = DataReader(self._context._sub, dds_topic,
                            qos=to_dds_qos(profile, _typehash_user_data(msg_type), ignore_local=intra is not None))
        sub = Subscription(self, msg_type, name, callback, profile, reader, raw=raw)
        self.subscriptions.append(sub)
        if intra is not None:
            intra.add_subscription(sub)
        self._context.publish_discovery_info()
        self._changed()
        return sub

    def create_timer(self, timer_period_sec, callback, callback_group=None, clock=None,
                     autostart=True):
        timer = Timer(self, callback, int(round(float(timer_period_sec) * 1e9)),
                      clock or self._clock, autostart)
        self.timers.append(timer)
        self._changed()
        return timer

    def destroy_publisher(self, publisher) -> bool:
        if publisher not in self.publishers:
            return False
        self.publishers.remove(publisher)
        if self._context._intra is not None:
            self._context._intra.remove_publisher(publisher)
        publisher._writer.__del__()
        self._context.publish_discovery_info()
        return True

    def destroy_subscription(self, subscription) -> bool:
        if subscription not in self.subscriptions:
            return False
        self.subscriptions.remove(subscription)
        if self._context._intra is not None:
            self._context._intra.remove_subscription(subscription)
        self._changed()
        for executor in list(self._executors):
            executor._detach(subscription)
        subscription._condition.__del__()
        subscription._reader.__del__()
        self._context.publish_discovery_info()
        return True

    def destroy_timer(self, timer) -> bool:
        if timer not in self.timers:
            return False
        self.timers.remove(timer)
        timer.cancel()
        self._changed()
        return True

    def destroy_node(self):
        """Delete every entity of the node and remove it from ``ros_discovery_info``."""
        if self._destroyed:
            return True
        self._destroyed = True
        for timer in list(self.timers):
            self.destroy_timer(timer)
        if self._context._dp is not None:
            for sub in list(self.subscriptions):
                self.destroy_subscription(sub)
            for pub in list(self.publishers):
                self.destroy_publisher(pub)
        else:
            self.subscriptions.clear()
            self.publishers.clear()
        for executor in list(self._executors):
            executor.remove_node(self)
        self._context._remove_node(self)
        return True

    # -- graph ------------------------------------------------------------------------------
    def _graph(self):
        from .graph import Graph
        if getattr(self, '_graph_cache', None) is None:
            self._graph_cache = Graph(
                participant=self._context.participant,
                info_topic=self._context.topic(
                    DISCOVERY_TOPIC,
                    _messages.dds_message('rmw_dds_common/msg/ParticipantEntitiesInfo')))
        self._graph_cache.update()
        return self._graph_cache

    def count_publishers(self, topic_name) -> int:
        """Writers of the topic in the domain (this process's included), from DDS discovery."""
        return self._graph().count(self.resolve_topic_name(topic_name), writers=True)

    def count_subscribers(self, topic_name) -> int:
        """Readers of the topic in the domain (this process's included), from DDS discovery."""
        return self._graph().count(self.resolve_topic_name(topic_name), writers=False)

    def get_publishers_info_by_topic(self, topic_name, no_mangle=False):
        """``rclpy``'s list of endpoint infos (node_name, node_namespace, topic_type,
        endpoint_type, endpoint_gid, qos_profile) of the topic's writers."""
        name = topic_name if no_mangle else self.resolve_topic_name(topic_name)
        return self._graph().endpoints(name, writers=True)

    def get_subscriptions_info_by_topic(self, topic_name, no_mangle=False):
        name = topic_name if no_mangle else self.resolve_topic_name(topic_name)
        return self._graph().endpoints(name, writers=False)

    def get_topic_names_and_types(self, no_demangle=False):
        return self._graph().topic_names_and_types()

    def get_node_names(self):
        return [name for name, _ in self._graph().node_names_and_namespaces()]

    def get_node_names_and_namespaces(self):
        return self._graph().node_names_and_namespaces()

    # -- parameters ------------------------------------------------------------------------
    def declare_parameter(self, name, value=None, descriptor=None, ignore_override=False):
        """Declare one parameter, as rclpy (Jazzy) does.

        ``value`` may be a default value or a ``Parameter.Type`` (statically typed, no default).
        The override from the command line or ``parameter_overrides`` wins over the default unless
        ``ignore_override``; it must have the declared type (or be an int for a double) and pass
        the descriptor's range, else :class:`InvalidParameterTypeException` /
        :class:`InvalidParameterValueException` name the parameter and what is allowed.
        """
        return self.declare_parameters('', [(name, value, descriptor or ParameterDescriptor())],
                                       ignore_override)[0]

    def declare_parameters(self, namespace, parameters, ignore_override=False):
        declared = []
        for entry in parameters:
            entry = tuple(entry) if isinstance(entry, (tuple, list)) else (entry,)
            name = f'{namespace}.{entry[0]}' if namespace else entry[0]
            value = entry[1] if len(entry) > 1 else None
            descriptor = entry[2] if len(entry) > 2 and entry[2] is not None else ParameterDescriptor()
            if not isinstance(name, str) or not name:
                raise TypeError(f'parameter name must be a non-empty str, got {name!r}')
            if name in self._parameters:
                raise ParameterAlreadyDeclaredException(name)
            if isinstance(value, ParameterType):
                if value == ParameterType.NOT_SET:
                    raise ValueError(
                        f'Cannot declare parameter {{{name}}} as statically typed of type NOT_SET')
                ptype, value = value, None
            elif value is None:
                if not descriptor.dynamic_typing:
                    raise ValueError(
                        f"parameter '{name}': cannot declare a statically typed parameter without "
                        'a default value; give a default, a Parameter.Type, or '
                        'ParameterDescriptor(dynamic_typing=True)')
                ptype = ParameterType.NOT_SET
            else:
                try:
                    ptype = ParameterType.from_parameter_value(value)
                except TypeError as exc:
                    raise TypeError(f"parameter '{name}': {exc}") from None
            descriptor.name = name
            if not descriptor.dynamic_typing:
                descriptor.type = int(ptype)
            if not ignore_override and name in self._parameter_overrides:
                value = self._parameter_overrides[name].value
            value = self._coerce(name, value, descriptor)
            reason = check_value(name, value, descriptor) if value is not None else None
            if reason:
                raise InvalidParameterValueException(name, value, reason)
            param = Parameter(name, value=value)
            result = self._run_set_callbacks([param])
            if not result.successful:
                raise InvalidParameterValueException(name, value, result.reason)
            self._descriptors[name] = descriptor
            self._parameters[name] = param
            self._run_post_callbacks([param])
            declared.append(param)
        return declared

    def _coerce(self, name, value, descriptor):
        """Type check against a statically typed descriptor.

        As in rclpy, an integer is *not* accepted for a double parameter (``-p rate:=20`` for a
        double fails; write ``20.0``), so a command line that works here works on ROS 2 too.
        """
        if value is None or descriptor.dynamic_typing or not descriptor.type:
            return value
        expected = ParameterType(descriptor.type)
        if not expected.check(value):
            raise InvalidParameterTypeException(name, value, expected)
        return value

    def undeclare_parameter(self, name):
        if name not in self._parameters:
            raise ParameterNotDeclaredException(name, self._parameters)
        if self._descriptors[name].read_only:
            raise ParameterImmutableException(name)
        del self._parameters[name]
        del self._descriptors[name]

    def has_parameter(self, name) -> bool:
        return name in self._parameters

    def get_parameter(self, name) -> Parameter:
        if name in self._parameters:
            param = self._parameters[name]
            if param.type_ == ParameterType.NOT_SET and self._descriptors[name].type and \
                    not self._descriptors[name].dynamic_typing:
                raise ParameterUninitializedException(name)
            return param
        if self._allow_undeclared:
            return Parameter(name)
        raise ParameterNotDeclaredException(name, self._parameters)

    def get_parameters(self, names):
        return [self.get_parameter(n) for n in names]

    def get_parameter_or(self, name, alternative_value=None):
        if name not in self._parameters:
            return Parameter(name, value=None) if alternative_value is None else alternative_value
        return self._parameters[name]

    def get_parameters_by_prefix(self, prefix):
        prefix = prefix + '.' if prefix else ''
        return {n[len(prefix):]: p for n, p in self._parameters.items() if n.startswith(prefix)}

    def describe_parameter(self, name):
        if name not in self._descriptors:
            raise ParameterNotDeclaredException(name, self._parameters)
        return self._descriptors[name]

    def describe_parameters(self, names):
        return [self.describe_parameter(n) for n in names]

    def set_parameters(self, parameter_list):
        return [self.set_parameters_atomically([p]) for p in parameter_list]

    def set_parameters_atomically(self, parameter_list):
        for param in parameter_list:
            if param.name not in self._parameters:
                if not self._allow_undeclared:
                    raise ParameterNotDeclaredException(param.name, self._parameters)
        checked = []
        for param in parameter_list:
            desc = self._descriptors.get(param.name, ParameterDescriptor(dynamic_typing=True))
            if desc.read_only:
                return SetParametersResult(successful=False,
                                           reason=f"parameter '{param.name}' is read-only")
            try:
                value = self._coerce(param.name, param.value, desc)
            except InvalidParameterTypeException as exc:
                return SetParametersResult(successful=False, reason=str(exc))
            reason = check_value(param.name, value, desc) if value is not None else None
            if reason:
                return SetParametersResult(successful=False, reason=f"parameter '{param.name}': {reason}")
            checked.append(Parameter(param.name, value=value))
        result = self._run_set_callbacks(checked)
        if result.successful:
            for param in checked:
                self._parameters[param.name] = param
                self._descriptors.setdefault(param.name, ParameterDescriptor(name=param.name))
            self._run_post_callbacks(checked)
        return result

    def add_on_set_parameters_callback(self, callback):
        self._on_set_callbacks.insert(0, callback)

    def remove_on_set_parameters_callback(self, callback):
        self._on_set_callbacks.remove(callback)

    def add_pre_set_parameters_callback(self, callback):
        self._pre_set_callbacks.insert(0, callback)

    def add_post_set_parameters_callback(self, callback):
        self._post_set_callbacks.insert(0, callback)

    def _run_set_callbacks(self, params):
        for callback in self._on_set_callbacks:
            result = callback(params)
            if not result.successful:
                return result
        return SetParametersResult(successful=True)

    def _run_post_callbacks(self, params):
        for param in params:
            if param.name == 'use_sim_time' and hasattr(self, '_clock'):
                self._apply_use_sim_time(param.value)
        for callback in self._post_set_callbacks:
            callback(params)

    # -- sim time --------------------------------------------------------------------------
    def _apply_use_sim_time(self, enabled):
        enabled = bool(enabled)
        if enabled and self._clock_sub is None:
            clock_cls = _messages.dds_message('rosgraph_msgs/msg/Clock')
            self._clock_sub = self.create_subscription(
                clock_cls, '/clock', self._on_clock, qos_profile_clock)
            self._clock._set_ros_time_is_active(True)
        elif not enabled and self._clock_sub is not None:
            self.destroy_subscription(self._clock_sub)
            self._clock_sub = None
            self._clock._set_ros_time_is_active(False)

    def _on_clock(self, msg):
        now = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
        if now < self._clock._override_ns:
            for timer in self.timers:
                timer._sim_jump(now)
        self._clock._set_ros_time(now)


# ----------------------------------------------------------------------------------------------
# Executors
# ----------------------------------------------------------------------------------------------
class _WaitSetCalls:
    """``dds_waitset_attach/detach/wait`` with integer attach arguments (ctypes, loaded once).

    cyclonedds' ``WaitSet.wait`` only returns how many entities triggered; calling
    ``dds_waitset_wait`` with an array gets the attach argument of each triggered entity, so the
    executor visits exactly the ready subscriptions (no ``is_triggered`` call per subscription).
    """

    _loaded = None

    @classmethod
    def get(cls):
        if cls._loaded is None:
            import ctypes as ct

            from cyclonedds.internal import load_cyclonedds
            dll = load_cyclonedds()
            attach, detach, wait = dll.dds_waitset_attach, dll.dds_waitset_detach, dll.dds_waitset_wait
            attach.argtypes, attach.restype = [ct.c_int32, ct.c_int32, ct.c_ssize_t], ct.c_int32
            detach.argtypes, detach.restype = [ct.c_int32, ct.c_int32], ct.c_int32
            wait.argtypes = [ct.c_int32, ct.POINTER(ct.c_ssize_t), ct.c_size_t, ct.c_int64]
            wait.restype = ct.c_int32
            cls._loaded = (attach, detach, wait, ct.c_ssize_t)
        return cls._loaded


#: attach argument of the context's guard condition in an executor's wait set
_GUARD_ARG = 0


def _wait_for_work(waitset_ref, triggered, timeout_ns) -> int:
    """Block in the wait set (at most ``timeout_ns``); fill ``triggered`` with the attach arguments
    of the ready entities and return how many there are. A function of its own so that profiles
    (``UH_PROFILE_DIR``) show the time a node spends idle."""
    return _WaitSetCalls.get()[2](waitset_ref, triggered, len(triggered), timeout_ns)


class Executor:
    """Runs the callbacks of one or more nodes in the calling thread (``rclpy.executors.Executor``).

    One Cyclone WaitSet holds a read condition per subscription and the context's guard
    condition; ``spin_once`` blocks until data arrives, the guard is triggered (new entity,
    shutdown, signal) or the next wall-clock timer is due, then takes every available sample of
    every ready subscription (the wait set names them) in one batch each and runs the callbacks,
    in the order of the nodes and of their subscriptions, then the due timers.
    """

    def __init__(self, *, context=None):
        self._context = context or _default_context
        self._nodes = []
        self._waitset = None
        self._attached = {}      # id(subscription) -> (attach argument, read condition)
        self._by_arg = {}        # attach argument -> subscription
        self._rank = {}          # id(subscription) -> dispatch order
        self._next_arg = _GUARD_ARG + 1
        self._triggered = None   # ctypes array the wait fills with attach arguments
        self._dirty = True
        self._is_shutdown = False
        self._lock = threading.RLock()

    @property
    def context(self):
        return self._context

    def add_node(self, node) -> bool:
        with self._lock:
            if node in self._nodes:
                return False
            self._nodes.append(node)
            node._executors.add(self)
            self._dirty = True
        self._context.wake()
        return True

    def remove_node(self, node):
        with self._lock:
            if node in self._nodes:
                # the read conditions are detached lazily at the next wait, so a node that is
                # added again at once (rt.spin_once in a loop) costs nothing
                self._nodes.remove(node)
                node._executors.discard(self)
                self._dirty = True

    def get_nodes(self):
        return list(self._nodes)

    def _entities_changed(self):
        self._dirty = True
        self._context.wake()

    def _detach(self, sub):
        with self._lock:
            self._detach_key(id(sub))

    def _sync(self):
        from cyclonedds.core import WaitSet
        attach, _, _, c_ssize_t = _WaitSetCalls.get()
        with self._lock:
            if self._waitset is None:
                self._waitset = WaitSet(self._context.participant)
                ret = attach(self._waitset._ref, self._context.guard._ref, _GUARD_ARG)
                if ret < 0:
                    raise RuntimeError(f'cannot attach the guard condition to the wait set (DDS error {ret})')
            wanted = [s for n in self._nodes for s in n.subscriptions]
            keys = {id(s) for s in wanted}
            for key in list(self._attached):
                if key not in keys:
                    self._detach_key(key)
            for sub in wanted:
                if id(sub) not in self._attached:
                    arg = self._next_arg
                    self._next_arg += 1
                    ret = attach(self._waitset._ref, sub._condition._ref, arg)
                    if ret < 0:
                        raise RuntimeError(f'cannot attach the read condition of {sub.topic_name} to the '
                                           f'wait set (DDS error {ret})')
                    self._attached[id(sub)] = (arg, sub._condition)
                    self._by_arg[arg] = sub
            self._rank = {id(s): i for i, s in enumerate(wanted)}
            if self._triggered is None or len(self._triggered) < len(self._attached) + 1:
                self._triggered = (c_ssize_t * (len(self._attached) + 9))()
            self._dirty = False

    def _detach_key(self, key):
        entry = self._attached.pop(key, None)
        if entry is None:
            return
        arg, cond = entry
        self._by_arg.pop(arg, None)
        if self._waitset is not None:
            try:
                _WaitSetCalls.get()[1](self._waitset._ref, cond._ref)
            except Exception:
                pass

    def _next_timer_ns(self):
        """Nanoseconds until the next wall-clock timer is due (None: no such timer)."""
        best = None
        for node in self._nodes:
            for timer in node.timers:
                if timer._canceled or timer._is_sim():
                    continue
                wait = timer._next - timer._clock._now_ns()
                best = wait if best is None or wait < best else best
        return best

    def spin_once(self, timeout_sec=None):
        """Wait (at most ``timeout_sec``; ``None`` = until something happens) and run ready work."""
        if not self._context.ok() or self._is_shutdown:
            raise ExternalShutdownException()
        try:
            if self._dirty:
                self._sync()
            timeout = _DDS_INFINITY if timeout_sec is None else max(0, int(timeout_sec * 1e9))
            due = self._next_timer_ns()
            if due is not None:
                timeout = max(0, min(timeout, due))
            intra = self._context._intra
            if intra is not None:
                intra.spinning_thread = threading.get_ident()
                if intra.pending:   # messages delivered in process are waiting: just poll DDS
                    timeout = 0
            triggered = self._triggered
            n = _wait_for_work(self._waitset._ref, triggered, timeout)
            if n < 0:
                raise RuntimeError(f'waiting in the wait set failed (DDS error {n})')
            ready = triggered[:min(n, len(triggered))]
            if _GUARD_ARG in ready:
                self._context._guard.take()
        except Exception:
            if not self._context.ok():  # shut down (e.g. SIGTERM) while getting ready to wait
                raise ExternalShutdownException() from None
            raise
        if not self._context.ok():
            raise ExternalShutdownException()
        self._dispatch(ready)

    def _dispatch(self, ready=None):
        """Run the callbacks of the subscriptions whose attach arguments are in ``ready`` (all
        triggered ones if None), in node/subscription order, then the due timers."""
        by_arg = self._by_arg
        attached = self._attached
        if ready is None:
            subs = [s for n in list(self._nodes) for s in list(n.subscriptions)
                    if id(s) in attached and s._condition.is_triggered()]
        else:
            subs = [by_arg[a] for a in ready if a in by_arg]
        from_dds = {id(s) for s in subs}
        intra = self._context._intra
        if intra is not None and intra.pending:
            subs += [s for s in intra.take_pending(lambda s: id(s) in attached) if id(s) not in from_dds]
        if len(subs) > 1:
            rank = self._rank
            subs.sort(key=lambda s: rank.get(id(s), 0))
        for sub in subs:
            # destroyed, or its node removed, by an earlier callback of this round
            if id(sub) not in attached or (self._dirty and sub._node not in self._nodes):
                continue
            callback = sub.callback
            for msg in sub._take_messages(id(sub) in from_dds):
                callback(msg)
        for node in list(self._nodes):
            for timer in list(node.timers):
                timer._fire_if_due()

    def spin(self):
        while self._context.ok() and not self._is_shutdown:
            self.spin_once()
        if not self._context.ok():
            raise ExternalShutdownException()

    def spin_until_future_complete(self, future, timeout_sec=None):
        end = None if timeout_sec is None else time.monotonic() + timeout_sec
        while self._context.ok() and not future.done():
            remaining = None if end is None else end - time.monotonic()
            if remaining is not None and remaining <= 0:
                return
            self.spin_once(timeout_sec=remaining)

    def wake(self):
        self._context.wake()

    def shutdown(self, timeout_sec=None) -> bool:
        self._is_shutdown = True
        self._context.wake()
        with self._lock:
            for node in list(self._nodes):
                self.remove_node(node)
            self._waitset = None
            self._attached.clear()
            self._by_arg.clear()
        return True


class SingleThreadedExecutor(Executor):
    """``rclpy.executors.SingleThreadedExecutor``."""


class MultiThreadedExecutor(Executor):
    """Accepts ``num_threads`` for rclpy compatibility; callbacks run one at a time in the spinning thread."""

    def __init__(self, num_threads=None, *, context=None):
        super().__init__(context=context)
        self.num_threads = num_threads


_global_executor = []


def get_global_executor() -> Executor:
    if not _global_executor:
        _global_executor.append(SingleThreadedExecutor())
    return _global_executor[0]


def spin(node, executor=None):
    """``rclpy.spin``: run ``node``'s callbacks until shutdown."""
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        while executor.context.ok():
            executor.spin_once()
    finally:
        executor.remove_node(node)


def spin_once(node, *, executor=None, timeout_sec=None):
    """``rclpy.spin_once``: wait at most ``timeout_sec`` and run the ready callbacks."""
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        executor.spin_once(timeout_sec=timeout_sec)
    finally:
        executor.remove_node(node)


def spin_until_future_complete(node, future, executor=None, timeout_sec=None):
    executor = get_global_executor() if executor is None else executor
    try:
        executor.add_node(node)
        executor.spin_until_future_complete(future, timeout_sec)
    finally:
        executor.remove_node(node)
