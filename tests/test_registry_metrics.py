"""One declaration per metric (uh_team.metric_registry): every reader takes it from there (docs/metrics.md).

The readers keep the layout they had (metrics.json keys, the results file's columns, the report's rows,
uh-simulate's summary, the campaign's units); the docs tables are the registry's; and one more
declaration in a copy of the registry reaches metrics.json, the report, the results file and the
campaign statistics with no other edit.
"""
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from uh_report import campaign_stats
from uh_report.report import RunData, table_rows
from uh_team import campaign_store, metric_registry
from uh_team.metric_registry import METRICS, Metric, json_table, metric_table
from uh_team.metrics import METRIC_KEYS, FaultedUH, compute_metrics

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / 'docs' / 'metrics.md'

#: The layouts every reader had before the registry: a reader that moves is a change of its output.
JSON_KEYS = ('case', 'departures', 'sim_time_s', 'wall_time_s', 'settle_time_s', 'formation_rms_m', 'containment_rms_m',
             'hull_distance_max_m', 'mse_formation', 'mse_containment', 'cpi', 'slowest_mode_s', 'fault_estimation',
             'false_fault_estimate', 'fault_nrmse', 'saturation_fraction', 'fault_isolation', 'faults',
             # docs/safety.md: the separation metrics, added at the end
             'min_separation_m', 'min_separation_pair', 'separation_violation_s', 'rotor_overlap_s', 'safety_active_s',
             'separation',
             # docs/resilience.md: the losses of a run with events
             'reconfiguration')
