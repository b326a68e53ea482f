"""Ahead-of-time compiled kernels: the model, the control law and the fault isolator without numba.

The kernel modules (the model's, the control law's, the fault isolator's, the link impairments'
and the safety filter's) are numba code. A process that runs them through numba's JIT holds numba
and LLVM in memory (about 90 MB for ``import numba`` alone, 175 MB for a node), even when every
kernel comes from numba's on-disk cache. :func:`build` compiles the same Python functions, with the
same argument types, into one CPython extension module (``numba.pycc``); a process that loads it
runs the kernels with numpy alone. docs/performance.md#memory says what this saves and how it was
checked to be bit-identical.

Which modules are kernel modules
--------------------------------
Each package declares its own kernel modules, in its ``setup.py``, as entry points; this module
reads them (:func:`kernel_modules`, with :mod:`importlib.metadata`, without importing the modules)
and names no module of a package above it. Three groups:

``uh_kernels`` (:data:`KERNEL_GROUP`)
    One entry per kernel module: name = the prefix of its kernels' names in the compiled module,
    value = ``module:warm_up``, the function that compiles the kernels the nodes call from Python
    (``module`` alone for a module whose kernels only other kernels call: the warm-ups of those
    compile them)::

        entry_points={'uh_kernels': [
            'control__ = uh_controller_node.control_kernels:compile_control_kernels',
            'loops__ = uh_controller_node.loop_kernels', ...]}

``uh_kernel_inputs`` (:data:`KERNEL_INPUT_GROUP`)
    The modules whose contents the kernels compile in without being kernel modules (the layouts of
    the state, the status and the law's parameter vector, the gains' slots): name = a label,
    value = the module.
``uh_kernel_builder`` (:data:`KERNEL_BUILDER_GROUP`)
    The module whose ``python -m`` builds the compiled kernels (:func:`build_command`).

Entry points exist once a package is installed (``pip install``, which ``scripts/_venv.sh`` runs
again whenever a ``setup.py`` changes, or ``colcon build``). A module that uses this file's
:func:`njit` and :func:`install` and is not declared runs numba's JIT; ``tests/test_kernel_registry.py``
checks that every such module is declared, by the package that holds it.

Which form a process runs
-------------------------
Chosen once, when the first kernel module is imported, by the environment variable ``UH_KERNELS``:

``numba`` (the default)
    numba's JIT (and its on-disk cache), as every process did before.
``auto``
    The compiled module when one was built for exactly these kernel sources, else numba. The node
    entry points and the composed processes of a run set this when it is unset.
``compiled``
    The compiled module, and an error (:class:`KernelModeError`) when there is none for these sources.

The compiled module's name carries a digest of the declared modules (the entry points and their
files' contents), this file and the versions of numba, Python and the machine
(:func:`kernel_digest`), so a module built for other sources is never loaded: after a kernel edit,
``auto`` runs numba until the builder (``python -m uh_team.compile_kernels``) builds the new one,
and a node's start line says so (:func:`kernel_form`: the stale module's name and that command).

A kernel module uses this file's :func:`njit` in place of numba's, and calls :func:`install` at its
end::

    from uh_core.compiled_kernels import njit
    ...
    _compiled_kernels.install(globals())

In a process running compiled kernels, :func:`njit` leaves the functions as they are (numba is not
imported) and :func:`install` replaces each kernel that has a compiled form by it. The compiled
forms are those :func:`build` finds compiled, with one signature each, after every module's warm-up
ran: the kernels the nodes call from Python. The others (building blocks that only tests call from
Python) stay plain Python functions there.
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
import time
import warnings
from functools import cache
from pathlib import Path
from typing import NamedTuple

__all__ = ['MODE_VARIABLE', 'DIR_VARIABLE', 'MODES', 'KERNEL_GROUP', 'KERNEL_INPUT_GROUP', 'KERNEL_BUILDER_GROUP',
           'KernelModule', 'KernelModeError', 'kernel_modules', 'kernel_input_modules', 'build_command', 'mode',
           'kernel_digest', 'library_name', 'search_dirs', 'find_built', 'compiled_library', 'njit', 'install',
           'active_modules', 'require_numba', 'prefer_compiled', 'run_node_main', 'kernel_form', 'warm_up_kernels',
           'build']

#: Environment variable that selects the kernels' form (:data:`MODES`).
MODE_VARIABLE = 'UH_KERNELS'
#: Environment variable naming the directory of the compiled module (default: :func:`search_dirs`).
DIR_VARIABLE = 'UH_COMPILED_KERNELS_DIR'
MODES = ('numba', 'auto', 'compiled')

#: Entry-point group of the kernel modules: ``prefix = module:warm_up`` (or ``prefix = module``).
KERNEL_GROUP = 'uh_kernels'
#: Entry-point group of the modules the kernels compile in without being kernel modules: ``label = module``.
KERNEL_INPUT_GROUP = 'uh_kernel_inputs'
#: Entry-point group of the module whose ``python -m`` builds the compiled kernels: ``label = module:main``.
KERNEL_BUILDER_GROUP = 'uh_kernel_builder'


class KernelModeError(RuntimeError):
    """``UH_KERNELS`` holds no mode of :data:`MODES`, or asks for compiled kernels that were not built."""


class KernelModule(NamedTuple):
    """A kernel module as its package declares it (an entry point of :data:`KERNEL_GROUP`).

    Attributes
    ----------
    module : str
        Its dotted name.
    prefix : str
        The prefix of its kernels' names in the compiled module (``control__``): the entry point's name.
    warm_up : str
        Its function that compiles the kernels the nodes call; empty when other modules' warm-ups compile them.
    """

    module: str
    prefix: str
    warm_up: str


def _entry_points(group: str) -> list:
    """Return the installed entry points of ``group``, sorted by name and value (not in the order found)."""
    return sorted(importlib.metadata.entry_points(group=group), key=lambda point: (point.name, point.value))


@cache
def kernel_modules() -> dict:
    """Return ``{module: KernelModule}`` of every declared kernel module, in the order of their prefixes.

    Read from the entry points of :data:`KERNEL_GROUP`; the modules are not imported.

    Raises
    ------
    KernelModeError
        Two entries declare the same module or the same prefix, or a prefix does not end in ``__``.
    """
    found = {}
    for point in _entry_points(KERNEL_GROUP):
        kernel = KernelModule(point.module, point.name, point.attr or '')
        clash = [k for k in found.values() if k.module == kernel.module or k.prefix == kernel.prefix]
        if clash or not kernel.prefix.endswith('__'):
            raise KernelModeError(f'entry point {point.name} = {point.value} of group {KERNEL_GROUP}: '
                                  + (f'clashes with {clash[0].prefix} = {clash[0].module}' if clash else
                                     'a prefix ends in "__"'))
        found[kernel.module] = kernel
    return found


@cache
def kernel_input_modules() -> tuple:
    """Return the modules the kernels compile in without being kernel modules (:data:`KERNEL_INPUT_GROUP`), sorted."""
    return tuple(sorted({point.module for point in _entry_points(KERNEL_INPUT_GROUP)}))


def build_command() -> str:
    """Return the command that builds the compiled kernels for these sources (:data:`KERNEL_BUILDER_GROUP`)."""
    builders = _entry_points(KERNEL_BUILDER_GROUP)
    if not builders:
        return f'the kernel builder (none is installed: no entry point of group {KERNEL_BUILDER_GROUP})'
    return f'python -m {builders[0].module}'


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


def _source_files() -> list[Path]:
    """Return the files the compiled code is made from: the declared kernel modules and inputs, this file."""
    files = []
    for name in (*kernel_modules(), *kernel_input_modules()):
        spec = importlib.util.find_spec(name)
        if spec is None or not spec.origin:
            raise KernelModeError(f'kernel module {name} is not installed')
        files.append(Path(spec.origin))
    return files + [Path(__file__)]


_digest_cache: list = []


def kernel_digest() -> str:
    """SHA-256, hex, of the kernel sources (:func:`_source_files`), their entry points and the versions.

    The versions are numba's, Python's and the machine's. The entry points count: a prefix or a
    warm-up declared otherwise names other kernels.
    """
    if not _digest_cache:
        total = hashlib.sha256()
        total.update(repr((sorted(kernel_modules().values()), kernel_input_modules())).encode())
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
    if chosen != 'numba' and not kernel_modules():
        unregistered = (f'no kernel module is declared (entry points of group {KERNEL_GROUP}): the packages are not '
                        'installed with their metadata (scripts/_venv.sh, or colcon build)')
        if chosen == 'compiled':
            raise KernelModeError(f'{MODE_VARIABLE}=compiled, but {unregistered}')
        _fallback.append(unregistered)
    elif chosen != 'numba':
        path = find_built()
        if path is None and chosen == 'compiled':
            raise KernelModeError(
                f'{MODE_VARIABLE}=compiled, but no compiled kernels were built for these sources (looked for '
                f'{_file_name(library_name())} in {", ".join(map(str, search_dirs()))}): run '
                f'{build_command()}, or set {MODE_VARIABLE}=auto to fall back to numba')
        if path is None:
            stale = _built_for_other_sources()
            _fallback.append(f'the compiled kernels {stale[0].name} are stale (built for other kernel sources): '
                             f'{build_command()} rebuilds them' if stale else
                             f'no compiled kernels were built for these sources: {build_command()} builds them')
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
        if compiled_library() is not None and function.__module__ in kernel_modules():
            return function
        import numba
        return numba.njit(*args, **kwargs)(function)
    return decorate


def install(namespace: dict) -> bool:
    """Put the compiled kernels of the module whose ``globals()`` is ``namespace`` in place of its functions.

    Returns True when the module now runs compiled kernels, False when it runs numba's.
    """
    name = namespace.get('__name__')
    library = compiled_library()
    if library is None or name not in kernel_modules():
        return False
    prefix = kernel_modules()[name].prefix
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


def warm_up_kernels() -> dict:
    """Run every declared kernel module's warm-up function (numba compiles, or loads from its cache).

    Returns ``{module: seconds}`` per module with a warm-up, in the order of :func:`kernel_modules`.
    """
    spent = {}
    for kernel in kernel_modules().values():
        if kernel.warm_up:
            start = time.perf_counter()
            getattr(importlib.import_module(kernel.module), kernel.warm_up)()
            spent[kernel.module] = time.perf_counter() - start
    return spent


def _export_kernels(compiler) -> int:
    """Export to ``compiler`` every public kernel of the declared modules that has one signature; how many."""
    exported = 0
    for module_name, kernel in kernel_modules().items():
        module = importlib.import_module(module_name)
        for attribute, value in sorted(vars(module).items()):
            py_func = getattr(value, 'py_func', None)
            if (getattr(py_func, '__module__', None) != module_name or attribute not in module.__all__
                    or len(value.signatures) != 1):
                continue
            (signature,) = value.signatures
            return_type = value.overloads[signature].signature.return_type
            compiler.export(kernel.prefix + attribute, return_type(*signature))(py_func)
            exported += 1
    return exported


def build(log=None) -> tuple[Path, bool]:
    """Compile the kernels into the module :func:`find_built` looks for, unless it exists.

    Runs every kernel module's warm-up function under numba (:func:`warm_up_kernels`; all of them
    first, as one module's kernels may be compiled by another's warm-up), then compiles every public
    kernel (in its module's ``__all__``) that then has exactly one compiled signature, with that
    signature (its types, its return type) and numba's default options, for this machine's CPU,
    with ``numba.pycc``. Needs a C compiler.

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
    warm_up_kernels()
    exported = _export_kernels(compiler)
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
