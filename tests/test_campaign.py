"""Campaigns run by uh-campaign.

Spec validation (file, line, key), reproducible draws, resolved scenarios that
re-run to the stored numbers, failure recording, resume after Ctrl-C, and a Dask cluster giving
the local pool's rows. Runs are short (12 s simulated, faults from 2-4 s so that the fault
estimation is scored) so the file stays well under a minute.
"""
import dataclasses
import math
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scenario_texts import paper_yaml
from team_runs import kill_session

from uh_campaign import cli
from uh_campaign.runner import run_campaign
from uh_campaign.spec import bundled_specs, load_spec, resolve_scenario, scenario_yaml
from uh_team import campaign_store as store
from uh_topology import errors as E

# 10 draws x 2 sweep values x 3 cases = 60 runs of 12 s (settle time: half of it)
REFERENCE_SPEC = """\
name: mc_test
scenario: paper
runs: 10
seed: 42
duration: 12.0
cases: [proposed, case1, case2]
draws:
  position_spread: 1.0
  attitude_spread: 0.05
  yaw_spread: 0.2
  faults:
    faulted_uhs: [1, 2]
    channels_per_uh: [1, 2]
    rho: [0.7, 0.95]
    bias_constant: [-0.01, 0.01]
    onset_time: [2.0, 4.0]
sweep: {parameter: model_mismatch, values: [0.9, 1.0]}
"""


def _write(directory: Path, text: str, name='spec.yaml') -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / name
    path.write_text(text)
    return path


def _rows(directory) -> dict:
    runs = store.read_runs(Path(directory) / store.DB_NAME)
    runs.pop('wall_time_s')
    return runs


def _assert_same_rows(a: dict, b: dict, draws=None):
    """Every column equal (NaN == NaN), optionally only for the draws < ``draws`` of ``a``."""
    if draws is not None:
        keep = a['draw'] < draws
        a = {k: v[keep] for k, v in a.items()}
    assert a.keys() == b.keys()
    for column in a:
        if a[column].dtype.kind == 'f':
            np.testing.assert_array_equal(a[column], b[column], err_msg=column)
        else:
            assert list(a[column]) == list(b[column]), column


@pytest.fixture(scope='module')
def reference(tmp_path_factory):
    """Run the reference campaign once on 2 local workers; give (spec path, campaign directory)."""
    base = tmp_path_factory.mktemp('reference')
    spec = _write(base, REFERENCE_SPEC)
    out = base / 'out'
    outcome = run_campaign(load_spec(spec), out, workers=2)
    assert (outcome.total, outcome.done, outcome.failures) == (60, 60, 0)
    return spec, out


# ----------------------------------------------------------------------------------------------
# Spec validation
# ----------------------------------------------------------------------------------------------
GOOD_HEAD = 'name: bad\nscenario: paper\nruns: 2\nduration: 4.0\n'       # lines 1-4


