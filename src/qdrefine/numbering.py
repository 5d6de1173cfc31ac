"""Edge numbering: every undirected edge of a triangle list gets an id, ordered by
``(min vertex, max vertex)``, in linear time and in parallel.

A two-level counting sort of the ``3 M`` half-edges by their smaller vertex:

1. per chunk of triangles, counts per *bucket* of ``2^s`` consecutive vertices; prefix sums
   give every chunk its own slots in every bucket, and the half-edges are scattered there;
2. each bucket is sorted on its own, in cache (a counting sort by the smaller vertex, then a
   small sort by the larger), and deduplicated: every half-edge gets its edge's id *within
   the bucket*, and the bucket's distinct edges are written to the front of its slots;
3. a prefix sum over the buckets' edge counts gives ``first``: the global id of edge ``u`` of
   bucket ``b`` is ``first[b] + u``, and a half-edge ``(a, b)`` is in bucket
   ``min(a, b) >> s``.

Ids depend on the vertex numbering only, never on the triangle order, the number of threads
or of chunks: a bucket's sorted content does not depend on the order its slots were filled.
Uniform refinement (:mod:`qdrefine.refine`) stops there: the new points are written per
bucket (:func:`bucket_points`) and emission adds ``first`` itself, so neither the edge list
nor global ids per half-edge are ever materialized. :func:`number_edges` builds both,
:func:`number_edges_around` also the triangles around each edge.

One concern: numbering the edges of a triangle list (and the incidence tables read off it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from .jit import AHEAD, PARALLEL_MIN, prefetch, prefetch_write, threads_for, unsigned

__all__ = ["EdgeBuckets", "sort_edges", "number_edges", "number_edges_around", "bucket_points",
           "edge_point", "edge_ids", "index_dtype", "incidence"]


def index_dtype(n_points: int) -> type[np.integer]:
    """``int32`` while vertex indices fit, ``int64`` beyond."""
    return np.int32 if n_points <= np.iinfo(np.int32).max else np.int64


@dataclass(frozen=True)
class EdgeBuckets:
    """The sorted, deduplicated edges of a triangle list, bucket by bucket.

    Attributes
    ----------
    shift : int
        Bucket ``b`` holds the edges whose smaller vertex ``v`` has ``v >> shift == b``.
    starts : (B + 1,) int64
        Slots of bucket ``b``: ``starts[b] .. starts[b + 1]`` (its half-edges).
    first : (B + 1,) int64
        Global id of the first edge of each bucket; ``first[B]`` is the number of edges ``E``.
    lo, hi, mult : (3 M,) arrays
        Edge ``u`` of bucket ``b`` is at slot ``starts[b] + u``: smaller vertex
        ``(b << shift) + lo``, larger vertex ``hi``, number of half-edges ``mult``.
    local : (M, 3) int32 or int64
        Id within its bucket of edge ``(v_i, v_{i+1})`` of every triangle (``int32`` while
        ``3 M`` fits).
    rows : (3 M,) int64 or None
        With ``sort_edges(..., with_rows=True)``: the triangles around every edge, edge by
        edge in id order and in increasing order around each edge (the rows of
        :func:`incidence` of the global ids); edge ``g`` has ``mult`` of them, so its first
        one is at the prefix sum of the multiplicities before ``g``.
    """

    shift: int
    starts: NDArray[np.int64]
    first: NDArray[np.int64]
    lo: NDArray[np.integer]
    hi: NDArray[np.integer]
    mult: NDArray[np.integer]
    local: NDArray[np.integer]
    rows: NDArray[np.int64] | None = None

    @property
    def n_edges(self) -> int:
        return int(self.first[-1])

    def edges(self) -> tuple[NDArray[np.integer], NDArray[np.int64]]:
        """``edges (E, 2)``, dtype of ``hi`` (``edges[:, 0] < edges[:, 1]``, rows sorted),
        and ``counts (E,) int64``, the number of half-edges of each."""
        out = np.empty((self.n_edges, 2), dtype=self.hi.dtype)
        counts = np.empty(self.n_edges, dtype=np.int64)
        with threads_for(self.local.shape[0]):
            _gather_edges(self.starts, self.first, self.shift, self.lo, self.hi, self.mult,
                          out, counts)
        return out, counts

    def global_ids(self, triangles: NDArray[np.integer]) -> NDArray[np.int64]:
        """``(M, 3) int64``: the global id of edge ``(v_i, v_{i+1})`` of every triangle."""
        out = np.empty(self.local.shape, dtype=np.int64)
        with threads_for(self.local.shape[0]):
            _global_ids(triangles, self.local, self.first, self.shift, out)
        return out


    def boundary_half_edges(self, triangles: NDArray[np.integer]
                            ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
        """The half-edges of ``triangles`` on no other triangle (the boundary), in row
        order: their rows ``(B,)``, their ends ``(B, 2) int64`` as the row walks them and
        their global edge ids ``(B,)``."""
        flags = np.empty(self.local.shape, dtype=np.bool_)
        with threads_for(self.local.shape[0]):
            _on_boundary(triangles, self.local, self.starts, self.shift, self.mult, flags)
        rows, sides = np.divmod(np.flatnonzero(flags.ravel()), 3)  # 20x np.nonzero's speed
        walked = np.stack([triangles[rows, sides], triangles[rows, (sides + 1) % 3]],
                          axis=1).astype(np.int64)
        ids = self.first[walked.min(axis=1) >> self.shift] + self.local[rows, sides]
        return rows.astype(np.int64), walked, ids


def number_edges(triangles: NDArray[np.integer], n_points: int
                 ) -> tuple[NDArray[np.integer], NDArray[np.int64], NDArray[np.int64]]:
    """Unique undirected edges of ``triangles (M,3)`` (vertex indices ``< n_points``).

    Returns ``edges (E,2)`` (``edges[:,0] < edges[:,1]``, rows sorted lexicographically,
    dtype of ``triangles``), ``tri_edges (M,3) int64`` (id of edge ``(v_i, v_{i+1})`` of
    each triangle) and ``counts (E,) int64`` (number of triangles using each edge).
    Temporary memory: ``3 M`` half-edge records (bucket offset, larger vertex, index).
    """
    edges, tri_edges, counts, _ = _numbered(triangles, n_points, with_rows=False)
    return edges, tri_edges, counts


def number_edges_around(triangles: NDArray[np.integer], n_points: int
                        ) -> tuple[NDArray[np.integer], NDArray[np.int64], NDArray[np.int64],
                                   tuple[NDArray[np.int64], NDArray[np.int64]]]:
    """:func:`number_edges` and the triangles around every edge, ``(start, rows)``: equal
    to :func:`incidence` of ``tri_edges`` (CSR, ``(E + 1,)`` and ``(3 M,)`` int64, in
    increasing order around each edge), read off the sort instead of a second counting
    sort (3 M scattered writes)."""
    edges, tri_edges, counts, rows = _numbered(triangles, n_points, with_rows=True)
    start = np.zeros(counts.shape[0] + 1, dtype=np.int64)
    np.cumsum(counts, out=start[1:])
    return edges, tri_edges, counts, (start, rows)


def _numbered(triangles: NDArray[np.integer], n_points: int, with_rows: bool):
    """:func:`number_edges` with the indices checked, and the sort's rows if asked."""
    tri = _as_index_array(triangles)
    if tri.size and (tri.min() < 0 or tri.max() >= n_points):
        raise ValueError(f"number_edges: vertex indices must be in [0, {n_points}), got "
                         f"[{tri.min()}, {tri.max()}]")
    buckets = sort_edges(tri, n_points, with_rows=with_rows)
    edges, counts = buckets.edges()
    return edges, buckets.global_ids(tri), counts, buckets.rows


