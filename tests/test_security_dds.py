"""Attacks on a secure team at the DDS level, in the secure virtualenv (docs/security.md; the secure tier).

Every process is ``tests/helpers_security/secure_peer.py`` on ``.venv-secure/bin/python`` (Cyclone DDS
0.10.2 with DDS Security, scripts/_venv_secure.sh), one participant each, with the identity of an
enclave of a keystore made by ``uh-security create`` for the paper scenario, through the runtime's own
participant (``ROS_SECURITY_*``, uh_runtime.dds.security) and the real ``uh_msgs`` types. Each test
runs twice: ``on``, the attack is refused; ``off`` (the same processes without ``ROS_SECURITY_ENABLE``),
the same attack succeeds, so the test shows the protection, not an attack that could not work anyway.

Timing: a secure participant's handshake takes 1.5-2 s before its endpoints match (measured, issue 35).
Publishers write every 50 ms for :data:`WRITE_S` s and readers listen :data:`LISTEN_S` s, started together;
a negative result (nothing received) is only asserted in a run where a permitted reader of the same
window did receive (the control), so a slow machine cannot make a refusal look like a success.
The tier: ``scripts/test.sh --secure``; elsewhere these tests are skipped with the reason.
"""
import datetime
import os
import shutil
import subprocess
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID
from helpers_security.tier import SECURE_PYTHON

from uh_runtime.network import loopback_environment
from uh_security import cli, keystore, policy

ROOT = Path(__file__).resolve().parents[1]
PEER = ROOT / 'tests' / 'helpers_security' / 'secure_peer.py'
#: How long a publisher writes and a reader listens (s): the 2 s handshake and discovery, with room.
WRITE_S, LISTEN_S = 8.0, 7.0
#: Bounds a failure only: a peer exits by itself after its window.
PEER_TIMEOUT_S = 60
REFUSED = 'DDS_RETCODE_NOT_ALLOWED_BY_SECURITY'
STATE, COMMAND = 'uh_msgs/msg/UHState', 'uh_msgs/msg/ActuatorCommand'

pytestmark = [pytest.mark.secure, pytest.mark.dds, pytest.mark.usefixtures('only_in_the_secure_tier'),
              pytest.mark.skipif(not SECURE_PYTHON.exists(),
                                 reason=f'no secure virtualenv at {SECURE_PYTHON}: scripts/test.sh --secure builds it '
                                        '(Cyclone DDS 0.10.2 with DDS Security, docs/security.md)')]


@pytest.fixture(scope='module')
def keys(tmp_path_factory):
    path = tmp_path_factory.mktemp('secure') / 'keys'
    assert cli.main(['create', '--scenario', 'paper', '--keystore', str(path)]) == 0
    return path


