"""Edge numbering on the device: the CPU's ids (edges ordered by ``(min vertex, max
vertex)``, :mod:`qdrefine.numbering`) from a counting sort of the half-edges by their smaller
vertex.

1. ``counts[v]``: half-edges whose smaller vertex is ``v`` (atomic adds); an exclusive scan
   gives ``starts (N + 1,)``, the slots of vertex ``v``;
2. every half-edge writes its larger vertex into a slot of its smaller vertex's run (an
   atomic counter per vertex: the order within a run depends on the scheduling);
3. one thread per vertex sorts its run (insertion sort, heapsort for runs longer than 16) and
   moves the distinct values to its front: ``unique[v]`` of them. A run's sorted content does
   not depend on the order it was filled, so neither does anything below;
4. an exclusive scan of ``unique`` gives ``first (N + 1,)``: edge ``(v, w)``, ``v < w``, has
   the global id ``first[v] + u``, ``u`` the position of ``w`` among ``v``'s distinct values
   (found by :func:`edge_id`, a binary search in a run of a few entries), and
   ``first[N]`` is the number of edges ``E``. These are exactly the CPU's ids.

Nothing here depends on the triangle order or on how the threads are scheduled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import cuda
from numpy.typing import NDArray

__all__ = ["DeviceEdges", "THREADS", "blocks", "edge_id", "exclusive_scan", "sort_edges",
           "zeros"]

THREADS = 128  #: threads per block of every kernel
SCAN_CHUNK = 32  #: elements per thread in :func:`exclusive_scan`
SCAN_SERIAL = 1024  #: at most this many elements are scanned by a single thread


def blocks(n: int) -> int:
    """Blocks of :data:`THREADS` threads covering ``n`` items (at least one)."""
    return max((int(n) + THREADS - 1) // THREADS, 1)


@dataclass(frozen=True)
class DeviceEdges:
    """The distinct edges of a triangle list on the device.

    Attributes
    ----------
    starts : (N + 1,) int64
        Run of vertex ``v`` in ``hi``: ``starts[v] .. starts[v + 1]``.
    first : (N + 1,) int64
        Global id of the first edge whose smaller vertex is ``v``; ``first[N] = E``.
    hi : (3 M,) int, dtype of the triangles
        The larger vertices of ``v``'s distinct edges, sorted, at ``starts[v] + u``,
        ``u < first[v + 1] - first[v]`` (the rest of the run is scratch).
    n_edges : int
    """

    starts: object
    first: object
    hi: object
    n_edges: int

    def ends_host(self) -> NDArray[np.int64]:
        """The edges ``(E, 2) int64`` on the host, by id: ``(v, w)``, ``v < w``."""
        first = self.first.copy_to_host().astype(np.int64)
        starts = self.starts.copy_to_host().astype(np.int64)
        hi = self.hi.copy_to_host()
        counts = np.diff(first)
        lo = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
        slot = np.repeat(starts[:-1] - first[:-1], counts) + np.arange(self.n_edges)
        return np.column_stack([lo, hi[slot].astype(np.int64)])


def sort_edges(triangles, n_points: int) -> DeviceEdges:
    """Number the edges of device ``triangles (M, 3)`` (indices in ``[0, n_points)``)."""
    m = triangles.shape[0]
    n = int(n_points)
    counts = zeros(n, np.int32)
    _count[blocks(m), THREADS](triangles, counts)
    starts = exclusive_scan(counts)
    counts = zeros(n, np.int32)  # fill pointers
    hi = cuda.device_array(3 * m, dtype=triangles.dtype)
    _scatter[blocks(m), THREADS](triangles, starts, counts, hi)
    _sort_runs[blocks(n), THREADS](starts, hi, counts)  # counts := distinct per vertex
    first = exclusive_scan(counts)
    n_edges = int(first[n:].copy_to_host()[0]) if n else 0
    return DeviceEdges(starts, first, hi, n_edges)


def zeros(size: int, dtype):
    """A device array of zeros, filled on the device (no host copy)."""
    out = cuda.device_array(size, dtype=dtype)
    if size:
        _zero[blocks(size), THREADS](out)
    return out


@cuda.jit
def _zero(a):
    i = cuda.grid(1)
    if i < a.shape[0]:
        a[i] = 0


@cuda.jit
def _count(tri, counts):
    t = cuda.grid(1)
    if t < tri.shape[0]:
        for i in range(3):
            cuda.atomic.add(counts, min(tri[t, i], tri[t, (i + 1) % 3]), 1)


@cuda.jit
def _scatter(tri, starts, fill, hi):
    t = cuda.grid(1)
    if t < tri.shape[0]:
        for i in range(3):
            a = tri[t, i]
            b = tri[t, (i + 1) % 3]
            v = min(a, b)
            p = starts[v] + cuda.atomic.add(fill, v, 1)
            hi[p] = max(a, b)


@cuda.jit(device=True)
def _sift_down(a, s, root, end):
    """Max-heap of ``a[s:end]`` (indices relative to ``s``): move ``root`` down."""
    while 2 * root + 1 < end - s:
        child = 2 * root + 1
        if child + 1 < end - s and a[s + child] < a[s + child + 1]:
            child += 1
        if a[s + root] < a[s + child]:
            x = a[s + root]
            a[s + root] = a[s + child]
            a[s + child] = x
            root = child
        else:
            return


@cuda.jit(device=True)
def _sort_run(a, s, e):
    """Sort ``a[s:e]`` in place: insertion sort for short runs, heapsort for long ones."""
    if e - s <= 16:
        for p in range(s + 1, e):
            x = a[p]
            q = p - 1
            while q >= s and a[q] > x:
                a[q + 1] = a[q]
                q -= 1
            a[q + 1] = x
        return
    for root in range((e - s) // 2 - 1, -1, -1):
        _sift_down(a, s, root, e)
    for end in range(e - 1, s, -1):
        x = a[s]
        a[s] = a[end]
        a[end] = x
        _sift_down(a, s, 0, end)


@cuda.jit
def _sort_runs(starts, hi, unique):
    v = cuda.grid(1)
    if v < unique.shape[0]:
        s = starts[v]
        e = starts[v + 1]
        _sort_run(hi, s, e)
        u = 0
        for q in range(s, e):
            if u == 0 or hi[q] != hi[s + u - 1]:
                hi[s + u] = hi[q]
                u += 1
        unique[v] = u


@cuda.jit(device=True)
def edge_id(a, b, starts, first, hi):
    """Global id of the edge ``(a, b)`` (either order); -1 if it is not an edge."""
    v = min(a, b)
    w = max(a, b)
    lo = 0
    top = first[v + 1] - first[v]
    s = starts[v]
    while lo < top:
        mid = (lo + top) // 2
        if hi[s + mid] < w:
            lo = mid + 1
        else:
            top = mid
    if lo < first[v + 1] - first[v] and hi[s + lo] == w:
        return first[v] + lo
    return -1


# ----------------------------------------------------------------------------------------
# exclusive prefix sums


def exclusive_scan(values):
    """``(L + 1,) int64`` exclusive prefix sums of device ``values (L,)`` (the last entry is
    the total): per thread a chunk of :data:`SCAN_CHUNK`, the chunk totals scanned
    recursively, a single thread for at most :data:`SCAN_SERIAL` (one thread walks memory
    with a latency per load: keep its share small)."""
    size = values.shape[0]
    out = cuda.device_array(size + 1, dtype=np.int64)
    if size <= SCAN_SERIAL:
        _serial_scan[1, 1](values, out)
        return out
    n_chunks = (size + SCAN_CHUNK - 1) // SCAN_CHUNK
    sums = cuda.device_array(n_chunks, dtype=np.int64)
    _chunk_sums[blocks(n_chunks), THREADS](values, sums)
    offsets = exclusive_scan(sums)
    _chunk_scan[blocks(n_chunks), THREADS](values, offsets, out)
    return out


@cuda.jit
def _serial_scan(values, out):
    total = 0
    for i in range(values.shape[0]):
        out[i] = total
        total += values[i]
    out[values.shape[0]] = total


@cuda.jit
def _chunk_sums(values, sums):
    c = cuda.grid(1)
    if c < sums.shape[0]:
        total = 0
        for i in range(c * SCAN_CHUNK, min((c + 1) * SCAN_CHUNK, values.shape[0])):
            total += values[i]
        sums[c] = total


@cuda.jit
def _chunk_scan(values, offsets, out):
    c = cuda.grid(1)
    n_chunks = offsets.shape[0] - 1
    if c < n_chunks:
        total = offsets[c]
        for i in range(c * SCAN_CHUNK, min((c + 1) * SCAN_CHUNK, values.shape[0])):
            out[i] = total
            total += values[i]
        if c == n_chunks - 1:
            out[values.shape[0]] = total
