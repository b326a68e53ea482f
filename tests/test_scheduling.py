"""Real-time scheduling of the control loop (uh_runtime.scheduling; docs/performance.md#real-time-scheduling).

What can be checked without timing: the policy the kernel reports for every thread of every node
process. Whether SCHED_FIFO is permitted depends on the machine (root, CAP_SYS_NICE, rtprio
limit); where it is not, the tests check the other promise instead: nothing changes, the reason
is said, and the run goes on.
"""
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from team_runs import start_run, stop_run, wait_for_log

from uh_bringup.team_nodes import NODES, node_specs
from uh_runtime import scheduling
from uh_topology.scenario import load_scenario

PRIORITY = 7   # any value of 1..98 shows the mechanism; not the default, so the test sees it was passed on


@pytest.mark.parametrize('bad', [0, 99, -1, True, 1.5, '5'])
def test_a_priority_outside_1_to_98_is_refused(bad):
    with pytest.raises(ValueError, match='allowed an integer 1..98'):
        scheduling.set_realtime_priority(bad)
    with pytest.raises(ValueError, match='allowed an integer 1..98'):
        scheduling.permitted(bad)


def test_asking_whether_it_is_permitted_leaves_the_caller_alone():
    me = threading.get_native_id()
    before = scheduling.policy_of(me)
    answer = scheduling.permitted(PRIORITY)
    assert answer is None or 'not permitted' in answer
    assert scheduling.policy_of(me) == before


_CHILD = r'''
import json, os, threading
from uh_runtime import scheduling
hold = threading.Event()
old = threading.Thread(target=hold.wait); old.start()          # a thread that exists before
why = scheduling.set_realtime_priority(%d)
new = threading.Thread(target=hold.wait); new.start()          # and one created after
policies = {tid: scheduling.policy_of(int(tid)) for tid in os.listdir('/proc/self/task')}
hold.set(); old.join(); new.join()
print(json.dumps({'why': why, 'policies': policies}))
'''


def test_every_thread_of_the_process_runs_under_sched_fifo_and_new_threads_inherit_it():
    out = subprocess.run([sys.executable, '-c', _CHILD % PRIORITY], capture_output=True, text=True, check=True)
    result = json.loads(out.stdout)
    assert len(result['policies']) >= 3
    if scheduling.permitted(PRIORITY) is None:
        assert result['why'] is None
        assert set(map(tuple, result['policies'].values())) == {('fifo', PRIORITY)}
    else:   # not permitted here: said, and nothing changed
        assert 'not permitted' in result['why'] and 'rtprio' in result['why']
        assert {p for p, _ in result['policies'].values()} == {'other'}


_BLAS_CHILD = '''
import json
import numpy
from threadpoolctl import threadpool_info
from uh_runtime import scheduling
before = [i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas']
scheduling.single_threaded_blas()
import scipy.linalg   # scipy's own OpenBLAS, loaded after the call
after = {i['filepath']: i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas'}
print(json.dumps({'before': before, 'after': after}))
'''


def test_a_realtime_process_computes_blas_in_its_own_thread_also_in_a_library_loaded_later():
    """Under SCHED_FIFO, OpenBLAS's busy wait for its workers starved a 2-core machine (uh_runtime.scheduling).

    numpy's BLAS is loaded before the call (threadpoolctl limits it), scipy's after (the environment does).
    """
    env = {k: v for k, v in os.environ.items() if k not in scheduling.BLAS_THREAD_VARIABLES}
    out = subprocess.run([sys.executable, '-c', _BLAS_CHILD], capture_output=True, text=True, check=True, env=env)
    result = json.loads(out.stdout)
    if os.cpu_count() > 1:   # with one core a BLAS starts single-threaded anyway: the limit would not show
        assert max(result['before']) > 1, result
    assert len(result['after']) >= 2 and set(result['after'].values()) == {1}, result


_EXPM_CHILD = '''
import signal, sys, time
import numpy as np
import scipy.linalg
from uh_runtime import scheduling
signal.alarm(%d)   # a livelocked child is ended by the kernel's SIGALRM (default action), whatever its priority
why = scheduling.set_realtime_priority(%d)
a = np.random.default_rng(0).normal(size=(5, 5))
start = time.monotonic()
for _ in range(20000):
    scipy.linalg.expm(a * 0.01)   # what a realtime controller's delay margin computes (delay_margin._plant)
print(why, time.monotonic() - start)
'''
#: bound on each child's life (s): the 20,000 products take 0.14 s on this 2-core machine; livelocked (two
#: SCHED_FIFO processes each busy-waiting for OpenBLAS workers that cannot run) they never ended in 15 s
EXPM_BOUND_S = 60


