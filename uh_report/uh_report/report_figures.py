"""Figures of a formation-containment run (the paper's Figures 4-12), drawn with Matplotlib's Agg backend.

Each function takes :class:`uh_report.run_data.RunData` objects (the arrays of
``uh_report.bag_metrics.read_team_bag`` or of ``timeseries.npz``, UH axis in ``scenario.ids``
order) and writes one PNG of a fixed pixel size (:data:`FIGURE_SIZES` at :data:`DPI`), so a test
can check what was drawn. Errors are computed with the one metrics module
(:mod:`uh_team.metrics`, docs/metrics.md).

========================  ========================================================================
figure                    content (paper figure)
========================  ========================================================================
``states``                x, y, z (m) and yaw psi (deg) of every UH against time, virtual leader
                          dashed (Figures 4-7)
``trajectory_3d``         3-D trajectories and their projections on the XY, XZ and YZ planes
                          (Figure 8)
``xy_snapshots``          XY plane: trajectories, the leaders' triangle and the followers at
                          snapshot times (Figure 9)
``faults_uh<i>``          estimated vs true lumped faults F_p (m/s^2) and F_w (rad/s^2) of each
                          faulted UH, per axis
``false_fault_estimate``  |Fhat_p| (m/s^2) and |Fhat_w| (rad/s^2) where no fault acts (healthy
                          UHs; faulted UHs before their onset), log scale, with the thresholds
``errors``                formation error (leaders) and containment error (followers), RMS over
                          the UHs, one line per run (Figures 10-12 when several runs are given)
``errors_per_uh``         the same per UH, one panel per UH, one line per run
========================  ========================================================================
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from uh_core.layout import X_P_SLICE
from uh_team.metrics import FALSE_ESTIMATE_START, LUMPED_FAULTS, containment_errors, faulted_uhs, formation_errors
from uh_team.run_arrays import RUN_REF_POSITION, RUN_REF_YAW

from . import loss_figures
from .loss_figures import errors_in_force, has_losses, mark_losses

__all__ = ['DPI', 'FIGURE_SIZES', 'pixel_size', 'plot_states', 'plot_trajectory_3d', 'plot_xy_snapshots',
           'plot_faults', 'plot_false_fault_estimate', 'plot_errors', 'plot_errors_per_uh', 'uh_errors',
           'snapshot_times', 'plot_topology', 'has_losses']

#: Dots per inch of every PNG.
DPI = 100

#: Figure size in inches (width, height) of each figure kind; pixels = inches * DPI.
FIGURE_SIZES = {
    'states': (14.0, 9.0),
    'trajectory_3d': (14.0, 11.0),
    'xy_snapshots': (11.0, 10.0),
    'faults': (14.0, 10.0),
    'false_fault_estimate': (14.0, 10.0),
    'errors': (14.0, 8.0),
    'errors_per_uh': (14.0, 11.0),
    'topology': (16.0, 7.0),
}

_STYLE = {
    'font.size': 12, 'axes.titlesize': 13, 'axes.labelsize': 12, 'legend.fontsize': 11,
    'xtick.labelsize': 11, 'ytick.labelsize': 11, 'axes.grid': True, 'grid.alpha': 0.35,
    'lines.linewidth': 1.6,
}
# one colour per UH (tab10), one colour and dash per run in comparison figures
_UH_COLOURS = ['tab:blue', 'tab:orange', 'tab:green', 'tab:red', 'tab:purple', 'tab:brown', 'tab:pink',
               'tab:olive', 'tab:cyan', 'tab:gray']
_RUN_STYLES = [('tab:blue', '-'), ('tab:red', '--'), ('tab:green', '-.'), ('tab:purple', ':'),
               ('tab:orange', '-'), ('tab:brown', '--')]
_VL = dict(color='black', linestyle='--', linewidth=1.4)

#: Start-up transient left out of the y range of the fault figures, s (the observers start at zero
#: and their first second holds spikes ten times larger than the faults).
TRANSIENT_S = 2.0


def pixel_size(kind: str) -> tuple[int, int]:
    """``(width, height)`` in pixels of the PNG of figure ``kind`` (a key of :data:`FIGURE_SIZES`)."""
    w, h = FIGURE_SIZES[kind]
    return int(round(w * DPI)), int(round(h * DPI))


def _figure(kind: str):
    from matplotlib.figure import Figure
    return Figure(figsize=FIGURE_SIZES[kind], dpi=DPI, layout='constrained')


def _save(fig, path: Path) -> Path:
    # no bbox_inches='tight': the pixel size stays FIGURE_SIZES * DPI
    fig.savefig(path, dpi=DPI, format='png')
    return path


def _style():
    import matplotlib
    return matplotlib.rc_context(_STYLE)


def _uh_colour(index: int) -> str:
    return _UH_COLOURS[index % len(_UH_COLOURS)]


def _uh_label(run, i: int) -> str:
    return f'UH{i} ({"leader" if i in run.scenario.leaders else "follower"})'


def _title(fig, run, what: str) -> None:
    fig.suptitle(f'{what}: {run.label}', fontsize=15, fontweight='bold')


def _vline(ax, t: float, text: str) -> None:
    """Dotted vertical line at ``t`` with ``text`` written along it at the top of the axes."""
    ax.axvline(t, color='0.35', linestyle=':', linewidth=1.3, zorder=1)
    ax.text(t, 0.98, f' {text}', transform=ax.get_xaxis_transform(), ha='left', va='top', fontsize=10,
            color='0.3')


def _mark_faults(ax, run, uh=None) -> None:
    """Labelled dotted vertical line at the fault onset(s) (of ``uh`` only if given)."""
    onsets = sorted({f.onset for i, f in faulted_uhs(run.scenario, run.arrays).items() if uh is None or i == uh})
    t_end = float(run.arrays['time'][-1])
    for onset in onsets:
        if onset <= t_end:
            _vline(ax, onset, 'faults' if uh is None else 'fault')


# ----------------------------------------------------------------------------------------------
# Figures 4-7: states against time
# ----------------------------------------------------------------------------------------------
def plot_states(run, path: Path) -> Path:
    """x, y, z (m) and psi (deg) of every UH against time (s) with the virtual leader (Figures 4-7).

    Yaw angles are unwrapped (continuous), so a turn through 180 deg draws no jump.
    """
    t = run.arrays['time']
    states = run.arrays['states']
    ref = run.arrays['reference']
    ids = run.scenario.ids
    with _style():
        fig = _figure('states')
        axes = fig.subplots(2, 2, sharex=True)
        panels = [(0, 'x (m)', 'position x'), (1, 'y (m)', 'position y'), (2, 'z (m)', 'altitude z'),
                  (8, 'ψ (deg)', 'yaw ψ')]
        for ax, (k, ylabel, title) in zip(axes.flat, panels, strict=True):
            for c, i in enumerate(ids):
                y = states[:, c, k]
                if k == 8:  # continuous yaw (the state's yaw may be wrapped)
                    y = np.degrees(_unwrap(y))
                ax.plot(t, y, color=_uh_colour(c), label=_uh_label(run, i))
            if k < 3:
                ax.plot(t, ref[:, k], label='virtual leader', **_VL)
            else:
                ax.plot(t, np.degrees(_unwrap(ref[:, RUN_REF_YAW])), label='virtual leader', **_VL)
            ax.set_ylabel(ylabel)
            ax.set_title(title)
            _mark_faults(ax, run)
        for ax in axes[1]:
            ax.set_xlabel('time t (s)')
        handles, labels = axes[0, 0].get_legend_handles_labels()
        fig.legend(handles, labels, loc='outside lower center', ncol=len(labels), frameon=False)
        _title(fig, run, 'Positions and yaw of every UH')
        return _save(fig, path)


def _unwrap(angle) -> np.ndarray:
    """``np.unwrap`` that leaves NaN samples (steps missing from a bag) in place."""
    angle = np.asarray(angle, dtype=float)
    out = np.full_like(angle, np.nan)
    ok = np.isfinite(angle)
    out[ok] = np.unwrap(angle[ok])
    return out


# ----------------------------------------------------------------------------------------------
# Figure 8: 3-D trajectories and the three orthogonal planes
# ----------------------------------------------------------------------------------------------
def plot_trajectory_3d(run, path: Path) -> Path:
    """3-D trajectories (m) with start (circle) and end (square) markers, and the XY, XZ, YZ projections."""
    states = run.arrays['states']
    ref = run.arrays['reference']
    ids = run.scenario.ids
    with _style():
        fig = _figure('trajectory_3d')
        ax3 = fig.add_subplot(2, 2, 1, projection='3d')
        planes = [(fig.add_subplot(2, 2, 2), 0, 1, 'XY plane (top view)'),
                  (fig.add_subplot(2, 2, 3), 0, 2, 'XZ plane (side view)'),
                  (fig.add_subplot(2, 2, 4), 1, 2, 'YZ plane (side view)')]
        names = 'xyz'
        for c, i in enumerate(ids):
            p = states[:, c, X_P_SLICE]
            colour = _uh_colour(c)
            ax3.plot(p[:, 0], p[:, 1], p[:, 2], color=colour, label=_uh_label(run, i))
            ax3.scatter(*p[0], color=colour, marker='o', s=30)
            for ax, a, b, _ in planes:
                ax.plot(p[:, a], p[:, b], color=colour)
                ax.plot(p[0, a], p[0, b], marker='o', color=colour, markersize=6)
                ax.plot(p[-1, a], p[-1, b], marker='s', color=colour, markersize=6)
        ax3.plot(ref[:, 0], ref[:, 1], ref[:, 2], label='virtual leader', **_VL)
        for ax, a, b, title in planes:
            ax.plot(ref[:, a], ref[:, b], **_VL)
            ax.set_xlabel(f'{names[a]} (m)')
            ax.set_ylabel(f'{names[b]} (m)')
            ax.set_title(title)
            if (a, b) == (0, 1):
                ax.set_aspect('equal', adjustable='datalim')
        ax3.set_xlabel('x (m)', labelpad=8)
        ax3.set_ylabel('y (m)', labelpad=8)
        ax3.set_zlabel('z (m)', labelpad=8)
        ax3.set_title('3-D trajectories')
        handles, labels = ax3.get_legend_handles_labels()
        fig.legend(handles, labels, loc='outside lower center', ncol=len(labels), frameon=False)
        _title(fig, run, 'Trajectories (circle: start, square: end)')
        return _save(fig, path)


# ----------------------------------------------------------------------------------------------
# Figure 9: XY plane with the leaders' triangle at snapshot times
# ----------------------------------------------------------------------------------------------
def snapshot_times(t_end: float, count: int = 7) -> list[float]:
    """``count`` evenly spaced snapshot times over ``[0, t_end]`` (s), rounded to 0.1 s."""
    if count < 2 or t_end <= 0:
        return [0.0]
    return [round(t_end * k / (count - 1), 1) for k in range(count)]


def plot_xy_snapshots(run, path: Path, count: int = 7) -> Path:
    """Draw the XY plane (m): trajectories and snapshots of the team.

    At ``count`` snapshot times the leaders' convex hull (filled polygon), the followers (filled
    markers) and the virtual leader (star).
    """
    from matplotlib.patches import Polygon

    t = run.arrays['time']
    states = run.arrays['states']
    ref = run.arrays['reference']
    ids = run.scenario.ids
    schedule = loss_figures.loss_schedule_of(run)   # roles change when the team re-forms after a loss
    with _style():
        fig = _figure('xy_snapshots')
        ax = fig.add_subplot(1, 1, 1)
        for c, i in enumerate(ids):
            ax.plot(states[:, c, 0], states[:, c, 1], color=_uh_colour(c), linewidth=1.0, alpha=0.6,
                    label=_uh_label(run, i))
        ax.plot(ref[:, 0], ref[:, 1], label='virtual leader', **_VL)
        centre = np.nanmean(ref[:, 0:2], axis=0)  # labels go outward from the middle of the path
        for ts in snapshot_times(float(t[-1]), count):
            k = int(np.argmin(np.abs(t - ts)))
            leaders, followers, lost = ([ids.index(i) for i in group]
                                        for group in loss_figures.roles_at(run, schedule, k))
            for c in lost:
                ax.plot(*states[k, c, 0:2], marker='X', color='0.55', markersize=10, markeredgecolor='black',
                        markeredgewidth=0.6, zorder=5)
            lead = states[k, leaders, 0:2]
            if np.isfinite(lead).all() and len(leaders) >= 3:
                hull = _convex_hull_2d(lead)
                ax.add_patch(Polygon(hull, closed=True, facecolor='tab:blue', alpha=0.12,
                                     edgecolor='tab:blue', linewidth=1.4, zorder=1))
            for c in leaders:
                ax.plot(*states[k, c, 0:2], marker='^', color=_uh_colour(c), markersize=9,
                        markeredgecolor='black', markeredgewidth=0.6, zorder=5)
            for c in followers:
                ax.plot(*states[k, c, 0:2], marker='o', color=_uh_colour(c), markersize=8,
                        markeredgecolor='black', markeredgewidth=0.6, zorder=5)
            ax.plot(ref[k, 0], ref[k, 1], marker='*', color='black', markersize=11, zorder=4)
            points = states[k, :, 0:2]
            points = points[np.isfinite(points).all(axis=1)]
            if len(points):
                middle = points.mean(axis=0)
                away = middle - centre
                norm = float(np.hypot(*away))
                away = away / norm if norm > 1e-9 else np.array([0.0, -1.0])
                reach = float(np.max((points - middle) @ away)) + 1.2
                ax.text(*(middle + away * reach), f't = {t[k]:g} s', ha='center', va='center', fontsize=11,
                        color='0.1', zorder=6,
                        bbox=dict(boxstyle='round,pad=0.2', facecolor='white', edgecolor='0.6', alpha=0.85))
        ax.set_aspect('equal', adjustable='datalim')
        ax.set_xlabel('x (m)')
        ax.set_ylabel('y (m)')
        handles, labels = ax.get_legend_handles_labels()
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch
        handles += [Patch(facecolor='tab:blue', alpha=0.25, edgecolor='tab:blue', label="leaders' convex hull"),
                    Line2D([], [], marker='^', linestyle='', color='0.5', markeredgecolor='black', label='leader'),
                    Line2D([], [], marker='o', linestyle='', color='0.5', markeredgecolor='black', label='follower'),
                    Line2D([], [], marker='*', linestyle='', color='black', markersize=11,
                           label='virtual leader at the snapshot')]
        fig.legend(handles=handles, loc='outside lower center', ncol=4, frameon=False)
        _title(fig, run, 'XY plane with snapshots of the formation')
        return _save(fig, path)


def _convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Vertices (counter-clockwise) of the convex hull of 2-D ``points`` (N, 2) (monotone chain)."""
    pts = sorted(map(tuple, np.asarray(points, dtype=float)))
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


