"""Message classes for both backends, built from the ``.msg`` files (docs/runtime.md).

On the rclpy backend, :func:`get_message` returns the rosidl-generated classes
(``uh_msgs.msg.UHState`` ...). On the Cyclone DDS backend it returns
:class:`cyclonedds.idl.IdlStruct` classes generated here from the same definitions:

* ``uh_msgs`` types are parsed from the ``.msg`` files with rosbags' ``get_types_from_msg``; the
  files are looked up in ``$UH_MSGS_DIR``, then ``<prefix>/share/uh_msgs/msg`` for every prefix of
  ``AMENT_PREFIX_PATH``, then ``<sys.prefix>/share/uh_msgs/msg`` (where pip installs them), and
  last the source tree's ``uh_msgs/msg``;
* standard types (``std_msgs/msg/Header``, ``rosgraph_msgs/msg/Clock``,
  ``visualization_msgs/msg/MarkerArray``, ``rmw_dds_common/msg/ParticipantEntitiesInfo`` ...) come
  from rosbags' ROS 2 Jazzy type store.

Every field gets its exact ROS width (``int32`` -> ``types.int32``, ``float64[4]`` ->
``types.array[types.float64, 4]``, ``string[]`` -> ``types.sequence[str]``), so
``IdlStruct.serialize()`` writes XCDR1 little-endian bytes identical to ROS 2 CDR. Fields have
ROS-like defaults (zeros, empty strings and lists, nested messages built by default factories) and
constants are class attributes, so ``msg = UHState(); msg.position.x = 1.0`` works as with rclpy.

Each DDS class carries ``__ros_typename__`` (``'uh_msgs/msg/UHState'``), ``__ros_typehash__``
(``'RIHS01_<hex>'``, ROS's type hash: :func:`type_hash`) and its DDS
type name ``uh_msgs::msg::dds_::UHState_``.
"""
import dataclasses
import functools
import hashlib
import importlib
import os
import re
import sys
import threading
from collections import OrderedDict
from pathlib import Path

from . import message_cache as _cache
from .backend import select_backend

__all__ = [
    'MessageError', 'get_message', 'dds_message', 'type_hash', 'ros_type_name', 'dds_type_name',
    'ros_type_from_dds', 'dds_service_message', 'SERVICE_DEFINITIONS', 'typestore', 'msg_search_path',
    'message_to_ordereddict', 'message_to_yaml', 'message_fields', 'BACKEND',
]

#: Backend whose classes :func:`get_message` and the module attributes return.
BACKEND = select_backend()

#: Short names available as module attributes (``uh_runtime.messages.UHState``).
KNOWN_TYPES = {
    'UHState': 'uh_msgs/msg/UHState',
    'ActuatorCommand': 'uh_msgs/msg/ActuatorCommand',
    'Reference': 'uh_msgs/msg/Reference',
    'ActuatorFault': 'uh_msgs/msg/ActuatorFault',
    'FaultTruth': 'uh_msgs/msg/FaultTruth',
    'ControllerStatus': 'uh_msgs/msg/ControllerStatus',
    'ReceivedStates': 'uh_msgs/msg/ReceivedStates',
    'Proximity': 'uh_msgs/msg/Proximity',
    'Clock': 'rosgraph_msgs/msg/Clock',
    'Header': 'std_msgs/msg/Header',
    'String': 'std_msgs/msg/String',
    'ColorRGBA': 'std_msgs/msg/ColorRGBA',
    'Time': 'builtin_interfaces/msg/Time',
    'Duration': 'builtin_interfaces/msg/Duration',
    'Vector3': 'geometry_msgs/msg/Vector3',
    'Point': 'geometry_msgs/msg/Point',
    'Quaternion': 'geometry_msgs/msg/Quaternion',
    'Pose': 'geometry_msgs/msg/Pose',
    'MarkerArray': 'visualization_msgs/msg/MarkerArray',
    'Marker': 'visualization_msgs/msg/Marker',
    'ParticipantEntitiesInfo': 'rmw_dds_common/msg/ParticipantEntitiesInfo',
    'NodeEntitiesInfo': 'rmw_dds_common/msg/NodeEntitiesInfo',
    'Gid': 'rmw_dds_common/msg/Gid',
}

