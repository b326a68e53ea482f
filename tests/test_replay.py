"""Replay of recorded bags over DDS (uh_runtime/bags/replay.py, scripts/replay.sh).

A listener process subscribes (raw CDR) to the replayed topics and writes down, per message, the
topic, the payload bytes and the monotonic time it arrived; the replay waits until every topic
has that subscriber (--wait-for-subscribers: an event, not a sleep), then gives the listener's
side of the match the default --delay (0.5 s) to complete: a keep-last writer may overwrite a
sample its new reader has not yet acknowledged. What arrives is compared
with the bag read by rosbags, an independent reader.

Timing tolerance. The replay sends message m at t0 + (log_time(m) - log_time(first)) / rate and
never earlier; a message arrives late by the replay's wake-up delay plus the DDS hand-over and the
listener's wake-up (well under 1 ms each on an idle machine). On the shared 2-core test machine a
runnable process may wait for the CPU for one or more scheduler periods (Linux CFS aims at 24 ms
for 2 CPUs), so we require the median lateness to stay below 20 ms and every message below
250 ms, measured from the least-late message (the arrival clock and the bag clock have no common
origin).
"""
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Reader

ROOT = Path(__file__).resolve().parents[1]
JAZZY = ROOT / 'tests' / 'data' / 'ros2_jazzy_sample'
REPLAY = ROOT / 'scripts' / 'replay.sh'
MEDIAN_LATENESS_S = 0.020
MAX_LATENESS_S = 0.250

pytestmark = pytest.mark.dds

LISTENER = r'''
import json, sys, time
import uh_runtime as rt
from uh_runtime import messages
topics, expected, out = json.loads(sys.argv[1]), json.loads(sys.argv[2]), sys.argv[3]
rt.init(args=['listener'])
node = rt.Node('replay_listener')
got = []
counts = dict.fromkeys(topics, 0)
def on(topic):
    def record(data):
        counts[topic] += 1
        got.append((topic, time.monotonic(), bytes(data).hex()))
    return record
qos = rt.QoSProfile(depth=100000, reliability=rt.ReliabilityPolicy.RELIABLE,
                    durability=rt.DurabilityPolicy.VOLATILE)
for name, type_name in topics.items():
    node.create_subscription(messages.get_message(type_name), name, on(name), qos, raw=True)
print('ready', flush=True)
deadline = time.monotonic() + 120
# stop once every topic has its expected count: topics are separate writers, so a total count
# could be reached by a later pass of one topic before the last message of another arrives
while any(counts[t] < n for t, n in expected.items()) and time.monotonic() < deadline:
    rt.spin_once(node, timeout_sec=0.1)
with open(out, 'w') as f:
    json.dump(got, f)
node.destroy_node()
rt.try_shutdown()
'''


def bag_messages(bag: Path, topics=None):
    """[(topic, type, log time ns, bytes)] of a bag in log-time order, read with rosbags."""
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if topics is None or c.topic in topics]
        return [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in reader.messages(connections=conns)]


