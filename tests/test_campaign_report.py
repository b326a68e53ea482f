"""uh-report on a campaign directory: its statistics, report files, re-run commands and error exits.

The statistics of uh_report.campaign_report are checked against values worked out by hand on small synthetic campaigns
(written with uh_team.campaign_store); then the report files, re-run commands and error exits of ``uh-report DIR``.
"""
import csv
import math

import numpy as np
import pytest

from uh_report import campaign_report as C
from uh_report.report import main
from uh_team import campaign_store as store

Z95 = 1.959963984540054   # standard normal quantile at 0.975


def _row(draw, case, status='ok', sweep_index=0, sweep_value=None, formation=0.01, containment=0.005,
         fault_w=0.1, success=None, reason=None, **metrics):
    if success is None:
        success = 1 if status == 'ok' else None
    return {'draw': draw, 'sweep_index': sweep_index, 'case_name': case, 'sweep_value': sweep_value,
            'status': status, 'reason': reason, 'success': success,
            'scenario_file': f'scenarios/draw_{draw:06d}' + (f'_s{sweep_index:02d}' if sweep_value is not None else '')
            + '.yaml',   # the runner's names (uh_campaign.spec.scenario_file_name)
            'wall_time_s': 1.5, 'formation_rms_m': formation if status == 'ok' else None,
            'containment_rms_m': containment if status == 'ok' else None,
            'fault_error_w': fault_w if status == 'ok' else None, **metrics}


def _campaign(directory, rows, **meta):
    directory.mkdir(parents=True, exist_ok=True)
    con = store.open_store(directory / store.DB_NAME)
    store.write_meta(con, **{'name': 'mc_test', 'seed': 7, 'runs': 4, 'cases': ['proposed', 'case1', 'case2'],
                             'success': {'formation_rms_m': 0.05, 'containment_rms_m': 0.02}, **meta})
    for row in rows:
        store.write_run(con, row)
    con.close()
    return directory


def _runs(rows, tmp_path):
    return store.read_runs(_campaign(tmp_path / 'c', rows) / store.DB_NAME)


# ----------------------------------------------------------------------------------------------
# Statistics
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize('k, n', [(7, 20), (0, 10), (10, 10), (1, 3)])
def test_wilson_interval_is_the_closed_form(k, n):
    p = k / n
    centre = (p + Z95 ** 2 / (2 * n)) / (1 + Z95 ** 2 / n)
    half = Z95 / (1 + Z95 ** 2 / n) * math.sqrt(p * (1 - p) / n + Z95 ** 2 / (4 * n ** 2))
    low, high = C.wilson_interval(k, n)
    assert low == pytest.approx(max(0.0, centre - half), abs=1e-12)
    assert high == pytest.approx(min(1.0, centre + half), abs=1e-12)


def test_wilson_interval_of_no_trials_is_undefined():
    assert all(math.isnan(v) for v in C.wilson_interval(0, 0))


def test_success_rate_counts_diverged_and_failed_runs_as_unsuccessful(tmp_path):
    rows = [_row(0, 'proposed'), _row(1, 'proposed'), _row(2, 'proposed', 'diverged', reason='x'),
            _row(3, 'proposed', 'failed', reason='y'), _row(4, 'proposed', success=0),
            _row(0, 'case1'), _row(1, 'case1', success=0)]
    runs = _runs(rows, tmp_path)
    table = {r['case']: r for r in C.success_table(runs, ['proposed', 'case1'])}
    assert (table['proposed']['successes'], table['proposed']['runs']) == (2, 5)
    assert table['proposed']['rate'] == pytest.approx(0.4)
    assert (table['proposed']['ci_low'], table['proposed']['ci_high']) == pytest.approx(C.wilson_interval(2, 5))
    assert (table['case1']['successes'], table['case1']['runs']) == (1, 2)
    counts = C.status_counts(runs, ['proposed', 'case1'])
    assert counts['proposed'] == {'runs': 5, 'ok': 3, 'diverged': 1, 'failed': 1}


def test_failures_are_grouped_by_reason_with_numbers_masked(tmp_path):
    rows = [_row(0, 'proposed', 'diverged', reason='non-finite state at step 120 (t = 1.2 s) on uh3'),
            _row(1, 'case1', 'diverged', reason='non-finite state at step 4411 (t = 44.11 s) on uh3'),
            _row(2, 'case1', 'diverged', reason='non-finite state at step 90 (t = 0.9 s) on uh3'),
            _row(3, 'case2', 'failed', reason='ValueError: bad gain'), _row(0, 'case2')]
    groups = C.failure_groups(_runs(rows, tmp_path))
    assert [(g['status'], g['count']) for g in groups] == [('diverged', 3), ('failed', 1)]
    assert groups[0]['pattern'] == 'non-finite state at step N (t = N s) on uh3'
    assert groups[0]['cases'] == {'proposed': 1, 'case1': 2}
    assert groups[0]['draws'] == [0, 1, 2]


