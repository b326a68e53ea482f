"""Parameter services, /parameter_events and /rosout of the Cyclone DDS backend, with rclpy's (Jazzy) answers.

These are what ``ros2 param`` and ``ros2 topic echo /rosout`` use. Also the ``uh param`` CLI against a node in another
process. Wire conventions: uh_runtime.dds.services.
"""
import subprocess
import sys
from pathlib import Path

import pytest
from spinning import spinning_in_thread

from uh_runtime import dds as rt
from uh_runtime import messages
from uh_runtime.dds.parameters import FloatingPointRange, ParameterDescriptor
from uh_runtime.dds.qos import qos_profile_rosout_default
from uh_runtime.dds.services import ServiceClient, parameter_value, value_message

pytestmark = pytest.mark.dds
BOUND = 10.0   # s; bounds a failure only (replies come within milliseconds on loopback)
Parameter = messages.dds_message('rcl_interfaces/msg/Parameter')


@pytest.fixture
def served(domain_id):
    """Spin a node ``/uh3/controller`` with a few parameters in a thread, with a second context to call it from.

    The second context is another participant, as ``ros2 param`` would be.
    """
    ctx = rt.Context()
    ctx.init(args=['node'])
    node = rt.Node('controller', namespace='/uh3', context=ctx)
    node.declare_parameter('outer.k1', 1.5, ParameterDescriptor(
        description='position gain', floating_point_range=[FloatingPointRange(0.0, 10.0, 0.0)]))
    node.declare_parameter('outer.rbf.nodes', 9)
    node.declare_parameter('case', 'proposed', ParameterDescriptor(read_only=True))
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    spinner = spinning_in_thread(executor, ctx, BOUND)
    spinner.__enter__()
    caller = rt.Context()
    caller.init(args=['caller'])
    clients = {}

    def call(service, **fields):
        if service not in clients:
            name = ''.join(p.capitalize() for p in service.split('_'))
            clients[service] = ServiceClient(caller, f'rcl_interfaces/srv/{name}', f'/uh3/controller/{service}')
            assert clients[service].wait_for_service(BOUND)
        client = clients[service]
        return client.call(client.request(**fields), timeout_sec=BOUND)
    yield node, call, caller
    spinner.__exit__(None, None, None)
    caller.try_shutdown()
    ctx.try_shutdown()


def test_the_six_services_exist_under_the_node_name(served):
    node, _, _ = served
    assert sorted(s.srv_name for s in node.services) == [
        f'/uh3/controller/{n}' for n in ('describe_parameters', 'get_parameter_types', 'get_parameters',
                                         'list_parameters', 'set_parameters', 'set_parameters_atomically')]


def test_list_follows_rclpy_prefixes_and_depth(served):
    _, call, _ = served
    everything = call('list_parameters').result
    assert sorted(everything.names) == ['case', 'outer.k1', 'outer.rbf.nodes', 'use_sim_time']
    assert sorted(everything.prefixes) == ['outer', 'outer.rbf']
    assert sorted(call('list_parameters', prefixes=['outer']).result.names) == ['outer.k1', 'outer.rbf.nodes']
    # depth 1: no separator in the part after the prefix
    assert call('list_parameters', prefixes=['outer'], depth=1).result.names == ['outer.k1']
    assert sorted(call('list_parameters', depth=1).result.names) == ['case', 'use_sim_time']


def test_get_and_get_types_and_describe(served):
    _, call, _ = served
    values = call('get_parameters', names=['outer.k1', 'case']).values
    assert [parameter_value(v) for v in values] == [1.5, 'proposed']
    assert call('get_parameters', names=['outer.k1', 'missing']).values == []    # rclpy: all or nothing
    assert list(call('get_parameter_types', names=['outer.k1', 'outer.rbf.nodes', 'case']).types) == [3, 2, 4]
    (d,) = call('describe_parameters', names=['outer.k1']).descriptors
    assert (d.name, d.type, d.description) == ('outer.k1', 3, 'position gain')
    assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) == (0.0, 10.0)
    assert call('describe_parameters', names=['missing']).descriptors == []


