"""How a team came through its losses: per event, when it was detected, agreed and re-formed (docs/resilience.md).

:func:`team_errors` scores positions against a :class:`~uh_topology.reform.ReformedTeam`'s targets
(formation error of its leaders, containment error of its followers; NaN for a UH outside it).
:func:`errors_in_force` gives every step the errors against the team the whole team flies then:
the scenario's until every surviving UH knows of a loss, the re-formed one from then on.
:func:`reconfiguration` gives the ``reconfiguration`` section of ``metrics.json``.
"""
from __future__ import annotations

import numpy as np

from uh_core.layout import CHANNEL_NAMES, X_P_SLICE
from uh_topology.events import silent_events
from uh_topology.reform import held_team

from .separation_metrics import closest_pair_series
from .team_events import NEVER, LossSchedule, holds, loss_schedule

__all__ = ['team_errors', 'errors_in_force', 'reconfiguration', 'agreed_losses', 'leaving_rows', 'leaving_of',
           'REFORMED_FORMATION_M',
           'REFORMED_CONTAINMENT_M']

#: A team is re-formed once every leader is this close to its new formation target, m, and stays so.
REFORMED_FORMATION_M = 0.05
#: ... and every follower this close to its new containment target, m (the campaigns' success thresholds).
REFORMED_CONTAINMENT_M = 0.02


def team_errors(positions: np.ndarray, p0: np.ndarray, team, ids) -> np.ndarray:
    """Give the errors (K+1, n) of ``positions`` (K+1, n, 3) against ``team`` (``p0`` (K+1, 3)), m.

    A leader's ``|p_i - h_i - p_0|``, a follower's ``|p_k - sum_j w_kj p_j|``; NaN for a UH outside the team.
    """
    col = {i: c for c, i in enumerate(ids)}
    out = np.full(positions.shape[:2], np.nan)
    for i in team.leaders:
        out[:, col[i]] = np.linalg.norm(positions[:, col[i]] - team.offsets[i] - p0, axis=-1)
    lead = positions[:, [col[j] for j in team.leaders]] if team.leaders else None
    for r, k in enumerate(team.followers):
        target = np.einsum('j,tjx->tx', team.containment_weights[r], lead)
        out[:, col[k]] = np.linalg.norm(positions[:, col[k]] - target, axis=-1)
    return out


def agreed_losses(schedule, scenario) -> list:
    """Give ``[(event step, agreed step, lost UH, lost set)]`` by event step.

    From the agreed step on (:data:`NEVER` with ``hold``) every surviving UH knows of the losses in
    the lost set: the team in force is ``scenario.reformed(lost set)``.
    """
    out, lost = [], set()
    for j, e in sorted(schedule.lost_at.items(), key=lambda item: item[1]):
        alive = [i for i in scenario.ids if schedule.lost_at.get(i, NEVER) > e]
        step = schedule.agreed_at(j, alive) if schedule.reform else NEVER
        lost.add(j)
        out.append((e, step, j, frozenset(lost)))
    return out


def errors_in_force(states: np.ndarray, reference_p0: np.ndarray, scenario, schedule) -> np.ndarray:
    """Give the errors (K+1, n) against the team in force at each step (see the module docstring), m."""
    positions = states[:, :, X_P_SLICE]
    out = team_errors(positions, reference_p0, scenario.reformed(()), scenario.ids)
    agreed = agreed_losses(schedule, scenario)
    for e, _, j, _ in agreed:
        out[e:, list(scenario.ids).index(j)] = np.nan
    for _, step, _, lost in agreed:
        if step < NEVER and step < len(out):
            out[step:] = team_errors(positions[step:], reference_p0[step:], scenario.reformed(lost), scenario.ids)
    return out


def _settled_from(errors: np.ndarray, team, ids, k0: int, k1: int) -> int | None:
    """Give the first step in ``k0..k1-1`` from which ``team``'s errors stay under the thresholds to ``k1``."""
    col = [list(ids).index(i) for i in team.leaders], [list(ids).index(i) for i in team.followers]
    ok = np.ones(k1 - k0, dtype=bool)
    if col[0]:
        ok &= (errors[k0:k1, col[0]] <= REFORMED_FORMATION_M).all(axis=1)
    if col[1]:
        ok &= (errors[k0:k1, col[1]] <= REFORMED_CONTAINMENT_M).all(axis=1)
    if not ok.any() or not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    return k0 + (int(bad[-1]) + 1 if bad.size else 0)


def leaving_rows(leaving: dict) -> np.ndarray:
    """Give ``{uh: (step, channel)}`` of the UHs that left as int rows ``[uh, step, channel]`` (a run's ``leaving``)."""
    return np.array([[uh, step, channel] for uh, (step, channel) in sorted(leaving.items())],
                    dtype=np.int64).reshape(-1, 3)


