"""CUDA kernels of one uniform level after the edge numbering: new points, decision and
emission, and the tags.

Each is the device twin of a CPU kernel and writes the same values to the same places:

* :func:`new_points`: :func:`qdrefine.numbering.bucket_points` (the old points, then the
  ``k`` points of edge ``g`` at ``N + g k + j`` by :func:`qdrefine.numbering.edge_point`'s
  formula: ``2.0 * a`` and ``0.5 * (a + b)`` are exact, so a fused multiply-add computes
  the same double as the CPU, and the division by 3 is IEEE's, correctly rounded);
* :func:`emit`: :func:`qdrefine.kernels.emit` with the labelling and signs of
  :mod:`qdrefine.gpu.predicates`, stages 1 and 2; a triangle some sign of which needs the
  exact stage is listed in ``hard`` instead, :func:`decide_rows` decides it with all three
  stages and :func:`emit_rows` writes its children;
* :func:`repeat` and :func:`split_edges`: ``np.repeat`` of the cell tags and
  :func:`qdrefine.refine.split_tagged_edges` of the tagged edges.
"""

from __future__ import annotations

from numba import cuda
from numba.types import float64, int64

from ..predicates import SCRATCH
from .numbering import edge_id
from .predicates import decide_exact, decide_fast, orient_filter, orient_sign, suspect

__all__ = ["new_points", "emit", "decide_rows", "emit_rows", "gather_rows", "repeat", "split_edges",
           "check_points"]

MAX_LOCAL = 9  # own local points of a triangle: 3 corners + 3 edges x at most 2


@cuda.jit(device=True, inline=True)
def edge_point(pa, pb, j, per_edge):
    """:func:`qdrefine.numbering.edge_point`."""
    if per_edge == 1:
        return (pa + pb) * 0.5
    if j == 0:
        return (2.0 * pa + pb) / 3.0
    return (pa + 2.0 * pb) / 3.0


@cuda.jit
def new_points(points, starts, first, hi, per_edge, out):
    """One thread per vertex ``v``: copy it, then write the points of its edges ``(v, w)``,
    ``v < w``."""
    v = cuda.grid(1)
    n = points.shape[0]
    if v < n:
        out[v, 0] = points[v, 0]
        out[v, 1] = points[v, 1]
        s = starts[v]
        for u in range(first[v + 1] - first[v]):
            w = hi[s + u]
            g = n + (first[v] + u) * per_edge
            for j in range(per_edge):
                for k in range(2):
                    out[g + j, k] = edge_point(points[v, k], points[w, k], j, per_edge)


@cuda.jit(device=True)
def _write_children(t, im, jn, row, triangles, starts, first, hi, n, per_edge, frames,
                    n_rows, width, out):
    """Children of triangle ``t`` with labelling ``(im, jn)`` and table ``row`` into
    ``out[t * width: (t + 1) * width]`` (the inner loop of :func:`qdrefine.kernels._emit`)."""
    loc = cuda.local.array(MAX_LOCAL, dtype=int64)
    for i in range(3):
        a = triangles[t, i]
        b = triangles[t, (i + 1) % 3]
        loc[i] = a
        base = n + edge_id(a, b, starts, first, hi) * per_edge
        back = 1 if a > b else 0
        for j in range(per_edge):
            loc[3 + per_edge * i + j] = base + j + back * (per_edge - 1 - 2 * j)
    # int64 casts: the table row is an int8 (a numpy scalar under the simulator, where
    # int8 arithmetic would wrap)
    f0 = ((int64(im) * 3 + int64(jn)) * n_rows + int64(row)) * width
    o = t * width
    for q in range(width):
        out[o + q] = loc[frames[f0 + q]]


@cuda.jit
def emit(points, triangles, starts, first, hi, per_edge, forms, factors, lut, frames, width,
         out, hard, n_hard, n_suspect, check):
    """One thread per triangle: decide and write its children into flat ``out``; list the
    triangles that need the exact stage in ``hard[: n_hard[0]]``; count the rounding
    suspects (:func:`qdrefine.kernels.rounding_suspects`) in ``n_suspect[0]``. With
    ``check``, a triangle the orientation filter does not prove counter-clockwise is listed
    too (:func:`decide_rows` then decides its orientation exactly)."""
    t = cuda.grid(1)
    if t < triangles.shape[0]:
        v0 = triangles[t, 0]
        v1 = triangles[t, 1]
        v2 = triangles[t, 2]
        x0, y0 = points[v0, 0], points[v0, 1]
        x1, y1 = points[v1, 0], points[v1, 1]
        x2, y2 = points[v2, 0], points[v2, 1]
        if suspect(x0, y0, x1, y1, x2, y2, float(per_edge + 1)):
            cuda.atomic.add(n_suspect, 0, 1)
        if check and orient_filter(x0, y0, x1, y1, x2, y2) <= 0:
            hard[cuda.atomic.add(n_hard, 0, 1)] = t
            return
        im, jn, ko, row = decide_fast(x0, y0, x1, y1, x2, y2, forms, factors, lut)
        if row < 0:
            hard[cuda.atomic.add(n_hard, 0, 1)] = t
            return
        n_rows = frames.shape[0] // (9 * width)
        _write_children(t, im, jn, row, triangles, starts, first, hi, points.shape[0],
                        per_edge, frames, n_rows, width, out)