STORE_COLUMNS = {
    'formation_rms_m': 'RMS formation error of the leaders after settle, m',
    'containment_rms_m': 'RMS containment error of the followers after settle, m',
    'hull_distance_max_m': 'largest follower distance to the leaders\' convex hull after settle, m',
    'mse_formation': 'mean squared formation error from t = 0, m^2',
    'mse_containment': 'mean squared containment error from t = 0, m^2',
    'cpi': 'cost performance index, integral of |z1|^2 + |u_p|^2',
    'slowest_mode_s': "time constant of the team's slowest linear mode without delay, s",
    'saturation_fraction': 'fraction of (step, UH) samples with an input limit active',
    'false_fault_p': 'largest RMS |Fhat_p| where no fault acts, m/s^2',
    'false_fault_w': 'largest RMS |Fhat_w| where no fault acts, rad/s^2',
    'fault_error_p': 'largest RMS |Fhat_p - F_p| over the faulted UHs, m/s^2',
    'fault_error_w': 'largest RMS |Fhat_w - F_w| over the faulted UHs, rad/s^2',
    'false_isolations': 'channels isolated by a controller that carry no fault',
    'missed_isolations': 'faulted channels no controller isolated',
    'min_separation_m': 'smallest hub-to-hub distance of any two UHs over the run, m',
    'separation_violation_s': 'time some pair is closer than the minimum separation, s',
    'rotor_overlap_s': 'time some pair is closer than two rotor radii (rotor disks overlap), s',
    'safety_active_s': 'time the safety filter of some UH changed its u_p, s',
    # docs/campaigns.md#losing-a-helicopter: a run's losses, from metrics.json's reconfiguration
    'reform_time_s': 'largest time from a loss to the team re-formed, s (none if one was not)',
    'agree_time_s': 'largest time from a loss to every surviving UH knowing of it, s (none if one was not)',
    'loss_formation_last_10s_m': "largest leader error over a loss's last 10 s, against the team then in force, m",
    'loss_containment_last_10s_m': "largest follower error over a loss's last 10 s, against the team then in force, m",
    'loss_min_separation_m': 'smallest hub-to-hub distance from a loss to re-forming (or the end), m',
}
REPORT_ROWS = [
    ('case', 'controller case', '', None),
    ('sim_time_s', 'simulated time', 's', None),
    ('cpi', 'CPI = ∫ Σ (‖z1‖² + ‖u_p‖²) dt', '-', 'lower'),
    ('mse_formation', 'MSE formation (whole run)', 'm²', 'lower'),
    ('mse_containment', 'MSE containment (whole run)', 'm²', 'lower'),
    ('formation_rms_m', 'formation RMS after settle', 'm', 'lower'),
    ('containment_rms_m', 'containment RMS after settle', 'm', 'lower'),
    ('hull_distance_max_m', 'max distance outside the hull after settle', 'm', 'lower'),
    ('min_separation_m', 'closest approach of two UHs (hub to hub)', 'm', 'higher'),
    ('separation_violation_s', 'time under the minimum separation', 's', 'lower'),
    ('rotor_overlap_s', 'time with rotor disks overlapping', 's', 'lower'),
    ('safety_active_s', 'time the safety filter acted', 's', 'lower'),
    ('saturation_fraction', 'saturated fraction of steps', '-', 'lower'),
    ('false_fault_estimate.max.p', 'false fault estimate RMS ‖F̂_p‖, max over UHs (threshold 0.05)', 'm/s²', 'lower'),
    ('false_fault_estimate.max.w', 'false fault estimate RMS ‖F̂_w‖, max over UHs (threshold 0.1)', 'rad/s²', 'lower'),
    ('fault_estimation.uh2.p.rms_error', 'fault estimation RMS error UH2 F_p (position loop)', 'm/s²', 'lower'),
    ('fault_estimation.uh2.p.nrmse', 'fault NRMSE UH2 F_p (position loop)', '-', 'lower'),
    ('fault_estimation.uh2.w.rms_error', 'fault estimation RMS error UH2 F_w (attitude loop)', 'rad/s²', 'lower'),
    ('fault_estimation.uh2.w.nrmse', 'fault NRMSE UH2 F_w (attitude loop)', '-', 'lower'),
    ('fault_isolation.summary.false_isolations', 'false isolations (isolated channels not faulty)', '-', 'lower'),
    ('fault_isolation.summary.missed', 'faulted channels never isolated', '-', 'lower'),
    ('fault_isolation.summary.max_delay', 'largest isolation delay after the onset', 's', 'lower'),
    ('settle_time_s', 'settle time', 's', None),
    ('wall_time_s', 'wall time of the run', 's', None),
]
SUMMARY_KEYS = ('formation_rms_m', 'containment_rms_m', 'hull_distance_max_m', 'mse_formation', 'mse_containment',
                'cpi', 'saturation_fraction', 'min_separation_m', 'separation_violation_s', 'rotor_overlap_s',
                'safety_active_s')
CAMPAIGN_UNITS = {'formation_rms_m': 'm', 'containment_rms_m': 'm', 'hull_distance_max_m': 'm',
                  'fault_error_p': 'm/s²', 'fault_error_w': 'rad/s²', 'false_fault_p': 'm/s²',
                  'false_fault_w': 'rad/s²', 'saturation_fraction': '-'}


def _run_arrays(K=300, dt=0.1) -> dict:
    """Keyword arguments of ``compute_metrics``: two leaders and a follower, UH2 faulted from 10 s."""
    time = np.arange(K + 1) * dt
    p0 = np.stack([time, np.zeros(K + 1), np.full(K + 1, 10.0)], axis=1)
    offsets = {1: np.array([0.0, 2.0, 0.0]), 2: np.array([0.0, -2.0, 0.0])}
    pos = np.zeros((K + 1, 3, 3))
    pos[:, 0] = p0 + offsets[1] + [0.0, 0.0, 0.1]
    pos[:, 1] = p0 + offsets[2]
    pos[:, 2] = 0.5 * (pos[:, 0] + pos[:, 1]) + [0.0, 0.0, 0.02]
    f_true = np.zeros((K, 3, 3))
    f_true[time[:K] >= 10.0, 1] = [0.0, 0.0, -1.0]
    return dict(case='proposed', time=time, positions=pos, reference_positions=p0, leaders=(1, 2), followers=(3,),
                offsets=offsets, containment_weights=np.array([[0.5, 0.5]]), z1=np.full((K, 3, 3), 0.1),
                u_p=np.full((K, 3, 3), 0.2), saturated=np.zeros((K, 3), dtype=bool), fault_true_p=f_true,
                fault_true_w=f_true, fault_est_p=0.9 * f_true, fault_est_w=0.9 * f_true,
                faulted={2: FaultedUH(10.0, True)}, wall_time=0.5)


