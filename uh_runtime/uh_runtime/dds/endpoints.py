"""A node's entities on the Cyclone DDS backend: ``Publisher``, ``Subscription``, ``Timer``.

Mirrors ``rclpy.publisher``, ``rclpy.subscription`` and ``rclpy.timer``. A publisher writes the
CDR bytes of a message (generated codecs, :mod:`uh_runtime.dds.cdr`) padded to a multiple of 4 bytes
as rmw_cyclonedds sends them, and hands the message itself to the subscriptions of this process
(:mod:`uh_runtime.dds.intra_process`); a subscription takes every available sample of its reader in one
batch; a timer fires on its node's clock with rcl's rule for missed periods. Nodes create them
(:mod:`uh_runtime.dds.node`), executors run their callbacks.
"""
import collections

from .. import messages as _messages
from . import intra_process as _intra
from .binding import matched_publications, matched_subscriptions, raw_take
from .clock import ROSClock
from .qos import DDS_INFINITY, DurabilityPolicy, HistoryPolicy

__all__ = ['Publisher', 'Subscription', 'Timer']

_TAKE_BATCH = 256
_PAD4 = [b'', b'\0', b'\0\0', b'\0\0\0']


class Publisher:
    """``rclpy.publisher.Publisher``: ``publish(msg)``, ``topic_name``, ``get_subscription_count()``.

    Made by :meth:`Node.create_publisher <uh_runtime.dds.node.Node.create_publisher>` around
    its DDS ``writer``.
    """

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
        """The resolved topic name, as rclpy's ``Publisher.topic``."""
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
        """Return the number of matched readers plus the subscriptions of this process it feeds directly.

        The matched readers are those of the DDS publication-matched status.
        """
        return len(matched_subscriptions(self._writer)) + len(self._local)

    def wait_for_all_acked(self, timeout=None) -> bool:
        """Wait until every reliable reader acknowledged what was written; return whether they did.

        ``timeout`` as rclpy's: a ``Duration``, negative (or None) for no limit.
        """
        ns = -1 if timeout is None else timeout.nanoseconds
        ns = DDS_INFINITY if ns < 0 else ns
        try:
            self._writer.wait_for_acks(ns)
            return True
        except Exception:
            return False

    def destroy(self):
        """Destroy the publisher through its node, as rclpy's ``Publisher.destroy`` does."""
        self._node.destroy_publisher(self)


class Subscription:
    """``rclpy.subscription.Subscription``; the callback gets a message (or CDR bytes if ``raw``).

    Made by :meth:`Node.create_subscription <uh_runtime.dds.node.Node.create_subscription>`
    around its DDS ``reader``.
    """

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
        from .cdr import codec
        self._take = raw_take()     # cyclonedds' ddspy_take (dds/binding.py)
        self._codec = codec(msg_type)
        self._deserialize = self._codec.deserialize
        self._inbox = _intra.Inbox(qos_profile)   # messages from publishers of this process

    @property
    def topic(self):
        """The resolved topic name, as rclpy's ``Subscription.topic``."""
        return self.topic_name

    def get_publisher_count(self) -> int:
        """Return the number of matched DDS writers plus the publishers of this process feeding it directly.

        As rclpy's ``Subscription.get_publisher_count``.
        """
        local = self._node._context._intra
        return len(matched_publications(self._reader)) + (
            local.local_publisher_count(self) if local is not None else 0)

    def _take_messages(self, from_dds=True):
        """Take every available sample in one batch (raw CDR bytes or deserialised messages).

        Those of DDS (if ``from_dds``) come first, then those delivered in process.
        """
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
        """Destroy the subscription through its node, as rclpy's ``Subscription.destroy`` does."""
        self._node.destroy_subscription(self)


class Timer:
    """``rclpy.timer.Timer`` on a node clock (wall or sim time).

    Made by :meth:`Node.create_timer <uh_runtime.dds.node.Node.create_timer>`: ``callback()``
    every ``period_ns`` ns of ``clock``, from now (cancelled until :meth:`reset` unless ``autostart``);
    ValueError for a period that is not positive.
    """

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
        """The clock the timer runs on, as rclpy's ``Timer.clock``."""
        return self._clock

    def _is_sim(self):
        return isinstance(self._clock, ROSClock) and self._clock.ros_time_is_active

    def is_canceled(self):
        """Return whether the timer is cancelled, as rclpy's ``Timer.is_canceled`` does."""
        return self._canceled

    def is_ready(self):
        """Return whether the timer runs and its next call is due on its clock, as rclpy's ``Timer.is_ready`` does."""
        return not self._canceled and self._clock._now_ns() >= self._next

    def cancel(self):
        """Stop the timer until :meth:`reset`, as rclpy's ``Timer.cancel`` does."""
        self._canceled = True

    def reset(self):
        """Restart the timer, a full period from now (waking a spinning executor), as rclpy's ``Timer.reset`` does."""
        self._canceled = False
        self._next = self._clock._now_ns() + self.timer_period_ns
        # a spinning executor recomputes its wait from the timers at every round: wake it (cheap)
        # rather than mark its entities changed
        self._node._context.wake()

    def time_until_next_call(self):
        """Return the ns until the next call (negative when overdue), None when cancelled; as rclpy's."""
        if self._canceled:
            return None
        return self._next - self._clock._now_ns()

    def time_since_last_call(self):
        """Return the ns since the last call on the timer's clock, None before the first call."""
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
        """Destroy the timer through its node, as rclpy's ``Timer.destroy`` does."""
        self._node.destroy_timer(self)
