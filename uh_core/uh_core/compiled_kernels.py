"""Ahead-of-time compiled kernels: the model, the control law and the fault isolator without numba.

The kernels of :mod:`uh_sim_node.plant_kernels`, :mod:`uh_controller_node.control_kernels`,
:mod:`uh_controller_node.isolation_kernels` and :mod:`uh_controller_node.impairments` are numba
code. A process that runs them through numba's JIT holds numba and LLVM in memory (about 90 MB for
``import numba`` alone, 175 MB for a node), even when every kernel comes from numba's on-disk cache.
:func:`build` compiles the same Python functions, with the same argument types, into one CPython
extension module (``numba.pycc``); a process that loads it runs the kernels with numpy alone.
docs/performance.md#memory says what this saves and how it was checked to be bit-identical.

Which form a process runs is chosen once, when the first kernel module is imported, by the
environment variable ``UH_KERNELS``:

``numba`` (the default)
    numba's JIT (and its on-disk cache), as every process did before.
``auto``
    The compiled module when one was built for exactly these kernel sources, else numba. The node
    entry points and the composed processes of a run set this when it is unset.
``compiled``
    The compiled module, and an error (:class:`KernelModeError`) when there is none for these sources.

The compiled module's name carries a digest of the kernel sources, :mod:`uh_core.layout`, this file
and the versions of numba, Python and the machine (:func:`kernel_digest`), so a module built for
other sources is never loaded: after a kernel edit, ``auto`` runs numba until
``python -m uh_team.compile_kernels`` builds the new one, and a node's start line says so
(:func:`kernel_form`: the stale module's name and that command).

A kernel module uses this file's :func:`njit` in place of numba's, and calls :func:`install` at its
end::

    from uh_core.compiled_kernels import njit
    ...
    _compiled_kernels.install(globals())

In a process running compiled kernels, :func:`njit` leaves the functions as they are (numba is not
imported) and :func:`install` replaces each kernel that has a compiled form by it. The compiled
forms are those :func:`build` finds compiled, with one signature each, after each module's
``compile_*_kernels`` function ran: the kernels the nodes call from Python. The others (building
blocks that only tests call from Python) stay plain Python functions there.
"""
from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.metadata
import importlib.util
import os
import platform
import sys
import tempfile
import warnings
from pathlib import Path

__all__ = ['MODE_VARIABLE', 'DIR_VARIABLE', 'MODES', 'KERNEL_MODULES', 'KERNEL_INPUT_MODULES', 'KernelModeError',
           'mode', 'kernel_digest', 'library_name', 'search_dirs', 'find_built', 'compiled_library', 'njit', 'install',
           'active_modules', 'require_numba', 'prefer_compiled', 'run_node_main', 'kernel_form', 'build',
           'BUILD_COMMAND']

#: Environment variable that selects the kernels' form (:data:`MODES`).
MODE_VARIABLE = 'UH_KERNELS'
#: Environment variable naming the directory of the compiled module (default: :func:`search_dirs`).
DIR_VARIABLE = 'UH_COMPILED_KERNELS_DIR'
MODES = ('numba', 'auto', 'compiled')

#: ``module: (prefix of its kernels' names in the compiled module, its warm-up function)``.
KERNEL_MODULES = {
    'uh_sim_node.plant_kernels': ('plant__', 'compile_plant_kernels'),
    'uh_controller_node.control_kernels': ('control__', 'compile_control_kernels'),
    'uh_controller_node.isolation_kernels': ('isolation__', 'compile_isolation_kernels'),
    'uh_controller_node.impairments': ('impairments__', 'compile_impairment_kernels'),
}


class KernelModeError(RuntimeError):
    """``UH_KERNELS`` holds no mode of :data:`MODES`, or asks for compiled kernels that were not built."""


def mode() -> str:
    """Return the mode ``UH_KERNELS`` selects (``numba`` when unset or empty).

    Raises
    ------
    KernelModeError
        The variable holds another value.
    """
    value = os.environ.get(MODE_VARIABLE, '').strip() or 'numba'
    if value not in MODES:
        raise KernelModeError(f'{MODE_VARIABLE}={value!r} is not a kernel mode: use one of {", ".join(MODES)}')
    return value


#: Modules whose contents the kernels compile in without being kernel modules: the gains' slots of
#: the law's parameter vector are declared in ``gains.py``.
KERNEL_INPUT_MODULES = ('uh_controller_node.gains',)


def _source_files() -> list[Path]:
    """Return the files the compiled code is made from: the kernel modules and inputs, ``layout.py``, this file."""
    files = []
    for name in (*KERNEL_MODULES, *KERNEL_INPUT_MODULES):
        spec = importlib.util.find_spec(name)
        if spec is None or not spec.origin:
            raise KernelModeError(f'kernel module {name} is not installed')
        files.append(Path(spec.origin))
    return files + [Path(__file__).with_name('layout.py'), Path(__file__)]


