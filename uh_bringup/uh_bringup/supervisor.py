"""Process supervision for a run: start node processes, watch them, restart or stop them, always clean up.

Every node runs as its own process in its own process group, with stdout/stderr in
``logs/<name>.log``. :class:`Supervisor` stops every process it started when the run ends, when a
node fails, on Ctrl-C/SIGTERM and when the supervisor itself raises: SIGINT first (nodes shut down
cleanly, the recorder finalises its bag), SIGKILL after a grace period. No orphans.

A node that exits while the run still needs it is reported once by :meth:`Supervisor.exited`
(with how it ended: exit status or signal); the caller decides whether the run goes on, and may
:meth:`Supervisor.respawn` it (like ``respawn=True`` of a ROS 2 launch file): the same command is
started again and its output appended to the same log, after a marker line.
"""
from __future__ import annotations

import os
import signal
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

from uh_runtime.runner import SUPERVISOR_ENV

__all__ = ['NodeProcess', 'Supervisor', 'NodeFailure', 'describe_exit']


def describe_exit(returncode: int | None) -> str:
    """Return ``'exited with status 1'``, ``'killed by SIGKILL'`` or ``'running'``."""
    if returncode is None:
        return 'running'
    if returncode < 0:
        try:
            return f'killed by {signal.Signals(-returncode).name}'
        except ValueError:
            return f'killed by signal {-returncode}'
    return f'exited with status {returncode}'


class NodeFailure(RuntimeError):
    """A node process exited while the run still needed it."""

    def __init__(self, node: 'NodeProcess'):
        self.node = node
        super().__init__(f'node {node.name} {describe_exit(node.returncode)} '
                         f'(log: {node.log_path}):\n{node.log_tail()}')


@dataclass
class NodeProcess:
    """One supervised process.

    Its name, node kind (``sim``, ``controller``, ... or the kind that decides for a group of
    nodes), command, log, the running ``Popen`` and its exit status.
    """

    name: str
    cmd: list
    log_path: Path
    kind: str = ''
    proc: subprocess.Popen | None = None
    returncode: int | None = None
    restarts: int = 0
    reported: bool = False
    pids: list = field(default_factory=list)

    def log_tail(self, lines: int = 15) -> str:
        """Return the last ``lines`` lines of the process's log, indented by 4 spaces (``(no log)`` if unreadable)."""
        try:
            text = self.log_path.read_text(errors='replace').splitlines()
        except OSError:
            return '(no log)'
        return '\n'.join('    ' + line for line in text[-lines:])

    def poll(self) -> int | None:
        """Return the exit status (None while it runs; negative: killed by that signal), noting it once known."""
        if self.proc is not None and self.returncode is None:
            self.returncode = self.proc.poll()
        return self.returncode

    def describe(self) -> str:
        """Return how the process is: ``running``, ``exited with status N`` or ``killed by SIGNAME``."""
        return describe_exit(self.poll())


def _child_setup(priority: int):
    """Return the ``preexec_fn`` of a node process, run in the child before its command.

    * SIGINT back to its default: the supervisor stops nodes with SIGINT, and a supervisor started
      in the background by a non-interactive shell (``run_formation.sh ... &`` in a script) has
      SIGINT ignored, which a child would inherit and keep (Python leaves an ignored SIGINT alone).
    * ``priority`` > 0: SCHED_FIFO at that priority from the first instruction (respawns). The
      parameter is made here, so the child only makes system calls.
    """
    param = os.sched_param(priority) if priority > 0 else None

    def setup():
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        if param is not None:
            try:
                os.sched_setscheduler(0, os.SCHED_FIFO, param)
            except OSError:
                pass    # not permitted: the node starts at normal priority and says so itself
    return setup