# ----------------------------------------------------------------------------------------------
# Fault estimation
# ----------------------------------------------------------------------------------------------
def plot_faults(run, uh: int, path: Path) -> Path:
    """Estimated (dashed) vs true (solid) lumped faults of UH ``uh``.

    F_p (m/s^2, inertial x, y, z) left, F_w (rad/s^2, body roll, pitch, yaw) right, one row per axis; dotted line at the
    onset.
    """
    t = run.arrays['time']
    c = run.scenario.ids.index(uh)
    info = faulted_uhs(run.scenario, run.arrays).get(uh)
    with _style():
        fig = _figure('faults')
        axes = fig.subplots(3, 2, sharex=True)
        loops = [('fault_true_p', 'fault_est_p', 'p', 'm/s²', ('x', 'y', 'z'), 'position loop'),
                 ('fault_true_w', 'fault_est_w', 'w', 'rad/s²', ('roll', 'pitch', 'yaw'), 'attitude loop')]
        t_end = float(t[-1])
        skip = TRANSIENT_S if t_end > 4 * TRANSIENT_S else 0.0
        for col, (true_key, est_key, name, unit, axes_names, loop) in enumerate(loops):
            true = run.arrays[true_key][:, c]
            est = run.arrays[est_key][:, c]
            for row in range(3):
                ax = axes[row, col]
                ax.plot(t, true[:, row], color='black', linewidth=1.8, label=f'true $F_{name}$')
                ax.plot(t, est[:, row], color='tab:red', linestyle='--', linewidth=1.6,
                        label=f'estimated $\\hat{{F}}_{name}$')
                ax.set_ylabel(f'$F_{{{name},\\mathrm{{{axes_names[row]}}}}}$ ({unit})')
                _robust_ylim(ax, t, true[:, row], est[:, row], skip)
                if row == 0:
                    scored = info is not None and (name == 'w' or info.collective)
                    ax.set_title(f'{loop}: $F_{name}$ ({"scored" if scored else "not scored: no collective fault"})')
                _mark_faults(ax, run, uh)
            axes[2, col].set_xlabel('time t (s)')
        handles = axes[0, 0].lines[:2]
        fig.legend(handles, ['true lumped fault $F$', r'estimate $\hat{F}$ of the fault observer'],
                   loc='outside lower center', ncol=2, frameon=False)
        clipped = f' (y range without the first {skip:g} s transient)' if skip else ''
        _title(fig, run, f'Lumped faults of UH{uh}, estimated vs true{clipped}')
        return _save(fig, path)


