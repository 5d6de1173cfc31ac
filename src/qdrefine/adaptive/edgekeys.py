"""Integer keys of edges (pairs of point ids) and the sorted registry of split edges."""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray

from ..jit import threads_for

#: Edge key ``min * KEY + max`` of an edge between two point ids (ids below ``2**31``).
KEY = np.int64(1) << np.int64(32)


def edge_keys(a: ArrayLike, b: ArrayLike) -> NDArray[np.int64]:
    """Keys of the edges ``(a, b)`` (either orientation), same shape as ``a`` and ``b``."""
    a = np.asarray(a, dtype=np.int64)
    b = np.asarray(b, dtype=np.int64)
    return np.minimum(a, b) * KEY + np.maximum(a, b)


def edge_keys_of_rows(edges: NDArray) -> NDArray[np.int64]:
    """:func:`edge_keys` of the rows of ``edges (E, 2)`` (one compiled parallel pass)."""
    out = np.empty(edges.shape[0], dtype=np.int64)
    with threads_for(edges.shape[0]):
        _row_keys(np.ascontiguousarray(edges), out)
    return out


@njit(parallel=True, cache=True)
def _row_keys(edges, out):
    for i in prange(edges.shape[0]):
        a = np.int64(edges[i, 0])
        b = np.int64(edges[i, 1])
        out[i] = min(a, b) * KEY + max(a, b)


def lookup(keys: NDArray[np.int64], query: NDArray[np.int64]) -> NDArray[np.int64]:
    """Position of each query in the sorted ``keys``, ``-1`` where absent (a binary search
    per query, in parallel)."""
    query = np.asarray(query, dtype=np.int64)
    out = np.empty(query.shape, dtype=np.int64)
    if keys.size == 0:
        out[...] = -1
        return out
    flat = np.ascontiguousarray(query).reshape(-1)
    with threads_for(flat.shape[0]):
        _binary_lookup(keys, flat, out.reshape(-1))
    return out


@njit(parallel=True, cache=True)
def _binary_lookup(keys, query, out):
    n = keys.shape[0]
    for i in prange(query.shape[0]):
        q = query[i]
        lo, hi = 0, n
        while lo < hi:
            mid = (lo + hi) >> 1
            if keys[mid] < q:
                lo = mid + 1
            else:
                hi = mid
        out[i] = lo if lo < n and keys[lo] == q else -1


def lookup_sorted(keys: NDArray[np.int64], query: NDArray[np.int64]) -> NDArray[np.int64]:
    """:func:`lookup` for an increasing ``query`` (e.g. the keys of edges numbered in
    sorted order): one merge of the two arrays instead of a binary search per query."""
    out = np.empty(query.shape[0], dtype=np.int64)
    _merge_lookup(keys, query, out)
    return out


@njit(cache=True)
def _merge_lookup(keys, query, out):
    """:func:`lookup_sorted` into ``out``: one pass over both sorted arrays."""
    i = 0
    for q in range(query.shape[0]):
        if q and query[q] < query[q - 1]:
            raise ValueError("lookup_sorted: the queries are not increasing")
        while i < keys.shape[0] and keys[i] < query[q]:
            i += 1
        out[q] = i if i < keys.shape[0] and keys[i] == query[q] else -1


def oriented(pts: NDArray[np.int64], a: NDArray, b: NDArray) -> NDArray[np.int64]:
    """Points ``(K, k)`` of the edges ``(a, b)`` listed from the lower id, relisted from
    ``a`` (and back: reversing where ``a > b`` is its own inverse)."""
    return np.where((a < b)[:, None], pts, pts[:, ::-1])


def register(keys: NDArray[np.int64], pts: NDArray[np.int64], new_keys: NDArray[np.int64],
             new_pts: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The registry ``keys (R,)`` (sorted), ``pts (R, k)`` with edges that are not in it
    yet added: ``new_keys (N,)`` with their points ``new_pts (N, k)``."""
    keys = np.concatenate([keys, new_keys])
    order = np.argsort(keys, kind="stable")
    return keys[order], np.concatenate([pts, new_pts])[order]
