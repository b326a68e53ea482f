"""Secure mode's policy, keystore and command, without DDS (docs/security.md; uh_security).

The policy follows the graph: each controller may read exactly the states its node subscribes to
(docs/topics.md's table for the paper scenario, written out here by hand), no identity but UH i's
controller may publish ``/uhi/command``, and the rules agree with the publishers the topic registry
names. The keystore has sros2's layout, its certificates chain to its CA and its documents are
S/MIME-signed by it (checked with the openssl command, an independent reader). The DDS-level attacks
are in tests/test_security_dds.py (the secure tier).
"""
import re
import shutil
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from cryptography import x509
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.hazmat.primitives.serialization import load_pem_private_key

from uh_security import cli, keystore, policy
from uh_topology.scenario import CONFIG_DIR, load_scenario, parse_scenario
from uh_wire import topics

PAPER = load_scenario('paper')
#: docs/topics.md, "Who hears whom": the states (and reference) each controller of the paper team reads
PAPER_READS = {1: {'/uh1/state', '/uh3/state', '/reference'}, 2: {'/uh2/state', '/uh1/state'},
               3: {'/uh3/state', '/uh2/state'}, 4: {'/uh4/state', '/uh1/state', '/uh2/state', '/uh5/state'},
               5: {'/uh5/state', '/uh3/state', '/uh4/state'}}
NODE_BASICS = set(policy.NODE_TOPICS)


@pytest.fixture(scope='module')
def grants():
    return policy.team_grants(PAPER)


def _grant(grants, enclave):
    return policy.grant_of(grants, enclave)


def test_uh3s_controller_reads_exactly_its_neighbours_states_and_publishes_its_command_and_status(grants):
    uh3 = _grant(grants, '/uh3/controller')
    assert set(uh3.subscribe) == {'/uh3/state', '/uh2/state', '/uh3/proximity'}   # safety on: its own proximity
    assert set(uh3.publish) == {'/uh3/command', '/uh3/status', '/diagnostics'} | NODE_BASICS
    assert set(uh3.request) == set()
    # the six parameter services and get_type_description, which every Jazzy node serves
    assert set(uh3.reply) == {f'/uh3/controller/{s}' for s in (
        'describe_parameters', 'get_parameters', 'get_parameter_types', 'list_parameters', 'set_parameters',
        'set_parameters_atomically', 'get_type_description')}


@pytest.mark.parametrize('tool', policy.TOOL_ENCLAVES)
def test_a_tool_may_run_the_ros2_command_lines_node_with_the_services_jazzy_starts_for_it(grants, tool):
    """Without ``get_type_description``, rmw_cyclonedds refused every ``ros2`` command (a Jazzy from source)."""
    cli = _grant(grants, tool)
    assert {'/_ros2cli_*/get_type_description', '/_ros2cli_*/get_parameters'} <= set(cli.reply)
    assert {'rr/_ros2cli_*/get_type_descriptionReply', 'rt/rosout'} <= set(cli.dds_publish())
    assert 'rq/_ros2cli_*/get_type_descriptionRequest' in cli.dds_subscribe()


@pytest.mark.parametrize('uh', PAPER.ids)
def test_every_controller_reads_what_docs_topics_says_it_hears(grants, uh):
    reads = set(_grant(grants, f'/uh{uh}/controller').subscribe)
    assert reads - {f'/uh{uh}/proximity'} == PAPER_READS[uh]


def test_without_the_safety_filter_no_controller_reads_proximity_and_there_is_no_sensing_identity():
    grants = policy.team_grants(load_scenario('paper', safety=False))
    assert '/sensing' not in {g.enclave for g in grants}
    for uh in PAPER.ids:
        assert set(_grant(grants, f'/uh{uh}/controller').subscribe) == PAPER_READS[uh]


def test_a_scenario_that_answers_losses_lets_a_controller_read_its_standby_neighbours():
    data = yaml.safe_load((CONFIG_DIR / 'paper.yaml').read_text())
    data.update(resilience={'standby_edges': 'bypass'}, gains=str(CONFIG_DIR / 'paper_gains.yaml'))
    scenario = parse_scenario(yaml.safe_dump(data), base_dir=CONFIG_DIR)
    grants = policy.team_grants(scenario)
    # bypass adds 4 <- 3 and the reference link of UH4 (docs/resilience.md), so UH4 may read both
    reads = set(_grant(grants, '/uh4/controller').subscribe)
    assert {'/uh3/state', '/reference'} <= reads and '/uh4/received' in _grant(grants, '/uh4/controller').publish


def test_no_identity_but_uh_is_controller_may_publish_its_command(grants):
    for uh in PAPER.ids:
        command = topics.uh_topic(uh, topics.COMMAND)
        writers = {g.enclave for g in grants if command in g.publish}
        assert writers == {f'/uh{uh}/controller'}, command


def test_a_simulator_publishes_only_its_own_state_and_reads_only_its_own_command(grants):
    for uh in PAPER.ids:
        sim = _grant(grants, f'/uh{uh}/sim')
        assert [t for t in sim.publish if t.endswith('/state')] == [f'/uh{uh}/state']
        assert [t for t in sim.subscribe if t.endswith('/command')] == [f'/uh{uh}/command']
        assert f'/uh{uh}/fault' in sim.subscribe


