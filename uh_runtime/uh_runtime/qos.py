"""QoS profiles of the Cyclone DDS backend (``rclpy.qos`` subset) and their DDS mapping.

The mapping is the one of rmw_cyclonedds_cpp's ``create_readwrite_qos`` (Jazzy): keep-last depth
N or keep-all; reliable (max blocking time infinite) or best effort; volatile or transient-local
(with a durability service of the same history); deadline and lifespan only when given; automatic
liveliness; auto-dispose of unregistered instances off; XCDR1 data representation; USER_DATA
``typehash=RIHS01_<hex>;``.
"""
import enum
from dataclasses import dataclass

__all__ = [
    'QoSProfile', 'ReliabilityPolicy', 'DurabilityPolicy', 'HistoryPolicy', 'LivelinessPolicy',
    'qos_profile_system_default', 'qos_profile_sensor_data', 'QoSPresetProfiles', 'to_dds_qos',
    'from_dds_qos', 'Duration',
]


class HistoryPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2
    UNKNOWN = 3


class ReliabilityPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class DurabilityPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class LivelinessPolicy(enum.IntEnum):
    SYSTEM_DEFAULT = 0
    AUTOMATIC = 1
    MANUAL_BY_TOPIC = 3
    UNKNOWN = 4
    BEST_AVAILABLE = 5


@dataclass(frozen=True)
class Duration:
    """Minimal ``rclpy.duration.Duration`` stand-in used for QoS durations (0 = unspecified)."""

    seconds: float = 0.0
    nanoseconds: int = 0

    @property
    def total_nanoseconds(self) -> int:
        return int(round(self.seconds * 1e9)) + int(self.nanoseconds)


class QoSProfile:
    """``rclpy.qos.QoSProfile(history=..., depth=..., reliability=..., durability=...)``.

    As in rclpy, ``QoSProfile(depth=10)`` means keep-last 10, reliable, volatile; giving only
    ``history=KEEP_LAST`` without ``depth`` is an error.
    """

    __slots__ = ('history', 'depth', 'reliability', 'durability', 'liveliness', 'deadline',
                 'lifespan', 'liveliness_lease_duration', 'avoid_ros_namespace_conventions')

    def __init__(self, *, history=None, depth=None, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.VOLATILE, liveliness=LivelinessPolicy.SYSTEM_DEFAULT,
                 deadline=None, lifespan=None, liveliness_lease_duration=None,
                 avoid_ros_namespace_conventions=False):
        if history is None:
            if depth is None:
                raise ValueError('QoSProfile needs a history policy or a depth (e.g. depth=10)')
            history = HistoryPolicy.KEEP_LAST
        if history == HistoryPolicy.KEEP_LAST and depth is None:
            raise ValueError('QoSProfile: history KEEP_LAST needs a depth')
        if depth is not None and int(depth) < 0:
            raise ValueError(f'QoSProfile: depth {depth} must be >= 0')
        self.history = HistoryPolicy(history)
        self.depth = int(depth) if depth is not None else 0
        self.reliability = ReliabilityPolicy(reliability)
        self.durability = DurabilityPolicy(durability)
        self.liveliness = LivelinessPolicy(liveliness)
        self.deadline = deadline
        self.lifespan = lifespan
        self.liveliness_lease_duration = liveliness_lease_duration
        self.avoid_ros_namespace_conventions = avoid_ros_namespace_conventions

    def __eq__(self, other):
        return isinstance(other, QoSProfile) and all(
            getattr(self, k) == getattr(other, k) for k in self.__slots__)

    def __repr__(self):
        return (f'QoSProfile(history={self.history.name}, depth={self.depth}, '
                f'reliability={self.reliability.name}, durability={self.durability.name})')


qos_profile_system_default = QoSProfile(history=HistoryPolicy.SYSTEM_DEFAULT, depth=0,
                                        reliability=ReliabilityPolicy.SYSTEM_DEFAULT,
                                        durability=DurabilityPolicy.SYSTEM_DEFAULT)
qos_profile_sensor_data = QoSProfile(depth=5, reliability=ReliabilityPolicy.BEST_EFFORT)
qos_profile_clock = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


