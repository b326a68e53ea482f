"""rosbag2 MCAP layout of the bag writer, checked against a bag recorded by ROS 2 Jazzy.

Both are read back with rosbags (an independent reader).
"""
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from uh_runtime.bags.bag import BagWriter, message_definition
from uh_runtime.bags.bag_reader import BagError
from uh_runtime.dds.qos import qos_profile_yaml

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / 'tests' / 'data' / 'ros2_jazzy_sample'


@pytest.fixture(scope='module')
def store():
    ts = get_typestore(Stores.ROS2_JAZZY)
    for path in (ROOT / 'uh_msgs' / 'msg').glob('*.msg'):
        ts.register(get_types_from_msg(path.read_text(), f'uh_msgs/msg/{path.stem}'))
    return ts


def _state(store, k):
    T = store.types

    def v(x, y, z):
        return T['geometry_msgs/msg/Vector3'](x=x, y=y, z=z)

    header = T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](sec=k // 100,
                                                                             nanosec=(k % 100) * 10_000_000),
                                      frame_id='world')
    return T['uh_msgs/msg/UHState'](header=header, uh_id=np.uint32(2), step=np.uint64(k), position=v(1.0 * k, 2.0, 3.0),
                                    velocity=v(0.5, -0.5, 0.0), euler=v(0.0, 0.1, 0.2), body_rates=v(0.0, 0.0, 0.01),
                                    lost_uhs=np.array([3], dtype=np.uint32), lost_steps=np.array([k], dtype=np.uint64))


def test_qos_yaml_matches_what_jazzy_writes():
    with open(REFERENCE / 'sample_bag_0.mcap', 'rb') as f:
        channel = next(iter(make_reader(f).get_summary().channels.values()))
    assert qos_profile_yaml('reliable', 'volatile', 'keep_last', 10) == channel.metadata['offered_qos_profiles']


def test_definition_hash_equals_the_hash_jazzy_recorded():
    recorded = yaml.safe_load((REFERENCE / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    for entry in recorded['topics_with_message_count']:
        meta = entry['topic_metadata']
        assert message_definition(meta['type'])[1] == meta['type_description_hash']


def test_written_bag_reads_back_with_rosbags(tmp_path, store):
    bag_dir = tmp_path / 'bag'
    qos = qos_profile_yaml('reliable', 'transient_local', 'keep_last', 50)
    sent = []
    with BagWriter(bag_dir) as bag:
        bag.add_topic('/uh2/state', 'uh_msgs/msg/UHState', qos)
        bag.add_topic('/clock', 'rosgraph_msgs/msg/Clock', qos)
        for k in range(30):
            msg = _state(store, k)
            data = store.serialize_cdr(msg, 'uh_msgs/msg/UHState')
            bag.write('/uh2/state', data, log_time_ns=k * 10_000_000)
            clock = store.types['rosgraph_msgs/msg/Clock'](clock=msg.header.stamp)
            bag.write('/clock', store.serialize_cdr(clock, 'rosgraph_msgs/msg/Clock'), log_time_ns=k * 10_000_000)
            sent.append(bytes(data))

    assert sorted(p.name for p in bag_dir.iterdir()) == ['bag_0.mcap', 'metadata.yaml']
    with Reader(bag_dir) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts == {'/uh2/state': 30, '/clock': 30}
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types['/uh2/state'] == 'uh_msgs/msg/UHState'
        got = [(c.topic, t, d) for c, t, d in reader.messages()]
    states = [d for topic, _, d in got if topic == '/uh2/state']
    assert states == sent  # payloads are stored byte for byte
    decoded = store.deserialize_cdr(states[7], 'uh_msgs/msg/UHState')
    assert decoded.position.x == 7.0 and decoded.step == 7

    # metadata.yaml has the structure rosbag2 on Jazzy writes (same keys at every level)
    ours = yaml.safe_load((bag_dir / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    ref = yaml.safe_load((REFERENCE / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert set(ours) == set(ref) and ours['version'] == 9
    assert (set(ours['topics_with_message_count'][0]['topic_metadata'])
            == set(ref['topics_with_message_count'][0]['topic_metadata']))
    assert ours['message_count'] == 60 and ours['duration']['nanoseconds'] == 29 * 10_000_000

    # the MCAP header and schema encoding are those of ros2 bag record
    with open(bag_dir / 'bag_0.mcap', 'rb') as f:
        reader = make_reader(f)
        assert reader.get_header().profile == 'ros2'
        schemas = {s.name: s for s in reader.get_summary().schemas.values()}
    assert schemas['uh_msgs/msg/UHState'].encoding == 'ros2msg'
    assert 'MSG: geometry_msgs/Vector3' in schemas['uh_msgs/msg/UHState'].data.decode()


def test_refuses_to_overwrite_a_bag(tmp_path):
    (tmp_path / 'bag').mkdir()
    (tmp_path / 'bag' / 'x').write_text('keep me')
    with pytest.raises(BagError, match='exists and is not empty'):
        BagWriter(tmp_path / 'bag')
