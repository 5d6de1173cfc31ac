"""Red families: the groups of triangles that are exactly a partition of one triangle of
an origin's uniform refinements, found from the points alone and checked against the
history (:attr:`qdrefine.Mesh.origins`); what :mod:`~qdrefine.adaptive.coarsen` undoes.

The corner children of a partition give its triangle's corners by the refinement's own
point formula (the trisection points are ``fl((2a + b) / 3)`` and ``fl((a + 2b) / 3)``),
so they are matched bit for bit; every child of that triangle's partition must then be a
working triangle. On a uniform lattice a group of children straddling two parents is such
a partition too: only a triangle met by descending the origin's refinements counts.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ..jit import first_row_at_or_after, threads_for
from ..mesh import Mesh
from ..numbering import edge_point, incidence
from ..partition import partition_many
from ..schemes import Scheme
from .edgekeys import oriented
from .families import Families, smallest_first
from .overlap import signed_twice_areas
from .working import emit_full, working_rows


def red_families(mesh: Mesh, fam: Families, marked: NDArray[np.bool_], sch: Scheme
                 ) -> NDArray[np.int64]:
    """The red families all of whose children are marked, as rows ``(F, 3 + 3k + T)``:
    the restored triangle ``P`` (counter-clockwise), the ``k`` points of each of its edges
    ``(v_i, v_{i+1})`` listed from ``v_i``, and the working triangles of its children
    (indices into :func:`working_rows`), in the partition's order."""
    k, t_count = sch.stencil.per_edge, sch.n_children
    if mesh.origins is None:  # no history: nothing is known to be a refinement
        return np.empty((0, 3 + 3 * k + t_count), dtype=np.int64)
    rows, owner = working_rows(mesh, fam)
    chosen = np.ones(rows.shape[0], dtype=bool)  # a working triangle: all of it marked
    member = fam.member
    plain = member < 0
    chosen[:int(plain.sum())] = marked[plain]
    if fam.n_families:
        unmarked = np.zeros(fam.n_families, dtype=bool)
        unmarked[member[~plain & ~marked]] = True
        chosen[int(plain.sum()):] = ~unmarked
    tags = None if mesh.cell_tags is None else mesh.cell_tags[owner]
    start, tris = incidence(rows, mesh.n_points)
    points = np.ascontiguousarray(mesh.points, dtype=np.float64)
    cand = np.flatnonzero(chosen)
    if not cand.size:
        return np.empty((0, 3 + 3 * k + t_count), dtype=np.int64)
    corners = np.full((cand.size, 3, 3 + 3 * k), -1, dtype=np.int64)
    with threads_for(rows.shape[0]):
        near = vertex_neighbours(points, rows, start, tris)
    with threads_for(cand.size):
        _corner_guesses(points, rows, *near, cand, k, corners)
    guess = corners.reshape(-1, 3 + 3 * k)
    guess = guess[guess[:, 0] >= 0]
    if not guess.size:
        return np.empty((0, 3 + 3 * k + t_count), dtype=np.int64)
    # one row per restored triangle: rotated to its smallest corner
    shift = np.argmin(guess[:, :3], axis=1)
    idx = (shift[:, None] + np.arange(3)) % 3
    pts = guess[:, 3:].reshape(-1, 3, k)
    guess = np.concatenate([np.take_along_axis(guess[:, :3], idx, axis=1),
                            np.take_along_axis(pts, idx[:, :, None], axis=1).reshape(-1, 3 * k)],
                           axis=1)
    guess = np.unique(guess, axis=0)
    tri3 = guess[:, :3]
    a, b = tri3, np.roll(tri3, -1, axis=1)
    from_lower = oriented(guess[:, 3:].reshape(-1, k), a.reshape(-1), b.reshape(-1))
    kids = emit_full(points, tri3, from_lower.reshape(-1, 3, k), sch)  # (G, T, 3)
    which = np.full(kids.shape[:2], -1, dtype=np.int64)
    _find_rows(rows, start, tris, kids, which)
    ok = (which >= 0).all(axis=1)
    ok[ok] = chosen[which[ok]].all(axis=1)
    if tags is not None:
        ok[ok] = (tags[which[ok]] == tags[which[ok][:, :1]]).all(axis=1)
    # the children share an origin, and the restored triangle is one of its refinements
    origin = smallest_first(mesh.origins[owner])  # a row given from another corner too
    ok[ok] = (origin[which[ok]] == origin[which[ok][:, :1]]).all(axis=(1, 2))
    ok[ok] = in_hierarchy(points, origin[which[ok][:, 0]], tri3[ok], sch)
    return np.concatenate([guess[ok], which[ok]], axis=1)