def leaving_of(rows) -> dict:
    """Give ``{uh: (step, channel)}`` of a run's ``leaving`` rows (:func:`leaving_rows`); ``{}`` for None."""
    return {} if rows is None else {int(r[0]): (int(r[1]), int(r[2])) for r in np.asarray(rows).reshape(-1, 3)}


def observed_schedule(scenario, losses: dict) -> LossSchedule | None:
    """Give the :class:`LossSchedule` a recorded run shows (``losses`` of :func:`uh_report.bag_metrics.read_team_bag`).

    Who knew of which loss when is what the states carried. A loss the scenario does not schedule (a
    killed node in real time) is dated from its first declaration: the step after the last state the
    declaring UH had, ``declared - lost_steps + 1``; a UH that left (its own states carried its
    declaration: ``losses['leaving']``) from its declaration. None when no state carried a loss.
    """
    if not losses or not losses.get('declared'):
        return None
    events = {e.uh: e.step for e in silent_events(scenario.events)}
    lost_steps = scenario.resilience.lost_steps(float(scenario.dt))
    leaving = dict(losses.get('leaving', {}))
    lost_at = {j: step if j in leaving else events.get(j, step - lost_steps + 1)
               for j, step in losses['declared'].items()}
    return LossSchedule(lost_at=lost_at, declared={(0, j): s for j, s in losses['declared'].items()},
                        known=dict(losses['known']), reform=scenario.resilience.on_loss == 'reform',
                        leaving=leaving)


def reconfiguration(time: np.ndarray, positions: np.ndarray, reference_p0: np.ndarray, scenario,
                    losses: dict | None = None, leaving=None) -> list | None:
    """Give one entry per loss, metrics.json's ``reconfiguration`` (docs/metrics.md); None without one.

    ``time`` (K+1,) s, ``positions`` (K+1, n, 3) m in ``scenario.ids`` order, ``reference_p0`` (K+1, 3) m.
    The losses are the scenario's ``events`` as the in-process run works them out, or, with ``losses``
    (a recorded run), what its states carried (:func:`observed_schedule`); ``leaving``: the run's
    ``leaving`` rows (:func:`leaving_rows`) of an in-process run.
    """
    dt, last = float(scenario.dt), len(time)
    schedule = observed_schedule(scenario, losses) if losses is not None else None
    if schedule is None:
        if not scenario.events:
            return None
        schedule = loss_schedule(scenario, last - 1, leaving_of(leaving))
    held = holds(scenario, schedule, last - 1)
    agreed = agreed_losses(schedule, scenario)
    out = []
    for n, (e, step, j, lost) in enumerate(agreed):
        end = agreed[n + 1][0] if n + 1 < len(agreed) else last
        team = scenario.reformed(lost) if schedule.reform else held_team(scenario, lost)
        errors = team_errors(positions, reference_p0, team, scenario.ids)
        errors[:, [list(scenario.ids).index(i) for i in lost]] = np.nan
        start = min(step, end) if step < NEVER else e
        flying = [i for i in team.ids if i not in lost and i not in held]
        settled = _settled_from(errors, team, scenario.ids, start, end) if flying and schedule.reform else None
        window = slice(e, settled if settled is not None else end)
        tail = slice(max(e, end - round(10.0 / dt)), end)      # the last 10 s before the next event or the end

        def worst(uhs, rows, errors=errors, lost=lost):
            cols = [list(scenario.ids).index(i) for i in uhs if i not in lost]
            values = errors[rows][:, cols]
            return float(np.nanmax(values)) if cols and values.size and not np.isnan(values).all() else None

        declared = [s for (i, jj), s in schedule.declared.items() if jj == j and s < NEVER]
        after = slice(settled, end) if settled is not None else slice(0, 0)
        event = next((ev for ev in scenario.events if ev.uh == j), None)
        out.append({
            'uh': j, 'kind': event.kind if event is not None else ('unable' if j in schedule.leaving else 'lost'),
            'time_s': event.time if event is not None and j in schedule.leaving else e * dt,
            'channel': CHANNEL_NAMES[schedule.leaving[j][1]] if schedule.leaving.get(j, (0, -1))[1] >= 0 else None,
            'on_loss': 'reform' if schedule.reform else 'hold',
            'detected_at_s': min(declared) * dt if declared and schedule.reform else None,
            'agreed_at_s': step * dt if step < NEVER else None,
            'reformed_at_s': settled * dt if settled is not None else None,
            'formation_error_after_m': worst(team.leaders, after),
            'containment_error_after_m': worst(team.followers, after),
            'formation_error_last_10s_m': worst(team.leaders, tail),
            'containment_error_last_10s_m': worst(team.followers, tail),
            'min_separation_m': float(np.min(closest_pair_series(positions[window]))) if window.stop > e else None,
            'leaders': list(team.leaders), 'followers': list(team.followers),
            'promoted': {str(k): v for k, v in team.promoted.items()},
            'holding': {str(i): reason for i, (_, reason) in sorted(held.items())},
        })
    return out
