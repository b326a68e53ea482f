"""``uh-report``: figures and a metrics table of one or several runs (the paper's Figures 4-12).

``uh-report RUN_DIR [RUN_DIR ...] [--out DIR]`` reads each run and writes into ``DIR``:

- ``report.md`` and ``index.html``: the metrics table of all runs side by side (one column per
  run, the numbers of each run's ``metrics.json``, docs/metrics.md), per run a table of its fault
  isolation (each faulted channel's delay, ``rho`` and ``b`` against the truth) and every figure;
- ``metrics_table.csv``: the same table at full precision;
- ``errors.png``, ``errors_per_uh.png``: formation and containment errors, the runs overlaid
  (Figures 10-12 when the runs are proposed, Case I and Case II);
- per run, in ``DIR/<run name>/``: ``states.png`` (Figures 4-7), ``trajectory_3d.png``
  (Figure 8), ``xy_snapshots.png`` (Figure 9), ``faults_uh<i>.png`` for every faulted UH and
  ``false_fault_estimate.png`` (the estimates where no fault acts, against the thresholds; see
  :mod:`uh_report.report_figures`).

A run is a directory written by ``scripts/run_formation.sh`` (``bag/``, ``run.json``,
``metrics.json``; the arrays are read from the bag with :func:`uh_report.bag_metrics.read_team_bag`),
a bare rosbag2 bag directory of such a run, or a directory written by ``uh-simulate``
(``timeseries.npz``, ``metrics.json``). The scenario comes from ``run.json``; for the other kinds
it is ``--scenario`` (default ``paper``). Without ``metrics.json`` the metrics are computed from
the arrays with :func:`uh_team.metrics.metrics_from_arrays` (and the table says so). Reading a run
is :mod:`uh_report.run_data`; this module lays out its tables and writes the report.

``uh-report CAMPAIGN_DIR [--out DIR]`` on a campaign directory (it holds ``campaign.sqlite`` of
``uh-campaign``; it must be the only argument) writes the campaign report of
:mod:`uh_report.campaign_report` instead (default ``DIR`` = ``CAMPAIGN_DIR/report``): success
rates with Wilson intervals, distributions, paired comparisons of the cases, the worst runs with
their re-run commands and the sweep; a missing, damaged or empty results file exits 2.

Exit status: 0 written, 2 bad input (a missing or empty run directory, a bag that is not MCAP,
truncated or damaged, arrays that do not fit the scenario, an unwritable output directory); the
message names the file and what is wrong.
"""
from __future__ import annotations

import argparse
import html
import math
import re
import sys
from pathlib import Path

from uh_core.layout import CHANNEL_NAMES
from uh_runtime.command_line import ArgumentParser, directory_argument
from uh_team.fault_metrics import fault_list
from uh_team.metric_registry import display_unit, report_metrics
from uh_team.metrics import (
    FALSE_ESTIMATE_START,
    FAULT_WINDOW_DELAY,
    LUMPED_FAULTS,
    NOT_MEANINGFUL_MARK,
    NRMSE_FLOOR_P,
    NRMSE_FLOOR_W,
    faulted_uhs,
    nrmse_below_floor,
)

from . import report_figures as F
from .campaign_report import CampaignReportError, is_campaign_dir, write_campaign_report
from .delay_section import DELAY_HEAD, delay_section
from .document import CSS_NUMBERS, NumberCell, csv_text, html_figure, html_page, make_writable_dir
from .document import html_table as html_grid
from .document import markdown_table as markdown_grid
from .run_data import CASE_LABELS, ReportError, RunData, load_run, run_of_arrays

__all__ = ['ReportError', 'RunData', 'load_run', 'run_of_arrays', 'table_rows', 'format_value', 'write_report', 'main',
           'build_parser', 'CASE_LABELS']

PROG = 'uh-report'

#: Heading of the per-run fault isolation table (:func:`isolation_table`).
ISOLATION_HEAD = ('UH', 'channel', 'onset (s)', 'isolated after (s)', 'ρ identified', 'ρ true',
                  'b identified (rad)', 'b constant true (rad)', 'verdict')


