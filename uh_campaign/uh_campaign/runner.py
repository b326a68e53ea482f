"""Running a campaign: work units in a local process pool or on a Dask cluster, resumably.

A *run* (work unit) is ``(draw, sweep_index, case)``. The main process resolves the scenario of
each (draw, sweep point) (:func:`uh_campaign.spec.resolve_scenario`), writes it to
``DIR/scenarios/`` before anything runs it, and hands the pending cases of that scenario to a
worker as one *task* (so the scenario is parsed once for its cases). A worker loads the scenario
from the YAML text, runs each case with
:func:`uh_team.team_simulation.run_team_simulation`, scores it with
:func:`uh_team.metrics.metrics_from_arrays` and returns one row per case
(:func:`uh_team.campaign_store.metric_row` plus status, reason and wall time). Only the main
process writes the results file, one committed row per run as soon as it arrives
(:mod:`uh_team.campaign_store`), so an interruption loses at most the runs in flight and a
re-run skips every stored key. What a worker runs is :mod:`uh_campaign.worker`; the progress line
and the closing summary are :mod:`uh_campaign.progress`.

Outcome of a run: ``ok``; ``diverged`` when the simulation raised a
:class:`~uh_team.team_simulation.SimulationError` about a non-finite state; ``failed`` with
``'<exception type>: <message>'`` for anything else (a scenario that does not load, a generated
draw without a valid graph, an error in the metrics). No run stops the campaign. A task the
executor itself loses (a Dask worker killed while running it) says nothing about its runs: they
are not stored, the campaign goes on and then ends with exit status 1, and a resume runs them
again. A local worker process that dies (a crash, the system ending it) takes the tasks in flight
with it: each of them is then run alone in a new pool, so the one that kills its worker is
recorded as ``failed`` (``a worker process died ... while running it``) and the campaign goes on. ``success`` is 1
when the run is ``ok`` and every metric of the spec's ``success`` mapping is at most its
threshold (a missing or NaN metric is not met), else 0.

Executors
---------
*Local* (default): :class:`concurrent.futures.ProcessPoolExecutor` with ``workers`` processes
(default ``os.cpu_count()``), started with the ``spawn`` method: no fork of a process holding
numba's state and an open results file, and, unlike Python 3.11's fork server, the workers get
the main process's ``sys.path`` (a worker started in the repository root would otherwise import
the source directories ``uh_team/``, ``uh_topology/`` as empty namespace packages). The main
process loads (or compiles into numba's cache) the kernels before the pool starts and each
worker loads them once, in its initializer (about 2 s per worker, once per campaign); workers
ignore SIGINT, so Ctrl-C reaches only the main process. At most ``2 x workers`` tasks are in
flight.

*Cluster*: ``distributed.Client(ADDRESS)`` of Dask's ``distributed``; tasks are sent with
``client.submit`` and collected with ``as_completed`` as they finish, at most ``2 x`` the
cluster's threads at a time. The scenario goes to the worker as text, so workers need no shared
file system, but they must have this project installed (the same versions: numbers are
compared across runs) and import ``uh_team``. Dask rather than Ray: Dask's packages are pure
Python wheels, a ``LocalCluster`` starts in-process in a test in a couple of seconds, ``dask
scheduler`` / ``dask worker`` start a real cluster from the command line, and its futures stream
back one by one as they finish, so each run is committed at once; Ray brings a large native
runtime (raylet, GCS, object store) that would compete with the runs for a small machine's cores.

Stopping
--------
:func:`run_campaign` checks ``stop`` (a :class:`threading.Event`, set by the CLI on SIGINT) while
it waits: it then submits nothing more, cancels the tasks not yet started, waits for those
running, commits their rows and raises :class:`CampaignInterrupted`.
"""
from __future__ import annotations

import concurrent.futures as cf
import math
import multiprocessing
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

from uh_team import campaign_store as store
from uh_team.compile_kernels import compile_all

from .progress import Progress, summary_lines
from .spec import CampaignSpec, resolve_scenario, scenario_file_name, scenario_yaml
from .worker import failure_reason, init_local_worker, run_task

