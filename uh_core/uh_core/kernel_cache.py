"""Keep numba's on-disk cache of a kernel module in step with the files it reads at compile time.

numba re-validates a cached kernel against the source file that defines it, and nothing else. A
kernel that reads a module-level constant of another module (the index constants of
:mod:`uh_core.layout`), or calls a kernel defined in another file, would keep a stale compiled value
after that other file is edited. :func:`refresh_cache` closes the gap: it keeps a digest of the
dependency files in a marker file next to the cache and flushes (empties the cache index of) every
given dispatcher when the digest changed, so the kernels are compiled afresh on their next call.

A kernel module calls it once, at its end (after every ``@njit`` definition, before any kernel
runs)::

    from uh_core import kernel_cache, layout
    kernel_cache.refresh_cache(kernel_cache.module_dispatchers(globals()), [layout.__file__])

which keeps the digest in ``<module>.dependencies.sha256`` in the module's cache directory.

This module does not import numba: it uses the ``_cache`` attribute of numba's dispatchers
(``cache_path``, the cache directory, and ``flush()``, which empties the dispatcher's cache index).
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Iterable

__all__ = ['module_dispatchers', 'dependency_digest', 'refresh_cache']


def module_dispatchers(namespace: dict) -> list:
    """Return the cached njit dispatchers defined in the module whose ``globals()`` is ``namespace``.

    Parameters
    ----------
    namespace : dict
        A module's ``globals()``.

    Returns
    -------
    list
        Values with a ``_cache`` whose Python function was defined in that module (kernels imported
        from other modules are left out: they have their own marker). Empty when numba is disabled
        (``NUMBA_DISABLE_JIT``: the decorators return plain functions).
    """
    name = namespace.get('__name__')
    return [value for value in namespace.values()
            if hasattr(value, '_cache') and getattr(getattr(value, 'py_func', None), '__module__', None) == name]


def dependency_digest(dependency_files: Iterable) -> str:
    """SHA-256, hex, of the contents of ``dependency_files`` (path-likes) in the order given.

    Raises
    ------
    OSError
        A file cannot be read.
    """
    total = hashlib.sha256()
    for path in dependency_files:
        total.update(hashlib.sha256(Path(path).read_bytes()).digest())
    return total.hexdigest()


def refresh_cache(dispatchers: Iterable, dependency_files: Iterable, marker_name: str | None = None) -> bool:
    """Flush the caches of ``dispatchers`` when ``dependency_files`` changed since the last call.

    Parameters
    ----------
    dispatchers : iterable
        numba dispatchers (``@njit(cache=True)`` functions) of one source file; each one's
        ``_cache`` has ``cache_path`` and ``flush()``. A dispatcher without a cache directory
        (caching off) is skipped.
    dependency_files : iterable of path-like
        The files, other than the dispatchers' own source file, whose contents the compiled code
        depends on.
    marker_name : str, optional
        Name of the marker file, in the cache directory of the first dispatcher, that holds the
        digest of ``dependency_files``. Default ``'<module>.dependencies.sha256'`` with the last
        component of the first dispatcher's module name (``'plant_kernels.dependencies.sha256'``).

    Returns
    -------
    bool
        True when the caches were flushed: the marker was missing or held another digest (so a
        cache written before the marker existed is flushed once). False when the digest matched,
        or when a file or the cache directory could not be read or written (numba does not cache
        in a directory it cannot write either).
    """
    cached = [d for d in dispatchers if hasattr(getattr(d, '_cache', None), 'cache_path')]
    if not cached:
        return False
    caches = [d._cache for d in cached]
    if marker_name is None:
        module = getattr(getattr(cached[0], 'py_func', None), '__module__', None) or 'kernels'
        marker_name = f'{module.rpartition(".")[2]}.dependencies.sha256'
    try:
        digest = dependency_digest(dependency_files)
        marker = Path(caches[0].cache_path) / marker_name
        if marker.is_file() and marker.read_text().strip() == digest:
            return False
        for cache in caches:
            cache.flush()
        # written after the flush: a run that dies in between flushes again next time
        marker.parent.mkdir(parents=True, exist_ok=True)
        partial = marker.with_name(f'{marker.name}.{os.getpid()}.tmp')
        partial.write_text(digest + '\n')
        os.replace(partial, marker)
        return True
    except OSError:
        return False
