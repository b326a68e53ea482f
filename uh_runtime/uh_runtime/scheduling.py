"""Real-time scheduling of a node's process (docs/performance.md#real-time-scheduling).

In realtime mode the control loop (the clock, the simulators, the controllers and the virtual
leader) has one control period, 10 ms in the paper scenario, to carry a tick, a state and a
command. Linux runs ordinary processes under its fair scheduler (``SCHED_OTHER``): when more
processes are runnable than there are cores, each waits its turn, and a command misses its step.
A ``SCHED_FIFO`` thread runs as soon as it is runnable, ahead of every ``SCHED_OTHER`` one; this is
how ROS 2 control stacks keep their period (ros2_control's controller manager, the ROS 2
real-time guides).

:func:`set_realtime_priority` puts every thread of the calling process under ``SCHED_FIFO``: the
node's own, and the middleware's receive threads, which deliver the inputs the node waits for.
Threads created later inherit the policy from the thread that creates them. It needs the
``CAP_SYS_NICE`` capability (root has it) or an ``rtprio`` limit (``ulimit -r``) of at least the
priority; without, it changes nothing and says why, and the node runs on at normal priority.

Before it does, it makes numpy's and scipy's BLAS compute in the calling thread
(:func:`single_threaded_blas`). OpenBLAS hands a large enough product to worker threads and busy-waits
for them; under ``SCHED_FIFO`` the waiting thread keeps its core, and with one process per node two such
waits filled both cores of a 2-core machine while the workers they waited for could not run: the
controllers spun at 100 % CPU and starved the machine (docs/performance.md#real-time-scheduling).

No ROS: both backends call it (:mod:`uh_wire.run_config`); threadpoolctl limits the BLAS already loaded.
"""
from __future__ import annotations

import os
import threading

__all__ = ['DEFAULT_PRIORITY', 'MAX_PRIORITY', 'BLAS_THREAD_VARIABLES', 'set_realtime_priority',
           'single_threaded_blas', 'permitted', 'policy_of']

#: default SCHED_FIFO priority of a realtime run's control loop: below the 50 of PREEMPT_RT's
#: interrupt threads, which deliver the packets the nodes wait for
DEFAULT_PRIORITY = 20
#: highest priority a node may ask for; 99 is for the kernel's own per-CPU threads
MAX_PRIORITY = 98
#: the thread counts a BLAS library reads when it loads (OpenBLAS, its OpenMP builds, MKL)
BLAS_THREAD_VARIABLES = ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS')


def _check(priority: int) -> None:
    if isinstance(priority, bool) or not isinstance(priority, int) or not 1 <= priority <= MAX_PRIORITY:
        raise ValueError(f'real-time priority {priority!r}: allowed an integer 1..{MAX_PRIORITY} '
                         '(0 leaves the scheduling to the operating system)')


def _unsupported() -> str | None:
    if not hasattr(os, 'sched_setscheduler') or not hasattr(os, 'SCHED_FIFO'):
        return 'this operating system has no SCHED_FIFO scheduling (Linux only)'
    return None


def _not_permitted(priority: int) -> str:
    limit = ''
    try:
        import resource
        soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
        limit = f' (this user\'s rtprio limit is {"unlimited" if soft == resource.RLIM_INFINITY else soft})'
    except (ImportError, AttributeError, OSError, ValueError):
        pass
    return (f'SCHED_FIFO priority {priority} is not permitted{limit}: it needs the CAP_SYS_NICE capability '
            f'(root has it) or an rtprio limit of at least {priority} (a line "<user> - rtprio {MAX_PRIORITY}" '
            'in /etc/security/limits.conf; in a container, the SYS_NICE capability and a real-time CPU budget)')


def _threads() -> list[int]:
    try:
        return sorted(int(tid) for tid in os.listdir('/proc/self/task'))
    except OSError:
        return [0]  # no /proc: the calling thread only


def single_threaded_blas() -> None:
    """Make every BLAS of this process compute in the thread that calls it, with no worker threads.

    The libraries loaded already through threadpoolctl, those loaded later through
    :data:`BLAS_THREAD_VARIABLES`, which a BLAS reads when it loads.
    """
    from threadpoolctl import threadpool_limits
    for name in BLAS_THREAD_VARIABLES:
        os.environ[name] = '1'
    threadpool_limits(limits=1, user_api='blas')


def set_realtime_priority(priority: int) -> str | None:
    """Run every thread of this process under ``SCHED_FIFO`` at ``priority`` (1..98), BLAS single-threaded.

    Returns None when done, else why it could not be done (nothing is changed then but the BLAS
    threads, :func:`single_threaded_blas`); raises ``ValueError`` for a priority outside 1..98.
    """
    _check(priority)
    why = _unsupported()
    if why:
        return why
    single_threaded_blas()
    param = os.sched_param(priority)
    done = []
    try:
        for tid in _threads():
            try:
                before = os.sched_getscheduler(tid), os.sched_getparam(tid)
                os.sched_setscheduler(tid, os.SCHED_FIFO, param)  # Linux: a thread id selects that thread
            except ProcessLookupError:
                continue  # the thread ended meanwhile
            done.append((tid, before))
    except PermissionError:
        for tid, (policy, old) in done:  # all or nothing: the first thread is the one that fails in practice
            try:
                os.sched_setscheduler(tid, policy, old)
            except OSError:
                pass
        return _not_permitted(priority)
    return None


def permitted(priority: int) -> str | None:
    """Whether this process may use ``SCHED_FIFO`` at ``priority``: None if so, else why not.

    Tried on a short-lived thread of its own, so the caller's scheduling does not change.
    """
    _check(priority)
    why = _unsupported()
    if why:
        return why
    answer = []

    def attempt():
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))  # 0: this thread only
            answer.append(None)
        except PermissionError:
            answer.append(_not_permitted(priority))
        except OSError as exc:
            answer.append(f'SCHED_FIFO priority {priority} failed: {exc}')
    thread = threading.Thread(target=attempt, name='rt-priority-probe')
    thread.start()
    thread.join()
    return answer[0]


def policy_of(tid: int) -> tuple[str, int]:
    """``('fifo' | 'rr' | 'other' | ..., priority)`` of a thread or process id (Linux)."""
    names = {getattr(os, f'SCHED_{n.upper()}'): n for n in ('other', 'fifo', 'rr', 'batch', 'idle')
             if hasattr(os, f'SCHED_{n.upper()}')}
    policy = os.sched_getscheduler(tid)
    return names.get(policy, str(policy)), os.sched_getparam(tid).sched_priority