__all__ = ['run_campaign', 'run_task', 'CampaignError', 'CampaignInterrupted', 'CampaignOutcome', 'Progress',
           'success_of', 'summary_lines', 'campaign_versions']

#: Tasks in flight per worker (one running, one queued: a worker never waits for the main process).
_IN_FLIGHT_PER_WORKER = 2

#: Seconds between checks of the stop flag while waiting for results.
_POLL = 0.2

#: Largest wait for the tasks running when the campaign is stopped, s.
_DRAIN_TIMEOUT = 120.0


class CampaignError(RuntimeError):
    """A campaign that cannot start or go on.

    The directory holds another campaign, the cluster cannot be reached (``status`` 2: bad input, nothing ran), a worker
    process died (``status`` 1: what is done is saved).
    """

    def __init__(self, message: str, status: int = 2):
        self.status = status
        super().__init__(message)


class WorkerDied(CampaignError):
    """A local worker process died (a crash, or the system ended it): every task in flight is lost."""


class CampaignInterrupted(Exception):
    """The campaign was stopped (``stop`` set): every finished run is committed; ``outcome`` counts them."""

    def __init__(self, outcome: 'CampaignOutcome'):
        self.outcome = outcome
        super().__init__(f'interrupted after {outcome.done} of {outcome.total} runs')


@dataclass
class CampaignOutcome:
    """Counts of a campaign after :func:`run_campaign`.

    Runs of the whole campaign (``total``), stored now (``done``), stored before this call (``skipped``), and of those
    run now, not ``ok`` (``failures``).
    """

    directory: Path
    total: int
    done: int
    skipped: int
    failures: int
    wall_time_s: float


# ------------------------------------------------------------------------------------------------
# Executors


class _LocalPool:
    """Tasks in a process pool on this machine."""

    def __init__(self, workers: int):
        compile_all()    # fill numba's cache once here, so the workers only load it
        self.context = multiprocessing.get_context('spawn')
        self.workers = workers
        self.slots = workers * _IN_FLIGHT_PER_WORKER
        self.pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=self.context,
                                           initializer=init_local_worker)
        self.description = f'{workers} local worker process{"es" if workers != 1 else ""}'
        self.unstarted = workers    # workers not started yet (the pool starts them as tasks come)

    def restart(self):
        """Return a new pool in place of a broken one (after :class:`WorkerDied`)."""
        self.pool.shutdown(wait=False, cancel_futures=True)
        self.pool = cf.ProcessPoolExecutor(max_workers=self.workers, mp_context=self.context,
                                           initializer=init_local_worker)
        self.unstarted = self.workers

    def submit(self, task):
        if not self.unstarted:
            return self.pool.submit(run_task, task)
        # The pool starts a worker per submit until it has them all. They inherit an ignored SIGINT,
        # so a terminal's Ctrl-C never reaches one still starting (before its initializer): the main
        # process handles it.
        self.unstarted -= 1
        try:
            previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
        except ValueError:        # not the main thread: signals are not ours to change
            return self.pool.submit(run_task, task)
        try:
            return self.pool.submit(run_task, task)
        finally:
            signal.signal(signal.SIGINT, previous)

    def wait(self, futures, timeout):
        done, _ = cf.wait(futures, timeout=timeout, return_when=cf.FIRST_COMPLETED)
        return done

    def result(self, future):
        try:
            return future.result()
        except cf.process.BrokenProcessPool as exc:
            raise WorkerDied(f'a worker process died ({exc})', status=1) from None

    def cancel(self, futures):
        for future in futures:
            future.cancel()

    def close(self, abort: bool = False):
        """Shut the pool down; ``abort``: end the running workers instead of waiting for them."""
        if abort:
            # ProcessPoolExecutor has no public way to stop running tasks; its worker processes are
            # in the (documented-as-internal) _processes mapping
            for process in list(getattr(self.pool, '_processes', {}).values()):
                process.terminate()
        self.pool.shutdown(wait=not abort, cancel_futures=True)


