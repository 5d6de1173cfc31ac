"""Compiled array kernels of uniform refinement (numba).

Three passes, each linear in the mesh size and free of Python loops:

1. :func:`number_edges`: every undirected edge gets an id, ordered by ``(min vertex, max
   vertex)``; a counting sort on the smaller vertex, then a sort of each (small) bucket by
   the larger vertex. Ids depend on the vertex numbering only, never on the triangle order.
2. :func:`edge_points`: the ``k`` new points of every edge, computed once from its two
   endpoints by a symmetric formula (the point nearer ``a`` is ``(2a + b) / 3`` whichever
   way the edge is walked; midpoints ``(a + b) / 2``), so both neighbours share them.
3. :func:`emit`: per triangle, the canonical labelling (exact squared-length comparisons,
   tie rules in :mod:`qdrefine.schemes`), the signs of the scheme's forms, a table row, and
   the children written to ``out[t * T: (t + 1) * T]``; children whose canonical frame is a
   reflection of the input are flipped so that the output stays counter-clockwise.

Input triangles must be counter-clockwise (``Mesh`` guarantees it).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .predicates import SCRATCH, form_sign

__all__ = ["number_edges", "edge_points", "emit", "classify", "CHUNK"]

CHUNK = 4096  # triangles per parallel work item


@njit(cache=True)
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


@njit(cache=True)
def canonical(x0, y0, x1, y1, x2, y2, buf):
    """Local vertex indices ``(iM, iN, iO)`` of the canonical labelling of one triangle.

    ``MN`` is the longest edge and ``M`` the endpoint nearer ``O`` (ties: see module
    :mod:`qdrefine.schemes`). Squared lengths relative to ``v0`` with ``u = v1 - v0`` and
    ``w = v2 - v0``: ``e0 = |v1 v2|^2 = uu + ww - 2uw``, ``e1 = ww``, ``e2 = uu``.
    """
    xs = (x0, x1, x2)
    ys = (y0, y1, y2)
    s01 = form_sign(x0, y0, x1, y1, x2, y2, 1.0, 0.0, -2.0, buf)  # sign(e0 - e1)
    s02 = form_sign(x0, y0, x1, y1, x2, y2, 0.0, 1.0, -2.0, buf)  # sign(e0 - e2)
    s12 = form_sign(x0, y0, x1, y1, x2, y2, -1.0, 1.0, 0.0, buf)  # sign(e1 - e2)
    o = -1
    for i in range(3):
        if _cmp(i, (i + 1) % 3, s01, s02, s12) >= 0 and _cmp(i, (i + 2) % 3, s01, s02, s12) >= 0:
            if o < 0 or _lex_less(xs[i], ys[i], xs[o], ys[o]):
                o = i
    j = (o + 1) % 3
    k = (o + 2) % 3
    # |O v_j|^2 = e_k and |O v_k|^2 = e_j
    c = _cmp(k, j, s01, s02, s12)
    if c < 0 or (c == 0 and _lex_less(xs[j], ys[j], xs[k], ys[k])):
        return j, k, o
    return k, j, o


@njit(cache=True)
def classify(x0, y0, x1, y1, x2, y2, forms, lut, buf):
    """Canonical labelling and table row of one triangle: ``(iM, iN, iO, row)``."""
    im, jn, ko = canonical(x0, y0, x1, y1, x2, y2, buf)
    xs = (x0, x1, x2)
    ys = (y0, y1, y2)
    code = 0
    power = 1
    for f in range(forms.shape[0]):
        s = form_sign(
            xs[im], ys[im], xs[jn], ys[jn], xs[ko], ys[ko], forms[f, 0], forms[f, 1], forms[f, 2],
            buf,
        )
        code += (s + 1) * power
        power *= 3
    return im, jn, ko, lut[code]


@njit(cache=True)
def number_edges(triangles, n_points):
    """Unique undirected edges of ``triangles (M,3)``.

    Returns ``edges (E,2)`` (``edges[:,0] < edges[:,1]``, rows sorted lexicographically),
    ``tri_edges (M,3) int64`` (id of edge ``(v_i, v_{i+1})`` of each triangle) and
    ``counts (E,) int64`` (number of triangles using each edge).
    """
    m = triangles.shape[0]
    start = np.zeros(n_points + 1, dtype=np.int64)
    for t in range(m):
        for i in range(3):
            a = triangles[t, i]
            b = triangles[t, (i + 1) % 3]
            start[min(a, b) + 1] += 1
    for v in range(n_points):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    his = np.empty(3 * m, dtype=np.int64)
    slots = np.empty(3 * m, dtype=np.int64)
    for t in range(m):
        for i in range(3):
            a = triangles[t, i]
            b = triangles[t, (i + 1) % 3]
            lo = min(a, b)
            p = fill[lo]
            fill[lo] += 1
            his[p] = max(a, b)
            slots[p] = 3 * t + i
    tri_edges = np.empty((m, 3), dtype=np.int64)
    edges = np.empty((3 * m, 2), dtype=triangles.dtype)
    counts = np.zeros(3 * m, dtype=np.int64)
    ne = 0
    for v in range(n_points):
        s = start[v]
        e = start[v + 1]
        if e - s > 16:
            order = np.argsort(his[s:e])
            his[s:e] = his[s:e][order]
            slots[s:e] = slots[s:e][order]
        else:
            for p in range(s + 1, e):
                h = his[p]
                sl = slots[p]
                q = p - 1
                while q >= s and his[q] > h:
                    his[q + 1] = his[q]
                    slots[q + 1] = slots[q]
                    q -= 1
                his[q + 1] = h
                slots[q + 1] = sl
        for p in range(s, e):
            if p == s or his[p] != his[p - 1]:
                edges[ne, 0] = v
                edges[ne, 1] = his[p]
                ne += 1
            counts[ne - 1] += 1
            tri_edges[slots[p] // 3, slots[p] % 3] = ne - 1
    return edges[:ne].copy(), tri_edges, counts[:ne].copy()


@njit(parallel=True, cache=True)
def edge_points(points, edges, per_edge, out):
    """Write the old points and ``per_edge`` new points per edge into ``out``.

    ``out`` is ``(N + E * per_edge, 2)``; the points of edge ``g = (a, b)``, ``a < b``, are at
    ``N + g * per_edge + j``, listed from ``a``.
    """
    n = points.shape[0]
    for i in prange(n):
        out[i, 0] = points[i, 0]
        out[i, 1] = points[i, 1]
    for g in prange(edges.shape[0]):
        a = edges[g, 0]
        b = edges[g, 1]
        for c in range(2):
            pa = points[a, c]
            pb = points[b, c]
            if per_edge == 2:
                out[n + 2 * g, c] = (2.0 * pa + pb) / 3.0
                out[n + 2 * g + 1, c] = (pa + 2.0 * pb) / 3.0
            else:
                out[n + g, c] = (pa + pb) * 0.5


@njit(parallel=True, cache=True)
def emit(points, triangles, tri_edges, per_edge, forms, lut, tables, out):
    """Children of every triangle into ``out (M * T, 3)``; see the module docstring."""
    m = triangles.shape[0]
    n = points.shape[0]
    n_children = tables.shape[1]
    n_local = 3 + 3 * per_edge
    n_chunks = (m + CHUNK - 1) // CHUNK
    for ch in prange(n_chunks):
        buf = np.empty(SCRATCH)
        loc = np.empty(n_local, dtype=np.int64)
        for t in range(ch * CHUNK, min(m, (ch + 1) * CHUNK)):
            v0 = triangles[t, 0]
            v1 = triangles[t, 1]
            v2 = triangles[t, 2]
            im, jn, ko, row = classify(
                points[v0, 0], points[v0, 1], points[v1, 0], points[v1, 1],
                points[v2, 0], points[v2, 1], forms, lut, buf,
            )
            lab = (im, jn, ko)
            for e in range(3):
                a = lab[e]
                b = lab[(e + 1) % 3]
                te = a if b == (a + 1) % 3 else b
                from_a = triangles[t, a] < triangles[t, b]
                base = n + tri_edges[t, te] * per_edge
                for j in range(per_edge):
                    loc[3 + per_edge * e + j] = base + (j if from_a else per_edge - 1 - j)
            loc[0] = triangles[t, im]
            loc[1] = triangles[t, jn]
            loc[2] = triangles[t, ko]
            flip = (jn - im) % 3 != 1
            for r in range(n_children):
                i0 = tables[row, r, 0]
                i1 = tables[row, r, 1]
                i2 = tables[row, r, 2]
                if flip:
                    i1, i2 = i2, i1
                out[t * n_children + r, 0] = loc[i0]
                out[t * n_children + r, 1] = loc[i1]
                out[t * n_children + r, 2] = loc[i2]
