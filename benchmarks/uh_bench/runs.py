"""One team run through the run supervisor (``uh_bringup.run_formation``), measured from outside.

The supervisor is started as a child process with ``UH_PROC_STATS_DIR`` set, so every node
process writes its own resource record when it ends (:mod:`uh_runtime.procstats`: CPU seconds of
all its threads, peak resident set ``VmHWM``). ``os.wait4`` on the supervisor gives the resource
use of the whole process tree (the supervisor waits for every node it started, so their usage is
folded into its children's). The real-time factor is the clock's own figure for the stepping loop
(``run complete: K steps, sim T s in W s wall (real-time factor R)``), which leaves out start-up
(process start, discovery) and shutdown.
"""
from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from uh_runtime.network import release_domain_id, reserve_domain_id

__all__ = ['run_team', 'node_kind', 'RunError', 'parse_run_complete']

_COMPLETE = re.compile(r'run complete: (\d+) steps, sim ([\d.]+) s in ([\d.]+) s wall '
                       r'\(real-time factor ([\d.]+)\)')
_LATE = re.compile(r'\((\d+) late command\(s\) so far\)')
_LATE_TOTAL = re.compile(r'; late commands: (\d+)')   # a simulator's closing summary


class RunError(RuntimeError):
    """A benchmark run could not be started or measured."""


def node_kind(name: str) -> str:
    """``'/uh3/controller'`` -> ``'controller'``, ``'/clock'`` -> ``'clock'``."""
    return name.rstrip('/').rsplit('/', 1)[-1] or name


def parse_run_complete(text: str):
    """Return (steps, sim s, loop wall s, real-time factor) of the clock's last 'run complete' line, or None."""
    found = _COMPLETE.findall(text)
    if not found:
        return None
    steps, sim, wall, rtf = found[-1]
    return int(steps), float(sim), float(wall), float(rtf)


def _read_stats(directory: Path) -> list:
    records = []
    for path in sorted(directory.glob('*.json')):
        try:
            records.append(json.loads(path.read_text()))
        except (OSError, ValueError):
            continue
    return records


def _memory_summary(processes: list) -> dict:
    by_kind: dict[str, list] = {}
    for proc in processes:
        kinds = sorted({node_kind(n) for n in proc['nodes']}) or ['?']
        key = kinds[0] if len(kinds) == 1 else '+'.join(kinds)
        by_kind.setdefault(key, []).append(proc['peak_rss_kb'])
    peaks = [p['peak_rss_kb'] for p in processes]
    return {
        'max_kb': max(peaks) if peaks else None,
        'mean_kb': sum(peaks) / len(peaks) if peaks else None,
        'total_kb': sum(peaks),
        'by_kind_max_kb': {k: max(v) for k, v in sorted(by_kind.items())},
    }


def _run_formation_command(scenario, run_dir: Path, layout: str, clock: str, rate: float, domain: int,
                           duration: float | None, extra_args) -> list:
    """Return the command line of the run supervisor writing its output to ``run_dir``."""
    cmd = [sys.executable, '-P', '-m', 'uh_bringup.run_formation', '--scenario', str(scenario),
           '--out', str(run_dir), '--no-metrics', '--processes', layout, '--clock', clock,
           '--rate', repr(float(rate)), '--domain-id', str(domain)]
    if duration is not None:
        cmd += ['--duration', repr(float(duration))]
    return cmd + list(extra_args)


def _supervisor_environment(env: dict | None, stats_dir: Path) -> dict:
    """Return the supervisor's environment: this one with ``env`` and ``UH_PROC_STATS_DIR`` set, unprofiled."""
    child_env = dict(os.environ)
    child_env.pop('UH_PROFILE_DIR', None)      # profiling distorts timing: only when asked for here
    child_env.update(env or {})
    child_env['UH_PROC_STATS_DIR'] = str(stats_dir)
    return child_env


def _wait_for_supervisor(proc, timeout: float | None, on_started) -> tuple:
    """Wait for the supervisor ``proc`` to end, interrupting it (SIGINT) after ``timeout`` wall seconds.

    Return ``(wait status, resource usage of the process tree, whether it was interrupted)``.
    """
    timed_out = []

    def interrupt():
        timed_out.append(True)
        try:
            proc.send_signal(signal.SIGINT)
        except ProcessLookupError:
            pass
    timer = threading.Timer(timeout, interrupt) if timeout else None
    if timer:
        timer.daemon = True
        timer.start()
    try:
        if on_started is not None:
            on_started(proc)
        _, wait_status, usage = os.wait4(proc.pid, 0)
    finally:
        if timer:
            timer.cancel()
    return wait_status, usage, bool(timed_out)


def _log_texts(log_dir: Path) -> list:
    """Return the text of every node log of the run (those that can be read)."""
    texts = []
    for path in sorted(log_dir.glob('*.log')):
        try:
            texts.append(path.read_text(errors='replace'))
        except OSError:
            pass
    return texts


def _exit_codes(run_dir: Path) -> dict:
    """Return ``{node process: exit status}`` from the supervisor's ``run.json`` (empty without one)."""
    try:
        return json.loads((run_dir / 'run.json').read_text()).get('exit_codes', {})
    except (OSError, ValueError):
        return {}


