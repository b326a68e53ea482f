"""The team that remains after helicopters are lost: one deterministic rule every UH applies (docs/resilience.md).

Every UH runs :func:`reformed_team` on the same two inputs, the scenario and the agreed lost set, so
every UH computes the same new team without negotiating. The rule works on *slots*: the scenario's
UHs are the slots; a slot keeps its in-edges, its formation offset (a leader's) and its reference
link whoever occupies it.

1. **Promotion.** Each lost leader's slot is given to a surviving follower: the assignment that
   minimises the total distance between the lost slots' offsets and the followers' places in the
   formation (:func:`~uh_topology.safety.formation_points`), by
   ``scipy.optimize.linear_sum_assignment``; when the available edges cannot serve it (someone would
   hold), the next assignments in order of cost are tried and the first that leaves nobody holding
   is kept (else the one that leaves fewest). Without a follower left, the slot stays empty.
2. **Repair.** Every occupied slot keeps its in-edges, read through the occupants: an edge from an
   occupied slot becomes an edge from its occupant; an edge from an empty slot (lost, or left by a
   promoted follower) is *bypassed*: it becomes edges from that slot's own in-neighbours, as far as
   needed to reach occupied slots or the virtual leader, each with the weight of the bypassed edge.
   A UH takes an edge only if it can receive it (a declared edge or a standby edge, so that the
   subscription exists from the start), and a leader only from a leader or the virtual leader.
   Two edges between one pair keep the larger weight.
3. **Check.** Assumption 1 and Lemma 1 again: every leader must have a path from the virtual leader
   through leaders, every follower a path from a leader. A UH without one is not part of the new
   team; it *holds* its position and the team says why (``holding``).

:func:`bypass_standby_edges` gives the standby edges the repair of every single loss needs: the
``standby_edges: bypass`` of a scenario.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from .graph import containment_weights, laplacian_blocks, reachable_from
from .safety import formation_points

__all__ = ['ReformedTeam', 'reformed_team', 'held_team', 'bypass_standby_edges', 'declared_edges']


@dataclass(frozen=True)
class ReformedTeam:
    """The team after the losses ``lost``, as every UH computes it.

    Attributes
    ----------
    lost : frozenset of int
        The lost UHs the team was computed for.
    leaders, followers : tuple of int
        The UHs flying in the new team, by role (ascending id); a promoted follower is a leader.
    offsets : dict {leader id: ndarray (3,)}
        Formation offsets, m (a promoted follower's is its slot's).
    edges : dict {(i, j): weight}
        UH ``i`` hears UH ``j`` (``j = 0``: the virtual leader) with weight ``a_ij``.
    promoted : dict {lost leader id: follower id}
        Whose slot each promoted follower took.
    holding : dict {UH id: reason}
        Surviving UHs without a valid place in the new team: they hold their position.
    containment_weights : ndarray (M, N)
        ``-L1^-1 L2`` of the new team (rows ``followers``, columns ``leaders``).
    """

    lost: frozenset
    leaders: tuple
    followers: tuple
    offsets: dict
    edges: dict
    promoted: dict = field(default_factory=dict)
    holding: dict = field(default_factory=dict)
    containment_weights: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def ids(self) -> tuple:
        """The UHs flying in the new team, leaders first."""
        return self.leaders + self.followers

    def neighbours(self, i: int) -> tuple:
        """Give the UHs ``i`` hears in the new team, ascending (the virtual leader left out)."""
        return tuple(sorted(j for (k, j) in self.edges if k == i and j != 0))

    def weight(self, i: int, j: int) -> float:
        """``a_ij`` in the new team (0 when ``i`` does not hear ``j``)."""
        return float(self.edges.get((i, j), 0.0))

    def leader_link(self, i: int) -> float:
        """``a_i0`` in the new team."""
        return self.weight(i, 0)

    def role(self, i: int) -> str:
        """``leader``, ``follower``, ``holding`` or ``lost``."""
        if i in self.lost:
            return 'lost'
        if i in self.holding:
            return 'holding'
        return 'leader' if i in self.leaders else 'follower'

    def places(self) -> dict:
        """``{UH id: its target relative to p_0}``, m, of every UH flying in the new team."""
        return formation_points(self.leaders, self.followers, self.offsets, self.containment_weights)


def declared_edges(scenario) -> set:
    """Give the scenario's edges ``(i, j)`` (``i`` hears ``j``; ``j = 0`` the virtual leader)."""
    a = np.asarray(scenario.adjacency)
    return {(int(i), int(j)) for i, j in zip(*np.nonzero(a > 0.0), strict=True)}


