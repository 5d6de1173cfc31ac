"""Transition patterns: the candidate triangulations per split code and the choice among
them (largest minimum angle), in the canonical stencil of :mod:`qdrefine.stencil`.

A triangle of the closure whose longest edge ``MN`` is split, and maybe one more edge, is
replaced by a *transition pattern*: a triangulation of the polygon of its corners and the
points of its split edges. For seven-triangle schemes the candidates also include the
triangulations that add the triangle's centroid ``X`` (:func:`qdrefine.stencil.with_centroid`):
on a near-equilateral triangle with one split edge they keep half of its minimum angle
where the three-triangle fan keeps a third. Every candidate is a list of three-letter
triangle names, counter-clockwise in the canonical frame; the validity of a candidate (no
flat or clockwise triangle) is decided once, exactly, on barycentric coordinates, which
are affine invariants, so it holds for every triangle.
"""

from __future__ import annotations

from fractions import Fraction
from functools import cache
from itertools import combinations, product

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ..jit import threads_for
from ..stencil import CENTROID, FIXED_7T, FOUR, SEVEN, Stencil, with_centroid
from .labels import MN, NO, OM

#: Split codes with a transition pattern (neither unsplit nor fully split).
PARTIAL = (MN, MN | NO, MN | OM)


def pattern_stencil(k: int) -> Stencil:
    """The points transition patterns may use: the scheme's stencil, plus the centroid for
    seven-triangle schemes (``k = 2``); four-triangle schemes keep longest-edge bisection."""
    return with_centroid(SEVEN) if k == 2 else FOUR


def _polygon(stencil: Stencil, code: int) -> tuple[str, ...]:
    """Boundary of the triangle with the points of its split edges, counter-clockwise."""
    k, n = stencil.per_edge, stencil.names
    poly: list[str] = []
    for e, bit in enumerate((MN, NO, OM)):
        poly.append(n[e])
        if code & bit:
            poly.extend(n[3 + k * e: 3 + k * (e + 1)])
    return tuple(poly)


def _ccw(stencil: Stencil, tri: str) -> bool:
    """Whether ``tri`` is counter-clockwise with positive area (exact, barycentric)."""
    (a1, a2), (b1, b2), (c1, c2) = (stencil.coefficients(ch) for ch in tri)
    return (b1 - a1) * (c2 - a2) - (b2 - a2) * (c1 - a1) > Fraction(0)


def _polygon_triangulations(poly: tuple[str, ...]) -> list[list[str]]:
    """All triangulations of a convex polygon (counter-clockwise names)."""
    if len(poly) < 3:
        return [[]]
    if len(poly) == 3:
        return [["".join(poly)]]
    a, b = poly[0], poly[-1]
    out = []
    for i in range(1, len(poly) - 1):
        for left in _polygon_triangulations(poly[: i + 1]):
            for right in _polygon_triangulations(poly[i:]):
                out.append(left + [a + poly[i] + b] + right)
    return out


def _valid(stencil: Stencil, tris: list[str]) -> bool:
    return all(_ccw(stencil, t) for t in tris)


def _with_centroid(stencil: Stencil, poly: tuple[str, ...]) -> list[list[str]]:
    """Triangulations of ``poly`` plus the interior point :data:`CENTROID`: the centroid is
    joined to a cyclic subset of the polygon's points, and the pockets between two
    consecutive neighbours are triangulated without it."""
    n, out = len(poly), []
    for r in range(3, n + 1):
        for nbrs in combinations(range(n), r):
            fan = [poly[nbrs[i]] + poly[nbrs[(i + 1) % r]] + CENTROID for i in range(r)]
            if not _valid(stencil, fan):
                continue
            pockets = []
            for i in range(r):
                a, b = nbrs[i], nbrs[(i + 1) % r]
                pocket = tuple(poly[(a + j) % n] for j in range((b - a) % n + 1))
                if len(pocket) >= 3:
                    pockets.append([t for t in _polygon_triangulations(pocket)
                                    if _valid(stencil, t)])
            for parts in product(*pockets):
                out.append(fan + [t for part in parts for t in part])
    return out


