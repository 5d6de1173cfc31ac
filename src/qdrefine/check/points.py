"""Searches among the points: identical points (an error) and near-identical ones (a
warning), each by a grid bucketing that is ``O(N log N)`` on any input."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .report import KEPT, Findings

__all__ = ["NEAR_DUPLICATE", "duplicate_pairs", "near_duplicates", "duplicates",
           "near_duplicate_points"]


def duplicates(found: Findings, p: NDArray, ids: NDArray) -> None:
    count, pairs = duplicate_pairs(p, ids, KEPT)
    if count:
        a, b = (int(v) for v in pairs[np.lexsort(pairs[:, ::-1].T)[0]])
        xy = tuple(p[a].tolist())
        found.add("duplicate-points", f"points {found.point(a)} and {found.point(b)} are both "
                  f"at {xy}", count, points=[found.point(a), found.point(b)], at=list(xy))


@njit(cache=True)
def duplicate_pairs(p, ids, cap):
    """Number of points ``p[ids]`` equal to one before them, and up to ``cap`` pairs
    ``(earlier, later)``: the points are bucketed on a grid (a counting sort), each bucket is
    compared pairwise when small and sorted when large, ``O(N log N)`` at worst."""
    k = ids.shape[0]
    pairs = np.empty((cap, 2), dtype=np.int64)
    if k < 2:
        return 0, pairs[:0]
    x, y = p[ids, 0], p[ids, 1]
    x0, x1, y0, y1 = x.min(), x.max(), y.min(), y.max()
    g = max(1, int(np.sqrt(k)))
    sx = (x1 - x0) / g if x1 > x0 else 1.0
    sy = (y1 - y0) / g if y1 > y0 else 1.0
    cell = np.empty(k, dtype=np.int64)
    start = np.zeros(g * g + 1, dtype=np.int64)
    for i in range(k):
        cell[i] = min(g - 1, int((x[i] - x0) / sx)) * g + min(g - 1, int((y[i] - y0) / sy))
        start[cell[i] + 1] += 1
    for c in range(g * g):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(k, dtype=np.int64)
    for i in range(k):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    count = 0
    for c in range(g * g):
        s, e = start[c], start[c + 1]
        if e - s < 2:
            continue
        run = order[s:e]
        if e - s > 16:  # sort by x, then by y within runs of equal x
            run = run[np.argsort(x[run])]
            q = 0
            while q < e - s:
                r = q + 1
                while r < e - s and x[run[r]] == x[run[q]]:
                    r += 1
                if r - q > 1:
                    run[q:r] = run[q:r][np.argsort(y[run[q:r]])]
                q = r
            for j in range(1, e - s):
                a, b = run[j - 1], run[j]
                if x[a] == x[b] and y[a] == y[b]:
                    if count < cap:
                        pairs[count, 0], pairs[count, 1] = ids[min(a, b)], ids[max(a, b)]
                    count += 1
            continue
        for j in range(1, e - s):
            for i in range(j):
                a, b = run[i], run[j]
                if x[a] == x[b] and y[a] == y[b]:
                    if count < cap:
                        pairs[count, 0], pairs[count, 1] = ids[min(a, b)], ids[max(a, b)]
                    count += 1
                    break
    return count, pairs[:min(count, cap)]


#: Two distinct used points closer than this times the mesh's extent are near duplicates.
NEAR_DUPLICATE = 1e-12


def near_duplicate_points(found: Findings, p: NDArray, ids: NDArray) -> None:
    q = p[ids]
    if len(q) < 2:
        return
    extent = float(max(np.ptp(q[:, 0]), np.ptp(q[:, 1])))
    if not extent > 0:
        return
    tol = NEAR_DUPLICATE * extent
    count, a, b = near_duplicates(q, tol)
    if count:
        a, b = int(ids[a]), int(ids[b])
        d = float(np.hypot(*(p[a] - p[b])))
        found.add("near-duplicate-points", f"points {found.point(a)} and {found.point(b)} are "
                  f"only {d:.2g} apart ({d / extent:.2g} of the mesh's extent) at "
                  f"{tuple(p[a].tolist())}", count, points=[found.point(a), found.point(b)],
                  distance=d)


def near_duplicates(q: NDArray, tol: float) -> tuple[int, int, int]:
    """Points of ``q (K, 2)`` with another point at a distance in ``(0, tol]``: their number
    and one such pair ``(i, j)`` (rows of ``q``; ``-1`` when none).

    The points are bucketed in square cells of side ``tol / sqrt(2)`` (sorted by cell): two
    different points in one cell are near; a point alone in its cell (or with copies only)
    looks at the 24 cells at most two away, each scanned by at most 24 such points, so the
    work is ``O(K log K)`` for the sort and ``O(K)`` after it, on any input.
    """
    h = tol / np.sqrt(2.0)
    cx = np.floor((q[:, 0] - q[:, 0].min()) / h).astype(np.int64)
    cy = np.floor((q[:, 1] - q[:, 1].min()) / h).astype(np.int64)
    order = np.lexsort((cy, cx))
    return _near_scan(np.ascontiguousarray(q[order]), cx[order], cy[order], order, tol * tol)


#: Rows a lone cell walks through its sorted neighbourhood before it bisects instead.
_WALK = 32


@njit(cache=True)
def _near_neighbour(q, cx, cy, s, e, tol2):
    """A row ``j`` outside the cell ``s:e`` within ``tol`` of ``q[s]`` (``-1``: none).

    The rows whose cell is at most two columns away are contiguous around ``s:e`` in the
    (cx, cy) order: walk them outwards (usually none or a few); a crowded column (many
    points on one vertical line) is bisected per column instead."""
    j = s - 1
    while j >= 0 and cx[j] >= cx[s] - 2:
        if s - j > _WALK:
            return _near_bisect(q, cx, cy, s, e, tol2)
        if abs(cy[j] - cy[s]) <= 2 and _within(q, j, s, tol2):
            return j
        j -= 1
    j = e
    while j < cx.shape[0] and cx[j] <= cx[s] + 2:
        if j - e >= _WALK:
            return _near_bisect(q, cx, cy, s, e, tol2)
        if abs(cy[j] - cy[s]) <= 2 and _within(q, j, s, tol2):
            return j
        j += 1
    return -1


@njit(cache=True)
def _within(q, j, s, tol2):
    ddx, ddy = q[j, 0] - q[s, 0], q[j, 1] - q[s, 1]
    d2 = ddx * ddx + ddy * ddy
    return 0 < d2 <= tol2


@njit(cache=True)
def _near_bisect(q, cx, cy, s, e, tol2):
    for dx in range(-2, 3):  # a cell's side is tol / sqrt(2): two cells away
        x = cx[s] + dx
        lo = np.searchsorted(cx, x)  # the row of cells with this x
        hi = np.searchsorted(cx, x + 1)
        a = lo + np.searchsorted(cy[lo:hi], cy[s] - 2)
        b = lo + np.searchsorted(cy[lo:hi], cy[s] + 3)
        for j in range(a, b):
            if s <= j < e:
                continue
            if _within(q, j, s, tol2):
                return j
    return -1


@njit(cache=True)
def _near_scan(q, cx, cy, order, tol2):
    k = q.shape[0]
    near = np.zeros(k, dtype=np.bool_)
    first_a = first_b = -1
    s = 0
    while s < k:  # cells: runs of equal (cx, cy)
        e = s + 1
        while e < k and cx[e] == cx[s] and cy[e] == cy[s]:
            e += 1
        mixed = -1
        for i in range(s + 1, e):
            if q[i, 0] != q[s, 0] or q[i, 1] != q[s, 1]:
                mixed = i
                break
        if mixed >= 0:
            for i in range(s, e):
                near[i] = True
            if first_a < 0:
                first_a, first_b = order[s], order[mixed]
        else:  # one position: look for a different point in the neighbouring cells
            j = _near_neighbour(q, cx, cy, s, e, tol2)
            if j >= 0:
                for i in range(s, e):
                    near[i] = True
                if first_a < 0:
                    first_a, first_b = order[s], order[j]
        s = e
    return int(near.sum()), first_a, first_b
