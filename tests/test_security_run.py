"""Secure team runs (``run_formation.sh --secure``, docs/security.md#flying-a-secure-team): the secure tier.

Each run is the run script itself, every node a process on ``.venv-secure`` with its own identity of a
keystore the run makes in ``OUT/keystore``. A lockstep secure run equals the in-process run to the bit,
and a packet capture of its domain shows none of the state and command values on the wire, while the
same run without ``--secure`` shows them (so the capture would see a leak). A realtime secure run
holds the formation.
"""
import json
import os
import shlex
import subprocess
from pathlib import Path

import numpy as np
import pytest
from helpers_security.capture import LoopbackCapture, can_capture, doubles
from helpers_security.tier import SECURE_PYTHON
from team_runs import first_difference, kill_session, start_run, wait_for_log

from uh_report.bag_metrics import read_team_bag
from uh_team.error_metrics import formation_errors
from uh_team.team_simulation import run_team_simulation

ROOT = Path(__file__).resolve().parents[1]
INJECT = ROOT / 'scripts' / 'inject_fault.sh'
#: Simulated seconds of the lockstep runs: 200 steps, each state and command written ~200 times per UH.
LOCKSTEP_S = 2.0
#: The realtime run: 15 s, judged over its last 5 s (the paper team holds its formation from about 4 s on,
#: in process 0.013-0.020 m; its first fault acts at 16 s, so the window is fault-free). Not from 7 s: in 3 of 6
#: whole secure tiers the leaders strayed up to 0.2 m between 4.5 and 6.5 s and were back by 8 s, which 30 runs
#: of the same command from a shell never did (not traced; docs/security.md#what-is-not-done).
REALTIME_S, WINDOW_S = 15.0, 5.0

pytestmark = [pytest.mark.secure, pytest.mark.dds, pytest.mark.usefixtures('only_in_the_secure_tier'), pytest.mark.slow,
              pytest.mark.skipif(not SECURE_PYTHON.exists(),
                                 reason=f'no secure virtualenv at {SECURE_PYTHON}: scripts/test.sh --secure builds it')]


def _run(out: Path, domain: int, *extra) -> str:
    proc = start_run(out, domain, *extra)
    try:
        output, _ = proc.communicate(timeout=300)
    finally:
        kill_session(proc)
    assert proc.returncode == 0, output
    return output


def _exports(env_sh: Path) -> dict:
    """Return the variables ``env.sh`` exports, as a shell that sources it has them."""
    done = subprocess.run(['bash', '-c', f'source {shlex.quote(str(env_sh))} && env -0'], capture_output=True,
                          check=True)
    return dict(item.split('=', 1) for item in done.stdout.decode().split('\0') if '=' in item)


def _known_values(reference) -> list:
    """Doubles of the run's states and commands that cannot occur by chance: not float32-round, not zero."""
    values = np.concatenate([reference.states[20::20].ravel(), reference.commands[20::20].ravel()])
    values = values[np.isfinite(values) & (values != 0) & (values.astype(np.float32).astype(float) != values)]
    return doubles(values)


@pytest.mark.parametrize('security', ['on', 'off'])
def test_a_secure_lockstep_run_equals_the_in_process_run_and_its_states_and_commands_are_encrypted(
        tmp_path, paper, secure_domain, security):
    """On: the bag equals the in-process run and no known double is on the wire; off: the doubles are there."""
    why_not = can_capture()
    if why_not:
        pytest.skip(why_not)
    out = tmp_path / 'run'
    capture = LoopbackCapture(secure_domain).start()
    try:
        output = _run(out, secure_domain, '--clock', 'lockstep', '--duration', f'{LOCKSTEP_S:g}', '--no-visualization',
                      '--no-metrics', *(['--secure'] if security == 'on' else []))
    finally:
        capture.stop()
    reference = run_team_simulation(paper, 'proposed', duration=LOCKSTEP_S)
    bag = read_team_bag(out / 'bag', paper)
    for name, expected in (('states', reference.states), ('commands', reference.commands)):
        assert np.array_equal(bag[name], expected), first_difference(name, bag[name], expected, paper.ids)
    known = _known_values(reference)
    seen = capture.find(known)
    # the capture saw the run's traffic: 200 steps of 5 states and 5 commands to several readers each
    # are more than 1 MB; 200 kB bounds a capture that missed the run
    assert capture.user_data_bytes() > 200_000, capture.user_data_bytes()
    info = json.loads((out / 'run.json').read_text())
    if security == 'on':
        assert info['keystore'] == str(out / 'keystore') and f'[run] keystore: {out / "keystore"}' in output
        assert not seen, f'{len(seen)} of {len(known)} state and command values in plaintext on the wire'
    else:
        assert info['keystore'] is None
        # most values are written in every step they hold: without encryption most are on the wire
        assert len(seen) > len(known) // 2, f'only {len(seen)} of {len(known)} values seen: the capture is blind'


