"""Generated team scenarios of any size, for scaling benchmarks (docs/graph.md, docs/scenario.md).

:func:`team_mapping` builds the mapping of a valid scenario (the form :mod:`uh_topology.scenario`
reads from YAML) with N leaders and M followers:

* **leaders** ``1..N`` on a circle around the virtual leader (offsets
  ``h_i = R [cos(2 pi (i-1)/N), sin(2 pi (i-1)/N), 0]``, the radius R keeping neighbouring slots at
  least :data:`MIN_SPACING` m apart and never below the paper's 3 m), connected in a directed ring
  (leader i hears leader i-1, leader 1 hears leader N) with every :data:`LINK_EVERY`-th leader
  (1, 1 + LINK_EVERY, ...) also hearing the virtual leader, so no leader is more than
  LINK_EVERY - 1 ring hops from the reference;
* **followers** ``N+1..N+M``: follower j (0-based) hears leaders ``j mod N`` and ``(j+1) mod N``
  (two leaders; one when N = 1) and the previous follower (cyclically; none when M = 1);
* initial states at rest, level, a few metres from the formation slot (deterministic
  perturbations), the paper's control period, substeps, model mismatch, helicopter, reference,
  disturbance and gains;
* the paper's actuator faults (docs/scenario.md) from t = 10 s, repeated over the team: the faults of
  UH 2 on leaders 2, 5, 8, ..., those of UH 3 on leaders 3, 6, 9, ..., those of UH 5 on every
  second follower.
* the safety filter off (``safety: {enabled: false}``, the law alone): followers between the same
  two leaders share a containment target, and with one leader every follower's target is its slot,
  which no filter can hold apart (docs/safety.md#design-time-check); these teams measure the law's
  cost as the team grows.

The paper's values are read from the bundled ``uh_topology/config/paper.yaml``, their one home.

Every follower hears a leader directly, so ``L1`` is strictly diagonally dominant (non-singular)
and ``-L1^-1 L2`` has non-negative rows summing to 1 (the topology checks of
:mod:`uh_topology.scenario` pass; :func:`write_team_scenario` loads the file it wrote to make
sure). :func:`split_team` chooses N and M for a team size.
"""
from __future__ import annotations

import copy
import functools
import math
from pathlib import Path

import yaml

from .scenario import duration_steps, load_scenario
from .schema import CONFIG_DIR

__all__ = ['GenerateError', 'split_team', 'team_mapping', 'write_team_scenario', 'MIN_SPACING',
           'LINK_EVERY', 'FOLLOWERS_PER_LEADER']

#: Smallest distance between neighbouring leader slots on the formation circle, m.
MIN_SPACING = 5.0
#: Every LINK_EVERY-th leader hears the virtual leader.
LINK_EVERY = 4
#: Default followers per leader of :func:`split_team` (the issue asks for 1 to 3).
FOLLOWERS_PER_LEADER = 1.5

#: The paper scenario, whose values a generated team takes.
PAPER_SCENARIO = CONFIG_DIR / 'paper.yaml'
# The UHs of the paper whose faults (docs/scenario.md) are repeated over a generated team.
_FAULT_PATTERN_UHS = (2, 3, 5)


class GenerateError(ValueError):
    """A team that cannot be generated (sizes, duration)."""


def split_team(size: int, followers_per_leader: float = FOLLOWERS_PER_LEADER) -> tuple[int, int]:
    """(N leaders, M followers) with ``N + M = size`` and ``M / N`` closest to ``followers_per_leader``.

    ``split_team(5) == (2, 3)``, ``split_team(40) == (16, 24)``. Needs ``size >= 2`` (a leader
    and a follower) and a ratio in [1, 3].
    """
    if isinstance(size, bool) or not isinstance(size, int) or size < 2:
        raise GenerateError(f'team size must be an integer >= 2 (a leader and a follower), got {size!r}')
    if not 1.0 <= followers_per_leader <= 3.0:
        raise GenerateError(f'followers per leader must be in [1, 3], got {followers_per_leader!r}')
    n = max(1, min(size - 1, round(size / (1.0 + followers_per_leader))))
    return n, size - n


@functools.lru_cache(maxsize=None)
def _paper() -> dict:
    """Read the paper scenario's mapping once (callers copy what they put in a team)."""
    return yaml.safe_load(PAPER_SCENARIO.read_text())


def _paper_radius() -> float:
    """Give the paper's formation radius ``|h_1|``, m (3 m)."""
    return math.hypot(*_paper()['uhs'][0]['offset'])


def _fault_pattern(uh_id: int) -> tuple:
    """Give the paper's faults of UH ``uh_id`` as ``(fault without uh and onset_time, onset_time)`` pairs."""
    return tuple(({k: v for k, v in f.items() if k not in ('uh', 'onset_time')}, f['onset_time'])
                 for f in _paper()['faults'] if f['uh'] == uh_id)


def _radius(n_leaders: int) -> float:
    paper = _paper_radius()
    if n_leaders < 2:
        return paper
    return max(paper, MIN_SPACING / (2.0 * math.sin(math.pi / n_leaders)))


def _perturbation(uh_id: int) -> list:
    """Deterministic initial offset from the slot, within +-2 m per axis (golden-ratio sequence)."""
    phi = (math.sqrt(5.0) - 1.0) / 2.0
    return [round(4.0 * (((uh_id * (axis + 1) * phi) % 1.0) - 0.5), 3) for axis in range(3)]