#: At most this many promotions are tried in order of cost for one that leaves nobody holding.
PROMOTIONS_TRIED = 720


def _promotions(scenario, lost) -> list:
    """Give the promotions ``{lost leader: follower}`` to try, the least total distance first.

    The first is ``linear_sum_assignment``'s (the least total distance from the lost slots' offsets
    to the followers' places); the others follow in order of cost (ties by candidate order), at most
    :data:`PROMOTIONS_TRIED`, so that a promotion the available edges cannot serve gives way to one they can.
    """
    slots = [i for i in scenario.leaders if i in lost]
    candidates = [k for k in scenario.followers if k not in lost]
    if not slots or not candidates:
        return [{}]
    places = formation_points(scenario.leaders, scenario.followers, scenario.offsets, scenario.containment_weights)
    cost = np.array([[np.linalg.norm(np.asarray(scenario.offsets[s]) - places[k]) for k in candidates]
                     for s in slots])
    rows, cols = linear_sum_assignment(cost)
    best = {slots[r]: candidates[c] for r, c in zip(rows, cols, strict=True)}
    chosen = [r for r in range(len(slots)) if slots[r] in best]
    others = []
    for perm in itertools.islice(itertools.permutations(range(len(candidates)), len(chosen)), PROMOTIONS_TRIED):
        total = sum(cost[r, c] for r, c in zip(chosen, perm, strict=True))
        others.append((total, perm))
    others.sort(key=lambda item: item[0])
    tries = [best] + [{slots[r]: candidates[c] for r, c in zip(chosen, perm, strict=True)} for _, perm in others]
    return [p for n, p in enumerate(tries) if p not in tries[:n]]


def _sources(a, slot, occupant, start) -> dict:
    """``{occupant or 0: weight}`` an occupied ``slot`` hears through its in-edges, empty slots bypassed."""
    out, best = {}, {slot: np.inf}
    stack = [(int(j), float(a[slot, j])) for j in np.nonzero(a[slot] > 0.0)[0]]
    while stack:
        j, w = stack.pop()
        if j == 0 or j in occupant:
            src = 0 if j == 0 else occupant[j]
            if src != start:
                out[src] = max(out.get(src, 0.0), w)
        elif w > best.get(j, 0.0):   # an empty slot: hear whom it heard, with the largest bypassed weight
            best[j] = w
            stack += [(int(m), w) for m in np.nonzero(a[j] > 0.0)[0]]
    return out


def reformed_team(scenario, lost, available=None, promote: bool = True) -> ReformedTeam:
    """Apply the rule of the module docstring to ``scenario`` without the UHs ``lost``.

    Parameters
    ----------
    scenario : Scenario
    lost : iterable of int
        The lost UHs (ids of the scenario).
    available : set of (i, j), optional
        The edges a UH can receive: the declared ones and the standby ones (default: every pair,
        which is how :func:`bypass_standby_edges` finds what the repair needs).
    promote : bool
        Give lost leaders' slots to followers (step 1); without, their slots stay empty (the team a
        hold is scored against).

    Returns
    -------
    ReformedTeam
    """
    lost = frozenset(int(i) for i in lost)
    team = None
    for promoted in (_promotions(scenario, lost) if promote else [{}]):
        candidate = _repaired(scenario, lost, available, promoted)
        if team is None or len(candidate.holding) < len(team.holding):
            team = candidate
        if not team.holding:
            break
    return team


