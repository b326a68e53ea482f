"""Shared fixtures: a private DDS domain per test, processes that are always cleaned up."""
import os
import signal
import subprocess
from pathlib import Path

import pytest

from uh_runtime.network import loopback_environment, release_domain_id, reserve_domain_id

ROOT = Path(__file__).resolve().parents[1]

# The tests stop the nodes they start with SIGINT, as Ctrl-C does. A test session started in the
# background by a non-interactive shell (`scripts/test.sh > log &` in a script) has SIGINT ignored,
# and every process it starts would inherit that and never stop: give the session SIGINT back.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def domain_id(monkeypatch):
    """Reserve a DDS domain id no other test, pytest session, benchmark or run on this machine holds.

    The id comes from :func:`uh_runtime.network.reserve_domain_id`, with loopback config; ROS_DOMAIN_ID and
    CYCLONEDDS_URI are set for this process and its children. Released after the test.
    """
    dom = reserve_domain_id()
    for key, value in loopback_environment(dom).items():
        if os.environ.get(key) != value:
            monkeypatch.setenv(key, value)
    yield dom
    release_domain_id(dom)


@pytest.fixture
def processes():
    """Start child processes with ``processes.start(cmd, **popen_kwargs)``; all are killed at teardown."""
    started = []

    class _Starter:
        def start(self, cmd, **kwargs):
            kwargs.setdefault('start_new_session', True)
            proc = subprocess.Popen(cmd, **kwargs)
            started.append(proc)
            return proc

    yield _Starter()
    for proc in started:
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
    for proc in started:
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
