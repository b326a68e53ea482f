"""Numeric columns of many CDR payloads at once (uh_report/cdr_columns.py) against rosbags' decoder."""
import numpy as np
import pytest
from random_messages import random_message

from uh_report import cdr_columns
from uh_report.cdr_columns import read_columns
from uh_runtime.messages import typestore

STORE = typestore()
UH_TYPES = sorted(t for t in STORE.fielddefs if t.startswith('uh_msgs/msg/'))


def _random_message(rng, typename: str, strings: bool):
    """Return a random message of ``typename`` (:func:`random_messages.random_message`)."""
    return random_message(rng, STORE, typename, strings)


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
    # the same float64, NaN included (the random values cover NaN and the infinities)
    assert columns['u_p.x'][-1].tobytes() == np.float64(real(payloads[-1], typename).u_p.x).tobytes()


def test_no_payloads_give_empty_columns_and_an_unknown_field_is_refused():
    columns = read_columns(STORE, 'uh_msgs/msg/UHState', [], ['step', 'position.x'])
    assert columns['step'].shape == (0,) and columns['position.x'].dtype == np.float64
    with pytest.raises(KeyError):
        read_columns(STORE, 'uh_msgs/msg/UHState', [], ['position.w'])
