"""The live view (``run_formation.sh --foxglove``) seen by a client of the Foxglove WebSocket protocol.

See docs/visualization.md#live-view-in-foxglove. The client is written here from the protocol's specification with the
``websockets`` package: advertise, subscribe, binary message data; the payloads are decoded with rosbags and compared
with the simulator's states in the bag. foxglove-sdk's server speaks the protocol as ``foxglove.sdk.v1``, the successor
of ``foxglove.websocket.v1`` with the same operations and frames; it refuses the old name.
"""
import json
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip('foxglove', reason='the live view needs foxglove-sdk')
from team_runs import stop_run  # noqa: E402
from websockets.sync.client import connect  # noqa: E402

from uh_runtime.messages import typestore  # noqa: E402
from uh_runtime.network import loopback_environment  # noqa: E402

pytestmark = [pytest.mark.dds, pytest.mark.slow]
ROOT = Path(__file__).resolve().parents[1]
BOUND = 120.0  # s of wall time; bounds a failure only
MESSAGE_DATA = 0x01  # binary opcode of a message: subscription id u32, log time u64, payload
SUBPROTOCOL = 'foxglove.sdk.v1'


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def _start(out, domain_id, *args):
    return subprocess.Popen([sys.executable, '-P', '-m', 'uh_bringup.run_formation', '--out', str(out),
                             '--domain-id', str(domain_id), '--no-metrics', *args],
                            env=loopback_environment(domain_id), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True)


def _connect(port, deadline):
    while True:
        try:
            return connect(f'ws://127.0.0.1:{port}', subprotocols=[SUBPROTOCOL], open_timeout=5, close_timeout=1)
        except OSError:
            assert time.monotonic() < deadline, 'the live view never accepted a connection'
            time.sleep(0.3)


def _advertised(ws, wanted, deadline):
    channels = {}
    while not wanted <= set(channels):
        assert time.monotonic() < deadline, f'never advertised: {wanted - set(channels)}'
        frame = ws.recv(timeout=10)
        if isinstance(frame, str):
            msg = json.loads(frame)
            if msg['op'] == 'advertise':
                channels.update({c['topic']: c for c in msg['channels']})
    return channels


def test_a_foxglove_client_receives_odometry_and_markers_that_match_the_simulator(tmp_path, domain_id):
    port, out = _free_port(), tmp_path / 'run'
    run = _start(out, domain_id, '--clock', 'realtime', '--duration', '8', '--foxglove', str(port))
    store, odom, markers = typestore(), [], []
    try:
        deadline = time.monotonic() + BOUND
        with _connect(port, deadline) as ws:
            channels = _advertised(ws, {'/uh1/odom', '/markers'}, deadline)
            for topic in ('/uh1/odom', '/markers'):
                c = channels[topic]
                assert (c['encoding'], c['schemaEncoding']) == ('cdr', 'ros2msg')
                assert 'geometry_msgs/PoseWithCovariance' in c['schema'] or topic == '/markers'
            subscriptions = {1: channels['/uh1/odom'], 2: channels['/markers']}
            subscribe = {sid: json.dumps({'op': 'subscribe', 'subscriptions': [{'id': sid, 'channelId': c['id']}]})
                         for sid, c in subscriptions.items()}
            for text in subscribe.values():
                ws.send(text)
            asked, got = time.monotonic(), {1: odom, 2: markers}
            while len(odom) < 50 or len(markers) < 3:
                assert time.monotonic() < deadline, f'{len(odom)} odometry, {len(markers)} marker messages'
                try:
                    frame = ws.recv(timeout=1)
                except TimeoutError:
                    frame = None
                if isinstance(frame, bytes) and frame[0] == MESSAGE_DATA:
                    sid, _log_time = struct.unpack_from('<IQ', frame, 1)
                    got[sid].append(store.deserialize_cdr(frame[13:], subscriptions[sid]['schemaName']))
                # the server once refused a subscription sent right after the channel's advertisement on a
                # loaded machine ("attempted to subscribe to unknown channel"): ask again, as a viewer would,
                # for a subscription that brought nothing for a second (odometry is 25 Hz, markers 10 Hz)
                if time.monotonic() - asked > 1.0:
                    for sid in [sid for sid, messages in got.items() if not messages]:
                        ws.send(subscribe[sid])
                    asked = time.monotonic()
        output, _ = run.communicate(timeout=BOUND)
    finally:
        stop_run(run)
    assert run.returncode == 0, output[-3000:]
    assert all(m.header.frame_id == 'world' and m.child_frame_id == 'uh1/base_link' for m in odom)
    assert all(any(k.header.frame_id == 'world' for k in m.markers) for m in markers)
    # the values are the simulator's: each odometry pose equals the recorded state of its step
    from rosbags.rosbag2 import Reader
    states = {}
    with Reader(out / 'bag') as reader:
        conns = [c for c in reader.connections if c.topic == '/uh1/state']
        for conn, _t, raw in reader.messages(connections=conns):
            s = store.deserialize_cdr(raw, conn.msgtype)
            states[(s.header.stamp.sec, s.header.stamp.nanosec)] = (s.position.x, s.position.y, s.position.z)
    for m in odom:
        p = m.pose.pose.position
        assert states[(m.header.stamp.sec, m.header.stamp.nanosec)] == (p.x, p.y, p.z)