def team_mapping(n_leaders: int, n_followers: int, *, duration: float = 60.0, faults: bool = True,
                 gains=None, name: str | None = None) -> dict:
    """Build the mapping of a valid scenario with ``n_leaders`` leaders and ``n_followers`` followers.

    Parameters
    ----------
    n_leaders, n_followers : int
        N >= 1, M >= 1.
    duration : float
        Run length, s (a multiple of the 0.01 s control period).
    faults : bool
        Apply the paper's fault patterns (module docstring) from t = 10 s.
    gains : str or Path, optional
        The ``gains:`` entry; default: the absolute path of the bundled ``paper_gains.yaml``, so the
        mapping can be written anywhere.
    name : str, optional
        Scenario name (default ``team_<N>l<M>f``).

    Returns
    -------
    dict
        Plain data (lists, floats, str) ready for ``yaml.safe_dump`` or
        :func:`uh_topology.scenario.scenario_from_mapping`.
    """
    for label, value in (('leaders', n_leaders), ('followers', n_followers)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise GenerateError(f'number of {label} must be an integer >= 1, got {value!r}')
    paper = _paper()
    dt = paper['dt']
    try:
        duration_steps(duration, dt)    # the one rule for durations
    except ValueError as exc:
        raise GenerateError(f'duration {exc}') from None
    n, m = n_leaders, n_followers
    radius = _radius(n)
    centre, r0 = paper['reference']['center'], paper['reference']['radius']
    start = (centre[0], centre[1] - r0, centre[2])   # the paper reference at t = 0: center + (0, -radius, 0)
    pattern_a, pattern_b, pattern_c = (_fault_pattern(uh) for uh in _FAULT_PATTERN_UHS)
    uhs, edges, links, fault_list = [], [], [], []
    slots = {}
    for i in range(1, n + 1):
        angle = 2.0 * math.pi * (i - 1) / n
        offset = [round(radius * math.cos(angle), 9), round(radius * math.sin(angle), 9), 0.0]
        slots[i] = offset
        d = _perturbation(i)
        uhs.append({'id': i, 'role': 'leader', 'offset': offset,
                    'initial_state': {'position': [round(start[a] + offset[a] + d[a], 6) for a in range(3)]}})
        if n > 1:
            edges.append({'uh': i, 'hears': n if i == 1 else i - 1, 'weight': 1.0})
        if (i - 1) % LINK_EVERY == 0:
            links.append({'uh': i, 'weight': 1.0})
        if faults and i % 3 == 2:
            fault_list += [dict(f, uh=i, onset_time=onset) for f, onset in pattern_a]
        elif faults and i % 3 == 0:
            fault_list += [dict(f, uh=i, onset_time=onset) for f, onset in pattern_b]
    for j in range(m):
        k = n + 1 + j
        heard = sorted({1 + j % n, 1 + (j + 1) % n})
        for leader in heard:
            edges.append({'uh': k, 'hears': leader, 'weight': 1.0})
        if m > 1:
            edges.append({'uh': k, 'hears': n + 1 + (j - 1) % m, 'weight': 1.0})
        centre = [sum(slots[leader][a] for leader in heard) / len(heard) for a in range(3)]
        d = _perturbation(k)
        uhs.append({'id': k, 'role': 'follower',
                    'initial_state': {'position': [round(start[a] + 0.5 * centre[a] + d[a], 6)
                                                   for a in range(3)]}})
        if faults and j % 2 == 1:
            fault_list += [dict(f, uh=k, onset_time=onset) for f, onset in pattern_c]
    mapping = {
        'name': name or f'team_{n}l{m}f',
        'description': f'generated team: {n} leaders in a ring around the virtual leader, {m} followers '
                       'each hearing two leaders and one follower (uh_topology.generate)',
        'dt': dt, 'substeps': paper['substeps'], 'duration': float(duration),
        'settle_time': min(paper['settle_time'], float(duration) / 2.0), 'model_mismatch': paper['model_mismatch'],
        'helicopter': paper['helicopter'],
        'gains': str(gains) if gains is not None else str(CONFIG_DIR / paper['gains']),
        'uhs': uhs, 'edges': edges, 'reference_links': links,
        'reference': copy.deepcopy(paper['reference']),
        'disturbance': copy.deepcopy(paper['disturbance']),
        'safety': {'enabled': False},   # shared containment targets: see the module docstring
    }
    if fault_list:
        mapping['faults'] = fault_list
    return mapping


def write_team_scenario(path, n_leaders: int, n_followers: int, **kwargs) -> Path:
    """Write :func:`team_mapping` as YAML to ``path``, check it loads, and return the path.

    Keyword arguments go to :func:`team_mapping`. Raises the scenario's own
    :class:`~uh_topology.errors.ScenarioError` if the written file does not validate.
    """
    path = Path(path)
    mapping = team_mapping(n_leaders, n_followers, **kwargs)
    header = (f'# Generated by uh_topology.generate: {n_leaders} leaders, {n_followers} followers.\n'
              '# Units: SI, angles in rad (see uh_topology/config/paper.yaml for every key).\n')
    path.write_text(header + yaml.safe_dump(mapping, sort_keys=False, default_flow_style=None, width=110))
    load_scenario(path)
    return path
