"""Where the time of a run goes: ``python -P -m uh_bench.profile [--layout L] [--duration S] [--scenario F]``.

Runs a lockstep team with ``UH_PROFILE_DIR`` set, so every node process dumps a :mod:`cProfile`
profile (:mod:`uh_runtime.procstats`), and prints, per process, the share of its busy time
(time not spent blocked in the wait set) in each part of the stack: the control law, the
helicopter model, message conversions (``uh_wire.wire``), the node runtime and its CDR
codecs, Cyclone DDS's write and take, the bag writer, numpy, ... cProfile adds a roughly constant
cost per Python call, so call-heavy parts look bigger than they are; the shares are for finding
the heavy parts, the benchmark (``uh_bench``) for the figures. For a sampling profile with native
frames (Cyclone DDS, the kernel) use ``py-spy record --native -p PID`` or ``perf record -g -p PID``
on a running node instead.
"""
from __future__ import annotations

import argparse
import collections
import pstats
import sys
import tempfile
from pathlib import Path

from . import runs

__all__ = ['CATEGORIES', 'categorise', 'main']

#: (category, test on (file name, function name)); the first match wins.
CATEGORIES = (
    ('blocked in the wait set', lambda f, fn: fn in ('_wait_for_work', 'final_func')),
    ('Cyclone DDS write (C)', lambda f, fn: 'ddspy_write' in fn),
    ('Cyclone DDS take (C)', lambda f, fn: 'ddspy_take' in fn),
    ('CDR codecs', lambda f, fn: 'cdr codec' in f or f.endswith('uh_runtime/dds/cdr.py')),
    ('node runtime (executor, pub/sub)', lambda f, fn: any(
        f'uh_runtime/dds/{m}.py' in f for m in ('clock', 'context', 'endpoints', 'executors', 'logger', 'node',
                                                 'services'))),
    ('node runtime, other', lambda f, fn: 'uh_runtime/uh_runtime/' in f and not any(
        x in f for x in ('recorder.py', 'bag.py'))),
    ('recorder and bag writer', lambda f, fn: 'recorder.py' in f or 'bag.py' in f or '/mcap/' in f),
    ('message conversions (wire.py)', lambda f, fn: 'uh_wire/wire.py' in f),
    ('controller node', lambda f, fn: any(x in f for x in ('controller_node.py', 'input_sync.py'))),
    ('simulator node', lambda f, fn: 'uh_sim_node/sim_node.py' in f),
    ('clock, virtual leader, visualisation', lambda f, fn: any(
        x in f for x in ('clock_node.py', 'clock_advance.py', 'virtual_leader_node.py', 'visualization_node.py',
                         'reference.py'))),
    # the numba kernels are not Python functions: cProfile books their time to the wrapper calling them
    ('control law', lambda f, fn: any(x in f for x in ('uh_controller_node/controller.py', 'control_kernels.py',
                                                       'loop_kernels.py', 'learning_kernels.py', 'safety_kernels.py',
                                                       'team_kernel.py', 'nominal_model.py'))),
    ('helicopter model and faults', lambda f, fn: any(x in f for x in ('helicopter.py', 'plant_kernels.py',
                                                                       'uh_sim_node/faults.py'))),
    ('numpy', lambda f, fn: 'numpy' in f or 'numpy' in fn),
    ('message objects (dataclass __init__)', lambda f, fn: fn == '__init__' and f == '<string>'),
    ('start-up (imports, YAML, types)', lambda f, fn: any(
        x in f for x in ('yaml/', 'importlib', 'rosbags', 'cyclonedds/idl', 'dataclasses.py', 'typing.py',
                         'inspect.py', 'uh_topology/', 'enum.py', 're/', '<frozen')) or any(
        x in fn for x in ('builtins.exec', 'marshal.loads', '_imp.', 'builtins.compile', '__build_class__',
                          "'read' of '_io"))),
    ('Python built-ins (math, struct, list, dict ...)', lambda f, fn: f == '~'),
)


def categorise(profile_path) -> tuple[dict, float]:
    """``({category: seconds}, busy seconds)`` of one cProfile dump (own time per function)."""
    stats = pstats.Stats(str(profile_path))
    shares = collections.Counter()
    for (filename, _line, function), (_cc, _nc, tottime, _ct, _callers) in stats.stats.items():
        for name, test in CATEGORIES:
            if test(filename, function):
                shares[name] += tottime
                break
        else:
            shares['other'] += tottime
    busy = sum(shares.values()) - shares['blocked in the wait set']
    return dict(shares), busy


def main(argv=None) -> int:
    """Run a profiled lockstep team and print each process's shares of busy time; return 0 (1: the run failed)."""
    p = argparse.ArgumentParser(prog='uh_bench.profile', description=__doc__.split('\n\n')[0])
    p.add_argument('--scenario', default='paper')
    p.add_argument('--layout', default='single', choices=('per-node', 'per-uh', 'single'))
    p.add_argument('--duration', type=float, default=20.0)
    p.add_argument('--keep', default=None, help='directory for the run and the .prof files (default: temporary)')
    p.add_argument('--top', type=int, default=12, help='categories shown per process')
    args = p.parse_args(argv)
    out = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix='uh-profile-'))
    prof_dir = out / 'profiles'
    run = runs.run_team(args.scenario, out / 'run', layout=args.layout, duration=args.duration,
                        env={'UH_PROFILE_DIR': str(prof_dir)})
    print(f'{args.scenario}, {args.layout}, {args.duration:g} s: status {run["status"]}, real-time factor '
          f'{run["rtf"]} (under cProfile), profiles in {prof_dir}\n')
    for path in sorted(prof_dir.glob('*.prof')):
        shares, busy = categorise(path)
        print(f'### {path.stem} (busy {busy:.2f} s)\n\n| part | share of busy time |\n|---|---|')
        ranked = sorted(((v, k) for k, v in shares.items() if k != 'blocked in the wait set'), reverse=True)
        for seconds, name in ranked[:args.top]:
            print(f'| {name} | {100 * seconds / max(busy, 1e-9):.1f} % |')
        print()
    return 0 if run['status'] == 0 else 1


if __name__ == '__main__':
    sys.exit(main())
