"""DDS network configuration for runs and tests on one machine, for Cyclone DDS and Fast DDS alike.

Every run and every test picks its own DDS domain id, so parallel runs never see each other
(docs/architecture.md#isolation-of-runs). On a machine without multicast on loopback, discovery uses
unicast to 127.0.0.1 over a range of participant indices.

:func:`reserve_domain_id` hands out domain ids that no other cooperating process on the machine
holds (a test session, a benchmark, a run started without ``--domain-id``), so that two of them
running at once never share a domain.
"""
import errno
import fcntl
import itertools
import os
import tempfile

__all__ = ['loopback_config', 'loopback_environment', 'environment_script', 'default_cyclonedds_uri',
           'apply_network_default', 'DISCOVERY_RANGES', 'reserve_domain_id', 'release_domain_id',
           'MAX_PARTICIPANTS', 'MAX_DOMAIN_ID', 'MAX_RESERVED_DOMAIN_ID', 'SPDP_INTERVAL_XML']

#: Largest DDS domain id ROS 2 allows (Cyclone's default port mapping ends there).
MAX_DOMAIN_ID = 232

#: Participants one domain can hold on loopback (unicast discovery probes this many port indices).
MAX_PARTICIPANTS = 120

#: Largest domain id :func:`reserve_domain_id` hands out: the highest whose every port fits in 16 bits
#: for :data:`MAX_PARTICIPANTS` participant indices. ROS 2's port mapping puts participant i of domain d
#: on 7400 + 250 d + 10 + 2 i (discovery) and + 11 (data); for domain 232 the indices above 62 would
#: be ports above 65535, to which Cyclone DDS's unicast discovery then fails to send, and says so on
#: stderr (measured: a test's one-line error came with those lines).
MAX_RESERVED_DOMAIN_ID = (65535 - 7400 - 11 - 2 * MAX_PARTICIPANTS) // 250

#: Cyclone DDS setting: a participant announces itself (SPDP) to every peer port index once a second.
#: A Fast DDS process started later (rclpy on ROS 2 Jazzy's default RMW, in a second terminal)
#: announces itself only to participant indices 0..3 (Fast DDS's ``maxInitialPeersRange`` of 4), so
#: a team participant with a higher index must find it by its own announcements. Measured
#: (docs/ros2.md#discovery-from-fast-dds): a Fast DDS process listed every node of a running team
#: after 1.4-4.0 s with Cyclone's default interval, 0.4-1.2 s with this one. The cost: each
#: participant sends ``MAX_PARTICIPANTS + 1`` small datagrams a second on loopback.
SPDP_INTERVAL_XML = '<SPDPInterval>1 s</SPDPInterval>'


def loopback_config(max_participants: int = MAX_PARTICIPANTS) -> str:
    """Return a ``CYCLONEDDS_URI`` value that keeps all traffic on the loopback interface.

    Multicast is off; participants find each other by unicast SPDP to 127.0.0.1 on the port
    indices ``0 .. max_participants``, so up to that many processes can join one domain.
    """
    return (
        '<CycloneDDS><Domain id="any"><General>'
        '<Interfaces><NetworkInterface name="lo"/></Interfaces>'
        '<AllowMulticast>false</AllowMulticast></General>'
        '<Discovery><ParticipantIndex>auto</ParticipantIndex>'
        f'<MaxAutoParticipantIndex>{int(max_participants)}</MaxAutoParticipantIndex>'
        f'{SPDP_INTERVAL_XML}<Peers><Peer address="127.0.0.1"/></Peers></Discovery>'
        '</Domain></CycloneDDS>'
    )


#: ``ROS_AUTOMATIC_DISCOVERY_RANGE`` values (ROS 2 Jazzy); the project's tools take ``LOCALHOST``
#: when it is not set (ROS 2's own default is ``SUBNET``): a run stays on this machine unless asked.
DISCOVERY_RANGES = ('LOCALHOST', 'SUBNET', 'OFF', 'SYSTEM_DEFAULT')