def test_the_recorder_and_the_inspection_tool_only_read_and_only_the_operator_may_inject(grants):
    recorder, inspect, operator = (_grant(grants, e) for e in ('/recorder', policy.INSPECT, policy.OPERATOR))
    assert set(recorder.publish) == {topics.RECORDER_PROGRESS.name} | NODE_BASICS
    assert {name for name, _ in topics.run_topics(PAPER.ids, **topics.scenario_flags(PAPER))} <= set(recorder.subscribe)
    assert set(inspect.publish) == NODE_BASICS and inspect.subscribe == ('/*',)
    assert not any(s.endswith(('/set_parameters', '/set_parameters_atomically')) for s in inspect.request)
    assert set(operator.publish) == NODE_BASICS | {f'/uh{i}/fault' for i in PAPER.ids}
    assert {'/*/set_parameters', '/*/set_parameters_atomically'} <= set(operator.request)   # gains: a deliberate act
    injectors = {g.enclave for g in grants if any(t.endswith('/fault') for t in g.publish)}
    assert injectors == {policy.OPERATOR}


#: words of a TopicSpec's ``publisher`` text -> the node kind (or 'tool') they name
PUBLISHER_WORDS = {'sim': 'sim', 'sims': 'sim', 'controller': 'controller', 'controllers': 'controller',
                   'virtual_leader': 'virtual_leader', 'clock': 'clock', 'visualization': 'visualization',
                   'recorder': 'recorder', 'sensing': 'sensing', 'inject_fault': 'tool'}


def test_who_may_publish_each_topic_is_who_the_topic_registry_says_publishes_it(grants):
    """The rules of uh_security.policy against the prose of uh_wire.topics: neither may drift alone."""
    for name, spec in topics.run_topics(PAPER.ids, **topics.scenario_flags(PAPER)):
        named = {PUBLISHER_WORDS[w] for w in re.findall(r'[a-z_]+', spec.publisher) if w in PUBLISHER_WORDS}
        granted = {g.kind for g in grants if name in g.publish}
        assert granted == named, f'{name}: registry says {spec.publisher!r}, the policy lets {granted}'


def test_dds_names_follow_the_runtimes_prefixes(grants):
    uh3 = _grant(grants, '/uh3/controller')
    assert {'rt/uh3/command', 'rt/rosout', 'ros_discovery_info',
            'rr/uh3/controller/get_parametersReply'} <= set(uh3.dds_publish())
    assert {'rt/uh2/state', 'ros_discovery_info', 'rq/uh3/controller/set_parametersRequest'} <= set(uh3.dds_subscribe())
    assert not [t for t in uh3.dds_publish() + uh3.dds_subscribe() if t.startswith('rt/uh1/')]
    inspect = _grant(grants, policy.INSPECT)
    assert 'rq/*/get_parametersRequest' in inspect.dds_publish() and 'rt/*' in inspect.dds_subscribe()


def test_the_policy_xml_has_one_enclave_per_identity_in_ros2s_format(grants):
    root = ET.fromstring(policy.xml_text(policy.policy_xml(grants)).split('\n', 1)[1])
    assert root.tag == 'policy' and root.get('version') == '0.2.0'
    enclaves = root.findall('enclaves/enclave')
    assert [e.get('path') for e in enclaves] == [g.enclave for g in grants]
    uh3 = next(e for e in enclaves if e.get('path') == '/uh3/controller')
    profile = uh3.find('profiles/profile')
    assert (profile.get('ns'), profile.get('node')) == ('/uh3', 'controller')
    published = {t.text for t in profile.findall("topics[@publish='ALLOW']/topic")}
    assert published == set(_grant(grants, '/uh3/controller').publish)


def test_permissions_and_governance_documents(grants):
    doc = policy.permissions_xml(_grant(grants, '/uh3/controller'), '2030-01-01T00:00:00', '2031-01-01T00:00:00',
                                 policy.DomainRange(7, 7))
    grant = doc.find('permissions/grant')
    assert grant.findtext('subject_name') == 'CN=/uh3/controller' and grant.findtext('default') == 'DENY'
    assert grant.findtext('allow_rule/domains/id') == '7'
    assert 'rt/uh3/command' in {t.text for t in grant.findall('allow_rule/publish/topics/topic')}
    governance = policy.governance_xml().find('domain_access_rules/domain_rule')
    assert governance.findtext('allow_unauthenticated_participants') == 'false'
    assert governance.findtext('domains/id_range/max') == '230'
    assert governance.findtext('topic_access_rules/topic_rule/data_protection_kind') == 'ENCRYPT'
    with pytest.raises(ValueError, match='not within'):
        policy.DomainRange(5, 300)


# -- the keystore -------------------------------------------------------------------------------------
@pytest.fixture(scope='module')
def store(tmp_path_factory):
    path = tmp_path_factory.mktemp('ks') / 'keys'
    assert cli.main(['create', '--scenario', 'paper', '--keystore', str(path)]) == 0
    return path