_UH_PACKAGE = 'uh_msgs'
_NAME_RE = re.compile(r'^([A-Za-z][A-Za-z0-9_]*)/(?:msg/)?([A-Za-z][A-Za-z0-9_]*)$')
_SRV_NAME_RE = re.compile(r'^([A-Za-z][A-Za-z0-9_]*)/srv/([A-Za-z][A-Za-z0-9_]*_(?:Request|Response))$')

#: The services the DDS backend serves (rclpy's parameter services), as the request and response
#: parts of their ``.srv`` definitions (rcl_interfaces, Jazzy); the field types are the Jazzy type
#: store's. Registered in :func:`typestore` as ``pkg/srv/<Service>_Request`` / ``_Response``.
SERVICE_DEFINITIONS = {
    'rcl_interfaces/srv/DescribeParameters': ('string[] names\n', 'ParameterDescriptor[] descriptors\n'),
    'rcl_interfaces/srv/GetParameters': ('string[] names\n', 'ParameterValue[] values\n'),
    'rcl_interfaces/srv/GetParameterTypes': ('string[] names\n', 'uint8[] types\n'),
    'rcl_interfaces/srv/ListParameters': ('uint64 DEPTH_RECURSIVE=0\nstring[] prefixes\nuint64 depth\n',
                                          'ListParametersResult result\n'),
    'rcl_interfaces/srv/SetParameters': ('Parameter[] parameters\n', 'SetParametersResult[] results\n'),
    'rcl_interfaces/srv/SetParametersAtomically': ('Parameter[] parameters\n', 'SetParametersResult result\n'),
}


class MessageError(LookupError):
    """A message type name is malformed or unknown, or the ``.msg`` files cannot be found."""


def _normalise(name: str) -> str:
    """Normalise a type name: ``'uh_msgs/UHState'`` or ``'uh_msgs/msg/UHState'`` -> ``'uh_msgs/msg/UHState'``.

    A service part ``'pkg/srv/<Service>_Request'`` (or ``_Response``) is kept as it is.
    """
    if _SRV_NAME_RE.match(str(name).strip()):
        return str(name).strip()
    match = _NAME_RE.match(str(name).strip())
    if not match:
        raise MessageError(
            f'{name!r} is not a message type name; expected "<package>/msg/<Type>", '
            'e.g. "uh_msgs/msg/UHState"')
    return f'{match.group(1)}/msg/{match.group(2)}'


def msg_search_path() -> list[Path]:
    """Directories searched, in order, for the ``uh_msgs`` ``.msg`` files (see module docstring)."""
    paths = []
    override = os.environ.get('UH_MSGS_DIR')
    if override:
        paths.append(Path(override))
    for prefix in filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)):
        paths.append(Path(prefix) / 'share' / _UH_PACKAGE / 'msg')
    paths.append(Path(sys.prefix) / 'share' / _UH_PACKAGE / 'msg')
    paths.append(Path(__file__).resolve().parents[2] / _UH_PACKAGE / 'msg')
    return paths


def _uh_msgs_dir() -> Path:
    override = os.environ.get('UH_MSGS_DIR')
    if override and not any(Path(override).glob('*.msg')):
        raise MessageError(f'UH_MSGS_DIR={override!r} holds no .msg files')
    for path in msg_search_path():
        if any(path.glob('*.msg')):
            return path
    raise MessageError(
        'cannot find the uh_msgs .msg files; looked in: '
        + ', '.join(str(p) for p in msg_search_path())
        + ' (install uh_msgs, source a ROS 2 workspace, or set UH_MSGS_DIR)')


_lock = threading.RLock()
_store = None
_store_digest = None   # of what the store was made of (:func:`_store_key`)
_classes: dict = {}


