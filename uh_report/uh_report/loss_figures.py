"""What a report shows of a run that lost helicopters (docs/resilience.md, docs/report.md).

* :func:`loss_schedule_of`: who knew of which loss when, from the run's states (a recorded run) or
  worked out from the scenario's ``events`` (an in-process run's arrays);
* :func:`errors_in_force`: each UH's error against the team it was flying (the scenario's until
  every UH knew of a loss, the re-formed one after; NaN for a lost or holding UH);
* :func:`mark_losses`: the loss, the agreement and the re-forming as labelled lines on a time axis;
* :func:`plot_topology`: the graph before and after each loss, UHs at their places in the formation.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from uh_team.reconfiguration import agreed_losses, leaving_of, observed_schedule
from uh_team.reconfiguration import errors_in_force as _errors_in_force
from uh_team.run_arrays import RUN_REF_POSITION
from uh_team.team_events import loss_schedule
from uh_topology.reform import declared_edges, reformed_team
from uh_topology.safety import formation_points

__all__ = ['loss_schedule_of', 'errors_in_force', 'mark_losses', 'plot_topology', 'has_losses', 'roles_at']


def has_losses(run) -> bool:
    """Tell whether the run's metrics report a loss (``reconfiguration``)."""
    return bool((run.metrics or {}).get('reconfiguration'))


def loss_schedule_of(run):
    """Give the run's :class:`~uh_team.team_events.LossSchedule`, or None when it lost no UH."""
    if not has_losses(run):
        return None
    observed = observed_schedule(run.scenario, run.arrays.get('losses')) if 'losses' in run.arrays else None
    if observed is None and run.scenario.events:
        observed = loss_schedule(run.scenario, len(run.arrays['time']) - 1, leaving_of(run.arrays.get('leaving')))
    return observed


def errors_in_force(run):
    """Give the (K+1, n) errors against the team in force (module docstring), or None when the run lost no UH."""
    schedule = loss_schedule_of(run)
    if schedule is None:
        return None
    states = np.asarray(run.arrays['states'], dtype=float)
    p0 = np.asarray(run.arrays['reference'], dtype=float)[:, RUN_REF_POSITION]
    return _errors_in_force(states, p0, run.scenario, schedule)


def roles_at(run, schedule, k: int) -> tuple:
    """Give ``(leaders, followers, lost)`` (UH ids) of the team in force at step ``k`` (``schedule`` may be None)."""
    scenario = run.scenario
    if schedule is None:
        return tuple(scenario.leaders), tuple(scenario.followers), ()
    lost = tuple(j for j, e in sorted(schedule.lost_at.items()) if e <= k)
    in_force = frozenset()      # the lost set of the last loss every UH knew of by step k (errors_in_force's rule)
    for _, step, _, known in agreed_losses(schedule, scenario):
        if step <= k:
            in_force = known
    team = scenario.reformed(in_force)
    return (tuple(i for i in team.leaders if i not in lost), tuple(i for i in team.followers if i not in lost), lost)


def mark_losses(ax, run, vline) -> None:
    """Draw each loss, its agreement and its re-forming on ``ax`` with ``vline(ax, t, text)``."""
    for event in (run.metrics or {}).get('reconfiguration') or ():
        vline(ax, event['time_s'], f'UH{event["uh"]} lost')
        if event.get('reformed_at_s') is not None:
            vline(ax, event['reformed_at_s'], 're-formed')


def _places(scenario, team) -> dict:
    """Give ``{UH: (x, y)}``: the places in the formation of ``team``; a lost UH 1.5 m outside its old place."""
    old = formation_points(scenario.leaders, scenario.followers, scenario.offsets, scenario.containment_weights)
    new = team.places() if team.leaders else {}
    centre = np.mean([np.asarray(p)[:2] for p in old.values()], axis=0)
    out = {}
    for i in scenario.ids:
        place = np.asarray(new.get(i, old[i]), dtype=float)[:2]
        if i in team.lost:
            away = place - centre
            place = place + 1.5 * away / max(float(np.hypot(*away)), 1e-9)
        out[i] = tuple(place)
    return out


def _draw_graph(ax, scenario, team, edges, title: str) -> None:
    """Draw one graph: UHs at their places, an arrow from each UH heard to its hearer, the virtual leader."""
    places = _places(scenario, team)
    centre = np.mean([places[i] for i in scenario.ids], axis=0)
    vl = (centre[0], centre[1] - 1.6 * max(1.0, np.ptp([p[1] for p in places.values()])))
    for (i, j) in sorted(edges):
        start = vl if j == 0 else places[j]
        ax.annotate('', xy=places[i], xytext=start, zorder=1,
                    arrowprops=dict(arrowstyle='-|>', color='0.35', shrinkA=14, shrinkB=14, linewidth=1.2))
    ax.plot(*vl, marker='*', color='black', markersize=16, zorder=3)
    ax.text(vl[0], vl[1] - 0.5, 'virtual leader', ha='center', va='top', fontsize=10)
    for i in scenario.ids:
        role = team.role(i)
        marker, face = {'leader': ('^', 'tab:blue'), 'follower': ('o', 'tab:orange'),
                        'lost': ('X', '0.6'), 'holding': ('s', 'tab:red')}[role]
        ax.plot(*places[i], marker=marker, color=face, markersize=18, markeredgecolor='black', zorder=4)
        slot = next((f' (slot {s})' for s, uh in team.promoted.items() if uh == i), '')
        ax.text(places[i][0], places[i][1] + 0.55, f'UH{i} {role}{slot}', ha='center', va='bottom', fontsize=10,
                zorder=5)
    ax.set_title(title)
    ax.set_aspect('equal', adjustable='datalim')
    ax.margins(0.25)
    ax.set_axis_off()


def plot_topology(run, path: Path, figure, save, title) -> Path:
    """Draw the communication graph before the first loss and after each loss.

    ``figure``, ``save`` and ``title`` are :mod:`uh_report.report_figures`' helpers.
    """
    scenario = run.scenario
    events = (run.metrics or {}).get('reconfiguration') or ()
    fig = figure('topology')
    axes = np.atleast_1d(fig.subplots(1, len(events) + 1))
    _draw_graph(axes[0], scenario, scenario.reformed(()), declared_edges(scenario), 'before')
    lost = set()
    for ax, event in zip(axes[1:], events, strict=True):
        lost.add(int(event['uh']))
        # a hold repairs nothing: the declared edges only, nothing promoted
        team = (scenario.reformed(lost) if event.get('on_loss') == 'reform'
                else reformed_team(scenario, lost, declared_edges(scenario), promote=False))
        _draw_graph(ax, scenario, team, team.edges, f'after UH{event["uh"]} lost at {event["time_s"]:g} s '
                    f'({event.get("on_loss", "reform")})')
    title(fig, run, 'Communication graph before and after the losses')
    return save(fig, path)
