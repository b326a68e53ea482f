"""Cyclone DDS network configuration for runs and tests on one machine.

Every run and every test picks its own DDS domain id, so parallel runs never see each other
(DESIGN.md section 1, "Isolation"). On a machine without multicast on loopback, discovery uses
unicast to 127.0.0.1 over a range of participant indices.
"""
import os

__all__ = ['loopback_config', 'loopback_environment', 'MAX_PARTICIPANTS']

#: Participants one domain can hold on loopback (unicast discovery probes this many port indices).
MAX_PARTICIPANTS = 120


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
        '<Peers><Peer address="127.0.0.1"/></Peers></Discovery>'
        '</Domain></CycloneDDS>'
    )


def loopback_environment(domain_id: int, base: dict | None = None) -> dict:
    """Return a copy of ``base`` (default ``os.environ``) set up for DDS domain ``domain_id`` on loopback.

    ``CYCLONEDDS_URI`` is only set when the caller has not chosen one, so a user's own
    configuration (e.g. a real network interface) wins.
    """
    if not 0 <= int(domain_id) <= 232:
        raise ValueError(f'DDS domain id {domain_id} is outside 0..232 (the range ROS 2 allows)')
    env = dict(os.environ if base is None else base)
    env['ROS_DOMAIN_ID'] = str(int(domain_id))
    env.setdefault('CYCLONEDDS_URI', loopback_config())
    return env
