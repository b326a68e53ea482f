"""Log times of the recorder (uh_runtime/bags/recorder.py): a stamp far from the sim time never sets the bag's range.

A fault sent from rclpy, or /rosout of an rclpy node, carries wall-clock time (about 1.8e18 ns) in a run on simulated
time; logged at its stamp it would make the bag of a 60 s run last decades.
"""
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from uh_runtime.bags.recorder import PROGRESS_EVERY, PROGRESS_FLUSH_S, STAMP_WINDOW_NS, LogClock, RecordedProgress

WALL_NS = 1_795_000_000_123_456_789          # a wall-clock stamp of 2026


def _stamped(ns: int) -> bytes:
    """Return a little-endian CDR payload that starts with a builtin_interfaces/Time of ``ns``."""
    return b'\x00\x01\x00\x00' + struct.pack('<iI', ns // 1_000_000_000, ns % 1_000_000_000) + b'\x00' * 8


def test_in_a_sim_time_run_a_wall_clock_stamp_is_logged_at_the_latest_clock():
    clock = LogClock(sim_time=True)
    assert clock.of('/rosout', _stamped(WALL_NS), True) == 0            # before the first /clock: its time, 0
    assert clock.of('/clock', _stamped(5_000_000_000), True) == 5_000_000_000
    assert clock.of('/uh1/fault', _stamped(WALL_NS), True) == 5_000_000_000
    assert clock.replaced == 2
    # the states of the next steps arrive before their /clock: their stamps stand
    assert clock.of('/uh1/state', _stamped(5_030_000_000), True) == 5_030_000_000
    assert clock.of('/uh1/state', _stamped(5_000_000_000 + STAMP_WINDOW_NS), True) == 5_000_000_000 + STAMP_WINDOW_NS
    assert clock.of('/uh1/state', _stamped(5_000_000_001 + STAMP_WINDOW_NS), True) == 5_000_000_000
    assert clock.of('/parameter_events', b'', False) == 5_000_000_000   # unstamped: the latest /clock
    assert clock.replaced == 3


def test_without_sim_time_every_stamp_is_the_log_time():
    clock = LogClock()
    clock.of('/clock', _stamped(5_000_000_000), True)
    assert clock.of('/uh1/fault', _stamped(WALL_NS), True) == WALL_NS
    assert clock.replaced == 0


@pytest.mark.dds
def test_a_wall_clock_stamped_fault_leaves_the_bags_time_range_that_of_the_run(tmp_path, domain_id, processes):
    from uh_runtime import dds as rt_dds
    from uh_runtime import messages as m
    from uh_wire import topics
    bag = tmp_path / 'bag'
    recorder = processes.start([str(Path(sys.executable).with_name('recorder_node')), '--ros-args',
                                '-p', f'output:={bag}', '-p', 'sim_time:=true', '-p', 'topics:=[/clock,/uh1/fault]',
                                '-p', 'expected_topics:=[/uh1/fault=uh_msgs/msg/ActuatorFault]'],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    context = rt_dds.Context()
    context.init(args=['talker'])
    try:
        node = rt_dds.Node('talker', context=context)
        clock = node.create_publisher(m.Clock, '/clock', topics.qos_profile(topics.STEP_QOS))
        fault = node.create_publisher(m.ActuatorFault, '/uh1/fault', topics.qos_profile(topics.EVENT_QOS))
        deadline = time.monotonic() + 30
        while clock.get_subscription_count() < 1 or fault.get_subscription_count() < 1:
            assert time.monotonic() < deadline and recorder.poll() is None, 'recorder not subscribed'
            time.sleep(0.05)
        for k in range(1, 4):
            msg = m.Clock()
            msg.clock.sec = k
            clock.publish(msg)
            time.sleep(0.05)
        injected = m.ActuatorFault(uh_id=1, channel=2, rho=0.5, onset_time=3.0)
        injected.header.stamp.sec, injected.header.stamp.nanosec = divmod(WALL_NS, 1_000_000_000)
        fault.publish(injected)
        fault.wait_for_all_acked(rt_dds.Duration(seconds=5))
    finally:
        context.try_shutdown()
    recorder.send_signal(signal.SIGINT)
    output, _ = recorder.communicate(timeout=30)
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    counts = {t['topic_metadata']['name']: t['message_count'] for t in info['topics_with_message_count']}
    assert counts == {'/clock': 3, '/uh1/fault': 1}
    assert info['starting_time']['nanoseconds_since_epoch'] == 1_000_000_000
    assert info['duration']['nanoseconds'] == 2_000_000_000, info     # 1 s .. 3 s of /clock, the fault at 3 s
    assert '1 message(s) stamped more than 10 s from the simulated time' in output


def test_progress_is_published_every_tenth_advance_and_the_rest_on_the_timer():
    # /recorder/progress: the oldest newest log time of the per-step topics, once each was written
    progress = RecordedProgress(['/a', '/b'], every=PROGRESS_EVERY)
    assert not progress.written('/a', 0) and progress.take() is None         # /b never written yet
    assert not progress.written('/other', 5)                                  # not a per-step topic
    published = []
    for step in range(25):
        progress.written('/a', step * 10)
        if progress.written('/b', step * 10):
            published.append(progress.take())
    # 25 advances (0 .. 240 ns): published at the 10th and 20th by the messages themselves
    assert published == [90, 190]
    assert progress.take() == 240 and progress.take() is None    # the timer publishes the rest, once
    assert not progress.written('/b', 240) and progress.take() is None   # no advance, nothing to publish


def test_the_timer_confirms_the_last_step_within_its_period():
    # the lockstep clock ends the run only once the last step is confirmed: it must not wait for a
    # tenth advance that never comes
    progress = RecordedProgress(['/a'], every=PROGRESS_EVERY)
    for step in range(3):
        assert not progress.written('/a', step)
    assert progress.take() == 2
    assert 0 < PROGRESS_FLUSH_S <= 0.05   # the end of a run waits at most this long for it


def test_progress_equals_the_oldest_newest_stamp_for_any_order_of_messages():
    # the incremental minimum against its definition, over shuffled steps, repeats and stale stamps
    import random
    rng = random.Random(7)
    topics = [f'/uh{i}/{kind}' for i in range(1, 9) for kind in ('state', 'command')]
    progress = RecordedProgress(topics, every=1)
    newest = {}
    for step in range(300):
        batch = [(t, step * 10) for t in topics] + [(rng.choice(topics), max(0, step - 3) * 10) for _ in range(4)]
        rng.shuffle(batch)
        for topic, ns in batch:
            before = progress.progress_ns
            published = progress.written(topic, ns)
            newest[topic] = max(newest.get(topic, -1), ns)
            expected = min(newest.values()) if len(newest) == len(topics) else -1
            assert progress.progress_ns == expected
            assert published == (expected > before)    # every=1: each advance asks to be published
            if published:
                assert progress.take() == expected