def _robust_ylim(ax, t, true, est, skip: float) -> None:
    """Set a y range holding the true fault everywhere and the estimate after ``skip`` s, with 8 % margins.

    Start-up spikes of the observers would otherwise squash the curves.
    """
    late = t >= skip
    values = np.concatenate([np.asarray(true, dtype=float), np.asarray(est, dtype=float)[late]])
    values = values[np.isfinite(values)]
    if values.size == 0:
        return
    lo, hi = float(values.min()), float(values.max())
    pad = 0.08 * (hi - lo) if hi > lo else max(abs(hi), 1e-3) * 0.5
    ax.set_ylim(lo - pad, hi + pad)


def _fault_free_steps(run, uh: int, faulted: dict) -> np.ndarray:
    """(K+1,) bool: the samples at which no scheduled fault of ``uh`` acts (all for a healthy UH)."""
    t = np.asarray(run.arrays['time'], dtype=float)
    return t < faulted[uh].onset if uh in faulted else np.ones(t.shape, dtype=bool)


def _log_ylim(ax, shown, threshold: float) -> float:
    """Log y range from below the scored values and a tenth of ``threshold`` up to the largest value drawn.

    Returns its bottom (curves are clipped to it, so a zero estimate stays visible).
    """
    values = np.concatenate(shown) if shown else np.empty(0)
    values = values[np.isfinite(values) & (values > 0)]
    low = min(threshold / 10, 0.5 * float(np.percentile(values, 1))) if values.size else threshold / 10
    bottom = max(low, threshold * 1e-4)
    top = max(3 * threshold, 2 * float(values.max())) if values.size else 10 * threshold
    ax.set_ylim(bottom, top)
    return bottom