def _candidates(k: int, code: int) -> list[tuple[str, ...]]:
    """Valid triangulations for a split code: without the centroid first (the ones sharing
    most corner triangles with the full seven-triangle partition first), then with it
    (fewest triangles first); exact ties of the minimum angle pick the first. Four-triangle
    schemes have one candidate, longest-edge bisection."""
    stencil = pattern_stencil(k)
    poly = _polygon(stencil, code)
    fixed = {frozenset(t) for t in FIXED_7T}
    plain = [t for t in _polygon_triangulations(poly) if _valid(stencil, t)]
    if k == 1:  # longest-edge bisection (Rivara): every child has the midpoint of MN
        plain = [c for c in plain if all(stencil.names[3] in t for t in c)]
    plain.sort(key=lambda c: -sum(frozenset(t) in fixed for t in c))
    centred = _with_centroid(stencil, poly) if CENTROID in stencil.names else []
    centred.sort(key=len)
    return [tuple(c) for c in plain + centred]


#: Transition patterns by points per edge and split code (bits MN=1, NO=2, OM=4): the
#: candidate triangulations (three-letter names over :func:`pattern_stencil`,
#: counter-clockwise in the canonical frame); the one with the largest minimum angle is
#: used, the first on ties.
TRANSITIONS: dict[int, dict[int, list[tuple[str, ...]]]] = {
    k: {code: _candidates(k, code) for code in PARTIAL} for k in (2, 1)
}


@cache
def tables(k: int, code: int) -> tuple[NDArray[np.int8], NDArray[np.int64], NDArray[np.int64]]:
    """``(tris (U, 3), cand (C, T) int, count (C,))``: the distinct triangles of the
    candidates as local indices of :func:`pattern_stencil`, each candidate's triangles as
    indices into ``tris`` padded with ``U`` to the longest candidate, and their counts."""
    names = pattern_stencil(k).names
    cands = TRANSITIONS[k][code]
    uniq = sorted({t for c in cands for t in c})
    tris = np.array([[names.index(ch) for ch in t] for t in uniq], dtype=np.int8)
    width = max(len(c) for c in cands)
    cand = np.full((len(cands), width), len(uniq), dtype=np.int64)
    for i, c in enumerate(cands):
        cand[i, : len(c)] = [uniq.index(t) for t in c]
    return tris, cand, np.array([len(c) for c in cands], dtype=np.int64)


def canonical_corners(points: NDArray[np.float64], rows: NDArray[np.int64],
                      labels: NDArray[np.int8]) -> NDArray[np.float64]:
    """Coordinates ``(G, 3, 2)`` of the canonical vertices ``M, N, O`` of ``rows (G, 3)``."""
    out = np.empty((rows.shape[0], 3, 2))
    with threads_for(rows.shape[0]):
        _corners(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(rows),
                 np.ascontiguousarray(labels), out)
    return out


@njit(parallel=True, cache=True)
def _corners(points, rows, labels, out):
    for g in prange(rows.shape[0]):
        for e in range(3):
            v = rows[g, labels[g, e]]
            out[g, e, 0] = points[v, 0]
            out[g, e, 1] = points[v, 1]


