"""``uh-report DIR`` on a campaign directory: statistics over the runs of a Monte Carlo campaign.

A campaign directory holds ``campaign.sqlite`` (:mod:`uh_team.campaign_store`, one row per run:
a draw, a sweep point and a controller case). The same draw is run for every case and every sweep
value, so cases can be compared *paired* over the draws. :func:`write_campaign_report` writes into
the output directory:

- ``report.md`` and ``index.html``: the header (name, seed, cases, success thresholds, ``N of M
  runs done``, ok/diverged/failed per case, failures grouped by reason), the success rate per case
  with its 95 % Wilson interval, the distributions (median, 90th percentile, max and the draw of
  the max), the paired comparisons of every two cases, the worst runs with the commands that
  re-run them, and the sweep (when the campaign has one);
- ``cdf_<metric>.png``: empirical CDF of ``formation_rms_m``, ``containment_rms_m``,
  ``fault_error_w``, ``fault_error_p`` and ``false_fault_w``, cases overlaid (log x-axis when the
  values span two decades or more);
- ``sweep.png``: median and interquartile range of the formation and containment RMS, and the
  success rate with its Wilson interval, against the swept value (only with a sweep);
- ``summary.csv`` (one row per case), ``paired.csv``, ``worst_runs.csv``, ``sweep.csv`` (only with
  a sweep) and ``runs.csv`` (every stored row, full precision).

The report is made of :mod:`.campaign_load` (the results file read back), :mod:`.campaign_stats`
(pure functions of the ``{column: ndarray}`` of :func:`uh_team.campaign_store.read_runs`, testable
without plotting), :mod:`.campaign_figures` (the figures) and :mod:`.document` (the one Markdown and
HTML renderer of the run and campaign reports); this module writes its sections and CSV files, and
every public name of those modules a caller of the report needs is importable from here.
"""
from __future__ import annotations

import json
import math
from itertools import combinations
from pathlib import Path

import numpy as np

from uh_team.campaign_store import DB_NAME, METRIC_COLUMNS, RUN_COLUMNS

from .campaign_figures import LOG_SPAN_RATIO, plot_distribution, plot_sweep
from .campaign_load import CASE_ORDER, Campaign, CampaignReportError, is_campaign_dir, load_campaign
from .campaign_stats import (
    BOOTSTRAP_RESAMPLES,
    BOOTSTRAP_SEED,
    CONFIDENCE,
    DISTRIBUTION_METRICS,
    METRIC_UNITS,
    PAIRED_METRICS,
    SWEEP_METRICS,
    WORST_COUNT,
    bootstrap_median_ci,
    distribution_summary,
    ecdf,
    failure_groups,
    paired_comparison,
    paired_differences,
    reason_pattern,
    rerun_commands,
    status_counts,
    success_rate,
    success_table,
    sweep_table,
    wilcoxon_p,
    wilson_interval,
    worst_runs,
)
from .document import Document, csv_text, make_writable_dir

__all__ = ['CampaignReportError', 'Campaign', 'is_campaign_dir', 'load_campaign', 'wilson_interval',
           'status_counts', 'success_rate', 'success_table', 'failure_groups', 'distribution_summary', 'ecdf',
           'paired_differences', 'bootstrap_median_ci', 'wilcoxon_p', 'paired_comparison', 'worst_runs',
           'rerun_commands', 'sweep_table', 'write_campaign_report',
           'DISTRIBUTION_METRICS', 'PAIRED_METRICS', 'SWEEP_METRICS', 'CASE_ORDER',
           # also importable from here, as before the report was split by concern
           'reason_pattern', 'plot_distribution', 'plot_sweep', 'make_writable_dir', 'METRIC_UNITS', 'WORST_COUNT',
           'CONFIDENCE', 'BOOTSTRAP_RESAMPLES', 'BOOTSTRAP_SEED', 'LOG_SPAN_RATIO']


