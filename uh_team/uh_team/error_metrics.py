"""Formation, containment and consensus errors of a run, from its positions (docs/metrics.md).

Positions are in the inertial z-up frame, m; the first axis of every array is the sample.
"""
from __future__ import annotations

import numpy as np

__all__ = ['formation_errors', 'containment_errors', 'consensus_errors']


def formation_errors(positions, reference_positions, offsets) -> np.ndarray:
    """``|p_i - h_i - p_0|`` (K, N) of the leaders, m.

    ``positions`` (K, N, 3) of the leaders in order, ``reference_positions`` (K, 3), ``offsets``
    (N, 3) in the same leader order.
    """
    dev = np.asarray(positions) - np.asarray(offsets)[None, :, :] - np.asarray(reference_positions)[:, None, :]
    return np.linalg.norm(dev, axis=-1)


def containment_errors(follower_positions, leader_positions, weights) -> np.ndarray:
    """``|p_k - sum_j w_kj p_j|`` (K, M), m; ``weights`` (M, N) = ``-L1^-1 L2``."""
    target = np.einsum('mn,knc->kmc', np.asarray(weights), np.asarray(leader_positions))
    return np.linalg.norm(np.asarray(follower_positions) - target, axis=-1)


def consensus_errors(positions, reference_positions, scenario) -> np.ndarray:
    """Consensus errors z1 (K, n, 3) of docs/graph.md from positions (K, n, 3) in ``scenario.ids`` order.

    ``z1_i = sum_j a_ij [(p_i - h_i) - (p_j - h_j)] + a_i0 [(p_i - h_i) - p_0]`` with the formation
    offsets ``h`` for a leader's errors and ``h = 0`` for a follower's: the same quantity the
    controllers compute from their neighbours' data, recomputed here from the recorded positions so
    that the CPI has one definition whatever produced the arrays.
    """
    positions = np.asarray(positions, dtype=float)
    p0 = np.asarray(reference_positions, dtype=float)
    ids = tuple(scenario.ids)
    leaders = set(scenario.leaders)
    col = {i: c for c, i in enumerate(ids)}
    out = np.zeros(positions.shape)
    for i in ids:
        h = (lambda j: np.asarray(scenario.offsets[j], dtype=float)) if i in leaders else (lambda j: 0.0)
        rel = positions[:, col[i]] - h(i)
        for j in scenario.neighbours(i):
            out[:, col[i]] += scenario.weight(i, j) * (rel - (positions[:, col[j]] - h(j)))
        a0 = scenario.leader_link(i)
        if a0 > 0.0:
            out[:, col[i]] += a0 * (rel - p0)
    return out
