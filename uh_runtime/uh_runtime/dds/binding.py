"""What differs between the two Cyclone DDS Python bindings the backend runs on, behind one call each.

PyPI's ``cyclonedds`` 11.0.1 (requirements.txt) and the 0.10.2 binding of secure mode
(requirements-secure.txt, docs/security.md) differ where the backend goes below the public API:

* taking raw samples: 11.0.1's ``_clayer.ddspy_take(reader, mask, N)`` takes those of ``mask``;
  0.10.2's ``ddspy_take(reader, N)`` takes every sample, which is what the backend's mask (any
  sample, view and instance state) asks for anyway (:func:`raw_take`);
* the readers a writer has matched and the writers a reader has matched: 11.0.1 has
  ``get_matched_subscriptions``, ``get_matched_subscription_data`` and their publication twins on
  its ``DataWriter`` and ``DataReader``; 0.10.2 has none of them, though its C library has the four
  calls, which the functions here then call through ``ctypes``, giving the same values (instance
  handles, and ``cyclonedds.builtin.DcpsEndpoint`` samples, ``None`` for a handle not matched).

On 11.0.1 every function calls what the backend called before, unchanged.
"""
from __future__ import annotations

import ctypes as ct
import functools
import uuid

__all__ = ['legacy_binding', 'raw_take', 'matched_subscriptions', 'matched_publications',
           'matched_subscription_data', 'matched_publication_data']


@functools.lru_cache(maxsize=1)
def legacy_binding() -> bool:
    """Return whether the installed binding is the 0.10 one (its ``DataReader`` cannot list matched writers)."""
    from cyclonedds.sub import DataReader
    return not hasattr(DataReader, 'get_matched_publications')


def raw_take():
    """Return ``take(reader_ref, mask, n)``: up to ``n`` samples as ``[(CDR bytes, sample info)]``, or an error code.

    11.0.1's ``ddspy_take`` itself; on 0.10 a call of its ``ddspy_take(reader_ref, n)``, which takes
    samples of any state, so only ``mask`` = any sample, view and instance state is accepted there.
    """
    from cyclonedds._clayer import ddspy_take
    if not legacy_binding():
        return ddspy_take
    from cyclonedds.core import InstanceState, SampleState, ViewState
    everything = SampleState.Any | ViewState.Any | InstanceState.Any

    def take(reader_ref, mask, n):
        if mask != everything:
            raise ValueError('the 0.10 binding of Cyclone DDS takes samples of any state only')
        return ddspy_take(reader_ref, n)
    return take


class _Guid(ct.Structure):
    _fields_ = [('v', ct.c_uint8 * 16)]


class _Endpoint(ct.Structure):
    """``dds_builtintopic_endpoint_t`` of ``dds/dds.h``."""

    _fields_ = [('key', _Guid), ('participant_key', _Guid), ('participant_instance_handle', ct.c_uint64),
                ('topic_name', ct.c_char_p), ('type_name', ct.c_char_p), ('qos', ct.c_void_p)]


@functools.lru_cache(maxsize=1)
def _library():
    """Return the Cyclone DDS C library with the C signatures of its matched-endpoint calls set."""
    from cyclonedds.internal import load_cyclonedds
    dll = load_cyclonedds()
    for name in ('dds_get_matched_subscriptions', 'dds_get_matched_publications'):
        getattr(dll, name).argtypes = [ct.c_int32, ct.POINTER(ct.c_uint64), ct.c_size_t]
        getattr(dll, name).restype = ct.c_int32
    for name in ('dds_get_matched_subscription_data', 'dds_get_matched_publication_data'):
        getattr(dll, name).argtypes = [ct.c_int32, ct.c_uint64]
        getattr(dll, name).restype = ct.POINTER(_Endpoint)
    dll.dds_builtintopic_free_endpoint.argtypes = [ct.POINTER(_Endpoint)]
    dll.dds_builtintopic_free_endpoint.restype = None
    return dll


def _handles(entity, call: str) -> list:
    """Return the instance handles the C call ``call`` (``dds_get_matched_*s``) gives for ``entity``."""
    from cyclonedds.core import DDSException
    function = getattr(_library(), call)
    for _ in range(3):    # the count may grow between the two calls: ask again with the larger array
        count = function(entity._ref, None, 0)
        if count < 0:
            raise DDSException(count, f'Occurred when getting the matched endpoints of {entity!r}')
        if count == 0:
            return []
        handles = (ct.c_uint64 * count)()
        got = function(entity._ref, handles, count)
        if got < 0:
            raise DDSException(got, f'Occurred when getting the matched endpoints of {entity!r}')
        if got <= count:
            return [int(h) for h in handles[:got]]
    return [int(h) for h in handles[:count]]


def _endpoint(entity, handle: int, call: str):
    """Return the ``DcpsEndpoint`` the C call ``call`` (``dds_get_matched_*_data``) gives, or None."""
    from cyclonedds.builtin import DcpsEndpoint
    from cyclonedds.internal import dds_c_t
    from cyclonedds.qos import _CQos
    pointer = getattr(_library(), call)(entity._ref, int(handle))
    if not pointer:
        return None
    try:
        sample = pointer.contents
        qos = _CQos.cqos_to_qos(ct.cast(sample.qos, dds_c_t.qos_p)) if sample.qos else None
        return DcpsEndpoint(uuid.UUID(bytes=bytes(sample.key.v)), uuid.UUID(bytes=bytes(sample.participant_key.v)),
                            int(sample.participant_instance_handle), (sample.topic_name or b'').decode(),
                            (sample.type_name or b'').decode(), qos, None)
    finally:
        _library().dds_builtintopic_free_endpoint(pointer)


def matched_subscriptions(writer) -> list:
    """Return the instance handles of the readers ``writer`` has matched."""
    if hasattr(writer, 'get_matched_subscriptions'):
        return writer.get_matched_subscriptions()
    return _handles(writer, 'dds_get_matched_subscriptions')


def matched_publications(reader) -> list:
    """Return the instance handles of the writers ``reader`` has matched."""
    if hasattr(reader, 'get_matched_publications'):
        return reader.get_matched_publications()
    return _handles(reader, 'dds_get_matched_publications')


def matched_subscription_data(writer, handle):
    """Return the ``DcpsEndpoint`` of the reader ``handle`` that ``writer`` has matched, or None."""
    if hasattr(writer, 'get_matched_subscription_data'):
        return writer.get_matched_subscription_data(handle)
    return _endpoint(writer, handle, 'dds_get_matched_subscription_data')


def matched_publication_data(reader, handle):
    """Return the ``DcpsEndpoint`` of the writer ``handle`` that ``reader`` has matched, or None."""
    if hasattr(reader, 'get_matched_publication_data'):
        return reader.get_matched_publication_data(handle)
    return _endpoint(reader, handle, 'dds_get_matched_publication_data')
