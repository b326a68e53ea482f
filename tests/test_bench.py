"""The benchmark harness (benchmarks/uh_bench) and the team generator it uses: a smoke test with tiny runs.

Nothing here is timed: the assertions are about what the harness records, not how fast.
"""
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from uh_topology.generate import LINK_EVERY, GenerateError, split_team, team_mapping, write_team_scenario
from uh_topology.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'benchmarks'))

from uh_bench import inprocess, probe, runs, suite  # noqa: E402


# -- generated teams ------------------------------------------------------------------------------
@pytest.mark.parametrize('size, expected', [(5, (2, 3)), (10, (4, 6)), (20, (8, 12)), (40, (16, 24)), (2, (1, 1))])
def test_split_team_keeps_the_followers_per_leader_between_one_and_three(size, expected):
    n, m = split_team(size)
    assert (n, m) == expected
    assert 1.0 <= m / n <= 3.0


def test_split_team_rejects_a_team_without_a_follower():
    with pytest.raises(GenerateError, match='team size must be an integer >= 2'):
        split_team(1)


def test_team_mapping_rejects_zero_leaders_and_odd_durations():
    with pytest.raises(GenerateError, match='number of leaders must be an integer >= 1'):
        team_mapping(0, 3)
    with pytest.raises(GenerateError, match=r'duration 1\.005 s is not a whole number of control periods dt = 0\.01 s'):
        team_mapping(2, 3, duration=1.005)


@pytest.mark.parametrize('size', [5, 40])
def test_generated_team_is_valid_with_the_requested_graph(tmp_path, size):
    n, m = split_team(size)
    sc = load_scenario(write_team_scenario(tmp_path / 'team.yaml', n, m, duration=2.0))
    assert tuple(sc.leaders) == tuple(range(1, n + 1))
    assert tuple(sc.followers) == tuple(range(n + 1, n + m + 1))
    for i in sc.leaders:   # a directed ring: leader i hears leader i-1 (1 hears N), nobody else
        assert tuple(sc.neighbours(i)) == (n if i == 1 else i - 1,)
        assert (sc.leader_link(i) > 0) == ((i - 1) % LINK_EVERY == 0)
    for k in sc.followers:  # two leaders and one follower
        heard = tuple(sc.neighbours(k))
        assert sum(j in sc.leaders for j in heard) == 2
        assert sum(j in sc.followers for j in heard) == 1
    w = np.asarray(sc.containment_weights)
    # convex weights: the topology checks guarantee them; 1e-12 is rounding of a small solve
    assert np.all(w >= -1e-12) and np.allclose(w.sum(axis=1), 1.0, atol=1e-12)
    bundled = load_scenario('paper')
    assert sc.gains_path == bundled.gains_path  # the paper gains, by absolute path
    assert sc.gains == bundled.gains


# -- pieces of the harness ----------------------------------------------------------------------
def test_probe_summary_counts_latency_late_and_missed_steps():
    ms = 1_000_000
    states = {0: 0, 1: 10 * ms, 2: 20 * ms, 3: 30 * ms}
    # command 0 one ms after its state; command 1 after state 2 was written (late); none for step 2
    commands = {0: 1 * ms, 1: 21 * ms, 3: 32 * ms}
    s = probe.summarise(states, commands, last_step=3)
    assert s['samples'] == 3
    assert s['late_steps'] == 1 and s['late_first'] == [1]
    assert s['missed_steps'] == 1 and s['missed_first'] == [2]
    assert s['p50_us'] == 2000.0 and s['max_us'] == 11000.0


def test_run_complete_line_is_parsed():
    text = ('[INFO] [1.0] [clock]: step 600/6000: sim 6.00 s, wall 1.00 s, real-time factor 6.00\n'
            '[INFO] [2.0] [clock]: run complete: 6000 steps, sim 60.00 s in 20.19 s wall (real-time factor 2.97)\n')
    assert runs.parse_run_complete(text) == (6000, 60.0, 20.19, 2.97)
    assert runs.parse_run_complete('nothing here') is None


def test_component_costs_and_reference_rtf_are_positive():
    costs = inprocess.component_costs('paper', steps=5)
    assert costs['uhs'] == 5 and costs['steps'] == 5
    for part in ('controller', 'model', 'fault_truth'):
        assert costs[part]['mean_us'] > 0 and costs[part]['median_us'] > 0
    ref = inprocess.reference_rtf('paper', duration=0.05)
    assert ref['finite'] and ref['rtf'] > 0 and ref['uhs'] == 5


