"""Distances to convex hulls in 3-D: the geometry of the containment metric (docs/metrics.md).

Every function takes points and vertices as arrays of shape (..., 3) in one frame (the inertial
z-up frame of the run, m) and broadcasts over the leading axes.
"""
from __future__ import annotations

import itertools

import numpy as np

__all__ = ['dot', 'point_segment_distance', 'point_triangle_distance', 'hull_distance']


def dot(a, b):
    """Row-wise dot product of the last axes of ``a`` and ``b`` (broadcast)."""
    return np.einsum('...i,...i->...', a, b)


def point_segment_distance(p, a, b) -> np.ndarray:
    """Distance from points ``p`` to segments ``[a, b]``; all (..., 3) broadcastable, m.

    A degenerate segment (``a == b``) is the point ``a``.
    """
    p, a, b = (np.asarray(x, dtype=float) for x in (p, a, b))
    ab = b - a
    denom = dot(ab, ab)
    t = np.clip(dot(p - a, ab) / np.where(denom > 0.0, denom, 1.0), 0.0, 1.0)
    t = np.where(denom > 0.0, t, 0.0)
    closest = a + t[..., None] * ab
    return np.linalg.norm(p - closest, axis=-1)


def point_triangle_distance(p, a, b, c) -> np.ndarray:
    """Exact distance from points ``p`` to the filled triangles ``(a, b, c)``; (..., 3) broadcastable.

    If the orthogonal projection of ``p`` on the triangle's plane lies inside the triangle, the
    distance is ``|n . (p - a)| / |n|``; otherwise the closest point is on an edge and the distance
    is the smallest point-segment distance. Degenerate (collinear) triangles reduce to their edges.
    """
    p, a, b, c = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (p, a, b, c)))
    ab, ac, ap = b - a, c - a, p - a
    n = np.cross(ab, ac)
    nn = dot(n, n)
    scale = np.maximum(dot(ab, ab), dot(ac, ac))
    flat = nn <= 1e-24 * np.maximum(scale * scale, 1e-300)   # collinear or coincident vertices
    safe = np.where(flat, 1.0, nn)
    # barycentric coordinates of the projection (Lagrange: d00 d11 - d01^2 = |n|^2)
    d00, d01, d11 = dot(ab, ab), dot(ab, ac), dot(ac, ac)
    d20, d21 = dot(ap, ab), dot(ap, ac)
    v = (d11 * d20 - d01 * d21) / safe
    w = (d00 * d21 - d01 * d20) / safe
    inside = (~flat) & (v >= 0.0) & (w >= 0.0) & (v + w <= 1.0)
    plane = np.abs(dot(n, ap)) / np.sqrt(safe)
    edges = np.minimum(np.minimum(point_segment_distance(p, a, b), point_segment_distance(p, b, c)),
                       point_segment_distance(p, c, a))
    return np.where(inside, plane, edges)


def _tetra_distance(p, v0, v1, v2, v3):
    # 0 inside a non-degenerate tetrahedron, else the nearest face (exact; a flat tetrahedron is
    # the union of its four faces)
    faces = np.minimum(np.minimum(point_triangle_distance(p, v0, v1, v2), point_triangle_distance(p, v0, v1, v3)),
                       np.minimum(point_triangle_distance(p, v0, v2, v3), point_triangle_distance(p, v1, v2, v3)))
    e1, e2, e3 = v1 - v0, v2 - v0, v3 - v0
    vol = dot(np.cross(e1, e2), e3)
    q = p - v0
    safe = np.where(vol != 0.0, vol, 1.0)
    l1 = dot(np.cross(q, e2), e3) / safe
    l2 = dot(np.cross(e1, q), e3) / safe
    l3 = dot(np.cross(e1, e2), q) / safe
    inside = (vol != 0.0) & (l1 >= 0) & (l2 >= 0) & (l3 >= 0) & (l1 + l2 + l3 <= 1.0)
    return np.where(inside, 0.0, faces)


def hull_distance(points, vertices) -> np.ndarray:
    """Distance from ``points`` (..., 3) to the convex hull of ``vertices`` (..., N, 3), m (0 inside).

    Exact for any N >= 1: a point, a segment, a triangle (N = 3, the paper's three leaders), or for
    N >= 4 the smallest distance to any tetrahedron of four vertices (Caratheodory: the hull is the
    union of those tetrahedra).
    """
    points = np.asarray(points, dtype=float)
    vertices = np.asarray(vertices, dtype=float)
    n = vertices.shape[-2]
    vs = [vertices[..., i, :] for i in range(n)]
    if n == 1:
        return np.linalg.norm(points - vs[0], axis=-1)
    if n == 2:
        return point_segment_distance(points, vs[0], vs[1])
    if n == 3:
        return point_triangle_distance(points, vs[0], vs[1], vs[2])
    best = None
    for i, j, k, m in itertools.combinations(range(n), 4):
        d = _tetra_distance(points, vs[i], vs[j], vs[k], vs[m])
        best = d if best is None else np.minimum(best, d)
    return best