def sort_edges(triangles: NDArray[np.integer], n_points: int, n_chunks: int | None = None,
               shift: int | None = None, with_rows: bool = False) -> EdgeBuckets:
    """Steps 1 and 2 of the module docstring for ``triangles (M, 3)``; ``n_chunks`` and
    ``shift`` (default: by size) change the work split, never the result. ``with_rows``:
    also the triangles around every edge (:attr:`EdgeBuckets.rows`).

    Indices must be in ``[0, n_points)`` (not checked here: :func:`qdrefine.refine` passes a
    validated :class:`~qdrefine.Mesh`; :func:`number_edges` checks)."""
    tri = _as_index_array(triangles)
    n = max(int(n_points), 1)
    m = tri.shape[0]
    if n_chunks is None:
        n_chunks = min(max(m // 65536, 1), 64)
    if shift is None:
        shift = _bucket_shift(n)
    n_buckets = ((n - 1) >> shift) + 1
    with threads_for(m):
        bucket_counts = np.zeros((n_chunks, n_buckets), dtype=np.int64)
        _count_buckets(tri, shift, bucket_counts)
        offsets, starts = _bucket_offsets(bucket_counts)
        lo = np.empty(3 * m, dtype=np.uint16 if shift <= 16 else np.int32)  # offset in bucket
        hi = np.empty(3 * m, dtype=tri.dtype)
        small = np.int32 if 3 * m < 2**31 else np.int64
        slot = np.empty(3 * m, dtype=small)
        _scatter(tri, shift, offsets, lo, hi, slot)
        local = np.empty((m, 3), dtype=small)
        n_unique = np.empty(n_buckets, dtype=np.int64)
        # None compiles a version without the rows (numba prunes the branch on the type)
        rows = np.empty(3 * m, dtype=np.int64) if with_rows else None
        _sort_buckets(starts, shift, lo, hi, slot, local.reshape(-1), n_unique, rows)
    first = np.zeros(n_buckets + 1, dtype=np.int64)
    np.cumsum(n_unique, out=first[1:])
    return EdgeBuckets(shift, starts, first, lo, hi, slot, local, rows)


def bucket_points(points: NDArray[np.float64], buckets: EdgeBuckets, per_edge: int,
                  out: NDArray[np.float64]) -> None:
    """:func:`qdrefine.kernels.edge_points` from the buckets: the old points, then the
    ``per_edge`` new points of edge ``g`` at ``N + g * per_edge + j``, listed from its smaller
    vertex, by the same symmetric formula."""
    with threads_for(buckets.local.shape[0]):
        _bucket_points(points, buckets.starts, buckets.first, buckets.shift, buckets.lo,
                       buckets.hi, per_edge, out)


def _as_index_array(triangles: NDArray[np.integer]) -> NDArray[np.integer]:
    tri = np.asarray(triangles)
    if tri.dtype not in (np.int32, np.int64):
        tri = tri.astype(np.int64)
    return np.ascontiguousarray(tri)


def _bucket_shift(n: int) -> int:
    """``s`` with buckets of ``2^s >= 1024`` vertices, at most about 4096 buckets."""
    s = 10
    while (n >> s) > 4096:
        s += 1
    return s


@njit(parallel=True, cache=True)
def _count_buckets(tri, shift, counts):
    """``counts[c, b]``: half-edges of chunk ``c`` whose smaller vertex is in bucket ``b``."""
    n_chunks = counts.shape[0]
    m = tri.shape[0]
    for c in prange(n_chunks):
        for t in range(c * m // n_chunks, (c + 1) * m // n_chunks):
            for i in range(3):
                counts[c, unsigned(min(tri[t, i], tri[t, (i + 1) % 3]) >> shift)] += 1


@njit(cache=True)
def _bucket_offsets(counts):
    """First slot of every (chunk, bucket) pair, and bucket starts ``(B + 1,)``."""
    n_chunks, n_buckets = counts.shape
    offsets = np.empty_like(counts)
    starts = np.empty(n_buckets + 1, dtype=np.int64)
    total = 0
    for b in range(n_buckets):
        starts[b] = total
        for c in range(n_chunks):
            offsets[c, b] = total
            total += counts[c, b]
    starts[n_buckets] = total
    return offsets, starts


@njit(parallel=True, cache=True)
def _scatter(tri, shift, offsets, lo, hi, slot):
    """Half-edges into their bucket slots: ``lo`` (offset in the bucket), ``hi`` and the
    half-edge's index ``3 t + i``."""
    n_chunks = offsets.shape[0]
    m = tri.shape[0]
    for c in prange(n_chunks):
        pos = offsets[c].copy()
        for t in range(c * m // n_chunks, (c + 1) * m // n_chunks):
            for i in range(3):
                a = tri[t, i]
                b = tri[t, (i + 1) % 3]
                v = min(a, b)
                k = v >> shift
                p = unsigned(pos[k])
                pos[k] += 1
                lo[p] = v - (k << shift)
                hi[p] = max(a, b)
                slot[p] = 3 * t + i


@njit(parallel=True, cache=True)
def _sort_buckets(starts, shift, lo, hi, slot, local, n_unique, rows):
    """Sort every bucket's half-edges by ``(lo, hi)``; give each its edge's id within the
    bucket (``local``, a scatter by half-edge index) and write the bucket's distinct edges
    to the front of its slots (``lo``, ``hi``, and their multiplicity over ``slot``); if
    ``rows`` is not None, the triangle of every sorted half-edge to ``rows`` (the buckets'
    slots are the edges' incidence ranges: every sort here is stable, so the half-edges of
    one edge stay in increasing order).

    A counting sort by ``lo`` into bucket-local buffers, then an insertion sort of each
    vertex's few ``hi`` values (an argsort for long runs at high-degree vertices).
    """
    width = 1 << shift
    for b in prange(starts.shape[0] - 1):
        s = starts[b]
        e = starts[b + 1]
        fill = np.zeros(width + 1, dtype=np.int64)
        for p in range(s, e):
            fill[unsigned(lo[p] + 1)] += 1
        for v in range(width):
            fill[v + 1] += fill[v]
        th = np.empty(e - s, dtype=hi.dtype)
        ts = np.empty(e - s, dtype=slot.dtype)
        for p in range(s, e):
            q = unsigned(fill[lo[p]])
            fill[lo[p]] += 1
            th[q] = hi[p]
            ts[q] = slot[p]
        u = -1
        q0 = 0
        for v in range(width):  # after the fill, fill[v] is the end of vertex v's run
            q1 = fill[v]
            if q1 - q0 > 16:
                order = np.argsort(th[q0:q1], kind="mergesort")
                th[q0:q1] = th[q0:q1][order]
                ts[q0:q1] = ts[q0:q1][order]
            else:
                for p in range(q0 + 1, q1):
                    x = th[p]
                    y = ts[p]
                    q = p - 1
                    while q >= q0 and th[q] > x:
                        th[q + 1] = th[q]
                        ts[q + 1] = ts[q]
                        q -= 1
                    th[q + 1] = x
                    ts[q + 1] = y
            for q in range(q0, q1):
                prefetch_write(local, ts[min(q + 4 * AHEAD, e - s - 1)])
                if q == q0 or th[q] != th[q - 1]:
                    u += 1
                    lo[s + u] = v  # u <= q: slots before q are no longer read
                    hi[s + u] = th[q]
                    slot[s + u] = 0
                slot[s + u] += 1
                local[unsigned(ts[q])] = u
                if rows is not None:
                    rows[s + q] = ts[q] // 3
            q0 = q1
        n_unique[b] = u + 1


@njit(parallel=True, cache=True)
def _gather_edges(starts, first, shift, lo, hi, mult, edges, counts):
    """The distinct edges of all buckets, in order, with their multiplicities."""
    for b in prange(starts.shape[0] - 1):
        s = starts[b]
        base = b << shift
        for u in range(first[b + 1] - first[b]):
            g = first[b] + u
            edges[g, 0] = base + lo[s + u]
            edges[g, 1] = hi[s + u]
            counts[g] = mult[s + u]


@njit(parallel=True, cache=True)
def _on_boundary(tri, local, starts, shift, mult, out):
    for t in prange(tri.shape[0]):
        for i in range(3):
            v = min(tri[t, i], tri[t, (i + 1) % 3])
            out[t, i] = mult[starts[v >> shift] + local[t, i]] == 1


@njit(parallel=True, cache=True)
def _global_ids(tri, local, first, shift, out):
    for t in prange(tri.shape[0]):
        for i in range(3):
            v = min(tri[t, i], tri[t, (i + 1) % 3])
            out[t, i] = first[v >> shift] + local[t, i]


@njit(parallel=True, cache=True)
def _bucket_points(points, starts, first, shift, lo, hi, per_edge, out):
    """Per bucket: copy its vertices' points, then write its edges' new points."""
    n = points.shape[0]
    for b in prange(starts.shape[0] - 1):
        base = b << shift
        for v in range(base, min(n, base + (1 << shift))):
            out[v, 0] = points[v, 0]
            out[v, 1] = points[v, 1]
        s = starts[b]
        n_b = first[b + 1] - first[b]
        for u in range(n_b):
            prefetch(points, hi[s + min(u + AHEAD, n_b - 1)])
            a = unsigned(base + lo[s + u])
            c = unsigned(hi[s + u])
            g = n + (first[b] + u) * per_edge
            for j in range(per_edge):
                for k in range(2):
                    out[unsigned(g + j), k] = edge_point(points[a, k], points[c, k], j, per_edge)


@njit(inline="always", cache=True)
def edge_point(pa, pb, j, per_edge):
    """One coordinate of new point ``j`` of edge ``(a, b)``, ``a < b``: ``(2a + b) / 3`` and
    ``(a + 2b) / 3`` for trisection, ``(a + b) / 2`` for ``per_edge == 1``. Symmetric: walked
    from ``b`` the same points come out, so both triangles of an edge share them."""
    if per_edge == 1:
        return (pa + pb) * 0.5
    if j == 0:
        return (2.0 * pa + pb) / 3.0
    return (pa + 2.0 * pb) / 3.0


def edge_ids(mesh_edges: NDArray, query: NDArray, n: int) -> NDArray[np.int64]:
    """Ids of ``query (K,2)`` rows in the sorted ``mesh_edges (E,2)``; -1 where absent."""
    key = mesh_edges[:, 0].astype(np.int64) * n + mesh_edges[:, 1]
    lo = np.minimum(query[:, 0], query[:, 1]).astype(np.int64)
    q = lo * n + np.maximum(query[:, 0], query[:, 1])
    pos = np.searchsorted(key, q)
    pos = np.minimum(pos, len(key) - 1)
    found = key[pos] == q
    return np.where(found, pos, -1)


#: Most chunks of :func:`incidence`'s parallel counting sort (each holds a count per id).
INCIDENCE_CHUNKS = 4


def incidence(table: NDArray[np.integer], n: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The rows of ``table (M, 3)`` that hold each id ``0 .. n - 1`` (vertices, edges ...):
    ``rows[start[i]:start[i + 1]]`` in increasing order (CSR, ``(n + 1,)`` and ``(3M,)``
    int64), by one counting sort: on large tables a parallel one over up to
    :data:`INCIDENCE_CHUNKS` consecutive blocks of rows (a count per id and block; the
    blocks fill their slices of each id's range in order, so the result is the same). The
    blocks are at most ``3M / n``, so that their counts take no more memory than ``rows``."""
    start = np.zeros(n + 1, dtype=np.int64)
    rows = np.empty(3 * table.shape[0], dtype=np.int64)
    chunks = 1
    if table.shape[0] >= PARALLEL_MIN:
        chunks = max(1, min(INCIDENCE_CHUNKS, numba.get_num_threads(),
                            3 * table.shape[0] // max(n, 1)))
    if chunks == 1:  # no parallel region: about 11 us a call, 10% at 30,000 rows
        _incidence(table, n, start, rows)
    else:
        bounds = np.linspace(0, table.shape[0], chunks + 1).astype(np.int64)
        cursor = np.zeros((chunks, n), dtype=np.int64)
        _incidence_blocks(table, bounds, start, cursor, rows)
    return start, rows


@njit(cache=True)
def _incidence(table, n, start, rows):
    for t in range(table.shape[0]):
        for j in range(3):
            start[table[t, j] + 1] += 1
    for v in range(n):
        start[v + 1] += start[v]
    fill = start[:-1].copy()
    for t in range(table.shape[0]):
        for j in range(3):
            v = table[t, j]
            rows[fill[v]] = t
            fill[v] += 1


@njit(parallel=True, cache=True)
def _incidence_blocks(table, bounds, start, cursor, rows):
    """:func:`incidence` by blocks of rows ``bounds[c] .. bounds[c + 1] - 1``: counts per
    block (in ``cursor``), the offsets, then each block fills from its cursor."""
    chunks, n = cursor.shape
    for c in prange(chunks):
        for t in range(bounds[c], bounds[c + 1]):
            for j in range(3):
                cursor[c, table[t, j]] += 1
    at = 0
    for v in range(n):
        start[v] = at
        for c in range(chunks):
            count = cursor[c, v]
            cursor[c, v] = at
            at += count
    start[n] = at
    for c in prange(chunks):
        for t in range(bounds[c], bounds[c + 1]):
            for j in range(3):
                v = table[t, j]
                rows[cursor[c, v]] = t
                cursor[c, v] += 1
