"""Canonical labelling ``(M, N, O)`` of triangles, their canonical edges and split codes."""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ..jit import threads_for
from ..kernels import CHUNK, canonical
from ..predicates import SCRATCH

# bit of each canonical edge in a triangle's split code
MN, NO, OM = 1, 2, 4
FULL = MN | NO | OM


@njit(parallel=True, cache=True)
def _labels(points, triangles, out):
    m = triangles.shape[0]
    n_chunks = (m + CHUNK - 1) // CHUNK
    for ch in prange(n_chunks):
        buf = np.empty(SCRATCH)
        for t in range(ch * CHUNK, min(m, (ch + 1) * CHUNK)):
            v0 = triangles[t, 0]
            v1 = triangles[t, 1]
            v2 = triangles[t, 2]
            im, jn, ko = canonical(points[v0, 0], points[v0, 1], points[v1, 0], points[v1, 1],
                                   points[v2, 0], points[v2, 1], buf)
            out[t, 0] = im
            out[t, 1] = jn
            out[t, 2] = ko


def canonical_labels(points: NDArray[np.float64], triangles: NDArray[np.integer]
                     ) -> NDArray[np.int8]:
    """Local indices ``(M, 3) int8`` of ``(M, N, O)`` for every triangle (exact, tie rules
    of :mod:`qdrefine.schemes`), the same labelling uniform refinement uses."""
    out = np.empty((triangles.shape[0], 3), dtype=np.int8)
    if triangles.shape[0]:
        with threads_for(triangles.shape[0]):
            _labels(points, triangles, out)
    return out


def canonical_edges(labels: NDArray[np.int8], tri_edges: NDArray[np.int64]
                    ) -> NDArray[np.int64]:
    """Edge ids ``(M, 3)`` of the canonical edges ``MN, NO, OM`` of each triangle.

    ``tri_edges[:, i]`` is the edge ``(v_i, v_{i+1})``, so the edge between local vertices
    ``a`` and ``b`` is column ``a`` when ``b == a + 1 (mod 3)`` and column ``b`` otherwise.
    """
    out = np.empty((labels.shape[0], 3), dtype=np.int64)
    with threads_for(labels.shape[0]):
        _canonical_edges(labels, tri_edges, out)
    return out


@njit(cache=True, inline="always")
def local_edge(a, b):
    """Local index of the edge between local vertices ``a`` and ``b`` (edge ``i`` is
    ``(v_i, v_{i+1})``)."""
    return a if b == (a + 1) % 3 else b


@njit(parallel=True, cache=True)
def _canonical_edges(labels, tri_edges, out):
    for t in prange(labels.shape[0]):
        for i in range(3):
            out[t, i] = tri_edges[t, local_edge(labels[t, i], labels[t, (i + 1) % 3])]


def edge_split_codes(split: NDArray[np.bool_], ce: NDArray[np.int64]) -> NDArray[np.int64]:
    """``split_codes(split[ce])`` in one compiled pass: the split code ``(M,)`` of triangles
    whose canonical edges ``MN, NO, OM`` are the edges ``ce (M, 3)`` and ``split (E,)``
    says which edges are split."""
    out = np.empty(ce.shape[0], dtype=np.int64)
    _edge_split_codes(split, ce, out)
    return out


@njit(parallel=True, cache=True)
def _edge_split_codes(split, ce, out):
    for t in prange(ce.shape[0]):
        out[t] = MN * split[ce[t, 0]] + NO * split[ce[t, 1]] + OM * split[ce[t, 2]]


def split_codes(split: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Split code ``(M,)`` (bits ``MN=1, NO=2, OM=4``) from ``split (M, 3)``, which says
    whether each canonical edge ``MN, NO, OM`` is split."""
    return (split * np.array([MN, NO, OM])).sum(axis=1)