_digest_cache: list = []


def kernel_digest() -> str:
    """SHA-256, hex, of the kernel sources (:func:`_source_files`) and the numba, Python and machine versions."""
    if not _digest_cache:
        total = hashlib.sha256()
        for path in _source_files():
            total.update(hashlib.sha256(path.read_bytes()).digest())
        total.update(f'numba {importlib.metadata.version("numba")} python {sys.version} '
                     f'{platform.machine()} {sys.implementation.cache_tag}'.encode())
        _digest_cache.append(total.hexdigest())
    return _digest_cache[0]


def library_name(digest: str | None = None) -> str:
    """Return the module name of the compiled kernels for ``digest`` (default: :func:`kernel_digest`)."""
    return f'uh_kernels_{(digest or kernel_digest())[:20]}'


def search_dirs() -> list[Path]:
    """Directories that may hold the compiled module, in the order searched and written.

    ``UH_COMPILED_KERNELS_DIR`` when set; else ``__pycache__`` of this package (next to numba's
    cache of the kernels), then ``$XDG_CACHE_HOME/uh_kernels`` (``~/.cache/uh_kernels``) for an
    install whose package directory is read-only.
    """
    if os.environ.get(DIR_VARIABLE):
        return [Path(os.environ[DIR_VARIABLE])]
    user = Path(os.environ.get('XDG_CACHE_HOME') or Path.home() / '.cache') / 'uh_kernels'
    return [Path(__file__).parent / '__pycache__', user]


def _file_name(name: str) -> str:
    return name + importlib.machinery.EXTENSION_SUFFIXES[0]


def find_built() -> Path | None:
    """Path of the compiled module built for these kernel sources, or None."""
    name = _file_name(library_name())
    for directory in search_dirs():
        if (directory / name).is_file():
            return directory / name
    return None


_decision: list = []      # [the loaded compiled module or None], fixed by the first kernel module
_active: set = set()
_fallback: list = []      # [why a process of mode auto runs numba], when it does

#: The command that builds the compiled kernels for the sources as they are.
BUILD_COMMAND = 'python -m uh_team.compile_kernels'


def _built_for_other_sources() -> list[Path]:
    """Compiled modules in :func:`search_dirs` that were built for other kernel sources (stale ones)."""
    suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
    return [path for directory in search_dirs() if directory.is_dir()
            for path in sorted(directory.glob('uh_kernels_*' + suffix)) if path.name != _file_name(library_name())]


def compiled_library():
    """Return the compiled kernel module this process runs, or None for numba (decided once per process).

    Raises
    ------
    KernelModeError
        ``UH_KERNELS`` is not a mode, or is ``compiled`` and no module was built for these sources.
    """
    if _decision:
        return _decision[0]
    chosen = mode()
    library = None
    if chosen != 'numba':
        path = find_built()
        if path is None and chosen == 'compiled':
            raise KernelModeError(
                f'{MODE_VARIABLE}=compiled, but no compiled kernels were built for these sources (looked for '
                f'{_file_name(library_name())} in {", ".join(map(str, search_dirs()))}): run '
                f'python -m uh_team.compile_kernels, or set {MODE_VARIABLE}=auto to fall back to numba')
        if path is None:
            stale = _built_for_other_sources()
            _fallback.append(f'the compiled kernels {stale[0].name} are stale (built for other kernel sources): '
                             f'{BUILD_COMMAND} rebuilds them' if stale else
                             f'no compiled kernels were built for these sources: {BUILD_COMMAND} builds them')
        else:
            loader = importlib.machinery.ExtensionFileLoader(library_name(), str(path))
            spec = importlib.util.spec_from_file_location(library_name(), path, loader=loader)
            library = importlib.util.module_from_spec(spec)
            loader.exec_module(library)
    _decision.append(library)
    return library


def prefer_compiled() -> None:
    """Set ``UH_KERNELS=auto`` unless it is set: a node process's entry point calls this before its imports."""
    if not os.environ.get(MODE_VARIABLE, '').strip():
        os.environ[MODE_VARIABLE] = 'auto'


def run_node_main(module: str, prog: str, args=None):
    """Run ``module.main(args)`` of a node that steps kernels, on compiled kernels where they were built.

    The console entry point of such a node calls this: ``UH_KERNELS`` is set to ``auto`` unless set
    (:func:`prefer_compiled`) before the node's module imports its kernels. A bad ``UH_KERNELS``, or
    ``compiled`` without a built module, is one line on stderr as ``prog: error: ...`` and status 2.
    """
    prefer_compiled()
    try:
        main = importlib.import_module(module).main
    except KernelModeError as exc:
        print(f'{prog}: error: {exc}', file=sys.stderr)
        return 2
    return main(args)