#: Heading of the per-run table of faults (:func:`faults_table`).
FAULTS_HEAD = ('UH', 'channel', 'ρ', 'b constant (rad)', 'b amplitude (rad)', 'b frequency (rad/s)',
               'acts from (s)', 'source')
_FAULTS_TEXT = 'Faults: scheduled by the scenario, and injected during the run'


def _unique_names(runs) -> None:
    """Make run names (directories of the per-run figures) and labels unique."""
    seen = {}
    for run in runs:
        base = re.sub(r'[^A-Za-z0-9_.-]+', '_', run.name) or 'run'
        name, k = base, 1
        while name in seen:
            k += 1
            name = f'{base}_{k}'
        seen[name] = run
        run.name = name
    labels = [r.label for r in runs]
    for run in runs:
        if labels.count(run.label) > 1:
            run.label = f'{run.label} [{run.name}]'


# ----------------------------------------------------------------------------------------------
# Table
# ----------------------------------------------------------------------------------------------
def format_value(value) -> str:
    """Table text of one metrics value: 4 significant digits, ``n/a`` for ``None``, ``-`` if absent."""
    if value is None:
        return 'n/a'
    if isinstance(value, bool):
        return str(value)
    if isinstance(value, (int, float)):
        if not math.isfinite(value):
            return str(value)
        return format(float(value), '.4g')
    return str(value)


def _lookup(metrics: dict, key: str):
    """Value of a dotted key (``fault_estimation.uh2.p.nrmse``); a KeyError if absent."""
    value = metrics
    for part in key.split('.'):
        if not isinstance(value, dict) or part not in value:
            raise KeyError(key)
        value = value[part]
    return value


def _fault_estimation_rows(runs) -> list[tuple[str, str, str, str]]:
    """Rows of ``fault_estimation`` (docs/metrics.md): per UH and vector any run scores, its RMS error and NRMSE."""
    scored = {}
    for run in runs:
        for uh, entry in (run.metrics.get('fault_estimation') or {}).items():
            scored.setdefault(uh, set()).update(v.key for v in LUMPED_FAULTS if v.key in entry)
    order = lambda uh: int(re.sub(r'\D', '', uh) or 0)  # noqa: E731
    rows = []
    for uh in sorted(scored, key=order):
        for v in LUMPED_FAULTS:
            if v.key not in scored[uh]:
                continue
            what = f'{uh.upper()} {v.symbol} ({v.loop} loop)'
            rows.append((f'fault_estimation.{uh}.{v.key}.rms_error', f'fault estimation RMS error {what}',
                         display_unit(v.unit), 'lower'))
            rows.append((f'fault_estimation.{uh}.{v.key}.nrmse', f'fault NRMSE {what}', '-', 'lower'))
    return rows


#: Rows of the ``metrics.json`` objects the table lays out itself (a metric with a report row and no label).
_OBJECT_ROWS = {'fault_estimation': _fault_estimation_rows}


def table_rows(runs) -> list[tuple[str, str, str, str | None]]:
    """``[(metrics.json key, what, unit, better), ...]`` of the table for ``runs``; ``better``: lower, higher or None.

    The metrics of :func:`uh_team.metric_registry.report_metrics` in the order of their report rows (docs/metrics.md):
    among them the false fault estimate (maximum over the UHs) of ``F_p`` and ``F_w``, then for every UH and vector any
    run scores the absolute RMS error ``fault_estimation.uh<i>.<p|w>.rms_error`` and the NRMSE
    ``fault_estimation.uh<i>.<p|w>.nrmse``, then the fault isolation's summary (false isolations, missed channels,
    largest delay).
    """
    rows = []
    for metric in report_metrics():
        if metric.label is None:
            rows += _OBJECT_ROWS[metric.key](runs)
        else:
            rows.append((metric.key, metric.label, display_unit(metric.unit), metric.better))
    return rows


