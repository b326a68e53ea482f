"""DDS domain reservation (uh_runtime/network.py).

Runs, test sessions and benchmarks started at the same time on one machine never share a domain id.
"""
import subprocess
import sys

import pytest

from uh_runtime import network
from uh_runtime.network import release_domain_id, reserve_domain_id

# Holds a domain id in another process until its stdin closes.
HOLDER = r'''
import sys
from uh_runtime.network import reserve_domain_id
print(reserve_domain_id(int(sys.argv[1]), int(sys.argv[2])), flush=True)
sys.stdin.read()
'''


@pytest.fixture
def holder():
    started = []

    def hold(first, last):
        """Start a process reserving an id in first..last; return (the id it reserved, that process)."""
        proc = subprocess.Popen([sys.executable, '-P', '-c', HOLDER, str(first), str(last)],
                                stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        started.append(proc)
        return int(proc.stdout.readline()), proc
    yield hold
    for proc in started:
        proc.stdin.close()
        proc.wait(timeout=30)


def _free_pair():
    """Two adjacent ids nobody holds right now (another session on the machine may hold some)."""
    for first in range(1, network.MAX_DOMAIN_ID, 2):
        # Either id may be held already: by another process, or by this test session itself (its
        # own runs reserve ids too, from an offset drawn from the process id).
        try:
            a = reserve_domain_id(first, first)
        except RuntimeError:
            continue
        try:
            b = reserve_domain_id(first + 1, first + 1)
        except RuntimeError:
            release_domain_id(a)
            continue
        release_domain_id(a)
        release_domain_id(b)
        return first
    pytest.skip('no two adjacent free domain ids on this machine')


def test_an_id_held_by_another_process_is_skipped_and_free_again_when_it_ends(holder):
    first = _free_pair()
    held, _ = holder(first, first + 1)
    other = first + 1 if held == first else first
    # the only other id of the range is the one left
    assert reserve_domain_id(first, first + 1) == other
    with pytest.raises(RuntimeError, match=rf'every DDS domain id in {first}..{first + 1} is held'):
        reserve_domain_id(first, first + 1)
    release_domain_id(other)
    assert reserve_domain_id(other, other) == other   # released: free for this process again
    release_domain_id(other)


def test_the_holders_exit_frees_its_id(holder):
    first = _free_pair()
    held, proc = holder(first, first)
    assert held == first
    with pytest.raises(RuntimeError):
        reserve_domain_id(first, first)
    proc.kill()          # no clean-up of its own: the kernel drops the lock with the process
    proc.wait(timeout=30)
    assert reserve_domain_id(first, first) == first
    release_domain_id(first)


def test_ids_of_one_process_are_distinct_and_a_bad_range_is_refused():
    ids = [reserve_domain_id() for _ in range(5)]
    try:
        assert len(set(ids)) == 5 and all(1 <= d <= network.MAX_DOMAIN_ID for d in ids)
    finally:
        for d in ids:
            release_domain_id(d)
    with pytest.raises(ValueError, match=r'range 5..300 is not within 0..232'):
        reserve_domain_id(5, 300)


@pytest.mark.parametrize('env, expect', [
    ({}, 'loopback'),
    ({'CYCLONEDDS_URI': ''}, 'loopback'),                             # empty counts as unset
    ({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'localhost'}, 'loopback'),
    ({'CYCLONEDDS_URI': '<CycloneDDS/>'}, None),                       # the user's own stands
    ({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'}, None),                # Cyclone's default: multicast
    ({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT', 'ROS_STATIC_PEERS': '10.0.0.2'}, None),
])
def test_default_network_follows_ros_discovery_variables(env, expect):
    from uh_runtime.network import default_cyclonedds_uri, loopback_config
    got = default_cyclonedds_uri(env)
    assert got == (loopback_config() if expect == 'loopback' else expect)


def test_static_peers_and_off():
    from uh_runtime.network import default_cyclonedds_uri
    local = default_cyclonedds_uri({'ROS_STATIC_PEERS': '10.0.0.2; robot.local'})
    assert '<Peer address="127.0.0.1"/><Peer address="10.0.0.2"/><Peer address="robot.local"/>' in local
    assert '<AllowMulticast>false</AllowMulticast>' in local and 'NetworkInterface' not in local
    subnet = default_cyclonedds_uri({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET', 'ROS_STATIC_PEERS': '10.0.0.2'})
    assert '<Peer address="10.0.0.2"/>' in subnet and 'AllowMulticast' not in subnet
    off = default_cyclonedds_uri({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'OFF', 'ROS_STATIC_PEERS': '10.0.0.2'})
    assert '<Tag>ros_discovery_off_' in off and 'Peer' not in off
    with pytest.raises(ValueError, match="ROS_AUTOMATIC_DISCOVERY_RANGE='LAN'; allowed: LOCALHOST, SUBNET"):
        default_cyclonedds_uri({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LAN'})


@pytest.mark.parametrize('env, expect_range, expect_uri', [
    ({}, 'LOCALHOST', 'loopback'),
    ({'ROS_AUTOMATIC_DISCOVERY_RANGE': ' ', 'CYCLONEDDS_URI': ''}, 'LOCALHOST', 'loopback'),   # empty is unset
    ({'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET'}, 'SUBNET', None),           # the user's choice stands
    ({'CYCLONEDDS_URI': '<CycloneDDS/>'}, 'LOCALHOST', '<CycloneDDS/>'),
])
def test_the_network_default_sets_the_discovery_range_every_rmw_reads(env, expect_range, expect_uri):
    """Fast DDS ignores CYCLONEDDS_URI: the range is what makes an rclpy node on it meet the Cyclone DDS nodes."""
    from uh_runtime.network import apply_network_default, environment_script, loopback_config
    got = apply_network_default(dict(env))
    assert got['ROS_AUTOMATIC_DISCOVERY_RANGE'] == expect_range
    assert got.get('CYCLONEDDS_URI') == (loopback_config() if expect_uri == 'loopback' else expect_uri)
    script = environment_script({**got, 'ROS_DOMAIN_ID': '7'})
    assert f'export ROS_AUTOMATIC_DISCOVERY_RANGE={expect_range}\n' in script
    assert 'export ROS_DOMAIN_ID=7\n' in script


def test_a_sourced_environment_script_gives_a_shell_the_runs_domain_and_discovery(tmp_path):
    from uh_runtime.network import environment_script, loopback_environment
    (tmp_path / 'env.sh').write_text(environment_script(loopback_environment(42, base={})))
    shown = subprocess.run(['env', '-i', 'bash', '-c', f'source {tmp_path / "env.sh"} && env'],
                           capture_output=True, text=True, check=True).stdout.splitlines()
    assert 'ROS_DOMAIN_ID=42' in shown and 'ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST' in shown
    assert any(line.startswith('CYCLONEDDS_URI=<CycloneDDS>') for line in shown)


def test_a_mixed_team_names_the_processes_on_cyclone_dds_and_only_existing_ones():
    from uh_bringup.run_checks import UsageError
    from uh_bringup.run_setup import dds_processes
    names = ['recorder', 'uh1', 'uh2', 'team']
    assert dds_processes({'UH_DDS_PROCESSES': ' uh2, team ,'}, names) == {'uh2', 'team'}
    assert dds_processes({}, names) == set()
    with pytest.raises(UsageError, match='UH_DDS_PROCESSES names uh3, which this run does not start; '
                                         'its processes: recorder, uh1, uh2, team'):
        dds_processes({'UH_DDS_PROCESSES': 'uh3,uh1'}, names)


def test_every_local_configuration_repeats_discovery_every_second():
    """Local configurations announce each participant to every port index once a second.

    A Fast DDS process started later announces itself to participant indices 0..3 only; the team's other
    participants find it by their own announcements (docs/ros2.md#discovery-from-fast-dds).
    """
    from uh_runtime.network import SPDP_INTERVAL_XML, default_cyclonedds_uri, loopback_config
    assert SPDP_INTERVAL_XML == '<SPDPInterval>1 s</SPDPInterval>'
    for config in (loopback_config(), default_cyclonedds_uri({'ROS_STATIC_PEERS': '10.0.0.2'})):
        discovery = config.split('<Discovery>')[1].split('</Discovery>')[0]
        assert SPDP_INTERVAL_XML in discovery and '<Peer address="127.0.0.1"/>' in discovery, config


def test_reserved_domain_ids_keep_every_port_of_every_participant_index_in_16_bits():
    # ROS 2's port mapping: 7400 + 250 d + 10 + 2 i (discovery), + 11 (data), i up to MAX_PARTICIPANTS
    def highest_port(domain):
        return 7400 + 250 * domain + 11 + 2 * network.MAX_PARTICIPANTS
    top = network.MAX_RESERVED_DOMAIN_ID
    assert highest_port(top) <= 65535 < highest_port(top + 1)
    assert top < network.MAX_DOMAIN_ID          # 232 is valid for ROS 2 but not with 120 indices on loopback
    import inspect
    assert inspect.signature(reserve_domain_id).parameters['last'].default == top   # what is handed out by default