def njit(*args, **kwargs):
    """``numba.njit(*args, **kwargs)`` for the kernel modules, or no decorator when they run compiled.

    Use it exactly as numba's (``@njit(cache=True)``). numba is imported only when a kernel is
    decorated with it.
    """
    def decorate(function):
        if function.__module__ in KERNEL_MODULES and compiled_library() is not None:
            return function
        import numba
        return numba.njit(*args, **kwargs)(function)
    return decorate


def install(namespace: dict) -> bool:
    """Put the compiled kernels of the module whose ``globals()`` is ``namespace`` in place of its functions.

    Returns True when the module now runs compiled kernels, False when it runs numba's.
    """
    name = namespace.get('__name__')
    library = compiled_library() if name in KERNEL_MODULES else None
    if library is None:
        return False
    prefix = KERNEL_MODULES[name][0]
    for attribute in dir(library):
        if attribute.startswith(prefix):
            namespace[attribute[len(prefix):]] = getattr(library, attribute)
    _active.add(name)
    return True


def active_modules() -> frozenset:
    """Kernel modules of this process that run compiled kernels."""
    return frozenset(_active)


def kernel_form() -> str:
    """Return ``'compiled kernels'`` when this process runs compiled kernels, else ``'numba kernels'`` (for logs).

    A process that wanted compiled kernels (``UH_KERNELS=auto``) and runs numba's says why, and the
    command that builds them: ``'numba kernels (the compiled kernels uh_kernels_....so are stale ...)'``.
    """
    if _active:
        return 'compiled kernels'
    return f'numba kernels ({_fallback[0]})' if _fallback else 'numba kernels'


def require_numba(user: str) -> None:
    """Raise ImportError when kernel modules of this process run compiled: ``user`` calls them from numba code."""
    if _active:
        raise ImportError(
            f'{user} calls the kernels from numba code, but this process runs them compiled ahead of time '
            f'({MODE_VARIABLE}={os.environ.get(MODE_VARIABLE)}): start it with {MODE_VARIABLE}=numba')


def build(log=None) -> tuple[Path, bool]:
    """Compile the kernels into the module :func:`find_built` looks for, unless it exists.

    Runs each kernel module's warm-up function under numba, then compiles every public kernel (in
    the module's ``__all__``) that then has exactly one compiled signature, with that signature (its
    types, its return type) and numba's default options, for this machine's CPU, with
    ``numba.pycc``. Needs a C compiler.

    Parameters
    ----------
    log : callable, optional
        Called with a line of progress.

    Returns
    -------
    (Path, bool)
        The module's path, and whether it was built now (False: it existed).

    Raises
    ------
    KernelModeError
        This process already runs compiled kernels, or no directory of :func:`search_dirs` is writable.
    """
    log = log or (lambda line: None)
    existing = find_built()
    if existing is not None:
        return existing, False
    if _active:
        raise KernelModeError(f'building the compiled kernels needs numba kernels: run with {MODE_VARIABLE}=numba')
    with warnings.catch_warnings():
        # numba.pycc is marked for removal in a future numba; numba is pinned (requirements.txt)
        warnings.simplefilter('ignore')
        from numba.pycc import CC
    name = library_name()
    compiler = CC(name)
    compiler.target_cpu = 'host'   # as numba's JIT compiles for the CPU it runs on
    compiler.verbose = False
    exported = 0
    for module_name, (prefix, warm_up) in KERNEL_MODULES.items():
        module = importlib.import_module(module_name)
        getattr(module, warm_up)()
        for attribute, value in sorted(vars(module).items()):
            py_func = getattr(value, 'py_func', None)
            if (getattr(py_func, '__module__', None) != module_name or attribute not in module.__all__
                    or len(value.signatures) != 1):
                continue
            (signature,) = value.signatures
            return_type = value.overloads[signature].signature.return_type
            compiler.export(prefix + attribute, return_type(*signature))(py_func)
            exported += 1
    target = None
    for directory in search_dirs():
        try:
            directory.mkdir(parents=True, exist_ok=True)
            if os.access(directory, os.W_OK):
                target = directory
                break
        except OSError:
            continue
    if target is None:
        raise KernelModeError('no writable directory for the compiled kernels among '
                              f'{", ".join(map(str, search_dirs()))} (set {DIR_VARIABLE})')
    log(f'compiling {exported} kernels ahead of time into {target / _file_name(name)}')
    with tempfile.TemporaryDirectory(prefix='uh_kernels_', dir=target) as scratch:
        compiler.output_dir = scratch
        compiler.compile()
        built = Path(scratch) / _file_name(name)
        os.replace(built, target / built.name)   # atomic: a process never loads half a module
    for stale in target.glob('uh_kernels_*' + importlib.machinery.EXTENSION_SUFFIXES[0]):
        if stale.name != _file_name(name):
            stale.unlink(missing_ok=True)
    return target / _file_name(name), True