def stencil_coordinates(corners: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    """Coordinates ``(G, S, 2)`` of :func:`pattern_stencil` on triangles whose canonical
    vertices ``M, N, O`` are ``corners (G, 3, 2)``: ``(w_M M + w_N N + w_O O) / d`` with the
    integer weights over their common denominator ``d``, the formula of the edge points
    (``(2 M + N) / 3``, ...), so these are the stored points bit for bit; the centroid is
    ``(M + N + O) / 3``. A function of the three vertices alone (the same whatever the
    input order)."""
    weights = pattern_stencil(k).weights
    den = np.lcm.reduce([c.denominator for row in weights for c in row])
    w = np.array([[int(c * den) for c in row] for row in weights], dtype=np.float64)
    corners = np.ascontiguousarray(corners, dtype=np.float64)
    out = np.empty((corners.shape[0], w.shape[0], 2))
    with threads_for(corners.shape[0]):
        _weighted(w, corners, float(den), out)
    return out


@njit(parallel=True, cache=True)
def _weighted(w, corners, den, out):
    # ((w_M M + w_N N) + w_O O) / d, multiplications and additions rounded one by one (no
    # fused multiply-add), as the edge points are computed
    for g in prange(corners.shape[0]):
        for s in range(w.shape[0]):
            for d in range(2):
                out[g, s, d] = (w[s, 0] * corners[g, 0, d] + w[s, 1] * corners[g, 1, d]
                                + w[s, 2] * corners[g, 2, d]) / den


def min_angles(tri: NDArray[np.float64]) -> NDArray[np.float64]:
    """Smallest angle (degrees) of triangles ``(..., 3, 2)``; 0 for degenerate ones."""
    flat = np.ascontiguousarray(tri, dtype=np.float64).reshape(-1, 3, 2)
    out = np.empty(flat.shape[0])
    _min_angles(flat, out)
    return out.reshape(tri.shape[:-2])


@njit(cache=True, inline="always")
def _corner_min(ax, ay, bx, by, cx, cy):
    """Smallest angle (degrees) of the triangle ``a, b, c``."""
    best = 180.0
    for i in range(3):
        if i == 0:
            px, py, qx, qy, rx, ry = ax, ay, bx, by, cx, cy
        elif i == 1:
            px, py, qx, qy, rx, ry = bx, by, cx, cy, ax, ay
        else:
            px, py, qx, qy, rx, ry = cx, cy, ax, ay, bx, by
        ex, ey = qx - px, qy - py
        fx, fy = rx - px, ry - py
        a = np.degrees(np.arctan2(abs(ex * fy - ey * fx), ex * fx + ey * fy))
        best = min(best, a)
    return best


@njit(cache=True)
def _min_angles(tri, out):
    for g in range(tri.shape[0]):
        out[g] = _corner_min(tri[g, 0, 0], tri[g, 0, 1], tri[g, 1, 0], tri[g, 1, 1],
                             tri[g, 2, 0], tri[g, 2, 1])


@njit(cache=True, inline="always")
def _tan_min(ax, ay, bx, by, cx, cy):
    """``tan`` of the smallest angle of the triangle ``a, b, c`` (at the vertex opposite its
    shortest edge, where the angle is at most 60 degrees, so ``tan`` is increasing); 0 for
    a degenerate triangle."""
    la = (bx - cx) ** 2 + (by - cy) ** 2  # opposite a
    lb = (cx - ax) ** 2 + (cy - ay) ** 2
    lc = (ax - bx) ** 2 + (ay - by) ** 2
    if la <= lb and la <= lc:
        px, py, qx, qy, rx, ry = ax, ay, bx, by, cx, cy
    elif lb <= lc:
        px, py, qx, qy, rx, ry = bx, by, cx, cy, ax, ay
    else:
        px, py, qx, qy, rx, ry = cx, cy, ax, ay, bx, by
    ex, ey = qx - px, qy - py
    fx, fy = rx - px, ry - py
    dot = ex * fx + ey * fy
    if dot <= 0.0:
        return 0.0
    return abs(ex * fy - ey * fx) / dot


#: Triangles per work item of :func:`_choose` (one scratch array each).
CHOOSE_CHUNK = 256


@njit(parallel=True, cache=True)
def _choose(coords, tris, cand, choice, score):
    n_u = tris.shape[0]
    n = coords.shape[0]
    for chunk in prange((n + CHOOSE_CHUNK - 1) // CHOOSE_CHUNK):
        ang = np.empty(n_u + 1)
        ang[n_u] = np.inf
        for g in range(chunk * CHOOSE_CHUNK, min(n, (chunk + 1) * CHOOSE_CHUNK)):
            for u in range(n_u):
                a, b, c = tris[u, 0], tris[u, 1], tris[u, 2]
                ang[u] = _tan_min(coords[g, a, 0], coords[g, a, 1], coords[g, b, 0],
                                  coords[g, b, 1], coords[g, c, 0], coords[g, c, 1])
            best, at = -1.0, 0
            for c in range(cand.shape[0]):
                s = np.inf
                for t in range(cand.shape[1]):
                    s = min(s, ang[cand[c, t]])
                if s > best:  # the first candidate on ties
                    best, at = s, c
            choice[g] = at
            score[g] = np.degrees(np.arctan(best))


def choose(coords: NDArray[np.float64], k: int, code: int
           ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Candidate index and its minimum angle (degrees) per triangle, from the stencil
    coordinates ``(G, S, 2)`` of :func:`stencil_coordinates`."""
    tris, cand, _ = tables(k, code)
    g = coords.shape[0]
    choice = np.empty(g, dtype=np.int64)
    score = np.empty(g)
    if g:
        with threads_for(g * tris.shape[0] // 16):
            _choose(np.ascontiguousarray(coords, dtype=np.float64), tris.astype(np.int64),
                    cand, choice, score)
    return choice, score


def quality(coords: NDArray[np.float64], k: int, code: int) -> NDArray[np.float64]:
    """Minimum angle (degrees) of the best transition of each triangle for ``code``."""
    return choose(coords, k, code)[1]


def uses_centroid(k: int, code: int, choice: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Whether each chosen candidate uses the centroid (a new point)."""
    if k != 2:
        return np.zeros(choice.shape, dtype=bool)
    tris, cand, _ = tables(k, code)
    centred = np.append((tris == 3 + 3 * k).any(axis=1), False)
    return centred[cand].any(axis=1)[choice]


def stencil_ids(t: NDArray, labels: NDArray[np.int8], ce: NDArray[np.int64],
                ep: NDArray[np.int64], k: int) -> NDArray[np.int64]:
    """Global point ids ``(G, 3 + 3k)`` of the local stencil (``-1`` on unsplit edges),
    from the edge points ``ep (E, k)`` listed from the lower id."""
    ids = np.empty((t.shape[0], 3 + 3 * k), dtype=np.int64)
    with threads_for(t.shape[0]):
        _stencil_ids(np.ascontiguousarray(t), np.ascontiguousarray(labels),
                     np.ascontiguousarray(ce), np.ascontiguousarray(ep, dtype=np.int64), k,
                     ids)
    return ids


@njit(parallel=True, cache=True)
def _stencil_ids(t, labels, ce, ep, k, ids):
    """:func:`stencil_ids` into ``ids``: the canonical corners, then each canonical edge's
    points relisted from its first corner."""
    for g in prange(t.shape[0]):
        for e in range(3):
            ids[g, e] = t[g, labels[g, e]]
        for e in range(3):
            a, b, row = ids[g, e], ids[g, (e + 1) % 3], ce[g, e]
            for i in range(k):
                ids[g, 3 + k * e + i] = ep[row, i] if a < b else ep[row, k - 1 - i]


def pattern(ids: NDArray[np.int64], labels: NDArray[np.int8], k: int, code: int,
            choice: NDArray[np.int64], out: NDArray | None = None,
            rows: NDArray[np.int64] | None = None) -> NDArray:
    """Children of triangles with split code ``code`` (not 0 or full) in the chosen
    candidates; ``ids (G, S)`` are the global ids of :func:`pattern_stencil` (the
    centroid's where it is used). Written to ``out[rows[g]:rows[g] + count]`` for
    triangle ``g``, where given; else returned as ``(sum count, 3)`` int64 (the
    children of each triangle in turn)."""
    tris, cand, count = tables(k, code)
    local = np.concatenate([tris, np.zeros((1, 3), np.int8)])[cand].astype(np.int64)
    flip = (labels[:, 1].astype(np.int64) - labels[:, 0]) % 3 != 1
    if out is None:
        n = count[choice]
        rows = np.cumsum(n) - n
        out = np.empty((int(n.sum()), 3), dtype=np.int64)
    _place(out, np.ascontiguousarray(rows, dtype=np.int64),
           np.ascontiguousarray(ids, dtype=np.int64), local, count,
           np.ascontiguousarray(choice, dtype=np.int64), flip)
    return out


@njit(cache=True)
def _place(out, rows, ids, local, count, choice, flip):
    """:func:`pattern`'s children of triangle ``g``, candidate ``choice[g]`` of ``local
    (C, T, 3)`` (stencil indices), to ``out[rows[g]:]``; a mirrored triangle (``flip``:
    labels clockwise) lists its children's last two vertices swapped."""
    for g in range(ids.shape[0]):
        c, r = choice[g], rows[g]
        for t in range(count[c]):
            a, b, d = local[c, t, 0], local[c, t, 1], local[c, t, 2]
            if flip[g]:
                b, d = d, b
            out[r + t, 0] = ids[g, a]
            out[r + t, 1] = ids[g, b]
            out[r + t, 2] = ids[g, d]
