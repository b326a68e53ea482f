"""Random messages of rosbags' classes for the CDR reader tests (test_cdr_columns.py, test_cdr_codec.py).

Numbers cover their whole range (NaN, infinities and -0.0 among the floats); with ``strings`` the strings and
the sequence lengths are random too, otherwise every message of a type has one layout.
"""
import numpy as np
from rosbags.typesys.base import Nodetype

__all__ = ['NUMPY_TYPES', 'random_value', 'random_message']

#: rosbags' base type names and the numpy type of their little-endian CDR encoding.
NUMPY_TYPES = {'bool': '?', 'byte': 'u1', 'char': 'u1', 'int8': 'i1', 'uint8': 'u1', 'int16': '<i2',
               'uint16': '<u2', 'int32': '<i4', 'uint32': '<u4', 'int64': '<i8', 'uint64': '<u8',
               'float32': '<f4', 'float64': '<f8'}


def random_value(rng, base: str):
    """Return a random value of a base type, NaN and infinities among the floats."""
    if base == 'string':
        return 'x' * int(rng.integers(0, 6))
    if base == 'bool':
        return bool(rng.integers(0, 2))
    if base.startswith('float'):
        return float(rng.choice([np.nan, np.inf, -0.0, rng.normal() * 10.0 ** rng.integers(-5, 6)]))
    info = np.iinfo(NUMPY_TYPES[base])
    return int(rng.integers(info.min, info.max, dtype=np.int64 if info.min < 0 else np.uint64, endpoint=True))


def random_message(rng, store, typename: str, strings: bool):
    """Return a message of ``typename`` with random numbers (and random strings and sequences if ``strings``)."""
    kwargs = {}
    for name, (nodetype, desc) in store.fielddefs[typename][1]:
        if nodetype == Nodetype.NAME:
            kwargs[name] = random_message(rng, store, desc, strings)
        elif nodetype == Nodetype.BASE:
            kwargs[name] = random_value(rng, desc[0]) if desc[0] != 'string' or strings else 'world'
        else:
            (element_type, element), length = desc
            if nodetype == Nodetype.SEQUENCE:
                length = int(rng.integers(0, 4)) if strings else 2
            if element_type == Nodetype.NAME:        # a sequence or array of messages
                kwargs[name] = [random_message(rng, store, element, strings) for _ in range(length)]
                continue
            base = element[0]
            # without ``strings`` a numeric sequence is fixed too: its elements are layout bytes (uh_report.cdr_columns)
            fixed = 'uh2' if base == 'string' else (0 if nodetype == Nodetype.SEQUENCE else None)
            values = [random_value(rng, base) if strings or fixed is None else fixed for _ in range(length)]
            kwargs[name] = values if base == 'string' else np.array(values, dtype=NUMPY_TYPES[base])
    return store.types[typename](**kwargs)