@pytest.mark.parametrize('tail, error, line, key', [
    ('runz: 3\n', E.UnknownKeyError, 5, 'runz'),
    ('seed: one\n', E.WrongTypeError, 5, 'seed'),
    ('cases: [proposed, case3]\n', E.InvalidValueError, 5, 'cases[1]'),
    ('draws:\n  faults:\n    rho: [0.0, 0.9]\n', E.InvalidValueError, 7, 'draws.faults.rho[0]'),
    ('draws:\n  faults:\n    rho:\n      - 0.5\n      - 1.2\n', E.InvalidValueError, 9, 'draws.faults.rho[1]'),
    ('draws:\n  model_mismatch: [1.0, 0.8]\n', E.InvalidValueError, 6, 'draws.model_mismatch'),
    ('draws:\n  faults: {faulted_uhs: [1, 9]}\n', E.InvalidValueError, 6, 'draws.faults.faulted_uhs[1]'),
    ('impairments:\n  delay_steps: -1\n', E.InvalidValueError, 6, 'impairments.delay_steps'),
    ('impairments:\n  seed: 3\n', E.InvalidValueError, 6, 'impairments.seed'),
    ('sweep:\n  parameter: impairments.delay_steps\n  values: [0, 2, -5]\n', E.InvalidValueError, 7,
     'sweep.values[2]'),
    ('sweep:\n  parameter: model_mismatc\n  values: [0.9]\n', E.UnknownKeyError, 6, 'sweep.parameter'),
    ('sweep:\n  parameter: model_mismatch\n  values: [0.9, 0.9]\n', E.InvalidValueError, 7, 'sweep.values[1]'),
    ('success: {formation_rms: 0.05}\n', E.UnknownKeyError, 5, 'success.formation_rms'),
    ('settle_time: 4.0\n', E.InvalidValueError, 5, 'settle_time'),
    # the delay remedies (docs/delay.md#remedies)
    ('remedies:\n  weight: 0.9\n', E.UnknownKeyError, 6, 'remedies.weight'),
    ('remedies:\n  feedforward_weight: 1.5\n', E.GainsFileError, 6, 'remedies.feedforward_weight'),
    ('remedies:\n  reference_links: every\n', E.InvalidValueError, 6, 'remedies.reference_links'),
])
def test_bad_specs_are_refused_with_file_line_and_key(tmp_path, tail, error, line, key):
    spec = _write(tmp_path, GOOD_HEAD + tail)
    with pytest.raises(error) as info:
        load_spec(spec)
    assert (info.value.source, info.value.line, info.value.path) == (str(spec), line, key)
    assert str(info.value).startswith(f'{spec}:{line}: {key}: ')


@pytest.mark.parametrize('text, error, line, key', [
    ('name: g\nruns: 1\ngenerator: {leaders: 0, followers: 2}\n', E.InvalidValueError, 3, 'generator.leaders'),
    ('name: g\nruns: 1\ngenerator:\n  leaders: 2\n  followers: 2\n  follower_edge_probability: 0\n',
     E.UnreachableFollowerError, 6, 'generator.follower_edge_probability'),
    ('name: g\nruns: 1\ngenerator:\n  leaders: 3\n  followers: 1\n  leader_edge_probability: 0.0\n',
     E.UnreachableLeaderError, 6, 'generator.leader_edge_probability'),
    ('name: g\nruns: 1\ngenerator:\n  leaders: 3\n  followers: 1\n  reference_links: [0, 1]\n',
     E.InvalidValueError, 6, 'generator.reference_links[0]'),
    ('name: g\nruns: 0\ngenerator: {leaders: 2, followers: 2}\n', E.InvalidValueError, 2, 'runs'),
    ('name: g\nruns: 1\ngenerator:\n  leaders: 2\n  followers: 2\n  weights: degree\n',
     E.InvalidValueError, 6, 'generator.weights'),
    # a new graph per draw: a link named in the spec would exist in some draws only
    ('name: g\nruns: 1\ngenerator: {leaders: 2, followers: 2}\nimpairments:\n  links: [{uh: 3, hears: 1}]\n',
     E.InvalidValueError, 5, 'impairments.links'),
    ('name: g\nruns: 1\nscenario: paper\ngenerator: {leaders: 2, followers: 2}\n', E.InvalidValueError, 1, None),
    ('name: g\nruns: 1\nscenario: nowhere.yaml\n', E.ScenarioNotFoundError, 3, 'scenario'),
    ('name: g\nruns: 1\nscenario: paper\nduration: 4.005\n', E.InvalidValueError, 4, 'duration'),
    ('name: g\nruns: [1\n', E.ScenarioSyntaxError, 3, None),
])
def test_impossible_generators_and_other_bad_specs(tmp_path, text, error, line, key):
    spec = _write(tmp_path, text)
    with pytest.raises(error) as info:
        load_spec(spec)
    assert (info.value.line, info.value.path) == (line, key)


def test_cli_refuses_a_bad_spec_with_status_2_before_running(tmp_path, capsys):
    spec = _write(tmp_path, GOOD_HEAD + 'draws:\n  faults: {rho: [0.5, 1.5]}\n')
    assert cli.main([str(spec), '--out', str(tmp_path / 'out')]) == 2
    assert f'uh-campaign: error: {spec}:6: draws.faults.rho[1]: ' in capsys.readouterr().err
    assert not (tmp_path / 'out').exists()
    assert cli.main([str(spec), '--out', str(tmp_path / 'out'), '--workers', '0']) == 2
    with pytest.raises(SystemExit) as info:
        cli.build_parser().parse_args(['--help'])
    assert info.value.code == 0
    assert '--cluster ADDRESS' in capsys.readouterr().out


