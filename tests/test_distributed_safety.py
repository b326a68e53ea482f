"""The safety filter on the nodes (docs/safety.md#on-the-nodes): scripts/run_formation.sh --safety on.

A lockstep run equals the in-process run to the bit, filter activity included; in real time the
filter keeps the rotors apart; each controller reads its own state, its Laplacian neighbours'
states, the reference if it hears it, and its own proximity input: nothing else.
"""
import json
import os
import signal
from pathlib import Path

import numpy as np
import pytest
from team_runs import controller_reads, kill_session, start_run, wait_for_log

from uh_core.airframe import load_helicopter_params
from uh_report.bag_metrics import read_team_bag
from uh_runtime.network import reserve_domain_id
from uh_team.team_simulation import run_team_simulation
from uh_topology.scenario import load_scenario

pytestmark = [pytest.mark.dds, pytest.mark.slow]

ROTOR_OVERLAP = 2.0 * load_helicopter_params('helicopter').rotor_radius      # 1.6 m
#: the paper team's closest approach (UH3, UH4, UH5) is at t = 2.3 s: 4 s cover it and the filter's work
DURATION = 4.0

#: 50 ms late, a third of the steps lost, 5 cm and 5 cm/s of noise on the proximity input
DEGRADED = ('safety: {proximity_delay_steps: 5, proximity_loss: 0.3, proximity_noise_position: 0.05,\n'
            '         proximity_noise_velocity: 0.05, proximity_seed: 3}\n')

# Who hears whom in the paper scenario, from docs/scenario.md, plus each UH's own proximity input.
PAPER_READS_WITH_FILTER = {
    1: {'/uh1/state', '/uh3/state', '/reference', '/uh1/proximity'},
    2: {'/uh2/state', '/uh1/state', '/uh2/proximity'},
    3: {'/uh3/state', '/uh2/state', '/uh3/proximity'},
    4: {'/uh4/state', '/uh1/state', '/uh2/state', '/uh5/state', '/uh4/proximity'},
    5: {'/uh5/state', '/uh3/state', '/uh4/state', '/uh5/proximity'},
}


def _lockstep_run(tmp_path, *args) -> tuple:
    """Run the team in lockstep for DURATION s with ``args``, to its end; return (output directory, output)."""
    out = tmp_path / 'run'
    proc = start_run(out, reserve_domain_id(), '--clock', 'lockstep', '--duration', str(DURATION), '--no-report',
                     *args)
    try:
        output, _ = proc.communicate(timeout=300)
    finally:
        kill_session(proc)
    assert proc.returncode == 0, output
    return out, output


def test_a_lockstep_run_with_degraded_sensing_equals_the_in_process_run_bit_for_bit(tmp_path):
    # the proximity input late, lossy and noisy (docs/safety.md#degraded-sensing): the controller nodes
    # degrade what the sensing node sends with the kernels the in-process loop degrades the true states with
    paper = Path(load_scenario('paper').source)
    (tmp_path / 'paper_gains.yaml').write_text((paper.parent / 'paper_gains.yaml').read_text())
    path = tmp_path / 'degraded.yaml'
    path.write_text(paper.read_text() + DEGRADED)
    scenario = load_scenario(path)
    out, _ = _lockstep_run(tmp_path, '--scenario', str(path))
    reference = run_team_simulation(scenario, 'proposed', duration=DURATION)
    assert reference.safety_active.sum() > 100          # the filter works in this window: a real test
    exact = run_team_simulation(load_scenario('paper'), 'proposed', duration=DURATION)
    assert not np.array_equal(reference.commands, exact.commands)   # ... and the degradation matters
    bag = read_team_bag(out / 'bag', scenario)
    assert np.array_equal(bag['states'], reference.states)
    assert np.array_equal(bag['commands'], reference.commands)
    assert np.array_equal(bag['safety_active'], reference.safety_active)
    metrics = json.loads((out / 'metrics.json').read_text())
    assert metrics['rotor_overlap_s'] == 0.0 and metrics['safety_active_s'] > 0
    assert json.loads((out / 'run.json').read_text())['safety'] == 'on'
    sensing = (out / 'logs' / 'sensing.log').read_text()
    steps = int(round(DURATION / scenario.dt)) + 1
    assert all(f'/uh{i}/proximity {steps}' in sensing for i in scenario.ids), sensing


def test_with_safety_off_the_nodes_fly_the_papers_law_bit_for_bit(tmp_path):
    out, output = _lockstep_run(tmp_path, '--safety', 'off')
    law = load_scenario('paper', safety=False)
    reference = run_team_simulation(law, 'proposed', duration=DURATION)
    bag = read_team_bag(out / 'bag', law)
    assert np.array_equal(bag['states'], reference.states)
    assert np.array_equal(bag['commands'], reference.commands)
    assert not bag['safety_active'].any()
    assert not (out / 'logs' / 'sensing.log').exists()          # no sensing node, no proximity topic
    assert json.loads((out / 'run.json').read_text())['safety'] == 'off'
    # ... and the law alone does let rotors touch, which the run says in its last line
    assert 'let rotors touch' in output.strip().splitlines()[-1]


def test_in_real_time_the_filter_keeps_the_rotors_apart_and_reads_only_its_own_proximity(tmp_path):
    out = tmp_path / 'run'
    domain = reserve_domain_id()
    proc = start_run(out, domain, '--clock', 'realtime', '--rate', '1', '--safety', 'on', '--duration', '8',
                     '--no-report')
    try:
        wait_for_log(out / 'logs' / 'clock.log', 'run of', proc, timeout=120)
        reads = controller_reads(domain, PAPER_READS_WITH_FILTER)
        output, _ = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
        kill_session(proc)
    assert reads == PAPER_READS_WITH_FILTER
    assert proc.returncode == 0, output
    metrics = json.loads((out / 'metrics.json').read_text())
    # real time: latest-value inputs, still the filter's guarantee (the in-process run keeps 1.78 m)
    assert metrics['min_separation_m'] >= ROTOR_OVERLAP, metrics['min_separation_m']
    assert metrics['safety_active_s'] > 0
