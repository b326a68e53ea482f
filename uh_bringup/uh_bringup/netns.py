"""A team spread over network namespaces: one "host" per helicopter, a real (virtual) network between them.

``run_formation.sh --hosts netns [--loss PCT]`` runs each UH's simulator and controller in a
network namespace of its own, the virtual leader in another and the ground nodes (clock, recorder,
visualisation) in a third kind, all joined by veth pairs to one Linux bridge that lives in a hub
namespace. DDS then discovers its peers and carries every sample over that network, exactly as on
separate machines: each namespace's Cyclone DDS configuration names the namespace's interface and
lists every host's address as a unicast peer (no multicast needed)::

    ns <run>-uh1  eth0 10.231.0.1 ─┐
    ns <run>-uh2  eth0 10.231.0.2 ─┤
    ...                            ├─ bridge br0 in ns <run>-hub
    ns <run>-vl   eth0 10.231.0.100┤
    ns <run>-ground eth0 10.231.0.200

Nothing of this touches the machine's own network namespace: the bridge lives in the hub
namespace, the addresses exist only inside the run's namespaces (which have no route out), so they
cannot clash with anything. ``<run>`` is ``uhnet<pid>`` of the run, so concurrent runs never share
a namespace, and a run started after one that was killed (SIGKILL leaves no chance to clean up)
removes the namespaces of runs whose process is gone (:func:`sweep_stale`).

Loss (``--loss PCT``): the kernel here has no ``netem`` qdisc, so loss is an nftables rule in the
input hook of every UH and virtual-leader namespace, ``numgen random mod 10000 < PCT*100 drop`` on
UDP arriving on ``eth0`` from another helicopter or the virtual leader: every link between two
helicopters (and from the virtual leader to a leader) loses PCT % of its packets in each direction,
DDS data, heartbeats, acknowledgements and discovery alike, and the sender does not notice (a drop
in the output hook would fail its ``sendto`` with EPERM, which no radio link does). Packets from
and to the ground host are not dropped: the bag records what really happened in the air, and the
clock's ticks (the simulation's time source, not a radio link) arrive. Traffic inside one namespace
(a UH's simulator and controller, i.e. on board) never crosses the network.
"""
from __future__ import annotations

import atexit
import os
import re
import shutil
import subprocess
from dataclasses import dataclass, field

from uh_runtime.network import SPDP_INTERVAL_XML

__all__ = ['NetnsError', 'Host', 'TeamNetwork', 'check_available', 'sweep_stale', 'SUBNET', 'PREFIX',
           'host_of_process', 'cyclone_config', 'FAST_RECOVERY_XML']

#: name prefix of every namespace a run creates: ``uhnet<pid>-<host>``
PREFIX = 'uhnet'
#: the /24 the hosts live in (exists only inside the run's namespaces)
SUBNET = '10.231.0'
_OCTET = {'vl': 100, 'ground': 200}
_NAME = re.compile(rf'^{PREFIX}(\d+)-')


class NetnsError(RuntimeError):
    """The machine cannot host a netns run (not root, no iproute2/nftables) or a command failed."""


@dataclass(frozen=True)
class Host:
    """One namespace of a run: ``name`` (``uh3``, ``vl``, ``ground``), namespace, address, lossy or not."""

    name: str
    netns: str
    address: str
    lossy: bool
    ifname: str = 'eth0'


def _run(cmd: list, what: str) -> str:
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=30)
    except FileNotFoundError:
        raise NetnsError(f'{what}: {cmd[0]} not found') from None
    except subprocess.TimeoutExpired:
        raise NetnsError(f'{what}: {" ".join(cmd)} did not finish within 30 s') from None
    if done.returncode != 0:
        raise NetnsError(f'{what}: `{" ".join(cmd)}` failed: {(done.stderr or done.stdout).strip()}')
    return done.stdout