def _node_processes(stats_dir: Path) -> list:
    """Return per node process its nodes, CPU seconds (user, system, before spinning) and peak resident set."""
    return [{'nodes': r['nodes'], 'cpu_s': r['cpu_s'], 'user_s': r['user_s'],
             'system_s': r['system_s'], 'startup_cpu_s': r.get('cpu_startup_s') or 0.0,
             'peak_rss_kb': r['peak_rss_kb']}
            for r in _read_stats(stats_dir)]


def run_team(scenario: str, out_dir, *, layout: str = 'per-node', clock: str = 'lockstep',
             rate: float = 1.0, duration: float | None = None, domain_id: int | None = None,
             timeout: float | None = None, env: dict | None = None, on_started=None,
             extra_args=()) -> dict:
    """Run a team with ``run_formation`` and measure it.

    Parameters
    ----------
    scenario : str
        ``'paper'`` or a scenario file.
    out_dir : path
        New directory: ``run/`` (the supervisor's output), ``stats/`` (per-process records),
        ``supervisor.log``.
    layout, clock, rate, duration
        ``--processes``, ``--clock``, ``--rate``, ``--duration`` of the run.
    domain_id : int, optional
        DDS domain (default: one from :func:`uh_runtime.network.reserve_domain_id`, given back
        when the run has ended).
    timeout : float, optional
        Wall seconds after which the run is interrupted (SIGINT) and reported as failed.
    env : dict, optional
        Extra environment for the supervisor and its nodes.
    on_started : callable, optional
        Called with the supervisor's ``Popen`` once it runs.
    extra_args : sequence of str
        More ``run_formation`` options (e.g. ``--no-standard-views``).

    Returns
    -------
    dict
        ``status`` (exit status), ``rtf``, ``steps``, ``loop_wall_s`` (the clock's stepping loop),
        ``wall_s`` (whole run with start-up), ``cpu_s`` / ``cpu_user_s`` / ``cpu_system_s`` (sum
        over the node processes), ``cpu_startup_s`` (their part before spinning) and ``cpu_run_s``
        (the rest: discovery, the run, shutdown), ``tree_cpu_s`` (supervisor and everything it waited for),
        ``processes`` (per process: nodes, cpu_s, peak_rss_kb), ``memory`` (peak resident set
        summary, kB), ``late_commands_logged`` (the largest late-command count a sim logged a
        warning at, realtime), ``late_commands`` (the sims' closing counts, summed; realtime),
        ``abnormal_exits`` (node processes that did not exit with status 0, from ``run.json``),
        ``out`` (output directory).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stats_dir = out / 'stats'
    domain = reserve_domain_id() if domain_id is None else int(domain_id)
    cmd = _run_formation_command(scenario, out / 'run', layout, clock, rate, domain, duration, extra_args)
    child_env = _supervisor_environment(env, stats_dir)
    log = open(out / 'supervisor.log', 'w')
    started = time.monotonic()
    try:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                env=child_env)
    except OSError as exc:
        log.close()
        if domain_id is None:
            release_domain_id(domain)
        raise RunError(f'cannot start the run supervisor: {exc}') from None
    try:
        wait_status, usage, timed_out = _wait_for_supervisor(proc, timeout, on_started)
    finally:
        log.close()
        if domain_id is None:
            release_domain_id(domain)
    proc.returncode = os.waitstatus_to_exitcode(wait_status)
    wall = time.monotonic() - started

    texts = _log_texts(out / 'run' / 'logs')
    complete = None
    for text in texts:
        complete = parse_run_complete(text) or complete
    late = [int(n) for text in texts for n in _LATE.findall(text)]
    exit_codes = _exit_codes(out / 'run')
    processes = _node_processes(stats_dir)
    result = {
        'scenario': str(scenario), 'layout': layout, 'clock': clock, 'rate': rate,
        'duration_s': duration, 'domain_id': domain, 'status': proc.returncode,
        'timed_out': timed_out, 'wall_s': wall,
        'steps': complete[0] if complete else None,
        'loop_wall_s': complete[2] if complete else None,
        'rtf': complete[3] if complete else None,
        'cpu_s': sum(p['cpu_s'] for p in processes),
        'cpu_user_s': sum(p['user_s'] for p in processes),
        'cpu_system_s': sum(p['system_s'] for p in processes),
        'cpu_startup_s': sum(p['startup_cpu_s'] for p in processes),
        'cpu_run_s': sum(p['cpu_s'] - p['startup_cpu_s'] for p in processes),
        'tree_cpu_s': usage.ru_utime + usage.ru_stime,
        'n_processes': len(processes),
        'processes': processes,
        'memory': _memory_summary(processes),
        'late_commands_logged': max(late) if late else 0,
        'late_commands': sum(int(n) for text in texts for n in _LATE_TOTAL.findall(text)),
        'abnormal_exits': {name: code for name, code in exit_codes.items() if code not in (0, None)},
        'out': str(out),
    }
    if complete is None or proc.returncode != 0:
        tail = (out / 'supervisor.log').read_text(errors='replace').splitlines()[-8:]
        result['error'] = '\n'.join(tail)
    return result