def test_a_port_in_use_is_refused_before_any_node_starts(tmp_path, domain_id):
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        run = _start(tmp_path / 'run', domain_id, '--foxglove', str(port))
        output, _ = run.communicate(timeout=BOUND)
    assert run.returncode == 2, output
    assert f'cannot serve the live view on 127.0.0.1:{port}: in use by another program' in output
    assert not (tmp_path / 'run').exists()   # nothing was started or written


def test_a_viewer_that_never_reads_or_leaves_does_not_stall_the_team(tmp_path, domain_id):
    """Lockstep waits for every node: a publisher blocked by a viewer would stop the run.

    One client subscribes to everything and never reads; another leaves mid-run.
    """
    port, out = _free_port(), tmp_path / 'run'
    run = _start(out, domain_id, '--duration', '10', '--foxglove', str(port))
    try:
        deadline = time.monotonic() + BOUND
        with _connect(port, deadline) as stuck:
            channels = _advertised(stuck, {'/uh1/state', '/tf', '/markers', '/uh5/status'}, deadline)
            stuck.send(json.dumps({'op': 'subscribe', 'subscriptions': [
                {'id': i, 'channelId': c['id']} for i, c in enumerate(channels.values(), 1)]}))
            with _connect(port, deadline) as leaving:
                _advertised(leaving, {'/uh1/state'}, deadline)
            output, _ = run.communicate(timeout=BOUND)   # stuck is never read while the run goes on
    finally:
        stop_run(run)
    assert run.returncode == 0, output[-3000:]
    assert 'run complete: 1000 steps' in output
    # and the live view itself shut down on SIGINT (not killed after the grace period)
    assert 'live view stopped:' in (out / 'logs' / 'live_view.log').read_text()


def test_replay_serves_a_bag_to_a_foxglove_client(tmp_path, domain_id):
    """``scripts/replay.sh BAG --foxglove PORT``: the replayed messages reach a client, decodable."""
    port = _free_port()
    bag = ROOT / 'tests' / 'data' / 'ros2_jazzy_sample'
    replay = subprocess.Popen([sys.executable, '-P', '-m', 'uh_runtime.bags.replay', str(bag), '--loop',
                               '--domain-id', str(domain_id), '--foxglove', str(port)],
                              env=loopback_environment(domain_id), stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, start_new_session=True)
    store, chatter = typestore(), []
    try:
        deadline = time.monotonic() + BOUND
        with _connect(port, deadline) as ws:
            channel = _advertised(ws, {'/uh1/chatter'}, deadline)['/uh1/chatter']
            ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [{'id': 7, 'channelId': channel['id']}]}))
            while len(chatter) < 5:
                assert time.monotonic() < deadline, 'no replayed message reached the client'
                frame = ws.recv(timeout=10)
                if isinstance(frame, bytes) and frame[0] == MESSAGE_DATA:
                    chatter.append(store.deserialize_cdr(frame[13:], channel['schemaName']))
    finally:
        replay.send_signal(signal.SIGINT)
        output, _ = replay.communicate(timeout=BOUND)
    assert all(m.data.startswith('hello ') for m in chatter), [m.data for m in chatter]  # as recorded
    assert f'live view: ws://127.0.0.1:{port}' in output and replay.returncode == 130
