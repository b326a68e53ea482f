"""Per-process resource accounting and profiling of node processes, switched on by environment.

Both are off unless asked for, and cost nothing then:

``UH_PROC_STATS_DIR=DIR``
    When the process ends, write ``DIR/<pid>.json``: the nodes it ran (fully qualified names),
    its command line, CPU seconds in user and kernel mode (``getrusage(RUSAGE_SELF)``, all
    threads, so Cyclone DDS's receive threads are included), the part of them spent before the
    executor started spinning (``cpu_startup_s``: imports, parameters, scenario, DDS entities),
    voluntary and involuntary context
    switches, the peak resident set (``VmHWM`` of ``/proc/self/status``, kB, with ``ru_maxrss``
    as fallback) and the wall time since :func:`install_from_env`. The benchmark harness
    (``benchmarks/``) sums these over the node processes of a run.
``UH_PROFILE_DIR=DIR``
    Run the process under :mod:`cProfile` from :func:`mark_spinning` on (the nodes are built, the
    executor starts: start-up is left out) and dump
    ``DIR/<first node name>[+<other nodes>]-<pid>.prof`` at exit (read with ``python -m pstats``). Profiling
    roughly doubles the cost of Python code, so profile one run and time another.

:func:`uh_runtime.run_node` calls :func:`install_from_env` and :func:`set_nodes`, so every
entry point of the stack (and several nodes composed in one process) is covered.
"""
from __future__ import annotations

import atexit
import json
import os
import resource
import sys
import time

__all__ = ['install_from_env', 'set_nodes', 'mark_spinning', 'snapshot', 'peak_rss_kb', 'STATS_ENV',
           'PROFILE_ENV']

#: Environment variable naming the directory for the per-process resource records.
STATS_ENV = 'UH_PROC_STATS_DIR'
#: Environment variable naming the directory for per-process cProfile dumps.
PROFILE_ENV = 'UH_PROFILE_DIR'

_state = {'installed': False, 'nodes': [], 'start': None, 'profiler': None, 'spin_cpu': None}


def peak_rss_kb() -> int:
    """Peak resident set size of this process in kB (``VmHWM``; ``ru_maxrss`` if /proc is absent)."""
    try:
        with open('/proc/self/status') as f:
            for line in f:
                if line.startswith('VmHWM:'):
                    return int(line.split()[1])
    except OSError:
        pass
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def snapshot() -> dict:
    """Resource use of this process so far (see the module docstring for the fields)."""
    ru = resource.getrusage(resource.RUSAGE_SELF)
    start = _state['start']
    spin = _state['spin_cpu']
    return {
        'pid': os.getpid(),
        'nodes': list(_state['nodes']),
        'argv': list(sys.argv),
        'user_s': ru.ru_utime,
        'system_s': ru.ru_stime,
        'cpu_s': ru.ru_utime + ru.ru_stime,
        'cpu_startup_s': spin,
        'voluntary_switches': ru.ru_nvcsw,
        'involuntary_switches': ru.ru_nivcsw,
        'peak_rss_kb': peak_rss_kb(),
        'wall_s': None if start is None else time.monotonic() - start,
    }


def set_nodes(nodes) -> None:
    """Record the fully qualified names of the nodes this process runs (for the stats record)."""
    names = []
    for node in nodes:
        try:
            names.append(node.get_fully_qualified_name())
        except Exception:  # a node that failed half-way through construction
            names.append(getattr(node, 'get_name', lambda: '?')())
    _state['nodes'] = names
    profiler = _state['profiler']
    if profiler is not None and names:
        first = names[0].strip('/').replace('/', '_') or 'node'
        profiler[1] = first if len(names) == 1 else f'{first}+{len(names) - 1}'


def mark_spinning() -> None:
    """Note the CPU seconds used so far as the start-up cost (imports, building the nodes).

    Call it once the nodes are built and the executor is about to spin.
    """
    if _state['spin_cpu'] is None:
        ru = resource.getrusage(resource.RUSAGE_SELF)
        _state['spin_cpu'] = ru.ru_utime + ru.ru_stime
        if _state['profiler'] is not None:
            _state['profiler'][0].enable()


def _write_stats(directory: str) -> None:
    try:
        os.makedirs(directory, exist_ok=True)
        path = os.path.join(directory, f'{os.getpid()}.json')
        tmp = path + '.tmp'
        with open(tmp, 'w') as f:
            json.dump(snapshot(), f)
        os.replace(tmp, path)
    except OSError as exc:
        print(f'[uh_runtime] cannot write process stats to {directory}: {exc}', file=sys.stderr)


def _dump_profile(directory: str) -> None:
    profiler, name = _state['profiler']
    profiler.disable()
    try:
        os.makedirs(directory, exist_ok=True)
        profiler.dump_stats(os.path.join(directory, f'{name}-{os.getpid()}.prof'))
    except OSError as exc:
        print(f'[uh_runtime] cannot write the profile to {directory}: {exc}', file=sys.stderr)


def install_from_env() -> None:
    """Start the accounting and profiling the environment asks for (once per process)."""
    if _state['installed']:
        return
    _state['installed'] = True
    _state['start'] = time.monotonic()
    stats_dir = os.environ.get(STATS_ENV, '').strip()
    profile_dir = os.environ.get(PROFILE_ENV, '').strip()
    if profile_dir:
        import cProfile
        profiler = cProfile.Profile()
        _state['profiler'] = [profiler, os.path.basename(sys.argv[0] or 'python')]
        atexit.register(_dump_profile, profile_dir)
    if stats_dir:
        atexit.register(_write_stats, stats_dir)
