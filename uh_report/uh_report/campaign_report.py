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

The statistics are pure functions of the ``{column: ndarray}`` of
:func:`uh_team.campaign_store.read_runs` (testable without plotting); the figures use Matplotlib's
``Figure`` directly (no pyplot, hence no display), like :mod:`uh_report.report_figures`.
"""
from __future__ import annotations

import csv
import html
import io
import json
import math
import re
import shlex
import sqlite3
import warnings
from dataclasses import dataclass, field
from itertools import combinations
from pathlib import Path

import numpy as np

from uh_team.campaign_store import DB_NAME, METRIC_COLUMNS, RUN_COLUMNS, StoreError, open_store, read_meta, read_runs

__all__ = ['CampaignReportError', 'Campaign', 'is_campaign_dir', 'load_campaign', 'wilson_interval',
           'status_counts', 'success_rate', 'success_table', 'failure_groups', 'distribution_summary', 'ecdf',
           'paired_differences', 'bootstrap_median_ci', 'wilcoxon_p', 'paired_comparison', 'worst_runs',
           'rerun_commands', 'sweep_table', 'write_campaign_report',
           'DISTRIBUTION_METRICS', 'PAIRED_METRICS', 'SWEEP_METRICS', 'CASE_ORDER']

#: Canonical order of the controller cases (pairs are formed in this order: proposed vs case1,
#: proposed vs case2, case1 vs case2); other case names follow alphabetically.
CASE_ORDER = ('proposed', 'case1', 'case2')

#: Metrics whose distribution per case is tabulated and drawn as an empirical CDF.
DISTRIBUTION_METRICS = ('formation_rms_m', 'containment_rms_m', 'fault_error_w', 'fault_error_p', 'false_fault_w')

#: Metrics of the paired comparisons (lower is better for each).
PAIRED_METRICS = ('formation_rms_m', 'containment_rms_m', 'fault_error_w')

#: Metrics drawn against the swept value.
SWEEP_METRICS = ('formation_rms_m', 'containment_rms_m')

#: Units of the metrics shown in tables and on axes.
METRIC_UNITS = {'formation_rms_m': 'm', 'containment_rms_m': 'm', 'hull_distance_max_m': 'm',
                'fault_error_p': 'm/s²', 'fault_error_w': 'rad/s²', 'false_fault_p': 'm/s²',
                'false_fault_w': 'rad/s²', 'saturation_fraction': '-'}

#: Number of worst runs listed per case.
WORST_COUNT = 5

#: Confidence level of every interval of the report.
CONFIDENCE = 0.95

#: Resamples and seed of the bootstrap of the median paired difference (fixed: the report of a
#: given campaign is reproducible).
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 20240229

#: An empirical CDF gets a log x-axis when max / min of its (positive) values is at least this.
LOG_SPAN_RATIO = 100.0

_DPI = 100
_CDF_SIZE = (10.0, 6.0)      # inches
_SWEEP_SIZE = (16.0, 5.5)    # inches
_CASE_STYLES = {'proposed': ('tab:blue', '-'), 'case1': ('tab:red', '--'), 'case2': ('tab:green', '-.')}
_OTHER_STYLES = [('tab:purple', ':'), ('tab:orange', '-'), ('tab:brown', '--'), ('tab:gray', '-.')]
_NOT_OK = ('failed', 'diverged')


class CampaignReportError(ValueError):
    """A campaign directory or results file that cannot be reported; the message says which and why."""


@dataclass
class Campaign:
    """One campaign as the report sees it.

    Attributes
    ----------
    directory : Path
        The campaign directory as given on the command line (re-run commands are relative to it).
    name : str
        The campaign's name (its directory name when the store has none).
    meta : dict
        Campaign-level values of the store, JSON decoded where they are JSON.
    runs : dict
        ``{column: ndarray}`` of :func:`uh_team.campaign_store.read_runs`.
    cases : list of str
        Controller cases, in :data:`CASE_ORDER`.
    planned_runs : int or None
        Runs of the complete campaign (draws x cases x sweep points), None if the store does not say.
    sweep_parameter : str or None
        The swept scenario parameter (e.g. ``impairments.delay_steps``), None without a sweep.
    sweep_values : list
        The swept values in sweep-index order (empty without a sweep).
    """

    directory: Path
    name: str
    meta: dict
    runs: dict
    cases: list
    planned_runs: int | None = None
    sweep_parameter: str | None = None
    sweep_values: list = field(default_factory=list)

    @property
    def done_runs(self) -> int:
        """Runs stored so far."""
        return len(self.runs['draw'])


# ----------------------------------------------------------------------------------------------
# Loading
# ----------------------------------------------------------------------------------------------
def is_campaign_dir(path) -> bool:
    """Whether ``path`` is a campaign: a directory holding ``campaign.sqlite`` or a ``scenarios/``
    folder (a campaign that has not stored a run yet; :func:`load_campaign` says so), or the
    ``.sqlite`` results file itself. Run directories (``bag/``, ``run.json``, ``timeseries.npz``)
    are not.
    """
    path = Path(path)
    if path.is_file():
        return path.suffix == '.sqlite'
    if not path.is_dir():
        return False
    if (path / DB_NAME).exists():
        return True
    is_run = any((path / marker).exists() for marker in ('bag', 'run.json', 'timeseries.npz', 'metadata.yaml'))
    return (path / 'scenarios').is_dir() and not is_run


def _decoded(value):
    """A stored meta value: its JSON content, or the string itself when it is not JSON."""
    if not isinstance(value, str):
        return value
    try:
        return json.loads(value)
    except ValueError:
        return value


def _case_rank(case: str):
    return (CASE_ORDER.index(case), '') if case in CASE_ORDER else (len(CASE_ORDER), case)


def load_campaign(path) -> Campaign:
    """Read the campaign in directory ``path`` (or the results file ``path``).

    Raises
    ------
    CampaignReportError
        No ``campaign.sqlite``, a file that is not a campaign results file (not SQLite, damaged, or
        of another layout), or a campaign with no stored run yet.
    """
    path = Path(path)
    directory, db = (path.parent, path) if path.is_file() else (path, path / DB_NAME)
    if not db.is_file():
        raise CampaignReportError(f'{directory}: no {DB_NAME}: the campaign has not stored a run yet '
                                  '(or this is not a campaign directory)')
    try:
        con = open_store(db)
    except StoreError as exc:
        raise CampaignReportError(str(exc)) from None
    try:
        meta = {key: _decoded(value) for key, value in read_meta(con).items()}
        runs = read_runs(con)
    except sqlite3.DatabaseError as exc:
        raise CampaignReportError(f'{db}: cannot be read, damaged? ({exc})') from None
    finally:
        con.close()

    name = str(meta.get('name') or directory.resolve().name)
    sweep_parameter = meta.get('sweep_parameter') or None
    sweep_values = list(meta.get('sweep_values') or []) if sweep_parameter else []
    meta_cases = [str(c) for c in meta.get('cases') or []]
    cases = sorted(set(meta_cases) | {str(c) for c in runs['case_name']}, key=_case_rank)
    draws = meta.get('runs')
    planned = None
    if isinstance(draws, int) and meta_cases:
        planned = draws * len(meta_cases) * max(1, len(sweep_values))
    if len(runs['draw']) == 0:
        of = f' of {planned} planned' if planned else ''
        raise CampaignReportError(f'{db}: campaign {name!r} has no runs stored yet (0{of}); report it once '
                                  'some runs have finished')
    return Campaign(directory=directory, name=name, meta=meta, runs=runs, cases=cases, planned_runs=planned,
                    sweep_parameter=str(sweep_parameter) if sweep_parameter else None, sweep_values=sweep_values)


# ----------------------------------------------------------------------------------------------
# Statistics (pure functions of the read_runs columns)
# ----------------------------------------------------------------------------------------------
def wilson_interval(successes: int, trials: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval ``(low, high)`` of a success probability from ``successes`` of
    ``trials`` (fractions in [0, 1]); ``(nan, nan)`` for no trials.
    """
    # With p = k/n and z the (1 + confidence)/2 normal quantile (1.96 for 95 %):
    #   centre = (p + z²/(2n)) / (1 + z²/n)
    #   half   = z / (1 + z²/n) * sqrt(p(1 - p)/n + z²/(4n²))
    #   [centre - half, centre + half]
    # It stays inside [0, 1] and is not empty at k = 0 or k = n (unlike p ± z sqrt(p(1-p)/n)).
    if trials <= 0:
        return math.nan, math.nan
    from scipy.stats import binomtest
    ci = binomtest(int(successes), int(trials)).proportion_ci(confidence_level=confidence, method='wilson')
    return float(ci.low), float(ci.high)


