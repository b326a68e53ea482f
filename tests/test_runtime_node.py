"""The Cyclone DDS backend's Node, parameters, executor, timers and sim time, in one process.

Each test has its own context (one DDS participant) on a private domain. Waits are on events:
``spin_until`` spins the executor until a condition holds, failing after a bound.
"""
import pytest
import spinning

from uh_runtime import dds as rt
from uh_runtime import messages
from uh_runtime.dds.parameters import (
    FloatingPointRange,
    IntegerRange,
    InvalidParameterTypeException,
    InvalidParameterValueException,
    Parameter,
    ParameterAlreadyDeclaredException,
    ParameterDescriptor,
    ParameterNotDeclaredException,
    ParameterUninitializedException,
    SetParametersResult,
    UnknownParameterOverrideError,
)
from uh_runtime.dds.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from uh_runtime.runner import check_parameter_overrides

pytestmark = pytest.mark.dds
BOUND = 10.0  # s; only bounds a failure, events arrive within milliseconds on loopback


@pytest.fixture
def ctx(domain_id):
    context = rt.Context()
    context.init(args=['test'])
    yield context
    context.try_shutdown()


def spin_until(executor, condition, bound=BOUND):
    spinning.spin_until(executor, condition, bound)


def test_names_namespace_and_remaps(ctx):
    node = rt.Node('sim', namespace='uh1', context=ctx)
    assert (node.get_name(), node.get_namespace(), node.get_fully_qualified_name()) == \
        ('sim', '/uh1', '/uh1/sim')
    assert node.create_publisher(messages.UHState, 'state', 10).topic_name == '/uh1/state'
    assert node.create_publisher(messages.UHState, '~/debug', 10).topic_name == '/uh1/sim/debug'
    assert node.get_logger().name == 'uh1.sim'
    other = rt.Node('sim', context=ctx, cli_args=[
        '--ros-args', '-r', '__ns:=/uh2', '-r', '__node:=plant', '-r', 'state:=/elsewhere'])
    assert other.get_fully_qualified_name() == '/uh2/plant'
    assert other.create_publisher(messages.UHState, 'state', 10).topic_name == '/elsewhere'
    with pytest.raises(ValueError, match='invalid node name'):
        rt.Node('bad-name', context=ctx)


def test_parameters_declared_validated_and_overridden(ctx):
    node = rt.Node('ctl', context=ctx, parameter_overrides=[
        Parameter('gain', value=2.5), Parameter('steps', value=40), Parameter('typo', value=1)])
    rng = ParameterDescriptor(floating_point_range=[FloatingPointRange(from_value=0.0, to_value=5.0)])
    assert node.declare_parameter('gain', 1.0, rng).value == 2.5
    assert node.declare_parameter('steps', 10, ParameterDescriptor(
        integer_range=[IntegerRange(from_value=1, to_value=100)])).value == 40
    assert node.declare_parameter('name', 'x', ParameterDescriptor(read_only=True)).value == 'x'
    assert node.get_parameter('use_sim_time').value is False
    with pytest.raises(ParameterAlreadyDeclaredException, match="'gain' has already been declared"):
        node.declare_parameter('gain', 1.0)
    with pytest.raises(ParameterNotDeclaredException,
                       match="parameter 'nope' is not declared; declared parameters: gain, name, steps, use_sim_time"):
        node.get_parameter('nope')
    with pytest.raises(UnknownParameterOverrideError,
                       match="node 'ctl' does not declare parameter 'typo'; declared parameters: gain, name, steps"):
        check_parameter_overrides(node)
    check_parameter_overrides(node, ignore=['ty*'])

    result = node.set_parameters([Parameter('gain', value=7.0)])[0]
    assert not result.successful and 'allowed range is [0.0, 5.0]' in result.reason
    result = node.set_parameters([Parameter('gain', value=3)])[0]
    assert not result.successful and 'allowed type is DOUBLE' in result.reason
    result = node.set_parameters([Parameter('name', value='y')])[0]
    assert not result.successful and 'read-only' in result.reason
    assert node.set_parameters([Parameter('gain', value=4.0)])[0].successful
    assert node.get_parameter('gain').value == 4.0

    seen = []

    def veto(params):
        seen.extend(p.name for p in params)
        return SetParametersResult(successful=all(p.value != 13 for p in params), reason='unlucky')
    node.add_on_set_parameters_callback(veto)
    assert not node.set_parameters([Parameter('steps', value=13)])[0].successful
    with pytest.raises(InvalidParameterValueException, match="parameter 'lucky': value 13 rejected: unlucky"):
        node.declare_parameter('lucky', 13)
    assert seen == ['steps', 'lucky']


