"""Process supervision for a run: start node processes, watch them, stop them all, always.

Every node runs as its own process in its own process group, with stdout/stderr in
``logs/<name>.log``. :class:`Supervisor` stops every process it started when the run ends, when a
node fails, on Ctrl-C/SIGTERM and when the supervisor itself raises: SIGINT first (nodes shut down
cleanly, the recorder finalises its bag), SIGKILL after a grace period. No orphans.
"""
from __future__ import annotations

import os
import signal
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ['NodeProcess', 'Supervisor', 'NodeFailure']


class NodeFailure(RuntimeError):
    """A node process exited while the run still needed it."""

    def __init__(self, node: 'NodeProcess'):
        self.node = node
        super().__init__(f'node {node.name} exited with status {node.returncode} '
                         f'(log: {node.log_path}):\n{node.log_tail()}')


@dataclass
class NodeProcess:
    name: str
    cmd: list
    log_path: Path
    proc: subprocess.Popen | None = None
    returncode: int | None = None

    def log_tail(self, lines: int = 15) -> str:
        try:
            text = self.log_path.read_text(errors='replace').splitlines()
        except OSError:
            return '(no log)'
        return '\n'.join('    ' + line for line in text[-lines:])

    def poll(self) -> int | None:
        if self.proc is not None and self.returncode is None:
            self.returncode = self.proc.poll()
        return self.returncode


@dataclass
class Supervisor:
    log_dir: Path
    env: dict
    nodes: list = field(default_factory=list)
    grace_s: float = 15.0

    def start(self, name: str, cmd: list) -> NodeProcess:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        node = NodeProcess(name, [str(c) for c in cmd], self.log_dir / f'{name}.log')
        log = open(node.log_path, 'w')
        try:
            node.proc = subprocess.Popen(node.cmd, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                         env=self.env, start_new_session=True)
        finally:
            log.close()
        self.nodes.append(node)
        return node

    def failed(self, ignore=()) -> NodeProcess | None:
        """The first node that exited with a non-zero status (or at all, unless in ``ignore``)."""
        for node in self.nodes:
            if node.poll() is not None and node.name not in ignore:
                return node
        return None

    def signal_all(self, sig) -> None:
        for node in self.nodes:
            if node.poll() is None:
                try:
                    os.killpg(node.proc.pid, sig)
                except ProcessLookupError:
                    pass

    def stop_all(self, last=()) -> dict:
        """SIGINT every running node (the ``last`` ones after the others have ended), wait, then
        SIGKILL what is left; return the exit codes by node name."""
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