def plot_false_fault_estimate(run, path: Path) -> Path:
    """Draw the false fault estimate made visible (docs/metrics.md#false-fault-estimate).

    ``|Fhat_p|`` (m/s^2, top) and ``|Fhat_w|`` (rad/s^2, bottom), log scale, of every UH where no
    fault acts: healthy UHs over the whole run (solid), faulted UHs up to their onset (dashed);
    the acceptance threshold (black dashes), the start-up that the metric leaves out shaded, and
    each UH's RMS over its window (the run's ``false_fault_estimate``) in the legend. Values below
    the y range (an estimate still exactly zero) are drawn on its bottom edge.
    """
    t = np.asarray(run.arrays['time'], dtype=float)
    ids = run.scenario.ids
    faulted = faulted_uhs(run.scenario, run.arrays)
    scores = run.metrics.get('false_fault_estimate') or {}
    scored = t >= FALSE_ESTIMATE_START
    with _style():
        fig = _figure('false_fault_estimate')
        axes = fig.subplots(2, 1, sharex=True)
        for ax, vector in zip(axes, LUMPED_FAULTS, strict=True):
            unit = vector.unit.replace('^2', '²')
            name = f'$\\|\\hat{{F}}_{vector.key}\\|$'
            norms = np.linalg.norm(np.asarray(run.arrays[vector.estimate_array], dtype=float), axis=-1)
            fault_free = {uh: _fault_free_steps(run, uh, faulted) for uh in ids}
            bottom = _log_ylim(ax, [norms[fault_free[uh] & scored, c] for c, uh in enumerate(ids)],
                               vector.false_estimate_threshold)
            for c, uh in enumerate(ids):
                keep = fault_free[uh]
                if not keep.any():
                    continue
                rms = (scores.get(f'uh{uh}') or {}).get(vector.key)
                where = 'healthy' if uh not in faulted else f'before its fault at {faulted[uh].onset:g} s'
                ax.semilogy(t[keep], np.maximum(norms[keep, c], bottom), color=_uh_colour(c),
                            linestyle='-' if uh not in faulted else '--',
                            label=f'UH{uh} ({where})' + (f': RMS {rms:.3g} {unit}' if rms is not None else ''))
            threshold = vector.false_estimate_threshold
            ax.axhline(threshold, color='black', linestyle=(0, (7, 3)), linewidth=2.2,
                       label=f'threshold {threshold:g} {unit}')
            ax.axvspan(float(t[0]), min(FALSE_ESTIMATE_START, float(t[-1])), color='0.88', zorder=0,
                       label='start-up, not scored')
            _mark_faults(ax, run)
            largest = (scores.get('max') or {}).get(vector.key)
            ax.set_title(f'{vector.loop} loop: {name} where no fault acts'
                         + (f' (largest RMS over the UHs: {largest:.3g} {unit})' if largest is not None else ''))
            ax.set_ylabel(f'{name} ({unit})')
            ax.legend(loc='upper left', bbox_to_anchor=(1.01, 1.0), frameon=False, fontsize=10)
        axes[1].set_xlabel('time t (s)')
        _title(fig, run, 'False fault estimates (log scale)')
        return _save(fig, path)