@cuda.jit
def decide_rows(points, triangles, rows, forms, factors, lut, check, labels):
    """``labels[r] = (iM, iN, iO, row)`` of triangle ``rows[r]`` by all three stages
    (:func:`qdrefine.gpu.predicates.decide_exact`), for the triangles :func:`emit` listed.
    With ``check``, a triangle whose exact orientation is not counter-clockwise gets
    ``row = -1`` (zero area) or ``-2`` (clockwise) instead."""
    r = cuda.grid(1)
    if r < rows.shape[0]:
        buf = cuda.local.array(SCRATCH, dtype=float64)
        cc = cuda.local.array(6, dtype=float64)
        t = rows[r]
        v0 = triangles[t, 0]
        v1 = triangles[t, 1]
        v2 = triangles[t, 2]
        x0, y0 = points[v0, 0], points[v0, 1]
        x1, y1 = points[v1, 0], points[v1, 1]
        x2, y2 = points[v2, 0], points[v2, 1]
        if check:
            s = orient_sign(x0, y0, x1, y1, x2, y2, buf)
            if s <= 0:
                labels[r, 3] = -1 if s == 0 else -2
                return
        im, jn, ko, row = decide_exact(x0, y0, x1, y1, x2, y2, forms, factors, lut, buf, cc)
        labels[r, 0] = im
        labels[r, 1] = jn
        labels[r, 2] = ko
        labels[r, 3] = row


@cuda.jit
def emit_rows(n, triangles, starts, first, hi, per_edge, frames, width, rows, labels, out):
    """:func:`emit`'s output for triangles ``rows`` with labellings and table rows
    ``labels (R, 4)`` from :func:`decide_rows` (``n``: the number of old points)."""
    r = cuda.grid(1)
    if r < rows.shape[0]:
        n_rows = frames.shape[0] // (9 * width)
        _write_children(rows[r], labels[r, 0], labels[r, 1], labels[r, 3], triangles, starts,
                        first, hi, n, per_edge, frames, n_rows, width, out)


@cuda.jit
def gather_rows(points, ids, out):
    """``out = points[ids]`` for rows ``(K, 2)``."""
    i = cuda.grid(1)
    if i < ids.shape[0]:
        out[i, 0] = points[ids[i], 0]
        out[i, 1] = points[ids[i], 1]


@cuda.jit
def repeat(values, times, out):
    """``out = np.repeat(values, times)``."""
    i = cuda.grid(1)
    if i < out.shape[0]:
        out[i] = values[i // times]


@cuda.jit
def split_edges(edges, n, starts, first, hi, per_edge, out, first_bad):
    """Each tagged edge ``(a, b)`` into ``per_edge + 1`` rows ``a -> ... -> b`` of ``out``
    (:func:`qdrefine.refine.split_tagged_edges` with every edge split); ``first_bad[0]``:
    the least row that is not an edge of any triangle (unchanged if none)."""
    r = cuda.grid(1)
    if r < edges.shape[0]:
        a = edges[r, 0]
        b = edges[r, 1]
        g = edge_id(a, b, starts, first, hi)
        if g < 0:
            cuda.atomic.min(first_bad, 0, r)
            return
        base = n + g * per_edge
        prev = a
        for j in range(per_edge + 1):
            if j == per_edge:
                nxt = b
            elif a < b:
                nxt = base + j
            else:
                nxt = base + per_edge - 1 - j
            out[r * (per_edge + 1) + j, 0] = prev
            out[r * (per_edge + 1) + j, 1] = nxt
            prev = nxt


@cuda.jit
def check_points(points, lo, hi, first_bad):
    """``first_bad[0]``: the least row of ``points`` with a non-finite coordinate or a
    nonzero one outside ``[lo, hi]`` in magnitude (:func:`qdrefine.predicates.check_coordinates`);
    unchanged when there is none."""
    i = cuda.grid(1)
    if i < points.shape[0]:
        for k in range(2):
            x = abs(points[i, k])
            if not (x <= hi) or (x != 0.0 and x < lo):  # NaN fails x <= hi
                cuda.atomic.min(first_bad, 0, i)