def test_distribution_summary_gives_median_p90_and_the_draw_of_the_max(tmp_path):
    values = [0.03, 0.01, 0.05, 0.02, 0.04]           # draws 0..4
    rows = [_row(d, 'proposed', formation=v) for d, v in enumerate(values)]
    rows.append(_row(5, 'proposed', 'diverged', reason='x'))  # not ok: not in the distribution
    (summary,) = C.distribution_summary(_runs(rows, tmp_path), ['proposed'], 'formation_rms_m')
    assert summary['n'] == 5
    assert summary['median'] == pytest.approx(0.03)
    assert summary['p90'] == pytest.approx(0.046)     # 0.04 + 0.6 * (0.05 - 0.04)
    assert (summary['max'], summary['max_draw']) == (pytest.approx(0.05), 2)


def test_paired_comparison_on_known_differences(tmp_path):
    proposed = [0.010, 0.020, 0.030, 0.040, 0.050, 0.060]
    case1 = [0.015, 0.022, 0.029, 0.050, 0.070, 0.100]
    rows = [_row(d, 'proposed', formation=a) for d, a in enumerate(proposed)]
    rows += [_row(d, 'case1', formation=b) for d, b in enumerate(case1[:5])]
    rows.append(_row(5, 'case1', 'diverged', reason='x'))     # draw 5: not a pair
    rows.append(_row(6, 'proposed', formation=0.5))           # draw 6: case1 did not run
    runs = _runs(rows, tmp_path)
    keys, diff = C.paired_differences(runs, 'proposed', 'case1', 'formation_rms_m')
    assert keys == [(d, 0) for d in range(5)]
    np.testing.assert_allclose(diff, [-0.005, -0.002, 0.001, -0.010, -0.020])
    result = C.paired_comparison(runs, 'proposed', 'case1', 'formation_rms_m')
    assert result['pairs'] == 5
    assert result['first_better'] == pytest.approx(0.8)
    assert result['median_difference'] == pytest.approx(-0.005)
    assert result['excluded'] == 1                             # draw 5: run by both, diverged in one
    # the percentile interval: the 2.5 and 97.5 % quantiles of the medians of the seeded resamples
    rng = np.random.default_rng(C.BOOTSTRAP_SEED)
    medians = np.median(diff[rng.integers(0, 5, size=(C.BOOTSTRAP_RESAMPLES, 5))], axis=1)
    assert (result['ci_low'], result['ci_high']) == tuple(np.quantile(medians, [0.025, 0.975]))
    # exact two-sided signed-rank p: W+ = rank of +0.001 = 1 of 32 sign patterns -> 2 * 2/32
    assert result['wilcoxon_p'] == pytest.approx(0.125)
    again = C.paired_comparison(runs, 'proposed', 'case1', 'formation_rms_m')
    assert (again['ci_low'], again['ci_high']) == (result['ci_low'], result['ci_high'])   # fixed seed


def test_paired_comparison_handles_zero_differences_and_too_few_pairs(tmp_path):
    rows = [_row(d, c, formation=0.01) for d in range(3) for c in ('proposed', 'case1')]
    rows += [_row(0, 'case2', formation=0.02)]
    runs = _runs(rows, tmp_path)
    zero = C.paired_comparison(runs, 'proposed', 'case1', 'formation_rms_m')
    assert zero['pairs'] == 3 and zero['ties'] == 3 and zero['first_better'] == 0.0
    assert math.isnan(zero['wilcoxon_p']) and zero['note'] == 'all differences are zero'
    single = C.paired_comparison(runs, 'proposed', 'case2', 'formation_rms_m')
    assert single['pairs'] == 1 and single['median_difference'] == pytest.approx(-0.01)
    assert math.isnan(single['wilcoxon_p']) and math.isnan(single['ci_low'])
    none = C.paired_comparison(runs, 'proposed', 'case2', 'fault_error_p')
    assert none['pairs'] == 0 and none['note'] == 'no pairs' and math.isnan(none['median_difference'])