# ----------------------------------------------------------------------------------------------
# Text
# ----------------------------------------------------------------------------------------------
def _num(value) -> str:
    """Table text of a number: 4 significant digits, ``n/a`` for NaN or None."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return 'n/a'
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return format(float(value), '.4g')


def _percent(value) -> str:
    return 'n/a' if value is None or not math.isfinite(value) else f'{100.0 * value:.1f} %'


def _interval(low, high, percent: bool = False) -> str:
    if not (math.isfinite(low) and math.isfinite(high)):
        return 'n/a'
    return f'[{_percent(low)}, {_percent(high)}]' if percent else f'[{_num(low)}, {_num(high)}]'


def _csv_value(value) -> str:
    """CSV text at full precision (``repr`` of floats), empty for NaN/None."""
    if value is None or (isinstance(value, (float, np.floating)) and not math.isfinite(value)):
        return ''
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, (np.integer,)):
        return str(int(value))
    if isinstance(value, (dict, list)):
        return json.dumps(value)
    return str(value)


def _csv(head, rows) -> str:
    return csv_text(head, rows, _csv_value)


# ----------------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------------
def _label(case: str, labels: dict | None) -> str:
    """``case = display name`` (header), or the case name alone when it has no other name."""
    label = (labels or {}).get(case, case)
    return case if label == case else f'{case} = {label}'


def _duration(meta: dict):
    """Return the campaign's simulated duration (s) if the store gives a positive number, else None."""
    value = meta.get('duration')
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value) and value > 0 else None


def _header(doc: Document, campaign: Campaign, labels) -> None:
    meta, runs = campaign.meta, campaign.runs
    done = campaign.done_runs
    if campaign.planned_runs:
        draws, n_sweep = meta.get('runs'), max(1, len(campaign.sweep_values))
        progress = (f'**{done} of {campaign.planned_runs} runs done** ({draws} draws x '
                    f'{len(meta.get("cases") or [])} cases' + (f' x {n_sweep} sweep points' if campaign.sweep_values
                                                                   else '') + ')')
        if done < campaign.planned_runs:
            progress += '; the campaign is not complete: this report covers the runs stored so far'
    else:
        progress = f'**{done} runs done** (the store does not give the planned number)'
    thresholds = meta.get('success')
    threshold_text = ', '.join(f'`{k}` ≤ {v:g}' if isinstance(v, (int, float)) else f'`{k}`: {v}'
                               for k, v in thresholds.items()) if isinstance(thresholds, dict) and thresholds \
        else 'none stored'
    items = [progress,
             'cases: ' + ', '.join(_label(c, labels) for c in campaign.cases),
             f'seed: {meta.get("seed", "n/a")}',
             f'success thresholds (an ok run is successful when every one holds): {threshold_text}']
    if campaign.sweep_parameter:
        items.append(f'sweep: `{campaign.sweep_parameter}` over {", ".join(map(str, campaign.sweep_values))}')
    if _duration(meta) is not None:
        items.append(f'simulated duration: {_duration(meta):g} s')
    for key, what in (('spec_path', 'spec'), ('created', 'created')):
        if meta.get(key):
            items.append(f'{what}: `{meta[key]}`')
    if isinstance(meta.get('versions'), dict) and meta['versions']:
        items.append('versions: ' + ', '.join(f'{k} {v}' for k, v in meta['versions'].items()))
    items.append(f'results: `{campaign.directory / DB_NAME}`')
    doc.heading(1, f'Campaign report: {campaign.name}')
    doc.bullets(items)

    doc.heading(2, 'Runs by status')
    counts = status_counts(runs, campaign.cases)
    doc.table(['case', 'runs', 'ok', 'diverged', 'failed'],
              [[c, *(counts[c][k] for k in ('runs', 'ok', 'diverged', 'failed'))]
               for c in campaign.cases])
    groups = failure_groups(runs)
    if groups:
        doc.paragraph('Diverged and failed runs, grouped by reason (numbers in the reason replaced by N):')
        doc.table(['status', 'reason', 'runs', 'cases', 'example draws', 'example reason'],
                  [[g['status'], g['pattern'], g['count'], ', '.join(f'{c}: {n}' for c, n in g['cases'].items()),
                    ', '.join(map(str, g['draws'])), g['example']] for g in groups])
    else:
        doc.paragraph('No run diverged or failed.')