def isolation_table(run) -> list[list[str]] | None:
    """Rows (cell texts, columns :data:`ISOLATION_HEAD`) of the fault isolation of ``run``.

    Every faulted channel (isolation delay, identified ``rho`` and ``b`` against the truth, or why they are not
    identifiable) and every falsely isolated one; ``None`` if ``metrics.json`` has no ``fault_isolation`` section (an
    older run, or one without commands).
    """
    section = run.metrics.get('fault_isolation')
    if not section:
        return None
    rows = []
    for uh, channels in section.items():
        for name, e in (channels.items() if uh != 'summary' else ()):
            if not (e['faulty'] or e['isolated']):
                continue
            after = (format_value(e['delay']) if e['faulty'] else 'false isolation') if e['isolated'] \
                else 'not isolated'
            rows.append([uh.upper(), name, format_value(e['onset']) if e['faulty'] else '-', after,
                         format_value(e['rho']), format_value(e['rho_true']), format_value(e['bias']),
                         format_value(e['bias_constant_true']), e['reason']])
    return rows


def faults_table(run) -> list[list[str]]:
    """Rows (cell texts, columns :data:`FAULTS_HEAD`) of the faults of ``run``: scheduled ones, then injected ones.

    From ``metrics.json``'s ``faults``, else from the scenario and the arrays
    (:func:`uh_team.fault_metrics.fault_list`). An injection that clears its channel says so.
    """
    faults = run.metrics.get('faults') or fault_list(run.scenario, run.arrays)
    rows = []
    for source, entries in (('scheduled', faults.get('scheduled', ())), ('injected', faults.get('injected', ()))):
        for f in entries:
            if source == 'scheduled':
                origin = 'scheduled'
            else:
                origin = f'injected, received at {format_value(f["received_s"])} s' + \
                    (' (clears the channel)' if f.get('nominal') else '')
            rows.append([f'UH{f["uh"]}', CHANNEL_NAMES[int(f['channel'])], *(format_value(f[k]) for k in (
                'rho', 'bias_constant', 'bias_amplitude', 'bias_frequency', 'onset_time')), origin])
    return rows


def _faults_section(run, grid, paragraph) -> str:
    """Render the per-run table of faults (:func:`faults_table`), or a sentence when the run had none."""
    rows = faults_table(run)
    return grid(FAULTS_HEAD, rows) if rows else paragraph('No fault: none scheduled, none injected.')


def _markdown_text(head, rows) -> str:
    """Return a Markdown table of texts, ending with a line break."""
    return '\n'.join(markdown_grid(head, rows)) + '\n'


def _html_grid(head, rows) -> str:
    """Return an HTML table of texts, quotes escaped like every text of the run report's page."""
    return html_grid(head, rows, quote=True)


def _html_paragraph(text: str) -> str:
    return f'<p>{html.escape(text)}</p>'


def _isolation_section(run, grid, paragraph) -> str:
    """Render the per-run fault isolation table, or a sentence when there is none.

    The table is rendered by ``grid`` (:func:`_markdown_text` or :func:`_html_grid`), the sentence
    by ``paragraph``.
    """
    rows = isolation_table(run)
    if rows is None:
        return paragraph('No fault isolation in metrics.json.')
    return grid(ISOLATION_HEAD, rows) if rows else paragraph('No faulted or isolated channel.')


def _delay_parts(run, grid, paragraph) -> list:
    """Render the run's communication-delay section (:mod:`.delay_section`): [] when it has none."""
    section = delay_section(run)
    if section is None:
        return []
    sentence, rows = section
    return [paragraph(sentence)] + ([grid(DELAY_HEAD, rows)] if rows else [])


def _table_value(metrics: dict, key: str):
    """Return the value of ``key`` as the tables show it.

    That of ``metrics.json``, except an NRMSE withheld below its floor, which is
    :data:`uh_team.metrics.NOT_MEANINGFUL_MARK` (not ``n/a``: it is defined, just not a measure of the estimator). A
    KeyError if absent.
    """
    value = _lookup(metrics, key)
    if value is None and key.startswith('fault_estimation.') and key.endswith('.nrmse'):
        if nrmse_below_floor(_lookup(metrics, key.rpartition('.')[0])):
            return NOT_MEANINGFUL_MARK
    return value


