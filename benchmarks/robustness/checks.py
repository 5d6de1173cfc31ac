"""Exact validity checks of triangle sets on small point sets (the nine points).

A set of triangles over points ``(K, P, 2)`` is checked against a *boundary*: the directed
counter-clockwise edges ``(K, P, P)`` it must tile, either the exact convex hull of the
points (:func:`hull_boundary`, for a Delaunay triangulation of the points) or the nine-point
polygon of the partitioned triangle (:func:`cycle_boundary`). With every triangle strictly
counter-clockwise, no directed edge used twice, and ``C - C^T`` equal to the boundary's
``B - B^T`` (``C`` counts directed triangle edges), the triangles cover the bounded region
exactly once, with no overlap, gap or T-junction (the chain's boundary is the region's).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .exact import incircle_sign, orient_sign

CHUNK = 2000


def _gather(points: NDArray, idx: NDArray) -> NDArray:
    """``points (K, P, 2)`` at local indices ``idx (K, ...)`` -> ``(K, ..., 2)``."""
    rows = np.arange(len(points)).reshape((-1,) + (1,) * (idx.ndim - 1))
    return points[rows, idx]


def lex_rank(points: NDArray) -> NDArray[np.int64]:
    """Rank ``(K, P)`` of each point in lexicographic (x, then y) order within its row."""
    order = np.lexsort((points[..., 1], points[..., 0]), axis=-1)
    return np.argsort(order, axis=-1)


def distinct(points: NDArray) -> NDArray[np.bool_]:
    """Whether the ``P`` points of each row ``(K, P, 2)`` are pairwise different."""
    order = np.lexsort((points[..., 1], points[..., 0]), axis=-1)
    s = np.take_along_axis(points, order[..., None], axis=1)
    return ~(s[:, 1:] == s[:, :-1]).all(axis=2).any(axis=1)


def hull_boundary(points: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Directed edges ``(K, P, P)`` of the exact convex hull, counter-clockwise, with
    collinear boundary points as vertices (so an edge joins consecutive boundary points).
    Rows must hold distinct points."""
    out = [_hull_chunk(points[s:s + CHUNK]) for s in range(0, len(points), CHUNK)]
    return np.concatenate(out) if out else np.zeros((0,) + points.shape[1:2] * 2, bool)


def _hull_chunk(points: NDArray) -> NDArray[np.bool_]:
    k, p = points.shape[:2]
    ii, jj = np.triu_indices(p, 1)
    kk = np.arange(p)
    s = orient_sign(points[:, ii, None], points[:, jj, None], points[:, None, kk])  # (K,Q,P)
    other = (kk[None, :] != ii[:, None]) & (kk[None, :] != jj[:, None])
    rank = lex_rank(points)
    ri, rj, rk = rank[:, ii, None], rank[:, jj, None], rank[:, None, kk]
    between = (s == 0) & other & (np.minimum(ri, rj) < rk) & (rk < np.maximum(ri, rj))
    left = ((s >= 0) | ~other).all(axis=2) & ((s > 0) & other).any(axis=2)
    right = ((s <= 0) | ~other).all(axis=2) & ((s < 0) & other).any(axis=2)
    ok = ~between.any(axis=2)
    out = np.zeros((k, p, p), dtype=bool)
    out[:, ii, jj] = left & ok
    out[:, jj, ii] = right & ok
    return out


def cycle_boundary(cycles: NDArray[np.int64], p: int) -> NDArray[np.bool_]:
    """Directed edges ``(K, P, P)`` of the closed cycles ``(K, L)`` of local indices."""
    k = len(cycles)
    out = np.zeros((k, p, p), dtype=bool)
    rows = np.arange(k)[:, None]
    out[rows, cycles, np.roll(cycles, -1, axis=1)] = True
    return out


def pad(triangle_lists: list[NDArray], width: int | None = None) -> NDArray[np.int64]:
    """Triangle lists of varying length as one ``(K, T, 3)`` array padded with -1."""
    width = width or max((len(t) for t in triangle_lists), default=0)
    out = np.full((len(triangle_lists), max(width, 1), 3), -1, dtype=np.int64)
    for i, t in enumerate(triangle_lists):
        if len(t):
            out[i, :len(t)] = t
    return out


def triangulation_flags(points: NDArray[np.float64], tris: NDArray[np.int64],
                        boundaries: dict[str, NDArray[np.bool_]], delaunay: bool = True
                        ) -> dict[str, NDArray]:
    """Exact checks of triangles ``(K, T, 3)`` (rows padded with -1) over ``points
    (K, P, 2)`` against each of ``boundaries`` (name -> ``(K, P, P)``).

    Returns ``(K,)`` arrays: ``n_triangles``; ``missing`` (a point used by no triangle),
    ``zero_area``, ``inverted`` (clockwise), ``not_tiling <name>`` per boundary (see the
    module docstring; also set by a zero-area or clockwise triangle) and, if ``delaunay``,
    ``not_delaunay`` (a point strictly inside the circumcircle of a non-degenerate triangle).
    """
    parts = [_flags_chunk(points[s:s + CHUNK], tris[s:s + CHUNK],
                          {k: b[s:s + CHUNK] for k, b in boundaries.items()}, delaunay)
             for s in range(0, len(points), CHUNK)]
    return {key: np.concatenate([q[key] for q in parts]) for key in parts[0]}


def _flags_chunk(points, tris, boundaries, delaunay):
    k, p = points.shape[:2]
    valid = tris[..., 0] >= 0
    t = np.where(valid[..., None], tris, 0)
    a, b, c = (_gather(points, t[..., i]) for i in range(3))
    s = np.where(valid, orient_sign(a, b, c), 1)
    zero = ((s == 0) & valid).any(axis=1)
    inverted = ((s < 0) & valid).any(axis=1)
    used = np.zeros((k, p), dtype=bool)
    rows = np.arange(k)[:, None]
    owner = np.broadcast_to(rows, valid.shape)[valid]
    for i in range(3):
        used[owner, t[..., i][valid]] = True
    count = np.zeros((k, p, p), dtype=np.int64)
    for i in range(3):
        src, dst = t[..., i], t[..., (i + 1) % 3]
        np.add.at(count, (owner, src[valid], dst[valid]), 1)
    chain = count - count.transpose(0, 2, 1)
    out = {"n_triangles": valid.sum(axis=1), "missing": ~used.all(axis=1), "zero_area": zero,
           "inverted": inverted}
    for name, boundary in boundaries.items():
        bnd = boundary.astype(np.int64) - boundary.transpose(0, 2, 1).astype(np.int64)
        out[f"not_tiling {name}"] = ((count > 1).any(axis=(1, 2))
                                     | (chain != bnd).any(axis=(1, 2)) | zero | inverted)
    if delaunay:
        kk = np.arange(p)
        ins = incircle_sign(a[:, :, None], b[:, :, None], c[:, :, None], points[:, None, :])
        own = (kk == t[..., 0:1]) | (kk == t[..., 1:2]) | (kk == t[..., 2:3])
        test = valid[..., None] & (s != 0)[..., None] & ~own
        out["not_delaunay"] = ((ins * s[..., None] > 0) & test).any(axis=(1, 2))
    return out