def test_bundled_specs_load_and_draw_from_their_own_seed():
    assert {'campaign_paper_faults', 'campaign_delay_sweep', 'campaign_random_graphs'} <= set(bundled_specs())
    faults = load_spec('campaign_paper_faults')
    assert (faults.runs, faults.cases, faults.total_runs) == (200, ('proposed', 'case1', 'case2'), 600)
    sweep = load_spec('campaign_delay_sweep')
    assert sweep.sweep.parameter == 'impairments.delay_steps' and sweep.sweep.values == (0, 1, 2, 5, 10, 20, 50)
    graphs = load_spec('campaign_random_graphs')
    assert (graphs.generator.leaders, graphs.generator.followers) == (4, 4)
    # draw i depends on (spec, seed, i) only: the same mapping however often and in whatever order
    assert resolve_scenario(faults, 7) == resolve_scenario(faults, 7)
    assert resolve_scenario(faults, 7)['faults'] != resolve_scenario(faults, 8)['faults']
    a, b = resolve_scenario(graphs, 3), resolve_scenario(graphs, 4)
    assert a['edges'] != b['edges']                    # a new random graph per draw
    # the delay sweep: the same draw at every delay, with one impairments seed per draw
    d0, d4 = resolve_scenario(sweep, 5, 0), resolve_scenario(sweep, 5, 6)
    assert d0['uhs'] == d4['uhs'] and (d0['impairments']['delay_steps'], d4['impairments']['delay_steps']) == (0, 50)
    other_draw = resolve_scenario(sweep, 6, 0)
    assert d0['impairments']['seed'] == d4['impairments']['seed'] != other_draw['impairments']['seed']


def test_normalised_weights_sum_to_one_per_uh_on_the_same_graphs():
    """generator.weights: normalised divides each UH's incoming weights by how many it hears; the graph is the same."""
    graphs = load_spec('campaign_random_graphs')
    assert graphs.generator.weights == 'normalised'
    unit = dataclasses.replace(graphs, generator=dataclasses.replace(graphs.generator, weights='unit'))
    for draw in range(5):
        normalised, plain = resolve_scenario(graphs, draw), resolve_scenario(unit, draw)
        links = lambda data: [(e['uh'], e['hears']) for e in data['edges']] + [  # noqa: E731
            (r['uh'], 0) for r in data['reference_links']]
        assert links(normalised) == links(plain)
        assert all(e['weight'] == 1.0 for e in plain['edges'] + plain['reference_links'])
        heard = {}
        for e in normalised['edges'] + normalised['reference_links']:
            heard.setdefault(e['uh'], []).append(e['weight'])
        for uh, weights in heard.items():
            assert len(set(weights)) == 1 and weights[0] == 1.0 / len(weights), (draw, uh, weights)
        assert any(len(w) > 1 for w in heard.values())     # the rule did change some weight


# ----------------------------------------------------------------------------------------------
# Reproducibility and the resolved scenarios
# ----------------------------------------------------------------------------------------------
def test_reference_campaign_stores_every_run_and_its_metadata(reference):
    spec_path, out = reference
    runs = store.read_runs(out / store.DB_NAME)
    assert len(runs['draw']) == 60 and set(runs['status']) == {'ok'}
    assert np.all(np.isfinite(runs['formation_rms_m'])) and np.all(np.isfinite(runs['fault_error_w']))
    assert set(runs['success']) <= {0, 1}
    ok = (runs['formation_rms_m'] <= 0.05) & (runs['containment_rms_m'] <= 0.02) & (runs['separation_violation_s'] <= 0)
    assert np.array_equal(runs['success'] == 1, ok)
    # the draws differ from each other, the cases of one draw too
    proposed = runs['case_name'] == 'proposed'
    assert len(set(runs['formation_rms_m'][proposed])) == 20
    con = store.open_store(out / store.DB_NAME)
    meta = store.read_meta(con)
    con.close()
    assert meta['name'] == 'mc_test' and meta['spec'] == REFERENCE_SPEC and meta['spec_path'] == str(spec_path)
    assert meta['cases'] == '["proposed", "case1", "case2"]' and meta['sweep_parameter'] == 'model_mismatch'
    assert meta['sweep_values'] == '[0.9, 1.0]' and meta['runs'] == '10' and meta['seed'] == '42'
    assert meta['success'] == ('{"formation_rms_m": 0.05, "containment_rms_m": 0.02, '
                               '"separation_violation_s": 0.0}')
    assert len(meta['spec_digest']) == 64 and '"numba"' in meta['versions']
    assert sorted(p.name for p in (out / 'scenarios').iterdir())[:3] == [
        'draw_000000_s00.yaml', 'draw_000000_s01.yaml', 'draw_000001_s00.yaml']


