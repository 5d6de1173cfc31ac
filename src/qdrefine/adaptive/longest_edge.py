"""The longest-edge closure of a set of split edges, in rounds over whole arrays."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ..jit import threads_for
from ..numbering import incidence
from .labels import MN, OM


def closure(cedges: NDArray[np.int64], marked: NDArray[np.bool_], n_edges: int,
            presplit: NDArray[np.bool_] | None = None,
            upgrade: Callable[[NDArray[np.int64], NDArray[np.int64]], NDArray[np.bool_]]
            | None = None, layers: int = 1, earlier: NDArray[np.bool_] | None = None,
            around: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None
            ) -> tuple[NDArray[np.bool_], int]:
    """Split edges: all edges of marked triangles, closed under the longest-edge rule
    (and the upgrade rule, if given).

    Parameters
    ----------
    cedges : (M, 3) int64
        Canonical edge ids (``MN, NO, OM``) per triangle, see
        :func:`~qdrefine.adaptive.canonical_edges`.
    marked : (M,) bool
    n_edges : int
    presplit : (E,) bool, optional
        Edges that are split already (their points exist); they seed the closure too.
    upgrade : callable, optional
        ``upgrade(triangles, codes)`` says which of these triangles, whose split code
        (bits ``MN=1, NO=2, OM=4``) has ``MN`` but not ``NO``, get ``NO`` split as well.
    earlier : (E,) bool, optional
        The edges of ``presplit`` split by an earlier step (the others got their points in
        this step, e.g. by an expansion); default: all of ``presplit``. A triangle whose
        only split edges are earlier ones is not in the closure of the marks.
    layers : int
        How far upgrades may bring new triangles into the refinement: the upgrades of the
        triangles of the closure of the marks may (layer 1), then those of the triangles
        they brought in (layer 2), up to ``layers``; any later upgrade only where the
        triangle across ``NO`` is refined already (or there is none). So upgrades cannot
        cascade through a mesh (a boundary layer of thin right triangles, where every
        transition wants one).
    around : ((E + 1,), (3 M,)) int64, optional
        The triangles around every edge, :func:`edge_triangles` of ``cedges`` (e.g. read
        off the edge numbering, :func:`~qdrefine.numbering.number_edges_around`);
        computed if not given.

    Returns
    -------
    split : (E,) bool
    rounds : int
        Number of propagation rounds (each one pass over the arrays).

    The set only grows and is bounded by the edge set, so the loop ends after at most
    ``E`` rounds; in practice the rounds follow longest-edge propagation paths, whose length
    is bounded by the number of times the edge length can grow along a path.
    """
    split = np.zeros(n_edges, dtype=bool) if presplit is None else presplit.copy()
    split[cedges[marked].ravel()] = True
    if around is None:
        around = edge_triangles(cedges, n_edges)
    rounds = _propagate(split, cedges, np.flatnonzero(touching(split, cedges)), around)
    if upgrade is None:
        return split, rounds
    before = earlier if earlier is not None else (
        np.zeros(n_edges, dtype=bool) if presplit is None else presplit)
    reached = _closure_of_marks(split, before, cedges, marked)
    while True:
        cand, codes = _candidates(split, cedges)
        if not cand.size:
            break
        up = cand[upgrade(cand, codes)]
        # an upgrade outside the closure of the marks brings no new triangle in: the
        # triangles across its NO edge are refined already (or there are none)
        no = _allowed(up, cedges, reached, split, *around)
        no = np.unique(no[~split[no]])
        if not no.size:
            break
        split[no] = True
        # the closure held before: only triangles around the new edges can break it, those
        # whose longest edge is not split (the rounds count as when all were looked at)
        start, tris = around
        new = np.unique(np.concatenate([tris[start[e]:start[e + 1]] for e in no]))
        rounds += 1 + _propagate(split, cedges, new[~split[cedges[new, 0]]], around)
        layers -= 1
        if layers > 0:
            reached = _closure_of_marks(split, before, cedges, marked)
    return split, rounds


def _closure_of_marks(split: NDArray[np.bool_], presplit: NDArray[np.bool_],
                      cedges: NDArray[np.int64], marked: NDArray[np.bool_]
                      ) -> NDArray[np.bool_]:
    """``(M,) bool``: the marked triangles and those with an edge split in this step. A
    transition elsewhere has split edges too (``presplit``: those of earlier steps): it is
    not in the closure of this step's marks, so its upgrade is judged as any triangle's
    outside it (otherwise every earlier transition of the mesh could be upgraded in every
    step, however far from the marks, and a step on a window around the marks would differ
    from the step on the whole mesh)."""
    out = np.empty(cedges.shape[0], dtype=np.bool_)
    with threads_for(cedges.shape[0]):
        _reached_into(split, presplit, cedges, marked, out)
    return out


@njit(parallel=True, cache=True)
def _reached_into(split, presplit, cedges, marked, out):
    for t in prange(cedges.shape[0]):
        hit = marked[t]
        for i in range(3):
            e = cedges[t, i]
            hit = hit or (split[e] and not presplit[e])
        out[t] = hit


@njit(parallel=True, cache=True)
def _touching_into(split, cedges, out):
    for t in prange(cedges.shape[0]):
        out[t] = split[cedges[t, 0]] or split[cedges[t, 1]] or split[cedges[t, 2]]


def touching(split: NDArray[np.bool_], cedges: NDArray[np.int64]) -> NDArray[np.bool_]:
    """``(M,) bool``: triangles with a split edge."""
    out = np.empty(cedges.shape[0], dtype=np.bool_)
    with threads_for(cedges.shape[0]):
        _touching_into(split, cedges, out)
    return out


def _candidates(split: NDArray[np.bool_], cedges: NDArray[np.int64]
                ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Triangles with a split edge and ``NO`` unsplit (with the closure: ``MN`` split), in
    order, and their split codes (bits ``MN=1, NO=2, OM=4``): counted per block of
    triangles, then written from each block's offset (in parallel, the same order)."""
    m = cedges.shape[0]
    blocks = max(1, min(64, m // 16384))
    bounds = np.linspace(0, m, blocks + 1).astype(np.int64)
    counts = np.zeros(blocks + 1, dtype=np.int64)
    with threads_for(m):
        _count_candidates(split, cedges, bounds, counts)
        np.cumsum(counts, out=counts)
        cand = np.empty(counts[-1], dtype=np.int64)
        codes = np.empty(counts[-1], dtype=np.int64)
        _fill_candidates(split, cedges, bounds, counts, cand, codes)
    return cand, codes


@njit(inline="always", cache=True)
def _is_candidate(split, cedges, t):
    return not split[cedges[t, 1]] and (split[cedges[t, 0]] or split[cedges[t, 2]])


@njit(parallel=True, cache=True)
def _count_candidates(split, cedges, bounds, counts):
    """``counts[c + 1]``: candidates among triangles ``bounds[c] .. bounds[c + 1] - 1``."""
    for c in prange(bounds.shape[0] - 1):
        n = 0
        for t in range(bounds[c], bounds[c + 1]):
            if _is_candidate(split, cedges, t):
                n += 1
        counts[c + 1] = n


@njit(parallel=True, cache=True)
def _fill_candidates(split, cedges, bounds, offsets, cand, codes):
    for c in prange(bounds.shape[0] - 1):
        j = offsets[c]
        for t in range(bounds[c], bounds[c + 1]):
            if _is_candidate(split, cedges, t):
                cand[j] = t
                codes[j] = (MN if split[cedges[t, 0]] else 0) + (OM if split[cedges[t, 2]] else 0)
                j += 1


@njit(cache=True)
def _allowed(up, cedges, reached, split, start, tris):
    """The ``NO`` edges of the upgraded triangles ``up`` that may be split: the triangle
    is in the closure of the marks, or every triangle around its ``NO`` edge has a split
    edge already."""
    out = np.empty(up.shape[0], dtype=np.int64)
    n = 0
    for i in range(up.shape[0]):
        t = up[i]
        e = cedges[t, 1]
        ok = reached[t]
        if not ok:
            ok = True
            for k in range(start[e], start[e + 1]):
                u = tris[k]
                if not (split[cedges[u, 0]] or split[cedges[u, 1]] or split[cedges[u, 2]]):
                    ok = False
                    break
        if ok:
            out[n] = e
            n += 1
    return out[:n]


def _propagate(split: NDArray[np.bool_], cedges: NDArray[np.int64],
               active: NDArray[np.int64], around: tuple[NDArray, NDArray]) -> int:
    """Close ``split`` in place under the longest-edge rule (a triangle with a split edge
    has its longest edge ``MN`` split), starting from the triangles ``active``; the number
    of rounds (breadth-first levels: round ``r`` splits the edges of triangles reached in
    round ``r - 1``, as if all were done at once)."""
    start, tris = around
    return _worklist(split, cedges, start, tris, np.ascontiguousarray(active, dtype=np.int64))


def edge_triangles(cedges: NDArray[np.int64], n_edges: int) -> tuple[NDArray[np.int64],
                                                                       NDArray[np.int64]]:
    """The triangles around every edge: ``tris[start[e]:start[e + 1]]`` (CSR, ``(E + 1,)``
    and ``(3M,)`` int64), in triangle order."""
    return incidence(cedges, n_edges)


@njit(cache=True)
def _worklist(split, cedges, start, tris, active):
    # every edge is split once and queues its triangles once: the queue needs at most
    # len(active) + len(tris) places
    queue = np.empty(active.shape[0] + tris.shape[0], dtype=np.int64)
    queue[:active.shape[0]] = active
    head, tail, rounds = 0, active.shape[0], 0
    while head < tail:
        rounds += 1
        end = tail
        grew = False
        while head < end:
            e = cedges[queue[head], 0]
            head += 1
            if not split[e]:
                split[e] = True
                grew = True
                for k in range(start[e], start[e + 1]):
                    queue[tail] = tris[k]
                    tail += 1
        if not grew:
            break
    return rounds