def status_counts(runs: dict, cases) -> dict:
    """``{case: {'runs', 'ok', 'diverged', 'failed'}}``: stored runs of each case by status."""
    out = {}
    for case in cases:
        mine = runs['status'][runs['case_name'] == case]
        out[case] = {'runs': int(len(mine)), **{s: int(np.sum(mine == s)) for s in ('ok', 'diverged', 'failed')}}
    return out


def success_rate(runs: dict, mask: np.ndarray, confidence: float = CONFIDENCE) -> dict:
    """Success rate of the runs selected by the boolean ``mask``: ``{'runs', 'successes', 'rate',
    'ci_low', 'ci_high'}`` (fractions). A run is successful only when its stored ``success`` is 1:
    diverged and failed runs, and runs without a verdict, count as not successful.
    """
    trials = int(np.sum(mask))
    successes = int(np.sum(runs['success'][mask] == 1))
    low, high = wilson_interval(successes, trials, confidence)
    return {'runs': trials, 'successes': successes, 'rate': successes / trials if trials else math.nan,
            'ci_low': low, 'ci_high': high}


def success_table(runs: dict, cases, confidence: float = CONFIDENCE) -> list[dict]:
    """:func:`success_rate` of every case (all its sweep points pooled), with the key ``case``."""
    return [{'case': case, **success_rate(runs, runs['case_name'] == case, confidence)} for case in cases]