def _docs_table(heading: str, header: str) -> str:
    """Return the Markdown table of docs/metrics.md whose header line is ``header``, in the section ``heading``."""
    text = DOCS.read_text()
    section = text[text.index(f'\n{heading}\n'):]
    lines = section[section.index(f'\n{header}\n') + 1:].splitlines()
    end = next(i for i, line in enumerate(lines) if not line.startswith('|'))
    return '\n'.join(lines[:end])


def test_the_docs_tables_are_the_registrys():
    assert _docs_table('## metrics.json', json_table().splitlines()[0]) == json_table()
    assert _docs_table('## The registry of metrics', metric_table().splitlines()[0]) == metric_table()


def test_every_reader_keeps_its_layout():
    assert METRIC_KEYS == JSON_KEYS
    assert campaign_store.METRIC_COLUMNS == STORE_COLUMNS
    assert list(campaign_store.METRIC_COLUMNS) == list(STORE_COLUMNS)
    assert metric_registry.summary_keys() == SUMMARY_KEYS
    assert {k: campaign_stats.METRIC_UNITS[k] for k in CAMPAIGN_UNITS} == CAMPAIGN_UNITS
    metrics = {'fault_estimation': {'uh2': {'p': {}, 'w': {}}}}
    run = RunData(directory=Path('/runs/a'), name='a', label='a', source='timeseries', case='proposed',
                  scenario=None, arrays={}, metrics=metrics)
    assert table_rows([run]) == REPORT_ROWS


def test_the_declarations_are_consistent():
    names = [m.name for m in METRICS]
    assert len(set(names)) == len(names)
    keys = [m.key for m in METRICS if m.key is not None]
    assert len(set(keys)) == len(keys)
    rows = [m.report_row for m in METRICS if m.report_row is not None]
    assert len(set(rows)) == len(rows)
    stored = {m.name: m for m in metric_registry.stored_metrics()}
    # the campaign report's choices are stored metrics; its paired comparisons assume lower is better
    for chosen in (campaign_stats.DISTRIBUTION_METRICS, campaign_stats.PAIRED_METRICS, campaign_stats.SWEEP_METRICS):
        assert set(chosen) <= set(stored)
    assert all(stored[m].better == 'lower' for m in campaign_stats.PAIRED_METRICS)


@pytest.mark.parametrize('bad, says', [
    (dict(better='smaller'), 'better'),
    (dict(json_type='number'), 'both json_type and compute'),
    (dict(path='a.b', read=len), 'either a path or a read function'),
    (dict(path='a.b', label='a b'), 'a label needs a report_row'),
    (dict(read=len, report_row=5), 'a report row needs a metrics.json key'),
    (dict(path='a.b', summary=True), 'top-level keys only'),
    (dict(path='a.b', stored=True, name='Not a column'), 'SQL column'),
])
def test_a_declaration_its_readers_cannot_use_is_refused(bad, says):
    with pytest.raises(ValueError, match=says):
        Metric(**{'name': 'x', **bad})


