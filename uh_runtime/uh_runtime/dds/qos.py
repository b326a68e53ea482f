"""QoS profiles of the Cyclone DDS backend, their DDS mapping, and the one translation from the project's QoS words.

The profiles are an ``rclpy.qos`` subset.

The DDS mapping is the one of rmw_cyclonedds_cpp's ``create_readwrite_qos`` (Jazzy): keep-last
depth N or keep-all; reliable (max blocking time infinite) or best effort; volatile or
transient-local (with a durability service of the same history); deadline and lifespan only when
given; automatic liveliness; auto-dispose of unregistered instances off; XCDR1 data
representation; USER_DATA ``typehash=RIHS01_<hex>;``.

The project's QoS words are rosbag2's spelling of a profile in a bag's ``offered_qos_profiles``
(``reliable``/``best_effort``, ``volatile``/``transient_local``, ``keep_last``/``keep_all``, a
depth), which the topic registry (``uh_wire.topics``) uses too. :class:`QoSWords` holds them;
:func:`profile_from_words` makes the active backend's ``QoSProfile`` of them, :func:`words_of` reads
them from a profile, :func:`qos_profile_yaml` writes the ``offered_qos_profiles`` YAML and
:func:`parse_offered_qos` reads it back.
"""
import enum
from dataclasses import dataclass

from ..backend import select_backend

__all__ = [
    'QoSProfile', 'ReliabilityPolicy', 'DurabilityPolicy', 'HistoryPolicy', 'LivelinessPolicy',
    'qos_profile_system_default', 'qos_profile_sensor_data', 'QoSPresetProfiles', 'to_dds_qos',
    'from_dds_qos', 'Duration', 'DDS_INFINITY', 'QoSWords', 'profile_from_words', 'words_of',
    'merge_offered', 'qos_profile_yaml', 'parse_offered_qos', 'qos_profile_rosout_default',
]

#: Cyclone DDS's ``DDS_INFINITY`` (``dds_duration_t``, ns): an infinite duration or time-out.
DDS_INFINITY = 0x7FFFFFFFFFFFFFFF
_BACKEND = select_backend()


class HistoryPolicy(enum.IntEnum):
    """``rclpy.qos.HistoryPolicy`` (the values are rmw's)."""

    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2
    UNKNOWN = 3


class ReliabilityPolicy(enum.IntEnum):
    """``rclpy.qos.ReliabilityPolicy`` (the values are rmw's)."""

    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class DurabilityPolicy(enum.IntEnum):
    """``rclpy.qos.DurabilityPolicy`` (the values are rmw's)."""

    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2
    UNKNOWN = 3
    BEST_AVAILABLE = 4


class LivelinessPolicy(enum.IntEnum):
    """``rclpy.qos.LivelinessPolicy`` (the values are rmw's)."""

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
        """The duration in integer nanoseconds (``seconds`` and ``nanoseconds`` added)."""
        return int(round(self.seconds * 1e9)) + int(self.nanoseconds)