def test_set_accepts_and_rejects_with_the_reason_keeping_the_old_value(served):
    node, call, _ = served
    results = call('set_parameters', parameters=[
        Parameter(name='outer.k1', value=value_message(2.5)),      # accepted
        Parameter(name='outer.k1', value=value_message(20.0)),     # out of range
        Parameter(name='outer.k1', value=value_message(3)),        # an int for a double
        Parameter(name='case', value=value_message('case1')),      # read-only
        Parameter(name='missing', value=value_message(1.0))]).results
    assert [r.successful for r in results] == [True, False, False, False, False]
    assert 'allowed range is [0.0, 10.0]' in results[1].reason
    assert 'INTEGER' in results[2].reason and 'read-only' in results[3].reason and 'missing' in results[4].reason
    assert node.get_parameter('outer.k1').value == 2.5 and node.get_parameter('case').value == 'proposed'
    # atomically: one bad value and nothing changes
    result = call('set_parameters_atomically', parameters=[
        Parameter(name='outer.k1', value=value_message(4.0)),
        Parameter(name='outer.rbf.nodes', value=value_message('many'))]).result
    assert not result.successful and node.get_parameter('outer.k1').value == 2.5
    assert call('set_parameters_atomically', parameters=[
        Parameter(name='outer.k1', value=value_message(4.0))]).result.successful
    assert node.get_parameter('outer.k1').value == 4.0


def test_parameter_events_report_declarations_and_changes(served):
    node, call, caller = served
    listener = rt.Node('listener', context=caller)
    got = []
    listener.create_subscription(messages.dds_message('rcl_interfaces/msg/ParameterEvent'), '/parameter_events',
                                 got.append, 1000)
    executor = rt.SingleThreadedExecutor(context=caller)
    executor.add_node(listener)
    client = ServiceClient(caller, 'rcl_interfaces/srv/SetParameters', '/uh3/controller/set_parameters')
    assert client.wait_for_service(BOUND)
    import time
    deadline = time.monotonic() + BOUND
    while not listener.count_publishers('/parameter_events') and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    client.call(client.request(parameters=[Parameter(name='outer.k1', value=value_message(7.5))]), BOUND)
    node.declare_parameter('late', True)
    while len(got) < 2 and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    changed = [e for e in got if e.changed_parameters]
    new = [e for e in got if e.new_parameters]
    assert changed and changed[0].node == '/uh3/controller'
    assert changed[0].changed_parameters[0].name == 'outer.k1'
    assert parameter_value(changed[0].changed_parameters[0].value) == 7.5
    assert new and new[0].new_parameters[0].name == 'late'


def test_rosout_carries_each_log_record_with_rclpy_fields(domain_id):
    ctx = rt.Context()
    ctx.init(args=['x'])
    try:
        node = rt.Node('talker', namespace='/uh2', context=ctx)
        node.get_logger().warning('rotor check')      # before anyone listens: rosout is transient-local
        listener = rt.Node('listener', context=ctx)
        got = []
        listener.create_subscription(messages.dds_message('rcl_interfaces/msg/Log'), '/rosout', got.append,
                                     qos_profile_rosout_default)
        executor = rt.SingleThreadedExecutor(context=ctx)
        executor.add_node(listener)
        import time
        deadline = time.monotonic() + BOUND
        while not any(m.msg == 'rotor check' for m in got) and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        (log,) = [m for m in got if m.msg == 'rotor check']
        assert (log.level, log.name) == (30, 'uh2.talker')
        assert log.file.endswith('test_parameter_services.py') and log.function.startswith('test_rosout')
        assert log.stamp.sec > 1_600_000_000
        quiet = rt.Node('quiet', context=ctx, cli_args=['--ros-args', '--disable-rosout-logs'])
        assert quiet._rosout is None and node._rosout is not None
        # like rclpy: rcl's rosout publisher is not among the node's publishers, /parameter_events is
        assert [p.topic_name for p in node.publishers] == ['/parameter_events']
    finally:
        ctx.try_shutdown()