def typestore():
    """Return the rosbags type store: ROS 2 Jazzy standard types plus every ``uh_msgs`` type.

    Built once per process; it is the reference for type hashes and CDR bytes. When a process built
    the same store before, its definitions come from :mod:`uh_runtime.message_cache` and rosbags'
    own message classes are built at first use only (:func:`_cached_store`).
    """
    global _store, _store_digest
    with _lock:
        if _store is None:
            _store_digest = _store_key()
            name = f'typestore-{_store_digest}.json'
            fielddefs = _cache.read(name, _cache.decode_fielddefs) if _store_digest else None
            if fielddefs is None:
                _store = _build_store()
                if _store_digest:
                    _cache.write(name, _cache.encode_fielddefs(_store.fielddefs))
            else:
                _store = _cached_store(fielddefs)
        return _store


def _build_store():
    """Build the store of :func:`typestore` from rosbags' Jazzy store, the ``.msg`` files and the services."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for name, text in uh_msg_texts().items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    # service parts: parsed as pkg/msg/X so their field types resolve in pkg (rosbags knows
    # no srv), stored under pkg/srv/X, the name ROS hashes them by
    parts = {}
    for service, texts in SERVICE_DEFINITIONS.items():
        pkg, _, typ = service.split('/')
        for part, text in zip(('Request', 'Response'), texts, strict=True):
            parsed = get_types_from_msg(text, f'{pkg}/msg/{typ}_{part}')
            parts[f'{pkg}/srv/{typ}_{part}'] = parsed[f'{pkg}/msg/{typ}_{part}']
    store.register(parts)
    return store


def _store_key() -> str | None:
    """Digest of what :func:`_build_store` and the classes are made of (None if it cannot be known).

    This module and :mod:`uh_runtime.message_cache` (how), the installed rosbags type system (its
    standard types and its ``.msg`` parser) and the ``uh_msgs`` definitions.
    """
    import rosbags.typesys
    try:
        digest = hashlib.sha256(Path(__file__).read_bytes() + Path(_cache.__file__).read_bytes())
        _cache.files_digest(digest, Path(rosbags.typesys.__file__).parent)
    except OSError:
        return None
    for name, text in uh_msg_texts().items():
        digest.update(f'{name}\0{text}\0'.encode())
    return digest.hexdigest()[:32]


def _cached_store(fielddefs):
    """Return a store like :func:`_build_store`'s with the definitions ``fielddefs`` (from the cache).

    Type hashes, this module's classes and the CDR codecs (:mod:`uh_runtime.dds.cdr`) read the
    definitions only. rosbags' message classes (``types``: ``serialize_cdr``, ``deserialize_cdr``,
    ``register``) are those of :func:`_build_store`, called at first use: importing rosbags'
    standard store, which defines ~1000 classes, took 0.1 s of every node's start.
    """
    from rosbags.typesys.store import Typestore

    class CachedTypestore(Typestore):
        def __init__(self):
            super().__init__()
            self.fielddefs.update(fielddefs)

        @property
        def types(self):
            with _lock:
                if self._types is None:
                    self._types = _build_store().types
                return self._types

        @types.setter
        def types(self, value):
            self._types = value or None    # Typestore.__init__ sets {}: not built yet

    return CachedTypestore()


@functools.lru_cache(maxsize=None)
def uh_msg_texts() -> dict:
    """``{'uh_msgs/msg/Type': .msg text}`` of every ``uh_msgs`` type (with its comments), read once."""
    return {f'{_UH_PACKAGE}/msg/{path.stem}': path.read_text() for path in sorted(_uh_msgs_dir().glob('*.msg'))}


def ros_type_name(msg_or_class) -> str:
    """``'pkg/msg/Type'`` of a message class or instance of either backend."""
    cls = msg_or_class if isinstance(msg_or_class, type) else type(msg_or_class)
    name = getattr(cls, '__ros_typename__', None)
    if name:
        return name
    module = getattr(cls, '__module__', '')
    if '.msg' in module:  # rosidl class, e.g. uh_msgs.msg._uh_state.UHState
        return f"{module.split('.')[0]}/msg/{cls.__name__}"
    raise MessageError(f'{cls!r} is not a ROS message class')


def dds_type_name(name_or_class) -> str:
    """DDS type name ROS uses for a message type: ``'uh_msgs::msg::dds_::UHState_'``."""
    name = name_or_class if isinstance(name_or_class, str) else ros_type_name(name_or_class)
    pkg, kind, typ = _normalise(name).split('/')
    return f'{pkg}::{kind}::dds_::{typ}_'


def ros_type_from_dds(dds_name: str) -> str:
    """Inverse of :func:`dds_type_name`; names that do not follow the convention are returned as is."""
    match = re.match(r'^(\w+)::(\w+)::dds_::(\w+)_$', dds_name)
    if not match:
        return dds_name
    return f'{match.group(1)}/{match.group(2)}/{match.group(3)}'


def type_hash(name_or_class) -> str:
    """``'RIHS01_<64 hex>'`` type hash of a message type (what ROS 2 Jazzy puts in USER_DATA).

    ROS hashes the type description of the IDL that rosidl generates from the ``.msg``, where a
    ``char`` field has become ``uint8`` (rosidl_adapter); rosbags hashes ``char`` as its own field
    type. :func:`_hash_store` is the type store with ``char`` written as ``uint8``, so the hash of
    a type with a ``char`` in it (``rmw_dds_common/msg/Gid`` and the types that hold it) is ROS's.
    """
    if not isinstance(name_or_class, str):
        cached = getattr(name_or_class, '__ros_typehash__', None)
        if cached:
            return cached
        name_or_class = ros_type_name(name_or_class)
    name = _normalise(name_or_class)
    store = typestore()
    if name not in store.fielddefs:
        raise MessageError(f'unknown message type {name!r}')
    # a second store, of this type and the types it holds only, for a type that holds a char somewhere
    return (_hash_store(name) if _holds_char(name) else store).hash_rihs01(name)


@functools.lru_cache(maxsize=None)
def _holds_char(name: str) -> bool:
    """Whether type ``name`` or a type it holds has a ``char`` field."""
    from rosbags.interfaces import Nodetype

    def char_in(field):
        kind, payload = field
        if kind == Nodetype.BASE:
            return payload[0] == 'char'
        if kind == Nodetype.NAME:
            return _holds_char(payload)
        return char_in(payload[0])   # array or sequence
    return any(char_in(f) for _, f in typestore().fielddefs[name][1])


def _char_as_uint8(field):
    """Return a rosbags field description with every ``char`` (alone, in an array or a sequence) as ``uint8``."""
    from rosbags.interfaces import Nodetype
    kind, payload = field
    if kind == Nodetype.BASE and payload[0] == 'char':
        return kind, ('uint8', payload[1])
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return kind, (_char_as_uint8(payload[0]), payload[1])
    return field


def _held_types(name: str, found: set) -> set:
    """Add ``name`` and every type it holds (nested, in arrays and sequences) to ``found``; return it."""
    from rosbags.interfaces import Nodetype

    def visit(field):
        kind, payload = field
        if kind == Nodetype.NAME and payload not in found:
            _held_types(payload, found)
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            visit(payload[0])
    found.add(name)
    for _, field in typestore().fielddefs[name][1]:
        visit(field)
    return found


@functools.lru_cache(maxsize=None)
def _hash_store(name: str):
    """Type ``name`` and the types it holds, with ``char`` fields as ``uint8`` (see :func:`type_hash`).

    For hashing only. Only these few types are copied: a copy of the whole :func:`typestore`
    took about 0.1 s, a noticeable part of a short-lived tool's start (``inject_fault.sh``).
    """
    from rosbags.typesys import Stores, get_typestore
    source = typestore().fielddefs
    store = get_typestore(Stores.EMPTY)
    store.register({held: (source[held][0], [(fname, _char_as_uint8(f)) for fname, f in source[held][1]])
                    for held in _held_types(name, set())})
    return store


# ----------------------------------------------------------------------------------------------
# IdlStruct generation
# ----------------------------------------------------------------------------------------------
def _base_type(types, base: str, bound: int):
    """Return the cyclonedds annotation and default value of a ROS primitive type."""
    table = {
        'bool': (bool, False),
        # rmw_cyclonedds describes ROS byte and char as DDS uint8 too (same CDR bytes)
        'byte': (types.uint8, 0),
        'char': (types.uint8, 0),
        'int8': (types.int8, 0), 'uint8': (types.uint8, 0),
        'int16': (types.int16, 0), 'uint16': (types.uint16, 0),
        'int32': (types.int32, 0), 'uint32': (types.uint32, 0),
        'int64': (types.int64, 0), 'uint64': (types.uint64, 0),
        'float32': (types.float32, 0.0), 'float64': (types.float64, 0.0),
    }
    if base == 'string':
        return (types.bounded_str[bound] if bound else str), ''
    if base in table:
        return table[base]
    raise MessageError(f'ROS primitive type {base!r} is not supported on the DDS backend')


def _field_type(types, spec):
    """(annotation, default factory) of one rosbags field spec ``(Nodetype, details)``."""
    from rosbags.typesys.base import Nodetype
    kind, details = spec
    if kind == Nodetype.BASE:
        annotation, default = _base_type(types, details[0], details[1])
        return annotation, (lambda d=default: d)
    if kind == Nodetype.NAME:
        cls = dds_message(details)
        return cls, cls
    if kind == Nodetype.ARRAY:
        sub, length = details
        sub_ann, sub_factory = _field_type(types, sub)
        return types.array[sub_ann, length], (lambda f=sub_factory, n=length: [f() for _ in range(n)])
    if kind == Nodetype.SEQUENCE:
        sub, bound = details
        sub_ann, _ = _field_type(types, sub)
        ann = types.sequence[sub_ann, bound] if bound else types.sequence[sub_ann]
        return ann, list
    raise MessageError(f'unsupported field specification {spec!r}')


def _idl_class(name: str, consts, fields, module: str, key: str):
    """Build the ``IdlStruct`` dataclass of ROS type ``name`` with rosbags ``fields`` and ``consts``.

    It has DDS type name :func:`dds_type_name`, ROS-like defaults, constants as class attributes,
    ``__ros_typename__`` and ``__ros_typehash__``, module ``<pkg>.<module>`` like rosidl's. Its
    XTypes type information is cached under ``key`` (:func:`uh_runtime.message_cache.cache_type_data`).
    """
    from cyclonedds.idl import IdlStruct, types
    from cyclonedds.idl._main import IdlMeta
    pkg, _, typ = name.split('/')
    bases = (IdlStruct,)
    namespace = IdlMeta.__prepare__(typ, bases, typename=dds_type_name(name))
    for fname, spec in fields:
        annotation, factory = _field_type(types, spec)
        namespace['__annotations__'][fname] = annotation
        namespace[fname] = dataclasses.field(default_factory=factory)
    for cname, _ctype, value in consts:
        namespace[cname] = value
    namespace['__ros_typename__'] = name
    namespace['__ros_typehash__'] = type_hash(name)
    namespace['__module__'] = f'{pkg}.{module}'
    namespace['__qualname__'] = typ
    cls = dataclasses.dataclass(IdlMeta(typ, bases, namespace))
    _cache.cache_type_data(cls, key, _store_digest)
    return cls


def dds_message(name: str):
    """Return the Cyclone DDS (``IdlStruct``) class of message type ``name``, whatever the backend.

    Raises
    ------
    MessageError
        ``name`` is malformed or not a known type.
    """
    name = _normalise(name)

    def build():
        store = typestore()
        if name not in store.fielddefs:
            raise MessageError(
                f'unknown message type {name!r}: not a uh_msgs type (.msg files in '
                f'{_uh_msgs_dir()}) nor a ROS 2 Jazzy standard type')
        return _idl_class(name, *store.fielddefs[name], module='msg', key=name)

    return _cached_class(name, build)


def _cached_class(key: str, build):
    """Return the class cached under ``key``, building it with ``build()`` once (thread-safe)."""
    with _lock:
        cls = _classes.get(key)
        if cls is None:
            cls = _classes[key] = build()
        return cls


def dds_service_message(name: str):
    """Return the Cyclone DDS class of a service's request or reply *sample*.

    ``name`` is ``'pkg/srv/<Service>_Request'`` or ``_Response``. The class is as rmw_cyclonedds puts it on
    the wire: the request header ``client_guid`` (uint64: the client's writer instance) and ``sequence_number``
    (int64) before the message's own fields. Its DDS type name is the message's
    (``rcl_interfaces::srv::dds_::ListParameters_Request_``) and its type hash the message's.
    """
    name = str(name).strip()
    if not _SRV_NAME_RE.match(name):
        raise MessageError(f'{name!r} is not a service part name; expected "<package>/srv/<Service>_Request" '
                           'or "_Response"')

    def build():
        from rosbags.interfaces import Nodetype
        store = typestore()
        if name not in store.fielddefs:
            raise MessageError(f'unknown service part {name!r}; known services: {", ".join(SERVICE_DEFINITIONS)}')
        consts, fields = store.fielddefs[name]
        header = [('client_guid', (Nodetype.BASE, ('uint64', 0))),
                  ('sequence_number', (Nodetype.BASE, ('int64', 0)))]
        return _idl_class(name, consts, header + list(fields), module='srv', key='wrapped:' + name)

    return _cached_class('wrapped:' + name, build)


def get_message(name: str):
    """Return the message class of ``name`` (``'uh_msgs/msg/UHState'``) for the active backend."""
    name = _normalise(name)
    if BACKEND == 'rclpy':
        pkg, _, typ = name.split('/')
        try:
            return getattr(importlib.import_module(f'{pkg}.msg'), typ)
        except (ImportError, AttributeError) as exc:
            raise MessageError(f'cannot import {name} from the ROS 2 installation: {exc}') from exc
    return dds_message(name)


def __getattr__(attr):
    if attr in KNOWN_TYPES:
        cls = get_message(KNOWN_TYPES[attr])
        globals()[attr] = cls
        return cls
    raise AttributeError(f'module {__name__!r} has no attribute {attr!r}')


# ----------------------------------------------------------------------------------------------
# Introspection and YAML (as ``ros2 topic echo`` prints)
# ----------------------------------------------------------------------------------------------
def message_fields(msg) -> list[str]:
    """Field names of a message instance or class of either backend, in definition order."""
    cls = msg if isinstance(msg, type) else type(msg)
    if hasattr(cls, 'get_fields_and_field_types'):  # rosidl
        return list(cls.get_fields_and_field_types())
    return [f.name for f in dataclasses.fields(cls)]


def _is_message(value) -> bool:
    return hasattr(type(value), '__ros_typename__') or hasattr(type(value), 'get_fields_and_field_types')


def message_to_ordereddict(msg, truncate_length=None):
    """Nested ``OrderedDict`` of a message (like ``rosidl_runtime_py.message_to_ordereddict``)."""
    out = OrderedDict()
    for name in message_fields(msg):
        out[name] = _convert(getattr(msg, name), truncate_length)
    return out


def _convert(value, truncate_length):
    if _is_message(value):
        return message_to_ordereddict(value, truncate_length)
    if isinstance(value, (bytes, bytearray)):
        value = list(value)
    if isinstance(value, (list, tuple)) or type(value).__name__ in ('ndarray', 'array'):
        items = [_convert(v, truncate_length) for v in list(value)]
        if truncate_length is not None and len(items) > truncate_length:
            items = items[:truncate_length] + ['...']
        return items
    if type(value).__module__ == 'numpy':
        return value.item()
    if isinstance(value, str) and truncate_length is not None and len(value) > truncate_length:
        return value[:truncate_length] + '...'
    return value


def message_to_yaml(msg, truncate_length=128, flow_style=False) -> str:
    """YAML text of a message as ``ros2 topic echo`` prints it (without the ``---`` separator)."""
    import yaml

    class _Dumper(yaml.SafeDumper):
        pass

    _Dumper.add_representer(
        OrderedDict, lambda dumper, data: dumper.represent_mapping('tag:yaml.org,2002:map', data.items()))
    data = message_to_ordereddict(msg, truncate_length) if _is_message(msg) else _convert(msg, truncate_length)
    text = yaml.dump(data, Dumper=_Dumper, allow_unicode=True, width=sys.maxsize,
                     default_flow_style=flow_style, sort_keys=False)
    if text.endswith('\n...\n'):  # a lone scalar: no YAML document end marker, as ros2 prints
        text = text[:-4]
    return text