class QoSProfile:
    """``rclpy.qos.QoSProfile(history=..., depth=..., reliability=..., durability=...)``.

    As in rclpy, ``QoSProfile(depth=10)`` means keep-last 10, reliable, volatile; giving only
    ``history=KEEP_LAST`` without ``depth`` is an error. ``liveliness``, ``deadline``, ``lifespan``,
    ``liveliness_lease_duration`` and ``avoid_ros_namespace_conventions`` are rclpy's too
    (durations as :class:`Duration` or a backend's ``Duration``; None or 0: unspecified).
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
#: rcl_qos_profile_rosout_default: keep last 1000, reliable, transient local, lifespan 10 s.
qos_profile_rosout_default = QoSProfile(depth=1000, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                                        lifespan=Duration(seconds=10.0))


class QoSPresetProfiles(enum.Enum):
    """``rclpy.qos.QoSPresetProfiles``: the system-default and sensor-data profiles by name."""

    SYSTEM_DEFAULT = qos_profile_system_default
    SENSOR_DATA = qos_profile_sensor_data


def as_profile(qos) -> QoSProfile:
    """Return ``qos`` as a ``QoSProfile``: rclpy accepts an int depth for a keep-last reliable volatile profile."""
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
    :mod:`uh_runtime.dds.intra_process` serves instead.
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


# ----------------------------------------------------------------------------------------------
# The project's QoS words (rosbag2's offered_qos_profiles spelling)
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class QoSWords:
    """A QoS profile in words.

    The defaults are ROS 2's default profile (what ``system_default`` stands for in a bag).
    """

    reliability: str = 'reliable'      # reliable | best_effort
    durability: str = 'volatile'       # volatile | transient_local
    history: str = 'keep_last'         # keep_last | keep_all
    depth: int = 10


_DEFAULT_WORDS = QoSWords()
#: Per policy, the word of each value rosbag2 writes.
_WORDS = {
    'reliability': {ReliabilityPolicy.RELIABLE: 'reliable', ReliabilityPolicy.BEST_EFFORT: 'best_effort'},
    'durability': {DurabilityPolicy.TRANSIENT_LOCAL: 'transient_local', DurabilityPolicy.VOLATILE: 'volatile'},
    'history': {HistoryPolicy.KEEP_LAST: 'keep_last', HistoryPolicy.KEEP_ALL: 'keep_all'},
}
#: Per policy, every spelling of a bag's ``offered_qos_profiles`` -> its word: the words,
#: ``system_default`` and the policy numbers (0 is the system default).
_SPELLINGS = {
    policy: {**{word: word for word in words.values()}, 'system_default': getattr(_DEFAULT_WORDS, policy),
             **{str(int(value)): word for value, word in words.items()}, '0': getattr(_DEFAULT_WORDS, policy)}
    for policy, words in _WORDS.items()
}


def profile_from_words(words):
    """Make the active backend's ``QoSProfile`` (rclpy's on the rclpy backend) of a profile in words.

    ``words`` has ``reliability``, ``durability``, ``history`` and ``depth``: a :class:`QoSWords`
    (``uh_wire.topics.QosSpec`` is this record).
    """
    if _BACKEND == 'rclpy':
        from rclpy import qos
        profile, reliability, durability, history = (
            qos.QoSProfile, qos.ReliabilityPolicy, qos.DurabilityPolicy, qos.HistoryPolicy)
    else:
        profile, reliability, durability, history = (
            QoSProfile, ReliabilityPolicy, DurabilityPolicy, HistoryPolicy)
    return profile(
        reliability=getattr(reliability, words.reliability.upper()),
        durability=getattr(durability, words.durability.upper()),
        history=getattr(history, words.history.upper()),
        depth=words.depth,
    )


def words_of(profile) -> QoSWords:
    """Return the words of a ``QoSProfile`` of either backend (e.g. a discovered publisher's).

    A policy value without a word (system default, unknown) gets the default profile's word, a depth of 0
    the default depth.
    """
    def word(policy):
        value = getattr(profile, policy)
        return _WORDS[policy].get(int(getattr(value, 'value', value)), getattr(_DEFAULT_WORDS, policy))

    return QoSWords(word('reliability'), word('durability'), word('history'),
                    int(getattr(profile, 'depth', _DEFAULT_WORDS.depth) or _DEFAULT_WORDS.depth))


def merge_offered(offered) -> QoSWords:
    """Return one profile that serves every publisher of a topic (``offered``: their :class:`QoSWords`).

    The profile is chosen as ``ros2 bag`` chooses it: reliable only if every publisher is, transient-local
    only if every publisher is, keep-all if any publisher keeps all, the largest depth.
    """
    return QoSWords(
        reliability='reliable' if all(w.reliability == 'reliable' for w in offered) else 'best_effort',
        durability='transient_local' if all(w.durability == 'transient_local' for w in offered) else 'volatile',
        history='keep_all' if any(w.history == 'keep_all' for w in offered) else 'keep_last',
        depth=max(w.depth for w in offered))


def qos_profile_yaml(reliability: str, durability: str, history: str, depth: int) -> str:
    """Return the rosbag2 ``offered_qos_profiles`` YAML for one writer's QoS.

    ``reliability`` is ``reliable``/``best_effort``, ``durability`` ``volatile``/``transient_local``,
    ``history`` ``keep_last``/``keep_all``; deadline, lifespan and lease are infinite as in ROS 2's
    defaults. The layout is the one rosbag2 on Jazzy writes (see :mod:`uh_runtime.bags.bag`).
    """
    inf = 'sec: {}\n    nsec: {}'.format(*divmod(DDS_INFINITY, 1_000_000_000))
    return (
        f'- history: {history}\n  depth: {int(depth)}\n  reliability: {reliability}\n'
        f'  durability: {durability}\n  deadline:\n    {inf}\n  lifespan:\n    {inf}\n'
        f'  liveliness: automatic\n  liveliness_lease_duration:\n    {inf}\n'
        '  avoid_ros_namespace_conventions: false'
    )


def parse_offered_qos(text: str | None) -> QoSWords:
    """Return the QoS to replay a topic with, from its rosbag2 ``offered_qos_profiles`` YAML.

    The text is a YAML list with one profile per publisher that was recorded (the layout of
    :func:`qos_profile_yaml`; rosbag2 writes the same), merged as ``ros2 bag play`` does
    (:func:`merge_offered`). An empty or missing entry gives the ROS 2 default (reliable,
    volatile, keep_last 10).

    Raises
    ------
    ValueError
        The text is not YAML, not a list of mappings, or has a policy value rosbag2 does not write
        (the message names the policy and the allowed values).
    """
    import yaml
    if text is None or not str(text).strip():
        return QoSWords()
    try:
        profiles = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f'offered_qos_profiles is not valid YAML ({exc})') from None
    if profiles in (None, []):
        return QoSWords()
    if isinstance(profiles, dict):
        profiles = [profiles]
    if not isinstance(profiles, list) or not all(isinstance(p, dict) for p in profiles):
        raise ValueError(f'offered_qos_profiles must be a list of QoS mappings, got {text[:80]!r}')
    return merge_offered([_parse_profile(profile) for profile in profiles])


def _parse_profile(profile: dict) -> QoSWords:
    """Return the words of one publisher's profile of ``offered_qos_profiles``."""
    words = {}
    for policy, spellings in _SPELLINGS.items():
        raw = str(profile.get(policy, 'system_default')).strip().lower()
        if raw not in spellings:
            choices = ', '.join(k for k in spellings if not k.isdigit())
            raise ValueError(f'offered_qos_profiles has {policy}: {raw!r}; allowed: {choices}')
        words[policy] = spellings[raw]
    try:
        depth = int(profile.get('depth', _DEFAULT_WORDS.depth) or 0)
    except (TypeError, ValueError):
        raise ValueError(f'offered_qos_profiles has depth {profile.get("depth")!r}; '
                         'expected a whole number') from None
    return QoSWords(**words, depth=depth if depth > 0 else _DEFAULT_WORDS.depth)