_NUMBER = re.compile(r'(?<![A-Za-z_])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?')


def reason_pattern(reason) -> str:
    """The reason of a run with its numbers (steps, times, values) replaced by ``N``, so that runs
    failing the same way group together; UH names such as ``uh3`` are kept.
    """
    text = ' '.join(str(reason or '').split())
    return _NUMBER.sub('N', text) if text else '(no reason stored)'


def failure_groups(runs: dict, examples: int = 5) -> list[dict]:
    """The diverged and failed runs grouped by status and :func:`reason_pattern`, largest group
    first: ``{'status', 'pattern', 'count', 'cases': {case: count}, 'draws': [first draws],
    'example': one full reason}``.
    """
    groups = {}
    for i in np.flatnonzero(np.isin(runs['status'], _NOT_OK)):
        status, reason = str(runs['status'][i]), runs['reason'][i]
        group = groups.setdefault((status, reason_pattern(reason)), {
            'status': status, 'pattern': reason_pattern(reason), 'count': 0, 'cases': {}, 'draws': [],
            'example': ' '.join(str(reason or '').split())})
        group['count'] += 1
        case = str(runs['case_name'][i])
        group['cases'][case] = group['cases'].get(case, 0) + 1
        draw = int(runs['draw'][i])
        if draw not in group['draws'] and len(group['draws']) < examples:
            group['draws'].append(draw)
    return sorted(groups.values(), key=lambda g: (-g['count'], g['status'], g['pattern']))


def _ok_finite(runs: dict, case: str, metric: str) -> np.ndarray:
    """Indices of the ok runs of ``case`` with a finite ``metric``."""
    values = runs[metric]
    return np.flatnonzero((runs['case_name'] == case) & (runs['status'] == 'ok') & np.isfinite(values))


