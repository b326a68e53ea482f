"""Compile the numba kernels of the model, the control law and the fault isolator and fill numba's on-disk cache.

``python -m uh_team.compile_kernels`` (run by ``scripts/_venv.sh`` whenever the kernel
sources change): without it, the first processes to need a kernel compile it, each on its own (a
distributed run starts about a dozen node processes at once).
"""
from __future__ import annotations

import argparse
import sys

from uh_controller_node.control_kernels import compile_control_kernels
from uh_controller_node.impairments import compile_impairment_kernels
from uh_controller_node.isolation_kernels import compile_isolation_kernels
from uh_sim_node.plant_kernels import compile_plant_kernels

from .team_kernel import compile_team_kernel

__all__ = ['compile_all', 'main']


def compile_all() -> dict:
    """Compile (or load from the cache) every kernel; seconds spent per group of kernels."""
    return {'model': compile_plant_kernels(), 'control law': compile_control_kernels(),
            'impairments': compile_impairment_kernels(), 'fault isolation': compile_isolation_kernels(),
            'team loop': compile_team_kernel()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog='python -m uh_team.compile_kernels',
        description='Compile the numba kernels of the helicopter model, the control law, the fault isolator and '
                    'the in-process team loop, and store them in numba\'s cache (__pycache__ next to the sources, or '
                    'NUMBA_CACHE_DIR).')
    parser.parse_args(argv)
    times = compile_all()
    print('kernels ready: ' + ', '.join(f'{name} {seconds:.1f} s' for name, seconds in times.items()))
    return 0


if __name__ == '__main__':
    sys.exit(main())
