"""Time on the Cyclone DDS backend: ``Time``, ``Duration``, ``Clock``, ``ROSClock``, ``ClockType``.

Mirrors ``rclpy.time``, ``rclpy.duration`` and ``rclpy.clock`` (Jazzy): times and durations are
integer nanoseconds; a ``ROSClock`` is system time, or the last ``/clock`` value while sim time is
active (the node's TimeSource sets it, see :mod:`uh_runtime.dds.node`).
"""
import time

from .. import messages as _messages

__all__ = ['ClockType', 'Duration', 'Time', 'Clock', 'ROSClock']


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
        """The duration in integer nanoseconds, as rclpy's ``Duration.nanoseconds``."""
        return self._ns

    def to_msg(self):
        """Return a ``builtin_interfaces/msg/Duration`` (sec, nanosec), as rclpy's ``Duration.to_msg`` does."""
        msg = _messages.dds_message('builtin_interfaces/msg/Duration')()
        msg.sec, msg.nanosec = divmod(self._ns, 1_000_000_000)
        return msg

    @classmethod
    def from_msg(cls, msg):
        """Return the Duration of a ``builtin_interfaces/msg/Duration``, as rclpy's ``Duration.from_msg`` does."""
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
        """The time in integer nanoseconds since its clock's epoch, as rclpy's ``Time.nanoseconds``."""
        return self._ns

    @property
    def clock_type(self):
        """The :class:`ClockType` of the time, as rclpy's ``Time.clock_type``."""
        return self._clock_type

    def seconds_nanoseconds(self):
        """(seconds, nanoseconds) with 0 <= nanoseconds < 1e9."""
        return divmod(self._ns, 1_000_000_000)

    def to_msg(self):
        """Return a ``builtin_interfaces/msg/Time`` (sec, nanosec), as rclpy's ``Time.to_msg`` does."""
        msg = _messages.dds_message('builtin_interfaces/msg/Time')()
        msg.sec, msg.nanosec = divmod(self._ns, 1_000_000_000)
        return msg

    @classmethod
    def from_msg(cls, msg, clock_type=ClockType.ROS_TIME):
        """Return the Time of a ``builtin_interfaces/msg/Time`` (ROS time by default), as rclpy's ``Time.from_msg``."""
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
    """``rclpy.clock.Clock(clock_type=ClockType.SYSTEM_TIME)``: system, steady or ROS time."""

    def __init__(self, *, clock_type=ClockType.SYSTEM_TIME):
        self._clock_type = clock_type

    @property
    def clock_type(self):
        """The :class:`ClockType` of the clock, as rclpy's ``Clock.clock_type``."""
        return self._clock_type

    def _now_ns(self) -> int:
        if self._clock_type == ClockType.STEADY_TIME:
            return time.monotonic_ns()
        return time.time_ns()

    def now(self) -> Time:
        """Return the current :class:`Time` of the clock, as rclpy's ``Clock.now`` does."""
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
        """Whether the clock gives sim time (the latest ``/clock``) instead of system time, as in rclpy."""
        return self._active

    def _set_ros_time_is_active(self, active: bool):
        self._active = bool(active)

    def _set_ros_time(self, ns: int):
        self._override_ns = int(ns)

    def _now_ns(self) -> int:
        return self._override_ns if self._active else time.time_ns()