def test_same_draws_with_one_worker_and_a_smaller_campaign(reference, tmp_path):
    spec_path, out = reference
    small = tmp_path / 'small'
    outcome = run_campaign(load_spec(spec_path).with_runs(3), small, workers=1)
    assert outcome.done == 18
    _assert_same_rows(_rows(out), _rows(small), draws=3)
    for name in ('draw_000002_s01.yaml', 'draw_000000_s00.yaml'):
        assert (small / 'scenarios' / name).read_text() == (out / 'scenarios' / name).read_text()
    # and the same scenario again when resolved on its own, out of order
    spec = load_spec(spec_path)
    expected = scenario_yaml(resolve_scenario(spec, 7, 1))
    assert (out / 'scenarios' / 'draw_000007_s01.yaml').read_text().endswith(expected)


def test_a_resolved_scenario_loads_alone_and_reruns_to_the_stored_metrics(reference, tmp_path):
    from uh_team.metrics import metrics_from_arrays
    from uh_team.team_simulation import run_team_simulation
    from uh_topology.scenario import load_scenario

    _, out = reference
    moved = tmp_path / 'elsewhere.yaml'           # no file it names is relative to the campaign
    moved.write_text((out / 'scenarios' / 'draw_000004_s01.yaml').read_text())
    scenario = load_scenario(moved)
    assert scenario.model_mismatch == 1.0 and scenario.duration == 12.0 and scenario.name == 'mc_test_draw000004_s01'
    runs = store.read_runs(out / store.DB_NAME)
    i = int(np.flatnonzero((runs['draw'] == 4) & (runs['sweep_index'] == 1) & (runs['case_name'] == 'case1'))[0])
    assert runs['scenario_file'][i] == 'scenarios/draw_000004_s01.yaml' and runs['sweep_value'][i] == 1.0
    run = run_team_simulation(scenario, 'case1', duration=scenario.duration)
    row = store.metric_row(metrics_from_arrays(run.arrays(), scenario, 'case1'))
    for metric, value in row.items():
        stored = runs[metric][i]
        assert (value is None and math.isnan(stored)) or value == stored, metric


# ----------------------------------------------------------------------------------------------
# Failures, resume, refusal of another campaign's directory
# ----------------------------------------------------------------------------------------------
FAILING_SPEC = """\
name: failing
generator: {leaders: 2, followers: 2, leader_edge_probability: 0.5, follower_edge_probability: 0.4, attempts: 1}
runs: 3
seed: 9
duration: 2.0
cases: [proposed]
sweep: {parameter: 'uhs[0].initial_state.omega[0]', values: [0.0, 10000.0]}
"""


def test_diverged_and_failed_runs_are_recorded_and_the_campaign_goes_on(tmp_path):
    # seed 9: draw 1 finds no valid graph in its one attempt; 1e4 rad/s of roll rate diverges
    out = tmp_path / 'out'
    outcome = run_campaign(load_spec(_write(tmp_path, FAILING_SPEC)), out, workers=2)
    assert (outcome.done, outcome.failures) == (6, 4)
    runs = store.read_runs(out / store.DB_NAME)
    status = {(int(d), int(s)): (st, r) for d, s, st, r in
              zip(runs['draw'], runs['sweep_index'], runs['status'], runs['reason'], strict=False)}
    assert status[(0, 0)] == ('ok', None) and status[(2, 0)] == ('ok', None)
    for draw in (0, 2):
        assert status[(draw, 1)][0] == 'diverged' and 'non-finite' in status[(draw, 1)][1]
    for sweep_index in (0, 1):
        state, reason = status[(1, sweep_index)]
        assert state == 'failed'
        assert reason.startswith('InvalidValueError: ') and 'no graph satisfying Assumption 1 in 1 attempt' in reason
    assert set(runs['success'][runs['status'] != 'ok']) == {0}
    assert np.isnan(runs['formation_rms_m'][runs['status'] != 'ok']).all()


