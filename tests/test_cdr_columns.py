"""Numeric columns of many CDR payloads at once (uh_report/cdr_columns.py) against rosbags' decoder."""
import numpy as np
import pytest
from rosbags.typesys.base import Nodetype

from uh_report import cdr_columns
from uh_report.cdr_columns import read_columns
from uh_runtime.messages import typestore

STORE = typestore()
UH_TYPES = sorted(t for t in STORE.fielddefs if t.startswith('uh_msgs/msg/'))
NUMERIC = {'bool', 'byte', 'char', 'int8', 'uint8', 'int16', 'uint16', 'int32', 'uint32', 'int64', 'uint64',
           'float32', 'float64'}


def _value(rng, base: str):
    """Return a random value of a base type, NaN and infinities among the floats."""
    if base == 'string':
        return 'x' * int(rng.integers(0, 6))
    if base == 'bool':
        return bool(rng.integers(0, 2))
    if base.startswith('float'):
        return float(rng.choice([np.nan, np.inf, -0.0, rng.normal() * 10.0 ** rng.integers(-5, 6)]))
    info = np.iinfo(cdr_columns._DTYPES[base])
    return int(rng.integers(info.min, info.max, dtype=np.int64 if info.min < 0 else np.uint64, endpoint=True))


def _random_message(rng, typename: str, strings: bool):
    """Return a message of ``typename`` with random numbers (and random strings and sequence lengths if ``strings``)."""
    kwargs = {}
    for name, (nodetype, desc) in STORE.fielddefs[typename][1]:
        if nodetype == Nodetype.NAME:
            kwargs[name] = _random_message(rng, desc, strings)
        elif nodetype == Nodetype.BASE:
            kwargs[name] = _value(rng, desc[0]) if desc[0] != 'string' or strings else 'world'
        else:
            (element_type, element), length = desc
            if nodetype == Nodetype.SEQUENCE:
                length = int(rng.integers(0, 4)) if strings else 2
            if element_type == Nodetype.NAME:        # a sequence or array of messages
                kwargs[name] = [_random_message(rng, element, strings) for _ in range(length)]
                continue
            base = element[0]
            values = [_value(rng, base) if base != 'string' or strings else 'uh2' for _ in range(length)]
            kwargs[name] = values if base == 'string' else np.array(values, dtype=cdr_columns._DTYPES[base])
    return STORE.types[typename](**kwargs)


def _numeric_fields(typename: str) -> list:
    return [leaf.name for leaf in cdr_columns._leaves(STORE, typename)]


def _decoded(payload: bytes, typename: str, field: str):
    obj = STORE.deserialize_cdr(payload, typename)
    for part in field.replace('[', '.').replace(']', '').split('.'):
        obj = obj[int(part)] if part.isdigit() else getattr(obj, part)
    return obj


@pytest.mark.parametrize('typename', UH_TYPES)
def test_columns_equal_rosbags_decoding_bit_for_bit_for_every_numeric_field(typename):
    rng = np.random.default_rng(len(typename))
    # mostly one layout (the fast path); some with other strings and sequence lengths, some
    # big-endian and some padded to a multiple of 4 bytes as a DDS writer sends them
    payloads = []
    for k in range(300):
        msg = _random_message(rng, typename, strings=k % 10 == 3)
        payload = bytes(STORE.serialize_cdr(msg, typename, little_endian=k % 17 != 5))
        payloads.append(payload + b'\0' * (-len(payload) % 4) if k % 2 else payload)
    fields = _numeric_fields(typename)
    assert fields, typename
    columns = read_columns(STORE, typename, payloads, fields)
    for field in fields:
        expected = np.array([_decoded(p, typename, field) for p in payloads], dtype=columns[field].dtype)
        assert columns[field].tobytes() == expected.tobytes(), field     # NaNs and -0.0 included


def test_payloads_of_one_layout_are_read_without_decoding_each(monkeypatch):
    typename = 'uh_msgs/msg/ControllerStatus'
    rng = np.random.default_rng(1)
    payloads = [bytes(STORE.serialize_cdr(_random_message(rng, typename, strings=False), typename))
                for _ in range(500)]
    decoded = []
    real = STORE.deserialize_cdr
    monkeypatch.setattr(STORE, 'deserialize_cdr', lambda raw, name: decoded.append(1) or real(raw, name))
    columns = read_columns(STORE, typename, payloads, ['step', 'u_p.x', 'fault_isolated[3]'])
    assert len(decoded) == 1          # the probe only: the 500 rows are read as columns
    assert columns['step'].dtype == np.uint64 and columns['fault_isolated[3]'].dtype == bool
    assert columns['u_p.x'][-1] == real(payloads[-1], typename).u_p.x


def test_no_payloads_give_empty_columns_and_an_unknown_field_is_refused():
    columns = read_columns(STORE, 'uh_msgs/msg/UHState', [], ['step', 'position.x'])
    assert columns['step'].shape == (0,) and columns['position.x'].dtype == np.float64
    with pytest.raises(KeyError):
        read_columns(STORE, 'uh_msgs/msg/UHState', [], ['position.w'])
