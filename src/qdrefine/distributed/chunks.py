"""Per-chunk passes of the distributed level (:mod:`qdrefine.distributed.level`), compiled
where they touch every edge or child: the distinct values of a chunk's arrays, the merge of
an edge partition's sorted pieces, the end coordinates and new points of edges, and the
children's global vertex rows and corner coordinates (one pass each instead of several
NumPy passes with temporaries of that size).

They run in the worker's one thread (a worker runs one task at a time; Dask's tasks are
the parallelism).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from ..numbering import edge_point


def distinct(values: NDArray, inverse: bool = True
             ) -> tuple[NDArray, NDArray[np.intp], NDArray[np.intp] | None]:
    """What ``np.unique(values, return_index=True, return_inverse=True)`` gives for a 1-D
    array, except that the index is of *one* occurrence of each value, not necessarily the
    first: ``(sorted distinct values (u,), one position of each (u,), inverse (n,))``, the
    inverse None unless asked for.

    Every use here reads data that is equal at every occurrence of a value (the
    coordinates of a vertex or of an edge's ends), so any occurrence will do, and an
    unstable sort is about four times faster than the stable one ``np.unique`` needs for
    the first occurrence.
    """
    return distinct_counted(values, inverse)[:3]


def distinct_counted(values: NDArray, inverse: bool = True
                     ) -> tuple[NDArray, NDArray[np.intp], NDArray[np.intp] | None,
                                NDArray[np.intp]]:
    """:func:`distinct` and the number of occurrences of each distinct value ``(u,)``."""
    order = np.argsort(values, kind="quicksort")
    ordered = values[order]
    keys = np.empty(ordered.shape[0], dtype=values.dtype)
    one = np.empty(ordered.shape[0], dtype=np.intp)
    count = np.zeros(ordered.shape[0], dtype=np.intp)
    back = np.empty(ordered.shape[0] if inverse else 0, dtype=np.intp)
    u = _distinct_sorted(ordered, order, keys, one, count, back, inverse)
    return keys[:u].copy(), one[:u].copy(), back if inverse else None, count[:u].copy()


@njit(cache=True)
def _distinct_sorted(ordered, order, keys, one, count, back, inverse):
    u = -1
    for i in range(ordered.shape[0]):
        if u < 0 or ordered[i] != keys[u]:
            u += 1
            keys[u] = ordered[i]
            one[u] = order[i]
        count[u] += 1
        if inverse:
            back[order[i]] = u
    return u + 1


def merge_sorted(keys: NDArray[np.int64], starts: NDArray[np.int64]
                 ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Merge sorted runs of distinct keys: ``keys[starts[i]:starts[i + 1]]`` is run ``i``.

    Returns ``first (u,)``, the row of one occurrence of each distinct key in increasing key
    order (``keys[first]`` are the sorted distinct keys), and ``inverse (n,)``, the index in
    that order of every row's key. A heap of the runs' heads: ``O(n log r)`` for ``r`` runs,
    every run read in order (no random gather, unlike an argsort of the concatenation).
    """
    first = np.empty(keys.shape[0], dtype=np.int64)
    inverse = np.empty(keys.shape[0], dtype=np.int64)
    u = _merge_sorted(keys, np.asarray(starts, dtype=np.int64), first, inverse)
    return first[:u].copy(), inverse


@njit(cache=True)
def _merge_sorted(keys, starts, first, inverse):
    runs = starts.shape[0] - 1
    heap = np.empty(runs, dtype=np.int64)  # runs, by the key at their position
    pos = starts[:-1].copy()
    size = 0
    for r in range(runs):
        if pos[r] < starts[r + 1]:
            heap[size] = r
            size += 1
            _sift_up(heap, size - 1, keys, pos)
    u = -1
    last = 0
    while size:
        r = heap[0]
        row = pos[r]
        if u < 0 or keys[row] != last:
            u += 1
            first[u] = row
            last = keys[row]
        inverse[row] = u
        pos[r] += 1
        if pos[r] == starts[r + 1]:
            size -= 1
            heap[0] = heap[size]
        _sift_down(heap, size, keys, pos)
    return u + 1


@njit(inline="always", cache=True)
def _sift_up(heap, i, keys, pos):
    while i:
        parent = (i - 1) // 2
        if keys[pos[heap[parent]]] <= keys[pos[heap[i]]]:
            break
        heap[parent], heap[i] = heap[i], heap[parent]
        i = parent


@njit(inline="always", cache=True)
def _sift_down(heap, size, keys, pos):
    i = 0
    while True:
        small = i
        for child in (2 * i + 1, 2 * i + 2):
            if child < size and keys[pos[heap[child]]] < keys[pos[heap[small]]]:
                small = child
        if small == i:
            return
        heap[small], heap[i] = heap[i], heap[small]
        i = small


def edge_ends(triangles: NDArray[np.integer], corners: NDArray[np.float64],
              half_edges: NDArray[np.integer]) -> NDArray[np.float64]:
    """Coordinates ``(E, 4)`` (smaller vertex first, then larger) of the ends of the
    half-edges ``h = 3 t + i`` (edge ``(v_i, v_{i+1})`` of triangle ``t``) of
    ``triangles (C, 3)`` with corner coordinates ``corners (C, 3, 2)``."""
    out = np.empty((half_edges.shape[0], 4), dtype=np.float64)
    _edge_ends(triangles, corners, half_edges, out)
    return out


@njit(cache=True)
def _edge_ends(triangles, corners, half_edges, out):
    for g in range(half_edges.shape[0]):
        t = half_edges[g] // 3
        i = half_edges[g] - 3 * t
        j = (i + 1) % 3
        if triangles[t, i] > triangles[t, j]:
            i, j = j, i
        out[g, 0] = corners[t, i, 0]
        out[g, 1] = corners[t, i, 1]
        out[g, 2] = corners[t, j, 0]
        out[g, 3] = corners[t, j, 1]


def new_points(ends: NDArray[np.float64], per_edge: int,
               at: NDArray[np.integer] | None = None, out: NDArray[np.float64] | None = None
               ) -> NDArray[np.float64]:
    """The ``per_edge`` new points of each edge ``(x_lo, y_lo, x_hi, y_hi)`` of ``ends
    (E, 4)`` (its smaller vertex's coordinates first), each edge's listed from its smaller
    vertex, by the formula of :func:`qdrefine.kernels.edge_points` (``edge_point``), so bit
    for bit the points that refinement in memory makes: rows ``g k .. g k + k - 1`` of
    ``out`` for edge ``g`` (default: a new ``(E k, 2)`` array), or for edge ``at[g]``
    (``at (E,)``: several edges may have the same place if they are the same edge)."""
    ends = np.ascontiguousarray(ends, dtype=np.float64)
    if at is None:
        at = np.arange(ends.shape[0], dtype=np.int64)
    if out is None:
        out = np.empty((ends.shape[0] * per_edge, 2), dtype=np.float64)
    _new_points(ends, at, per_edge, out)
    return out


@njit(cache=True)
def _new_points(ends, at, per_edge, out):
    for g in range(ends.shape[0]):
        r = at[g] * per_edge
        for j in range(per_edge):
            for x in range(2):
                out[r + j, x] = edge_point(ends[g, x], ends[g, 2 + x], j, per_edge)


def global_children(children: NDArray[np.integer], vertices: NDArray[np.int64], n: int,
                    out: NDArray[np.integer]) -> None:
    """Write the global vertex rows of the children ``(C T, 3)`` into ``out`` (same shape).

    ``children`` holds the emission kernel's local indices: ``i < u`` is the chunk's vertex
    of rank ``i``, global row ``vertices[i]`` (``vertices (u,)`` sorted); ``u + g k + j`` is
    the ``j``-th new point of edge ``g``, global row ``n + g k + j`` (``n`` old points).
    """
    _global_children(children, vertices, n, out)


@njit(cache=True)
def _global_children(children, vertices, n, out):
    u = vertices.shape[0]
    for i in range(children.shape[0]):
        for c in range(3):
            v = children[i, c]
            out[i, c] = vertices[v] if v < u else n + (v - u)


def child_coordinates(points: NDArray[np.float64], local: NDArray[np.integer],
                      gid: NDArray[np.int64], children: NDArray[np.integer], per_edge: int
                      ) -> NDArray[np.float64]:
    """Corner coordinates ``(C T, 3, 2)`` of the children of the chunk's triangles.

    Parameters
    ----------
    points : (u, 2) float64
        The chunk's vertices in rank order.
    local : (C, 3) int
        The chunk's triangles as rows of ``points``.
    gid : (C, 3) int64
        Edge id of each half-edge ``(v_i, v_{i+1})``.
    children : (C T, 3) int
        The emission kernel's output for these triangles, ``T`` children per triangle in
        order (local indices as in :func:`global_children`).
    per_edge : int
        New points per edge ``k``.

    A new point is computed from its edge's endpoints, smaller vertex rank first, by the
    formula of :func:`qdrefine.kernels.edge_points` (``edge_point``): the coordinates the
    edge partitions computed for the points array, bit for bit (ranks keep the order of the
    global vertex rows).
    """
    out = np.empty((children.shape[0], 3, 2), dtype=np.float64)
    if local.shape[0]:
        _child_coordinates(points, local, gid, children,
                           children.shape[0] // local.shape[0], per_edge, out)
    return out


@njit(cache=True)
def _child_coordinates(points, local, gid, children, n_children, per_edge, out):
    u = points.shape[0]
    new = np.empty((3, per_edge, 2), dtype=np.float64)
    for t in range(local.shape[0]):
        for e in range(3):
            a = local[t, e]
            b = local[t, (e + 1) % 3]
            lo, hi = min(a, b), max(a, b)
            for j in range(per_edge):
                for x in range(2):
                    new[e, j, x] = edge_point(points[lo, x], points[hi, x], j, per_edge)
        for r in range(t * n_children, (t + 1) * n_children):
            for c in range(3):
                v = children[r, c]
                if v < u:
                    out[r, c, 0] = points[v, 0]
                    out[r, c, 1] = points[v, 1]
                    continue
                g = (v - u) // per_edge
                j = (v - u) - g * per_edge
                e = 0 if gid[t, 0] == g else (1 if gid[t, 1] == g else 2)
                out[r, c, 0] = new[e, j, 0]
                out[r, c, 1] = new[e, j, 1]