def test_a_directory_of_another_campaign_is_refused(reference, tmp_path, capsys):
    spec_path, out = reference
    before = (out / store.DB_NAME).stat().st_mtime_ns
    assert cli.main([str(spec_path), '--out', str(out), '--runs', '4', '--quiet']) == 2
    err = capsys.readouterr().err
    assert "holds campaign 'mc_test' of another spec" in err and 'new --out directory' in err
    assert (out / store.DB_NAME).stat().st_mtime_ns == before
    (tmp_path / 'other').mkdir()
    (tmp_path / 'other' / 'notes.txt').write_text('x')
    assert cli.main([str(spec_path), '--out', str(tmp_path / 'other'), '--quiet']) == 2
    assert 'holds no campaign' in capsys.readouterr().err


def _stored(db: Path) -> int:
    try:
        con = sqlite3.connect(str(db), timeout=5)
        try:
            return con.execute('SELECT COUNT(*) FROM runs').fetchone()[0]
        finally:
            con.close()
    except sqlite3.OperationalError:      # not created yet
        return 0


def test_sigint_saves_what_is_done_and_a_rerun_completes_it(reference, tmp_path, processes):
    spec_path, reference_out = reference
    out = tmp_path / 'out'
    command = [str(Path(sys.executable).with_name('uh-campaign')), str(spec_path), '--out', str(out),
               '--workers', '2']
    proc = processes.start(command, stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    deadline = time.monotonic() + 60
    while _stored(out / store.DB_NAME) < 6:
        assert proc.poll() is None and time.monotonic() < deadline, 'the campaign ended before it was interrupted'
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    err = proc.communicate(timeout=60)[1]
    assert proc.returncode == 130, err
    assert 'interrupted: ' in err and f'resume with:\n  uh-campaign {spec_path} --out {out} --workers 2' in err
    stored = _stored(out / store.DB_NAME)
    assert 6 <= stored < 60

    again = subprocess.run(command, capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert again.returncode == 0, again.stderr
    assert f'resuming: {stored} of 60 runs already stored' in again.stderr
    assert f'60/60 runs stored ({60 - stored} now' in again.stderr
    assert 'proposed ' in again.stderr and 'runs/s' in again.stderr      # progress lines and the summary
    _assert_same_rows(_rows(reference_out), _rows(out))


def test_a_terminal_ctrl_c_while_the_workers_start_is_a_clean_interruption(tmp_path):
    """Handle a terminal's Ctrl-C in the main process, also while the workers start.

    A terminal sends Ctrl-C to the whole process group, workers included: one still starting (before
    its initializer ignores SIGINT) must not die with a traceback; the main process handles it.
    """
    spec = _write(tmp_path, 'name: early\nscenario: paper\nruns: 4\nduration: 2.0\ncases: [proposed]\n')
    command = [str(Path(sys.executable).with_name('uh-campaign')), str(spec), '--out', str(tmp_path / 'out'),
               '--workers', '2']
    proc = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, cwd=tmp_path, start_new_session=True)
    try:
        seen = ''
        while 'running on' not in seen:     # the pool is being started: the workers import and warm up
            line = proc.stderr.readline()
            assert line, 'the campaign ended before it started its workers'
            seen += line
        time.sleep(0.1)   # within the workers' start-up (about 2 s); without the fix, 0.05-0.15 s fail
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal does: to every process of the group
        err = seen + proc.communicate(timeout=120)[1]
    finally:
        kill_session(proc)
    assert proc.returncode == 130, err
    assert 'Traceback' not in err and 'KeyboardInterrupt' not in err, err


# ----------------------------------------------------------------------------------------------
# Dask cluster
# ----------------------------------------------------------------------------------------------
def test_a_dask_cluster_gives_the_rows_of_the_local_pool(reference, tmp_path):
    distributed = pytest.importorskip('distributed')
    spec_path, reference_out = reference
    out = tmp_path / 'dask'
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  worker_dashboard_address=None) as cluster:
        status = cli.main([str(spec_path), '--out', str(out), '--runs', '4', '--cluster', cluster.scheduler_address,
                           '--quiet'])
    assert status == 0
    _assert_same_rows(_rows(reference_out), _rows(out), draws=4)