def default_cyclonedds_uri(env: dict | None = None) -> str | None:
    """Return the ``CYCLONEDDS_URI`` the project's commands use when the user has not set one.

    An empty value counts as not set. The choice follows ROS 2's discovery variables as rmw_cyclonedds
    maps them (docs/architecture.md#isolation-of-runs):

    - ``ROS_AUTOMATIC_DISCOVERY_RANGE`` unset or ``LOCALHOST``: :func:`loopback_config` (loopback
      only, no multicast, unicast discovery on this machine), plus the ``ROS_STATIC_PEERS``
      (``;``-separated addresses) as peers, in which case the interface is not restricted;
    - ``SUBNET``: Cyclone's default (multicast), plus the static peers;
    - ``SYSTEM_DEFAULT``: Cyclone's default, peers ignored;
    - ``OFF``: no discovery at all (no multicast, no peers, a tag of this process).

    Returns None when Cyclone's own default applies or the user's ``CYCLONEDDS_URI`` stands.
    """
    env = os.environ if env is None else env
    if env.get('CYCLONEDDS_URI', '').strip():
        return None
    scope = env.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '').strip().upper() or 'LOCALHOST'
    if scope not in DISCOVERY_RANGES:
        raise ValueError(f'ROS_AUTOMATIC_DISCOVERY_RANGE={env["ROS_AUTOMATIC_DISCOVERY_RANGE"]!r}; '
                         f'allowed: {", ".join(DISCOVERY_RANGES)}')
    peers = [p.strip() for p in env.get('ROS_STATIC_PEERS', '').split(';') if p.strip()]
    peer_xml = ''.join(f'<Peer address="{p}"/>' for p in peers)
    if scope == 'LOCALHOST' and not peers:
        return loopback_config()
    if scope == 'LOCALHOST':
        return ('<CycloneDDS><Domain id="any"><General><AllowMulticast>false</AllowMulticast></General>'
                '<Discovery><ParticipantIndex>auto</ParticipantIndex>'
                f'<MaxAutoParticipantIndex>{MAX_PARTICIPANTS}</MaxAutoParticipantIndex>{SPDP_INTERVAL_XML}'
                f'<Peers><Peer address="127.0.0.1"/>{peer_xml}</Peers></Discovery></Domain></CycloneDDS>')
    if scope == 'SUBNET':
        return (f'<CycloneDDS><Domain id="any"><Discovery><Peers>{peer_xml}</Peers></Discovery></Domain>'
                '</CycloneDDS>') if peers else None
    if scope == 'OFF':
        return ('<CycloneDDS><Domain id="any"><General><AllowMulticast>false</AllowMulticast></General>'
                '<Discovery><ParticipantIndex>none</ParticipantIndex>'
                f'<Tag>ros_discovery_off_{os.getpid()}</Tag></Discovery></Domain></CycloneDDS>')
    return None


def apply_network_default(env: dict | None = None) -> dict:
    """Give ``env`` (default ``os.environ``) the project's discovery settings for every DDS vendor; return ``env``.

    ``ROS_AUTOMATIC_DISCOVERY_RANGE`` becomes ``LOCALHOST`` when it is not set (empty counts as not
    set): rmw_fastrtps and rmw_cyclonedds read it, and ROS 2's own default, ``SUBNET``, would have an
    rclpy node on Fast DDS announce addresses that the loopback-only Cyclone DDS configuration of
    the project's other nodes never reaches, so the two would not meet. ``CYCLONEDDS_URI`` is set to
    :func:`default_cyclonedds_uri` when that is not None (the user has not set one), which follows the
    same range for the Cyclone DDS backend. What ``uh``, the scripts and the runs do first.
    """
    env = os.environ if env is None else env
    uri = default_cyclonedds_uri(env)
    if not env.get('ROS_AUTOMATIC_DISCOVERY_RANGE', '').strip():
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    if uri is not None:
        env['CYCLONEDDS_URI'] = uri
    return env