def test_pre_set_callbacks_change_what_is_set_as_rclpy_does(ctx):
    # rclpy (Jazzy) Node._set_parameters_atomically: the pre-set callbacks' lists, joined, are set atomically
    # instead (on-set and post-set callbacks see them); an empty list is refused; declaring calls none
    node = rt.Node('ctl', context=ctx)
    node.declare_parameter('gain', 1.0)
    node.declare_parameter('gain_squared', 1.0)
    calls, validated, posted = [], [], []

    def square_too(params):
        calls.append([p.name for p in params])
        return params + [Parameter('gain_squared', value=p.value ** 2) for p in params if p.name == 'gain']

    def drop_typos(params):
        return [p for p in params if p.name != 'gian']

    node.add_pre_set_parameters_callback(square_too)
    node.add_pre_set_parameters_callback(drop_typos)
    node.add_on_set_parameters_callback(lambda params: validated.append([p.name for p in params])
                                        or SetParametersResult(successful=True))
    node.add_post_set_parameters_callback(lambda params: posted.append([(p.name, p.value) for p in params]))
    node.declare_parameter('steps', 10)
    assert calls == [] and validated == [['steps']]
    assert node.set_parameters_atomically([Parameter('gain', value=3.0)]).successful
    assert calls == [['gain']]
    assert validated[-1] == ['gain', 'gain', 'gain_squared']   # drop_typos' list, then square_too's
    assert (node.get_parameter('gain').value, node.get_parameter('gain_squared').value) == (3.0, 9.0)
    assert posted[-1] == [('gain', 3.0), ('gain', 3.0), ('gain_squared', 9.0)]
    other = rt.Node('other', context=ctx)
    other.add_pre_set_parameters_callback(drop_typos)
    result = other.set_parameters([Parameter('gian', value=2.0)])[0]   # before the undeclared check, as rclpy
    assert not result.successful and 'parameter list cannot be empty' in result.reason


def test_override_type_and_range_errors_name_the_parameter(ctx):
    node = rt.Node('sim', context=ctx, cli_args=['--ros-args', '-p', 'rate:=20', '-p', 'uh_id:=0'])
    with pytest.raises(InvalidParameterTypeException,
                       match="parameter 'rate': value 20 has type INTEGER, allowed type is DOUBLE"):
        node.declare_parameter('rate', 10.0)
    with pytest.raises(InvalidParameterValueException,
                       match=r"parameter 'uh_id': value 0 rejected: allowed range is \[1, 20\]"):
        node.declare_parameter('uh_id', 1, ParameterDescriptor(
            integer_range=[IntegerRange(from_value=1, to_value=20)]))
    node.declare_parameter('later', Parameter.Type.DOUBLE)
    with pytest.raises(ParameterUninitializedException, match="'later' is declared without a value"):
        node.get_parameter('later')
    with pytest.raises(ValueError, match='statically typed parameter without a default'):
        node.declare_parameter('nothing', None, ParameterDescriptor())


def test_overrides_come_from_global_args_and_match_the_node(domain_id, tmp_path):
    params = tmp_path / 'p.yaml'
    params.write_text('/**:\n  ros__parameters:\n    rate: 5.0\n'
                      '/uh1/sim:\n  ros__parameters:\n    uh_id: 1\n'
                      '/uh2/sim:\n  ros__parameters:\n    uh_id: 2\n')
    context = rt.Context()
    context.init(args=['prog', '--ros-args', '--params-file', str(params), '-p', 'sim:rate:=7.0'])
    try:
        one = rt.Node('sim', namespace='/uh1', context=context)
        two = rt.Node('sim', namespace='/uh2', context=context)
        other = rt.Node('ctl', namespace='/uh2', context=context)
        assert one.declare_parameter('uh_id', 0).value == 1
        assert two.declare_parameter('uh_id', 0).value == 2
        assert one.declare_parameter('rate', 1.0).value == 7.0  # -p after the file wins
        assert other.declare_parameter('rate', 1.0).value == 5.0
        assert not other.has_parameter('uh_id')
    finally:
        context.try_shutdown()


def test_executor_runs_several_nodes_and_timers_in_the_spinning_thread(ctx):
    import threading
    talker = rt.Node('talker', context=ctx)
    listener = rt.Node('listener', context=ctx)
    qos = QoSProfile(depth=64)  # holds all 50 messages published before the first spin
    pub = talker.create_publisher(messages.UHState, '/chatter', qos)
    got, threads = [], []
    listener.create_subscription(messages.UHState, '/chatter',
                                 lambda m: (got.append(m.step), threads.append(threading.get_ident())), qos)
    ticks = []
    talker.create_timer(0.005, lambda: ticks.append(threading.get_ident()))
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(talker)
    executor.add_node(listener)
    spin_until(executor, lambda: pub.get_subscription_count() == 1)
    for step in range(50):
        msg = messages.UHState()
        msg.step = step
        pub.publish(msg)
    spin_until(executor, lambda: len(got) == 50 and len(ticks) >= 3)
    assert got == list(range(50))  # reliable, taken in batches, in order
    assert set(threads) == set(ticks) == {threading.get_ident()}
    with pytest.raises(TypeError, match='expected uh_msgs/msg/UHState on /chatter, got Header'):
        pub.publish(messages.Header())


