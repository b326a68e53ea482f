"""Process-level tests of the Cyclone DDS backend: wire conventions checked through DDS discovery.

Separate processes (tests/helpers_runtime/talker.py and listener.py, built like the project's
nodes) talk on a private domain; what they put on the wire is read back through the DDS builtin
topics (DCPSParticipant/DCPSPublication/DCPSSubscription) and ``ros_discovery_info``, never from
the nodes' own configuration. Every wait is on an event with a bounded timeout.
"""
import json
import os
import selectors
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from cyclonedds.qos import Policy

from uh_runtime.dds.graph import Graph, user_data_value
from uh_runtime.messages import typestore

pytestmark = pytest.mark.dds

HELPERS = Path(__file__).resolve().parent / 'helpers_runtime'
TIMEOUT = 20.0  # s; discovery on loopback takes well under a second, this only bounds a failure


def _start(processes, script, *ros_args, cwd):
    # cwd outside the repository: the top-level package folders must not shadow the packages
    return processes.start([sys.executable, str(HELPERS / script), '--ros-args', *ros_args],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd)


def _read_line(proc, timeout=TIMEOUT):
    """Next stdout line of ``proc`` (None on timeout or exit)."""
    sel = selectors.DefaultSelector()
    sel.register(proc.stdout, selectors.EVENT_READ)
    ready = sel.select(timeout)
    sel.close()
    return proc.stdout.readline() if ready else None


def _talker_discovered(graph, node='talker', namespace='/uh3'):
    def check(g):
        # the talker creates its writer, then its reader: wait until both are known by node name
        writers = g.endpoints(f'{namespace}/state', writers=True)
        readers = g.endpoints(f'{namespace}/command', writers=False)
        return (bool(writers) and writers[0].node_name == node
                and bool(readers) and readers[0].node_name == node)
    return check


def _wait_discovered(graph, proc, node='talker', namespace='/uh3'):
    """Wait until ``proc``'s talker is discovered; on failure say what the process did."""
    if graph.wait_until(_talker_discovered(graph, node, namespace), TIMEOUT):
        return
    state = 'running' if proc.poll() is None else f'exited with {proc.returncode}: {proc.stderr.read()}'
    pytest.fail(f'{namespace}/{node} not discovered within {TIMEOUT} s; process {state}; '
                f'graph: nodes {graph.node_names_and_namespaces()}, '
                f'topics {graph.topic_names_and_types()}')


@pytest.fixture
def graph(domain_id):
    g = Graph(domain_id=domain_id)
    yield g
    g.close()


def test_two_processes_exchange_uhstate_on_ros_topic_and_type_names_with_declared_qos(
        domain_id, processes, graph, tmp_path):
    talker = _start(processes, 'talker.py', '-r', '__ns:=/uh3', '-p', 'uh_id:=3', cwd=tmp_path)
    listener = _start(processes, 'listener.py', '-r', '__ns:=/uh3', '-p', 'count:=3', cwd=tmp_path)

    lines = [_read_line(listener) for _ in range(3)]
    assert all(lines), f'listener got {lines}; stderr: {listener.stderr.read() if listener.poll() is not None else ""}'
    received = [json.loads(line) for line in lines]
    for msg in received:
        assert msg['uh_id'] == 3 and msg['frame_id'] == 'world'
        assert msg['x'] == 1.5 * msg['step'] and msg['vz'] == -2.25 and msg['yaw'] == 0.125
    assert [m['step'] for m in received] == sorted(m['step'] for m in received)
    assert listener.wait(timeout=TIMEOUT) == 0

    # what the talker announced, as any DDS participant (e.g. ROS 2) discovers it
    _wait_discovered(graph, talker)
    writers = [w for w in graph.writers.values() if w.topic_name == 'rt/uh3/state']
    assert len(writers) == 1
    w = writers[0]
    assert w.type_name == 'uh_msgs::msg::dds_::UHState_'
    assert w.qos[Policy.Reliability] == Policy.Reliability.Reliable(max_blocking_time=0x7FFFFFFFFFFFFFFF)
    assert w.qos[Policy.History] == Policy.History.KeepLast(7)
    assert w.qos[Policy.Durability] == Policy.Durability.Volatile
    assert w.qos[Policy.WriterDataLifecycle] == Policy.WriterDataLifecycle(autodispose=False)
    assert w.qos[Policy.DataRepresentation] == Policy.DataRepresentation(use_cdrv0_representation=True)
    expected_hash = typestore().hash_rihs01('uh_msgs/msg/UHState')
    assert w.qos[Policy.Userdata].data == f'typehash={expected_hash};'.encode()

    readers = [r for r in graph.readers.values() if r.topic_name == 'rt/uh3/command']
    assert len(readers) == 1
    r = readers[0]
    assert r.type_name == 'uh_msgs::msg::dds_::ActuatorCommand_'
    assert r.qos[Policy.Reliability] == Policy.Reliability.BestEffort
    assert r.qos[Policy.History] == Policy.History.KeepLast(3)
    assert user_data_value(r.qos, 'typehash') == typestore().hash_rihs01('uh_msgs/msg/ActuatorCommand')

    participant_qos = graph.participants[w.participant_key]
    assert participant_qos[Policy.Userdata].data == b'enclave=/;'


