"""A team over a real (virtual) network, one network namespace per helicopter.

The namespaces are joined by veth pairs and a bridge, with random loss by nftables (uh_bringup.netns,
run_formation.sh --hosts netns --loss PCT).

Needs root (CAP_NET_ADMIN) and iproute2; the loss tests also need nftables, which is installed with
apt-get when missing. Elsewhere every test here is skipped with the reason.
"""
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from team_runs import kill_session

from uh_bringup import netns
from uh_runtime.network import reserve_domain_id

ROOT = Path(__file__).resolve().parents[1]
RUN = ROOT / 'scripts' / 'run_formation.sh'


def _why_not() -> str | None:
    """Why this machine cannot run the namespace tests (None if it can)."""
    try:
        netns.check_available(0.0)
    except netns.NetnsError as exc:
        return str(exc)
    return None


def _why_no_nft() -> str | None:
    if shutil.which('nft'):
        return None
    if shutil.which('apt-get'):
        subprocess.run(['apt-get', 'install', '-y', '-q', 'nftables'], capture_output=True, timeout=300)
        if shutil.which('nft'):
            return None
    return 'nftables (the nft command) is not installed and apt-get could not install it'


REASON = _why_not()
pytestmark = [pytest.mark.skipif(REASON is not None, reason=f'network namespaces unavailable: {REASON}')]


@pytest.fixture(scope='module')
def nft():
    reason = _why_no_nft()
    if reason:
        pytest.skip(reason)


def _namespaces(tag: str) -> list:
    return [n for n in netns.list_namespaces() if n.startswith(tag + '-')]


def _udp_delivery(net, src: str, dst: str, count: int = 2000) -> float:
    """Fraction of ``count`` UDP datagrams sent from host ``src`` that host ``dst`` receives."""
    dst_host = net.hosts[dst]
    # The receiver must not drop datagrams itself: a default receive buffer (~212 KB, a few
    # hundred datagrams) overflows while a loaded machine keeps the receiver off the CPU, so it
    # forces an 8 MB buffer (SO_RCVBUFFORCE = 33: root may exceed net.core.rmem_max). It waits up
    # to 30 s for the first datagram (the sender is a new process), then stops after `count` or
    # after 1 s without one.
    receiver = subprocess.Popen(
        ['ip', 'netns', 'exec', dst_host.netns, sys.executable, '-c',
         'import socket, sys\n'
         's = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)\n'
         's.setsockopt(socket.SOL_SOCKET, 33, 8 << 20)\n'
         f's.bind(("{dst_host.address}", 47000)); s.settimeout(30.0)\n'
         'print("ready", flush=True)\n'
         'n = 0\n'
         'try:\n'
         f'    while n < {count}:\n'
         '        s.recv(64); n += 1; s.settimeout(1.0)\n'
         'except socket.timeout:\n'
         '    pass\n'
         'print(n, flush=True)\n'],
        stdout=subprocess.PIPE, text=True)
    assert receiver.stdout.readline().strip() == 'ready'
    subprocess.run(['ip', 'netns', 'exec', net.hosts[src].netns, sys.executable, '-c',
                    'import socket, time\n'
                    's = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)\n'
                    f'for i in range({count}):\n'
                    f'    s.sendto(b"x", ("{dst_host.address}", 47000))\n'
                    '    if i % 100 == 0: time.sleep(0.001)\n'], check=True, timeout=60)
    out, _ = receiver.communicate(timeout=60)
    return int(out.strip()) / count


def test_loss_rule_drops_its_share_between_helicopters_only(nft):
    with netns.TeamNetwork((1, 2), loss_pct=30.0, tag=f'uhnet{os.getpid()}') as net:
        assert sorted(_namespaces(net.tag)) == sorted(
            [f'{net.tag}-{h}' for h in ('hub', 'uh1', 'uh2', 'vl', 'ground')])
        # 2000 datagrams, 30 % drop: the delivered share is 0.70 with a standard deviation of
        # sqrt(0.3 * 0.7 / 2000) = 0.010, so +-0.06 is six standard deviations
        assert abs(_udp_delivery(net, 'uh1', 'uh2') - 0.70) < 0.06
        # the ground host (recorder, clock) is exempt both ways
        assert _udp_delivery(net, 'uh1', 'ground') == 1.0
        assert _udp_delivery(net, 'ground', 'uh2') == 1.0
        # dropped where they arrive, counted by the rule
        dropped = net.dropped()
        assert dropped['uh2'] > 0 and dropped['uh1'] == 0
    assert _namespaces(net.tag) == []   # deleting the namespaces took the veths and the bridge along