def loopback_environment(domain_id: int, base: dict | None = None) -> dict:
    """Return a copy of ``base`` (default ``os.environ``) set up for DDS domain ``domain_id``.

    The copy has the project's network default (:func:`apply_network_default`: loopback only unless
    ``CYCLONEDDS_URI``, ``ROS_AUTOMATIC_DISCOVERY_RANGE`` or ``ROS_STATIC_PEERS`` say otherwise).
    """
    if not 0 <= int(domain_id) <= MAX_DOMAIN_ID:
        raise ValueError(f'DDS domain id {domain_id} is outside 0..{MAX_DOMAIN_ID} (the range ROS 2 allows)')
    env = dict(os.environ if base is None else base)
    env['ROS_DOMAIN_ID'] = str(int(domain_id))
    return apply_network_default(env)


def environment_script(env: dict) -> str:
    """Return a POSIX shell script that exports the ``ROS_DOMAIN_ID`` and discovery settings of ``env``.

    ``CYCLONEDDS_URI`` for Cyclone DDS, ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (and ``ROS_STATIC_PEERS``)
    for Fast DDS and every other RMW: a second terminal that sources it (``ros2 topic list``, ``uh
    topic list``) joins the same DDS domain with the same discovery settings, whichever RMW it uses.
    """
    import shlex
    lines = ['# source this file to reach the run from another terminal (ros2 CLI, uh CLI)']
    for key in ('ROS_DOMAIN_ID', 'CYCLONEDDS_URI', 'ROS_AUTOMATIC_DISCOVERY_RANGE', 'ROS_STATIC_PEERS'):
        if env.get(key):
            lines.append(f'export {key}={shlex.quote(env[key])}')
    return '\n'.join(lines) + '\n'


_held: dict = {}          # domain id -> open lock file descriptor of this process
_reservations = itertools.count()


def _lock_path(domain_id: int) -> str:
    return os.path.join(tempfile.gettempdir(), f'uh-dds-domain-{domain_id}.lock')


def reserve_domain_id(first: int = 1, last: int = MAX_RESERVED_DOMAIN_ID) -> int:
    """Claim a DDS domain id in ``first .. last`` that no other process on this machine holds.

    The claim is an exclusive ``flock`` on ``<tmp>/uh-dds-domain-<id>.lock``, kept until
    :func:`release_domain_id` or the end of this process (the kernel drops it then, also after a
    crash). The default range ends at :data:`MAX_RESERVED_DOMAIN_ID` (231), whose ports all fit.
    The search starts at an offset drawn from the process id, so concurrent processes
    rarely even try the same id. Only processes that reserve take part: an explicit
    ``--domain-id`` or ``ROS_DOMAIN_ID`` is used as given.

    Raises
    ------
    RuntimeError
        Every id of the range is held.
    """
    if not 0 <= first <= last <= MAX_DOMAIN_ID:
        raise ValueError(f'domain id range {first}..{last} is not within 0..{MAX_DOMAIN_ID}')
    size = last - first + 1
    offset = os.getpid() * 7 + next(_reservations)
    for i in range(size):
        domain = first + (offset + i) % size
        if domain in _held:
            continue
        try:
            fd = os.open(_lock_path(domain), os.O_RDWR | os.O_CREAT, 0o666)
        except OSError:
            continue          # e.g. a lock file of another user that this one may not open
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                continue      # held by another process
            raise
        _held[domain] = fd
        return domain
    raise RuntimeError(f'every DDS domain id in {first}..{last} is held by another process on this machine '
                       f'(lock files {_lock_path(first)} ..); stop some runs or pass --domain-id')


def release_domain_id(domain_id: int) -> None:
    """Give back a domain id taken with :func:`reserve_domain_id` (nothing happens for others)."""
    fd = _held.pop(domain_id, None)
    if fd is not None:
        os.close(fd)