def test_ros_discovery_info_names_the_node_and_lists_its_endpoint_gids(domain_id, processes, graph,
                                                                        tmp_path):
    proc = _start(processes, 'talker.py', '-r', '__ns:=/uh3', '-r', '__node:=sim', cwd=tmp_path)
    _wait_discovered(graph, proc, node='sim')

    info_topic = [w for w in graph.writers.values() if w.topic_name == 'ros_discovery_info']
    assert len(info_topic) == 1  # one per participant, as rmw_cyclonedds
    iw = info_topic[0]
    assert iw.type_name == 'rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_'
    assert iw.qos[Policy.Durability] == Policy.Durability.TransientLocal
    assert iw.qos[Policy.History] == Policy.History.KeepLast(1)
    assert iw.qos[Policy.Reliability] == Policy.Reliability.Reliable(max_blocking_time=0x7FFFFFFFFFFFFFFF)

    participant = iw.participant_key
    info = graph.infos[participant.bytes]
    # rmw_cyclonedds_cpp: gid.data = the 16 bytes of the DDS GUID (convert_guid_to_gid)
    assert bytes(info.gid.data) == participant.bytes
    assert [(n.node_name, n.node_namespace) for n in info.node_entities_info_seq] == [('sim', '/uh3')]
    node = info.node_entities_info_seq[0]
    # every ROS endpoint of the node: topics (rt/) and its parameter services (rq/ readers, rr/ writers)
    ros_writers = {k.bytes: w.topic_name for k, w in graph.writers.items()
                   if w.participant_key == participant and w.topic_name[:3] in ('rt/', 'rr/')}
    ros_readers = {k.bytes: r.topic_name for k, r in graph.readers.items()
                   if r.participant_key == participant and r.topic_name[:3] in ('rt/', 'rq/')}
    assert {bytes(g.data) for g in node.writer_gid_seq} == set(ros_writers)
    assert {bytes(g.data) for g in node.reader_gid_seq} == set(ros_readers)
    services = ('describe_parameters', 'get_parameter_types', 'get_parameters', 'list_parameters',
                'set_parameters', 'set_parameters_atomically')
    assert sorted(ros_writers.values()) == sorted(
        ['rt/parameter_events', 'rt/rosout', 'rt/uh3/state'] + [f'rr/uh3/sim/{s}Reply' for s in services])
    assert sorted(ros_readers.values()) == sorted(
        ['rt/uh3/command'] + [f'rq/uh3/sim/{s}Request' for s in services])


def _uh(*args, domain_id):
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id))
    return subprocess.run([sys.executable, '-m', 'uh_runtime.cli.uh', *args], capture_output=True,
                          text=True, timeout=TIMEOUT + 10, env=env, cwd=HELPERS.parent.parent / 'docs')


def test_uh_cli_lists_topics_and_nodes_and_echoes(domain_id, processes, graph, tmp_path):
    proc = _start(processes, 'talker.py', '-r', '__ns:=/uh3', '-p', 'uh_id:=3', cwd=tmp_path)
    _wait_discovered(graph, proc)

    listed = _uh('topic', 'list', '-t', domain_id=domain_id)
    assert listed.returncode == 0, listed.stderr
    assert listed.stdout.splitlines() == ['/parameter_events [rcl_interfaces/msg/ParameterEvent]',
                                          '/rosout [rcl_interfaces/msg/Log]',
                                          '/uh3/command [uh_msgs/msg/ActuatorCommand]',
                                          '/uh3/state [uh_msgs/msg/UHState]']   # as ros2 topic list -t
    nodes = _uh('node', 'list', domain_id=domain_id)
    assert nodes.returncode == 0, nodes.stderr
    assert nodes.stdout.splitlines() == ['/uh3/talker']

    echo = _uh('topic', 'echo', '/uh3/state', '--once', '--timeout', str(TIMEOUT), domain_id=domain_id)
    assert echo.returncode == 0, echo.stderr
    text, sep, rest = echo.stdout.partition('---\n')
    assert sep and rest == ''
    import yaml
    msg = yaml.safe_load(text)
    assert msg['uh_id'] == 3 and msg['header']['frame_id'] == 'world'
    assert msg['position']['x'] == 1.5 * msg['step'] and msg['velocity'] == {'x': 0.0, 'y': 0.0, 'z': -2.25}

    field = _uh('topic', 'echo', '/uh3/state', '--once', '--field', 'euler.z', domain_id=domain_id)
    assert field.returncode == 0 and field.stdout == '0.125\n---\n'

    info = _uh('topic', 'info', '/uh3/state', '-v', domain_id=domain_id)
    assert info.returncode == 0, info.stderr
    assert 'Publisher count: 1' in info.stdout and 'Node name: talker' in info.stdout
    assert 'Node namespace: /uh3' in info.stdout and 'History (Depth): KEEP_LAST (7)' in info.stdout