def _cells(runs, key: str, better: str | None, bold: bool) -> list[str]:
    values = []
    for run in runs:
        try:
            values.append(_table_value(run.metrics, key))
        except KeyError:
            values.append(KeyError)
    texts = ['-' if v is KeyError else format_value(v) for v in values]
    numeric = [float(v) for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)
               and math.isfinite(v)]
    if bold and better is not None and len(runs) > 1 and len(numeric) > 1:
        best = (min if better == 'lower' else max)(float(format_value(v)) for v in numeric)
        texts = [f'**{t}**' if v is not KeyError and isinstance(v, (int, float)) and not isinstance(v, bool)
                 and math.isfinite(v) and float(t) == best else t for t, v in zip(texts, values, strict=True)]
    return texts


def _source_text(run) -> str:
    kind = 'distributed run (MCAP bag)' if run.source == 'bag' else 'reference simulation (uh-simulate)'
    return kind + ('' if run.metrics_source == 'metrics.json' else ', metrics computed by uh-report')


def _metric_table(runs) -> tuple[list, list]:
    """``(head, rows)`` of the metrics table: one row per metric, one column per run (best value in bold).

    The cells of the runs' values are :class:`uh_report.document.NumberCell`; ``None`` is an empty cell.
    """
    head = ['metric', 'unit', 'metrics.json key'] + [r.label for r in runs]
    rows = [['run directory', None, None] + [f'`{r.directory.name}`' for r in runs],
            ['source', None, None] + [_source_text(r) for r in runs]]
    for key, what, unit, better in table_rows(runs):
        rows.append([what, unit, f'`{key}`'] + [NumberCell(t) for t in _cells(runs, key, better, True)])
    return head, rows


def markdown_table(runs) -> str:
    """Return the metrics table in Markdown: one row per metric, one column per run (best value in bold)."""
    head, rows = _metric_table(runs)
    return '\n'.join(markdown_grid(head, rows, right_aligned=range(3, len(head)))) + '\n'


def _csv_cell(value) -> str:
    """CSV text of a metrics value at full precision: ``repr`` of a float, ``null`` for ``None``, empty if absent."""
    if value is KeyError:
        return ''
    return 'null' if value is None else repr(value) if isinstance(value, float) else str(value)


def csv_table(runs) -> str:
    """Return the metrics table as CSV at full precision (``repr`` of each number of ``metrics.json``)."""
    rows = []
    for key, _what, _unit, _better in table_rows(runs):
        row = [key]
        for run in runs:
            try:
                row.append(_table_value(run.metrics, key))
            except KeyError:
                row.append(KeyError)
        rows.append(row)
    return csv_text(['key'] + [r.name for r in runs], rows, _csv_cell)


def html_table(runs) -> str:
    """Return the metrics table in HTML, as :func:`markdown_table`."""
    return _html_grid(*_metric_table(runs))


# ----------------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------------
_FIGURE_TEXT = {
    'errors': 'Formation and containment errors (RMS over leaders / followers), runs overlaid (paper Figures 10-12)',
    'errors_per_uh': 'Error of each UH, runs overlaid',
    'states': 'x, y, z and yaw of every UH with the virtual leader (paper Figures 4-7)',
    'trajectory_3d': '3-D trajectories and the three orthogonal planes (paper Figure 8)',
    'xy_snapshots': "XY plane with snapshots of the leaders' triangle and the followers (paper Figure 9)",
    'topology': 'Communication graph before and after each loss: roles, promotions, repaired edges',
}


_DELAY_TEXT = 'Communication delay: the team\'s delay margin and the neighbour ages each controller measured'
_ISOLATION_TEXT = 'Fault isolation: delay after the onset, ρ and b identified vs truth, or why not'