def distribution_summary(runs: dict, cases, metric: str) -> list[dict]:
    """Per case, over its ok runs with a finite ``metric``: ``{'case', 'n', 'median', 'p90', 'max',
    'max_draw', 'max_sweep_value'}`` (NaN / None when no run has a value). Percentiles interpolate
    linearly between order statistics (numpy's default).
    """
    rows = []
    for case in cases:
        index = _ok_finite(runs, case, metric)
        row = {'case': case, 'n': int(len(index)), 'median': math.nan, 'p90': math.nan, 'max': math.nan,
               'max_draw': None, 'max_sweep_value': math.nan}
        if len(index):
            values = runs[metric][index]
            worst = index[int(np.argmax(values))]
            row.update(median=float(np.median(values)), p90=float(np.percentile(values, 90)),
                       max=float(values.max()), max_draw=int(runs['draw'][worst]),
                       max_sweep_value=float(runs['sweep_value'][worst]))
        rows.append(row)
    return rows


def ecdf(values) -> tuple[np.ndarray, np.ndarray]:
    """Empirical CDF of the finite ``values``: sorted values and the fraction ``i/n`` (i = 1..n) of
    values at or below each.
    """
    x = np.sort(np.asarray(values, dtype=float)[np.isfinite(values)])
    return x, np.arange(1, len(x) + 1) / max(len(x), 1)


def paired_differences(runs: dict, first: str, second: str, metric: str,
                       sweep_index: int | None = None) -> tuple[list, np.ndarray]:
    """``(keys, differences)``: for every (draw, sweep index) where both cases ran ok with a finite
    ``metric``, ``metric(first) - metric(second)`` (negative: ``first`` is better), keys sorted;
    with ``sweep_index``, at that sweep point only.
    """
    def by_key(case):
        index = _ok_finite(runs, case, metric)
        if sweep_index is not None:
            index = [i for i in index if int(runs['sweep_index'][i]) == sweep_index]
        return {(int(runs['draw'][i]), int(runs['sweep_index'][i])): float(runs[metric][i]) for i in index}
    a, b = by_key(first), by_key(second)
    keys = sorted(a.keys() & b.keys())
    return keys, np.array([a[k] - b[k] for k in keys], dtype=float)