class QoSPresetProfiles(enum.Enum):
    SYSTEM_DEFAULT = qos_profile_system_default
    SENSOR_DATA = qos_profile_sensor_data


def as_profile(qos) -> QoSProfile:
    """rclpy accepts an int depth for a keep-last reliable volatile profile."""
    if isinstance(qos, QoSProfile):
        return qos
    if isinstance(qos, int) and not isinstance(qos, bool):
        return QoSProfile(depth=qos)
    if isinstance(qos, QoSPresetProfiles):
        return qos.value
    raise TypeError(f'{qos!r} is not a QoSProfile or a history depth (int)')


def _ns(duration) -> int | None:
    if duration is None:
        return None
    ns = getattr(duration, 'nanoseconds', None)
    if hasattr(duration, 'total_nanoseconds'):
        ns = duration.total_nanoseconds
    return int(ns) if ns else None


def to_dds_qos(profile: QoSProfile, user_data: bytes | None = None, ignore_local: bool = False):
    """``cyclonedds.qos.Qos`` for a reader/writer with this profile (rmw_cyclonedds mapping).

    ``ignore_local``: Cyclone's ``IgnoreLocal(Participant)`` (what rmw_cyclonedds sets for
    ``ignore_local_publications``): no match with endpoints of the same participant, which
    :mod:`uh_runtime.intra_process` serves instead.
    """
    from cyclonedds.qos import Policy, Qos
    from cyclonedds.util import duration
    policies = []
    if profile.history == HistoryPolicy.KEEP_ALL:
        history = Policy.History.KeepAll
    else:
        history = Policy.History.KeepLast(profile.depth if profile.depth > 0 else 1)
    policies.append(history)
    if profile.reliability == ReliabilityPolicy.BEST_EFFORT:
        policies.append(Policy.Reliability.BestEffort)
    else:
        policies.append(Policy.Reliability.Reliable(max_blocking_time=duration(infinite=True)))
    if profile.durability == DurabilityPolicy.TRANSIENT_LOCAL:
        policies.append(Policy.Durability.TransientLocal)
        policies.append(Policy.DurabilityService(
            cleanup_delay=0, history=history, max_samples=-1, max_instances=-1,
            max_samples_per_instance=-1))
    else:
        policies.append(Policy.Durability.Volatile)
    lifespan, deadline = _ns(profile.lifespan), _ns(profile.deadline)
    if lifespan:
        policies.append(Policy.Lifespan(lifespan))
    if deadline:
        policies.append(Policy.Deadline(deadline))
    lease = _ns(profile.liveliness_lease_duration)
    lease = lease if lease else duration(infinite=True)
    if profile.liveliness == LivelinessPolicy.MANUAL_BY_TOPIC:
        policies.append(Policy.Liveliness.ManualByTopic(lease))
    else:
        policies.append(Policy.Liveliness.Automatic(lease))
    policies.append(Policy.WriterDataLifecycle(autodispose=False))
    policies.append(Policy.DataRepresentation(use_cdrv0_representation=True))
    if user_data is not None:
        policies.append(Policy.Userdata(user_data))
    if ignore_local:
        policies.append(Policy.IgnoreLocal.Participant)
    return Qos(*policies)


def from_dds_qos(qos) -> QoSProfile:
    """ROS profile of a discovered endpoint's DDS QoS (for ``uh topic info -v`` and echo)."""
    from cyclonedds.qos import Policy
    history = HistoryPolicy.KEEP_LAST
    depth = 1
    reliability = ReliabilityPolicy.RELIABLE
    durability = DurabilityPolicy.VOLATILE
    for policy in qos:
        if isinstance(policy, Policy.History.KeepLast):
            depth = policy.depth
        elif policy == Policy.History.KeepAll:
            history, depth = HistoryPolicy.KEEP_ALL, 0
        elif policy == Policy.Reliability.BestEffort:
            reliability = ReliabilityPolicy.BEST_EFFORT
        elif policy == Policy.Durability.TransientLocal:
            durability = DurabilityPolicy.TRANSIENT_LOCAL
    return QoSProfile(history=history, depth=depth, reliability=reliability, durability=durability)