def test_worst_runs_put_failed_then_diverged_first_then_the_largest_errors(tmp_path):
    rows = [_row(0, 'case1', formation=0.01, containment=0.01),
            _row(1, 'case1', formation=0.30, containment=0.01),
            _row(2, 'case1', 'diverged', reason='nan'),
            _row(3, 'case1', formation=0.10, containment=0.25),
            _row(4, 'case1', 'failed', reason='boom'),
            _row(5, 'case1', formation=0.02, containment=0.01),
            _row(6, 'case1', formation=0.001, containment=0.001)]
    runs = _runs(rows, tmp_path)
    assert [int(runs['draw'][i]) for i in C.worst_runs(runs, 'case1')] == [4, 2, 3, 1, 5]


def test_rerun_commands_name_the_stored_scenario_and_the_case():
    distributed, in_process = C.rerun_commands('camps/a', 'scenarios/draw_000042.yaml', 'case2', 'mc run', 42)
    assert distributed == ('scripts/run_formation.sh --scenario camps/a/scenarios/draw_000042.yaml --case case2 '
                           '--clock lockstep --out runs/mc_run_draw42_case2')
    assert in_process == ('uh-simulate --scenario camps/a/scenarios/draw_000042.yaml --case case2 '
                          '--out runs/mc_run_draw42_case2_sim')
    swept, _ = C.rerun_commands('c', 'scenarios/x.yaml', 'proposed', 'mc', 3, sweep_index=2)
    assert swept.endswith('--out runs/mc_draw3_s2_proposed')   # the scenario file holds the duration


def _sweep_rows():
    """3 draws x 2 cases x sweep over delay 0, 2, 4; formation = 0.01 * (draw + 1) * (1 + delay)."""
    rows = []
    for k, delay in enumerate((0, 2, 4)):
        for draw in range(3):
            for case, scale in (('proposed', 1.0), ('case1', 2.0)):
                formation = 0.01 * (draw + 1) * (1 + delay) * scale
                rows.append(_row(draw, case, sweep_index=k, sweep_value=float(delay), formation=formation,
                                 containment=formation / 2, success=int(formation <= 0.05)))
    rows[-1] = _row(2, 'case1', 'failed', sweep_index=2, sweep_value=4.0, reason='timeout after 600 s')
    return rows


def test_sweep_table_gives_median_iqr_and_success_per_sweep_point(tmp_path):
    runs = _runs(_sweep_rows(), tmp_path)
    table = {(r['case'], r['sweep_value']): r for r in C.sweep_table(runs, ['proposed', 'case1'], [0, 2, 4])}
    assert len(table) == 6
    at = table[('proposed', 2.0)]            # formation 0.03, 0.06, 0.09
    assert at['formation_rms_m_median'] == pytest.approx(0.06)
    assert (at['formation_rms_m_q25'], at['formation_rms_m_q75']) == (pytest.approx(0.045), pytest.approx(0.075))
    assert at['containment_rms_m_median'] == pytest.approx(0.03)
    assert (at['successes'], at['runs']) == (1, 3)
    failed = table[('case1', 4.0)]           # 0.10, 0.20 (draw 2 failed)
    assert (failed['runs'], failed['ok'], failed['formation_rms_m_n']) == (3, 2, 2)
    assert failed['formation_rms_m_median'] == pytest.approx(0.15)
    assert failed['rate'] == 0.0 and failed['ci_low'] == pytest.approx(0.0, abs=1e-12)


# ----------------------------------------------------------------------------------------------
# uh-report DIR
# ----------------------------------------------------------------------------------------------
def test_uh_report_writes_the_campaign_report_with_sweep(tmp_path, capsys):
    directory = _campaign(tmp_path / 'camp', _sweep_rows(), runs=3, cases=['proposed', 'case1'],
                          sweep_parameter='impairments.delay_steps', sweep_values=[0, 2, 4])
    assert main([str(directory)]) == 0
    out = directory / 'report'
    for name in ('report.md', 'index.html', 'summary.csv', 'runs.csv', 'paired.csv', 'worst_runs.csv',
                 'sweep.csv', 'sweep.png', 'cdf_formation_rms_m.png', 'cdf_containment_rms_m.png',
                 'cdf_fault_error_w.png'):
        assert (out / name).is_file(), name
    for png in out.glob('*.png'):
        assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    md = (out / 'report.md').read_text()
    assert 'mc_test' in md and '18 of 18 runs done' in md
    assert 'timeout after N s' in md                      # failures grouped by reason
    # the failed run is the worst of case1, with its re-run commands
    command = (f'scripts/run_formation.sh --scenario {directory}/scenarios/draw_000002_s02.yaml --case case1 '
               '--clock lockstep --out runs/mc_test_draw2_s2_case1')
    assert command in md and command in (out / 'index.html').read_text()
    assert f'uh-simulate --scenario {directory}/scenarios/draw_000002_s02.yaml --case case1' in md
    assert 'impairments.delay_steps' in md and 'Wilcoxon' in md
    with open(out / 'runs.csv') as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 18 and {r['case_name'] for r in rows} == {'proposed', 'case1'}
    with open(out / 'summary.csv') as f:
        summary = {r['case']: r for r in csv.DictReader(f)}
    assert int(summary['case1']['failed']) == 1 and int(summary['proposed']['runs']) == 9
    with open(out / 'sweep.csv') as f:
        sweep = list(csv.DictReader(f))
    assert len(sweep) == 6
    assert 'campaign' in capsys.readouterr().err


