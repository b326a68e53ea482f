"""Statistics of a campaign: pure functions of the ``{column: ndarray}`` of its runs.

The columns are those of :func:`uh_team.campaign_store.read_runs`: success rates with Wilson
intervals, failures grouped by reason, distributions, paired comparisons of two cases over the same
draws (bootstrap interval of the median difference, Wilcoxon signed-rank test), the worst runs and
the commands that re-run them, and the sweep table. Testable without plotting.
"""
from __future__ import annotations

import math
import re
import shlex
import warnings
from pathlib import Path

import numpy as np

from uh_team.metric_registry import campaign_units

__all__ = ['wilson_interval', 'status_counts', 'success_rate', 'success_table', 'reason_pattern', 'failure_groups',
           'ok_finite', 'distribution_summary', 'ecdf', 'paired_differences', 'bootstrap_median_ci', 'wilcoxon_p',
           'paired_comparison', 'worst_runs', 'rerun_commands', 'sweep_table', 'DISTRIBUTION_METRICS',
           'PAIRED_METRICS', 'SWEEP_METRICS', 'METRIC_UNITS', 'WORST_COUNT', 'CONFIDENCE', 'BOOTSTRAP_RESAMPLES',
           'BOOTSTRAP_SEED']

#: Metrics whose distribution per case is tabulated and drawn as an empirical CDF.
DISTRIBUTION_METRICS = ('formation_rms_m', 'containment_rms_m', 'fault_error_w', 'fault_error_p', 'false_fault_w')

#: Metrics of the paired comparisons (lower is better for each: their ``better`` in the registry).
PAIRED_METRICS = ('formation_rms_m', 'containment_rms_m', 'fault_error_w')

#: Metrics drawn against the swept value.
SWEEP_METRICS = ('formation_rms_m', 'containment_rms_m')

#: Units of the metric columns, as tables and axes show them (:func:`uh_team.metric_registry.campaign_units`).
METRIC_UNITS = campaign_units()

#: Number of worst runs listed per case.
WORST_COUNT = 5

#: Confidence level of every interval of the report.
CONFIDENCE = 0.95

#: Resamples and seed of the bootstrap of the median paired difference (fixed: the report of a
#: given campaign is reproducible).
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 20240229

_NOT_OK = ('failed', 'diverged')


