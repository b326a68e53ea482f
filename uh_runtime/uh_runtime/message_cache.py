"""Per-user cache of what :mod:`uh_runtime.messages` derives from the message definitions at a node's start.

Files in :func:`cache_dir`, JSON, each named after a digest of everything it was made from (a stale
file is never read, so nothing needs invalidating; any file may be deleted at any time). Written
atomically by whichever process first needs one; a cache that cannot be read or written is simply
not used. Held:

* ``typestore-<digest>.json``: the definitions (``fielddefs``) of :func:`uh_runtime.messages.typestore`,
  which otherwise needs rosbags' ROS 2 Jazzy store, whose modules define ~1000 classes on import
  (0.1 s of CPU at every start);
* ``xtypes-<digest>/<type>.json``: the XTypes type information of a message class, serialised
  (:func:`cache_type_data`), which cyclonedds otherwise builds in Python for each topic's type
  (40 ms of CPU for a process's first type, 1-5 ms for each further one).
"""
import functools
import hashlib
import json
import os
from pathlib import Path

__all__ = ['cache_dir', 'read', 'write', 'files_digest', 'encode_fielddefs', 'decode_fielddefs', 'cache_type_data']


def cache_dir() -> Path | None:
    """Directory of the cache: ``$UH_CACHE_DIR``, else ``$XDG_CACHE_HOME/uh_runtime`` (``~/.cache/uh_runtime``).

    None (no cache) when neither is set and the user has no home directory.
    """
    override = os.environ.get('UH_CACHE_DIR', '').strip()
    if override:
        return Path(override)
    base = os.environ.get('XDG_CACHE_HOME', '').strip()
    try:
        return Path(base or Path.home() / '.cache') / 'uh_runtime'
    except RuntimeError:
        return None


def read(name: str, decode):
    """Return ``decode(data)`` of the JSON cache file ``name``, or None if it is missing or unreadable."""
    folder = cache_dir()
    try:
        return decode(json.loads((folder / name).read_text())) if folder else None
    except (OSError, ValueError, TypeError, KeyError, IndexError):
        return None


def write(name: str, data) -> None:
    """Write ``data`` as JSON to cache file ``name`` atomically (nothing if the cache cannot be written)."""
    folder = cache_dir()
    if folder is None:
        return
    path = folder / name
    temporary = path.with_name(f'.{path.name}.{os.getpid()}.tmp')
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary.write_text(json.dumps(data, separators=(',', ':')))
        os.replace(temporary, path)
    except OSError:
        try:
            temporary.unlink()
        except OSError:
            pass


def files_digest(digest, folder: Path, pattern: str = '*.py') -> None:
    """Add path, size and modification time of every file of ``folder`` matching ``pattern`` to ``digest``.

    Enough to notice another installed version of a package (pip rewrites its files).
    """
    for path in sorted(folder.rglob(pattern)):
        stat = path.stat()
        digest.update(f'{path}\0{stat.st_size}\0{stat.st_mtime_ns}\n'.encode())


def encode_fielddefs(fielddefs: dict) -> dict:
    """JSON form of rosbags ``fielddefs``: tuples become lists and ``Nodetype`` values ints."""
    return {name: [consts, fields] for name, (consts, fields) in fielddefs.items()}


def decode_fielddefs(data: dict) -> dict:
    """Return rosbags ``fielddefs`` from their JSON form (:func:`encode_fielddefs`), equal to the original."""
    from rosbags.interfaces import Nodetype

    def spec(item):
        kind, details = Nodetype(item[0]), item[1]
        if kind == Nodetype.BASE:
            return kind, (str(details[0]), int(details[1]))
        if kind == Nodetype.NAME:
            return kind, str(details)
        return kind, (spec(details[0]), int(details[1]))
    return {str(name): ([tuple(const) for const in consts], [(str(fname), spec(item)) for fname, item in fields])
            for name, (consts, fields) in data.items()}


@functools.cache
def _cyclonedds_digest() -> str:
    """Digest of the installed cyclonedds package (which builds and serialises the type information)."""
    import cyclonedds
    digest = hashlib.sha256()
    files_digest(digest, Path(cyclonedds.__file__).parent)
    return digest.hexdigest()


def cache_type_data(cls, key: str, store_digest: str) -> None:
    """Let the ``IdlStruct`` class ``cls``, just made, take its serialised XTypes type information from the cache.

    A topic of a type needs the type's ``TypeInformation`` and ``TypeMapping`` serialised: cyclonedds'
    C layer reads them from ``cls.__idl__._xt_bytedata``, which ``IDL.fill_type_data`` fills when the
    topic is created. The file is named after ``key`` (the class among the module's classes), the
    digest of the definitions and of how classes are made of them (``store_digest``) and the installed
    cyclonedds; the objects themselves (``get_type_info()`` ...) are built when first asked for.
    """
    if not store_digest:     # definitions of unknown origin: nothing to name a file after
        return
    try:
        installed = _cyclonedds_digest()
    except OSError:          # a package being reinstalled: no cache this time
        return
    digest = hashlib.sha256(f'{store_digest}\0{installed}'.encode()).hexdigest()[:32]
    name = key.replace('/', '.').replace(':', '.')
    cls.__idl__ = _caching_idl()(cls, f'xtypes-{digest}/{name}.json')


def _decode_type_data(data) -> tuple:
    info, mapping = (bytes.fromhex(part) for part in data)
    if not info or not mapping:
        raise ValueError('no type information')
    return info, mapping


@functools.cache
def _caching_idl():
    """Return the subclass of cyclonedds' ``IDL`` (a class's type support) behind :func:`cache_type_data`."""
    from cyclonedds.idl._main import IDL

    class CachingIDL(IDL):
        def __init__(self, datatype, cache_name):
            super().__init__(datatype)
            self.cache_name = cache_name

        def fill_type_data(self) -> None:
            if self._xt_bytedata[0] is not None:
                return
            cached = read(self.cache_name, _decode_type_data)
            if cached is None:
                super().fill_type_data()
                write(self.cache_name, [part.hex() for part in self._xt_bytedata])
            else:
                self._xt_bytedata = cached

        def _built(self):
            if self._xt_data[0] is None:
                super().fill_type_data()
            return self._xt_data

        def get_type_info(self):
            return self._built()[0]

        def get_type_mapping(self):
            return self._built()[1]

        def get_type_id(self):
            return self._built()[0].complete.typeid_with_size.type_id

    return CachingIDL
