"""What a UH flies once it knows of losses, the same in process and on the nodes (docs/resilience.md).

* :func:`loss_impairments`: the links of a scenario with events as every receiver applies them: the
  declared and the standby links (a standby link gets the worst declared delay, jitter and loss),
  and each lost UH dropped from its event step on (as ``impairments.dropouts``).
* :func:`row_team`: the neighbours, weights, offsets and reference link a UH's controller uses when
  it sees the lost set ``lost`` (``on_loss: reform``) or the silent neighbours ``silent`` (``hold``),
  or the hold it flies instead.
* :func:`failsafe_step` and :func:`hold_reference`: a lost UH's failsafe (it brakes to a hover), a holding
  UH's pseudo virtual leader; :func:`leave_reference` that of a UH leaving the team (it climbs clear).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from uh_core.layout import R_P, R_YAW, REFERENCE_SIZE, STATE_SIZE, X_OMEGA, X_P, X_THETA, X_V

from .events import silent_events
from .graph import reachable_from
from .impairments import DEFAULT_COMPENSATION, NO_DROPOUT, PREDICTING, ImpairmentSpec
from .schema import read_only_array

__all__ = ['RowTeam', 'row_team', 'loss_impairments', 'failsafe_step', 'hold_reference', 'leave_reference',
           'predicting', 'NEVER']

#: A step that never comes (the impairments' "no dropout" step).
NEVER = NO_DROPOUT


@dataclass(frozen=True)
class RowTeam:
    """What one UH's controller flies: its neighbours (ascending) and weights, their offsets, its own, ``a_i0``.

    ``hold_reason`` is not None when the UH holds its position instead (no neighbour, ``a_i0 = 1``
    towards :func:`hold_reference`, own offset zero).
    """

    neighbours: tuple
    weights: tuple
    neighbour_offsets: tuple
    offset: np.ndarray
    leader_link: float
    hold_reason: str | None = None


def row_team(scenario, i: int, silent, lost, teams: dict) -> RowTeam:
    """Give the team UH ``i`` flies seeing the silent neighbours ``silent`` and the lost set ``lost``.

    ``lost`` selects the reformed team (:meth:`Scenario.reformed`, cached in ``teams`` by lost set);
    the UHs of ``silent`` are left out of it. A UH the team holds, or one without a path from the
    virtual leader once the silent and lost UHs are left out (Assumption 1), holds.
    """
    lost = frozenset(lost)
    if lost not in teams:
        teams[lost] = scenario.reformed(lost)
    team = teams[lost]
    zero = np.zeros(3)
    if i in team.holding:
        return RowTeam((), (), (), zero, 1.0, team.holding[i])
    gone = set(silent) | set(lost)
    size = max(scenario.ids) + 1
    adjacency = np.zeros((size, size))
    for (r, j), w in team.edges.items():
        adjacency[r, j] = w
    if i not in reachable_from(adjacency, (0,), allowed=set(team.ids) - gone):
        return RowTeam((), (), (), zero, 1.0, f'no path from the virtual leader without UH(s) {sorted(gone)}')
    neighbours = tuple(j for j in team.neighbours(i) if j not in gone)
    leader = i in team.leaders
    offsets = tuple(team.offsets[j] if leader else zero for j in neighbours)
    return RowTeam(neighbours, tuple(team.weight(i, j) for j in neighbours), offsets,
                   team.offsets[i] if leader else zero, team.leader_link(i))


def loss_impairments(scenario) -> ImpairmentSpec:
    """Give the links of ``scenario`` (which has events) as its receivers apply them (see the module docstring)."""
    imp = scenario.impairments
    links = {(i, j) for (i, j) in scenario.receivable_edges() if j != 0}
    if imp is None:
        delays, jitters, losses = ({e: 0 for e in links}, {e: 0 for e in links}, {e: 0.0 for e in links})
        noise, seed, dropouts, compensation = np.zeros(STATE_SIZE), 0, {}, DEFAULT_COMPENSATION
    else:
        worst = (max(imp.delays.values(), default=0), max(imp.jitters.values(), default=0),
                 max(imp.losses.values(), default=0.0))
        delays = {e: imp.delays.get(e, worst[0]) for e in links}
        jitters = {e: imp.jitters.get(e, worst[1]) for e in links}
        losses = {e: imp.losses.get(e, worst[2]) for e in links}
        noise, seed, dropouts, compensation = imp.noise, imp.seed, dict(imp.dropouts), imp.compensation
    dt = float(scenario.dt)
    for event in silent_events(scenario.events):   # from its event step on, nobody receives a lost UH
        dropouts[event.uh] = min(dropouts.get(event.uh, np.inf), event.step * dt)
    return ImpairmentSpec(seed=seed, delays=MappingProxyType(delays), losses=MappingProxyType(losses),
                          noise=read_only_array(np.array(noise, dtype=float)), dropouts=MappingProxyType(dropouts),
                          jitters=MappingProxyType(jitters), compensation=compensation)


def predicting(spec: ImpairmentSpec) -> tuple:
    """Give ``(predict, reference_motion)`` of ``spec``'s delay compensation."""
    return spec.compensation in PREDICTING, spec.compensation == 'reference_motion'


def failsafe_step(x, dt, accel):
    """Advance a lost UH's state ``x`` (12,) by one step ``dt`` (s) of its failsafe, in place.

    The failsafe of an autopilot that loses its link: the helicopter brakes at ``accel`` (m/s^2, the
    deceleration the safety filter assumes every UH of a pair gives, ``safety.brake_accel``) along its
    velocity until it is at rest, then hovers there; attitude kept, body rates zero. Plain arithmetic
    in a fixed order, so that the simulator node (Python) and the team kernel (numba) give the same bits.
    """
    vx, vy, vz = x[X_V], x[X_V + 1], x[X_V + 2]
    speed = math.sqrt(vx * vx + vy * vy + vz * vz)
    if speed > 0.0:
        scale = max(speed - accel * dt, 0.0) / speed
        nx, ny, nz = vx * scale, vy * scale, vz * scale
        x[X_P] += 0.5 * (vx + nx) * dt
        x[X_P + 1] += 0.5 * (vy + ny) * dt
        x[X_P + 2] += 0.5 * (vz + nz) * dt
        x[X_V], x[X_V + 1], x[X_V + 2] = nx, ny, nz
    x[X_OMEGA] = 0.0
    x[X_OMEGA + 1] = 0.0
    x[X_OMEGA + 2] = 0.0


def hold_reference(x_row: np.ndarray) -> np.ndarray:
    """Give the pseudo virtual leader ``[p, 0, psi]`` of a hold at the UH's position and yaw in ``x_row``."""
    ref = np.zeros(REFERENCE_SIZE)
    ref[R_P:R_P + 3] = x_row[X_P:X_P + 3]
    ref[R_YAW] = x_row[X_THETA + 2]     # psi, the third Euler angle
    return ref


def leave_reference(x_row: np.ndarray, climb: float) -> np.ndarray:
    """Give the pseudo virtual leader of a UH leaving the team: ``climb`` m above its position in ``x_row``, its yaw.

    docs/resilience.md#leaving-the-team: it holds there, clear of the team's plane, an obstacle the
    others' safety filters still see.
    """
    ref = hold_reference(x_row)
    ref[R_P + 2] += climb      # z up (docs/model.md#frames)
    return ref