def replay_to_listener(processes, tmp_path, domain, bag, topics, rate, extra=()):
    """Replay ``topics`` of ``bag`` to a listener; returns (listener records, replay stderr)."""
    expected = bag_messages(bag, set(topics))
    types = {t: ty for t, ty, _, _ in expected}
    script = tmp_path / 'listener.py'
    script.write_text(LISTENER)
    out = tmp_path / 'received.json'
    listener = processes.start([sys.executable, str(script), json.dumps(types),
                                json.dumps({t: sum(1 for m in expected if m[0] == t) for t in types}), str(out)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    assert listener.stdout.readline().strip() == 'ready', listener.stderr.read()
    replay = subprocess.run([str(REPLAY), str(bag), '--rate', str(rate), '--domain-id', str(domain),
                             '--wait-for-subscribers', '--topics', *topics, *extra],
                            capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert replay.returncode == 0, replay.stderr
    listener.wait(timeout=120)
    assert listener.returncode == 0, listener.stderr.read()
    return expected, json.loads(out.read_text()), replay.stderr


def assert_same_messages(expected, received):
    """Per topic, the same payloads in the same order (DDS orders per writer, not across topics)."""
    for topic in {t for t, _, _, _ in expected}:
        want = [data.hex() for t, _, _, data in expected if t == topic]
        got = [data for t, _, data in received if t == topic]
        assert got == want, f'{topic}: {len(got)} received, {len(want)} recorded, first difference at ' \
            f'{next((i for i, (a, b) in enumerate(zip(got, want, strict=False)) if a != b), min(len(got), len(want)))}'


def lateness(expected, received, rate):
    """Seconds each message arrived after its due time, relative to the least-late message."""
    t0 = min(t for _, _, t, _ in expected)
    due = {}
    for topic, _, log_ns, data in expected:
        due.setdefault((topic, data.hex()), []).append((log_ns - t0) * 1e-9 / rate)
    late = []
    for topic, arrived, data in received:
        late.append(arrived - due[(topic, data)].pop(0))
    late = np.array(late)
    return late - late.min()


@pytest.mark.slow
def test_replay_of_a_team_run_sends_the_recorded_bytes_in_order_on_time(processes, domain_id, tmp_path,
                                                                         tmp_path_factory):
    from test_report import shared_team_run
    bag = shared_team_run(tmp_path_factory) / 'bag'
    topics = ['/uh1/state', '/reference', '/markers']
    rate = 10.0   # the 22 s run in 2.2 s
    expected, received, log = replay_to_listener(processes, tmp_path, domain_id, bag, topics + ['/clock'], rate)
    assert_same_messages(expected, received)
    assert {t for t, _, _ in received} == set(topics) | {'/clock'}
    late = lateness(expected, received, rate)
    assert np.median(late) < MEDIAN_LATENESS_S and late.max() < MAX_LATENESS_S, \
        f'median {np.median(late) * 1e3:.1f} ms, max {late.max() * 1e3:.1f} ms'
    assert '/clock from the bag' in log


def test_replay_of_a_ros2_jazzy_bag(processes, domain_id, tmp_path):
    """A bag recorded by `ros2 bag record -s mcap` on ROS 2 Jazzy replays the same way.

    It replays at its own (wall-clock) log times, /clock included as recorded.
    """
    topics = ['/uh1/chatter', '/uh1/arr', '/uh1/header', '/clock']
    rate = 2.0
    expected, received, _ = replay_to_listener(processes, tmp_path, domain_id, JAZZY, topics, rate)
    assert len(received) == 4 * 57
    assert_same_messages(expected, received)
    late = lateness(expected, received, rate)
    assert np.median(late) < MEDIAN_LATENESS_S and late.max() < MAX_LATENESS_S, \
        f'median {np.median(late) * 1e3:.1f} ms, max {late.max() * 1e3:.1f} ms'
    # rate 2: the 1.12 s of the bag take half as long
    span = max(t for _, t, _ in received) - min(t for _, t, _ in received)
    bag_span = (max(t for _, _, t, _ in expected) - min(t for _, _, t, _ in expected)) * 1e-9
    assert span == pytest.approx(bag_span / rate, abs=MAX_LATENESS_S)


def test_clock_is_synthesised_from_log_times_and_qos_is_the_recorded_one(processes, domain_id, tmp_path):
    """A bag without /clock: the replay publishes Clock(log time) before each new log time.

    The replayed topic offers the QoS of the bag's offered_qos_profiles (here transient-local, depth 5).
    """
    from rosbags.typesys import Stores, get_typestore

    from uh_runtime.bags.bag import BagWriter
    from uh_runtime.dds.graph import Graph
    from uh_runtime.dds.qos import qos_profile_yaml
    store = get_typestore(Stores.ROS2_JAZZY)
    String = store.types['std_msgs/msg/String']
    bag = tmp_path / 'noclock'
    times = [5_000_000_000 + k * 50_000_000 for k in range(12)]   # 12 messages, 50 ms apart
    with BagWriter(bag) as writer:
        writer.add_topic('/talk', 'std_msgs/msg/String',
                         qos_profile_yaml('reliable', 'transient_local', 'keep_last', 5))
        for k, t in enumerate(times):
            writer.write('/talk', store.serialize_cdr(String(data=f'message {k}'), 'std_msgs/msg/String'), t)
    script = tmp_path / 'listener.py'
    script.write_text(LISTENER)
    out = tmp_path / 'received.json'
    types = {'/talk': 'std_msgs/msg/String', '/clock': 'rosgraph_msgs/msg/Clock'}
    listener = processes.start([sys.executable, str(script), json.dumps(types),
                                json.dumps(dict.fromkeys(types, len(times))), str(out)],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    assert listener.stdout.readline().strip() == 'ready'
    # --loop keeps the writer up while its QoS is read from discovery; the listener stops after
    # the first pass (12 messages on each topic)
    replay = processes.start([str(REPLAY), str(bag), '--domain-id', str(domain_id), '--wait-for-subscribers',
                              '--loop'],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    graph = Graph(domain_id=domain_id)
    try:
        assert graph.wait_until(lambda g: g.endpoints('/talk', writers=True), timeout_sec=30)
        qos = graph.endpoints('/talk', writers=True)[0].qos_profile
    finally:
        graph.close()
    assert (qos.durability.name, qos.reliability.name, qos.history.name, qos.depth) == \
        ('TRANSIENT_LOCAL', 'RELIABLE', 'KEEP_LAST', 5)
    assert listener.wait(timeout=60) == 0, listener.stderr.read()
    os.killpg(replay.pid, signal.SIGTERM)
    assert replay.wait(timeout=30) == 130
    received = json.loads(out.read_text())
    clocks = [bytes.fromhex(d) for t, _, d in received if t == '/clock'][:len(times)]
    stamps = [store.deserialize_cdr(c, 'rosgraph_msgs/msg/Clock').clock for c in clocks]
    assert [s.sec * 1_000_000_000 + s.nanosec for s in stamps] == times
    talk = [store.deserialize_cdr(bytes.fromhex(d), 'std_msgs/msg/String').data
            for t, _, d in received if t == '/talk'][:len(times)]
    assert talk == [f'message {k}' for k in range(len(times))]


def test_ctrl_c_stops_the_replay_cleanly(processes, domain_id, tmp_path):
    proc = processes.start([str(REPLAY), str(JAZZY), '--loop', '--domain-id', str(domain_id)],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    first = proc.stderr.readline()          # printed once the publishers exist
    assert first.startswith('[replay]') and '228 messages on 4 topics' in first
    os.killpg(proc.pid, signal.SIGINT)      # what Ctrl-C in the terminal does
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert 'interrupted after' in err and 'Traceback' not in err


# ----------------------------------------------------------------------------------------------
# bad bags: checked before anything is published
# ----------------------------------------------------------------------------------------------
def _replay_error(capsys, *args) -> str:
    from uh_runtime.bags.replay import main
    assert main(['replay', *map(str, args)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('replay: error:') and 'Traceback' not in err
    return err


def test_a_truncated_bag_is_named(tmp_path, capsys):
    bag = tmp_path / 'bag'
    bag.mkdir()
    data = (JAZZY / 'sample_bag_0.mcap').read_bytes()
    (bag / 'cut_0.mcap').write_bytes(data[:len(data) * 2 // 3])   # a recorder killed mid-write
    err = _replay_error(capsys, bag)
    assert str(bag / 'cut_0.mcap') in err and 'truncated' in err
    assert f'python -m uh_runtime.bags.bag recover {bag}' in err   # the error says how to fix it


def test_a_damaged_chunk_is_named(tmp_path, capsys):
    """A chunk with a CRC (this project's bags) is checked byte for byte."""
    from rosbags.typesys import Stores, get_typestore
    from test_report import damaged_chunk

    from uh_runtime.bags.bag import BagWriter
    from uh_runtime.dds.qos import qos_profile_yaml
    store = get_typestore(Stores.ROS2_JAZZY)
    String = store.types['std_msgs/msg/String']
    with BagWriter(tmp_path / 'good') as writer:
        writer.add_topic('/talk', 'std_msgs/msg/String', qos_profile_yaml('reliable', 'volatile', 'keep_last', 10))
        for k in range(2000):   # several chunks
            writer.write('/talk', store.serialize_cdr(String(data=f'message {k} ' * 5), 'std_msgs/msg/String'), k)
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'bad_0.mcap').write_bytes(damaged_chunk(tmp_path / 'good' / 'good_0.mcap'))
    err = _replay_error(capsys, bag)
    assert str(bag / 'bad_0.mcap') in err and 'corrupted (CRC mismatch)' in err
    assert f'python -m uh_runtime.bags.bag recover {bag}' in err


def test_a_broken_chunk_without_crc_is_named(tmp_path, capsys):
    """rosbag2 on Jazzy stores no chunk CRC: the record structure is checked instead."""
    from mcap.reader import make_reader
    source = JAZZY / 'sample_bag_0.mcap'
    with open(source, 'rb') as f:
        chunk = make_reader(f).get_summary().chunk_indexes[0]
    data = bytearray(source.read_bytes())
    # first record of the chunk: opcode and length (after the chunk's opcode, length and the
    # 8+8+8+4 byte times, size and CRC, the compression string and the 8-byte records length)
    first = chunk.chunk_start_offset + 1 + 8 + 28 + 4 + len(chunk.compression) + 8
    data[first:first + 9] = b'\xff' * 9          # a record that claims to be longer than the file
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'broken_0.mcap').write_bytes(bytes(data))
    err = _replay_error(capsys, bag)
    assert str(bag / 'broken_0.mcap') in err and 'corrupted' in err


def test_not_mcap_missing_and_empty_are_named(tmp_path, capsys):
    (tmp_path / 'db3').mkdir()
    (tmp_path / 'db3' / 'x_0.mcap').write_bytes(b'SQLite format 3\x00' + bytes(100))
    err = _replay_error(capsys, tmp_path / 'db3')
    assert 'x_0.mcap' in err and 'not an MCAP file' in err
    assert 'no such file or directory' in _replay_error(capsys, tmp_path / 'nothing')
    (tmp_path / 'empty').mkdir()
    assert 'no MCAP bag here' in _replay_error(capsys, tmp_path / 'empty')


def test_bad_qos_metadata_is_named(tmp_path):
    from uh_runtime.bags.bag import BagWriter
    from uh_runtime.bags.bag_reader import BagError, open_bag
    from uh_runtime.dds.qos import parse_offered_qos
    with BagWriter(tmp_path / 'f') as writer:
        writer.add_topic('/x', 'std_msgs/msg/String', '- reliability: sometimes\n  durability: volatile\n')
    with pytest.raises(BagError, match=r"f_0.mcap: topic /x: offered_qos_profiles has reliability: 'sometimes'; "
                                       'allowed: reliable, best_effort, system_default'):
        open_bag(tmp_path / 'f')
    mixed = parse_offered_qos('- {reliability: reliable, durability: transient_local, history: keep_last, depth: 5}\n'
                              '- {reliability: best_effort, durability: transient_local, history: keep_last, '
                              'depth: 20}\n')
    # like ros2 bag play: reliable only if every publisher was; the largest depth
    assert (mixed.reliability, mixed.durability, mixed.depth) == ('best_effort', 'transient_local', 20)
