"""Message classes of the DDS path (uh_runtime.messages) against rosbags, the independent reference.

For every uh_msgs type and the standard types the stack uses, the IdlStruct class must serialise
to exactly the bytes rosbags' ``serialize_cdr`` produces for the same non-trivial values, and
read them back unchanged (docs/runtime.md: the payload is ROS 2 CDR).
"""
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from cyclonedds.idl import types
from rosbags.typesys.base import Nodetype

from uh_runtime import messages
from uh_runtime.dds.cdr import codec
from uh_runtime.messages import MessageError, dds_message, typestore

ROOT = Path(__file__).resolve().parents[1]
UH_TYPES = sorted(f'uh_msgs/msg/{p.stem}' for p in (ROOT / 'uh_msgs' / 'msg').glob('*.msg'))
STD_TYPES = [
    'rosgraph_msgs/msg/Clock', 'std_msgs/msg/Header', 'builtin_interfaces/msg/Time',
    'builtin_interfaces/msg/Duration', 'geometry_msgs/msg/Vector3', 'std_msgs/msg/String',
    'std_msgs/msg/Float64MultiArray', 'visualization_msgs/msg/Marker',
    'visualization_msgs/msg/MarkerArray', 'rmw_dds_common/msg/ParticipantEntitiesInfo',
]
SAMPLE_BAG = ROOT / 'tests' / 'data' / 'ros2_jazzy_sample'

_NUMPY = {'bool': np.bool_, 'byte': np.uint8, 'char': np.uint8, 'int8': np.int8,
          'uint8': np.uint8, 'int16': np.int16, 'uint16': np.uint16, 'int32': np.int32,
          'uint32': np.uint32, 'int64': np.int64, 'uint64': np.uint64, 'float32': np.float32,
          'float64': np.float64}