@pytest.mark.dds
@pytest.mark.slow
def test_tiny_suite_records_every_section_and_prints_the_table(tmp_path, domain_id):
    cfg = {'transport_quick': True, 'paper_duration': 0.2, 'paper_layouts': ('single',), 'component_steps': 5,
           'scaling_sizes': (3,), 'scaling_duration': 0.2, 'scaling_layouts': ('single',),
           'realtime_duration': 0.5, 'realtime_runs': ((5, 'single'),)}
    results = suite.run_suite(cfg, tmp_path)
    paper = results['paper']['lockstep']['single']
    assert paper['status'] == 0, paper.get('error')
    assert paper['steps'] == 20 and paper['rtf'] > 0
    # one composed process runs every node of the team and reports them
    assert paper['n_processes'] == 1
    nodes = set(paper['processes'][0]['nodes'])
    assert {'/clock', '/recorder', '/uh1/sim', '/uh5/controller'} <= nodes
    assert paper['cpu_s'] > 0 and paper['memory']['max_kb'] > 10_000
    row = results['scaling'][0]
    assert (row['uhs'], row['leaders'], row['followers']) == (3, 1, 2)
    assert row['lockstep']['single']['status'] == 0 and row['inprocess']['rtf'] > 0
    rt_run = results['realtime'][0]
    assert rt_run['status'] == 0, rt_run.get('error')
    assert set(rt_run['controllers']) == {'1', '2', '3', '4', '5'}
    assert all(c['samples'] > 0 for c in rt_run['controllers'].values())
    text = suite.markdown(results)
    assert results['transport']['inprocess']['received'] > 0
    assert results['transport']['dds']['echo_cpu_us_per_message'] >= 0
    for heading in ('### Cost of one message', '### Paper scenario', '### Per-step cost in process',
                    '### Scaling, lockstep', '### Real time, rate 1', '### Goals'):
        assert heading in text
    json.dumps(results, default=str)  # the results file is plain JSON


@pytest.mark.dds
@pytest.mark.slow
def test_backends_section_measures_the_dds_backend_and_says_why_rclpy_is_not(tmp_path, monkeypatch):
    monkeypatch.delenv('UH_BACKEND', raising=False)
    # one contention run (at normal priority) checks the wiring; tests/test_scheduling.py checks SCHED_FIFO
    cfg = {'backend_lockstep_duration': 0.2, 'backend_realtime_duration': 0.5, 'executor_messages': 200,
           'contention_runs': ('normal',)}
    results = suite.run_suite(cfg, tmp_path, sections=('backends',))
    section = results['backends']
    lock, realtime = section['lockstep']['dds'], section['realtime']['dds']
    assert lock['status'] == 0 and lock['steps'] == 20 and lock['cpu_us_per_step'] > 0
    assert realtime['status'] == 0 and realtime['controller_steps'] > 0
    row = next(line for line in suite.markdown(results).splitlines() if line.startswith('| dds |'))
    assert row.endswith('| exit 0 |')
    by_case = {e['case']: e for e in section['executors']}
    assert by_case['dds']['messages'] >= 200 and by_case['dds']['cpu_us_per_message'] > 0
    # real time again while busy processes want every core
    busy = section['contention']
    assert busy['busy_processes'] == (os.cpu_count() or 1) + 1
    assert list(busy['runs']) == ['dds/normal']
    normal = busy['runs']['dds/normal']
    assert normal['status'] == 0 and normal['controller_steps'] > 0
    assert normal['priority'] == 0 and not normal['priority_granted']
    assert json.loads((Path(normal['out']) / 'run' / 'run.json').read_text())['realtime_priority'] == 0
    assert 'Real time on a busy machine' in suite.markdown(results)
    if suite.rclpy_available() is None:      # a sourced ROS 2: both measured, the ratio printed
        assert set(section['lockstep']) == {'dds', 'rclpy'}
        assert section['lockstep']['rclpy']['steps'] == 20 and section['realtime']['rclpy']['status'] == 0
        assert set(by_case) == {'dds', 'rclpy', 'rclpy-static'}
        assert 'rclpy / DDS backend' in suite.markdown(results)
    else:
        assert set(section['lockstep']) == {'dds'} and 'rclpy is not importable' in section['skipped_rclpy']
        assert set(by_case) == {'dds'}
        assert 'rclpy not measured' in suite.markdown(results)


def test_the_harness_gives_back_the_domain_ids_it_took(tmp_path, monkeypatch):
    """A benchmark run inside a test session must not keep a DDS domain id reserved after it.

    The next test that needs that id would find it held.
    """
    from uh_runtime import network
    monkeypatch.setattr(runs.subprocess, 'Popen', lambda *a, **k: (_ for _ in ()).throw(OSError('no supervisor')))
    held_before = dict(network._held)
    with pytest.raises(runs.RunError, match='cannot start the run supervisor'):
        runs.run_team('paper', tmp_path / 'run')
    assert network._held == held_before
