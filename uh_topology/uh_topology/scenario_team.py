"""The team of a scenario: its UHs (``uhs``), its graph (``edges``, ``reference_links``), Assumption 1 and Lemma 1.

The readers that :func:`uh_topology.scenario.scenario_from_mapping` calls for these parts (docs/scenario.md,
docs/graph.md); errors name the file, line and key path.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import errors as E
from .graph import (
    check_lemma1,
    containment_pattern,
    laplacian_blocks,
    unreachable_follower_message,
    unreachable_followers,
    unreachable_leader_message,
    unreachable_leaders,
)
from .schema import ConfigContext, read_only_array, type_name

__all__ = ['Team', 'read_team', 'read_edges', 'read_reference_links', 'check_assumptions', 'REFERENCE_LINK_RULES']

_UH_REQUIRED = ('id', 'role', 'initial_state')
_UH_OPTIONAL = ('offset',)
_STATE_REQUIRED = ('position',)
_STATE_OPTIONAL = ('velocity', 'euler', 'omega')


@dataclass(frozen=True)
class Team:
    """The UHs of a scenario: roles, offsets, initial states and where each is listed."""

    roles: dict      # id -> 'leader' | 'follower'
    offsets: dict    # leader id -> (3,) m
    states: dict     # id -> (12,)
    where: dict      # id -> index in `uhs`
    leaders: tuple
    followers: tuple


def read_team(ctx: ConfigContext, uhs) -> Team:
    """Read the ``uhs`` list and check the numbering: ids 1..N+M, leaders first, leaders with offsets."""
    if not isinstance(uhs, list) or not uhs:
        raise ctx.error(E.WrongTypeError, ('uhs',), f'expected a non-empty list of UHs, got {type_name(uhs)}')
    roles, offsets, states, where = {}, {}, {}, {}
    for idx, entry in enumerate(uhs):
        path = ('uhs', idx)
        ctx.mapping(entry, path, _UH_REQUIRED, _UH_OPTIONAL, what='a UH mapping')
        uid = ctx.integer(entry['id'], path + ('id',), what='an integer UH id')
        if uid in roles:
            raise ctx.error(E.DuplicateIdError, path + ('id',),
                            f'UH id {uid} is already used by uhs[{where[uid]}]; ids must be unique')
        if uid < 1:
            raise ctx.error(E.IdNumberingError, path + ('id',),
                            f'UH id {uid} is not allowed; 0 is the virtual leader, UH ids are 1..N+M')
        where[uid] = idx
        roles[uid] = ctx.string(entry['role'], path + ('role',), choices=('leader', 'follower'))
        states[uid] = _initial_state(ctx, entry['initial_state'], path + ('initial_state',))
        if 'offset' in entry:
            if roles[uid] == 'follower':
                raise ctx.error(E.FollowerOffsetError, path + ('offset',),
                                f'follower {uid} has a formation offset; only leaders have offsets '
                                f'(followers are placed by the containment weights)')
            offsets[uid] = ctx.vector(entry['offset'], path + ('offset',), unit='m')

    n = len(roles)
    leaders = tuple(sorted(i for i, r in roles.items() if r == 'leader'))
    followers = tuple(sorted(i for i, r in roles.items() if r == 'follower'))
    if not leaders:
        raise ctx.error(E.IdNumberingError, ('uhs',), 'no leader; at least one UH must have role: leader')
    if set(roles) != set(range(1, n + 1)) or leaders != tuple(range(1, len(leaders) + 1)):
        raise ctx.error(E.IdNumberingError, ('uhs',),
                        f'ids must be 1..{n} with the leaders first; got leaders {list(leaders)} and '
                        f'followers {list(followers)}')
    for j in leaders:
        if j not in offsets:
            raise ctx.error(E.MissingOffsetError, ('uhs', where[j]),
                            f'leader {j} has no formation offset; add offset: [x, y, z] (m)')
    return Team(roles=roles, offsets=offsets, states=states, where=where, leaders=leaders, followers=followers)


def _initial_state(ctx: ConfigContext, raw, sp: tuple) -> np.ndarray:
    """Read an ``initial_state`` mapping as the (12,) state: position m, velocity m/s, Euler rad, rate rad/s."""
    st = ctx.mapping(raw, sp, _STATE_REQUIRED, _STATE_OPTIONAL, what='an initial_state mapping')
    pos = ctx.vector(st['position'], sp + ('position',), unit='m')
    vel = ctx.vector(st.get('velocity', [0.0] * 3), sp + ('velocity',), unit='m/s')
    eul = ctx.vector(st.get('euler', [0.0] * 3), sp + ('euler',), unit='rad')
    omg = ctx.vector(st.get('omega', [0.0] * 3), sp + ('omega',), unit='rad/s')
    for axis, lim in ((0, math.pi / 2), (1, math.pi / 2)):
        if abs(eul[axis]) >= lim:
            raise ctx.error(E.InvalidValueError, sp + ('euler', axis),
                            f'{("roll", "pitch")[axis]} {eul[axis]} rad; allowed: |angle| < pi/2')
    return read_only_array(np.concatenate([pos, vel, eul, omg]))


def read_edges(ctx: ConfigContext, edges, team: Team, adjacency: np.ndarray) -> None:
    """Read the ``edges`` list into ``adjacency[i, j] = a_ij`` (UH i hears UH j)."""
    roles, known = team.roles, set(team.roles)
    if edges is None:
        edges = []
    if not isinstance(edges, list):
        raise ctx.error(E.WrongTypeError, ('edges',), f'expected a list of edges, got {type_name(edges)}')
    edge_at = {}
    for idx, edge in enumerate(edges):
        path = ('edges', idx)
        ctx.mapping(edge, path, ('uh', 'hears'), ('weight',), what='an edge mapping {uh, hears, weight}')
        i = ctx.uh_id(edge['uh'], path + ('uh',), known)
        j = ctx.uh_id(edge['hears'], path + ('hears',), known)
        if i == j:
            raise ctx.error(E.SelfLoopError, path, f'UH {i} hears itself (self-loop); an edge must join '
                            f'two different UHs')
        w = ctx.number(edge.get('weight', 1.0), path + ('weight',))
        if w < 0.0:
            raise ctx.error(E.NegativeWeightError, path + ('weight',),
                            f'negative weight {w} on edge {i}<-{j}; allowed: a weight >= 0')
        if (i, j) in edge_at:
            raise ctx.error(E.DuplicateEdgeError, path,
                            f'edge {i}<-{j} is already listed as edges[{edge_at[(i, j)]}]; list each '
                            f'directed edge once')
        if roles[i] == 'leader' and roles[j] == 'follower' and w > 0.0:
            raise ctx.error(E.LeaderHearsFollowerError, path,
                            f'leader {i} hears follower {j}; leaders may only hear leaders and the '
                            f'virtual leader')
        edge_at[(i, j)] = idx
        adjacency[i, j] = w


#: The rules ``reference_links`` may name instead of a list: a departure from the paper's graph
#: (docs/delay.md#remedies), recorded in run.json and metrics.json.
REFERENCE_LINK_RULES = ('all_leaders',)


def read_reference_links(ctx: ConfigContext, links, team: Team, adjacency: np.ndarray) -> str | None:
    """Read ``reference_links`` into ``adjacency[i, 0] = a_i0`` (UH i hears the virtual leader).

    A list of links, or the rule ``all_leaders``: every leader hears the virtual leader with weight 1
    (the delay remedy of docs/delay.md#remedies). Returns the rule, or None for a list.
    """
    roles, known = team.roles, set(team.roles)
    if links is None:
        links = []
    if isinstance(links, str):
        if links not in REFERENCE_LINK_RULES:
            raise ctx.error(E.InvalidValueError, ('reference_links',),
                            f'{links!r} is not a rule; allowed: a list of links {{uh, weight}} or '
                            + ', '.join(REFERENCE_LINK_RULES))
        if not team.leaders:
            raise ctx.error(E.InvalidValueError, ('reference_links',),
                            f'{links} needs leaders, and the team has none; allowed: a list of links')
        for i in team.leaders:
            adjacency[i, 0] = 1.0
        return links
    if not isinstance(links, list):
        raise ctx.error(E.WrongTypeError, ('reference_links',),
                        f'expected a list of links {{uh, weight}} or {", ".join(REFERENCE_LINK_RULES)}, '
                        f'got {type_name(links)}')
    link_at = {}
    for idx, link in enumerate(links):
        path = ('reference_links', idx)
        ctx.mapping(link, path, ('uh',), ('weight',), what='a link mapping {uh, weight}')
        i = ctx.uh_id(link['uh'], path + ('uh',), known)
        w = ctx.number(link.get('weight', 1.0), path + ('weight',))
        if w < 0.0:
            raise ctx.error(E.NegativeWeightError, path + ('weight',),
                            f'negative weight {w} on the virtual-leader link {i}<-0; allowed: a weight >= 0')
        if i in link_at:
            raise ctx.error(E.DuplicateEdgeError, path,
                            f'virtual-leader link {i}<-0 is already listed as reference_links'
                            f'[{link_at[i]}]; list each link once')
        if roles[i] == 'follower' and w > 0.0:
            raise ctx.error(E.FollowerLinkedToReferenceError, path + ('uh',),
                            f'follower {i} hears the virtual leader; only leaders may (followers '
                            f'are contained by the leaders)')
        link_at[i] = idx
        adjacency[i, 0] = w
    return None


def check_assumptions(ctx: ConfigContext, adjacency: np.ndarray, team: Team) -> tuple:
    """Check Assumption 1 and Lemma 1 (docs/graph.md); give ``(L1, L2, -L1^-1 L2)``.

    An unreachable UH is reported at its entry under ``uhs`` (the first one without a path).
    """
    leaders, followers, where = team.leaders, team.followers, team.where
    lost = unreachable_leaders(adjacency, leaders)
    if lost:
        raise ctx.error(E.UnreachableLeaderError, ('uhs', where[lost[0]]), unreachable_leader_message(lost),
                        ids=lost)
    lost = unreachable_followers(adjacency, leaders, followers)
    if lost:
        raise ctx.error(E.UnreachableFollowerError, ('uhs', where[lost[0]]),
                        unreachable_follower_message(lost), ids=lost)
    l1, l2 = laplacian_blocks(adjacency, leaders, followers)
    try:  # Lemma 1 (implied by Assumption 1; checked numerically as a guard)
        weights = check_lemma1(l1, l2, containment_pattern(adjacency, leaders, followers))
    except E.LaplacianConditionError as exc:
        raise ctx.error(E.LaplacianConditionError, ('edges',), exc.message) from None
    return l1, l2, weights