def test_network_setup_failure_leaves_nothing_behind():
    tag = f'uhnet{os.getpid()}'
    with pytest.raises(netns.NetnsError, match=r'UH id 150: --hosts netns supports ids 1\.\.99'):
        with netns.TeamNetwork((1, 150), tag=tag):
            pass
    # a failure half-way (the namespace of uh2 exists already) removes what was created
    subprocess.run(['ip', 'netns', 'add', f'{tag}-uh2'], check=True)
    try:
        with pytest.raises(netns.NetnsError, match=rf'creating namespace {tag}-uh2'):
            with netns.TeamNetwork((1, 2), tag=tag):
                pass
        assert _namespaces(tag) == [f'{tag}-uh2']
    finally:
        subprocess.run(['ip', 'netns', 'del', f'{tag}-uh2'])


def test_namespaces_of_a_killed_run_are_swept():
    dead = subprocess.Popen(['true'])
    dead.wait()               # its pid belongs to no process any more
    name = f'{netns.PREFIX}{dead.pid}-hub'
    subprocess.run(['ip', 'netns', 'add', name], check=True)
    try:
        assert name in netns.sweep_stale()
        assert name not in netns.list_namespaces()
    finally:
        subprocess.run(['ip', 'netns', 'del', name], capture_output=True)


@pytest.mark.dds
@pytest.mark.slow
def test_team_flies_over_a_lossy_network(tmp_path, nft):
    """The paper team, each UH in its own namespace, 10 % loss on every air link, realtime."""
    out = tmp_path / 'run'
    proc = subprocess.Popen([str(RUN), '--hosts', 'netns', '--loss', '10', '--clock', 'realtime', '--duration', '8',
                             '--out', str(out), '--domain-id', str(reserve_domain_id())],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        output, _ = proc.communicate(timeout=300)
    finally:
        kill_session(proc)
    tag = f'{netns.PREFIX}{proc.pid}'
    assert _namespaces(tag) == [], 'namespaces left behind'
    assert proc.returncode == 0, output
    assert '8 network namespaces' in output and '10 % loss on the links of uh1, uh2, uh3, uh4, uh5, vl' in output
    info = json.loads((out / 'run.json').read_text())
    assert info['hosts'] == 'netns' and all(n > 0 for n in info['dropped_packets'].values()), info
    # data crossed the network: every controller (each hears a UH in another namespace) computed
    # commands up to the end, and they were recorded from the ground namespace
    import numpy as np

    from uh_report.bag_metrics import read_team_bag
    from uh_topology.scenario import load_scenario
    bag = read_team_bag(out / 'bag', load_scenario('paper'))
    commanded = ~np.isnan(bag['commands'][:, :, 0])
    assert commanded[-50:].any(axis=0).all()           # every UH was commanded in the last 0.5 s
    assert commanded.mean() > 0.9                      # and at most steps (realtime: a few missed)
    assert np.isfinite(bag['states'][~np.isnan(bag['states'][:, :, 0])]).all()


@pytest.mark.dds
@pytest.mark.slow
def test_interrupted_netns_run_removes_its_namespaces(tmp_path):
    out = tmp_path / 'run'
    proc = subprocess.Popen([str(RUN), '--hosts', 'netns', '--clock', 'realtime', '--duration', '60',
                             '--out', str(out), '--domain-id', str(reserve_domain_id())],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    tag = f'{netns.PREFIX}{proc.pid}'
    try:
        deadline = time.monotonic() + 120
        log = out / 'logs' / 'clock.log'
        while not (log.exists() and 'team complete' in log.read_text()):
            assert time.monotonic() < deadline and proc.poll() is None, 'the team did not come up'
            time.sleep(0.1)
        assert len(_namespaces(tag)) == 8                   # hub, 5 UHs, vl, ground
        os.killpg(proc.pid, signal.SIGINT)
        output, _ = proc.communicate(timeout=120)
    finally:
        kill_session(proc)
    assert proc.returncode == 130, output
    assert _namespaces(tag) == []