def wilson_interval(successes: int, trials: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Return the Wilson score interval ``(low, high)`` of a success probability.

    From ``successes`` of ``trials`` (fractions in [0, 1]); ``(nan, nan)`` for no trials.
    """
    # With p = k/n and z the (1 + confidence)/2 normal quantile (1.96 for 95 %):
    #   centre = (p + z²/(2n)) / (1 + z²/n)
    #   half   = z / (1 + z²/n) * sqrt(p(1 - p)/n + z²/(4n²))
    #   [centre - half, centre + half]
    # It stays inside [0, 1] and is not empty at k = 0 or k = n (unlike p ± z sqrt(p(1-p)/n)).
    if trials <= 0:
        return math.nan, math.nan
    # scipy.stats takes about a second to import: only when a campaign report needs it
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
    """Success rate of the runs selected by the boolean ``mask``.

    ``{'runs', 'successes', 'rate', 'ci_low', 'ci_high'}`` (fractions). A run is successful only when its stored
    ``success`` is 1: diverged and failed runs, and runs without a verdict, count as not successful.
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
    """Replace the numbers (steps, times, values) in the reason of a run by ``N``.

    So runs failing the same way group together; UH names such as ``uh3`` are kept.
    """
    text = ' '.join(str(reason or '').split())
    return _NUMBER.sub('N', text) if text else '(no reason stored)'


def failure_groups(runs: dict, examples: int = 5) -> list[dict]:
    """Return the diverged and failed runs grouped by status and :func:`reason_pattern`, largest group first.

    ``{'status', 'pattern', 'count', 'cases': {case: count}, 'draws': [first draws], 'example': one full reason}``.
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


def ok_finite(runs: dict, case: str, metric: str) -> np.ndarray:
    """Return indices of the ok runs of ``case`` with a finite ``metric``."""
    values = runs[metric]
    return np.flatnonzero((runs['case_name'] == case) & (runs['status'] == 'ok') & np.isfinite(values))


def distribution_summary(runs: dict, cases, metric: str) -> list[dict]:
    """Per case, over its ok runs with a finite ``metric``.

    ``{'case', 'n', 'median', 'p90', 'max', 'max_draw', 'max_sweep_value'}`` (NaN / None when no run has a value).
    Percentiles interpolate linearly between order statistics (numpy's default).
    """
    rows = []
    for case in cases:
        index = ok_finite(runs, case, metric)
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
    """Empirical CDF of the finite ``values``.

    Sorted values and the fraction ``i/n`` (i = 1..n) of values at or below each.
    """
    x = np.sort(np.asarray(values, dtype=float)[np.isfinite(values)])
    return x, np.arange(1, len(x) + 1) / max(len(x), 1)


def paired_differences(runs: dict, first: str, second: str, metric: str,
                       sweep_index: int | None = None) -> tuple[list, np.ndarray]:
    """``(keys, differences)``.

    For every (draw, sweep index) where both cases ran ok with a finite ``metric``, ``metric(first) - metric(second)``
    (negative: ``first`` is better), keys sorted; with ``sweep_index``, at that sweep point only.
    """
    def by_key(case):
        index = ok_finite(runs, case, metric)
        if sweep_index is not None:
            index = [i for i in index if int(runs['sweep_index'][i]) == sweep_index]
        return {(int(runs['draw'][i]), int(runs['sweep_index'][i])): float(runs[metric][i]) for i in index}
    a, b = by_key(first), by_key(second)
    keys = sorted(a.keys() & b.keys())
    return keys, np.array([a[k] - b[k] for k in keys], dtype=float)


def bootstrap_median_ci(differences, resamples: int = BOOTSTRAP_RESAMPLES, seed: int = BOOTSTRAP_SEED,
                        confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Percentile bootstrap interval of the median of ``differences``.

    The median of ``resamples`` resamples drawn with replacement (generator seeded with ``seed``), and the (1 -
    confidence)/2 and (1 + confidence)/2 quantiles of those medians; ``(nan, nan)`` for fewer than 2 values.
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
    """Return the two-sided Wilcoxon signed-rank p-value of paired ``differences`` and a note.

    Zero differences are dropped (scipy's default). ``(nan, why)`` for fewer than 2 pairs or all
    differences zero, ``(p, '')`` otherwise.
    """
    d = np.asarray(differences, dtype=float)
    if len(d) < 2:
        return math.nan, 'fewer than 2 pairs'
    if not np.any(d != 0.0):
        return math.nan, 'all differences are zero'
    from scipy.stats import wilcoxon  # slow to import, as in wilson_interval
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')      # ties or few non-zero values: scipy's note on its method
        return float(wilcoxon(d).pvalue), ''


def paired_comparison(runs: dict, first: str, second: str, metric: str, resamples: int = BOOTSTRAP_RESAMPLES,
                      seed: int = BOOTSTRAP_SEED, sweep_index: int | None = None) -> dict:
    """Compare ``first`` and ``second`` on ``metric`` (lower is better) over the draws where both ran ok.

    At ``sweep_index`` only, if given (the draws of one sweep point are independent, those of
    several sweep points are not). Returns ``{'first', 'second', 'metric', 'sweep_index', 'pairs',
    'excluded' (draws run by both cases that are not a pair: a run not ok or without the metric),
    'first_better' (fraction with first < second), 'ties' (count), 'median_difference' (first -
    second), 'ci_low', 'ci_high' (:func:`bootstrap_median_ci`), 'wilcoxon_p', 'note'}``.
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
    """Row indices of the ``count`` worst runs of ``case``.

    Failed ones first, then diverged ones, then ok runs without a score (a metric undefined), then the ok runs by
    ``formation_rms_m + containment_rms_m`` largest first; ties in draw and sweep order.
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
    """Per case and sweep point.

    ``{'case', 'sweep_index', 'sweep_value', 'runs', 'ok', '<metric>_median', '<metric>_q25', '<metric>_q75',
    '<metric>_n'`` for each of :data:`SWEEP_METRICS` (over the ok runs with a finite value), and the
    :func:`success_rate` keys ``successes``, ``rate``, ``ci_low``, ``ci_high``}. The sweep value is the stored one, else
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