def test_uh_echo_of_a_topic_nobody_publishes_waits_then_times_out(domain_id):
    result = _uh('topic', 'echo', '/nobody/here', '--timeout', '1', domain_id=domain_id)
    assert result.returncode == 1
    assert 'does not appear to be published yet' in result.stderr
    assert 'no publisher of /nobody/here appeared within 1.0 s' in result.stderr


@pytest.mark.parametrize('ros_args, expected', [
    (['-p', 'nope:=1'],
     "node 'talker' does not declare parameter 'nope'; declared parameters: frame_id, rate, teardown_s, uh_id"),
    (['-p', 'uh_id:=99'], "parameter 'uh_id': value 99 rejected: allowed range is [1, 20]"),
    (['-p', 'uh_id:=abc'],
     "parameter 'uh_id': value 'abc' has type STRING, allowed type is INTEGER"),
    (['-p', 'rate:=0.5'], "parameter 'rate': value 0.5 rejected: allowed range is [1.0, 1000.0]"),
    (['-p', 'rate:=fast'], "parameter 'rate': value 'fast' has type STRING, allowed type is DOUBLE"),
    (['-r', 'bad rule'], 'remap rule'),
    (['--bogus'], "Found unknown ROS argument '--bogus'"),
])
def test_bad_parameters_exit_non_zero_with_a_clear_message(processes, domain_id, tmp_path,
                                                           ros_args, expected):
    proc = _start(processes, 'talker.py', *ros_args, cwd=tmp_path)
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2      # bad input
    assert expected in err
    assert 'Traceback' not in err


def test_params_file_with_wildcard_and_node_keys(processes, domain_id, tmp_path, graph):
    params = tmp_path / 'params.yaml'
    params.write_text('/**:\n  ros__parameters:\n    rate: 20.0  # Hz\n'
                      '/uh5/talker:\n  ros__parameters:\n    uh_id: 5\n')
    proc = _start(processes, 'talker.py', '-r', '__ns:=/uh5', '--params-file', str(params), cwd=tmp_path)
    _wait_discovered(graph, proc, namespace='/uh5')
    echo = _uh('topic', 'echo', '/uh5/state', '--once', '--field', 'uh_id', domain_id=domain_id)
    assert echo.stdout == '5\n---\n'

    bad = tmp_path / 'bad.yaml'
    bad.write_text('/**:\n  ros__parameters:\n    uh_id: 0\n')
    proc = _start(processes, 'talker.py', '--params-file', str(bad), cwd=tmp_path)
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 2 and "parameter 'uh_id': value 0 rejected" in err


def test_a_second_sigint_does_not_cut_the_teardown_short(processes, domain_id, tmp_path, graph):
    """Ctrl-C under ros2 launch: the terminal's SIGINT and launch's own reach each node at once.

    The second one lands in ``destroy_node`` (here made to take 1 s) and must not interrupt it.
    """
    import time
    proc = _start(processes, 'talker.py', '-r', '__ns:=/uh3', '-p', 'teardown_s:=1.0', cwd=tmp_path)
    _wait_discovered(graph, proc)
    proc.send_signal(signal.SIGINT)
    time.sleep(0.3)     # well inside the 1 s teardown (a failure only shows as the traceback below)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 0, err
    assert 'teardown complete' in err and 'Traceback' not in err


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_sigint_and_sigterm_end_the_node_cleanly(processes, domain_id, tmp_path, graph, sig):
    proc = _start(processes, 'talker.py', '-r', '__ns:=/uh3', cwd=tmp_path)
    _wait_discovered(graph, proc)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=TIMEOUT)
    assert proc.returncode == 0, err
    assert 'Traceback' not in err
    # the participant left the domain (deleted on shutdown), so its node is gone from the graph
    assert graph.wait_until(lambda g: ('talker', '/uh3') not in g.node_names_and_namespaces(), TIMEOUT)