def _success_section(doc: Document, campaign: Campaign) -> list[dict]:
    rows = success_table(campaign.runs, campaign.cases)
    doc.heading(2, 'Success rate')
    pooled = ' (all sweep points pooled; per sweep point in the Sweep section)' if campaign.sweep_parameter else ''
    doc.paragraph(f'Successful: the run ended ok and met every success threshold; diverged and failed runs count '
                  f'as not successful. Interval: 95 % Wilson score interval{pooled}.')
    doc.table(['case', 'successful / runs', 'success rate', '95 % Wilson interval'],
              [[r['case'], f'{r["successes"]} / {r["runs"]}', _percent(r['rate']),
                _interval(r['ci_low'], r['ci_high'], percent=True)] for r in rows])
    if not np.any(campaign.runs['success'] != -1):
        doc.paragraph('Note: no run has a stored success verdict, so every rate is 0.')
    return rows


def _distribution_section(doc: Document, campaign: Campaign, out: Path, labels) -> dict:
    doc.heading(2, 'Distributions')
    doc.paragraph('Over the ok runs of each case with a defined value (all sweep points pooled). p90: 90th '
                  'percentile (linear interpolation).')
    summaries = {}
    rows = []
    for metric in DISTRIBUTION_METRICS:
        summaries[metric] = distribution_summary(campaign.runs, campaign.cases, metric)
        for r in summaries[metric]:
            at = 'n/a' if r['max_draw'] is None else f'draw {r["max_draw"]}' + (
                f', {campaign.sweep_parameter} = {_num(r["max_sweep_value"])}' if campaign.sweep_parameter else '')
            rows.append([f'`{metric}`', METRIC_UNITS.get(metric, '-'), r['case'], r['n'],
                         _num(r['median']), _num(r['p90']), _num(r['max']), at])
    doc.table(['metric', 'unit', 'case', 'n', 'median', 'p90', 'max', 'max at'], rows)
    for metric in DISTRIBUTION_METRICS:
        path = plot_distribution(campaign.runs, campaign.cases, metric, out / f'cdf_{metric}.png', labels)
        doc.heading(3, f'{metric} ({METRIC_UNITS.get(metric, "-")})')
        if path is None:
            doc.paragraph(f'No ok run has a value of `{metric}` (e.g. no fault on that channel).')
        else:
            doc.figure(path.name, f'Empirical CDF of {metric}, cases overlaid')
    return summaries


def _paired_section(doc: Document, campaign: Campaign) -> list[dict]:
    doc.heading(2, 'Paired comparisons')
    swept = bool(campaign.sweep_parameter)
    doc.paragraph('Each pair of cases over the same draws' + (' at each sweep point (the draws of one sweep point '
                  'are independent, those of several are not)' if swept else '') + ', where both runs ended ok; '
                  '"excluded": draws where one of the two did not. Difference = first − second (negative: the '
                  'first is better, every metric is lower-is-better). '
                  f'"first better": fraction of pairs with a strictly lower value for the first case. CI: '
                  f'percentile bootstrap of the median difference ({BOOTSTRAP_RESAMPLES} resamples, seed '
                  f'{BOOTSTRAP_SEED}). p: two-sided Wilcoxon signed-rank test (zero differences dropped).')
    points = list(range(len(campaign.sweep_values))) if swept else [None]
    results = [paired_comparison(campaign.runs, a, b, metric, sweep_index=k)
               for k in points for a, b in combinations(campaign.cases, 2) for metric in PAIRED_METRICS]
    for r in results:
        r['sweep_value'] = campaign.sweep_values[r['sweep_index']] if swept else None
    if not results:
        doc.paragraph('Only one case: nothing to compare.')
        return results
    doc.table(['first vs second'] + ([campaign.sweep_parameter] if swept else []) +
              ['metric', 'pairs', 'excluded', 'first better', 'median difference', '95 % CI', 'Wilcoxon p'],
              [[f'{r["first"]} vs {r["second"]}'] + ([_num(r['sweep_value'])] if swept else []) +
               [f'`{r["metric"]}` ({METRIC_UNITS.get(r["metric"], "-")})',
                r['pairs'], r['excluded'], _percent(r['first_better']), _num(r['median_difference']),
                _interval(r['ci_low'], r['ci_high']),
                _num(r['wilcoxon_p']) if math.isfinite(r['wilcoxon_p']) else f'n/a ({r["note"]})'] for r in results])
    return results