# ----------------------------------------------------------------------------------------------
# Figures 10-12: formation and containment errors, runs overlaid
# ----------------------------------------------------------------------------------------------
def plot_topology(run, path: Path) -> Path:
    """Draw the communication graph before and after each loss (:func:`uh_report.loss_figures.plot_topology`)."""
    with _style():
        return loss_figures.plot_topology(run, path, _figure, _save, _title)


def uh_errors(run) -> np.ndarray:
    """Return the (K+1, n) errors of each UH, m (docs/metrics.md), UH axis in ``scenario.ids`` order.

    The formation error ``|p_i - h_i - p_0|`` of each leader and the containment error
    ``|p_k - sum_j w_kj p_j|`` of each follower; in a run that lost UHs against the team in force
    (:func:`uh_report.loss_figures.errors_in_force`: NaN for a lost or holding UH).
    """
    in_force = errors_in_force(run)
    if in_force is not None:
        return in_force
    sc = run.scenario
    pos = np.asarray(run.arrays['states'], dtype=float)[..., X_P_SLICE]
    p0 = np.asarray(run.arrays['reference'], dtype=float)[:, RUN_REF_POSITION]
    n_lead = len(sc.leaders)
    h = np.array([sc.offsets[i] for i in sc.leaders], dtype=float)
    out = np.empty(pos.shape[:2])
    out[:, :n_lead] = formation_errors(pos[:, :n_lead], p0, h)
    if sc.followers:
        out[:, n_lead:] = containment_errors(pos[:, n_lead:], pos[:, :n_lead], sc.containment_weights)
    return out


