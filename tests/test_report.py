"""uh-report: every figure of the paper's Figures 4-12, the metrics table, and clear errors for unusable input.

The figures come from a recorded run (MCAP bag) and from the reference simulation (timeseries.npz); the metrics table
equals each run's metrics.json with one column per run.

One short distributed run (22 s lockstep: the 20 s settle window of the after-settle metrics
exists) is shared by this file, tests/test_replay.py and tests/test_markers_recorded.py through
:func:`shared_team_run`.
"""
import csv
import fcntl
import io
import json
import re
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from uh_runtime.network import reserve_domain_id
from uh_team.metrics import nrmse_below_floor

ROOT = Path(__file__).resolve().parents[1]
RUN = ROOT / 'scripts' / 'run_formation.sh'
TEAM_RUN_DURATION = 22.0   # s: past the paper scenario's settle time (20 s), so every metric is defined

# The paper scenario (docs/scenario.md) has faults in UH2, UH3 and UH5: one fault figure each, and
# one figure of the estimates where no fault acts.
FAULTED = (2, 3, 5)
PER_RUN_FIGURES = (['states', 'trajectory_3d', 'xy_snapshots'] + [f'faults_uh{i}' for i in FAULTED]
                   + ['false_fault_estimate'])


def shared_team_run(tmp_path_factory) -> Path:
    """Return the run directory of one 22 s lockstep run of the paper scenario (run_formation.sh).

    It is made once per test session and shared by the test files that need a recorded team bag.
    """
    base = tmp_path_factory.getbasetemp()
    out = base / 'shared_team_run'
    with open(base / 'shared_team_run.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)   # several test files may ask for it: one run only
        failed = base / 'shared_team_run.failed'
        if failed.exists():
            pytest.fail(failed.read_text())
        if not (out / 'metrics.json').exists():
            domain = reserve_domain_id()
            proc = subprocess.run([str(RUN), '--duration', str(TEAM_RUN_DURATION), '--out', str(out),
                                   '--force', '--domain-id', str(domain)],
                                  capture_output=True, text=True, timeout=600)
            if proc.returncode != 0 or not (out / 'metrics.json').exists():
                failed.write_text(f'run_formation.sh failed ({proc.returncode}):\n{proc.stderr[-3000:]}')
                pytest.fail(failed.read_text())
    return out


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) from a PNG's IHDR chunk."""
    data = path.read_bytes()[:24]
    assert data[:8] == b'\x89PNG\r\n\x1a\n', f'{path} is not a PNG'
    return struct.unpack('>II', data[16:24])


def assert_drawn(path: Path, size: tuple[int, int]) -> None:
    """Assert that the PNG has the expected pixel size and holds a drawing, not a blank canvas."""
    import matplotlib.image as mpimg
    assert path.stat().st_size > 10_000, f'{path} is suspiciously small'
    assert png_size(path) == size, path
    pixels = mpimg.imread(path)[..., :3]
    ink = np.mean(np.any(pixels < 0.9, axis=-1))   # fraction of pixels that are not (near) white
    # axes frames, ticks, labels and curves cover a few per cent of a figure; a blank one has none
    assert ink > 0.02, f'{path}: only {ink:.1%} of the pixels are drawn'