def _figure_text(key: str) -> str:
    if key == 'false_fault_estimate':
        return ('Fault estimates ‖F̂_p‖ and ‖F̂_w‖ where no fault acts (healthy UHs; faulted UHs before the '
                'onset) against the false-estimate thresholds')
    if key.startswith('faults_uh'):
        return f'Estimated vs true lumped faults of UH{key[9:]} (position and attitude loops)'
    return _FIGURE_TEXT.get(key, key)


def write_figures(runs, out: Path, kinds=None) -> dict:
    """Draw the figures ``kinds`` (every one when None); returns ``{'errors': path, ..., run.name: {kind: path}}``.

    The kinds: ``errors``, ``errors_per_uh`` (the runs overlaid); per run ``states``,
    ``trajectory_3d``, ``xy_snapshots``, ``faults`` (one figure per faulted UH),
    ``false_fault_estimate`` and, for a run that lost UHs, ``topology``.
    """
    wanted = (lambda kind: True) if kinds is None else (lambda kind: kind in kinds)  # noqa: E731
    written = {key: plot(runs, out / f'{key}.png')
               for key, plot in (('errors', F.plot_errors), ('errors_per_uh', F.plot_errors_per_uh)) if wanted(key)}
    for run in runs:
        d = out / run.name
        d.mkdir(parents=True, exist_ok=True)
        # drawn below, in this iteration (``run`` bound explicitly all the same)
        plots = [(key, lambda path, plot=plot, run=run: plot(run, path)) for key, plot in
                 (('states', F.plot_states), ('trajectory_3d', F.plot_trajectory_3d),
                  ('xy_snapshots', F.plot_xy_snapshots))]
        plots += [(f'faults_uh{uh}', lambda path, uh=uh, run=run: F.plot_faults(run, uh, path))
                  for uh in faulted_uhs(run.scenario, run.arrays) if wanted('faults')]
        plots.append(('false_fault_estimate', lambda path, run=run: F.plot_false_fault_estimate(run, path)))
        if F.has_losses(run):
            plots.append(('topology', lambda path, run=run: F.plot_topology(run, path)))
        run.figures = {key: plot(d / f'{key}.png') for key, plot in plots
                       if key.startswith('faults_uh') or wanted(key)}
        written[run.name] = dict(run.figures)
    return written


def _title(runs) -> str:
    return 'Run report: ' + ' vs '.join(r.label for r in runs)


def _notes(runs) -> list[str]:
    settle = sorted({r.metrics.get('settle_time_s') for r in runs if r.metrics.get('settle_time_s') is not None})
    settle_text = ', '.join(f'{s:g}' for s in settle) or 'the settle time'
    return [
        'Metrics of docs/metrics.md (`uh_team/metrics.py`), copied from each run\'s `metrics.json` '
        '(4 significant digits; full precision in `metrics_table.csv`). Bold: the lowest value of a row.',
        f'MSE and CPI cover the whole run; RMS errors and the hull distance the samples after t = {settle_text} s. '
        f'False fault estimate: RMS of ‖F̂‖ on the healthy UHs from {FALSE_ESTIMATE_START:g} s to the end and on '
        f'the faulted UHs from {FALSE_ESTIMATE_START:g} s to their onset. Fault estimation: RMS ‖F̂ − F‖ from the '
        f'onset + {FAULT_WINDOW_DELAY:g} s to the end, `F_p` only for a UH with a collective fault; NRMSE = that '
        f'/ RMS ‖F‖, `{NOT_MEANINGFUL_MARK}` (not meaningful) when RMS ‖F‖ is below the floor '
        f'({NRMSE_FLOOR_P:g} m/s² for `F_p`, {NRMSE_FLOOR_W:g} rad/s² for `F_w`). `n/a`: undefined (e.g. the '
        'run ends before the settle time); `-`: the run does not have that entry.',
        'Fault isolation: the verdicts of the isolator every controller runs, as each controller '
        'published them on its last `/uhN/status` (a recorded run) or recomputed over the run\'s arrays '
        '(an in-process run: the same computation); false isolations count isolated channels that are '
        'not faulty (healthy UHs included), the delay is from the channel\'s onset '
        '(docs/faults.md#isolation-and-identification).',
    ]