NODE = '''
import sys, time
from uh_runtime import dds as rt
from uh_runtime.dds.parameters import ParameterDescriptor, FloatingPointRange
rt.init(args=sys.argv)
node = rt.Node('controller', namespace='/uh1')
node.declare_parameter('stale_timeout', 0.25, ParameterDescriptor(
    description='s', floating_point_range=[FloatingPointRange(0.0, 60.0, 0.0)]))
print('ready', flush=True)
end = time.monotonic() + 60
while time.monotonic() < end and rt.ok():
    rt.spin_once(node, timeout_sec=0.1)
'''


def test_uh_param_cli_against_a_node_in_another_process(domain_id, processes):
    proc = processes.start([sys.executable, '-c', NODE], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == 'ready'
    uh = str(Path(sys.executable).with_name('uh'))

    def run(*argv):
        return subprocess.run([uh, 'param', *argv], capture_output=True, text=True, timeout=60)
    listed = run('list', '/uh1/controller')
    assert listed.returncode == 0 and listed.stdout.split() == ['stale_timeout', 'use_sim_time'], listed
    assert run('get', '/uh1/controller', 'stale_timeout').stdout.strip() == 'Double value is: 0.25'
    ok = run('set', '/uh1/controller', 'stale_timeout', '0.5')
    assert ok.returncode == 0 and 'Set parameter successful' in ok.stdout
    assert run('get', '/uh1/controller', 'stale_timeout').stdout.strip() == 'Double value is: 0.5'
    bad = run('set', '/uh1/controller', 'stale_timeout', '100.0')
    assert bad.returncode == 1 and 'allowed range is [0.0, 60.0]' in bad.stderr
    missing = run('get', '/uh1/controller', 'nope')
    assert missing.returncode == 1 and "parameter 'nope' is not declared by /uh1/controller" in missing.stderr
    described = run('describe', '/uh1/controller', 'stale_timeout').stdout
    assert 'Type: double' in described and 'Max value: 60.0' in described
    nobody = run('get', '/uh9/controller', 'x', '--spin-time', '0.5')
    assert nobody.returncode == 1 and "no parameter services of node '/uh9/controller'" in nobody.stderr


def test_a_client_that_cannot_be_answered_is_named_once_and_ours_is_not(served, monkeypatch):
    """A Fast DDS client (Jazzy's default) sends requests without rmw_cyclonedds' header: the node says so, once.

    Its request writer does not say ``clientid=`` in USER_DATA, as this backend's and rmw_cyclonedds' do.
    """
    import time

    from cyclonedds.pub import DataWriter

    from uh_runtime.dds.context import typehash_user_data
    from uh_runtime.dds.qos import to_dds_qos
    from uh_runtime.dds.services import FOREIGN_CLIENT_CHECK_S, qos_profile_parameters
    node, call, caller = served
    warnings = []
    logger = node.get_logger()
    monkeypatch.setattr(logger, 'warning', lambda text, **kw: warnings.append(text))
    assert call('get_parameters', names=['outer.k1']).values     # this backend's client: answered, not named
    time.sleep(2.5 * FOREIGN_CLIENT_CHECK_S)
    assert warnings == []
    cls = messages.dds_service_message('rcl_interfaces/srv/GetParameters_Request')
    topic = caller.topic('rq/uh3/controller/get_parametersRequest', cls)
    writers = [DataWriter(caller._pub, topic, qos=to_dds_qos(qos_profile_parameters, typehash_user_data(cls)))
               for _ in range(2)]                  # as Fast DDS's request writer: a type hash, no clientid
    deadline = time.monotonic() + BOUND
    while not warnings and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(2.5 * FOREIGN_CLIENT_CHECK_S)
    assert len(warnings) == 1, warnings
    assert 'RMW_IMPLEMENTATION=rmw_cyclonedds_cpp' in warnings[0] and 'uh param' in warnings[0]
    assert '/uh3/controller/' in warnings[0]
    del writers
