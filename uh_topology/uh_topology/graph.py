"""Communication-graph maths: adjacency, Laplacian blocks, reachability, containment weights.

docs/graph.md and the paper's Assumption 1 / Lemma 1. Conventions:

* nodes ``0..n``: 0 is the virtual leader, ``1..N`` the leaders, ``N+1..N+M`` the followers;
* ``A`` (n+1, n+1) with ``A[i, j] = a_ij`` = weight with which UH ``i`` hears ``j`` (row = receiver);
  column 0 holds the virtual-leader links ``a_i0``; row 0 is zero (the virtual leader hears nobody);
* the Laplacian is over the UHs 1..n: ``L = D - A[1:, 1:]`` with ``D = diag(row sums of A[1:, 1:])``;
* ``L1 = L[F, F]`` (M, M) follower-follower block, ``L2 = L[F, L]`` (M, N) follower-leader block;
  the followers' positions converge to ``-L1^-1 L2 P_L`` (convex weights, rows sum to 1);
* the leaders' tracking matrix is ``L[L, L] + diag(a_i0)`` (N, N).

Pure numpy; errors are the topology errors of :mod:`uh_topology.errors`.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from .errors import LaplacianConditionError, UnreachableFollowerError, UnreachableLeaderError

__all__ = [
    'laplacian', 'laplacian_blocks', 'leader_tracking_matrix', 'containment_weights',
    'reachable_from', 'containment_pattern', 'unreachable_leaders', 'unreachable_followers',
    'check_assumption1', 'check_lemma1',
    'ROW_SUM_TOL', 'POSITIVE_TOL',
]

#: Tolerance on the row sums of -L1^-1 L2 (they equal 1 exactly in exact arithmetic; the solve
#: of an M x M system with unit-order weights loses at most a few ulps times the condition number).
ROW_SUM_TOL = 1e-9
#: Entries of -L1^-1 L2 below this count as zero (same reasoning as ROW_SUM_TOL).
POSITIVE_TOL = 1e-12


def laplacian(adjacency) -> np.ndarray:
    """Laplacian ``L = D - A`` (n, n) over the UHs 1..n of an (n+1, n+1) adjacency matrix.

    The virtual-leader column is not part of ``L`` (see :func:`leader_tracking_matrix`).
    """
    a = np.asarray(adjacency, dtype=float)[1:, 1:]
    return np.diag(a.sum(axis=1)) - a


def laplacian_blocks(adjacency, leaders, followers) -> tuple:
    """``(L1 (M, M), L2 (M, N))``: follower-follower and follower-leader blocks of :func:`laplacian`.

    ``leaders`` and ``followers`` are sequences of UH ids (1-based); rows/columns follow their order.
    """
    lap = laplacian(adjacency)
    fi = [f - 1 for f in followers]
    li = [j - 1 for j in leaders]
    return lap[np.ix_(fi, fi)], lap[np.ix_(fi, li)]


def leader_tracking_matrix(adjacency, leaders) -> np.ndarray:
    """``L[L, L] + diag(a_i0)`` (N, N): the leaders' consensus-tracking matrix.

    Nonsingular under Assumption 1 when leaders hear only leaders and the virtual leader.
    """
    a = np.asarray(adjacency, dtype=float)
    li = [j - 1 for j in leaders]
    lap = laplacian(a)[np.ix_(li, li)]
    return lap + np.diag(a[list(leaders), 0])


def containment_weights(l1, l2) -> np.ndarray:
    """``-L1^-1 L2`` (M, N): follower k's target is ``sum_j W[k, j] p_j`` (docs/graph.md)."""
    l1 = np.asarray(l1, dtype=float)
    l2 = np.asarray(l2, dtype=float)
    if l1.size == 0:
        return np.zeros((0, l2.shape[1] if l2.ndim == 2 else 0))
    return -np.linalg.solve(l1, l2)


def reachable_from(adjacency, sources, allowed=None) -> set:
    """Nodes with a directed path from any of ``sources`` (information flows j -> i when a_ij > 0).

    Parameters
    ----------
    adjacency : array_like (n+1, n+1)
    sources : iterable of int
        Start nodes (included in the result).
    allowed : set of int, optional
        If given, the search only enters these nodes (sources are always included).
    """
    a = np.asarray(adjacency, dtype=float)
    hears = [np.nonzero(a[:, j] > 0.0)[0] for j in range(a.shape[0])]  # who hears j
    seen = set(int(s) for s in sources)
    queue = deque(seen)
    while queue:
        j = queue.popleft()
        for i in hears[j]:
            i = int(i)
            if i not in seen and (allowed is None or i in allowed):
                seen.add(i)
                queue.append(i)
    return seen