def _markdown_report(runs, figures: dict, rel, hint: str | None = None) -> str:
    """Return ``report.md``.

    The runs, the metrics table and its notes, the comparison figures, per run its fault isolation
    and figures; ``rel`` gives a figure's path relative to the report.
    """
    md = [f'# {_title(runs)}', '', 'Runs:', '']
    for run in runs:
        md.append(f'- **{run.label}**: `{run.directory}` ({_source_text(run)}, scenario `{run.scenario.name}`, '
                  f'{run.metrics.get("sim_time_s", float("nan")):g} s simulated)')
    md += ['', '## Metrics', '', markdown_table(runs)]
    md += [f'{n}\n' for n in _notes(runs) + ([hint] if hint else [])]
    md += ['## Comparison figures', '']
    for key in ('errors', 'errors_per_uh'):
        if key in figures:
            md += [f'### {_figure_text(key)}', '', f'![{key}]({rel(figures[key])})', '']
    for run in runs:
        md += [f'## {run.label} (`{run.directory.name}`)', '', f'### {_FAULTS_TEXT}', '',
               _faults_section(run, _markdown_text, str), '', f'### {_ISOLATION_TEXT}', '',
               _isolation_section(run, _markdown_text, str), '']
        delay = _delay_parts(run, _markdown_text, str)
        md += [f'### {_DELAY_TEXT}', '', *[f'{part}\n' for part in delay]] if delay else []
        for key, path in run.figures.items():
            md += [f'### {_figure_text(key)}', '', f'![{run.name} {key}]({rel(path)})', '']
    return '\n'.join(md)


def _html_report(runs, figures: dict, rel, hint: str | None = None) -> str:
    """``index.html``: the content of :func:`_markdown_report` as an HTML page."""
    parts = [f'<h1>{html.escape(_title(runs))}</h1>',
             '<ul>' + ''.join(f'<li><b>{html.escape(r.label)}</b>: <code>{html.escape(str(r.directory))}</code> '
                              f'({html.escape(_source_text(r))})</li>' for r in runs) + '</ul>',
             '<h2>Metrics</h2>', html_table(runs)]
    parts += [f'<p>{html.escape(n).replace("`", "")}</p>' for n in _notes(runs) + ([hint] if hint else [])]
    parts.append('<h2>Comparison figures</h2>')
    parts += [html_figure(rel(figures[key]), _figure_text(key), alt=key)
              for key in ('errors', 'errors_per_uh') if key in figures]
    for run in runs:
        parts.append(f'<h2>{html.escape(run.label)} <small><code>{html.escape(str(run.directory))}</code></small></h2>')
        parts.append(f'<h3>{html.escape(_FAULTS_TEXT)}</h3>\n{_faults_section(run, _html_grid, _html_paragraph)}')
        parts.append(f'<h3>{html.escape(_ISOLATION_TEXT)}</h3>\n{_isolation_section(run, _html_grid, _html_paragraph)}')
        delay = _delay_parts(run, _html_grid, _html_paragraph)
        if delay:
            parts.append(f'<h3>{html.escape(_DELAY_TEXT)}</h3>\n' + '\n'.join(delay))
        for key, path in run.figures.items():
            parts.append(html_figure(rel(path), _figure_text(key), alt=run.name + ' ' + key))
    return html_page(_title(runs), '\n'.join(parts), css=(CSS_NUMBERS,))


def write_report(runs, out: Path, kinds=None, hint: str | None = None) -> Path:
    """Write the figures ``kinds`` (every one when None), ``report.md``, ``index.html`` and ``metrics_table.csv``.

    ``hint`` is a line added to the notes (e.g. how to draw the figures left out).
    """
    _unique_names(runs)
    make_writable_dir(out, ReportError)
    figures = write_figures(runs, out, kinds)
    (out / 'metrics_table.csv').write_text(csv_table(runs))
    rel = lambda p: p.relative_to(out).as_posix()  # noqa: E731
    (out / 'report.md').write_text(_markdown_report(runs, figures, rel, hint))
    (out / 'index.html').write_text(_html_report(runs, figures, rel, hint))
    return out / 'report.md'