@dataclass
class Supervisor:
    """Starts, restarts and stops the node processes of one run (see the module docstring).

    Parameters
    ----------
    log_dir : Path
        Directory of the processes' logs (``<name>.log``), created on the first start.
    env : dict
        Environment of every process (a process in ``envs`` gets its own instead).
    nodes : list of NodeProcess
        The processes started so far, in start order.
    grace_s : float
        Seconds :meth:`stop_all` waits after SIGINT before it sends SIGKILL.
    """

    log_dir: Path
    env: dict
    nodes: list = field(default_factory=list)
    grace_s: float = 15.0
    #: per-process command prefix (e.g. ``ip netns exec NS``): name -> list
    prefix: dict = field(default_factory=dict)
    #: per-process environment replacing ``env``: name -> dict
    envs: dict = field(default_factory=dict)
    #: SCHED_FIFO priority a respawned process runs under from its first instruction (0: none).
    #: Its start-up (imports, DDS discovery) competes with a running team whose control loop is
    #: under SCHED_FIFO itself (docs/reliability.md#2-node-failures-realtime)
    respawn_priority: int = 0

    def _popen(self, node: NodeProcess, mode: str) -> None:
        log = open(node.log_path, mode)
        try:
            if mode == 'a':
                log.write(f'---- {time.strftime("%H:%M:%S")} respawned ({node.restarts}) after the process '
                          f'{describe_exit(node.returncode)} ----\n')
                log.flush()
            # the node ends with this process even if it is killed (uh_runtime.runner.end_with_supervisor)
            env = {**self.envs.get(node.name, self.env), SUPERVISOR_ENV: str(os.getpid())}
            node.proc = subprocess.Popen([*self.prefix.get(node.name, []), *node.cmd], stdout=log,
                                         stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=env,
                                         start_new_session=True,
                                         preexec_fn=_child_setup(self.respawn_priority if mode == 'a' else 0))
        finally:
            log.close()
        node.pids.append(node.proc.pid)
        node.returncode = None
        node.reported = False

    def start(self, name: str, cmd: list, kind: str = '') -> NodeProcess:
        """Start ``cmd`` as process ``name`` (its own process group, output to ``<log_dir>/<name>.log``).

        ``kind`` is the node kind (default: ``name``). Return its :class:`NodeProcess`.
        """
        self.log_dir.mkdir(parents=True, exist_ok=True)
        node = NodeProcess(name, [str(c) for c in cmd], self.log_dir / f'{name}.log', kind=kind or name)
        self._popen(node, 'w')
        self.nodes.append(node)
        return node

    def respawn(self, node: NodeProcess) -> NodeProcess:
        """Start ``node``'s command again (it must have exited); output goes on in the same log."""
        if node.poll() is None:
            raise RuntimeError(f'node {node.name} is still running')
        node.restarts += 1
        self._popen(node, 'a')
        return node

    def exited(self, ignore=()) -> list:
        """Nodes (not in ``ignore``) that exited since the last call, each reported once."""
        out = []
        for node in self.nodes:
            if node.name not in ignore and not node.reported and node.poll() is not None:
                node.reported = True
                out.append(node)
        return out

    def failed(self, ignore=()) -> NodeProcess | None:
        """Return the first node that exited (unless in ``ignore``)."""
        for node in self.nodes:
            if node.poll() is not None and node.name not in ignore:
                return node
        return None

    def signal_all(self, sig) -> None:
        """Send ``sig`` to the process group of every process still running."""
        for node in self.nodes:
            if node.poll() is None:
                try:
                    os.killpg(node.proc.pid, sig)
                except ProcessLookupError:
                    pass

    def stop_all(self, last=()) -> dict:
        """Stop every node; return the exit codes by node name.

        SIGINT every running node (the ``last`` ones after the others have ended), wait, then
        SIGKILL what is left.
        """
        for group in ([n for n in self.nodes if n.name not in last], [n for n in self.nodes if n.name in last]):
            for node in group:
                if node.poll() is None:
                    try:
                        os.killpg(node.proc.pid, signal.SIGINT)
                    except ProcessLookupError:
                        pass
            self._wait(group, self.grace_s)
        left = [n for n in self.nodes if n.poll() is None]
        if left:
            self.signal_all(signal.SIGKILL)
            self._wait(left, 5.0)
        return {n.name: n.poll() for n in self.nodes}

    @staticmethod
    def _wait(nodes, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        for node in nodes:
            if node.proc is None:
                continue
            try:
                node.proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
            node.poll()