class _Values:
    """Deterministic, non-trivial values for every field, built in parallel for both libraries."""

    def __init__(self):
        self.i = 0

    def base(self, name, bound):
        self.i += 1
        i = self.i
        if name == 'bool':
            return i % 2 == 1
        if name == 'string':
            text = f'text-{i}-é'  # non-ASCII: the length is in bytes
            return text[:bound] if bound else text
        if name.startswith('float'):
            return (-1) ** i * (i + 0.25) if name == 'float32' else (-1) ** i * (i / 3.0 + 1e-9)
        signed = not name.startswith('uint') and name not in ('byte', 'char')
        bits = {'byte': 8, 'char': 8}.get(name) or int(name.lstrip('uint'))
        top = 2 ** (bits - 1) - 1 if signed else 2 ** bits - 1
        value = top - (3 * i) % (top // 2)  # upper half of the range: a narrower field overflows
        return -value if signed and i % 2 else value

    def message(self, name):
        store = typestore()
        _, fields = store.fielddefs[name]
        ref_kwargs, dds_kwargs = {}, {}
        for fname, spec in fields:
            ref_kwargs[fname], dds_kwargs[fname] = self.field(spec)
        return store.types[name](**ref_kwargs), dds_message(name)(**dds_kwargs)

    def field(self, spec):
        kind, details = spec
        if kind == Nodetype.BASE:
            value = self.base(*details)
            return value, value
        if kind == Nodetype.NAME:
            return self.message(details)
        count = details[1] if kind == Nodetype.ARRAY else 2 + self.i % 2
        pairs = [self.field(details[0]) for _ in range(count)]
        ref = [p[0] for p in pairs]
        dds = [p[1] for p in pairs]
        sub_kind, sub_details = details[0]
        if sub_kind == Nodetype.BASE and sub_details[0] in _NUMPY:
            ref = np.array(ref, dtype=_NUMPY[sub_details[0]])  # rosbags keeps numbers in numpy
        return ref, dds


@pytest.mark.parametrize('name', UH_TYPES + STD_TYPES)
def test_serialises_to_the_bytes_of_rosbags_and_round_trips(name):
    ref, dds = _Values().message(name)
    expected = bytes(typestore().serialize_cdr(ref, name))
    data = dds.serialize(use_version_2=False)
    assert data[:4] == b'\x00\x01\x00\x00'  # CDR little endian, as ROS 2 sends
    assert data == expected
    back = type(dds).deserialize(data)
    # uint8 arrays come back as bytes: compare the plain-data view
    assert messages.message_to_ordereddict(back) == messages.message_to_ordereddict(dds)
    assert back.serialize(use_version_2=False) == expected


def test_every_uh_msgs_type_is_covered():
    assert len(UH_TYPES) >= 6 and 'uh_msgs/msg/UHState' in UH_TYPES


@pytest.mark.parametrize('name', UH_TYPES + STD_TYPES)
def test_fast_codec_of_the_backend_writes_and_reads_the_same_bytes(name):
    ref, dds = _Values().message(name)
    expected = bytes(typestore().serialize_cdr(ref, name))
    fast = codec(type(dds))
    assert fast.serialize(dds) == expected
    back = fast.deserialize(expected)
    assert type(back) is type(dds)
    assert messages.message_to_ordereddict(back) == messages.message_to_ordereddict(dds)
    # big-endian CDR (another machine's rmw may send it) goes through cyclonedds' reader
    big = bytes(typestore().serialize_cdr(ref, name, little_endian=False))
    assert messages.message_to_ordereddict(fast.deserialize(big)) == messages.message_to_ordereddict(dds)


def test_fast_codec_reports_bad_values_with_the_type():
    msg = messages.UHState()
    msg.uh_id = -1  # uint32
    with pytest.raises(TypeError, match='cannot serialise uh_msgs/msg/UHState'):
        codec(messages.UHState).serialize(msg)
    msg.uh_id = 1
    msg.position.x = 'far'
    with pytest.raises(TypeError, match='cannot serialise uh_msgs/msg/UHState'):
        codec(messages.UHState).serialize(msg)


#: types holding a char field (rmw_dds_common/msg/Gid)
CHAR_TYPES = ('rmw_dds_common/msg/Gid', 'rmw_dds_common/msg/NodeEntitiesInfo',
              'rmw_dds_common/msg/ParticipantEntitiesInfo')


@pytest.mark.parametrize('name', UH_TYPES + STD_TYPES)
def test_type_hash_and_dds_type_name(name):
    cls = dds_message(name)
    if name not in CHAR_TYPES:   # rosbags hashes char as its own type, ROS as uint8
        assert cls.__ros_typehash__ == typestore().hash_rihs01(name)
    assert messages.type_hash(cls) == messages.type_hash(name) == cls.__ros_typehash__
    pkg, _, typ = name.split('/')
    assert cls.__idl_typename__ == f'{pkg}::msg::dds_::{typ}_'
    assert messages.ros_type_name(cls()) == name
    assert messages.ros_type_from_dds(messages.dds_type_name(name)) == name


def test_standard_type_hashes_equal_those_recorded_by_ros2_jazzy():
    meta = yaml.safe_load((SAMPLE_BAG / 'metadata.yaml').read_text())
    topics = meta['rosbag2_bagfile_information']['topics_with_message_count']
    recorded = {t['topic_metadata']['type']: t['topic_metadata']['type_description_hash']
                for t in topics}
    assert 'rosgraph_msgs/msg/Clock' in recorded and 'std_msgs/msg/Header' in recorded
    for name, hash_ in recorded.items():
        assert dds_message(name).__ros_typehash__ == hash_


def test_type_hashes_of_types_with_char_fields_are_ross():
    # ROS hashes the IDL that rosidl makes of a .msg, where char is uint8; ros_discovery_info's
    # hash is the constant rmw_cyclonedds (Jazzy) writes into its graph writer's USER_DATA
    assert messages.type_hash('rmw_dds_common/msg/ParticipantEntitiesInfo') == \
        'RIHS01_91a0593bacdcc50ea9bdcf849a938b128412cc1ea821245c663bcd26f83c295e'
    assert dds_message('rmw_dds_common/msg/ParticipantEntitiesInfo').__ros_typehash__ == \
        messages.type_hash('rmw_dds_common/msg/ParticipantEntitiesInfo')
    # the char-free types hash as rosbags computes them
    assert messages.type_hash('std_msgs/msg/Header') == typestore().hash_rihs01('std_msgs/msg/Header')


def test_every_standard_type_hash_equals_the_one_a_ros2_jazzy_build_generated():
    # tests/data/ros2_jazzy_type_hashes.json: the type_hashes of the <Type>.json files that a ROS 2
    # Jazzy built from source installs (share/<pkg>/msg, share/<pkg>/srv), for every standard type
    # of the project's type store (messages, and the parameter services' request and response)
    recorded = json.loads((Path(__file__).parent / 'data' / 'ros2_jazzy_type_hashes.json').read_text())
    assert len(recorded) > 150 and 'rcl_interfaces/srv/ListParameters_Request' in recorded
    assert 'rmw_dds_common/msg/Gid' in recorded
    differ = {name: (messages.type_hash(name), expected) for name, expected in recorded.items()
              if messages.type_hash(name) != expected}
    assert not differ


def test_messages_recorded_by_ros2_jazzy_read_and_rewrite_byte_for_byte():
    from mcap.reader import make_reader
    seen = set()
    with open(SAMPLE_BAG / 'sample_bag_0.mcap', 'rb') as stream:
        for schema, _channel, message in make_reader(stream).iter_messages():
            cls = dds_message(schema.name)
            msg = cls.deserialize(message.data)
            assert codec(cls).deserialize(message.data) == msg
            data = msg.serialize(use_version_2=False)
            assert codec(cls).serialize(msg) == data
            # the writer pads to a multiple of 4 bytes, as rmw_cyclonedds does on the wire
            assert data.ljust((len(data) + 3) & ~3, b'\0') == message.data
            seen.add(schema.name)
    assert {'rosgraph_msgs/msg/Clock', 'std_msgs/msg/Header', 'std_msgs/msg/String'} <= seen


def test_exact_field_widths():
    ann = dds_message('uh_msgs/msg/UHState').__annotations__
    assert ann['uh_id'] == types.uint32 and ann['step'] == types.uint64
    truth = dds_message('uh_msgs/msg/FaultTruth').__annotations__
    assert truth['actual_inputs'] == types.array[types.float64, 4]
    status = dds_message('uh_msgs/msg/ControllerStatus').__annotations__
    assert status['stale_neighbours'] == types.sequence[str]
    marker = dds_message('visualization_msgs/msg/Marker').__annotations__
    assert marker['id'] == types.int32 and marker['scale'] is dds_message('geometry_msgs/msg/Vector3')
    time_ann = dds_message('builtin_interfaces/msg/Time').__annotations__
    assert time_ann == {'sec': types.int32, 'nanosec': types.uint32}


def test_ros_like_defaults_and_constants():
    UHState = messages.UHState
    a = UHState()
    a.position.x = 1.0
    a.header.frame_id = 'world'
    b = UHState()
    assert (b.position.x, b.header.frame_id, b.header.stamp.sec, b.uh_id) == (0.0, '', 0, 0)
    assert a.position.x == 1.0  # nested defaults are separate objects
    truth = messages.FaultTruth()
    assert truth.actual_inputs == [0.0] * 4
    fault = messages.ActuatorFault
    assert (fault.CHANNEL_COLLECTIVE, fault.CHANNEL_TAIL_ROTOR, fault.CHANNEL_LATERAL,
            fault.CHANNEL_LONGITUDINAL) == (0, 1, 2, 3)
    assert messages.Marker.DELETEALL == 3
    assert messages.get_message('uh_msgs/UHState') is UHState
    assert [f.name for f in dataclasses.fields(UHState)][:3] == ['header', 'uh_id', 'step']


def test_bad_names_are_clear_errors():
    with pytest.raises(MessageError, match='not a message type name'):
        messages.get_message('UHState')
    with pytest.raises(MessageError, match="unknown message type 'uh_msgs/msg/Nope'"):
        dds_message('uh_msgs/msg/Nope')
    with pytest.raises(AttributeError, match='NoSuchType'):
        messages.NoSuchType  # noqa: B018


def test_msg_files_are_found_through_the_override_then_ament_then_prefix(tmp_path, monkeypatch):
    (tmp_path / 'msg').mkdir()
    (tmp_path / 'msg' / 'UHState.msg').write_text('uint32 uh_id\n')
    monkeypatch.setenv('UH_MSGS_DIR', str(tmp_path / 'msg'))
    assert messages._uh_msgs_dir() == tmp_path / 'msg'
    monkeypatch.setenv('UH_MSGS_DIR', str(tmp_path))
    with pytest.raises(MessageError, match='holds no .msg files'):
        messages._uh_msgs_dir()
    monkeypatch.delenv('UH_MSGS_DIR')
    share = tmp_path / 'ament' / 'share' / 'uh_msgs' / 'msg'
    share.mkdir(parents=True)
    (share / 'UHState.msg').write_text('uint32 uh_id\n')
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path / 'ament'))
    assert messages._uh_msgs_dir() == share
    assert messages.msg_search_path()[-1] == ROOT / 'uh_msgs' / 'msg'


def test_echo_yaml_has_the_shape_of_ros2_topic_echo():
    msg = messages.ControllerStatus()
    msg.uh_id = 4
    msg.z1.x = 0.5
    msg.stale_neighbours = ['2', '3']
    text = messages.message_to_yaml(msg)
    loaded = yaml.safe_load(text)
    assert loaded['uh_id'] == 4 and loaded['z1'] == {'x': 0.5, 'y': 0.0, 'z': 0.0}
    assert loaded['stale_neighbours'] == ['2', '3']
    assert text.startswith('header:\n  stamp:\n    sec: 0\n    nanosec: 0\n')
    assert "stale_neighbours:\n- '2'\n- '3'\n" in text