class _DaskCluster:
    """Tasks on a Dask ``distributed`` cluster (its scheduler at ``address``)."""

    def __init__(self, address: str):
        try:
            from distributed import Client, as_completed
        except ImportError as exc:
            raise CampaignError(f'--cluster needs dask[distributed] ({exc}); install requirements.txt') from None
        try:
            self.client = Client(address, timeout='15s')
        except (OSError, TimeoutError, ValueError) as exc:
            raise CampaignError(f'cannot reach the Dask scheduler at {address!r}: {exc}') from None
        threads = sum(self.client.nthreads().values()) or 1
        self.slots = threads * _IN_FLIGHT_PER_WORKER
        self.completed = as_completed()
        self.description = f'Dask cluster {address} ({threads} worker thread{"s" if threads != 1 else ""})'

    def submit(self, task):
        future = self.client.submit(run_task, task, pure=False)
        self.completed.add(future)
        return future

    def wait(self, futures, timeout):
        deadline = time.monotonic() + timeout
        while not self.completed.has_ready() and time.monotonic() < deadline:
            time.sleep(0.02)
        return set(self.completed.next_batch(block=False)) if self.completed.has_ready() else set()

    def result(self, future):
        return future.result()

    def cancel(self, futures):
        pending = [f for f in futures if not f.done()]
        if pending:
            self.client.cancel(pending)

    def close(self, abort: bool = False):
        self.client.close()


# ------------------------------------------------------------------------------------------------
# Main side


def success_of(row: dict, thresholds: dict) -> int:
    """1 when the run is ``ok`` and every thresholded metric is at most its threshold, else 0."""
    if row.get('status') != 'ok':
        return 0
    for metric, threshold in thresholds.items():
        value = row.get(metric)
        if value is None or not math.isfinite(float(value)) or float(value) > threshold:
            return 0
    return 1


def campaign_versions() -> dict:
    """Versions of what produces the numbers: Python, numpy, numba and the project's packages."""
    out = {'python': sys.version.split()[0]}
    for name in ('numpy', 'numba', 'uh_team', 'uh_topology', 'uh_core', 'uh_sim_node', 'uh_controller_node'):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def _open_campaign_dir(spec: CampaignSpec, directory: Path):
    """Open ``DIR/campaign.sqlite`` for ``spec``: new, or the same campaign (resume)."""
    if directory.exists() and not directory.is_dir():
        raise CampaignError(f'--out {str(directory)!r} exists and is not a directory')
    db = directory / store.DB_NAME
    if directory.is_dir() and not db.exists() and any(directory.iterdir()):
        raise CampaignError(f'--out {str(directory)!r} is not empty and holds no campaign ({store.DB_NAME}); '
                            'choose a new or empty directory')
    try:
        (directory / 'scenarios').mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CampaignError(f'--out {str(directory)!r}: cannot write there ({exc.strerror}); choose a directory '
                            'you can write to') from None
    try:
        con = store.open_store(db)
    except store.StoreError as exc:
        raise CampaignError(str(exc)) from None
    meta = store.read_meta(con)
    if meta.get('spec_digest') not in (None, spec.digest):
        con.close()
        runs = f' with --runs {spec.runs_override}' if spec.runs_override is not None else ''
        raise CampaignError(
            f'{str(directory)!r} holds campaign {meta.get("name")!r} of another spec ({meta.get("spec_path")!r}, '
            f'runs {meta.get("runs")}): its spec digest differs from that of {spec.source or "this spec"}{runs}. '
            f'Resume it with the spec text and --runs it was started with, or give a new --out directory')
    if 'spec_digest' not in meta:
        values = dict(
            name=spec.name, spec=spec.text, spec_digest=spec.digest, spec_path=str(spec.source or ''),
            seed=spec.seed, runs=spec.runs, cases=list(spec.cases), success=dict(spec.success),
            duration=spec.duration, created=datetime.now(timezone.utc).isoformat(timespec='seconds'),
            versions=campaign_versions())
        if spec.sweep is not None:
            values.update(sweep_parameter=spec.sweep.parameter, sweep_values=list(spec.sweep.values))
        store.write_meta(con, **values)
    return con


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + '.tmp')
    tmp.write_text(text)
    os.replace(tmp, path)