def _inject(out: Path, domain: int, *how, env=None):
    """Run ``inject_fault.sh`` on the team of ``out`` (a fault whose onset is after the run: it changes nothing)."""
    return subprocess.run([str(INJECT), '--domain-id', str(domain), '--uh', '4', '--channel', 'collective', '--rho',
                           '0.7', '--onset', '1000', *how], capture_output=True, text=True, timeout=120,
                          env=env or os.environ)


def test_a_secure_realtime_run_holds_the_formation_and_only_the_operator_injects(tmp_path, paper, secure_domain):
    """RMS formation error of the leaders over the last 5 s <= 0.05 m (the issue's goal), largest < 0.10 m.

    The RMS is the metric ``formation_rms_m`` over that window; a late or missed tick on a loaded 2-core
    machine puts short spikes into the error (measured up to 0.051 m with RMS 0.021 m), so the largest
    sample is held to the 0.1 m bound of the realtime run of tests/test_distributed_run.py. While the team
    flies, ``inject_fault.sh --secure`` (the operator identity) injects a fault the simulator acknowledges,
    and the same with the read-only identity of the run's ``env.sh`` is refused.
    """
    out = tmp_path / 'run'
    # the default SCHED_FIFO priority, as a user flies it (one process per node: where OpenBLAS's busy wait once
    # livelocked two controllers, docs/performance.md#real-time-scheduling); kill_session's SIGKILL ends a hang
    proc = start_run(out, secure_domain, '--secure', '--clock', 'realtime', '--duration', f'{REALTIME_S:g}',
                     '--no-visualization', '--no-metrics')
    try:
        wait_for_log(out / 'logs' / 'clock.log', 'realtime run of', proc, timeout=120)
        operator = _inject(out, secure_domain, '--secure', '--keystore', str(out / 'keystore'))
        # a second terminal of a user: env.sh on a plain shell (the tier's own virtualenv variables dropped)
        plain = {k: v for k, v in os.environ.items() if k not in ('UH_VENV', 'UH_REQUIREMENTS', 'VIRTUAL_ENV')}
        inspect = dict(plain, **_exports(out / 'env.sh'))
        read_only = _inject(out, secure_domain, '--timeout', '3', env=inspect)
        output, _ = proc.communicate(timeout=300)
    finally:
        kill_session(proc)
    assert proc.returncode == 0, output
    assert operator.returncode == 0 and 'injected on /uh4/fault' in operator.stderr, operator.stderr
    assert inspect['ROS_SECURITY_ENCLAVE_OVERRIDE'] == '/tools/inspect'
    assert read_only.returncode != 0 and 'NOT_ALLOWED_BY_SECURITY' in read_only.stderr, read_only.stderr
    bag = read_team_bag(out / 'bag', paper)
    leaders = [paper.ids.index(i) for i in paper.leaders]
    errors = formation_errors(bag['states'][:, leaders, :3], bag['reference'][:, :3],
                              np.array([paper.offsets[i] for i in paper.leaders]))
    window = errors[bag['time'] >= REALTIME_S - WINDOW_S]
    # a step missing from the bag is a NaN row (seen once, in a SCHED_FIFO run on a loaded machine: all three
    # leaders' errors NaN at one step), so the window is judged over the steps recorded, at least 90 % of them
    window = window[np.isfinite(window).all(axis=1)]
    assert len(window) >= 0.9 * WINDOW_S / paper.dt, len(window)
    assert np.sqrt(np.mean(window ** 2)) <= 0.05, np.sqrt(np.mean(window ** 2))
    assert window.max() < 0.10, window.max()