def test_two_realtime_processes_computing_scipys_expm_do_not_livelock_a_two_core_machine():
    """Before BLAS was single-threaded under SCHED_FIFO, two such processes spun at 100 % CPU until killed."""
    if scheduling.permitted(PRIORITY) is not None:
        pytest.skip('SCHED_FIFO is not permitted here')
    children = [subprocess.Popen([sys.executable, '-c', _EXPM_CHILD % (EXPM_BOUND_S, PRIORITY)],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    for child in children:
        out, err = child.communicate(timeout=EXPM_BOUND_S + 30)
        assert child.returncode == 0, f'status {child.returncode} (-14: livelocked until SIGALRM) {err}'
        assert out.split()[0] == 'None', out


class _FakeKernel:
    """os's scheduling calls over a table of threads; the second thread refuses."""

    SCHED_OTHER, SCHED_FIFO = 0, 1

    def __init__(self):
        self.table = {101: (0, 0), 102: (0, 0), 103: (0, 0)}

    def sched_param(self, priority):
        return os.sched_param(priority)

    def sched_getscheduler(self, tid):
        return self.table[tid][0]

    def sched_getparam(self, tid):
        return os.sched_param(self.table[tid][1])

    def sched_setscheduler(self, tid, policy, param):
        if tid == 102 and policy == self.SCHED_FIFO:
            raise PermissionError(1, 'Operation not permitted')
        self.table[tid] = (policy, param.sched_priority)


def test_a_refusal_part_way_changes_no_thread(monkeypatch):
    kernel = _FakeKernel()
    monkeypatch.setattr(scheduling, 'os', kernel)
    monkeypatch.setattr(scheduling, 'single_threaded_blas', lambda: None)   # the fake kernel has no environment
    monkeypatch.setattr(scheduling, '_threads', lambda: sorted(kernel.table))
    why = scheduling.set_realtime_priority(PRIORITY)
    assert 'SCHED_FIFO priority 7 is not permitted' in why
    assert kernel.table == {101: (0, 0), 102: (0, 0), 103: (0, 0)}   # 101 was moved, then put back


def test_only_the_control_loop_nodes_of_a_realtime_run_are_given_the_priority():
    scenario = load_scenario('paper')

    def priorities(clock, priority):
        specs = node_specs(scenario, 'paper', 'proposed', clock, 1.0, 1.0, Path('bag'), 60.0,
                           realtime_priority=priority)
        return {kind: [a for a in args if a.startswith('realtime_priority:=')] for _, kind, args in specs}
    given = priorities('realtime', PRIORITY)
    for kind, args in given.items():
        assert args == ([] if NODES[kind].infrastructure else [f'realtime_priority:={PRIORITY}']), kind
    assert set(given) >= {'clock', 'sim', 'controller', 'virtual_leader', 'recorder', 'visualization'}
    assert all(not args for args in priorities('lockstep', PRIORITY).values())   # lockstep needs no deadline
    assert all(not args for args in priorities('realtime', 0).values())


def _process_policies(pid: int) -> set:
    return {scheduling.policy_of(int(tid)) for tid in os.listdir(f'/proc/{pid}/task')}


def test_a_realtime_run_puts_the_control_loop_under_sched_fifo_and_not_the_recorder(tmp_path, domain_id):
    out = tmp_path / 'run'
    proc = start_run(out, domain_id, '--clock', 'realtime', '--duration', '30', '--no-metrics',
                     '--realtime-priority', str(PRIORITY))
    permitted = scheduling.permitted(PRIORITY) is None
    try:
        wait_for_log(out / 'logs' / 'clock.log', 'realtime run of', proc, timeout=120)
        pids = json.loads((out / 'run.json').read_text())['pids']
        policies = {name: _process_policies(pid) for name, pid in pids.items()}
        assert json.loads((out / 'run.json').read_text())['realtime_priority'] == (PRIORITY if permitted else 0)
    finally:
        stop_run(proc)
    output = proc.stdout.read()
    loop = [n for n in pids if n not in ('recorder', 'visualization')]
    # 5 simulators, 5 controllers, the virtual leader, the clock and the safety filter's sensing node (on by default)
    assert len(loop) == 13 and 'sensing' in loop
    if permitted:
        assert f'real-time scheduling: SCHED_FIFO priority {PRIORITY} for the clock' in output
        for name in loop:   # every thread: the node's and the DDS receive threads
            assert policies[name] == {('fifo', PRIORITY)}, name
            assert f'real-time scheduling: SCHED_FIFO priority {PRIORITY}' in (out / 'logs' / f'{name}.log').read_text()
    else:
        assert 'real-time scheduling not available' in output and 'not permitted' in output
        for name in loop:
            assert {p for p, _ in policies[name]} == {'other'}, name
    for name in ('recorder', 'visualization'):   # they move data for people: normal priority
        assert {p for p, _ in policies[name]} == {'other'}, name


def test_a_bad_priority_is_refused_before_anything_starts(tmp_path):
    out = tmp_path / 'run'
    run = subprocess.run([str(Path(__file__).resolve().parents[1] / 'scripts' / 'run_formation.sh'),
                          '--clock', 'realtime', '--realtime-priority', '99', '--out', str(out)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    assert '--realtime-priority 99: allowed 0 (normal scheduling) .. 98' in run.stderr
    assert not out.exists()


_UNPRIVILEGED = ['setpriv', '--bounding-set=-sys_nice', '--inh-caps=-sys_nice', 'prlimit', '--rtprio=0']


def _can_drop_the_permission() -> str | None:
    import shutil
    if os.geteuid() != 0:
        return 'needs root, to take CAP_SYS_NICE away from a child'
    if not (shutil.which('setpriv') and shutil.which('prlimit')):
        return 'needs setpriv and prlimit (util-linux)'
    return None


@pytest.mark.skipif(_can_drop_the_permission() is not None, reason=str(_can_drop_the_permission()))
def test_without_the_permission_a_run_and_a_node_say_why_and_go_on(tmp_path, domain_id, processes):
    """No CAP_SYS_NICE, rtprio limit 0: the run says so once and runs at normal priority.

    A node asked for the priority directly (as the launch file asks) logs why it did not get it and runs.
    """
    from uh_runtime.network import loopback_environment
    out = tmp_path / 'run'
    run = subprocess.run([*_UNPRIVILEGED, str(Path(__file__).resolve().parents[1] / 'scripts' / 'run_formation.sh'),
                          '--out', str(out), '--domain-id', str(domain_id), '--clock', 'realtime', '--duration', '1',
                          '--no-metrics', '--realtime-priority', str(PRIORITY)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    assert (f'real-time scheduling not available, the control loop runs at normal priority and may miss steps '
            f'on a busy machine: SCHED_FIFO priority {PRIORITY} is not permitted (this user\'s rtprio limit is 0)'
            in run.stderr)
    assert json.loads((out / 'run.json').read_text())['realtime_priority'] == 0

    node = processes.start([*_UNPRIVILEGED, sys.executable, '-P', '-m', 'uh_sim_node.virtual_leader_node',
                            '--ros-args', '-p', 'clock_mode:=realtime', '-p', f'realtime_priority:={PRIORITY}'],
                           env=loopback_environment(domain_id), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)   # stopped at teardown, whatever the outcome
    lines = []

    def read():
        for line in node.stdout:
            lines.append(line)
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    deadline = time.monotonic() + 60   # bounds a failure only; the node logs it within its start-up
    while not any('real-time scheduling' in line for line in lines) and time.monotonic() < deadline:
        time.sleep(0.1)
    said = [line for line in lines if 'real-time scheduling' in line]
    assert said and 'real-time scheduling not used, the node runs at normal priority' in said[0], lines
    assert node.poll() is None   # and it runs on


def test_a_respawned_process_starts_under_sched_fifo_a_first_start_does_not(tmp_path):
    """A restarted controller's start-up (imports, discovery) competes with a team already under SCHED_FIFO.

    The supervisor starts it under the run's priority from its first instruction.
    """
    from uh_bringup.supervisor import Supervisor
    sup = Supervisor(tmp_path / 'logs', dict(os.environ), respawn_priority=PRIORITY)
    show = [sys.executable, '-c',
            'import os; print("policy", os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)']
    node = sup.start('probe', show)
    node.proc.wait(timeout=60)
    sup.respawn(node)
    node.proc.wait(timeout=60)
    first, again = [line for line in node.log_path.read_text().splitlines() if line.startswith('policy')]
    assert first == f'policy {os.SCHED_OTHER} 0'
    if scheduling.permitted(PRIORITY) is None:
        assert again == f'policy {os.SCHED_FIFO} {PRIORITY}'
    else:   # not permitted: the restart still happens, at normal priority
        assert again == f'policy {os.SCHED_OTHER} 0'


def test_nodes_get_sigint_even_from_a_supervisor_that_ignores_it(tmp_path):
    """A run started in the background by a script has SIGINT ignored (the shell does that).

    Children inherit an ignored signal; the supervisor stops its nodes with SIGINT, so it gives them the default back.
    """
    from uh_bringup.supervisor import Supervisor
    show = [sys.executable, '-c', 'import signal; print("sigint", signal.getsignal(signal.SIGINT).__name__)']
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)   # as under `run_formation.sh ... &`
    try:
        sup = Supervisor(tmp_path / 'logs', dict(os.environ))
        node = sup.start('probe', show)
        node.proc.wait(timeout=60)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert 'sigint default_int_handler' in node.log_path.read_text()