def _tasks(spec: CampaignSpec, directory: Path, done: set):
    """``(task, failed_rows)`` per (draw, sweep point) with pending cases, in key order.

    The task to run, or the failed rows of a scenario that could not be resolved.
    """
    for draw in range(spec.runs):
        for s, value in enumerate(spec.sweep_values):
            cases = [case for case in spec.cases if (draw, s, case) not in done]
            if not cases:
                continue
            sweep_value = None if value is None else float(value)
            rel = scenario_file_name(spec, draw, s)
            try:
                mapping = resolve_scenario(spec, draw, s)
            except Exception as exc:   # noqa: BLE001 - e.g. no valid graph for this draw
                yield None, [dict(draw=draw, sweep_index=s, case_name=case, sweep_value=sweep_value, status='failed',
                                  reason=failure_reason(exc), wall_time_s=0.0) for case in cases]
                continue
            header = (f'# Resolved scenario of campaign {spec.name!r}, draw {draw}'
                      + (f', {spec.sweep.parameter} = {value!r}' if spec.sweep is not None else '')
                      + f' (uh-campaign, seed {spec.seed}).\n'
                      f'# Re-run from the campaign directory: uh-simulate --scenario {rel} --case {spec.cases[0]} '
                      f'--out runs/draw{draw}\n')
            text = scenario_yaml(mapping, header)
            _write_atomic(directory / rel, text)    # saved before it runs
            yield {'draw': draw, 'sweep_index': s, 'sweep_value': sweep_value, 'scenario_file': rel,
                   'scenario_text': text, 'cases': cases}, None


def run_campaign(spec: CampaignSpec, directory, *, workers: int | None = None, cluster: str | None = None,
                 progress: 'Progress | None' = None, stop: threading.Event | None = None) -> CampaignOutcome:
    """Run every run of ``spec`` not yet stored in ``directory`` (module docstring).

    Parameters
    ----------
    spec : CampaignSpec
    directory : path
        The campaign directory (created; or one holding this campaign: resumed).
    workers : int, optional
        Local worker processes (default ``os.cpu_count()``); ignored with ``cluster``.
    cluster : str, optional
        Address of a Dask scheduler (``tcp://host:8786``).
    progress : Progress, optional
        Told about every stored run.
    stop : threading.Event, optional
        When set, the campaign stops (see module docstring).

    Raises
    ------
    CampaignError
        The directory holds another campaign or no campaign, the cluster cannot be reached, or
        the executor lost runs (they are not stored; a resume runs them).
    CampaignInterrupted
        ``stop`` was set; finished runs are committed.
    """
    directory = Path(directory)
    executor = _DaskCluster(cluster) if cluster else None     # an unreachable cluster: DIR stays untouched
    try:
        con = _open_campaign_dir(spec, directory)
    except BaseException:
        if executor is not None:
            executor.close()
        raise
    start = time.monotonic()
    done_before = store.done_keys(con)
    total = spec.total_runs
    skipped = sum(1 for key in spec.units() if key in done_before)
    counts = {'done': skipped, 'failures': 0}
    if progress is not None:
        progress.start(total, skipped)

    def commit(rows):
        for row in rows:
            row['success'] = success_of(row, spec.success)
            store.write_run(con, row)
            counts['done'] += 1
            counts['failures'] += row['status'] != 'ok'
            if progress is not None:
                progress.update(counts['done'], counts['failures'])

    def outcome():
        return CampaignOutcome(directory=directory, total=total, done=counts['done'], skipped=skipped,
                               failures=counts['failures'], wall_time_s=time.monotonic() - start)

    inflight = {}
    lost = []    # (runs, reason) of tasks the executor lost
    try:
        if skipped < total:
            if executor is None:
                executor = _LocalPool(workers or os.cpu_count() or 1)
            if progress is not None:
                progress.note(f'running on {executor.description}')
        tasks = _tasks(spec, directory, done_before)
        if skipped < total:
            _run_tasks(executor, tasks, inflight, commit, lost, stop)
        if lost:
            raise CampaignError(f'{sum(n for n, _ in lost)} runs were lost by the executor, not run (e.g. '
                                f'{lost[0][1]}); the rest is saved, and a resume runs them again', status=1)
    except _Stop:
        _drain(executor, inflight, commit)
        raise CampaignInterrupted(outcome()) from None
    finally:
        if executor is not None:
            # a second Ctrl-C (KeyboardInterrupt) does not wait for the runs in flight
            executor.close(abort=sys.exc_info()[0] is KeyboardInterrupt)
        con.close()
    return outcome()


