"""The DDS backend's CDR codecs (uh_runtime/dds/cdr.py) against rosbags' deserialiser, with random values.

For every uh_msgs type: random messages (numbers over their whole range, NaN, infinities and -0.0 among the
floats; random strings and sequence lengths), encoded by rosbags as a DDS writer sends them (little-endian,
some padded to a multiple of 4 bytes) and some big-endian (which the codec hands to cyclonedds' reader). The
codec's message must hold, field for field and bit for bit, what rosbags' ``deserialize_cdr`` reads from the
same bytes, and the codec must write those bytes again. The report's column reader is checked against rosbags
the same way (test_cdr_columns.py).
"""
from pathlib import Path

import numpy as np
import pytest
from random_messages import NUMPY_TYPES, random_message
from rosbags.typesys.base import Nodetype

from uh_runtime.dds.cdr import codec
from uh_runtime.messages import dds_message, typestore

STORE = typestore()
UH_TYPES = sorted(t for t in STORE.fielddefs if t.startswith('uh_msgs/msg/'))
MSG_DIR = Path(__file__).resolve().parents[1] / 'uh_msgs' / 'msg'


def assert_same(decoded, reference, spec, where: str) -> None:
    """Assert that the codec's ``decoded`` value is rosbags' ``reference`` (field type ``spec``), bit for bit."""
    kind, details = spec
    if kind == Nodetype.NAME:
        for name, field in STORE.fielddefs[details][1]:
            assert_same(getattr(decoded, name), getattr(reference, name), field, f'{where}.{name}')
    elif kind == Nodetype.BASE and details[0] == 'string':
        assert decoded == reference, where
    elif kind == Nodetype.BASE:
        dtype = NUMPY_TYPES[details[0]]
        assert np.array([decoded], dtype).tobytes() == np.array([reference], dtype).tobytes(), where
    else:
        element, _ = details
        assert len(decoded) == len(reference), where
        for k, (one, other) in enumerate(zip(decoded, reference, strict=True)):
            assert_same(one, other, element, f'{where}[{k}]')


def test_every_uh_msgs_type_is_checked():
    assert UH_TYPES == sorted(f'uh_msgs/msg/{p.stem}' for p in MSG_DIR.glob('*.msg'))


@pytest.mark.parametrize('typename', UH_TYPES)
def test_codec_reads_what_rosbags_reads_from_random_messages(typename):
    rng = np.random.default_rng(len(typename) + 7)
    fast = codec(dds_message(typename))
    for k in range(200):
        msg = random_message(rng, STORE, typename, strings=k % 3 == 1)
        little_endian, padded = k % 17 != 5, k % 2 == 1
        payload = bytes(STORE.serialize_cdr(msg, typename, little_endian=little_endian))
        if padded:
            payload += b'\0' * (-len(payload) % 4)     # as a DDS writer sends it
        decoded = fast.deserialize(payload)
        assert_same(decoded, STORE.deserialize_cdr(payload, typename), (Nodetype.NAME, typename), typename)
        if little_endian and not padded:
            assert fast.serialize(decoded) == payload