def _log_floor(values) -> float:
    finite = np.asarray(values)[np.isfinite(values) & (np.asarray(values) > 0)]
    return max(1e-5, float(np.min(finite))) if finite.size else 1e-5


def _settle_line(ax, runs) -> None:
    settle = runs[0].scenario.settle_time
    if all(settle <= float(r.arrays['time'][-1]) for r in runs):
        _vline(ax, settle, 'settle')


def plot_errors(runs, path: Path) -> Path:
    """Draw the RMS formation and containment errors against time, one line per run (Figures 10-12).

    RMS over the leaders of the formation errors and RMS over the followers of the containment
    errors (m, log scale), with an inset table of the after-settle RMS from each run's metrics.
    """
    with _style():
        fig = _figure('errors')
        axes = fig.subplots(2, 1, sharex=True)
        for r, run in enumerate(runs):
            colour, dash = _RUN_STYLES[r % len(_RUN_STYLES)]
            err = uh_errors(run)
            n_lead = len(run.scenario.leaders)
            t = run.arrays['time']
            groups = [(axes[0], err[:, :n_lead], 'formation_rms_m'), (axes[1], err[:, n_lead:], 'containment_rms_m')]
            for ax, e, key in groups:
                if e.shape[1] == 0:
                    continue
                with np.errstate(invalid='ignore'), warnings.catch_warnings():   # a step with every UH lost: NaN
                    warnings.simplefilter('ignore', RuntimeWarning)
                    rms = np.sqrt(np.nanmean(e ** 2, axis=1))
                after = run.metrics.get(key)
                label = run.label + (f' (RMS after settle: {after:.3g} m)' if isinstance(after, (int, float)) else '')
                ax.semilogy(t, np.maximum(rms, 1e-6), color=colour, linestyle=dash, label=label)
        axes[0].set_ylabel('formation error (m)')
        axes[0].set_title(r'Leaders: RMS over the leaders of $\|p_i - h_i - p_0\|$')
        axes[1].set_ylabel('containment error (m)')
        axes[1].set_title(r'Followers: RMS over the followers of $\|p_k - \sum_j w_{kj}\, p_j\|$')
        axes[1].set_xlabel('time t (s)')
        for ax in axes:
            _settle_line(ax, runs)
            _mark_faults(ax, runs[0])
            mark_losses(ax, runs[0], _vline)
            ax.legend(loc='upper right', framealpha=0.9)
        what = 'Formation and containment errors' + (' of ' + ', '.join(r.label for r in runs) if len(runs) > 1 else '')
        fig.suptitle(what + ' (log scale)',
                     fontsize=14, fontweight='bold')
        return _save(fig, path)