def _repaired(scenario, lost, available, promoted) -> ReformedTeam:
    """Give the team of steps 2 and 3 with the promotions ``promoted``."""
    a = np.asarray(scenario.adjacency)
    vacated = set(promoted.values())
    occupant = {i: i for i in scenario.ids if i not in lost and i not in vacated}
    occupant.update(promoted)
    leader_slots = [s for s in scenario.leaders if s in occupant]
    leaders = {occupant[s] for s in leader_slots}
    edges = {}
    for slot, uh in occupant.items():
        for src, w in _sources(a, slot, occupant, uh).items():
            if (available is None or (uh, src) in available) and (uh not in leaders or src == 0 or src in leaders):
                edges[(uh, src)] = w
    offsets = {occupant[s]: np.asarray(scenario.offsets[s], dtype=float) for s in leader_slots}
    return _checked(lost, leaders, set(occupant.values()) - leaders, offsets, edges, promoted)


def _checked(lost, leaders, followers, offsets, edges, promoted) -> ReformedTeam:
    """Keep the UHs that meet Assumption 1 in the repaired graph; the others hold (with the reason)."""
    ids = sorted(leaders | followers)
    size = max(ids, default=0) + 1
    adjacency = np.zeros((size, size))
    for (i, j), w in edges.items():
        adjacency[i, j] = w
    holding = {}
    reached = reachable_from(adjacency, (0,), allowed=leaders)
    for i in sorted(leaders - reached):
        holding[i] = 'no path from the virtual leader through leaders'
    flying_leaders = leaders & reached
    reached = reachable_from(adjacency, flying_leaders, allowed=followers)
    for k in sorted(followers - reached):
        holding[k] = 'no path from a flying leader' if flying_leaders else 'no leader left with a path'
    lead = tuple(sorted(flying_leaders))
    follow = tuple(sorted(followers & reached))
    flying = set(lead) | set(follow)
    kept = {(i, j): w for (i, j), w in edges.items() if i in flying and (j == 0 or j in flying)}
    weights = np.zeros((len(follow), len(lead)))
    if follow and lead:
        sub = np.zeros((size, size))
        for (i, j), w in kept.items():
            sub[i, j] = w
        l1, l2 = laplacian_blocks(sub, lead, follow)
        weights = containment_weights(l1, l2)
    return ReformedTeam(lost=lost, leaders=lead, followers=follow, offsets={i: offsets[i] for i in lead},
                        edges=kept, promoted=dict(sorted(promoted.items())), holding=holding,
                        containment_weights=weights)


def held_team(scenario, lost) -> ReformedTeam:
    """Give the team a hold is scored against: the scenario's without the UHs ``lost``, nothing repaired.

    Every surviving leader keeps its slot (one that holds included: its error is its distance from the
    slot); a surviving follower is scored against the containment of the declared edges among the
    survivors, which is what it flies (none when it has no path from a leader).
    """
    lost = frozenset(int(i) for i in lost)
    leaders = tuple(i for i in scenario.leaders if i not in lost)
    edges = {(i, j): float(scenario.adjacency[i, j]) for (i, j) in declared_edges(scenario)
             if i not in lost and j not in lost}
    size = max(scenario.ids) + 1
    adjacency = np.zeros((size, size))
    for (i, j), w in edges.items():
        adjacency[i, j] = w
    reached = reachable_from(adjacency, leaders, allowed={k for k in scenario.followers if k not in lost})
    followers = tuple(k for k in scenario.followers if k not in lost and k in reached)
    weights = np.zeros((len(followers), len(leaders)))
    if followers and leaders:
        weights = containment_weights(*laplacian_blocks(adjacency, leaders, followers))
    return ReformedTeam(lost=lost, leaders=leaders, followers=followers,
                        offsets={i: np.asarray(scenario.offsets[i], dtype=float) for i in leaders}, edges=edges,
                        containment_weights=weights)


def bypass_standby_edges(scenario) -> tuple:
    """Give the edges ``(i, j)`` the repair of any single loss uses and the scenario does not declare, sorted.

    ``standby_edges: bypass`` (docs/resilience.md#standby-edges): with these every single loss is
    repaired as if any UH could hear any other; their subscriptions exist from the start.
    """
    declared = declared_edges(scenario)
    needed = set()
    for uh in scenario.ids:
        needed |= set(reformed_team(scenario, {uh}).edges)
    return tuple(sorted(needed - declared))