def test_the_keystore_has_sros2s_layout_with_one_enclave_per_identity(store, grants):
    assert keystore.is_keystore(store)
    for enclave in [g.enclave for g in grants]:
        folder = keystore.enclave_dir(store, enclave)
        for name in ('cert.pem', 'key.pem', 'governance.p7s', 'permissions.p7s', 'identity_ca.cert.pem',
                     'permissions_ca.cert.pem'):
            assert (folder / name).is_file(), folder / name
    assert (store / 'private' / 'ca.key.pem').stat().st_mode & 0o077 == 0
    assert (keystore.enclave_dir(store, '/uh1/sim') / 'key.pem').stat().st_mode & 0o077 == 0
    assert keystore.read_metadata(store)['enclaves'] == [g.enclave for g in grants]
    assert ET.parse(store / 'policy.xml').getroot().get('version') == '0.2.0'


def test_identities_are_p256_keys_certified_by_the_keystores_ca(store):
    ca = x509.load_pem_x509_certificate((store / 'public' / 'ca.cert.pem').read_bytes())
    folder = keystore.enclave_dir(store, '/uh3/controller')
    cert = x509.load_pem_x509_certificate((folder / 'cert.pem').read_bytes())
    key = load_pem_private_key((folder / 'key.pem').read_bytes(), None)
    assert isinstance(key.curve, ec.SECP256R1) and cert.public_key() == key.public_key()
    assert cert.subject.rfc4514_string() == 'CN=/uh3/controller' and cert.issuer == ca.subject
    cert.verify_directly_issued_by(ca)    # raises if the CA did not sign it


@pytest.mark.skipif(shutil.which('openssl') is None, reason='no openssl command to verify the S/MIME signatures')
def test_the_documents_are_smime_signed_by_the_ca_and_a_changed_one_is_not(store, tmp_path):
    folder = keystore.enclave_dir(store, '/uh3/controller')

    def verify(signed: Path):
        return subprocess.run(['openssl', 'smime', '-verify', '-in', str(signed), '-CAfile',
                               str(store / 'public' / 'permissions_ca.cert.pem'), '-text'],
                              capture_output=True, text=True)
    done = verify(folder / 'permissions.p7s')
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == (folder / 'permissions.xml').read_text().strip()
    assert verify(store / 'enclaves' / 'governance.p7s').returncode == 0
    forged = tmp_path / 'forged.p7s'
    forged.write_text((folder / 'permissions.p7s').read_text().replace('<topic>rt/uh3/command</topic>',
                                                                       '<topic>rt/uh1/command</topic>'))
    assert verify(forged).returncode != 0


# -- the command ---------------------------------------------------------------------------------------
def _run(argv, capsys):
    code = cli.main(argv)
    return code, capsys.readouterr()


def test_help_and_policy_commands(capsys):
    code, out = _run(['--help'], capsys)
    assert code == 0 and 'create' in out.out and 'policy' in out.out
    code, out = _run(['policy', '--scenario', 'paper'], capsys)
    assert code == 0 and out.out.startswith('<?xml') and '<enclave path="/uh3/controller">' in out.out


@pytest.mark.parametrize('argv, message', [
    (['create', '--scenario', 'nope', '--keystore', '{tmp}/k'], r"no scenario file 'nope'; give a path"),
    (['create', '--scenario', '', '--keystore', '{tmp}/k'], r"--scenario '': give a scenario"),
    (['create', '--scenario', 'paper', '--keystore', '{tmp}/full'], r'full exists and is not a keystore; give a new'),
    (['create', '--scenario', 'paper', '--keystore', '{tmp}/file'], r'file exists and is not a directory'),
    (['create', '--scenario', 'paper', '--keystore', '{tmp}/k', '--domain-id', '300'], r'--domain-id 300 is outside'),
    (['create', '--scenario', 'paper'], r'the following arguments are required: --keystore'),
    (['remove'], r"invalid choice: 'remove'"),
])
def test_bad_input_is_one_line_and_exit_2_and_writes_nothing(argv, message, tmp_path, capsys):
    (tmp_path / 'full').mkdir()
    (tmp_path / 'full' / 'notes.txt').write_text('mine')
    (tmp_path / 'file').write_text('')
    code, out = _run([a.replace('{tmp}', str(tmp_path)) for a in argv], capsys)
    assert code == 2 and out.err.count('\n') == 1 and 'Traceback' not in out.err, out.err
    assert re.search(message, out.err), out.err
    assert not (tmp_path / 'k').exists() and sorted(p.name for p in (tmp_path / 'full').iterdir()) == ['notes.txt']


def test_an_existing_keystore_is_not_overwritten(store, capsys):
    before = (store / 'public' / 'ca.cert.pem').read_bytes()
    code, out = _run(['create', '--scenario', 'paper', '--keystore', str(store)], capsys)
    assert code == 2 and 'is a keystore already' in out.err
    assert (store / 'public' / 'ca.cert.pem').read_bytes() == before
