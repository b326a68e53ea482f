"""Intra-process delivery of the Cyclone DDS backend (uh_runtime.dds.intra_process).

Nodes of one process exchange message objects directly; DDS still serves other processes, and
no subscription gets a message twice. Each test has its own context (one DDS participant).
"""
import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
import spinning
from spinning import spin_for

from uh_runtime import dds as rt
from uh_runtime import messages
from uh_runtime.dds.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

pytestmark = pytest.mark.dds
HELPERS = Path(__file__).resolve().parent / 'helpers_runtime'
BOUND = 20.0  # s; only bounds a failure, events arrive within milliseconds on loopback


def _context(monkeypatch, enabled=True):
    monkeypatch.setenv('UH_INTRA_PROCESS', '1' if enabled else '0')
    context = rt.Context()
    context.init(args=['test'])
    return context


@pytest.fixture
def ctx(domain_id, monkeypatch):
    context = _context(monkeypatch)
    yield context
    context.try_shutdown()


def spin_until(executor, condition, bound=BOUND):
    spinning.spin_until(executor, condition, bound)


def _state(step):
    msg = messages.UHState()
    msg.uh_id, msg.step = 3, step
    msg.position.x = 0.5 * step
    return msg


def _pair(ctx, pub_qos, sub_qos, raw=False, topic='/state'):
    talker, listener = rt.Node('talker', context=ctx), rt.Node('listener', context=ctx)
    pub = talker.create_publisher(messages.UHState, topic, pub_qos)
    got = []
    sub = listener.create_subscription(messages.UHState, topic, got.append, sub_qos, raw=raw)
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(talker)
    executor.add_node(listener)
    return pub, sub, got, executor


def test_same_process_subscription_gets_the_published_object_once(ctx):
    pub, sub, got, executor = _pair(ctx, QoSProfile(depth=10), QoSProfile(depth=10))
    assert pub.get_subscription_count() == 1 and sub.get_publisher_count() == 1
    sent = [_state(k) for k in range(5)]
    for msg in sent:
        pub.publish(msg)
    spin_until(executor, lambda: len(got) == 5)
    spin_for(executor, 0.3)   # a copy through DDS as well would arrive in this time
    assert len(got) == 5
    assert all(a is b for a, b in zip(got, sent, strict=False))   # the objects themselves, in order


def test_raw_subscription_gets_the_bytes_dds_would_carry(ctx):
    pub, _, got, executor = _pair(ctx, QoSProfile(depth=10), QoSProfile(depth=10), raw=True)
    msg = _state(7)
    msg.header.frame_id = 'world'   # odd length: the payload is padded to a multiple of 4 bytes
    pub.publish(msg)
    spin_until(executor, lambda: got)
    data = msg.serialize(use_version_2=False)
    data += b'\0' * (-len(data) % 4)
    assert got == [data]


def test_bytes_published_reach_a_typed_subscription_as_a_message(ctx):
    pub, _, got, executor = _pair(ctx, QoSProfile(depth=10), QoSProfile(depth=10))
    pub.publish(_state(4).serialize(use_version_2=False))
    spin_until(executor, lambda: got)
    assert (got[0].step, got[0].position.x) == (4, 2.0)


def test_keep_last_subscription_keeps_only_depth_messages(ctx):
    pub, _, got, executor = _pair(ctx, QoSProfile(depth=10), QoSProfile(depth=3))
    for k in range(10):
        pub.publish(_state(k))
    spin_until(executor, lambda: got)
    spin_for(executor, 0.1)
    assert [m.step for m in got] == [7, 8, 9]


def test_incompatible_qos_is_not_delivered(ctx):
    best_effort = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
    pub, sub, got, executor = _pair(ctx, best_effort, QoSProfile(depth=10))   # reliable reader
    assert sub.get_publisher_count() == 0
    pub.publish(_state(1))
    spin_for(executor, 0.3)
    assert got == []


def test_late_transient_local_subscription_gets_the_history(ctx):
    latched = QoSProfile(depth=4, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    talker = rt.Node('talker', context=ctx)
    pub = talker.create_publisher(messages.UHState, '/state', latched)
    for k in range(6):
        pub.publish(_state(k))
    listener = rt.Node('listener', context=ctx)
    late, volatile = [], []
    listener.create_subscription(messages.UHState, '/state', late.append, latched)
    listener.create_subscription(messages.UHState, '/state', volatile.append, QoSProfile(depth=10))
    executor = rt.SingleThreadedExecutor(context=ctx)
    executor.add_node(listener)
    spin_until(executor, lambda: len(late) == 4)
    pub.publish(_state(6))
    spin_until(executor, lambda: len(late) == 5 and volatile)
    assert [m.step for m in late] == [2, 3, 4, 5, 6]   # the last depth=4, then the new one
    assert [m.step for m in volatile] == [6]            # a volatile subscription gets no history


def test_publish_from_another_thread_wakes_the_executor(ctx):
    import threading
    pub, _, got, executor = _pair(ctx, QoSProfile(depth=10), QoSProfile(depth=10))
    timer = threading.Timer(0.2, lambda: pub.publish(_state(1)))
    timer.start()
    start = time.monotonic()
    executor.spin_once(timeout_sec=5.0)   # blocks until woken
    timer.join()
    spin_until(executor, lambda: got, bound=1.0)
    assert time.monotonic() - start < 4.0


def test_destroyed_subscription_gets_nothing_more(ctx):
    pub, sub, got, executor = _pair(ctx, QoSProfile(depth=10), QoSProfile(depth=10))
    pub.publish(_state(1))
    sub._node.destroy_subscription(sub)
    assert pub.get_subscription_count() == 0
    pub.publish(_state(2))
    spin_for(executor, 0.2)
    assert got == []


def test_other_processes_get_every_message_and_the_local_one_no_duplicate(ctx, processes, tmp_path):
    """A listener in another process matches through DDS while a node of this process is fed in process.

    Both get each message exactly once.
    """
    qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE)
    pub, _, got, executor = _pair(ctx, QoSProfile(depth=50), qos, topic='/uh3/state')
    remote = processes.start([sys.executable, str(HELPERS / 'listener.py'), '--ros-args',
                              '-r', '__ns:=/uh3', '-p', 'count:=3'],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    spin_until(executor, lambda: pub.get_subscription_count() == 2)   # local + remote
    sent = [_state(k) for k in range(3)]
    for msg in sent:
        pub.publish(msg)
    lines = []
    end = time.monotonic() + BOUND
    while len(lines) < 3 and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.05)
        if remote.poll() is not None:
            lines += [json.loads(line) for line in remote.stdout.read().splitlines() if line.strip()]
            break
    assert remote.wait(timeout=BOUND) == 0, remote.stderr.read()
    assert [line['step'] for line in lines if 'step' in line] == [0, 1, 2]
    spin_for(executor, 0.3)
    assert len(got) == 3 and all(a is b for a, b in zip(got, sent, strict=False))


def test_turned_off_every_message_goes_through_dds(domain_id, monkeypatch):
    context = _context(monkeypatch, enabled=False)
    try:
        pub, _, got, executor = _pair(context, QoSProfile(depth=10), QoSProfile(depth=10))
        spin_until(executor, lambda: pub.get_subscription_count() == 1)   # a DDS match now
        msg = _state(5)
        pub.publish(msg)
        spin_until(executor, lambda: got)
        spin_for(executor, 0.2)
        assert len(got) == 1 and got[0] is not msg and got[0].step == 5
    finally:
        context.try_shutdown()
