"""The ``safety`` mapping of a scenario, and the design-time check that its formation is separable.

The collision-avoidance layer is not part of the control law (docs/safety.md): this module reads
what configures it (:data:`uh_topology.scenario_keys.SAFETY_KEYS`) and checks, before anything
starts, that the team the scenario asks for can be flown apart:

* the leaders' formation slots ``p_0 + h_i`` and the followers' steady-state targets (the rows of
  ``-L1^-1 L2`` applied to the leaders' slots, docs/graph.md), pairwise, and the initial positions,
  pairwise;
* closer than two rotor radii (the rotor disks overlap: impossible to fly) is an error naming the
  UHs and the distance; closer than ``min_separation`` but not that close is a warning (the filter
  will hold the pair apart, so containment cannot reach zero there), printed at start and written
  to ``metrics.json``.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from . import errors as E
from . import scenario_keys
from .scenario_keys import SEPARATION_MARGIN, key_named, key_names, read_key
from .schema import ConfigContext

__all__ = ['SafetySpec', 'read_safety', 'default_min_separation', 'formation_points', 'close_pairs',
           'SeparationIssue', 'SAFETY_CHOICES', 'add_safety_argument', 'safety_override', 'overlap_line']

#: The values of the run scripts' ``--safety``.
SAFETY_CHOICES = ('on', 'off')


def _default(name: str):
    """Return the declared default of the ``safety`` key ``name``."""
    return key_named(scenario_keys.SAFETY_KEYS, name).default


@dataclass(frozen=True)
class SafetySpec:
    """The ``safety`` mapping as read (docs/scenario.md#safety).

    Attributes
    ----------
    enabled : bool
    min_separation : float or None
        m; None: the default, ``2 rotor_radius + SEPARATION_MARGIN`` of the airframe.
    sensing_radius, barrier_gain, brake_accel, slack_weight, sidestep_accel : float
        m, 1/s, m/s^2, -, m/s^2.
    proximity_delay_steps, proximity_loss, proximity_noise_position, proximity_noise_velocity, proximity_seed
        What degrades the proximity input: control steps, probability, m, m/s, seed.
    """

    # the defaults are those the keys declare (uh_topology.scenario_keys.SAFETY_KEYS), read once here
    enabled: bool = _default('enabled')
    min_separation: float | None = _default('min_separation')
    sensing_radius: float = _default('sensing_radius')
    barrier_gain: float = _default('barrier_gain')
    brake_accel: float = _default('brake_accel')
    slack_weight: float = _default('slack_weight')
    sidestep_accel: float = _default('sidestep_accel')
    proximity_delay_steps: int = _default('proximity_delay_steps')
    proximity_loss: float = _default('proximity_loss')
    proximity_noise_position: float = _default('proximity_noise_position')
    proximity_noise_velocity: float = _default('proximity_noise_velocity')
    proximity_seed: int = _default('proximity_seed')

    def separation(self, rotor_radius: float) -> float:
        """Return the minimum separation in force for an airframe of ``rotor_radius`` m."""
        return self.min_separation if self.min_separation is not None else default_min_separation(rotor_radius)


def default_min_separation(rotor_radius: float) -> float:
    """``2 rotor_radius + SEPARATION_MARGIN``, m (docs/safety.md#the-separation)."""
    return 2.0 * rotor_radius + SEPARATION_MARGIN


def read_safety(ctx: ConfigContext, raw) -> SafetySpec:
    """Validate the ``safety`` mapping ``raw`` (None: absent, every default)."""
    path = ('safety',)
    raw = {} if raw is None else raw
    ctx.mapping(raw, path, (), key_names(scenario_keys.SAFETY_KEYS), what='a safety mapping')
    values = {key.name: read_key(ctx, key, raw, path) for key in scenario_keys.SAFETY_KEYS
              if key.default is not None or raw.get(key.name) is not None}   # min_separation: the airframe's
    spec = SafetySpec(**values)
    if spec.min_separation is not None and spec.sensing_radius <= spec.min_separation:
        raise ctx.error(E.InvalidValueError, path + ('sensing_radius',),
                        f'sensing_radius {spec.sensing_radius:g} m is not beyond min_separation '
                        f'{spec.min_separation:g} m; allowed: > min_separation')
    return spec


def formation_points(leaders, followers, offsets, containment_weights) -> dict:
    """``{UH id: its place in the formation relative to p_0}``, m.

    ``h_i`` of a leader, ``sum_k w_ik h_k`` of a follower (the containment weights of the leaders' slots).
    """
    slots = np.array([offsets[k] for k in leaders], dtype=float).reshape(len(leaders), 3)
    points = {k: slots[r] for r, k in enumerate(leaders)}
    for r, i in enumerate(followers):
        points[i] = containment_weights[r] @ slots
    return points


@dataclass(frozen=True)
class SeparationIssue:
    """Two UHs whose planned places are closer than allowed: ``what`` is ``formation`` or ``initial``."""

    what: str
    first: int
    second: int
    distance: float

    def text(self) -> str:
        """One line: ``formation: UH4 and UH5 are 1.20 m apart``."""
        where = 'formation targets' if self.what == 'formation' else 'initial positions'
        return f'{where} of UH{self.first} and UH{self.second} are {self.distance:.2f} m apart'


def close_pairs(points: dict, limit: float, what: str) -> list:
    """Return the pairs of ``points`` ({id: position}) closer than ``limit`` m, closest first."""
    found = []
    for (i, p), (j, q) in itertools.combinations(sorted(points.items()), 2):
        distance = math.dist(p, q)
        if distance < limit:
            found.append(SeparationIssue(what, i, j, distance))
    return sorted(found, key=lambda issue: issue.distance)


def add_safety_argument(parser) -> None:
    """Add ``--safety on|off`` to an argparse parser (the run scripts share its wording)."""
    parser.add_argument('--safety', choices=SAFETY_CHOICES, default=None,
                        help="the collision-avoidance filter (docs/safety.md): 'on' or 'off' overrides the "
                             "scenario's safety.enabled; 'off' is the paper's law alone (default: the scenario's)")


def safety_override(value: str | None) -> bool | None:
    """``--safety``'s value as :func:`uh_topology.scenario.load_scenario` takes it (None: the scenario's)."""
    return None if value is None else value == 'on'


def overlap_line(metrics: dict, enabled: bool) -> str | None:
    """One line when a run's rotor disks overlapped (``metrics.json`` content), else None."""
    overlap = metrics.get('rotor_overlap_s')
    if not overlap:
        return None
    limit = (metrics.get('separation') or {}).get('rotor_overlap_m')
    where = f'{metrics["min_separation_pair"]} came within {metrics["min_separation_m"]:.2f} m'
    what = 'with the safety filter on' if enabled else "the paper's law alone (safety off) let rotors touch"
    advice = '' if enabled else '; --safety on keeps them apart (docs/safety.md)'
    return f'{what}: {where}, rotor disks overlapping (under {limit:.2f} m) for {overlap:g} s{advice}'