class Peers:
    """Start ``secure_peer.py`` processes of one test on one domain, with or without security."""

    def __init__(self, processes, domain: int, store: Path, secure: bool):
        self.processes, self.store, self.secure = processes, store, secure
        self.env = {**os.environ, **loopback_environment(domain), 'PYTHONUNBUFFERED': '1',
                    'ROS_SECURITY_KEYSTORE': str(store), 'ROS_SECURITY_STRATEGY': 'Enforce'}
        for key in ('ROS_SECURITY_ENABLE', 'ROS_SECURITY_ENCLAVE_OVERRIDE', 'UH_BACKEND'):
            self.env.pop(key, None)

    def start(self, enclave, *args, keystore_dir=None, **extra):
        """Start a peer with the identity ``enclave`` (None: no identity at all)."""
        env = dict(self.env, **extra)
        if enclave is not None:
            env['ROS_SECURITY_ENCLAVE_OVERRIDE'] = enclave
            if self.secure:
                env['ROS_SECURITY_ENABLE'] = 'true'
        if keystore_dir is not None:
            env['ROS_SECURITY_KEYSTORE'] = str(keystore_dir)
        return self.processes.start([str(SECURE_PYTHON), '-P', str(PEER), *args], env=env,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _output(proc) -> list:
    out, err = proc.communicate(timeout=PEER_TIMEOUT_S)
    assert 'Traceback' not in err, err
    return out.splitlines()


def _steps(lines) -> list:
    return [int(line.split()[2]) for line in lines if line.startswith('got ')]


def _refused(lines, entity: str) -> bool:
    return any(line.startswith('refused') and REFUSED in line and entity in line for line in lines)


@pytest.fixture(params=['on', 'off'])
def peers(request, processes, secure_domain, keys):
    return Peers(processes, secure_domain, keys, secure=request.param == 'on')


def test_a_permitted_reader_gets_the_state_and_a_participant_without_identity_sees_no_topic_and_no_data(peers):
    writer = peers.start('/uh2/sim', 'publish', '/uh2/state', STATE, str(WRITE_S))
    reader = peers.start('/uh3/controller', 'subscribe', '/uh2/state', STATE, str(LISTEN_S))   # UH3 hears UH2
    stranger = peers.start(None, 'look', '/uh2/state', str(LISTEN_S))
    assert 'ready' in _output(writer)
    assert _steps(_output(reader)), 'the permitted pair exchanged nothing: the negative results below prove nothing'
    seen = _output(stranger)
    topics = {line.split()[1] for line in seen if line.startswith('topic ')}
    data = int(next(line.split()[1] for line in seen if line.startswith('data ')))
    if peers.secure:
        assert topics == set() and data == 0, seen
    else:
        assert 'rt/uh2/state' in topics and data > 0, seen


def test_the_inspection_identity_lists_and_echoes_the_team_and_no_identity_lists_nothing(peers):
    """``uh`` (its graph's own participant) with ``/tools/inspect`` and with no identity, beside UH2's simulator."""
    writer = peers.start('/uh2/sim', 'publish', '/uh2/state', STATE, str(WRITE_S))
    # the listings start once the writer exists, so a stranger's empty listing is not an early one
    assert [writer.stdout.readline().strip() for _ in range(2)] == ['node', 'ready']
    uh = str(SECURE_PYTHON.parent / 'uh')
    inspect = peers.processes.start([uh, 'topic', 'echo', '/uh2/state', '--once', '--timeout', '30'],
                                    env=dict(peers.env, ROS_SECURITY_ENCLAVE_OVERRIDE=policy.INSPECT,
                                             **({'ROS_SECURITY_ENABLE': 'true'} if peers.secure else {})),
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stranger = peers.processes.start([uh, 'topic', 'list', '--spin-time', str(LISTEN_S)], env=peers.env,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    echoed, listed = inspect.communicate(timeout=PEER_TIMEOUT_S)[0], stranger.communicate(timeout=PEER_TIMEOUT_S)[0]
    _output(writer)
    assert 'uh_id: 2' in echoed, echoed     # the read-only identity reads the team
    if peers.secure:
        assert '/uh2/state' not in listed.split(), listed
    else:
        assert '/uh2/state' in listed.split(), listed


@pytest.mark.parametrize('tool', policy.TOOL_ENCLAVES)
def test_a_tool_identity_may_make_the_node_a_ros2_command_makes_and_a_team_node_may_not(peers, tool):
    """The node of ``ros2 topic echo``, ``/_ros2cli_<pid>``: its parameter services and get_type_description.

    On a Jazzy built from source, rmw_cyclonedds refused that node to ``/tools/inspect`` until the policy
    granted get_type_description (docs/security.md#on-a-real-ros-2-jazzy). A controller's identity may not
    make it (the control: a refusal is seen when the grant is missing).
    """
    if not peers.secure:
        pytest.skip('without security every identity may make any topic: nothing to compare')
    assert _output(peers.start(tool, 'cli_node', '0.5'))[:2] == ['ready', 'ready']
    refused = _output(peers.start('/uh3/controller', 'cli_node', '0.5'))
    assert refused and refused[0].startswith('refused') and REFUSED in refused[0], refused


def test_an_identity_without_the_write_permission_cannot_create_the_command_writer(peers):
    # the recorder may read /uh1/command (so the topic exists for it) but never write it
    attacker = peers.start('/recorder', 'publish', '/uh1/command', COMMAND, str(WRITE_S))
    sim = peers.start('/uh1/sim', 'subscribe', '/uh1/command', COMMAND, str(LISTEN_S))
    control = peers.start('/uh1/controller', 'publish', '/uh1/command', COMMAND, str(WRITE_S),
                          UH_PEER_FIRST_STEP='1000000')
    attack, received = _output(attacker), _steps(_output(sim))
    assert 'ready' in _output(control) and any(s >= 1_000_000 for s in received), 'the control did not get through'
    if peers.secure:
        assert _refused(attack, 'DataWriter'), attack
        assert all(s >= 1_000_000 for s in received)
    else:
        assert 'ready' in attack and any(s < 1_000_000 for s in received)


def test_uh3s_controller_can_neither_command_uh1_nor_read_a_non_neighbours_state(peers):
    state = peers.start('/uh1/sim', 'publish', '/uh1/state', STATE, str(WRITE_S))
    spy = peers.start('/uh3/controller', 'subscribe', '/uh1/state', STATE, str(LISTEN_S))   # UH3 does not hear UH1
    control = peers.start('/uh2/controller', 'subscribe', '/uh1/state', STATE, str(LISTEN_S))   # UH2 does
    commander = peers.start('/uh3/controller', 'publish', '/uh1/command', COMMAND, str(WRITE_S))
    sim = peers.start('/uh1/sim', 'subscribe', '/uh1/command', COMMAND, str(LISTEN_S))
    spied, commanded, received = _output(spy), _output(commander), _steps(_output(sim))
    assert 'ready' in _output(state) and _steps(_output(control)), 'the permitted reader got nothing'
    if peers.secure:
        assert _refused(spied, 'Topic') and not _steps(spied), spied
        assert _refused(commanded, 'Topic') and received == [], commanded
    else:
        assert _steps(spied) and 'ready' in commanded and received


def _attacker_ca():
    """Make a CA of the attacker's own: ``(certificate, key)`` (what sros2 makes, with another key)."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, keystore.CA_NAME)])
    now = datetime.datetime.now(datetime.timezone.utc)
    cert = (x509.CertificateBuilder().issuer_name(name).subject_name(name).serial_number(x509.random_serial_number())
            .not_valid_before(now).not_valid_after(now + datetime.timedelta(days=1)).public_key(key.public_key())
            .add_extension(x509.BasicConstraints(ca=True, path_length=1), critical=True).sign(key, hashes.SHA256()))
    return cert, key


def _forge(store: Path, into: Path, own_ca: bool) -> Path:
    """Copy ``store`` to ``into`` with UH3's controller's permissions widened to ``rt/uh1/command``.

    ``own_ca=False``: the signed file is edited, its signature left as it was. ``own_ca=True``: the
    attacker signs the widened permissions and the governance with a CA of their own and puts its
    certificate in the enclave as the permissions CA (a valid chain, but not the team's).
    """
    shutil.copytree(store, into, symlinks=True)
    folder = keystore.enclave_dir(into, '/uh3/controller')
    own, extra = '<topic>rt/uh3/command</topic>', '<topic>rt/uh1/command</topic>'
    if not own_ca:
        signed = (folder / 'permissions.p7s').read_text()
        assert signed.count(own) == 1
        (folder / 'permissions.p7s').write_text(signed.replace(own, own + extra))
        return into
    widened = (folder / 'permissions.xml').read_text().replace(own, own + extra)
    ca_cert, ca_key = _attacker_ca()
    for name in ('permissions_ca.cert.pem', 'governance.p7s', 'permissions.p7s'):
        (folder / name).unlink()
    (folder / 'permissions_ca.cert.pem').write_bytes(ca_cert.public_bytes(serialization.Encoding.PEM))
    (folder / 'permissions.p7s').write_bytes(keystore.sign_smime(ca_cert, ca_key, widened.encode()))
    governance = (into / 'enclaves' / 'governance.xml').read_bytes()
    (folder / 'governance.p7s').write_bytes(keystore.sign_smime(ca_cert, ca_key, governance))
    return into


@pytest.mark.parametrize('forgery', ['edited', 'own_ca'])
def test_forged_permissions_are_rejected(peers, forgery, tmp_path):
    forged = _forge(peers.store, tmp_path / 'forged', own_ca=forgery == 'own_ca')
    sim = peers.start('/uh1/sim', 'subscribe', '/uh1/command', COMMAND, str(LISTEN_S))
    forger = peers.start('/uh3/controller', 'publish', '/uh1/command', COMMAND, str(WRITE_S), keystore_dir=forged)
    control = peers.start('/uh1/controller', 'publish', '/uh1/command', COMMAND, str(WRITE_S),
                          UH_PEER_FIRST_STEP='1000000')
    forging, received = _output(forger), _steps(_output(sim))
    assert 'ready' in _output(control) and any(s >= 1_000_000 for s in received), 'the control did not get through'
    if not peers.secure:
        assert 'ready' in forging and any(s < 1_000_000 for s in received)
    elif forgery == 'edited':     # the signature no longer matches: the participant itself is refused
        assert any(line.startswith('refused participant') for line in forging), forging
    else:                         # valid in its own eyes, never matched by the team's participants
        assert 'ready' in forging and all(s >= 1_000_000 for s in received), forging