def test_partial_campaign_without_sweep_reports_what_is_there(tmp_path):
    rows = [_row(0, 'proposed'), _row(0, 'case1', formation=0.02), _row(1, 'proposed', 'diverged', reason='nan'),
            _row(1, 'case1'), _row(2, 'proposed')]
    directory = _campaign(tmp_path / 'part', rows)
    out = tmp_path / 'elsewhere'
    assert main([str(directory), '--out', str(out)]) == 0
    md = (out / 'report.md').read_text()
    assert '5 of 12 runs done' in md and 'not complete' in md
    assert 'no sweep' in md and not (out / 'sweep.png').exists() and not (out / 'sweep.csv').exists()
    assert (out / 'cdf_formation_rms_m.png').is_file()
    assert '--scenario ' + str(directory / 'scenarios' / 'draw_000001.yaml') + ' --case proposed' in md


def test_empty_campaign_exits_2_with_a_clear_message(tmp_path, capsys):
    directory = _campaign(tmp_path / 'empty', [])
    assert main([str(directory)]) == 2
    err = capsys.readouterr().err
    assert 'no runs stored yet' in err and '0 of 12 planned' in err
    assert not (directory / 'report' / 'report.md').exists()


def test_a_results_file_that_is_not_sqlite_exits_2(tmp_path, capsys):
    directory = tmp_path / 'bad'
    directory.mkdir()
    (directory / store.DB_NAME).write_text('this is not a database, just some text\n' * 20)
    assert main([str(directory)]) == 2
    err = capsys.readouterr().err
    assert 'not a campaign results file' in err and str(directory / store.DB_NAME) in err


def test_a_campaign_directory_without_results_exits_2(tmp_path, capsys):
    directory = tmp_path / 'started'
    (directory / 'scenarios').mkdir(parents=True)
    assert main([str(directory)]) == 2
    assert 'no campaign.sqlite' in capsys.readouterr().err
    assert not (directory / store.DB_NAME).exists()          # the report does not create one


def test_a_campaign_must_be_the_only_argument(tmp_path, capsys):
    directory = _campaign(tmp_path / 'c', [_row(0, 'proposed')])
    other = tmp_path / 'run'
    other.mkdir()
    assert main([str(other), str(directory)]) == 2
    assert 'campaign directory' in capsys.readouterr().err


def test_with_a_sweep_cases_are_compared_at_each_sweep_point(tmp_path):
    """The draws of one sweep point are independent, those of several are not: one comparison per point."""
    rows = [_row(d, c, sweep_index=k, sweep_value=float(v),
                 formation=0.01 * (d + 1) * (1 + v) * (2 if c == 'case1' else 1))
            for k, v in enumerate((0, 5)) for d in range(4) for c in ('proposed', 'case1')]
    runs = _runs(rows, tmp_path)
    at = [C.paired_comparison(runs, 'proposed', 'case1', 'formation_rms_m', sweep_index=k) for k in (0, 1)]
    assert [r['pairs'] for r in at] == [4, 4] and [r['sweep_index'] for r in at] == [0, 1]
    assert at[0]['median_difference'] == pytest.approx(-0.025)    # -0.01 (d + 1), d = 0..3
    assert at[1]['median_difference'] == pytest.approx(-0.15)     # -0.06 (d + 1)
    assert C.paired_comparison(runs, 'proposed', 'case1', 'formation_rms_m')['pairs'] == 8   # pooled: 8


def test_a_draw_without_a_scenario_gets_no_rerun_command(tmp_path):
    rows = [_row(0, 'proposed'), {**_row(1, 'proposed', 'failed', reason='InvalidValueError: no valid graph'),
                                  'scenario_file': None}]
    directory = _campaign(tmp_path / 'mc', rows, cases=['proposed'], runs=2)
    assert main([str(directory)]) == 0
    md = (directory / 'report' / 'report.md').read_text()
    assert 'no scenario to re-run' in md and 'draw_000001' not in md