def damaged_chunk(path: Path) -> bytes:
    """Return the bytes of MCAP file ``path`` with 64 bytes in the middle of its middle chunk inverted.

    This is a damaged disk block; the file keeps its size, footer and summary. Inverted, not zeroed: the middle of a
    chunk may already be zeros (an odometry message's covariance is 576 of them), and zeroing it would change nothing.
    """
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        chunks = make_reader(f).get_summary().chunk_indexes
    chunk = chunks[len(chunks) // 2]
    data = bytearray(path.read_bytes())
    middle = chunk.chunk_start_offset + chunk.chunk_length // 2
    data[middle:middle + 64] = bytes(b ^ 0xFF for b in data[middle:middle + 64])
    return bytes(data)


def markdown_table(text: str) -> list[list[str]]:
    """Rows (lists of cell texts) of the first Markdown table in ``text``, separator row dropped."""
    rows = []
    for line in text.splitlines():
        if line.startswith('|'):
            cells = [c.strip() for c in line.strip().strip('|').split('|')]
            if not all(re.fullmatch(r':?-+:?', c) for c in cells if c):
                rows.append(cells)
        elif rows:
            break
    return rows


def lookup(metrics: dict, dotted: str):
    value = metrics
    for part in dotted.split('.'):
        value = value[part]
    return value


@pytest.fixture(scope='module')
def team_run(tmp_path_factory):
    return shared_team_run(tmp_path_factory)


@pytest.fixture(scope='module')
def simulated_runs(tmp_path_factory):
    """Case I and Case II from the in-process reference simulation, as long as the team run."""
    from uh_team import simulate_cli
    base = tmp_path_factory.mktemp('sim')
    for case in ('case1', 'case2'):
        assert simulate_cli.main(['--scenario', 'paper', '--case', case, '--duration', str(TEAM_RUN_DURATION),
                                  '--out', str(base / case)]) == 0
    return [base / 'case1', base / 'case2']


@pytest.fixture(scope='module')
def report(team_run, simulated_runs, tmp_path_factory):
    from uh_report.report import main
    out = tmp_path_factory.mktemp('report') / 'out'
    runs = [team_run, *simulated_runs]
    assert main([str(r) for r in runs] + ['--out', str(out)]) == 0
    return out, runs


@pytest.mark.dds
@pytest.mark.slow
def test_every_figure_is_drawn_at_its_size(report):
    from uh_report.report_figures import pixel_size
    out, runs = report
    assert_drawn(out / 'errors.png', pixel_size('errors'))
    assert_drawn(out / 'errors_per_uh.png', pixel_size('errors_per_uh'))
    for run in runs:
        for name in PER_RUN_FIGURES:
            kind = 'faults' if name.startswith('faults') else name
            assert_drawn(out / run.name / f'{name}.png', pixel_size(kind))


@pytest.mark.dds
@pytest.mark.slow
def test_table_has_one_column_per_run_with_the_numbers_of_metrics_json(report):
    out, runs = report
    rows = markdown_table((out / 'report.md').read_text())
    header = rows[0]
    assert len(header) == 3 + len(runs)          # metric, unit, key, then one column per run
    assert header[3:] == ['proposed', 'Case I (β = 1)', 'Case II (no SPEM)']
    by_label = {r[0]: r for r in rows[1:]}
    assert by_label['run directory'][3:] == [f'`{r.name}`' for r in runs]
    checked = 0
    for row in rows[1:]:
        key = row[2].strip('`')
        if not key:
            continue
        for run, cell in zip(runs, row[3:], strict=False):
            metrics = json.loads((run / 'metrics.json').read_text())
            value = lookup(metrics, key)
            text = cell.strip('*')
            if isinstance(value, str):
                assert text == value, (key, run)
            elif value is None:
                below_floor = key.endswith('.nrmse') and nrmse_below_floor(lookup(metrics, key.rpartition('.')[0]))
                assert text == ('n/m' if below_floor else 'n/a'), (key, run)
            else:
                # the table shows 4 significant digits: relative rounding error at most 5e-4
                assert float(text) == pytest.approx(value, rel=5e-4, abs=0), (key, run, text, value)
                checked += 1
    # every scalar of docs/metrics.md, the false fault estimate of F_p and F_w, and the absolute
    # error and NRMSE of the five scored fault vectors, for each run
    assert {'false_fault_estimate.max.p', 'false_fault_estimate.max.w', 'fault_estimation.uh2.p.rms_error',
            'fault_estimation.uh3.w.nrmse'} <= {row[2].strip('`') for row in rows[1:]}
    assert checked >= 3 * (10 + 2 + 5 + 5)
    # the CSV holds the same numbers at full precision: equal to metrics.json to the bit
    with open(out / 'metrics_table.csv') as f:
        table = list(csv.reader(f))
    assert table[0][1:] == [r.name for r in runs]
    for key, *cells in table[1:]:
        for run, cell in zip(runs, cells, strict=False):
            value = lookup(json.loads((run / 'metrics.json').read_text()), key)
            if isinstance(value, float):
                assert float(cell) == value, (key, run)


@pytest.mark.dds
@pytest.mark.slow
def test_index_html_shows_every_figure_and_the_table(report):
    out, runs = report
    page = (out / 'index.html').read_text()
    images = set(re.findall(r'<img src="([^"]+)"', page))
    on_disk = {p.relative_to(out).as_posix() for p in out.rglob('*.png')}
    assert images == on_disk and len(on_disk) == 2 + len(runs) * len(PER_RUN_FIGURES)
    metrics_table = page.split('</table>')[0]
    assert metrics_table.count('<tr>') == len(markdown_table((out / 'report.md').read_text()))
    # per run a table of its faults and one of its fault isolation (the paper scenario has faults)
    assert page.count('<table>') == 1 + 2 * len(runs)
    assert page.count('Faults: scheduled by the scenario, and injected during the run') == len(runs)


def _run_with_metrics(name: str, metrics: dict):
    from uh_report.report import RunData
    return RunData(directory=Path('/runs') / name, name=name, label=name, source='timeseries', case='proposed',
                   scenario=None, arrays={}, metrics=metrics)


def _fault_metrics(uh3_truth_rms: float, uh3_nrmse) -> dict:
    """Return the fault part of a metrics.json: UH3's F_w below the NRMSE floor when ``uh3_nrmse`` is None."""
    def vector(rms_error, truth_rms, nrmse):
        note = None if nrmse is not None else 'not meaningful: below the floor'
        return {'rms_error': rms_error, 'truth_rms': truth_rms, 'nrmse': nrmse, 'nrmse_note': note}
    return {'case': 'proposed',
            'fault_estimation': {'uh2': {'window': [15.0, 59.99], 'p': vector(0.07, 2.3, 0.0304),
                                         'w': vector(0.7, 2.8, 0.25)},
                                 'uh3': {'window': [15.0, 59.99], 'w': vector(0.05, uh3_truth_rms, uh3_nrmse)}},
            'false_fault_estimate': {'uh1': {'p': 0.04, 'w': 0.02, 'window': [5.0, 59.99]},
                                     'max': {'p': 0.04, 'w': 0.02}, 'threshold': {'p': 0.05, 'w': 0.1}}}


def test_tables_mark_an_nrmse_below_the_floor_as_not_meaningful():
    """An NRMSE withheld below the floor shows 'n/m' (never a number, never 'n/a').

    It takes no part in the bold of its row, and the absolute error next to it is still shown; false estimate rows.
    """
    from uh_report.report import csv_table
    from uh_report.report import markdown_table as report_table
    runs = [_run_with_metrics('below', _fault_metrics(0.3, None)), _run_with_metrics('above', _fault_metrics(1.4, 0.5))]
    rows = {r[2].strip('`'): r[3:] for r in markdown_table(report_table(runs))[1:]}
    assert rows['fault_estimation.uh3.w.nrmse'] == ['n/m', '0.5']      # only one number: no bold
    assert rows['fault_estimation.uh3.w.rms_error'] == ['**0.05**', '**0.05**']
    assert rows['fault_estimation.uh2.p.nrmse'] == ['**0.0304**', '**0.0304**']
    assert rows['false_fault_estimate.max.p'] == ['**0.04**', '**0.04**']
    assert rows['false_fault_estimate.max.w'] == ['**0.02**', '**0.02**']
    assert 'fault_estimation.uh3.p.nrmse' not in rows                  # UH3 scores F_w only
    keys = list(rows)
    assert keys.index('false_fault_estimate.max.p') < keys.index('fault_estimation.uh2.p.rms_error') < \
        keys.index('fault_estimation.uh2.p.nrmse') < keys.index('fault_estimation.uh3.w.nrmse')
    csv_rows = {r[0]: r[1:] for r in csv.reader(io.StringIO(csv_table(runs)))}
    assert csv_rows['fault_estimation.uh3.w.nrmse'] == ['n/m', '0.5']


def test_report_of_a_short_simulation_marks_undefined_metrics(tmp_path):
    """A 5 s run ends before the 20 s settle time.

    Its after-settle metrics are null in metrics.json and 'n/a' in the table; the default output directory is
    RUN_DIR/report.
    """
    from uh_report.report import main
    from uh_team import simulate_cli
    run = tmp_path / 'short'
    assert simulate_cli.main(['--scenario', 'paper', '--out', str(run), '--duration', '5']) == 0
    assert main([str(run)]) == 0
    rows = {r[2].strip('`'): r[3] for r in markdown_table((run / 'report' / 'report.md').read_text())[1:]}
    metrics = json.loads((run / 'metrics.json').read_text())
    assert metrics['formation_rms_m'] is None and rows['formation_rms_m'] == 'n/a'
    # the faults start at 10 s: no step is scored after onset + 5 s, none after the 5 s start-up
    assert metrics['fault_estimation']['uh2']['p']['nrmse'] is None and rows['fault_estimation.uh2.p.nrmse'] == 'n/a'
    assert metrics['false_fault_estimate']['max'] == {'p': None, 'w': None}
    assert rows['false_fault_estimate.max.p'] == 'n/a'
    assert float(rows['cpi']) == pytest.approx(metrics['cpi'], rel=5e-4)
    assert (run / 'report' / 'errors.png').stat().st_size > 10_000


def test_a_report_of_some_figures_draws_and_shows_only_those(tmp_path):
    """The report a run writes when it ends: the errors and the XY snapshots, and how to get the rest."""
    from uh_report.report import load_run, write_report
    from uh_team import simulate_cli
    run_dir = tmp_path / 'short'
    assert simulate_cli.main(['--scenario', 'paper', '--out', str(run_dir), '--duration', '2']) == 0
    out = tmp_path / 'report'
    write_report([load_run(run_dir)], out, ('errors', 'xy_snapshots'), hint='Every figure: `uh-report short`.')
    drawn = sorted(p.relative_to(out).as_posix() for p in out.rglob('*.png'))
    assert drawn == ['errors.png', 'short/xy_snapshots.png']
    text = (out / 'report.md').read_text()
    assert '](errors.png)' in text and '](short/xy_snapshots.png)' in text and 'states.png' not in text
    assert 'Every figure: `uh-report short`.' in text
    assert 'short/xy_snapshots.png' in (out / 'index.html').read_text()


# ----------------------------------------------------------------------------------------------
# bad input
# ----------------------------------------------------------------------------------------------
def _copy_run(team_run: Path, dest: Path) -> Path:
    (dest / 'bag').mkdir(parents=True)
    for name in ('run.json', 'metrics.json'):
        shutil.copy(team_run / name, dest / name)
    shutil.copy(team_run / 'bag' / 'metadata.yaml', dest / 'bag' / 'metadata.yaml')
    return dest / 'bag' / 'bag_0.mcap'


def _report_error(capsys, *args) -> str:
    from uh_report.report import main
    assert main([str(a) for a in args]) == 2
    err = capsys.readouterr().err
    assert 'uh-report: error:' in err and 'Traceback' not in err
    return err


def test_missing_and_empty_run_directories(tmp_path, capsys):
    assert 'no such run directory' in _report_error(capsys, tmp_path / 'nope')
    (tmp_path / 'empty').mkdir()
    assert 'empty directory, not a run' in _report_error(capsys, tmp_path / 'empty')
    (tmp_path / 'other').mkdir()
    (tmp_path / 'other' / 'notes.txt').write_text('x')
    err = _report_error(capsys, tmp_path / 'other')
    assert 'not a run' in err and 'notes.txt' in err


@pytest.mark.dds
@pytest.mark.slow
def test_truncated_bag_is_named(team_run, tmp_path, capsys):
    mcap = _copy_run(team_run, tmp_path / 'run')
    data = (team_run / 'bag' / 'bag_0.mcap').read_bytes()
    mcap.write_bytes(data[:len(data) // 2])    # what a recorder killed mid-run leaves
    err = _report_error(capsys, tmp_path / 'run')
    assert str(mcap) in err and 'truncated' in err
    assert f'python -m uh_runtime.bags.bag recover {mcap.parent}' in err   # the error says how to fix it


def test_a_bag_that_is_not_mcap_is_named(tmp_path, capsys):
    (tmp_path / 'run' / 'bag').mkdir(parents=True)
    bad = tmp_path / 'run' / 'bag' / 'bag_0.mcap'
    bad.write_bytes(b'SQLite format 3\x00' + bytes(200))
    err = _report_error(capsys, tmp_path / 'run')
    assert str(bad) in err and 'not an MCAP file' in err


@pytest.mark.dds
@pytest.mark.slow
def test_a_damaged_chunk_is_named(team_run, tmp_path, capsys):
    mcap = _copy_run(team_run, tmp_path / 'run')
    mcap.write_bytes(damaged_chunk(team_run / 'bag' / 'bag_0.mcap'))
    err = _report_error(capsys, tmp_path / 'run')
    assert str(mcap) in err and 'corrupted' in err


def test_the_console_script_exits_2_without_traceback(tmp_path):
    exe = Path(sys.executable).with_name('uh-report')
    proc = subprocess.run([str(exe), str(tmp_path / 'missing')], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert 'no such run directory' in proc.stderr and 'Traceback' not in proc.stderr


def test_tables_show_the_fault_isolation_summary_and_a_per_run_table():
    from uh_report.report import ISOLATION_HEAD, html_table, isolation_table
    from uh_report.report import markdown_table as report_table
    entry = {'faulty': True, 'onset': 10.0, 'isolated': True, 'detected_at': 10.56, 'delay': 0.56, 'rho': None,
             'bias': None, 'identifiable': False, 'reason': 'actual input nearly constant', 'rho_true': 0.8,
             'bias_constant_true': 0.0}
    false = dict(entry, faulty=False, onset=None, delay=None, rho_true=1.0, reason='fit too short')
    healthy = dict(false, isolated=False, detected_at=None, reason='not isolated')
    isolation = {'uh2': {'collective': entry, 'tail_rotor': healthy, 'lateral': healthy, 'longitudinal': healthy},
                 'uh4': {'collective': healthy, 'tail_rotor': false, 'lateral': healthy, 'longitudinal': healthy},
                 'summary': {'false_isolations': 1, 'missed': 0, 'max_delay': 0.56}}
    runs = [_run_with_metrics('with', {**_fault_metrics(1.4, 0.5), 'fault_isolation': isolation}),
            _run_with_metrics('older', _fault_metrics(1.4, 0.5))]
    rows = {r[2].strip('`'): r[3:] for r in markdown_table(report_table(runs))[1:]}
    assert rows['fault_isolation.summary.false_isolations'] == ['1', '-']
    assert rows['fault_isolation.summary.missed'] == ['0', '-']
    assert rows['fault_isolation.summary.max_delay'] == ['0.56', '-']
    assert 'fault_isolation.summary.max_delay' in html_table(runs)
    table = isolation_table(runs[0])
    assert len(ISOLATION_HEAD) == len(table[0])
    assert table == [['UH2', 'collective', '10', '0.56', 'n/a', '0.8', 'n/a', '0', 'actual input nearly constant'],
                     ['UH4', 'tail_rotor', '-', 'false isolation', 'n/a', '1', 'n/a', '0', 'fit too short']]
    assert isolation_table(runs[1]) is None
