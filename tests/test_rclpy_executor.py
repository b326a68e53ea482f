"""``uh_runtime.rclpy_backend.executors.StaticSingleThreadedExecutor`` on rclpy (docs/runtime.md#executors-on-rclpy).

It must run every kind of entity the way rclpy's ``SingleThreadedExecutor`` does: messages in
order, timers, services and clients, guard conditions, coroutine callbacks, futures, entities
created or destroyed while spinning, and callback exceptions. Needs a sourced ROS 2 Jazzy (the
project's ``uh_msgs`` is not needed); skipped with the reason elsewhere, as in CI.
"""
import threading
import time

import pytest

rclpy = pytest.importorskip('rclpy', reason='needs a sourced ROS 2 Jazzy (rclpy not importable)')
from rcl_interfaces.srv import ListParameters  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from std_msgs.msg import Int64  # noqa: E402

from uh_runtime.rclpy_backend.executors import StaticSingleThreadedExecutor  # noqa: E402

pytestmark = [pytest.mark.ros, pytest.mark.rclpy_real, pytest.mark.dds]
BOUND = 20.0  # s of wall time; bounds a failure only


@pytest.fixture
def context(domain_id):
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=domain_id)
    yield ctx
    rclpy.try_shutdown(context=ctx)


@pytest.fixture
def executor(context):
    ex = StaticSingleThreadedExecutor(context=context)
    yield ex
    ex.shutdown()


def _spin_until(executor, done, bound=BOUND):
    deadline = time.monotonic() + bound
    while not done():
        assert time.monotonic() < deadline, 'condition not reached while spinning'
        executor.spin_once(timeout_sec=0.1)


def _publish_when_matched(executor, pub, matched, values):
    """Spin until ``pub`` has ``matched`` subscriptions, then publish ``Int64`` ``values``."""
    _spin_until(executor, lambda: pub.get_subscription_count() == matched)
    for value in values:
        pub.publish(Int64(data=value))


def _node(context, name, **kwargs):
    return rclpy.create_node(name, context=context, **kwargs)


def test_messages_arrive_in_order_also_on_a_subscription_created_while_spinning(context, executor):
    node = _node(context, 'listener')
    talker = _node(context, 'talker')
    executor.add_node(node)
    executor.add_node(talker)
    first, second = [], []
    node.create_subscription(Int64, 'a', lambda m: first.append(m.data), 100)
    pub_a = talker.create_publisher(Int64, 'a', 100)
    _publish_when_matched(executor, pub_a, 1, range(50))
    _spin_until(executor, lambda: len(first) == 50)
    assert first == list(range(50))

    # created after the wait set was built: the executor must rebuild it
    node.create_subscription(Int64, 'b', lambda m: second.append(m.data), 100)
    pub_b = talker.create_publisher(Int64, 'b', 100)
    _spin_until(executor, lambda: pub_b.get_subscription_count() == 1)
    for k in range(20):
        pub_b.publish(Int64(data=k))
        pub_a.publish(Int64(data=100 + k))
    _spin_until(executor, lambda: len(second) == 20 and len(first) == 70)
    assert second == list(range(20)) and first[50:] == list(range(100, 120))


def test_a_subscription_destroyed_by_a_callback_gets_no_more_messages(context, executor):
    node = _node(context, 'listener')
    executor.add_node(node)
    got, other = [], []
    subs = {}

    def once(msg):
        got.append(msg.data)
        node.destroy_subscription(subs['once'])
    subs['once'] = node.create_subscription(Int64, 'a', once, 100)
    node.create_subscription(Int64, 'a', lambda m: other.append(m.data), 100)
    pub = node.create_publisher(Int64, 'a', 100)
    _publish_when_matched(executor, pub, 2, range(10))
    _spin_until(executor, lambda: len(other) == 10)
    assert got == [0]


def test_timers_fire_and_a_cancelled_timer_stays_quiet_until_reset(context, executor):
    node = _node(context, 'timers')
    executor.add_node(node)
    ticks, one_shot = [], []
    node.create_timer(0.01, lambda: ticks.append(time.monotonic()))
    shot = node.create_timer(0.02, lambda: (one_shot.append(1), shot.cancel()))
    _spin_until(executor, lambda: len(ticks) >= 20)
    assert one_shot == [1]
    shot.reset()
    _spin_until(executor, lambda: len(one_shot) == 2)
    assert shot.is_canceled()


def test_a_client_on_rclpys_executor_gets_answers_from_services_spun_by_this_one(context, executor):
    server = _node(context, 'server')  # rclpy's parameter services, plus one of ours
    server.declare_parameter('gain', 1.5)
    executor.add_node(server)
    serving = threading.Event()

    def run():
        serving.set()
        while context.ok() and not stop.is_set():
            executor.spin_once(timeout_sec=0.05)
    stop = threading.Event()
    thread = threading.Thread(target=run)
    thread.start()
    try:
        client_node = _node(context, 'client')
        client_executor = SingleThreadedExecutor(context=context)
        client_executor.add_node(client_node)
        client = client_node.create_client(ListParameters, '/server/list_parameters')
        assert client.wait_for_service(timeout_sec=BOUND)
        future = client.call_async(ListParameters.Request())
        client_executor.spin_until_future_complete(future, timeout_sec=BOUND)
        assert future.done() and 'gain' in future.result().result.names
        client_executor.shutdown()
    finally:
        stop.set()
        thread.join(BOUND)


def test_spin_until_future_complete_guard_conditions_and_coroutines(context, executor):
    node = _node(context, 'misc')
    executor.add_node(node)
    # a client spun by this executor: spin_until_future_complete takes rclpy's own path
    server = _node(context, 'server')
    executor.add_node(server)
    client = node.create_client(ListParameters, '/server/list_parameters')
    assert client.wait_for_service(timeout_sec=BOUND)
    future = client.call_async(ListParameters.Request())
    executor.spin_until_future_complete(future, timeout_sec=BOUND)
    assert future.done() and future.result() is not None

    fired = []
    guard = node.create_guard_condition(lambda: fired.append('guard'))
    guard.trigger()
    _spin_until(executor, lambda: fired == ['guard'])

    async def coroutine_callback(msg):
        fired.append(msg.data)
    node.create_subscription(Int64, 'c', coroutine_callback, 10)
    pub = node.create_publisher(Int64, 'c', 10)
    _spin_until(executor, lambda: pub.get_subscription_count() == 1)
    pub.publish(Int64(data=7))
    _spin_until(executor, lambda: fired == ['guard', 7])

    task = executor.create_task(lambda: 42)
    _spin_until(executor, task.done)
    assert task.result() == 42


def test_a_callbacks_exception_leaves_spin_once(context, executor):
    node = _node(context, 'raiser')
    executor.add_node(node)

    def boom():
        raise RuntimeError('from the timer callback')
    node.create_timer(0.01, boom)
    with pytest.raises(RuntimeError, match='from the timer callback'):
        _spin_until(executor, lambda: False)


def test_shutdown_from_another_thread_ends_a_blocked_spin(context, executor):
    node = _node(context, 'idle')
    executor.add_node(node)
    threading.Timer(0.3, executor.shutdown).start()
    start = time.monotonic()
    executor.spin()
    assert time.monotonic() - start < BOUND
