"""The numbered working mesh of one round (:class:`SplitPlan`): built from scratch
(:func:`working_edges`) or advanced from the previous round's after an expansion
(:func:`advanced`), with the same arrays bit for bit.

A step runs rounds until no conflict is left (:mod:`~qdrefine.adaptive.rounds`); each
expansion replaces a few working triangles by their children. Numbering the whole working
mesh again (a sort of every half-edge) costs most of a round on a mesh with history, where
a step runs ten rounds over a million triangles; the advance keeps the previous round's
sorted edges and merges the children's in, in passes that copy and gather.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ..jit import AHEAD, prefetch, threads_for
from ..mesh import index_dtype
from ..numbering import number_edges_around
from .edgekeys import KEY, edge_keys, edge_keys_of_rows, lookup, lookup_sorted
from .labels import canonical_edges, edge_split_codes
from .working import Tree


@dataclass
class SplitPlan:
    """The working mesh's edges and which of them get points: the longest-edge closure
    (:func:`~qdrefine.adaptive.longest_edge.closure`) of its marks, made by
    :func:`~qdrefine.adaptive.rounds.plan_splits`."""

    leaves: NDArray[np.int64]  # (W,) tree node of each working triangle, by key then node
    triangles: NDArray[np.integer]  # (W, 3) their vertex rows (int32 while ids fit)
    edges: NDArray[np.integer]  # (E, 2) sorted rows, edges[:, 0] < edges[:, 1]
    tri_edges: NDArray[np.int64]  # (W, 3) id of edge (v_i, v_i+1) of each
    counts: NDArray[np.int64]  # (E,) working triangles of each edge
    keys: NDArray[np.int64]  # (E,) edge keys, increasing
    pos: NDArray[np.int64]  # registry position of each edge, -1 if it has no points yet
    labels: NDArray[np.int8]  # (W, 3) canonical labels
    ce: NDArray[np.int64]  # (W, 3) canonical edges MN, NO, OM
    split: NDArray[np.bool_]  # (E,)
    around: tuple[NDArray[np.int64], NDArray[np.int64]]  # working triangles of each edge (CSR)

    @property
    def pre(self) -> NDArray[np.bool_]:
        return self.pos >= 0

    def codes(self) -> NDArray[np.int64]:
        """Split code of each working triangle."""
        return edge_split_codes(self.split, self.ce)


def working_edges(tree: Tree) -> SplitPlan:
    """The working mesh's leaves, numbered edges (in sorted order), their registry
    positions and canonical edges; no edge split yet."""
    leaves = tree.leaves()
    # 32-bit ids where they fit: the edge numbering sorts about 20% faster
    triangles = tree.triangles[leaves].astype(index_dtype(tree.points.shape[0]), copy=False)
    edges, tri_edges, counts, around = number_edges_around(triangles, tree.points.shape[0])
    keys = edge_keys_of_rows(edges)
    pos = lookup_sorted(tree.reg_keys, keys)  # edges are numbered in sorted order
    labels = tree.labels[leaves]
    ce = canonical_edges(labels, tri_edges)
    return SplitPlan(leaves, triangles, edges, tri_edges, counts, keys, pos, labels, ce,
                     np.zeros(edges.shape[0], dtype=bool), around)


def advanced(tree: Tree, cl: SplitPlan, own: NDArray[np.bool_], kids: NDArray[np.int64]
             ) -> SplitPlan:
    """:func:`working_edges` of ``tree`` after the working triangles ``own (W,) bool`` of
    ``cl`` were expanded into the tree nodes ``kids (X, T)`` (in the order of
    ``cl.leaves[own]``, :func:`~qdrefine.adaptive.working.expand`), computed from ``cl``:
    the same arrays, bit for bit.

    The kept working triangles keep their order and the children go after the kept ones
    of the same key (their node ids are larger); the edges only the expanded triangles
    used are dropped and the children's new edges merged in by key. Every array is one
    compiled pass that moves the kept rows to their new places (and maps their edge ids),
    plus the few children's rows.
    """
    dtype = index_dtype(tree.points.shape[0])
    if cl.triangles.dtype != dtype:  # the ids outgrew 32 bits: number from scratch
        return working_edges(tree)
    e = cl.keys.shape[0]
    gone = np.flatnonzero(own)
    children = kids.reshape(-1)
    # leaves: each child after the kept leaves of its key (and after earlier children)
    after = np.searchsorted(tree.key[cl.leaves], tree.key[children], side="right")
    at = after - np.searchsorted(gone, after)  # kept leaves before each child
    leaf_pos = np.empty(own.shape[0], dtype=np.int64)  # new place of each old leaf, or -1
    _new_places(own, at, leaf_pos)
    child_pos = at + np.arange(children.size)
    n_leaves = own.shape[0] - gone.size + children.size
    child_rows = tree.triangles[children]
    leaves = _moved(cl.leaves, leaf_pos, n_leaves, child_pos, children)
    triangles = _moved(cl.triangles, leaf_pos, n_leaves, child_pos, child_rows.astype(dtype))
    labels = _moved(cl.labels, leaf_pos, n_leaves, child_pos, tree.labels[children])

    # edges: drop those only expanded triangles used, merge the children's new ones in
    counts = cl.counts.copy()
    np.subtract.at(counts, cl.tri_edges[gone].reshape(-1), 1)
    half = edge_keys(child_rows, np.roll(child_rows, -1, axis=1))  # (C, 3)
    old_id = lookup(cl.keys, half)
    np.add.at(counts, old_id[old_id >= 0], 1)
    new_keys, new_counts = np.unique(half[old_id < 0], return_counts=True)
    dropped = counts == 0
    # kept edges with a smaller key than each new one (new keys are no old key)
    smaller = np.searchsorted(cl.keys, new_keys)
    smaller -= np.searchsorted(np.flatnonzero(dropped), smaller)
    edge_map = np.empty(e, dtype=np.int64)  # new id of each old edge, or -1
    _new_places(dropped, smaller, edge_map)
    new_ids = smaller + np.arange(new_keys.size)
    n_edges = e - int(dropped.sum()) + new_keys.size
    keys = _moved(cl.keys, edge_map, n_edges, new_ids, new_keys)
    edge_counts = _moved(counts, edge_map, n_edges, new_ids, new_counts.astype(np.int64))
    new_rows = np.stack([new_keys // KEY, new_keys % KEY], axis=1).astype(cl.edges.dtype)
    edges = _moved(cl.edges, edge_map, n_edges, new_ids, new_rows)

    child_edges = np.empty(half.shape, dtype=np.int64)
    found = old_id >= 0
    child_edges[found] = edge_map[old_id[found]]
    child_edges[~found] = new_ids[np.searchsorted(new_keys, half[~found])]
    tri_edges = _moved(cl.tri_edges, leaf_pos, n_leaves, child_pos, child_edges, edge_map)
    ce = _moved(cl.ce, leaf_pos, n_leaves, child_pos,
                canonical_edges(tree.labels[children], child_edges), edge_map)
    pos = lookup_sorted(tree.reg_keys, keys)

    # the working triangles around each edge: the kept ones' lists moved, then the
    # children merged in (both in increasing position)
    start = np.zeros(n_edges + 1, dtype=np.int64)
    np.cumsum(edge_counts, out=start[1:])
    rows = np.empty(3 * n_leaves, dtype=np.int64)
    old_start, old_rows = cl.around
    with threads_for(e):
        _move_around(edge_map, old_start, old_rows, leaf_pos, start, rows)
    c_edge = child_edges.reshape(-1)
    c_leaf = np.repeat(child_pos, 3)
    order = np.lexsort((c_leaf, c_edge))
    _merge_children(c_edge[order], c_leaf[order], start, rows)
    return SplitPlan(leaves, triangles, edges, tri_edges, edge_counts, keys, pos, labels, ce,
                     np.zeros(n_edges, dtype=bool), (start, rows))


def _moved(old: NDArray, dest: NDArray[np.int64], n: int, new_at: NDArray[np.int64],
           new: NDArray, id_map: NDArray[np.int64] | None = None) -> NDArray:
    """An array of ``n`` rows: row ``j`` of ``old`` at ``dest[j]`` (none where -1), with
    its values mapped by ``id_map`` if given, and the rows ``new`` at ``new_at``."""
    out = np.empty((n,) + old.shape[1:], dtype=old.dtype)
    flat_old = old.reshape(old.shape[0], -1)
    with threads_for(old.shape[0]):
        if id_map is None:
            _move_rows(flat_old, dest, out.reshape(n, -1))
        else:
            _move_mapped_rows(flat_old, dest, id_map, out.reshape(n, -1))
    out[new_at] = new
    return out


@njit(cache=True)
def _new_places(drop, before, out):
    """``out[j]``: the place of row ``j`` once the rows ``drop`` are dropped and rows
    inserted, ``before (K,)`` (increasing) the number of kept rows before each inserted
    one; -1 for a dropped row."""
    r = 0
    i = 0
    for j in range(drop.shape[0]):
        if drop[j]:
            out[j] = -1
            continue
        while i < before.shape[0] and before[i] <= r:
            i += 1
        out[j] = r + i
        r += 1


@njit(parallel=True, cache=True)
def _move_rows(old, dest, out):
    for j in prange(old.shape[0]):
        d = dest[j]
        if d >= 0:
            for c in range(old.shape[1]):
                out[d, c] = old[j, c]


@njit(parallel=True, cache=True)
def _move_mapped_rows(old, dest, id_map, out):
    last = old.shape[0] - 1
    for j in prange(old.shape[0]):
        for c in range(old.shape[1]):  # the map's entries are far apart: ask for them early
            prefetch(id_map, old[min(j + AHEAD, last), c])
        d = dest[j]
        if d >= 0:
            for c in range(old.shape[1]):
                out[d, c] = id_map[old[j, c]]


@njit(parallel=True, cache=True)
def _move_around(edge_map, old_start, old_rows, leaf_pos, start, rows):
    """Per kept old edge: the new places of its kept working triangles, from the start of
    its new range."""
    last = old_rows.shape[0] - 1
    for g in prange(edge_map.shape[0]):
        d = edge_map[g]
        if d < 0:
            continue
        out = start[d]
        for k in range(old_start[g], old_start[g + 1]):
            prefetch(leaf_pos, old_rows[min(k + 2 * AHEAD, last)])
            p = leaf_pos[old_rows[k]]
            if p >= 0:
                rows[out] = p
                out += 1


@njit(cache=True)
def _merge_children(c_edge, c_leaf, start, rows):
    """Merge the children ``c_leaf`` around the edges ``c_edge`` (sorted by edge, then
    place) into the edges' lists, whose other entries fill the front of their ranges."""
    i = 0
    while i < c_edge.shape[0]:
        g = c_edge[i]
        j = i
        while j < c_edge.shape[0] and c_edge[j] == g:
            j += 1
        end = start[g + 1]
        kept = end - start[g] - (j - i)  # entries already there
        a = start[g] + kept - 1  # last kept entry
        b = j - 1  # last child
        for out in range(end - 1, start[g] - 1, -1):  # merge from the back
            if b >= i and (a < start[g] or c_leaf[b] > rows[a]):
                rows[out] = c_leaf[b]
                b -= 1
            else:
                rows[out] = rows[a]
                a -= 1
        i = j
