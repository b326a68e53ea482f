"""The record of one controller step's status: :class:`ControllerStatusData`, built from the layout table.

Its fields are those of :data:`uh_core.layout.STATUS_FIELDS` (the order of
``uh_msgs/ControllerStatus.msg``) between the step's identity (``uh_id``, ``step``, ``stamp``) and
what the node and the isolator add (``stale_neighbours``, ``isolation``); :func:`status_record`
reads the kernel's status vector into one, with getters built once from the same table.
"""
from __future__ import annotations

import dataclasses
import operator

import numpy as np

from uh_core.layout import (
    SATURATION_FLAGS,
    STATUS_FIELDS,
    STATUS_FLAG,
    STATUS_FLOAT,
    STATUS_INDEX,
    STATUS_SIZE,
    STATUS_VECTOR3,
    STATUS_WIDTH,
)

from .fault_isolation import IsolationStatus

__all__ = ['ControllerStatusData', 'status_record']


def _items(indices):
    """Give ``operator.itemgetter(*indices)`` that always returns a tuple (also of one index, or none)."""
    if len(indices) == 1:
        return lambda seq, i=indices[0]: (seq[i],)
    return operator.itemgetter(*indices) if indices else (lambda seq: ())


def _status_readers():
    """Build the getters :meth:`ControllerStatusData.from_vector` reads the status vector with.

    From :data:`uh_core.layout.STATUS_FIELDS`, whose 3-vectors come first (``STATUS_VECTORS``): the
    views of the 3-vectors; the flags, read from ``status.tolist()``; the other fields in order,
    from that list with the flags' truth values appended.
    """
    kinds = [f.kind for f in STATUS_FIELDS]
    if kinds != sorted(kinds, key=lambda kind: kind != STATUS_VECTOR3):
        raise ImportError('uh_core.layout.STATUS_FIELDS: the 3-vectors must come first')
    flags = [f.name for f in STATUS_FIELDS if f.kind == STATUS_FLAG]
    return (_items([slice(STATUS_INDEX[f.name], STATUS_INDEX[f.name] + STATUS_WIDTH[f.kind])
                    for f in STATUS_FIELDS if f.kind == STATUS_VECTOR3]),
            _items([STATUS_INDEX[name] for name in flags]), (0.0,) * len(flags),
            _items([STATUS_SIZE + flags.index(f.name) if f.kind == STATUS_FLAG else STATUS_INDEX[f.name]
                    for f in STATUS_FIELDS if f.kind != STATUS_VECTOR3]))


_STATUS_VECTOR_VIEWS, _STATUS_FLAG_VALUES, _FLAG_ZEROS, _STATUS_SCALARS = _status_readers()
_FIELD_TYPES = {STATUS_VECTOR3: np.ndarray, STATUS_FLOAT: float, STATUS_FLAG: bool}


def _field_docs() -> str:
    """Write the numpydoc entries of the fields of :data:`uh_core.layout.STATUS_FIELDS`."""
    return '\n    '.join(f'{f.name} : {_FIELD_TYPES[f.kind].__name__}\n        {f.description}.' for f in STATUS_FIELDS)


class _StatusMethods:
    """What :class:`ControllerStatusData` does besides holding the fields."""

    __slots__ = ()

    @property
    def saturated(self) -> bool:
        """True when any input limit was active."""
        return any(map(self.__getattribute__, SATURATION_FLAGS))

    @classmethod
    def from_vector(cls, uh_id: int, step: int, stamp: float, status: np.ndarray) -> 'ControllerStatusData':
        """Make the record of the kernel's ``status`` vector (STATUS_SIZE,).

        Its layout is :data:`uh_core.layout.STATUS_FIELDS`, whose field names and order are those of
        this record. The vector fields are views of ``status``, which the record then owns; a flag
        is ``entry != 0.0``.
        """
        values = status.tolist()
        values += map(operator.ne, _STATUS_FLAG_VALUES(values), _FLAG_ZEROS)
        return cls(uh_id, step, stamp, *_STATUS_VECTOR_VIEWS(status), *_STATUS_SCALARS(values))


_STATUS_DOC = f"""Internal signals of one UH controller for one step (fields of ``uh_msgs/ControllerStatus``).

    Outer-loop vectors are in the inertial frame; inner-loop vectors in the body frame (Euler-rate
    frame for ``z3``). All arrays are (3,) float64 and owned by this record. The fields from
    ``{STATUS_FIELDS[0].name}`` to ``{STATUS_FIELDS[-1].name}`` are those of
    :data:`uh_core.layout.STATUS_FIELDS`.

    Attributes
    ----------
    uh_id, step : int
        Helicopter id and step index k.
    stamp : float
        t_k = k dt, s.
    {_field_docs()}
    stale_neighbours : tuple of str
        Filled by the node when a neighbour's data is older than its timeout; empty here.
    isolation : IsolationStatus or None
        The controller's fault isolation and identification after this step
        (:class:`~uh_controller_node.fault_isolation.FaultIsolator`,
        docs/faults.md#isolation-and-identification); None in a record not made by a controller.
    lost_uhs : tuple of int
        The UHs the controller knows to be lost (docs/resilience.md); empty without ``resilience``.
    role : str
        ``leader``, ``follower``, ``holding (why)`` or ``lost`` in the team it flies; empty without ``resilience``.
    """
ControllerStatusData = dataclasses.make_dataclass(
    'ControllerStatusData',
    [('uh_id', int), ('step', int), ('stamp', float), *((f.name, _FIELD_TYPES[f.kind]) for f in STATUS_FIELDS),
     ('stale_neighbours', tuple, dataclasses.field(default_factory=tuple)),
     ('isolation', IsolationStatus | None, dataclasses.field(default=None)),
     ('lost_uhs', tuple, dataclasses.field(default_factory=tuple)), ('role', str, dataclasses.field(default=''))],
    bases=(_StatusMethods,), namespace={'__module__': __name__, '__doc__': _STATUS_DOC})
#: :meth:`ControllerStatusData.from_vector`, bound once: the controller calls it every step.
status_record = ControllerStatusData.from_vector