def _worst_section(doc: Document, campaign: Campaign) -> list[dict]:
    runs = campaign.runs
    doc.heading(2, 'Worst runs')
    doc.paragraph(f'The {WORST_COUNT} worst runs of each case: failed, then diverged, then by `formation_rms_m` + '
                  '`containment_rms_m` (largest first). Each comes with the command that re-runs it as a '
                  'distributed lockstep run recorded to a bag, and the in-process equivalent.')
    entries = []
    for case in campaign.cases:
        index = worst_runs(runs, case)
        if not index:
            continue
        doc.heading(3, case)
        head = ['#', 'draw'] + ([campaign.sweep_parameter] if campaign.sweep_parameter else []) + [
            'status', 'formation_rms_m', 'containment_rms_m', 'fault_error_p', 'fault_error_w', 'false_fault_w',
            'reason']
        rows, commands = [], []
        for rank, i in enumerate(index, 1):
            draw = int(runs['draw'][i])
            sweep_index = int(runs['sweep_index'][i]) if campaign.sweep_parameter else None
            scenario_file = runs['scenario_file'][i]
            if scenario_file:
                distributed, in_process = rerun_commands(campaign.directory, scenario_file, case, campaign.name,
                                                         draw, sweep_index)
            else:   # the draw's scenario could not be made (e.g. no valid random graph): nothing to re-run
                distributed = in_process = '# no scenario to re-run: the draw could not be resolved'
                scenario_file = ''
            entry = {'case': case, 'rank': rank, 'draw': draw, 'sweep_index': int(runs['sweep_index'][i]),
                     'sweep_value': float(runs['sweep_value'][i]), 'status': str(runs['status'][i]),
                     'reason': ' '.join(str(runs['reason'][i] or '').split()), 'scenario_file': scenario_file,
                     **{m: float(runs[m][i]) for m in METRIC_COLUMNS},
                     'rerun_distributed': distributed, 'rerun_in_process': in_process}
            entries.append(entry)
            rows.append([rank, draw] + ([_num(entry['sweep_value'])] if campaign.sweep_parameter else []) + [
                entry['status'], *(_num(entry[m]) for m in ('formation_rms_m', 'containment_rms_m', 'fault_error_p',
                                                            'fault_error_w', 'false_fault_w')),
                entry['reason'] or '-'])
            commands += [f'# {rank}: draw {draw}, {case}', distributed, in_process]
        doc.table(head, rows)
        doc.code('\n'.join(commands))
    return entries


def _sweep_section(doc: Document, campaign: Campaign, out: Path, labels) -> list[dict]:
    doc.heading(2, 'Sweep')
    if not campaign.sweep_parameter:
        doc.paragraph('This campaign has no sweep (no `sweep_parameter` in its spec).')
        return []
    table = sweep_table(campaign.runs, campaign.cases, campaign.sweep_values)
    doc.paragraph(f'`{campaign.sweep_parameter}` swept over {", ".join(map(str, campaign.sweep_values))}. Median '
                  'and interquartile range (25th-75th percentile) over the ok runs; success rate over all runs at '
                  'the sweep point with its 95 % Wilson interval.')
    path = plot_sweep(table, campaign.cases, campaign.sweep_parameter, out / 'sweep.png', labels)
    doc.figure(path.name, f'formation and containment RMS and success rate against {campaign.sweep_parameter}')
    doc.table(['case', campaign.sweep_parameter, 'runs', 'ok', 'formation_rms_m median [IQR] (m)',
               'containment_rms_m median [IQR] (m)', 'success rate', '95 % Wilson interval'],
              [[r['case'], _num(r['sweep_value']), r['runs'], r['ok'],
                *(f'{_num(r[f"{m}_median"])} [{_num(r[f"{m}_q25"])}, {_num(r[f"{m}_q75"])}]' for m in SWEEP_METRICS),
                _percent(r['rate']), _interval(r['ci_low'], r['ci_high'], percent=True)] for r in table])
    return table


