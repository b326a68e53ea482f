"""Shared fixtures: a private DDS domain per test, processes that are always cleaned up."""
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from uh_runtime.network import loopback_environment, release_domain_id, reserve_domain_id

ROOT = Path(__file__).resolve().parents[1]
#: The secure tier's fixtures (only_in_the_secure_tier, secure_domain).
pytest_plugins = ('helpers_security.tier',)

# The tests stop the nodes they start with SIGINT, as Ctrl-C does. A test session started in the
# background by a non-interactive shell (`scripts/test.sh > log &` in a script) has SIGINT ignored,
# and every process it starts would inherit that and never stop: give the session SIGINT back.
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope='module')
def paper():
    """Load the bundled paper scenario, once per test module."""
    from uh_topology.scenario import load_scenario
    return load_scenario('paper')


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


#: Every first-party Python package (a top-level folder ``uh_*`` holding a package of its name).
FIRST_PARTY = sorted(d.name for d in ROOT.glob('uh_*') if (d / d.name / '__init__.py').is_file())


def pytest_sessionfinish(session, exitstatus):
    """Check that the quick tier (``scripts/test.sh --quick``) still exercises every package.

    The tier deselects the DDS and slow tests; the rest run in this process, so a package no quick
    test imports is a package the tier does not cover. Checked only for the whole tier (no file or
    keyword selection), and only when it passed.
    """
    if os.environ.get('UH_TEST_TIER') != 'quick' or exitstatus != 0:
        return
    if session.config.args not in ([], [str(ROOT / 'tests')], ['tests']) or session.config.getoption('keyword'):
        return
    missing = [pkg for pkg in FIRST_PARTY if pkg not in sys.modules]
    if missing:
        session.config.get_terminal_writer().line(
            f'quick tier: no quick test imports {", ".join(missing)}: add a fast test for it', red=True)
        session.exitstatus = 1