def test_raw_subscription_gets_the_cdr_bytes(ctx):
    node = rt.Node('rec', context=ctx)
    pub = node.create_publisher(messages.Reference, 'ref', 10)
    raw = []
    node.create_subscription(messages.Reference, 'ref', raw.append, 10, raw=True)
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    spin_until(executor, lambda: pub.get_subscription_count() == 1)
    msg = messages.Reference()
    msg.header.frame_id = 'world'
    msg.yaw = 0.5
    pub.publish(msg)
    spin_until(executor, lambda: raw)
    data = msg.serialize(use_version_2=False)
    assert raw[0] == data.ljust((len(data) + 3) & ~3, b'\0')
    assert messages.Reference.deserialize(raw[0]) == msg


def test_sim_time_follows_clock_and_drives_timers(ctx):
    node = rt.Node('ctl', context=ctx, parameter_overrides=[Parameter('use_sim_time', value=True)])
    clock_node = rt.Node('clock', context=ctx)
    clock_pub = clock_node.create_publisher(
        messages.Clock, '/clock', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    fired = []
    node.create_timer(0.1, lambda: fired.append(node.get_clock().now().nanoseconds))
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    executor.add_node(clock_node)
    assert node.get_clock().ros_time_is_active and node.get_clock().now().nanoseconds == 0
    spin_until(executor, lambda: clock_pub.get_subscription_count() == 1)

    def tick(ns):
        msg = messages.Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(ns, 1_000_000_000)
        clock_pub.publish(msg)
        spin_until(executor, lambda: node.get_clock().now().nanoseconds == ns)

    tick(50_000_000)
    assert fired == []
    tick(250_000_000)   # a jump over two periods fires once, like rcl
    tick(300_000_000)
    tick(1_000_000_000)
    assert fired == [250_000_000, 300_000_000, 1_000_000_000]
    now = node.get_clock().now()
    assert now.seconds_nanoseconds() == (1, 0) and now.to_msg().sec == 1


def test_graph_queries_see_local_and_discovered_endpoints(ctx):
    node = rt.Node('sim', namespace='/uh1', context=ctx)
    node.create_publisher(messages.UHState, 'state',
                          QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    other = rt.Node('ctl', namespace='/uh1', context=ctx)
    other.create_subscription(messages.UHState, '/uh1/state', lambda m: None,
                              QoSProfile(history=HistoryPolicy.KEEP_ALL))
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    spin_until(executor, lambda: node.count_subscribers('state') == 1 and node.count_publishers('state') == 1)
    infos = node.get_publishers_info_by_topic('state')
    assert [(i.node_name, i.node_namespace, i.topic_type) for i in infos] == \
        [('sim', '/uh1', 'uh_msgs/msg/UHState')]
    assert infos[0].qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
    (state_pub,) = [p for p in node.publishers if p.topic_name == '/uh1/state']
    assert infos[0].endpoint_gid == state_pub.gid
    subs = node.get_subscriptions_info_by_topic('/uh1/state')
    assert subs[0].node_name == 'ctl' and subs[0].qos_profile.history == HistoryPolicy.KEEP_ALL
    assert ('/uh1/state', ['uh_msgs/msg/UHState']) in node.get_topic_names_and_types()
    assert set(node.get_node_names_and_namespaces()) >= {('sim', '/uh1'), ('ctl', '/uh1')}


def test_destroy_and_shutdown(ctx):
    node = rt.Node('n', context=ctx)
    sub = node.create_subscription(messages.UHState, 's', lambda m: None, 10)
    timer = node.create_timer(1.0, lambda: None)
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    executor.spin_once(timeout_sec=0)
    assert node.destroy_subscription(sub) and not node.destroy_subscription(sub)
    assert node.destroy_timer(timer) and timer.is_canceled()
    executor.spin_once(timeout_sec=0)
    names = [(n.node_name, n.node_namespace) for n in ctx.discovery_info().node_entities_info_seq]
    assert names == [('n', '/')]
    ctx.try_shutdown()
    assert not ctx.ok()
    with pytest.raises(rt.ExternalShutdownException):
        executor.spin_once(timeout_sec=0)
    with pytest.raises(rt.NotInitializedException):
        rt.Node('late', context=ctx)