class _Stop(Exception):
    pass


def _submit_more(executor, tasks, inflight: dict, commit, stop) -> bool:
    """Submit tasks while the executor has free slots and no stop is asked; return whether ``tasks`` is exhausted.

    A task whose scenario could not be made comes with its failed rows, which are committed at once.
    """
    while len(inflight) < executor.slots and not (stop and stop.is_set()):
        try:
            task, failed = next(tasks)
        except StopIteration:
            return True
        if failed:
            commit(failed)
        else:
            inflight[executor.submit(task)] = task
    return False


def _collect(executor, inflight: dict, commit, lost: list, stop) -> None:
    """Commit the rows of the tasks finished within :data:`_POLL` seconds.

    A dead local worker takes every task in flight with it: each of them is then run alone in a new
    pool, so the one that kills its worker is recorded as failed and the others run.
    """
    for future in executor.wait(list(inflight), _POLL):
        task = inflight.pop(future)
        try:
            rows = _task_rows(executor, future, task, lost)
        except CampaignError as exc:
            if stop is not None and stop.is_set():
                raise _Stop from None   # workers hit by the same Ctrl-C (a terminal's)
            if not isinstance(exc, WorkerDied):
                raise
            suspects = [task, *inflight.values()]
            inflight.clear()
            for suspect in suspects:
                executor.restart()
                commit(_run_alone(executor, suspect, stop))
            executor.restart()
            return
        commit(rows)


def _run_tasks(executor, tasks, inflight: dict, commit, lost: list, stop) -> None:
    """Keep the executor's slots filled from ``tasks`` and commit the rows as they come, until all are done.

    Raises
    ------
    _Stop
        ``stop`` was set (the tasks in flight are still in ``inflight``).
    """
    exhausted = False
    while True:
        if not exhausted:
            exhausted = _submit_more(executor, tasks, inflight, commit, stop)
        if stop is not None and stop.is_set():
            raise _Stop
        if not inflight:
            return
        _collect(executor, inflight, commit, lost, stop)


def _run_alone(executor, task, stop) -> list:
    """Return the rows of ``task`` run with nothing else in flight; failed rows if its worker dies."""
    future = executor.submit(task)
    while not future.done():
        if stop is not None and stop.is_set():
            raise _Stop
        executor.wait([future], _POLL)
    try:
        return executor.result(future)
    except WorkerDied as exc:
        return [dict(draw=task['draw'], sweep_index=task['sweep_index'], case_name=case,
                     sweep_value=task['sweep_value'], scenario_file=task['scenario_file'], status='failed',
                     reason=f'{exc} while running it', wall_time_s=0.0) for case in task['cases']]


def _task_rows(executor, future, task, lost: list) -> list:
    """Return the rows a finished task returned.

    A task the executor lost (e.g. a Dask worker killed while running it) says nothing about its runs: they are not
    stored, so a resume runs them again, and the reason goes to ``lost``.
    """
    try:
        return executor.result(future)
    except CampaignError:
        raise
    except Exception as exc:   # noqa: BLE001 - an executor's error, not the runs' outcome
        lost.append((len(task['cases']), failure_reason(exc)))
        return []


def _drain(executor, inflight: dict, commit) -> None:
    """After a stop: cancel what has not started, commit what finishes within the drain time."""
    if executor is None or not inflight:
        return
    executor.cancel(list(inflight))
    deadline = time.monotonic() + _DRAIN_TIMEOUT
    while inflight and time.monotonic() < deadline:
        for future in [f for f in inflight if f.done()]:
            task = inflight.pop(future)
            if not future.cancelled():
                try:
                    commit(_task_rows(executor, future, task, []))
                except CampaignError:
                    return
        if inflight:
            executor.wait(list(inflight), _POLL)