def _write_csvs(out: Path, campaign: Campaign, success: list, summaries: dict, paired: list, worst: list,
                sweep: list) -> None:
    counts = status_counts(campaign.runs, campaign.cases)
    head = ['case', 'runs', 'ok', 'diverged', 'failed', 'successes', 'success_rate', 'success_ci_low',
            'success_ci_high']
    for metric in DISTRIBUTION_METRICS:
        head += [f'{metric}_{k}' for k in ('n', 'median', 'p90', 'max', 'max_draw', 'max_sweep_value')]
    rows = []
    for case, rate in zip(campaign.cases, success, strict=False):
        row = [case, *(counts[case][k] for k in ('runs', 'ok', 'diverged', 'failed')), rate['successes'],
               rate['rate'], rate['ci_low'], rate['ci_high']]
        for metric in DISTRIBUTION_METRICS:
            s = next(r for r in summaries[metric] if r['case'] == case)
            row += [s['n'], s['median'], s['p90'], s['max'], s['max_draw'], s['max_sweep_value']]
        rows.append(row)
    (out / 'summary.csv').write_text(_csv(head, rows))

    paired_keys = ['first', 'second', 'sweep_index', 'sweep_value', 'metric', 'pairs', 'excluded', 'first_better',
                   'ties', 'median_difference', 'ci_low', 'ci_high', 'wilcoxon_p', 'note']
    (out / 'paired.csv').write_text(_csv(paired_keys, [[r[k] for k in paired_keys] for r in paired]))

    worst_keys = ['case', 'rank', 'draw', 'sweep_index', 'sweep_value', 'status', 'reason', 'scenario_file',
                  *METRIC_COLUMNS, 'rerun_distributed', 'rerun_in_process']
    (out / 'worst_runs.csv').write_text(_csv(worst_keys, [[e[k] for k in worst_keys] for e in worst]))

    if sweep:
        (out / 'sweep.csv').write_text(_csv(list(sweep[0]), [list(r.values()) for r in sweep]))

    names = [name for name, _ in RUN_COLUMNS]
    runs = campaign.runs
    stored = lambda n, i: None if n == 'success' and runs[n][i] == -1 else runs[n][i]  # noqa: E731 (-1: NULL)
    (out / 'runs.csv').write_text(_csv(names, [[stored(n, i) for n in names] for i in range(campaign.done_runs)]))


def write_campaign_report(campaign, out, case_labels: dict | None = None) -> Path:
    """Write the campaign report (see the module docstring) into ``out``; returns ``out/report.md``.

    Parameters
    ----------
    campaign : Campaign or path
        A loaded campaign, or its directory (read with :func:`load_campaign`).
    out : path
        Output directory (created).
    case_labels : dict, optional
        Display names of the cases (e.g. ``uh_report.report.CASE_LABELS``), shown next to the names.

    Raises
    ------
    CampaignReportError
        The campaign cannot be read (:func:`load_campaign`) or ``out`` cannot be written.
    """
    if not isinstance(campaign, Campaign):
        campaign = load_campaign(campaign)
    out = Path(out)
    make_writable_dir(out, CampaignReportError)

    doc = Document()
    _header(doc, campaign, case_labels)
    success = _success_section(doc, campaign)
    summaries = _distribution_section(doc, campaign, out, case_labels)
    paired = _paired_section(doc, campaign)
    worst = _worst_section(doc, campaign)
    sweep = _sweep_section(doc, campaign, out, case_labels)
    _write_csvs(out, campaign, success, summaries, paired, worst, sweep)
    doc.heading(2, 'Files')
    doc.paragraph('`summary.csv` (per case: counts, success rate and interval, the distribution table), '
                  '`paired.csv`, `worst_runs.csv` (with the re-run commands), ' +
                  ('`sweep.csv`, ' if sweep else '') + '`runs.csv` (every stored run, full precision); '
                  'metric meanings: docs/metrics.md.')
    (out / 'report.md').write_text(doc.markdown())
    (out / 'index.html').write_text(doc.html(f'Campaign report: {campaign.name}'))
    return out / 'report.md'