#: Deepest refinement of an origin looked through for a restored triangle.
MAX_DEPTH = 64


def in_hierarchy(points: NDArray[np.float64], origins: NDArray[np.int64],
                 rows: NDArray[np.int64], sch: Scheme) -> NDArray[np.bool_]:
    """``(G,) bool``: whether triangle ``rows[g]`` is a triangle of the uniform
    refinements of ``origins[g]`` by ``sch`` (exact: the refinements' points are made by
    the refinement's own kernels from the origin's coordinates, as the mesh's were). Each
    is followed down from its origin, into the child holding its centroid, until the
    triangle is met or the child is no larger than it. A group of children that happens
    to be a partition (on a uniform lattice, a triangle straddling two parents is one)
    is not."""
    g = rows.shape[0]
    found = np.zeros(g, dtype=bool)
    target = points[rows]  # (G, 3, 2)
    key = _sorted_corners(target)
    centre = target.mean(axis=1)
    size = signed_twice_areas(target)
    node = points[origins]
    todo = np.arange(g)
    for _ in range(MAX_DEPTH):
        if not todo.size:
            break
        same = (_sorted_corners(node) == key[todo]).all(axis=(1, 2))
        found[todo[same]] = True
        go = ~same & (signed_twice_areas(node) > size[todo] * (1 + 1e-9))
        todo, node = todo[go], node[go]
        if not todo.size:
            break
        local, kids = partition_many(node, sch, strict=False)
        corners = local[np.arange(todo.size)[:, None, None], kids]  # (K, T, 3, 2)
        inside = _contains(corners, centre[todo][:, None, :])
        hit = inside.any(axis=1)
        todo = todo[hit]
        node = corners[hit, np.argmax(inside[hit], axis=1)]
    return found


def _sorted_corners(tri: NDArray[np.float64]) -> NDArray[np.float64]:
    """The corners of each triangle ``(..., 3, 2)`` in lexicographic order."""
    order = np.lexsort((tri[..., 1], tri[..., 0]), axis=-1)
    return np.take_along_axis(tri, order[..., None], axis=-2)


