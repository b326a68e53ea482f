"""How close the UHs of a run came to each other (docs/metrics.md#separation, docs/safety.md).

Hub-to-hub distances, 3-D, of every pair at every sample: the smallest, the pair it belongs to and
when, and how long any pair spent under a limit (the scenario's minimum separation, or two rotor
radii: rotor disks overlapping). A sample at which a UH's state is missing (NaN: a real-time run
did not record it, or the UH's simulator had died) leaves that UH's pairs out of that sample.
"""
from __future__ import annotations

import numpy as np

from uh_core.airframe import HelicopterParamsError, load_helicopter_params

__all__ = ['pair_distances', 'closest_approach', 'time_below', 'separation_limits', 'closest_pair_series']


def pair_distances(positions: np.ndarray) -> tuple:
    """Distances of every pair: ``(d (K+1, P), pairs [(a, b)])`` for ``positions`` (K+1, n, 3), m.

    ``pairs`` index the UH axis of ``positions`` (a < b), in ``itertools.combinations`` order.
    """
    n = positions.shape[1]
    first, second = np.triu_indices(n, k=1)
    distances = np.linalg.norm(positions[:, first] - positions[:, second], axis=2)
    return distances, list(zip(first.tolist(), second.tolist(), strict=True))


def _known(distances: np.ndarray) -> np.ndarray:
    """``distances`` with the pairs of missing samples (NaN) as ``inf``: never the closest."""
    return np.where(np.isnan(distances), np.inf, distances)


def closest_pair_series(positions: np.ndarray) -> np.ndarray:
    """Return the smallest pair distance at each sample (K+1,), m.

    ``inf`` with fewer than two UHs, NaN at a sample where no pair is known.
    """
    distances, _ = pair_distances(positions)
    if not distances.shape[1]:
        return np.full(positions.shape[0], np.inf)
    closest = _known(distances).min(axis=1)
    closest[np.isnan(distances).all(axis=1)] = np.nan
    return closest


def closest_approach(time: np.ndarray, positions: np.ndarray, ids: tuple) -> dict:
    """``{'distance_m', 'pair', 'time_s'}`` of the closest approach of any two UHs over the run.

    ``pair`` is ``'UH4-UH5'`` (ids of the pair, ascending); all None with fewer than two UHs or no
    sample of any pair.
    """
    distances, pairs = pair_distances(positions)
    known = _known(distances)
    if not pairs or not np.isfinite(known).any():
        return {'distance_m': None, 'pair': None, 'time_s': None}
    sample, pair = np.unravel_index(int(np.argmin(known)), distances.shape)
    a, b = sorted((ids[pairs[pair][0]], ids[pairs[pair][1]]))
    return {'distance_m': float(distances[sample, pair]), 'pair': f'UH{a}-UH{b}', 'time_s': float(time[sample])}


def time_below(time: np.ndarray, positions: np.ndarray, limit: float | None) -> float | None:
    """Seconds during which some pair is closer than ``limit`` m (None when there is no limit).

    Each sample stands for one control period (the samples of the after-settle metrics).
    """
    if limit is None:
        return None
    below = closest_pair_series(positions) < limit
    dt = float(time[1] - time[0]) if time.shape[0] > 1 else 0.0
    return float(np.count_nonzero(below[:-1]) * dt) if below.shape[0] > 1 else 0.0


def separation_limits(scenario) -> dict:
    """``{'min_separation_m', 'rotor_overlap_m'}``: the scenario's minimum separation and two rotor radii, m.

    None where the airframe file does not load (or there is no scenario).
    """
    if scenario is None:
        return {'min_separation_m': None, 'rotor_overlap_m': None}
    try:
        rotor_radius = load_helicopter_params(scenario.helicopter).rotor_radius
    except HelicopterParamsError:
        return {'min_separation_m': None, 'rotor_overlap_m': None}
    return {'min_separation_m': scenario.safety.separation(rotor_radius), 'rotor_overlap_m': 2.0 * rotor_radius}