def bootstrap_median_ci(differences, resamples: int = BOOTSTRAP_RESAMPLES, seed: int = BOOTSTRAP_SEED,
                        confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Percentile bootstrap interval of the median of ``differences``: the median of ``resamples``
    resamples drawn with replacement (generator seeded with ``seed``), and the (1 - confidence)/2
    and (1 + confidence)/2 quantiles of those medians; ``(nan, nan)`` for fewer than 2 values.
    """
    d = np.asarray(differences, dtype=float)
    if len(d) < 2:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    medians = np.empty(resamples)
    block = max(1, 2_000_000 // len(d))      # resamples per block: bounded memory for large campaigns
    for start in range(0, resamples, block):
        stop = min(resamples, start + block)
        medians[start:stop] = np.median(d[rng.integers(0, len(d), size=(stop - start, len(d)))], axis=1)
    tail = (1.0 - confidence) / 2.0
    low, high = np.quantile(medians, [tail, 1.0 - tail])
    return float(low), float(high)


def wilcoxon_p(differences) -> tuple[float, str]:
    """Two-sided Wilcoxon signed-rank p-value of paired ``differences`` (zero differences dropped,
    scipy's default) and a note: ``(nan, why)`` for fewer than 2 pairs or all differences zero,
    ``(p, '')`` otherwise.
    """
    d = np.asarray(differences, dtype=float)
    if len(d) < 2:
        return math.nan, 'fewer than 2 pairs'
    if not np.any(d != 0.0):
        return math.nan, 'all differences are zero'
    from scipy.stats import wilcoxon
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')      # ties or few non-zero values: scipy's note on its method
        return float(wilcoxon(d).pvalue), ''


def paired_comparison(runs: dict, first: str, second: str, metric: str, resamples: int = BOOTSTRAP_RESAMPLES,
                      seed: int = BOOTSTRAP_SEED, sweep_index: int | None = None) -> dict:
    """Paired comparison of ``first`` and ``second`` on ``metric`` (lower is better) over the draws
    where both ran ok (at ``sweep_index`` only, if given: the draws of one sweep point are
    independent, those of several sweep points are not): ``{'first', 'second', 'metric',
    'sweep_index', 'pairs', 'excluded' (draws run by both cases that are not a pair: a run not ok
    or without the metric), 'first_better' (fraction with first < second), 'ties' (count),
    'median_difference' (first - second), 'ci_low', 'ci_high' (:func:`bootstrap_median_ci`),
    'wilcoxon_p', 'note'}``.
    """
    _, d = paired_differences(runs, first, second, metric, sweep_index)
    n = len(d)

    def keys(case):
        rows = np.flatnonzero(runs['case_name'] == case)
        return {(int(runs['draw'][i]), int(runs['sweep_index'][i])) for i in rows
                if sweep_index is None or int(runs['sweep_index'][i]) == sweep_index}
    low, high = bootstrap_median_ci(d, resamples, seed)
    p, note = wilcoxon_p(d)
    return {'first': first, 'second': second, 'metric': metric, 'sweep_index': sweep_index, 'pairs': n,
            'excluded': len(keys(first) & keys(second)) - n,
            'first_better': float(np.mean(d < 0.0)) if n else math.nan, 'ties': int(np.sum(d == 0.0)),
            'median_difference': float(np.median(d)) if n else math.nan, 'ci_low': low, 'ci_high': high,
            'wilcoxon_p': p, 'note': note if n else 'no pairs'}


def worst_runs(runs: dict, case: str, count: int = WORST_COUNT) -> list[int]:
    """Row indices of the ``count`` worst runs of ``case``: failed ones first, then diverged ones,
    then ok runs without a score (a metric undefined), then the ok runs by ``formation_rms_m +
    containment_rms_m`` largest first; ties in draw and sweep order.
    """
    rank = {'failed': 0, 'diverged': 1}
    score = runs['formation_rms_m'] + runs['containment_rms_m']

    def key(i):
        status = str(runs['status'][i])
        if status in rank:
            return (rank[status], 0.0, int(runs['draw'][i]), int(runs['sweep_index'][i]))
        if not math.isfinite(score[i]):
            return (2, 0.0, int(runs['draw'][i]), int(runs['sweep_index'][i]))
        return (3, -float(score[i]), int(runs['draw'][i]), int(runs['sweep_index'][i]))
    return sorted(np.flatnonzero(runs['case_name'] == case).tolist(), key=key)[:count]


def _safe_name(text: str) -> str:
    return re.sub(r'[^A-Za-z0-9_.-]+', '_', str(text)).strip('_') or 'campaign'


def rerun_commands(directory, scenario_file: str, case: str, campaign_name: str, draw: int,
                   sweep_index: int | None = None) -> tuple[str, str]:
    """Shell commands that re-run one run: ``(distributed, in-process)``.

    The first runs it as a distributed lockstep run recorded to a bag
    (``scripts/run_formation.sh``, output ``runs/<campaign>_draw<draw>_<case>``, with
    ``_s<sweep index>`` before the case when the campaign sweeps), the second in one process
    (``uh-simulate``, output ``runs/<same>_sim``). The scenario is ``directory / scenario_file``
    (``directory`` as given on the command line), which holds everything, its duration included.
    """
    scenario = (Path(directory) / str(scenario_file)).as_posix()
    sweep = f'_s{int(sweep_index)}' if sweep_index is not None else ''
    out = f'runs/{_safe_name(campaign_name)}_draw{int(draw)}{sweep}_{case}'
    q = shlex.quote
    distributed = (f'scripts/run_formation.sh --scenario {q(scenario)} --case {q(case)} --clock lockstep '
                   f'--out {q(out)}')
    in_process = f'uh-simulate --scenario {q(scenario)} --case {q(case)} --out {q(out + "_sim")}'
    return distributed, in_process


def sweep_table(runs: dict, cases, sweep_values=(), confidence: float = CONFIDENCE) -> list[dict]:
    """Per case and sweep point: ``{'case', 'sweep_index', 'sweep_value', 'runs', 'ok',
    '<metric>_median', '<metric>_q25', '<metric>_q75', '<metric>_n'`` for each of
    :data:`SWEEP_METRICS` (over the ok runs with a finite value), and the :func:`success_rate`
    keys ``successes``, ``rate``, ``ci_low``, ``ci_high``}. The sweep value is the stored one, else
    ``sweep_values[sweep_index]``.
    """
    rows = []
    for case in cases:
        mine = runs['case_name'] == case
        for k in sorted({int(s) for s in runs['sweep_index'][mine]}):
            at = mine & (runs['sweep_index'] == k)
            stored = runs['sweep_value'][at]
            value = float(stored[np.isfinite(stored)][0]) if np.isfinite(stored).any() else \
                (float(sweep_values[k]) if k < len(sweep_values) else math.nan)
            row = {'case': case, 'sweep_index': k, 'sweep_value': value, 'runs': int(np.sum(at)),
                   'ok': int(np.sum(at & (runs['status'] == 'ok')))}
            for metric in SWEEP_METRICS:
                values = runs[metric][at & (runs['status'] == 'ok') & np.isfinite(runs[metric])]
                q25, median, q75 = np.percentile(values, [25, 50, 75]) if len(values) else (math.nan,) * 3
                row.update({f'{metric}_median': float(median), f'{metric}_q25': float(q25),
                            f'{metric}_q75': float(q75), f'{metric}_n': int(len(values))})
            rate = success_rate(runs, at, confidence)
            row.update({key: rate[key] for key in ('successes', 'rate', 'ci_low', 'ci_high')})
            rows.append(row)
    return rows


# ----------------------------------------------------------------------------------------------
# Figures
# ----------------------------------------------------------------------------------------------
def _case_style(case: str, cases) -> tuple[str, str]:
    if case in _CASE_STYLES:
        return _CASE_STYLES[case]
    others = [c for c in cases if c not in _CASE_STYLES]
    return _OTHER_STYLES[others.index(case) % len(_OTHER_STYLES)]


def _metric_axis_label(metric: str) -> str:
    return f'{metric} ({METRIC_UNITS.get(metric, "-")})'


def plot_distribution(runs: dict, cases, metric: str, path: Path, labels: dict | None = None) -> Path | None:
    """Empirical CDF of ``metric`` over the ok runs of each case, cases overlaid (legend: n and
    median); log x-axis when the positive values span :data:`LOG_SPAN_RATIO` or more. None (no file)
    when no case has a value.
    """
    from matplotlib.figure import Figure

    series = {case: ecdf(runs[metric][_ok_finite(runs, case, metric)]) for case in cases}
    series = {case: xy for case, xy in series.items() if len(xy[0])}
    if not series:
        return None
    every = np.concatenate([x for x, _ in series.values()])
    log_x = bool(every.min() > 0.0 and every.max() / every.min() >= LOG_SPAN_RATIO)
    fig = Figure(figsize=_CDF_SIZE, dpi=_DPI, layout='constrained')
    ax = fig.subplots()
    for case, (x, y) in series.items():
        colour, dash = _case_style(case, cases)
        label = f'{(labels or {}).get(case, case)} (n = {len(x)}, median {np.median(x):.3g})'
        ax.step(np.concatenate([[x[0]], x]), np.concatenate([[0.0], y]), where='post', color=colour,
                linestyle=dash, linewidth=1.8, label=label)
    if log_x:
        ax.set_xscale('log')
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel(_metric_axis_label(metric) + (', log scale' if log_x else ''))
    ax.set_ylabel('fraction of ok runs ≤ x')
    ax.set_title(f'Empirical CDF of {metric}: {METRIC_COLUMNS.get(metric, metric)}', fontsize=11)
    ax.grid(True, which='both', alpha=0.35)
    ax.legend(loc='lower right')
    fig.savefig(path, dpi=_DPI, format='png')
    return path


def plot_sweep(table: list[dict], cases, parameter: str, path: Path, labels: dict | None = None) -> Path:
    """Three panels against the swept value: median (line) and interquartile range (band) of
    ``formation_rms_m`` and ``containment_rms_m`` per case, and the success rate with its Wilson
    interval (error bars, shifted slightly per case so they do not overlap) per case.
    """
    from matplotlib.figure import Figure

    fig = Figure(figsize=_SWEEP_SIZE, dpi=_DPI, layout='constrained')
    axes = fig.subplots(1, 3)
    swept = np.array([r['sweep_value'] for r in table], dtype=float)
    span = float(np.nanmax(swept) - np.nanmin(swept)) if np.isfinite(swept).any() else 0.0
    for position, case in enumerate(cases):
        rows = sorted((r for r in table if r['case'] == case), key=lambda r: r['sweep_value'])
        if not rows:
            continue
        colour, dash = _case_style(case, cases)
        label = (labels or {}).get(case, case)
        x = np.array([r['sweep_value'] for r in rows])
        for ax, metric in zip(axes, SWEEP_METRICS):
            median = np.array([r[f'{metric}_median'] for r in rows])
            ax.plot(x, median, color=colour, linestyle=dash, marker='o', label=label)
            ax.fill_between(x, [r[f'{metric}_q25'] for r in rows], [r[f'{metric}_q75'] for r in rows],
                            color=colour, alpha=0.18, linewidth=0)
        rate = np.array([r['rate'] for r in rows]) * 100.0
        below = np.clip(rate - np.array([r['ci_low'] for r in rows]) * 100.0, 0.0, None)
        above = np.clip(np.array([r['ci_high'] for r in rows]) * 100.0 - rate, 0.0, None)
        dodge = (position - (len(cases) - 1) / 2) * 0.012 * (span or 1.0)   # error bars side by side
        axes[2].errorbar(x + dodge, rate, yerr=[below, above], color=colour, linestyle=dash, marker='o', capsize=4,
                         label=label)
    for ax, metric in zip(axes, SWEEP_METRICS):
        ax.set_ylabel(f'{_metric_axis_label(metric)}, median and IQR')
        ax.set_title(metric, fontsize=11)
    axes[2].set_ylabel('success rate (%), 95 % Wilson interval')
    axes[2].set_ylim(-2.0, 102.0)
    axes[2].set_title('success rate', fontsize=11)
    for ax in axes:
        ax.set_xlabel(parameter)
        ax.grid(True, alpha=0.35)
        ax.legend(fontsize=9)
    fig.savefig(path, dpi=_DPI, format='png')
    return path


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
    out = io.StringIO()
    writer = csv.writer(out, lineterminator='\n')
    writer.writerow(head)
    for row in rows:
        writer.writerow([_csv_value(v) for v in row])
    return out.getvalue()


class _Document:
    """A report as a list of blocks, rendered to Markdown and to HTML alike. Paragraph texts may hold
    ``code`` spans (backticks) and **bold**.
    """

    def __init__(self):
        self.blocks = []

    def heading(self, level: int, text: str):
        self.blocks.append(('heading', level, text))

    def paragraph(self, text: str):
        self.blocks.append(('paragraph', text))

    def bullets(self, items):
        self.blocks.append(('bullets', list(items)))

    def table(self, head, rows):
        self.blocks.append(('table', list(head), [list(r) for r in rows]))

    def code(self, text: str):
        self.blocks.append(('code', text))

    def figure(self, path: str, caption: str):
        self.blocks.append(('figure', path, caption))

    def markdown(self) -> str:
        cell = lambda t: str(t).replace('|', '\\|').replace('\n', ' ')  # noqa: E731
        lines = []
        for block in self.blocks:
            kind = block[0]
            if kind == 'heading':
                lines += ['#' * block[1] + ' ' + block[2], '']
            elif kind == 'paragraph':
                lines += [block[1], '']
            elif kind == 'bullets':
                lines += [f'- {item}' for item in block[1]] + ['']
            elif kind == 'table':
                head, rows = block[1], block[2]
                lines.append('| ' + ' | '.join(map(cell, head)) + ' |')
                lines.append('|' + '---|' * len(head))
                lines += ['| ' + ' | '.join(map(cell, row)) + ' |' for row in rows]
                lines.append('')
            elif kind == 'code':
                lines += ['```bash', block[1], '```', '']
            elif kind == 'figure':
                lines += [f'![{block[2]}]({block[1]})', '', f'*{block[2]}*', '']
        return '\n'.join(lines).rstrip('\n') + '\n'

    @staticmethod
    def _inline(text: str) -> str:
        text = html.escape(str(text), quote=False)
        text = re.sub(r'`([^`]+)`', r'<code>\1</code>', text)
        return re.sub(r'\*\*([^*]+)\*\*', r'<strong>\1</strong>', text)

    def html(self, title: str) -> str:
        parts = []
        for block in self.blocks:
            kind = block[0]
            if kind == 'heading':
                parts.append(f'<h{block[1]}>{self._inline(block[2])}</h{block[1]}>')
            elif kind == 'paragraph':
                parts.append(f'<p>{self._inline(block[1])}</p>')
            elif kind == 'bullets':
                parts.append('<ul>' + ''.join(f'<li>{self._inline(i)}</li>' for i in block[1]) + '</ul>')
            elif kind == 'table':
                th = ''.join(f'<th>{self._inline(h)}</th>' for h in block[1])
                body = ''.join('<tr>' + ''.join(f'<td>{self._inline(c)}</td>' for c in row) + '</tr>\n'
                               for row in block[2])
                parts.append(f'<table>\n<thead><tr>{th}</tr></thead>\n<tbody>\n{body}</tbody>\n</table>')
            elif kind == 'code':
                parts.append(f'<pre><code>{html.escape(block[1])}</code></pre>')
            elif kind == 'figure':
                parts.append(f'<figure><img src="{html.escape(block[1])}" alt="{html.escape(block[2])}">'
                             f'<figcaption>{html.escape(block[2])}</figcaption></figure>')
        return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em auto; max-width: 1450px; color: #222; }}
table {{ border-collapse: collapse; margin: 1em 0; }}
th, td {{ border: 1px solid #bbb; padding: 0.3em 0.6em; }}
th {{ background: #eef; }}
pre {{ background: #f6f6f6; padding: 0.6em; overflow-x: auto; }}
figure {{ margin: 1.5em 0; }}
img {{ max-width: 100%; border: 1px solid #ddd; }}
figcaption {{ font-style: italic; margin-top: 0.3em; }}
</style></head>
<body>
{chr(10).join(parts)}
</body></html>
"""


# ----------------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------------
def _label(case: str, labels: dict | None) -> str:
    """``case = display name`` (header), or the case name alone when it has no other name."""
    label = (labels or {}).get(case, case)
    return case if label == case else f'{case} = {label}'


def _duration(meta: dict):
    """The campaign's simulated duration (s) if the store gives a positive number, else None."""
    value = meta.get('duration')
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value) and value > 0 else None


def _header(doc: _Document, campaign: Campaign, labels) -> None:
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


def _success_section(doc: _Document, campaign: Campaign) -> list[dict]:
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


def _distribution_section(doc: _Document, campaign: Campaign, out: Path, labels) -> dict:
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


def _paired_section(doc: _Document, campaign: Campaign) -> list[dict]:
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


def _worst_section(doc: _Document, campaign: Campaign) -> list[dict]:
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


def _sweep_section(doc: _Document, campaign: Campaign, out: Path, labels) -> list[dict]:
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
    for case, rate in zip(campaign.cases, success):
        row = [case, *(counts[case][k] for k in ('runs', 'ok', 'diverged', 'failed')), rate['successes'],
               rate['rate'], rate['ci_low'], rate['ci_high']]
        for metric in DISTRIBUTION_METRICS:
            s = next(r for r in summaries[metric] if r['case'] == case)
            row += [s['n'], s['median'], s['p90'], s['max'], s['max_draw'], s['max_sweep_value']]
        rows.append(row)
    (out / 'summary.csv').write_text(_csv(head, rows))

    paired_keys = ['first', 'second', 'sweep_index', 'sweep_value', 'metric', 'pairs', 'excluded', 'first_better', 'ties', 'median_difference', 'ci_low',
                   'ci_high', 'wilcoxon_p', 'note']
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


def make_writable_dir(out: Path, error=ValueError) -> None:
    """Create ``out`` if needed and check that a file can be written in it; raise ``error`` with
    the reason otherwise.
    """
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / '.write_test'
        probe.write_text('')
        probe.unlink()
    except OSError as exc:
        raise error(f'--out {out}: cannot write there ({exc.strerror})') from None


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

    doc = _Document()
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
