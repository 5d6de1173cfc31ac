"""Compiled array kernels of uniform refinement (numba).

Three passes, each linear in the mesh size, parallel and free of Python loops:

1. Edge numbering (:mod:`qdrefine.numbering`): every undirected edge gets an id, ordered by
   ``(min vertex, max vertex)``, by a parallel two-level counting sort of the half-edges;
   ids never depend on the triangle order or the number of threads.
2. New points (:func:`edge_points` from an edge list, or
   :func:`qdrefine.numbering.bucket_points` straight from the sorted buckets): the ``k``
   new points of every edge, computed once from its two endpoints by a symmetric formula
   (the point nearer ``a`` is ``(2a + b) / 3`` whichever way the edge is walked; midpoints
   ``(a + b) / 2``), so both neighbours share them.
3. :func:`emit`: per triangle, the canonical labelling (exact squared-length comparisons,
   tie rules in :mod:`qdrefine.schemes`), the signs of the scheme's forms, a table row, and
   the children written to ``out[t * T: (t + 1) * T]``; children whose canonical frame is a
   reflection of the input are flipped so that the output stays counter-clockwise. Signs
   go through the stages of :mod:`qdrefine.predicates` (filter, error-free products,
   expansions); each is exact, so the output does not depend on which stage decided. The
   same sweep flags the triangles whose children rounding could spoil
   (:func:`rounding_suspects`).

Input triangles must be counter-clockwise (``Mesh`` guarantees it).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from .jit import AHEAD, CHUNK, prefetch, threads_for, unsigned
from .numbering import EdgeBuckets, edge_point, number_edges
from .predicates import (
    SCRATCH,
    congruent,
    factor_forms,
    form_filter,
    form_sign_slow,
    length_filter,
    length_sign_slow,
)

__all__ = ["number_edges", "edge_points", "emit", "classify", "decide", "canonical",
           "rounding_suspects", "CHUNK"]

# ----------------------------------------------------------------------------------------
# labelling and classification of one triangle
#
# Hot helpers take scalars only: numba increments and decrements the reference count of
# every array argument on entry to a compiled helper (two atomic operations per array and
# call), which cost more than the float filter itself.


@njit(inline="always", cache=True)
def _lex_less(ax, ay, bx, by):
    return ax < bx or (ax == bx and ay < by)


@njit(inline="always", cache=True)
def _cmp(i, j, s01, s02, s12):
    """``sign(e_i - e_j)`` from the three pairwise signs."""
    if i == j:
        return 0
    lo = min(i, j)
    hi = max(i, j)
    s = s01 if (lo == 0 and hi == 1) else (s02 if lo == 0 else s12)
    return s if i < j else -s


@njit(inline="always", cache=True)
def _pick(i, a, b, c):
    """``(a, b, c)[i]`` as selects (a runtime tuple index compiles to a branchy switch)."""
    return a if i == 0 else (b if i == 1 else c)


def _strict_labels() -> np.ndarray:
    """``(27,)``: packed ``iM + 3 iN + 9 iO`` for every sign code of three distinct lengths
    (``N`` is opposite the shortest edge, ``O`` opposite the longest); -1 for codes with a
    tie (or no realizable order). The code is ``(s01+1) + 3 (s02+1) + 9 (s12+1)``."""
    out = np.full(27, -1, dtype=np.int64)
    for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        e = np.empty(3)
        e[list(perm)] = [0.0, 1.0, 2.0]  # e[i]: rank of the edge opposite vertex i
        s01, s02, s12 = (int(np.sign(e[i] - e[j])) for i, j in ((0, 1), (0, 2), (1, 2)))
        code = (s01 + 1) + 3 * (s02 + 1) + 9 * (s12 + 1)
        out[code] = int(np.argsort(e)[1]) + 3 * int(np.argmin(e)) + 9 * int(np.argmax(e))
    return out


def _apex_labels() -> np.ndarray:
    """``(27,)``: for sign codes with one longest edge and the other two tied (an isosceles
    triangle with apex ``O``, e.g. every triangle of a right isosceles grid), the local index
    of ``O``; -1 for every other code."""
    out = np.full(27, -1, dtype=np.int64)
    for o in range(3):
        e = np.zeros(3)
        e[o] = 1.0  # the edge opposite O is the longest, the other two are equal
        s01, s02, s12 = (int(np.sign(e[i] - e[j])) for i, j in ((0, 1), (0, 2), (1, 2)))
        out[(s01 + 1) + 3 * (s02 + 1) + 9 * (s12 + 1)] = o
    return out


_STRICT = _strict_labels()
_APEX = _apex_labels()


@njit(cache=True)
def canonical(x0, y0, x1, y1, x2, y2, buf):
    """Local vertex indices ``(iM, iN, iO)`` of the canonical labelling of one triangle.

    ``MN`` is the longest edge and ``M`` the endpoint nearer ``O`` (ties: see module
    :mod:`qdrefine.schemes`). ``buf`` is not used (kept for callers).
    """
    return _canonical(x0, y0, x1, y1, x2, y2)


@njit(cache=True)
def _canonical(x0, y0, x1, y1, x2, y2):
    """:func:`canonical`. ``e_i``, the squared length of the edge opposite ``v_i``, is
    compared exactly (:func:`qdrefine.predicates.length_sign`); three distinct lengths are
    labelled by a table lookup, ties by the rules of :func:`_tied_labels`."""
    s01 = length_filter(x2 - x1, y2 - y1, x0 - x2, y0 - y2)  # sign(e0 - e1)
    s02 = length_filter(x2 - x1, y2 - y1, x1 - x0, y1 - y0)  # sign(e0 - e2)
    s12 = length_filter(x0 - x2, y0 - y2, x1 - x0, y1 - y0)  # sign(e1 - e2)
    if s01 == 0 and not congruent(x1, y1, x2, y2, x2, y2, x0, y0):
        s01 = length_sign_slow(x1, y1, x2, y2, x2, y2, x0, y0)
    if s02 == 0 and not congruent(x1, y1, x2, y2, x0, y0, x1, y1):
        s02 = length_sign_slow(x1, y1, x2, y2, x0, y0, x1, y1)
    if s12 == 0 and not congruent(x2, y2, x0, y0, x0, y0, x1, y1):
        s12 = length_sign_slow(x2, y2, x0, y0, x0, y0, x1, y1)
    packed = _STRICT[(s01 + 1) + 3 * (s02 + 1) + 9 * (s12 + 1)]
    if packed >= 0:
        return packed % 3, (packed // 3) % 3, packed // 9
    o = _APEX[(s01 + 1) + 3 * (s02 + 1) + 9 * (s12 + 1)]
    if o >= 0:  # |OM| = |ON|: M is the lexicographically smaller endpoint
        j = (o + 1) % 3
        k = (o + 2) % 3
        if _lex_less(_pick(j, x0, x1, x2), _pick(j, y0, y1, y2),
                     _pick(k, x0, x1, x2), _pick(k, y0, y1, y2)):
            return j, k, o
        return k, j, o
    return _tied_labels(x0, y0, x1, y1, x2, y2, s01, s02, s12)


@njit(cache=True)
def _tied_labels(x0, y0, x1, y1, x2, y2, s01, s02, s12):
    """Labelling with ties: of equally long longest edges the one whose opposite vertex is
    lexicographically smaller; of ``|OM| = |ON|`` the smaller endpoint is ``M``."""
    o = -1
    for i in range(3):
        if _cmp(i, (i + 1) % 3, s01, s02, s12) >= 0 and _cmp(i, (i + 2) % 3, s01, s02, s12) >= 0:
            if o < 0 or _lex_less(_pick(i, x0, x1, x2), _pick(i, y0, y1, y2),
                                  _pick(o, x0, x1, x2), _pick(o, y0, y1, y2)):
                o = i
    j = (o + 1) % 3
    k = (o + 2) % 3
    # |O v_j|^2 = e_k and |O v_k|^2 = e_j
    c = _cmp(k, j, s01, s02, s12)
    if c < 0 or (c == 0 and _lex_less(_pick(j, x0, x1, x2), _pick(j, y0, y1, y2),
                                      _pick(k, x0, x1, x2), _pick(k, y0, y1, y2))):
        return j, k, o
    return k, j, o


@njit(cache=True)
def classify(x0, y0, x1, y1, x2, y2, forms, lut, buf):
    """Canonical labelling and table row of one triangle: ``(iM, iN, iO, row)``
    (:func:`decide` with the factors of ``forms`` computed here)."""
    return decide(x0, y0, x1, y1, x2, y2, forms, factor_forms(forms), lut, buf)


@njit(inline="always", cache=True)
def decide(x0, y0, x1, y1, x2, y2, forms, factors, lut, buf):
    """Canonical labelling and table row of one triangle: ``(iM, iN, iO, row)``.

    ``forms (F, 3)`` and ``lut`` are a scheme's, ``factors`` is
    :func:`qdrefine.predicates.factor_forms` of ``forms`` (computed once per mesh) and ``buf``
    a scratch array. The sign of every form is exact (filter, then the slow stages)."""
    im, jn, ko = _canonical(x0, y0, x1, y1, x2, y2)
    mx, my = _pick(im, x0, x1, x2), _pick(im, y0, y1, y2)
    nx, ny = _pick(jn, x0, x1, x2), _pick(jn, y0, y1, y2)
    ox, oy = _pick(ko, x0, x1, x2), _pick(ko, y0, y1, y2)
    code = 0
    power = 1
    for f in range(forms.shape[0]):
        s = form_filter(mx, my, nx, ny, ox, oy, forms[f, 0], forms[f, 1], forms[f, 2])
        if s == 0:
            s = form_sign_slow(mx, my, nx, ny, ox, oy, forms[f, 0], forms[f, 1], forms[f, 2],
                               factors[f, 0], factors[f, 1], factors[f, 2], factors[f, 3],
                               factors[f, 4], buf)
        code += (s + 1) * power
        power *= 3
    return im, jn, ko, lut[code]


# ----------------------------------------------------------------------------------------
# new points and children


def edge_points(points: NDArray[np.float64], edges: NDArray[np.integer], per_edge: int,
                out: NDArray[np.float64]) -> None:
    """Write the old points and ``per_edge`` new points per edge into ``out``.

    ``out`` is ``(N + E * per_edge, 2)``; the points of edge ``g = (a, b)``, ``a < b``, are at
    ``N + g * per_edge + j``, listed from ``a``.
    """
    with threads_for(edges.shape[0]):
        _edge_points(points, edges, per_edge, out)


@njit(parallel=True, cache=True)
def _edge_points(points, edges, per_edge, out):
    n = points.shape[0]
    n_edges = edges.shape[0]
    n_chunks = max((n_edges + CHUNK - 1) // CHUNK, 1)
    for c in prange(n_chunks):  # one parallel region: chunk c copies its share of old points
        for i in range(c * n // n_chunks, (c + 1) * n // n_chunks):
            out[i, 0] = points[i, 0]
            out[i, 1] = points[i, 1]
        for g in range(c * CHUNK, min(n_edges, (c + 1) * CHUNK)):
            prefetch(points, edges[min(g + AHEAD, n_edges - 1), 1])
            a = edges[g, 0]
            b = edges[g, 1]
            for j in range(per_edge):
                for k in range(2):
                    out[n + g * per_edge + j, k] = edge_point(points[a, k], points[b, k], j,
                                                              per_edge)


@njit(cache=True)
def _frame_tables(tables, per_edge):
    """``(9, R, 3 T) uint8``: the children of every table row as indices into a
    triangle's *own* local points, for each labelling ``code = iM * 3 + iN``.

    Own local points: ``v0, v1, v2``, then the ``per_edge`` points of each edge
    ``(v_i, v_{i+1})`` listed from ``v_i``. Children of a labelling whose canonical frame is
    a reflection of the input (``iN != iM + 1 mod 3``) are flipped (counter-clockwise).
    """
    n_rows, n_children, _ = tables.shape
    out = np.zeros((9, n_rows, 3 * n_children), dtype=np.uint8)
    own = np.empty(3 + 3 * per_edge, dtype=np.uint8)  # canonical local -> own local
    for im in range(3):
        for jn in range(3):
            if im == jn:
                continue
            lab = (im, jn, 3 - im - jn)
            for e in range(3):
                own[e] = lab[e]
                a = lab[e]
                b = lab[(e + 1) % 3]
                for j in range(per_edge):
                    if b == (a + 1) % 3:
                        own[3 + per_edge * e + j] = 3 + per_edge * a + j
                    else:
                        own[3 + per_edge * e + j] = 3 + per_edge * b + per_edge - 1 - j
            flip = (jn - im) % 3 != 1
            for r in range(n_rows):
                for c in range(n_children):
                    out[im * 3 + jn, r, 3 * c] = own[tables[r, c, 0]]
                    out[im * 3 + jn, r, 3 * c + 1] = own[tables[r, c, 2 if flip else 1]]
                    out[im * 3 + jn, r, 3 * c + 2] = own[tables[r, c, 1 if flip else 2]]
    return out


def emit(points: NDArray[np.float64], triangles: NDArray[np.integer],
         tri_edges: NDArray[np.integer], per_edge: int, forms: NDArray[np.float64],
         lut: NDArray[np.int8], tables: NDArray[np.int8], out: NDArray[np.integer],
         buckets: EdgeBuckets | None = None) -> NDArray[np.bool_]:
    """Children of every triangle into ``out (M * T, 3)``; see the module docstring.

    ``tri_edges (M, 3)`` numbers edge ``(v_i, v_{i+1})`` of each triangle; its points are
    ``N + tri_edges * per_edge + j`` (from the smaller vertex). ``forms (F, 3)``, ``lut``
    and ``tables (R, T, 3)`` are a :class:`qdrefine.schemes.Scheme`'s. With ``buckets``,
    ``tri_edges`` is ``buckets.local`` and the global ids are completed on the fly
    (:mod:`qdrefine.numbering`).

    Returns :func:`rounding_suspects` ``(M,) bool`` for lattice ``per_edge + 1``, computed in
    the same sweep (the corners are loaded anyway).
    """
    if not out.flags.c_contiguous:
        raise ValueError("emit: out must be C-contiguous")
    if lut.size and lut.min() < 0:
        raise ValueError("emit: the scheme's lookup table has sign patterns without a row")
    suspect = np.empty(triangles.shape[0], dtype=np.bool_)
    first, shift = (_GLOBAL, 62) if buckets is None else (buckets.first, buckets.shift)
    with threads_for(triangles.shape[0]):
        _emit(points, triangles, tri_edges, first, shift, per_edge, forms, lut,
              _frame_tables(tables, per_edge).reshape(-1), 3 * tables.shape[1], out.reshape(-1),
              suspect)
    return suspect


_GLOBAL = np.zeros(1, dtype=np.int64)  # ``first`` when tri_edges are global ids already


@njit(parallel=True, cache=True)
def _emit(points, triangles, tri_edges, first, shift, per_edge, forms, lut, frames, width,
          out, suspect):
    """``frames``: :func:`_frame_tables` flattened, ``width = 3 T`` entries per (labelling,
    row); ``out`` flat. The output loop indexes with :func:`unsigned` (signed indices cost
    a sixth of this kernel in wraparound checks)."""
    m = triangles.shape[0]
    n = points.shape[0]
    n_rows = frames.shape[0] // (9 * width)
    factors = factor_forms(forms)
    lattice = float(per_edge + 1)
    n_chunks = (m + CHUNK - 1) // CHUNK
    for ch in prange(n_chunks):
        buf = np.empty(SCRATCH)
        loc = np.empty(3 + 3 * per_edge, dtype=np.int64)
        for t in range(ch * CHUNK, min(m, (ch + 1) * CHUNK)):
            ahead = min(t + AHEAD, m - 1)
            for i in range(3):
                prefetch(points, triangles[ahead, i])
            v0 = triangles[t, 0]
            v1 = triangles[t, 1]
            v2 = triangles[t, 2]
            x0, y0 = points[v0, 0], points[v0, 1]
            x1, y1 = points[v1, 0], points[v1, 1]
            x2, y2 = points[v2, 0], points[v2, 1]
            suspect[t] = _suspect(x0, y0, x1, y1, x2, y2, lattice)
            im, jn, ko, row = decide(x0, y0, x1, y1, x2, y2, forms, factors, lut, buf)
            # own local points: v0, v1, v2, then each edge (v_i, v_i+1)'s points from v_i
            for i in range(3):
                a = triangles[t, i]
                b = triangles[t, (i + 1) % 3]
                loc[i] = a
                base = n + (first[min(a, b) >> shift] + tri_edges[t, i]) * per_edge
                back = int(a > b)  # stored from the smaller vertex: reverse when walking down
                for j in range(per_edge):
                    loc[3 + per_edge * i + j] = base + j + back * (per_edge - 1 - 2 * j)
            f0 = ((im * 3 + jn) * n_rows + row) * width
            o = t * width
            for q in range(width):
                out[unsigned(o + q)] = loc[frames[unsigned(f0 + q)]]


@njit(parallel=True, cache=True)
def rounding_suspects(points, triangles, lattice):
    """``(M,) bool``: triangles whose children might be flattened or inverted when the new
    points are rounded to float64 (checked exactly afterwards; almost always all False).

    Every child's corners lie on the barycentric lattice of step ``1 / lattice`` of its
    parent (3 for the 7T stencil, 2 for midpoints), so its exact doubled area is at least
    ``A / lattice**2`` (``A``: the parent's doubled area). Rounding a new point moves it by at
    most ``d = 4 eps C`` per coordinate (``C``: the largest coordinate magnitude), which
    changes a child's doubled area by at most ``3 sqrt(2) L d + 6 d**2`` (``L``: the parent's
    longest edge, bounding every child edge; bounded in turn by the largest ``|dx| + |dy|``
    of an edge). A triangle is a suspect unless ``A`` beats that change with a margin of 8,
    after allowing ``4 L d`` for the float error of ``A`` itself.
    """
    m = triangles.shape[0]
    out = np.zeros(m, dtype=np.bool_)
    for t in prange(m):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        out[t] = _suspect(points[a, 0], points[a, 1], points[b, 0], points[b, 1],
                          points[c, 0], points[c, 1], float(lattice))
    return out


@njit(inline="always", cache=True)
def _suspect(ax, ay, bx, by, cx, cy, lattice):
    """One triangle of :func:`rounding_suspects`; ``L`` is bounded by the largest
    ``|dx| + |dy|`` of an edge (no square root; a larger ``L`` only adds suspects)."""
    eps = 2.220446049250313e-16
    big = max(max(abs(ax), abs(ay)), max(max(abs(bx), abs(by)), max(abs(cx), abs(cy))))
    ux, uy, wx, wy = bx - ax, by - ay, cx - ax, cy - ay
    vx, vy = cx - bx, cy - by
    area = abs(ux * wy - uy * wx)
    longest = max(abs(ux) + abs(uy), max(abs(wx) + abs(wy), abs(vx) + abs(vy)))
    d = 4.0 * eps * big
    change = 3.0 * np.sqrt(2.0) * longest * d + 6.0 * d * d
    return area <= 8.0 * lattice * lattice * change + 4.0 * longest * d
