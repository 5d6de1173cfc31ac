"""The longest-edge closure of a set of split edges, in rounds over whole arrays."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .labels import split_codes


def closure(cedges: NDArray[np.int64], marked: NDArray[np.bool_], n_edges: int,
            presplit: NDArray[np.bool_] | None = None,
            upgrade: Callable[[NDArray[np.int64], NDArray[np.int64]], NDArray[np.bool_]]
            | None = None, layers: int = 1) -> tuple[NDArray[np.bool_], int]:
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
    layers : int
        How far upgrades may bring new triangles into the refinement: the upgrades of the
        triangles of the closure of the marks may (layer 1), then those of the triangles
        they brought in (layer 2), up to ``layers``; any later upgrade only where the
        triangle across ``NO`` is refined already (or there is none). So upgrades cannot
        cascade through a mesh (a boundary layer of thin right triangles, where every
        transition wants one).

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
    around = edge_triangles(cedges, n_edges)
    rounds = _propagate(split, cedges, np.flatnonzero(split[cedges].any(axis=1)), around)
    if upgrade is None:
        return split, rounds
    reached = split[cedges].any(axis=1)  # the closure of the marks
    incident = np.bincount(cedges.ravel(), minlength=n_edges)
    while True:
        s = split[cedges]
        active = s.any(axis=1)
        cand = np.flatnonzero(active & ~s[:, 1])
        if not cand.size:
            break
        up = cand[upgrade(cand, split_codes(s[cand]))]
        # an upgrade outside the closure of the marks brings no new triangle in: the
        # triangles across its NO edge are refined already (or there are none)
        touched = np.bincount(cedges[active].ravel(), minlength=n_edges)
        no = cedges[up, 1]
        no = no[reached[up] | (touched[no] == incident[no])]
        no = np.unique(no[~split[no]])
        if not no.size:
            break
        split[no] = True
        rounds += 1 + _propagate(split, cedges, np.flatnonzero(split[cedges[:, 1:]].any(axis=1)
                                                               & ~split[cedges[:, 0]]), around)
        layers -= 1
        if layers > 0:
            reached = split[cedges].any(axis=1)
    return split, rounds


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
    return _edge_triangles(cedges, n_edges)


@njit(cache=True)
def _edge_triangles(cedges, n_edges):
    start = np.zeros(n_edges + 1, dtype=np.int64)
    for t in range(cedges.shape[0]):
        for i in range(3):
            start[cedges[t, i] + 1] += 1
    for e in range(n_edges):
        start[e + 1] += start[e]
    fill = start[:-1].copy()
    tris = np.empty(start[n_edges], dtype=np.int64)
    for t in range(cedges.shape[0]):
        for i in range(3):
            e = cedges[t, i]
            tris[fill[e]] = t
            fill[e] += 1
    return start, tris


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