def plot_errors_per_uh(runs, path: Path) -> Path:
    """Draw the formation (leaders) or containment (followers) error of each UH against time.

    In m, log scale; one panel per UH, one line per run.
    """
    sc = runs[0].scenario
    ids = sc.ids
    cols = 2
    rows = math.ceil(len(ids) / cols)
    with _style():
        fig = _figure('errors_per_uh')
        axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True)).reshape(rows, cols)
        for r, run in enumerate(runs):
            colour, dash = _RUN_STYLES[r % len(_RUN_STYLES)]
            err = uh_errors(run)
            for c, _i in enumerate(ids):
                ax = axes.flat[c]
                ax.semilogy(run.arrays['time'], np.maximum(err[:, c], 1e-6), color=colour, linestyle=dash,
                            label=run.label)
        for c, i in enumerate(ids):
            ax = axes.flat[c]
            leader = i in sc.leaders
            ax.set_title(f'UH{i}: {"formation" if leader else "containment"} error'
                         + (' (against the team in force)' if has_losses(runs[0]) else ''))
            ax.set_ylabel((r'$\|p_i - h_i - p_0\|$' if leader else r'$\|p_k - \sum_j w_{kj} p_j\|$') + ' (m)')
            _settle_line(ax, runs)
            _mark_faults(ax, runs[0], i)
            mark_losses(ax, runs[0], _vline)
        handles, labels = axes.flat[0].get_legend_handles_labels()
        spare = list(axes.flat[len(ids):])
        for ax in spare:
            ax.set_visible(False)
        for c in range(cols):
            visible = [axes[rr, c] for rr in range(rows) if rr * cols + c < len(ids)]
            if visible:
                visible[-1].set_xlabel('time t (s)')
                visible[-1].xaxis.set_tick_params(labelbottom=True)
        if spare:  # the legend goes where a panel is left free
            spare[0].set_visible(True)
            spare[0].axis('off')
            spare[0].legend(handles, labels, loc='center', frameon=False, fontsize=13, title='runs')
        else:
            fig.legend(handles, labels, loc='outside lower center', ncol=len(labels), frameon=False)
        fig.suptitle('Formation error of each leader and containment error of each follower (log scale)',
                     fontsize=14, fontweight='bold')
        return _save(fig, path)
