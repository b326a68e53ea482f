"""Bad messages on a running team (real processes over DDS).

Invalid fault injections, states and commands carrying NaN/inf or another UH's id. Each is
rejected by its receiver with the reason in its log, the receiver keeps its last valid input, the
plant keeps running, nothing is taken down, and the bag stays complete.
"""
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from team_runs import start_run, wait_for_log

from uh_report.bag_metrics import read_team_bag
from uh_runtime.network import reserve_domain_id
from uh_topology.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
ROGUE = ROOT / 'tests' / 'data' / 'reliability_rogue_publisher.py'

pytestmark = [pytest.mark.dds, pytest.mark.slow]

DURATION = 14.0  # s simulated, realtime at rate 1: long enough for the rogue and inject_fault to join


@pytest.fixture(scope='module')
def rogue_run(tmp_path_factory):
    out = tmp_path_factory.mktemp('rogue') / 'run'
    domain = reserve_domain_id()
    proc = start_run(out, domain, '--clock', 'realtime', '--duration', str(DURATION))
    try:
        wait_for_log(out / 'logs' / 'clock.log', 'team complete', proc, timeout=120)
        from uh_runtime.network import loopback_environment
        # both at once, so that both are done well within the run on a loaded machine
        started = [subprocess.Popen([sys.executable, str(ROGUE)], env=loopback_environment(domain),
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True),
                   subprocess.Popen([str(ROOT / 'scripts' / 'inject_fault.sh'), '--domain-id', str(domain),
                                     '--uh', '9', '--channel', 'collective', '--rho', '0.5'],
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)]
        rogue, unknown = (_finished(p) for p in started)
        output, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait(timeout=60)
    return out, proc.returncode, output, rogue, unknown


def _finished(proc: subprocess.Popen) -> subprocess.CompletedProcess:
    stdout, stderr = proc.communicate(timeout=60)
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)


def _log(out: Path, node: str) -> str:
    return (out / 'logs' / f'{node}.log').read_text(errors='replace')


def test_rogue_messages_were_sent_while_the_team_ran(rogue_run):
    out, code, output, rogue, _ = rogue_run
    assert rogue.returncode == 0 and 'sent' in rogue.stdout, rogue.stderr
    # nothing was taken down: the run ends normally, every node with status 0
    assert code == 0, output
    info = json.loads((out / 'run.json').read_text())
    assert info['node_failures'] == [] and set(info['exit_codes'].values()) == {0}, info


@pytest.mark.parametrize('message', [
    # each invalid injection: the reason, and that the plant goes on with its current faults
    r'rejected fault injection: fault rho \(effectiveness\) must be in \[0, 1\], got 1\.5 on channel 0 '
    r'\(theta_col\); the plant keeps its current faults',
    r"rejected fault injection: fault parameter 'bias_constant' must be finite, got nan; the plant keeps",
    r'rejected fault injection: fault channel must be an int in 0\.\.3 .*got 7; the plant keeps',
    r'rejected fault injection: it names uh3 but arrived on /uh1/fault; the plant keeps its current faults',
    # rho = 0 is accepted, with the warning that no controller compensates a stuck actuator
    r'rho = 0 on channel 0: the actuator is stuck, which is outside what the controller can compensate',
    # the infinite command: rejected, the last valid command kept
    r'rejected command: command of uh1 at step 100 carries a non-finite value .*; keeping the last valid command',
])
def test_simulator_rejects_with_the_reason(rogue_run, message):
    import re
    out = rogue_run[0]
    assert re.search(message, _log(out, 'uh1_sim')), _log(out, 'uh1_sim')[-3000:]


def test_clock_counts_a_command_by_its_topic_never_as_another_uhs(rogue_run):
    out = rogue_run[0]
    assert 'ignored a command carrying uh_id 9 on the command topic of uh1' in _log(out, 'clock')


@pytest.mark.parametrize('node, message', [
    ('uh2_controller', r'rejected own state: state of uh2 at step 100 carries a non-finite value'),
    ('uh3_controller', r'rejected state of uh2: state of uh2 at step 100 carries a non-finite value'),
    ('uh4_controller', r'rejected state of uh2: state of uh2 at step 100 carries a non-finite value'),
    ('uh3_controller', r'rejected state of uh2: state message carries uh_id 9, expected 2'),
])
def test_controllers_reject_with_the_reason(rogue_run, node, message):
    import re
    out = rogue_run[0]
    # errors are rate-limited to one line a second per input; the count is in the shutdown summary
    text = _log(out, node)
    assert re.search(message, text) or 'rejected inputs: ' in text, text[-3000:]
    assert re.search(r'rejected inputs: .*state', text), text[-2000:]


def test_inject_fault_names_a_uh_the_running_team_lacks(rogue_run):
    unknown = rogue_run[4]
    assert unknown.returncode == 2
    assert 'inject_fault.sh: error: --uh 9: the team running in DDS domain' in unknown.stderr
    assert 'has no UH 9; its UHs: 1, 2, 3, 4, 5' in unknown.stderr


def test_plant_kept_running_and_the_bag_is_complete(rogue_run):
    out = rogue_run[0]
    paper = load_scenario('paper')
    meta = yaml.safe_load((out / 'bag' / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['message_count'] > 0   # finalised by the recorder on SIGINT
    bag = read_team_bag(out / 'bag', paper)
    # the recorder keeps what was on the wire; the reader leaves out what the receivers rejected
    assert bag['rejected'] == {'/uh2/state': 2, '/uh1/command': 2}
    last = int(round(DURATION / paper.dt))
    # UH1 (whose simulator got every bad injection and the bad command) flew to the end with
    # finite states, and its faults are the scenario's: it is healthy, so its true fault stays 0
    states = bag['states'][:, 0]
    recorded = ~np.isnan(states[:, 0])
    assert recorded[last] and np.isfinite(states[recorded]).all()
    assert np.nanmax(np.abs(bag['fault_true_p'][:, 0])) == 0.0
    # and it kept flying near the formation: its altitude never left the 6..14 m band
    assert 6.0 < np.nanmin(states[:, 2]) and np.nanmax(states[:, 2]) < 14.0