def test_the_store_row_is_read_from_metrics_json():
    metrics = compute_metrics(**_run_arrays())
    row = campaign_store.metric_row(json.loads(json.dumps(metrics)))
    assert list(row) == list(STORE_COLUMNS)
    assert row['formation_rms_m'] == metrics['formation_rms_m']
    assert row['false_fault_p'] == metrics['false_fault_estimate']['max']['p']
    assert row['fault_error_p'] == metrics['fault_estimation']['uh2']['p']['rms_error']
    assert row['false_isolations'] is None and row['missed_isolations'] is None   # no isolation without a scenario
    empty = campaign_store.metric_row({})
    assert set(empty.values()) == {None}


def test_the_loss_columns_are_read_from_reconfiguration():
    """Over a run's losses: the largest times and errors, the closest approach; none when a loss has none."""
    first = {'time_s': 20.0, 'agreed_at_s': 20.5, 'reformed_at_s': 24.71, 'formation_error_last_10s_m': 0.01,
             'containment_error_last_10s_m': 0.002, 'min_separation_m': 1.9}
    second = {'time_s': 40.0, 'agreed_at_s': 40.6, 'reformed_at_s': 47.5, 'formation_error_last_10s_m': 0.03,
              'containment_error_last_10s_m': 0.001, 'min_separation_m': 1.8}
    row = campaign_store.metric_row({'reconfiguration': [first, second]})
    assert (row['reform_time_s'], row['agree_time_s']) == (7.5, 0.6)
    assert (row['loss_formation_last_10s_m'], row['loss_containment_last_10s_m']) == (0.03, 0.002)
    assert row['loss_min_separation_m'] == 1.8
    held = campaign_store.metric_row({'reconfiguration': [first, {**second, 'reformed_at_s': None,
                                                                  'agreed_at_s': None}]})
    assert (held['reform_time_s'], held['agree_time_s'], held['loss_formation_last_10s_m']) == (None, None, 0.03)
    without = campaign_store.metric_row({'reconfiguration': None, 'formation_rms_m': 0.01})
    losses = ('reform_time_s', 'agree_time_s', 'loss_formation_last_10s_m', 'loss_containment_last_10s_m',
              'loss_min_separation_m')
    assert [without[m] for m in losses] == [None] * 5 and without['formation_rms_m'] == 0.01


#: One more metric, as a developer adds it: its computation and its declaration, at the end of the registry.
_DUMMY = '''

def _peak_speed(values):
    """Largest speed of any UH, m/s (a finite difference of the positions)."""
    speed = np.linalg.norm(np.diff(values.positions, axis=0), axis=-1) / values.dt
    return float(np.max(speed))


METRICS = METRICS + (
    Metric('peak_speed_mps', 'm/s', 'largest speed of any UH, m/s', 'lower', label='peak speed',
           report_row=95, json_type='number', doc='largest speed of any UH, m/s', compute=_peak_speed,
           stored=True, summary=True),
)
'''

_READERS = '''
import json, sys
from pathlib import Path
import numpy as np
from uh_team.metrics import compute_metrics, METRIC_KEYS
from uh_team.metric_registry import summary_keys
from uh_team import campaign_store
from uh_report import campaign_stats
from uh_report.report import RunData, markdown_table, csv_table

arrays = {k: np.asarray(v) if isinstance(v, list) else v for k, v in json.loads(sys.argv[1]).items()}
arrays['offsets'] = {int(k): np.asarray(v) for k, v in arrays['offsets'].items()}
arrays['faulted'] = {}
arrays['leaders'], arrays['followers'] = tuple(arrays['leaders']), tuple(arrays['followers'])
metrics = json.loads(json.dumps(compute_metrics(**arrays)))
out = Path(sys.argv[2])
con = campaign_store.open_store(out / 'campaign.sqlite')
campaign_store.write_run(con, {'draw': 0, 'sweep_index': 0, 'case_name': 'proposed', 'status': 'ok',
                               **campaign_store.metric_row(metrics)})
runs = campaign_store.read_runs(con)
run = RunData(directory=out, name='a', label='a', source='timeseries', case='proposed', scenario=None, arrays={},
              metrics=metrics)
(summary,) = campaign_stats.distribution_summary(runs, ['proposed'], 'peak_speed_mps')
print(json.dumps({'keys': list(metrics), 'metric_keys': list(METRIC_KEYS), 'value': metrics['peak_speed_mps'],
                  'stored': float(runs['peak_speed_mps'][0]), 'columns': list(runs),
                  'unit': campaign_stats.METRIC_UNITS['peak_speed_mps'], 'median': summary['median'],
                  'summary': list(summary_keys()), 'described': campaign_store.METRIC_COLUMNS['peak_speed_mps'],
                  'markdown': markdown_table([run]), 'csv': csv_table([run])}))
'''


