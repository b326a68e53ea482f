"""Numeric fields of many CDR payloads of one message type, read at once as numpy columns.

rosbags decodes one message in about 20 µs; the metrics of a 60 s run of the paper scenario need
126,000 of them (docs/metrics.md). But the messages of one topic come from one node and share one
layout: the same ``frame_id``, the same sequence lengths, so every fixed-size numeric field sits at
the same byte offset in every payload. :func:`read_columns` finds those offsets with rosbags itself
and reads the payloads as rows of one byte array:

1. decode the first payload (the probe) with rosbags and encode it back; the bytes must be the same;
2. for every fixed-size numeric field of the type (nested messages and fixed arrays included), encode
   the probe twice with the field set to two values that differ in every byte: the bytes that
   change are the field's, and nothing else may change;
3. every byte no numeric field owns (the CDR header, strings, sequence lengths, padding) is a layout
   byte: a payload of the probe's length whose layout bytes equal the probe's has the probe's
   layout, and its fields are read from the rows at once; any other payload (another length, another
   string, a big-endian one) is decoded by rosbags on its own.

No CDR rule is written here: where a field lives is what rosbags' own encoder says.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rosbags.typesys.base import Nodetype

__all__ = ['read_columns']

# rosbags' base type names and the numpy type of their little-endian CDR encoding
_DTYPES = {'bool': '?', 'byte': 'u1', 'char': 'u1', 'int8': 'i1', 'uint8': 'u1', 'int16': '<i2',
           'uint16': '<u2', 'int32': '<i4', 'uint32': '<u4', 'int64': '<i8', 'uint64': '<u8',
           'float32': '<f4', 'float64': '<f8'}


@dataclass(frozen=True)
class _Leaf:
    """One fixed-size numeric field: its dotted name, where it lives in the message and its type."""

    name: str        # e.g. 'position.x', 'fault_isolated[2]'
    path: tuple      # attribute names from the message down, then an element index for arrays
    dtype: np.dtype


def _leaves(store, typename: str, prefix: str = '', path: tuple = ()) -> list[_Leaf]:
    """Return every fixed-size numeric field of ``typename`` (strings and sequences are layout)."""
    found = []
    for name, (nodetype, desc) in store.fielddefs[typename][1]:
        dotted, here = f'{prefix}{name}', path + (name,)
        if nodetype == Nodetype.NAME:
            found += _leaves(store, desc, dotted + '.', here)
        elif nodetype == Nodetype.BASE and desc[0] in _DTYPES:
            found.append(_Leaf(dotted, here, np.dtype(_DTYPES[desc[0]])))
        elif nodetype == Nodetype.ARRAY and desc[0][0] == Nodetype.BASE and desc[0][1][0] in _DTYPES:
            dtype = np.dtype(_DTYPES[desc[0][1][0]])
            found += [_Leaf(f'{dotted}[{k}]', here + (k,), dtype) for k in range(desc[1])]
    return found


def _owner(msg, leaf: _Leaf):
    """Return the object holding ``leaf`` and its key: (message or nested message, attribute) or (array, index)."""
    obj = msg
    for key in leaf.path[:-1]:
        obj = getattr(obj, key)
    return obj, leaf.path[-1]


def _get(msg, leaf: _Leaf):
    """Return the value of ``leaf`` in ``msg``."""
    obj, key = _owner(msg, leaf)
    return obj[key] if isinstance(key, int) else getattr(obj, key)


def _set(msg, leaf: _Leaf, value) -> None:
    """Set ``leaf`` of ``msg`` to ``value``."""
    obj, key = _owner(msg, leaf)
    if isinstance(key, int):
        obj[key] = value
    else:
        setattr(obj, key, value)


def _writable_arrays(msg, store, typename: str) -> None:
    """Replace the (read-only, buffer-backed) arrays rosbags decoded into ``msg`` by copies."""
    for name, (nodetype, desc) in store.fielddefs[typename][1]:
        if nodetype == Nodetype.NAME:
            _writable_arrays(getattr(msg, name), store, desc)
        elif nodetype == Nodetype.ARRAY and isinstance(getattr(msg, name), np.ndarray):
            setattr(msg, name, getattr(msg, name).copy())


def _sentinels(dtype: np.dtype):
    """Two values of ``dtype`` whose encodings differ in every byte."""
    if dtype.kind == 'b':
        return False, True
    a, b = (np.frombuffer(bytes([v] * dtype.itemsize), dtype)[0] for v in (0x11, 0x22))
    return a.item(), b.item()


def _offsets(store, typename: str, probe: bytes) -> tuple[dict, np.ndarray] | None:
    """Return ``({field name: (offset, leaf)}, layout byte mask)`` of ``probe``, or None if unusable."""
    msg = store.deserialize_cdr(probe, typename)
    encoded = bytes(store.serialize_cdr(msg, typename))
    # a DDS writer may pad the payload to a multiple of 4 bytes; rosbags' encoding ends without it
    size = len(encoded)
    if probe[:size] != encoded or probe[size:].strip(b'\x00') or len(probe) - size > 3 or probe[:2] != b'\x00\x01':
        return None     # not re-encoded to the same bytes, or not little-endian CDR: decode one by one
    _writable_arrays(msg, store, typename)
    layout = np.ones(len(probe), bool)
    where = {}
    for leaf in _leaves(store, typename):
        kept = _get(msg, leaf)
        pair = []
        for value in _sentinels(leaf.dtype):
            _set(msg, leaf, value)
            pair.append(np.frombuffer(bytes(store.serialize_cdr(msg, typename)), np.uint8))
        _set(msg, leaf, kept)
        if len(pair[0]) != size or len(pair[1]) != size:
            return None
        changed = np.flatnonzero(pair[0] != pair[1])
        width = leaf.dtype.itemsize
        if len(changed) != width or changed[-1] - changed[0] != width - 1:
            return None
        where[leaf.name] = (int(changed[0]), leaf)
        layout[changed[0]:changed[0] + width] = False
    return where, layout


def read_columns(store, typename: str, payloads: list, fields) -> dict:
    """Return ``{field: array of len(payloads)}`` of the numeric ``fields`` of every payload, in order.

    ``fields`` are dotted names of fixed-size numeric fields (``'step'``, ``'position.x'``,
    ``'fault_isolated[2]'``); each array has the field's numpy type. Payloads that share the first
    one's layout are read as numpy rows; the others are decoded one by one with rosbags. Raises
    whatever rosbags raises for a payload that does not decode, and KeyError for an unknown field.
    """
    leaves = {leaf.name: leaf for leaf in _leaves(store, typename)}
    columns = {f: np.empty(len(payloads), leaves[f].dtype) for f in fields}
    if not payloads:
        return columns
    probe = bytes(payloads[0])
    found = _offsets(store, typename, probe)
    fast = np.zeros(len(payloads), bool)
    if found is not None:
        where, layout = found
        fast = np.fromiter(map(len, payloads), int, len(payloads)) == len(probe)
        rows = np.frombuffer(b''.join(p for p, f in zip(payloads, fast, strict=True) if f),
                             np.uint8).reshape(-1, len(probe))
        same = (rows[:, layout] == np.frombuffer(probe, np.uint8)[layout]).all(axis=1)
        fast[np.flatnonzero(fast)[~same]] = False
        rows = rows[same]
        for f in fields:
            offset, leaf = where[f]
            columns[f][fast] = np.ascontiguousarray(rows[:, offset:offset + leaf.dtype.itemsize]).view(leaf.dtype)[:, 0]
    for k in np.flatnonzero(~fast):
        msg = store.deserialize_cdr(payloads[k], typename)
        for f in fields:
            columns[f][k] = _get(msg, leaves[f])
    return columns
