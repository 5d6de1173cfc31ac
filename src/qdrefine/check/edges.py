"""Checks of the edge structure, from one sort of the edges
(:func:`qdrefine.numbering.sort_edges`): edges shared by more than two triangles, folded
edges, the boundary, unused points and pinched vertices."""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ..jit import threads_for
from ..numbering import EdgeBuckets
from .report import Findings

__all__ = ["Topology", "bucket_scan", "edge_scan", "used", "summary", "overused", "folded",
           "unused", "pinched"]


class Topology:
    """The sorted edges of ``t`` and one scan of them; the edge list and global ids are built
    only when a message or the tagged edges need them."""

    def __init__(self, t: NDArray, n: int, buckets: EdgeBuckets) -> None:
        self.t, self.n, self.buckets = t, n, buckets
        b = buckets
        (self.n_over, self.first_over, self.n_fold, self.first_fold, self.bedges,
         self.btris) = bucket_scan(t, b.local, b.starts, b.first, b.shift, b.mult)
        self._edges: tuple[NDArray, NDArray] | None = None

    @property
    def edges(self) -> NDArray:
        """``(E, 2)`` sorted edges."""
        if self._edges is None:
            self._edges = self.buckets.edges()
        return self._edges[0]

    def count(self, g: int) -> int:
        if self._edges is None:
            self._edges = self.buckets.edges()
        return int(self._edges[1][g])

    def triangles_of(self, g: int) -> list[int]:
        return np.flatnonzero((self.buckets.global_ids(self.t) == g).any(axis=1)).tolist()


@njit(parallel=True, cache=True)
def _mark_used(t, used):
    for k in prange(t.shape[0]):
        for i in range(3):
            used[t[k, i]] = True


def used(t: NDArray, n: int) -> NDArray[np.bool_]:
    used = np.zeros(n, dtype=np.bool_)
    with threads_for(t.shape[0]):
        _mark_used(t, used)
    return used


def summary(t: NDArray, used: NDArray, topo: Topology) -> dict[str, Any]:
    n_used = int(np.count_nonzero(used))
    n_edges = topo.buckets.n_edges
    return {"points": len(used), "used_points": n_used, "triangles": len(t), "edges": n_edges,
            "boundary_edges": len(topo.bedges),
            "euler_characteristic": n_used - n_edges + len(t)}


@njit(cache=True)
def bucket_scan(t, local, starts, first, shift, mult):
    """:func:`edge_scan` from the sorted edges of :func:`qdrefine.numbering.sort_edges`
    (``local``, ``starts``, ``first``, ``shift`` and the multiplicities ``mult``)."""
    ne = first[first.shape[0] - 1]
    n_boundary = 0
    for b in range(first.shape[0] - 1):
        for u in range(first[b + 1] - first[b]):
            if mult[starts[b] + u] == 1:
                n_boundary += 1
    bedges = np.empty((n_boundary, 2), dtype=np.int64)
    btris = np.empty(n_boundary, dtype=np.int64)
    forward = np.zeros(ne, dtype=np.int8)
    j = 0
    for k in range(t.shape[0]):
        for i in range(3):
            u, v = t[k, i], t[k, (i + 1) % 3]
            b = min(u, v) >> shift
            cnt = mult[starts[b] + local[k, i]]
            if cnt == 1:
                bedges[j, 0], bedges[j, 1] = u, v
                btris[j] = k
                j += 1
            elif cnt == 2 and u < v:
                g = first[b] + local[k, i]
                forward[g] = min(forward[g] + 1, 3)
    n_over = n_fold = 0
    first_over = first_fold = -1
    for b in range(first.shape[0] - 1):
        for u in range(first[b + 1] - first[b]):
            g = first[b] + u
            cnt = mult[starts[b] + u]
            if cnt > 2:
                n_over += 1
                if first_over < 0:
                    first_over = g
            elif cnt == 2 and forward[g] != 1:
                n_fold += 1
                if first_fold < 0:
                    first_fold = g
    return n_over, first_over, n_fold, first_fold, bedges, btris


@njit(cache=True)
def edge_scan(t, tri_edges, counts):
    """One pass over the triangles' sides: the number of edges used more than twice and the
    first one, of edges walked the same way by both of their two triangles and the first one,
    and the boundary edges ``(B, 2)`` as oriented in their triangle ``(B,)``."""
    ne = counts.shape[0]
    n_boundary = 0
    for g in range(ne):
        if counts[g] == 1:
            n_boundary += 1
    bedges = np.empty((n_boundary, 2), dtype=np.int64)
    btris = np.empty(n_boundary, dtype=np.int64)
    forward = np.zeros(ne, dtype=np.int8)
    b = 0
    for k in range(t.shape[0]):
        for i in range(3):
            g = tri_edges[k, i]
            u, v = t[k, i], t[k, (i + 1) % 3]
            if u < v:
                forward[g] = min(forward[g] + 1, 3)
            if counts[g] == 1:
                bedges[b, 0], bedges[b, 1] = u, v
                btris[b] = k
                b += 1
    n_over = n_fold = 0
    first_over = first_fold = -1
    for g in range(ne):
        if counts[g] > 2:
            n_over += 1
            if first_over < 0:
                first_over = g
        elif counts[g] == 2 and forward[g] != 1:
            n_fold += 1
            if first_fold < 0:
                first_fold = g
    return n_over, first_over, n_fold, first_fold, bedges, btris


def overused(found: Findings, topo: Topology) -> bool:
    """True when no edge is shared by more than two triangles."""
    return _edge_problem(found, topo, "overused-edge", topo.n_over, topo.first_over,
                         lambda edge, tris, g: f"edge {edge} is shared by {topo.count(g)} "
                         f"triangles {tuple(tris)}; at most two may share an edge"
                         if len(tris) == topo.count(g) else  # a repeated vertex: (0, 1, 1)
                         f"edge {edge} is used {topo.count(g)} times, by triangles "
                         f"{tuple(tris)} (a triangle with a repeated vertex uses it twice); "
                         "at most two triangles may share an edge")


def folded(found: Findings, topo: Topology) -> bool:
    """True when every interior edge is walked both ways."""
    return _edge_problem(found, topo, "folded-edge", topo.n_fold, topo.first_fold,
                         lambda edge, tris, g: f"triangles {tris[0]} and {tris[1]} lie on "
                         f"the same side of their common edge {edge}: they overlap")


def _edge_problem(found: Findings, topo: Topology, kind: str, count: int, g: int,
                  message) -> bool:
    """Report ``count`` edges of ``kind``, the first one ``g`` (``message(edge, triangles,
    g)``); True when there are none."""
    if not count:
        return True
    edge = found.ids(topo.edges[g])
    tris = [found.triangle(i) for i in topo.triangles_of(g)]
    found.add(kind, message(tuple(edge), tris, g), count, edge=edge, triangles=tris)
    return False


def unused(found: Findings, used: NDArray) -> None:
    n = len(used)
    if not used.all():
        unused = np.flatnonzero(~used)
        found.add("unused-points", f"{len(unused)} of {n} points are used by no triangle "
                  f"(first: point {found.point(unused[0])}); they are kept",
                  len(unused), point=found.point(unused[0]))


def pinched(found: Findings, bedges: NDArray) -> None:
    out = np.bincount(bedges[:, 0], minlength=1)
    pinched = np.flatnonzero(out > 1)
    if len(pinched):
        v = int(pinched[0])
        found.add("pinched-vertex", f"vertex {found.point(v)} joins {int(out[v])} separate fans "
                  "of triangles (the mesh touches itself there)", len(pinched),
                  vertex=found.point(v))