def containment_pattern(adjacency, leaders, followers) -> np.ndarray:
    """Boolean (M, N): True where leader j reaches follower k through followers only.

    These are exactly the strictly positive entries of ``-L1^-1 L2`` (``L1^-1`` of a nonsingular
    M-matrix is positive on the pairs joined by a path in the follower graph).
    """
    fset = set(followers)
    out = np.zeros((len(followers), len(leaders)), dtype=bool)
    for col, j in enumerate(leaders):
        reach = reachable_from(adjacency, [j], allowed=fset)
        for row, k in enumerate(followers):
            out[row, col] = k in reach
    return out


def unreachable_leaders(adjacency, leaders) -> list:
    """Leaders with no directed path from the virtual leader (0) through leaders, ascending."""
    reach = reachable_from(adjacency, [0], allowed=set(leaders))
    return sorted(int(j) for j in leaders if j not in reach)


def unreachable_followers(adjacency, leaders, followers) -> list:
    """Followers with no directed path from any leader, ascending."""
    reach = reachable_from(adjacency, list(leaders))
    return sorted(int(k) for k in followers if k not in reach)


def unreachable_leader_message(ids) -> str:
    """Return the error text for leaders ``ids`` without a directed path from the virtual leader (Assumption 1)."""
    return (f'no directed path from the virtual leader (id 0) to leader(s) {list(ids)}; every leader '
            f'must hear the virtual leader directly (reference_links) or through other leaders (edges)')


def unreachable_follower_message(ids) -> str:
    """Return the error text for followers ``ids`` without a directed path from any leader (Assumption 1)."""
    return (f'no directed path from any leader to follower(s) {list(ids)}; every follower must hear a '
            f'leader directly or through other followers (edges)')


def check_assumption1(adjacency, leaders, followers, *, source=None, path=None) -> None:
    """Check Assumption 1.

    Assumption 1: a path from the virtual leader to every leader (through leaders), and from the
    leaders to every follower.

    Raises
    ------
    UnreachableLeaderError, UnreachableFollowerError
        Naming every leader / follower without such a path (``ids`` attribute).
    """
    lost = unreachable_leaders(adjacency, leaders)
    if lost:
        raise UnreachableLeaderError(unreachable_leader_message(lost), ids=lost, source=source, path=path)
    lost = unreachable_followers(adjacency, leaders, followers)
    if lost:
        raise UnreachableFollowerError(unreachable_follower_message(lost), ids=lost, source=source,
                                       path=path)


def check_lemma1(l1, l2, pattern=None, *, source=None, path=None) -> np.ndarray:
    """Check Lemma 1 and return the containment weights ``W``.

    Lemma 1: eigenvalues of L1 with positive real parts; ``W = -L1^-1 L2`` non-negative with rows
    summing to 1 and (if ``pattern`` (M, N) is given) positive exactly where it is True.

    Returns
    -------
    ndarray (M, N)
        ``W``.

    Raises
    ------
    LaplacianConditionError
    """
    l1 = np.asarray(l1, dtype=float)
    l2 = np.asarray(l2, dtype=float)
    if l1.size == 0:
        return containment_weights(l1, l2)
    eig = np.linalg.eigvals(l1)
    if np.any(eig.real <= POSITIVE_TOL):
        raise LaplacianConditionError(
            f'L1 (follower block of the Laplacian) has eigenvalue(s) with non-positive real part '
            f'{np.round(eig[eig.real <= POSITIVE_TOL], 12).tolist()}; Lemma 1 requires all real parts > 0',
            source=source, path=path)
    w = containment_weights(l1, l2)
    if not np.all(np.isfinite(w)):
        raise LaplacianConditionError('-L1^-1 L2 is not finite (L1 is singular to working precision)',
                                      source=source, path=path)
    if np.any(w < -POSITIVE_TOL):
        raise LaplacianConditionError(
            f'-L1^-1 L2 has negative entries {np.round(w, 12).tolist()}; Lemma 1 requires '
            f'non-negative (convex) weights', source=source, path=path)
    sums = w.sum(axis=1)
    if np.any(np.abs(sums - 1.0) > ROW_SUM_TOL):
        raise LaplacianConditionError(
            f'rows of -L1^-1 L2 sum to {np.round(sums, 12).tolist()}; Lemma 1 requires 1 '
            f'(followers must not hear anything but leaders and followers)', source=source, path=path)
    if pattern is not None:
        positive = w > POSITIVE_TOL
        if not np.array_equal(positive, np.asarray(pattern, dtype=bool)):
            raise LaplacianConditionError(
                f'-L1^-1 L2 = {np.round(w, 12).tolist()} is positive at {positive.tolist()} but the '
                f'graph connects {np.asarray(pattern, dtype=bool).tolist()}; Lemma 1 requires positive '
                f'entries exactly where a leader reaches a follower', source=source, path=path)
    return w