def test_one_declaration_reaches_every_reader(tmp_path):
    """A copy of uh_team with one more declaration: metrics.json, the report, the store and the statistics show it."""
    copy = tmp_path / 'src'
    for package in ('uh_team', 'uh_report'):
        shutil.copytree(ROOT / package / package, copy / package / package,
                        ignore=shutil.ignore_patterns('__pycache__'))
    registry = copy / 'uh_team' / 'uh_team' / 'metric_registry.py'
    registry.write_text(registry.read_text() + _DUMMY)

    arrays = _run_arrays(K=100)
    arrays.update(faulted=None, fault_true_p=None, fault_true_w=None, fault_est_p=None, fault_est_w=None)
    given = {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in arrays.items()}
    given['offsets'] = {k: v.tolist() for k, v in arrays['offsets'].items()}
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(str(copy / p) for p in ('uh_team', 'uh_report'))}
    proc = subprocess.run([sys.executable, '-c', _READERS, json.dumps(given), str(tmp_path)], env=env, cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout)

    speed = float(np.max(np.linalg.norm(np.diff(arrays['positions'], axis=0), axis=-1) / 0.1))
    assert seen['keys'] == seen['metric_keys'] == [*JSON_KEYS, 'peak_speed_mps']       # metrics.json: last key
    assert seen['value'] == pytest.approx(speed)
    assert seen['columns'][-1] == 'peak_speed_mps' and seen['stored'] == seen['value']  # results file: last column
    assert seen['described'] == 'largest speed of any UH, m/s'                      # what a campaign may threshold
    assert seen['unit'] == 'm/s' and seen['median'] == seen['value']                 # campaign statistics
    assert seen['summary'] == [*SUMMARY_KEYS, 'peak_speed_mps']                      # uh-simulate's summary
    rows = [line for line in seen['markdown'].splitlines() if line.startswith('| ')]
    keys = [re.search(r'`([^`]+)`', row).group(1) for row in rows[3:]]               # after head, directory, source
    assert keys.index('peak_speed_mps') == keys.index('saturation_fraction') + 1     # report row 95: after 90
    assert f'| peak speed | m/s | `peak_speed_mps` | {seen["value"]:.4g} |' in seen['markdown']
    assert f'peak_speed_mps,{seen["value"]!r}' in seen['csv']


def test_the_report_marks_the_best_run_the_way_a_metric_ranks(monkeypatch):
    import uh_report.report as report
    declared = (Metric('score', '-', 'a score', 'higher', label='score', report_row=1, json_type='number',
                       compute=lambda v: 0.0),
                Metric('cost', '-', 'a cost', 'lower', label='cost', report_row=2, json_type='number',
                       compute=lambda v: 0.0))
    monkeypatch.setattr(report, 'report_metrics', lambda: declared)
    runs = [RunData(directory=Path(f'/runs/{name}'), name=name, label=name, source='timeseries', case='proposed',
                    scenario=None, arrays={}, metrics={'score': score, 'cost': score})
            for name, score in (('a', 1.0), ('b', 2.0))]
    table = report.markdown_table(runs)
    assert '| score | - | `score` | 1 | **2** |' in table
    assert '| cost | - | `cost` | **1** | 2 |' in table