# ----------------------------------------------------------------------------------------------
# Entry point
# ----------------------------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``uh-report``."""
    p = ArgumentParser(
        prog=PROG,
        description='Figures (the paper\'s Figures 4-12) and a side-by-side metrics table of one or '
                    'several runs of run_formation.sh (MCAP bag) or uh-simulate (timeseries.npz).',
        epilog='Example: uh-report runs/proposed runs/case1 runs/case2 --out runs/report')
    p.add_argument('runs', nargs='+', metavar='RUN_DIR',
                   help='run directories (or bag directories), or one campaign directory (campaign.sqlite)')
    p.add_argument('--out', type=directory_argument, default=None,
                   help='output directory (default: RUN_DIR/report for one run, report/ next to the runs for several)')
    p.add_argument('--scenario', default='paper',
                   help='scenario of runs without run.json (uh-simulate output, bare bags); default paper')
    p.add_argument('--labels', nargs='+', default=None, metavar='LABEL',
                   help='legend/table names of the runs, in order (default: from the controller case)')
    return p


def _default_out(run_dirs) -> Path:
    if len(run_dirs) == 1:
        return Path(run_dirs[0]) / 'report'
    parents = {Path(d).resolve().parent for d in run_dirs}
    return (parents.pop() if len(parents) == 1 else Path.cwd()) / 'report'


def _fail(message: str, status: int = 2) -> int:
    print(f'{PROG}: error: {message}', file=sys.stderr)
    return status


def _campaign_main(args, campaign_dir) -> int:
    """``uh-report CAMPAIGN_DIR [--out DIR]``: the report of :mod:`uh_report.campaign_report`."""
    if len(args.runs) != 1:
        return _fail(f'{campaign_dir} is a campaign directory (campaign.sqlite); a campaign is reported on its '
                     f'own: uh-report {campaign_dir} [--out DIR]')
    if args.labels:
        return _fail('--labels does not apply to a campaign report')
    base = Path(campaign_dir) if Path(campaign_dir).is_dir() else Path(campaign_dir).parent
    out = args.out or base / 'report'
    print(f'[report] reading campaign {campaign_dir}', file=sys.stderr, flush=True)
    try:
        report = write_campaign_report(campaign_dir, out, CASE_LABELS)
    except CampaignReportError as exc:
        return _fail(str(exc))
    print(f'[report] wrote {report}, {out / "index.html"}, the figures and the CSV files in {out}', file=sys.stderr)
    return 0


def main(argv=None) -> int:
    """Entry point of ``uh-report``; returns the exit status (see the module docstring)."""
    import matplotlib  # a file-only backend before any figure: uh-report draws without a display
    matplotlib.use('Agg')

    args = build_parser().parse_args(argv)
    if any(not str(d).strip() for d in args.runs):
        return _fail("RUN_DIR '': give a run directory (e.g. runs/proposed)")
    campaigns = [d for d in args.runs if is_campaign_dir(d)]
    if campaigns:
        return _campaign_main(args, campaigns[0])
    if args.labels is not None and len(args.labels) != len(args.runs):
        return _fail(f'--labels gives {len(args.labels)} names for {len(args.runs)} runs')
    try:
        runs = []
        for run_dir in args.runs:
            print(f'[report] reading {run_dir}', file=sys.stderr, flush=True)
            runs.append(load_run(run_dir, args.scenario))
        if args.labels:
            for run, label in zip(runs, args.labels, strict=True):
                run.label = label
        ids = {tuple(r.scenario.ids) for r in runs}
        if len(ids) > 1:
            return _fail('the runs have different teams (UH ids ' + ', '.join(map(str, sorted(ids))) +
                         '); compare runs of one scenario')
        out = args.out or _default_out(args.runs)
        report = write_report(runs, out)
    except ReportError as exc:
        return _fail(str(exc))
    print(f'[report] wrote {report}, {out / "index.html"} and the figures in {out}', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