def test_runs_lost_by_the_executor_are_not_stored_so_a_resume_runs_them_again():
    """A task the executor loses (a killed Dask worker) is not a failed run: no row, the reason kept."""
    from uh_campaign.runner import _task_rows

    class LosingExecutor:
        def result(self, future):
            raise RuntimeError('worker tcp://10.0.0.7:4321 was killed')

    lost = []
    task = {'draw': 3, 'sweep_index': 0, 'sweep_value': None, 'scenario_file': 'scenarios/draw_000003.yaml',
            'cases': ['proposed', 'case1']}
    assert _task_rows(LosingExecutor(), None, task, lost) == []
    assert lost == [(2, 'RuntimeError: worker tcp://10.0.0.7:4321 was killed')]


def test_the_script_runs_the_campaign_and_writes_its_report(tmp_path):
    """Run scripts/campaign.sh (uh-campaign): the campaign, then its report.

    Once every run is stored it runs uh-report DIR; not with --no-report.
    """
    spec = _write(tmp_path, 'name: script\nscenario: paper\nruns: 2\nduration: 2.0\ncases: [proposed]\n')
    out = tmp_path / 'mc'
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.run([str(root / 'scripts' / 'campaign.sh'), str(spec), f'--out={out}', '--workers', '1',
                           '--quiet'], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert len(_rows(out)['draw']) == 2
    report = (out / 'report' / 'report.md').read_text()
    assert '2 of 2 runs done' in report
    bare = tmp_path / 'bare'
    proc = subprocess.run([str(Path(sys.executable).with_name('uh-campaign')), str(spec), '--out', str(bare),
                           '--workers', '1', '--quiet', '--no-report'], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert (bare / store.DB_NAME).is_file() and not (bare / 'report').exists()


def test_an_impaired_campaign_stores_what_its_resolved_scenarios_give(tmp_path):
    """Impairments through the runner: fixed loss and noise, a swept delay, one seed per draw."""
    from uh_team.metrics import metrics_from_arrays
    from uh_team.team_simulation import run_team_simulation
    from uh_topology.scenario import load_scenario

    spec = _write(tmp_path, 'name: impaired\nscenario: paper\nruns: 2\nseed: 5\nduration: 3.0\ncases: [proposed]\n'
                            'impairments: {loss: 0.2, noise: {position: 0.01}}\n'
                            'sweep: {parameter: impairments.delay_steps, values: [0, 4]}\n')
    out = tmp_path / 'mc'
    run_campaign(load_spec(spec), out, workers=1)
    runs = store.read_runs(out / store.DB_NAME)
    assert list(runs['status']) == ['ok'] * 4
    scenarios = {(d, s): load_scenario(out / 'scenarios' / f'draw_{d:06d}_s{s:02d}.yaml')
                 for d in (0, 1) for s in (0, 1)}
    imp = {key: sc.impairments for key, sc in scenarios.items()}
    assert imp[(1, 1)].delays[(4, 1)] == 4 and imp[(1, 0)].delays[(4, 1)] == 0 and imp[(1, 1)].losses[(4, 1)] == 0.2
    assert imp[(1, 0)].seed == imp[(1, 1)].seed != imp[(0, 0)].seed     # a seed per draw, the same across the sweep
    for i in range(4):
        scenario = scenarios[(int(runs['draw'][i]), int(runs['sweep_index'][i]))]
        run = run_team_simulation(scenario, 'proposed', duration=scenario.duration)
        row = store.metric_row(metrics_from_arrays(run.arrays(), scenario, 'proposed'))
        assert row['formation_rms_m'] == runs['formation_rms_m'][i]
    assert runs['formation_rms_m'][1] != runs['formation_rms_m'][0]      # the delay changes the run


def test_an_attitude_spread_that_could_tip_a_base_attitude_past_pi_2_is_refused(tmp_path):
    text = paper_yaml()
    base = 'initial_state: {position: [2.0, -1.0, 8.0]}'
    assert base in text
    _write(tmp_path, text.replace(base, 'initial_state: {position: [2.0, -1.0, 8.0], euler: [1.2, 0.0, 0.0]}'),
           'tilted.yaml')
    spec = _write(tmp_path, 'name: t\nscenario: tilted.yaml\nruns: 1\ndraws:\n  attitude_spread: 0.5\n')
    with pytest.raises(E.InvalidValueError) as info:
        load_spec(spec)
    assert info.value.line == 5 and 'draws.attitude_spread' in str(info.value) and 'below 0.3708' in str(info.value)
    spec.write_text(spec.read_text().replace('0.5', '0.3'))
    assert load_spec(spec).draws.attitude_spread == 0.3


def test_progress_draws_a_bar_on_a_terminal_and_a_line_per_tenth_otherwise():
    import io

    from uh_campaign.runner import Progress

    terminal = io.StringIO()
    progress = Progress(terminal, tty=True)
    progress.start(10, 0)
    progress.update(10, 1)
    assert '\r' + 'uh-campaign: [' + '#' * 30 + '] 10/10 runs (100 %), 1 not ok' in terminal.getvalue()
    log = io.StringIO()
    progress = Progress(log, tty=False)
    progress.start(20, 0)
    for done in range(1, 21):
        progress.update(done, 0)
    lines = log.getvalue().splitlines()
    assert len(lines) == 10 and lines[0].startswith('uh-campaign: 2/20 runs (10 %), 0 not ok')
    assert '[' not in log.getvalue() and '\r' not in log.getvalue()
    quiet = io.StringIO()
    Progress(quiet, quiet=True, tty=True).update(3, 0)
    assert quiet.getvalue() == ''


def _task_that_kills_its_worker_on_draw_1(task):
    """Run by the workers in place of run_task (pickled by name: the workers import this module)."""
    from uh_campaign.runner import run_task

    if task['draw'] == 1:
        os._exit(7)          # as a crash does: no exception, the process is gone
    return run_task(task)


def test_a_run_that_kills_its_worker_is_recorded_as_failed_and_the_campaign_goes_on(tmp_path, monkeypatch):
    from uh_campaign import runner

    monkeypatch.setattr(runner, 'run_task', _task_that_kills_its_worker_on_draw_1)
    spec = _write(tmp_path, 'name: crash\nscenario: paper\nruns: 4\nduration: 2.0\ncases: [proposed, case1]\n')
    outcome = run_campaign(load_spec(spec), tmp_path / 'out', workers=2)
    runs = store.read_runs(tmp_path / 'out' / store.DB_NAME)
    assert outcome.done == 8 and len(runs['draw']) == 8
    for draw, status, reason in zip(runs['draw'], runs['status'], runs['reason'], strict=False):
        if draw == 1:
            assert status == 'failed' and 'a worker process died' in reason and 'while running it' in reason
        else:
            assert status == 'ok', reason


def test_a_specs_remedies_reach_every_resolved_scenario(tmp_path):
    """``remedies`` write the rule and the gain into each draw's scenario (docs/delay.md#remedies)."""
    from uh_campaign.resolve import resolve_scenario
    remedies = 'remedies: {reference_links: all_leaders, feedforward_weight: 0.9}\n'
    spec = load_spec(_write(tmp_path, GOOD_HEAD + remedies))
    data = resolve_scenario(spec, 1)
    gains = data['gains']['/**']['ros__parameters'] if '/**' in data['gains'] else data['gains']
    assert data['reference_links'] == 'all_leaders' and gains['feedforward_weight'] == 0.9
    plain = resolve_scenario(load_spec(_write(tmp_path, GOOD_HEAD)), 1)
    assert isinstance(plain['reference_links'], list) and 'feedforward_weight' not in str(plain['gains'])