def _contains(tri: NDArray[np.float64], p: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Whether the counter-clockwise triangles ``(..., 3, 2)`` hold the points ``p``
    (inside or on the boundary; ``p`` is a centroid, well inside)."""
    out = np.ones(tri.shape[:-2], dtype=bool)
    for i in range(3):
        a, b = tri[..., i, :], tri[..., (i + 1) % 3, :]
        out &= (b[..., 0] - a[..., 0]) * (p[..., 1] - a[..., 1]) \
            - (b[..., 1] - a[..., 1]) * (p[..., 0] - a[..., 0]) >= 0
    return out


def vertex_neighbours(points: NDArray[np.float64], rows: NDArray[np.int64],
                      start: NDArray[np.int64], tris: NDArray[np.int64]
                      ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """The vertices sharing a triangle of ``rows (W, 3)`` with each vertex, each once, in
    the order of their coordinates ``(x, y)`` (then of their ids), with the coordinates
    beside them: the searches around a vertex read one contiguous run and find a point
    near a given place by bisection, so a vertex of degree ``d`` costs ``O(log d)`` per
    search instead of ``O(d)`` (parallel over vertices, the same on any number of
    threads; :func:`~qdrefine.numbering.incidence` gives ``start, tris``).

    Returns
    -------
    first : (N + 1,) int64
        The neighbours of vertex ``v`` are ``ids[first[v]:first[v + 1]]``.
    ids : (first[-1],) int64
    xy : (first[-1], 2) float64
        ``points[ids]``.
    """
    n = start.shape[0] - 1
    # at most two others per incident triangle: 2 deg(v) places from 2 start[v] (6 W in all)
    room = np.empty(2 * tris.shape[0], dtype=np.int64)
    count = np.zeros(n, dtype=np.int64)
    _distinct_neighbours(rows, start, tris, room, count)
    first = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(count, out=first[1:])
    ids = np.empty(int(first[-1]), dtype=np.int64)
    xy = np.empty((ids.shape[0], 2))
    _packed_neighbours(points, start, room, first, ids, xy)
    return first, ids, xy


#: Up to this many entries are put in order by insertion, beyond it by a merge sort.
_FEW = 24


@njit(parallel=True, cache=True)
def _distinct_neighbours(rows, start, tris, room, count):
    """``room[2 start[v]:]``: the distinct other vertices of ``v``'s triangles, by id;
    ``count[v]``: how many (a sort and one pass: ``O(d log d)`` for degree ``d``)."""
    for v in prange(start.shape[0] - 1):
        base = 2 * start[v]
        c = 0
        for i in range(start[v], start[v + 1]):
            for m in range(3):
                u = rows[tris[i], m]
                if u != v:
                    room[base + c] = u
                    c += 1
        run = room[base:base + c]
        if c <= _FEW:
            for h in range(1, c):  # insertion
                u, g = run[h], h
                while g > 0 and run[g - 1] > u:
                    run[g] = run[g - 1]
                    g -= 1
                run[g] = u
        else:  # numba's quicksort is slow on these runs of pairs; merge sort is not
            run[:] = run[np.argsort(run, kind="mergesort")]
        kept = 0
        for h in range(c):
            if h == 0 or run[h] != run[h - 1]:
                run[kept] = run[h]
                kept += 1
        count[v] = kept


@njit(parallel=True, cache=True)
def _packed_neighbours(points, start, room, first, ids, xy):
    """Each vertex's run of ``room`` (by id) to ``ids[first[v]:]`` in the order of
    ``(x, y, id)``, with the coordinates."""
    for v in prange(first.shape[0] - 1):
        base, out, c = 2 * start[v], first[v], first[v + 1] - first[v]
        if c <= _FEW:
            for h in range(c):  # insertion: stable, so equal points stay by id
                u = room[base + h]
                x, y = points[u, 0], points[u, 1]
                g = out + h
                while g > out and (xy[g - 1, 0] > x or (xy[g - 1, 0] == x and xy[g - 1, 1] > y)):
                    ids[g], xy[g, 0], xy[g, 1] = ids[g - 1], xy[g - 1, 0], xy[g - 1, 1]
                    g -= 1
                ids[g], xy[g, 0], xy[g, 1] = u, x, y
            continue
        run = room[base:base + c]
        by_y = np.argsort(points[run, 1], kind="mergesort")  # stable: (x, y), then id
        order = by_y[np.argsort(points[run[by_y], 0], kind="mergesort")]
        for h in range(c):
            u = run[order[h]]
            ids[out + h], xy[out + h, 0], xy[out + h, 1] = u, points[u, 0], points[u, 1]


@njit(cache=True)
def _same_point(points, v, x, y):
    return points[v, 0] == x and points[v, 1] == y


@njit(cache=True)
def _far_corner(points, first, ids, xy, a, p, k):
    """The point ``b`` and ``b``'s-side point ``p2`` such that ``p`` (and ``p2``) are the
    points of edge ``(a, b)`` by the refinement's formula, searched two working edges
    from ``p`` (only among the points near where they would be, found by bisection, then
    exactly); ``(-1, -1)`` if there is none. ``first, ids, xy``: :func:`vertex_neighbours`."""
    dx, dy = points[p, 0] - points[a, 0], points[p, 1] - points[a, 1]
    # far below the edge, far above rounding: the exact test decides
    tol = 1e-6 * (abs(dx) + abs(dy)) + 1e-13 * (abs(points[p, 0]) + abs(points[p, 1]))
    bx, by = points[a, 0] + (k + 1) * dx, points[a, 1] + (k + 1) * dy  # b, about
    if k == 1:
        h = first_row_at_or_after(xy, first[p], first[p + 1], bx - tol, -np.inf)
        while h < first[p + 1] and xy[h, 0] <= bx + tol:
            y = ids[h]
            if y != a and abs(xy[h, 1] - by) <= tol and \
                    _same_point(points, p, edge_point(points[a, 0], points[y, 0], 0, 1),
                                edge_point(points[a, 1], points[y, 1], 0, 1)):
                return y, -1
            h += 1
        return -1, -1
    cx, cy = points[a, 0] + 2 * dx, points[a, 1] + 2 * dy  # p2, about
    h = first_row_at_or_after(xy, first[p], first[p + 1], cx - tol, -np.inf)
    while h < first[p + 1] and xy[h, 0] <= cx + tol:
        x = ids[h]
        h += 1
        if x == a or abs(xy[h - 1, 1] - cy) > tol:
            continue
        h2 = first_row_at_or_after(xy, first[x], first[x + 1], bx - tol, -np.inf)
        while h2 < first[x + 1] and xy[h2, 0] <= bx + tol:
            y = ids[h2]
            h2 += 1
            if y == a or y == p or abs(xy[h2 - 1, 1] - by) > tol:
                continue
            if _same_point(points, p, edge_point(points[a, 0], points[y, 0], 0, 2),
                           edge_point(points[a, 1], points[y, 1], 0, 2)) and \
                    _same_point(points, x, edge_point(points[a, 0], points[y, 0], 1, 2),
                                edge_point(points[a, 1], points[y, 1], 1, 2)):
                return y, x
    return -1, -1


@njit(cache=True)
def _near_point(points, first, ids, xy, b, c, j, k):
    """The working-mesh neighbour of ``b`` at point ``j`` of edge ``(b, c)`` (from ``b``),
    or -1 (by bisection of ``b``'s run)."""
    x0 = edge_point(points[b, 0], points[c, 0], j, k)
    x1 = edge_point(points[b, 1], points[c, 1], j, k)
    h = first_row_at_or_after(xy, first[b], first[b + 1], x0, x1)
    if h < first[b + 1] and xy[h, 0] == x0 and xy[h, 1] == x1:
        return ids[h]
    return -1


@njit(parallel=True, cache=True)
def _corner_guesses(points, rows, first, ids, xy, cand, k, out):
    """For each candidate working triangle and each of its vertices ``a``: if it is the
    corner child at ``a`` of a triangle ``(a, b, c)``, that triangle and its edges'
    points (from ``v_i`` along ``(v_i, v_{i+1})``) into ``out[i, j]`` (each candidate
    on its own: bit-identical on any number of threads); ``first, ids, xy``:
    :func:`vertex_neighbours`."""
    for i in prange(cand.shape[0]):
        t = cand[i]
        for j in range(3):
            a, p, q = rows[t, j], rows[t, (j + 1) % 3], rows[t, (j + 2) % 3]
            b, p2 = _far_corner(points, first, ids, xy, a, p, k)
            if b < 0:
                continue
            c, q2 = _far_corner(points, first, ids, xy, a, q, k)
            if c < 0:
                continue
            r1 = _near_point(points, first, ids, xy, b, c, 0, k)
            if r1 < 0:
                continue
            out[i, j, 0], out[i, j, 1], out[i, j, 2] = a, b, c
            if k == 1:
                out[i, j, 3], out[i, j, 4], out[i, j, 5] = p, r1, q
            else:
                r2 = _near_point(points, first, ids, xy, c, b, 0, k)
                if r2 < 0:
                    out[i, j, 0] = -1
                    continue
                out[i, j, 3], out[i, j, 4] = p, p2
                out[i, j, 5], out[i, j, 6] = r1, r2
                out[i, j, 7], out[i, j, 8] = q2, q


@njit(cache=True)
def _find_rows(rows, start, tris, kids, which):
    """``which[g, c]``: the working triangle with the vertices of ``kids[g, c]`` (in any
    rotation), -1 if none; the lowest row if several (incidence lists are in row order, so
    the list of the kid's corner of least degree is scanned)."""
    for g in range(kids.shape[0]):
        for c in range(kids.shape[1]):
            x, y, z = kids[g, c, 0], kids[g, c, 1], kids[g, c, 2]
            # scan the incidence list of the corner of least degree
            if start[y + 1] - start[y] < start[x + 1] - start[x]:
                x, y = y, x
            if start[z + 1] - start[z] < start[x + 1] - start[x]:
                x, z = z, x
            for i in range(start[x], start[x + 1]):
                t = tris[i]
                hit = 0
                for m in range(3):
                    v = rows[t, m]
                    if v == y or v == z:
                        hit += 1
                if hit == 2:
                    which[g, c] = t
                    break
