"""Figures of a campaign's report: empirical CDFs of the metrics per case, and the sweep.

The figures use Matplotlib's ``Figure`` directly (no pyplot, hence no display), like
:mod:`uh_report.report_figures`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from uh_team.campaign_store import METRIC_COLUMNS

from .campaign_stats import METRIC_UNITS, SWEEP_METRICS, ecdf, ok_finite

__all__ = ['plot_distribution', 'plot_sweep', 'LOG_SPAN_RATIO']

#: An empirical CDF gets a log x-axis when max / min of its (positive) values is at least this.
LOG_SPAN_RATIO = 100.0

_DPI = 100
_CDF_SIZE = (10.0, 6.0)      # inches
_SWEEP_SIZE = (16.0, 5.5)    # inches
_CASE_STYLES = {'proposed': ('tab:blue', '-'), 'case1': ('tab:red', '--'), 'case2': ('tab:green', '-.')}
_OTHER_STYLES = [('tab:purple', ':'), ('tab:orange', '-'), ('tab:brown', '--'), ('tab:gray', '-.')]


def _case_style(case: str, cases) -> tuple[str, str]:
    if case in _CASE_STYLES:
        return _CASE_STYLES[case]
    others = [c for c in cases if c not in _CASE_STYLES]
    return _OTHER_STYLES[others.index(case) % len(_OTHER_STYLES)]


def _metric_axis_label(metric: str) -> str:
    return f'{metric} ({METRIC_UNITS.get(metric, "-")})'


def plot_distribution(runs: dict, cases, metric: str, path: Path, labels: dict | None = None) -> Path | None:
    """Empirical CDF of ``metric`` over the ok runs of each case, cases overlaid (legend: n and median).

    Log x-axis when the positive values span :data:`LOG_SPAN_RATIO` or more. None (no file) when no case has a value.
    """
    from matplotlib.figure import Figure  # matplotlib only when figures are drawn (slow to import)

    series = {case: ecdf(runs[metric][ok_finite(runs, case, metric)]) for case in cases}
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
    """Three panels against the swept value.

    Median (line) and interquartile range (band) of ``formation_rms_m`` and ``containment_rms_m`` per case, and the
    success rate with its Wilson interval (error bars, shifted slightly per case so they do not overlap) per case.
    """
    from matplotlib.figure import Figure  # as in plot_distribution

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
        for ax, metric in zip(axes, SWEEP_METRICS, strict=False):
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
    for ax, metric in zip(axes, SWEEP_METRICS, strict=False):
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

