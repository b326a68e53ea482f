"""Compile the numba kernels of the model, the control law and the fault isolator, and their ahead-of-time form.

``python -m uh_team.compile_kernels`` (run by ``scripts/_venv.sh`` whenever the kernel
sources change, and by the launch file before any node starts) fills numba's on-disk cache: without
it, the first processes to need a kernel compile it, each on its own (a distributed run starts about
a dozen node processes at once). It runs the warm-up of every kernel module its package declares
(:func:`uh_core.compiled_kernels.warm_up_kernels`) and compiles the in-process team loop, then builds
the kernels the nodes call into one extension module (:func:`uh_core.compiled_kernels.build`), which
the node processes load instead of numba (docs/performance.md#memory); where that fails (no C
compiler), it says so and the nodes run numba. This package declares this module the kernels'
builder (entry point group ``uh_kernel_builder``): the nodes name it when the compiled kernels are stale.
"""
from __future__ import annotations

import argparse
import sys
import time

from uh_core import compiled_kernels

from .team_kernel import compile_team_kernel

__all__ = ['compile_all', 'main']


def compile_all() -> dict:
    """Compile (or load from the cache) every kernel; seconds spent per kernel module (last name), and the team loop."""
    spent = {module.rpartition('.')[2]: seconds for module, seconds in compiled_kernels.warm_up_kernels().items()}
    return {**spent, 'team loop': compile_team_kernel()}


def main(argv=None) -> int:
    """Compile every kernel, then build the ahead-of-time compiled module (unless ``--no-compiled-module``); return 0.

    A module that cannot be built is a warning on stderr: the nodes then run numba's kernels.
    """
    parser = argparse.ArgumentParser(
        prog='python -m uh_team.compile_kernels',
        description='Compile the numba kernels of the helicopter model, the control law, the fault isolator, the '
                    'link impairments, the safety filter (every kernel module a package declares) and the '
                    'in-process team loop, and store them in numba\'s cache (__pycache__ next to the sources, or '
                    'NUMBA_CACHE_DIR).')
    parser.add_argument('--no-compiled-module', action='store_true',
                        help='only fill numba\'s cache; do not build the ahead-of-time compiled kernels the node '
                             'processes load instead of numba')
    args = parser.parse_args(argv)
    times = compile_all()
    print('kernels ready: ' + ', '.join(f'{name} {seconds:.1f} s' for name, seconds in times.items()))
    if not args.no_compiled_module:
        start = time.perf_counter()
        try:
            path, built = compiled_kernels.build(log=print)
        except Exception as exc:   # a missing C compiler, an unwritable cache: the nodes run numba instead
            print(f'compile_kernels: warning: the ahead-of-time compiled kernels were not built ({exc}); '
                  'the nodes will run numba\'s kernels', file=sys.stderr)
        else:
            state = 'built' if built else 'up to date'
            print(f'compiled kernels {state} in {time.perf_counter() - start:.1f} s: {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