def check_available(loss_pct: float = 0.0) -> None:
    """Raise :class:`NetnsError` saying why this machine cannot run ``--hosts netns`` (with loss)."""
    if os.geteuid() != 0:
        raise NetnsError('--hosts netns needs root (CAP_NET_ADMIN to create network namespaces); '
                         'run as root or without --hosts')
    if shutil.which('ip') is None:
        raise NetnsError('--hosts netns needs iproute2 (the `ip` command): apt-get install -y iproute2')
    if loss_pct > 0 and shutil.which('nft') is None:
        raise NetnsError('--loss needs nftables (the `nft` command; this kernel has no netem qdisc): '
                         'apt-get install -y nftables')
    probe = f'{PREFIX}{os.getpid()}-probe'
    try:
        _run(['ip', 'netns', 'add', probe], 'creating a network namespace')
    finally:
        subprocess.run(['ip', 'netns', 'del', probe], capture_output=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def list_namespaces() -> list[str]:
    """Names of the network namespaces ``ip netns`` knows."""
    out = subprocess.run(['ip', 'netns', 'list'], capture_output=True, text=True).stdout
    return [line.split()[0] for line in out.splitlines() if line.strip()]


def sweep_stale() -> list[str]:
    """Delete the namespaces of runs whose process no longer exists; return their names."""
    removed = []
    for name in list_namespaces():
        match = _NAME.match(name)
        if match and not _alive(int(match.group(1))):
            subprocess.run(['ip', 'netns', 'del', name], capture_output=True)
            removed.append(name)
    return removed


def host_of_process(name: str) -> str:
    """Return the host of a supervised process.

    ``uh3_sim``/``uh3_controller``/``uh3`` -> ``uh3``, the virtual leader -> ``vl``, everything else
    (clock, recorder, visualisation, a composed team) -> ``ground``.
    """
    if re.match(r'^uh\d+(_|$)', name):
        return name.split('_')[0]
    return 'vl' if name == 'virtual_leader' else 'ground'


#: Faster loss recovery than Cyclone DDS's defaults (heartbeat every 100 ms, NACK 100 ms after a
#: heartbeat reveals a gap, so a lost sample arrives 100-200 ms late, more when a repair is lost
#: too): heartbeats every 20 ms (at least 5 ms apart) and a NACK 10 ms after one. Per-step data
#: comes every 10 ms, so a repair then takes a few steps instead of tens. And participant
#: discovery is repeated every second instead of every 30 s (as on loopback,
#: :data:`uh_runtime.network.SPDP_INTERVAL_XML`): when the few discovery packets two
#: participants exchange at start-up are lost, they would otherwise not find each other for half
#: a minute (seen at 25 % loss). Set the environment variable UH_NETNS_CYCLONE_DEFAULTS=1 to run
#: with Cyclone's defaults instead.
FAST_RECOVERY_XML = ('<Internal><HeartbeatInterval min="5 ms">20 ms</HeartbeatInterval>'
                     '<NackDelay>10 ms</NackDelay></Internal>')
FAST_DISCOVERY_XML = SPDP_INTERVAL_XML   # as on loopback (uh_runtime.network)


def cyclone_config(host: Host, peers: list, max_participants: int = 10) -> str:
    """Return the ``CYCLONEDDS_URI`` of a process on ``host``.

    Its interface, no multicast, every host a peer, fast loss recovery (:data:`FAST_RECOVERY_XML`).
    """
    peer_xml = ''.join(f'<Peer address="{p}"/>' for p in peers)
    defaults = os.environ.get('UH_NETNS_CYCLONE_DEFAULTS') == '1'
    internal, spdp = ('', '') if defaults else (FAST_RECOVERY_XML, FAST_DISCOVERY_XML)
    return ('<CycloneDDS><Domain id="any"><General>'
            f'<Interfaces><NetworkInterface name="{host.ifname}"/></Interfaces>'
            '<AllowMulticast>false</AllowMulticast></General>'
            f'{internal}'
            '<Discovery><ParticipantIndex>auto</ParticipantIndex>'
            f'<MaxAutoParticipantIndex>{int(max_participants)}</MaxAutoParticipantIndex>'
            f'{spdp}<Peers>{peer_xml}</Peers></Discovery></Domain></CycloneDDS>')


@dataclass
class TeamNetwork:
    """The namespaces, veth pairs, bridge and loss rules of one run; a context manager.

    Parameters
    ----------
    uh_ids : iterable of int
        Helicopters: one host each (``uh<id>``, address ``10.231.0.<id>``).
    loss_pct : float
        Packet loss in percent (0..100) on every link between helicopters and from the virtual leader.
    tag : str, optional
        Namespace prefix; default ``uhnet<pid>``.

    ``with TeamNetwork(ids, 10) as net:`` creates everything (removing it again if any step
    fails), ``net.prefix(name)`` and ``net.environment(name, env)`` place a process on its host,
    and leaving the block (also on an exception) deletes every namespace, which takes the veth
    pairs and the bridge with it.
    """

    uh_ids: tuple
    loss_pct: float = 0.0
    tag: str = ''
    hosts: dict = field(default_factory=dict)

    def __post_init__(self):
        if not 0.0 <= float(self.loss_pct) <= 100.0:
            raise NetnsError(f'loss {self.loss_pct} %: allowed 0 .. 100')
        self.tag = self.tag or f'{PREFIX}{os.getpid()}'
        for i in sorted(int(i) for i in self.uh_ids):
            if not 1 <= i <= 99:
                raise NetnsError(f'UH id {i}: --hosts netns supports ids 1..99')
            self.hosts[f'uh{i}'] = Host(f'uh{i}', f'{self.tag}-uh{i}', f'{SUBNET}.{i}', True)
        for name, octet in _OCTET.items():
            self.hosts[name] = Host(name, f'{self.tag}-{name}', f'{SUBNET}.{octet}', name != 'ground')
        self.hub = f'{self.tag}-hub'
        self._created: list = []

    # -- lifecycle ---------------------------------------------------------------------------------
    def __enter__(self):
        atexit.register(self.close)
        try:
            self._create()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc):
        self.close()

    def _ns(self, name: str) -> None:
        _run(['ip', 'netns', 'add', name], f'creating namespace {name}')
        self._created.append(name)
        _run(['ip', '-n', name, 'link', 'set', 'lo', 'up'], f'bringing up lo in {name}')

    def _create(self) -> None:
        self._ns(self.hub)
        _run(['ip', '-n', self.hub, 'link', 'add', 'br0', 'type', 'bridge'], 'creating the bridge')
        _run(['ip', '-n', self.hub, 'link', 'set', 'br0', 'up'], 'bringing up the bridge')
        for host in self.hosts.values():
            self._ns(host.netns)
            port = f'p-{host.name}'
            _run(['ip', '-n', self.hub, 'link', 'add', port, 'type', 'veth', 'peer', 'name', host.ifname,
                  'netns', host.netns], f'creating the veth pair of {host.name}')
            _run(['ip', '-n', self.hub, 'link', 'set', port, 'master', 'br0'], f'attaching {port} to the bridge')
            _run(['ip', '-n', self.hub, 'link', 'set', port, 'up'], f'bringing up {port}')
            _run(['ip', '-n', host.netns, 'addr', 'add', f'{host.address}/24', 'dev', host.ifname],
                 f'addressing {host.name}')
            _run(['ip', '-n', host.netns, 'link', 'set', host.ifname, 'up'], f'bringing up {host.name}')
            if host.lossy and self.loss_pct > 0:
                self._add_loss(host)

    def _add_loss(self, host: Host) -> None:
        ground = self.hosts['ground'].address
        threshold = int(round(float(self.loss_pct) * 100))
        ruleset = (
            'table inet uhloss {\n'
            '  chain air_in {\n'
            '    type filter hook input priority 0; policy accept;\n'
            f'    iifname "{host.ifname}" meta l4proto udp ip saddr != {ground} '
            f'numgen random mod 10000 < {threshold} counter drop\n'
            '  }\n'
            '}\n')
        proc = subprocess.run(['ip', 'netns', 'exec', host.netns, 'nft', '-f', '-'], input=ruleset,
                              capture_output=True, text=True, timeout=30)
        if proc.returncode != 0:
            raise NetnsError(f'adding the loss rule in {host.netns} failed: {proc.stderr.strip()}')

    def close(self) -> None:
        """Delete every namespace this network created (idempotent; never raises)."""
        while self._created:
            name = self._created.pop()
            subprocess.run(['ip', 'netns', 'del', name], capture_output=True)
        try:
            atexit.unregister(self.close)
        except Exception:
            pass

    # -- placing processes -------------------------------------------------------------------------
    def host(self, process_name: str) -> Host:
        """Return the :class:`Host` a supervised process runs on (:func:`host_of_process`)."""
        return self.hosts[host_of_process(process_name)]

    def prefix(self, process_name: str) -> list:
        """Command prefix that runs a process in its host's namespace."""
        return ['ip', 'netns', 'exec', self.host(process_name).netns]

    def environment(self, process_name: str, base: dict) -> dict:
        """Return ``base`` with the Cyclone DDS configuration of the process's host."""
        env = dict(base)
        env['CYCLONEDDS_URI'] = cyclone_config(self.host(process_name), [h.address for h in self.hosts.values()])
        return env

    def dropped(self) -> dict:
        """Packets dropped so far by each host's loss rule (reads the nftables counters)."""
        out = {}
        for host in self.hosts.values():
            if not (host.lossy and self.loss_pct > 0):
                continue
            text = subprocess.run(['ip', 'netns', 'exec', host.netns, 'nft', 'list', 'table', 'inet', 'uhloss'],
                                  capture_output=True, text=True).stdout
            match = re.search(r'counter packets (\d+)', text)
            out[host.name] = int(match.group(1)) if match else None
        return out

    def describe(self) -> str:
        """Return a one-line description of the network: its namespaces, subnet and loss."""
        lossy = ', '.join(h.name for h in self.hosts.values() if h.lossy)
        return (f'{len(self.hosts) + 1} network namespaces {self.tag}-* ({", ".join(self.hosts)} and the hub '
                f'with bridge br0, {SUBNET}.0/24); '
                + (f'{self.loss_pct:g} % loss on the links of {lossy}' if self.loss_pct > 0 else 'no loss'))
