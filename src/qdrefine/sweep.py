"""A plane sweep over the boundary edges of a triangle list: crossings, hanging nodes and
doubly covered area, with the exact orientation predicate, in ``O(B log B)`` for ``B``
edges on any input.

One concern, hence one module over 400 lines: the sweep, its treap and its exact event
order are one algorithm whose parts rely on each other's invariants.

Why the boundary suffices: interior edges are shared by two triangles walking them in
opposite directions, so the number of triangles covering a point ``q`` (its *cover*) is the
winding number of the directed boundary edges around ``q`` (each triangle lies on the left
of its boundary edges). A mesh whose triangles are counter-clockwise overlaps itself exactly
when two boundary edges cross (or run along each other in the same direction) or, where they
do not cross, when some region has a cover of 2 or more. Without crossings the cover is
constant on the region directly above a boundary edge ``s`` all along ``s``, and equals the
cover above the edge just below ``s`` plus ``+1`` (the triangle of ``s`` lies above it: ``s``
is walked from its lexicographically smaller end) or ``-1``. Every bounded region lies
directly above some boundary edge, so checking that value for every edge checks the plane.

The sweep (Shamos and Hoey's) moves a vertical line over the boundary vertices in
lexicographic order (``x``, then ``y``: vertical edges behave as if tilted slightly). The
edges it cuts are kept ordered from below in a treap (a randomized balanced search tree with
deterministic priorities); at every vertex ``v`` it

1. removes the edges ending at ``v`` and tests each pair of new neighbours for a crossing;
2. locates ``v`` among the remaining edges: an edge through ``v`` holds ``v`` strictly inside
   (a *hanging node*, non-conforming);
3. inserts the edges starting at ``v`` (the order compares a start point with an edge by one
   orientation sign, ties by the other end, then by the side the triangle lies on; two edges
   running along each other with their triangles on the same side are an overlap), tests each
   against its new neighbours for a proper crossing and sets the cover above it.

The first crossing of two edges ends the sweep: before it, the order is consistent and every
hanging node and cover is exact; at it, the sweep reports the pair (the leftmost crossing
always becomes a pair of neighbours before the line reaches it). Edges sharing an endpoint
(a vertex where several fans of triangles touch) or touching at a vertex are not crossings.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .predicates import FILTER, SCRATCH, orient_sign

__all__ = ["CROSSING", "NEAR", "SAME_SIDE", "sweep", "vertices_of"]

CROSSING = 1  #: two boundary edges cross at a point inside both
SAME_SIDE = 2  #: two boundary edges overlap along a segment with their triangles on one side
#: A vertex off a boundary edge by less than this times the edge's length, outside it, is
#: reported as *near* the edge (a crack too thin to see; the mesh is valid).
NEAR = 1e-12


def sweep(points: NDArray[np.float64], bedges: NDArray[np.integer], covers: bool,
          stop_first: bool, cap: int = 64, same_place: list[int] | None = None) -> tuple:
    """Run the sweep over the directed boundary edges ``bedges (B, 2)`` (each as walked by
    its triangle, counter-clockwise) of ``points (N, 2)``.

    Parameters
    ----------
    covers : bool
        Also check the cover above every edge (meaningful only when every triangle is
        counter-clockwise and every interior edge is walked both ways).
    stop_first : bool
        Return at the first hanging node or doubly covered region too (validation).
    cap : int
        Instances kept of hanging nodes (all are counted).
    same_place : list, optional
        Receives the first two distinct vertices at one place, if any (the sweep takes
        them for one vertex).

    Returns
    -------
    n_hanging : int
        Vertices found strictly inside a boundary edge.
    hanging : (h, 2) int64
        Up to ``cap`` of them as ``(vertex, row of bedges)``.
    crossing : (3,) int64
        ``(kind, row, row)`` of the first crossing (kind :data:`CROSSING` or
        :data:`SAME_SIDE`), ``(0, -1, -1)`` when none.
    n_covered : int
        Edges with a cover other than 0 or 1 directly above them (``covers`` only).
    first_covered : int
        Row of the first such edge, ``-1`` when none.
    n_near : int
        Vertices off the edge just above or below them by less than :data:`NEAR` times its
        length (not on it).
    nearest : (3,) float64
        ``(vertex, row, relative distance)`` of the nearest of them.
    firsts : (3,) int64
        When the first hanging node, the first doubly covered edge and the crossing were
        found (the count of tests then; ``-1``: none), so that a full report lists them in
        the order validation meets them.
    work : int
        Orientation tests made (for tests of the cost bound).
    """
    e = np.ascontiguousarray(bedges, dtype=np.int64).reshape(-1, 2)
    p = np.ascontiguousarray(points, dtype=np.float64)
    if len(e) == 0:
        return (0, np.empty((0, 2), np.int64), np.array([0, -1, -1]), 0, -1, 0,
                np.full(3, -1.0), np.full(3, -1), 0)
    verts = vertices_of(e, len(p))
    xy = np.empty(len(verts), dtype=np.complex128)  # complex numbers sort by (real, imag):
    xy.real, xy.imag = p[verts, 0], p[verts, 1]  # lexicographic, 2-3x faster than lexsort
    order = np.argsort(xy)
    xs, ys = xy.real[order], xy.imag[order]
    new = np.ones(len(order), dtype=bool)
    new[1:] = (xs[1:] != xs[:-1]) | (ys[1:] != ys[:-1])
    if same_place is not None and not new.all():
        i = int(np.flatnonzero(~new)[0])
        same_place.extend(int(v) for v in verts[order[i - 1:i + 1]])
    rank_sorted = np.cumsum(new) - 1
    rank = np.empty(len(p) if len(p) else 1, dtype=np.int64)
    rank[verts[order]] = rank_sorted
    rep = verts[order][new]  # one vertex per distinct position
    ra, rb = rank[e[:, 0]], rank[e[:, 1]]
    forward = ra < rb
    lo = np.where(forward, e[:, 0], e[:, 1])
    hi = np.where(forward, e[:, 1], e[:, 0])
    delta = np.where(forward, 1, -1).astype(np.int64)
    live = ra != rb  # a zero-length edge (duplicate points) is reported elsewhere
    rows = np.flatnonzero(live)
    n_ranks = len(rep)
    by_start, start_at = _counting_sort(rows, rank[lo[rows]], n_ranks)
    by_end, end_at = _counting_sort(rows, rank[hi[rows]], n_ranks)
    return _sweep(p, lo, hi, delta, rep, by_start, start_at, by_end, end_at, covers,
                  stop_first, cap)


def vertices_of(edges: NDArray[np.integer], n: int) -> NDArray[np.int64]:
    """The sorted distinct vertices of ``edges (B, 2)`` (indices below ``n``), by a mask:
    linear (``np.unique`` hashes or sorts, several times slower on millions)."""
    mask = np.zeros(max(n, 1), dtype=np.bool_)
    mask[edges.ravel()] = True
    return np.flatnonzero(mask)


@njit(cache=True)
def _counting_sort(rows, keys, n_keys):
    """``rows`` ordered by ``keys`` (integers below ``n_keys``, stable) and where each key's
    run starts ``(n_keys + 1,)``: linear."""
    at = np.zeros(n_keys + 1, dtype=np.int64)
    for k in keys:
        at[k + 1] += 1
    for k in range(n_keys):
        at[k + 1] += at[k]
    fill = at[:-1].copy()
    out = np.empty_like(rows)
    for i in range(rows.shape[0]):
        out[fill[keys[i]]] = rows[i]
        fill[keys[i]] += 1
    return out, at


@njit(inline="always", cache=True)
def _orient(p, a, b, cx, cy, buf):
    """:func:`qdrefine.predicates.orient_sign` of points ``a``, ``b`` of ``p`` and
    ``(cx, cy)``, its float filter inline (the call only when the filter cannot decide)."""
    ax, ay, bx, by = p[a, 0], p[a, 1], p[b, 0], p[b, 1]
    u = (bx - ax) * (cy - ay)
    w = (by - ay) * (cx - ax)
    bound = FILTER * (abs(u) + abs(w))
    if u - w > bound:
        return 1
    if u - w < -bound:
        return -1
    return orient_sign(ax, ay, bx, by, cx, cy, buf)


@njit(inline="always", cache=True)
def _priority(i):
    """A fixed pseudo-random priority (splitmix64 of the index)."""
    z = np.uint64(i) + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@njit(cache=True)
def _rotate_up(x, lc, rc, par, root):
    """Rotate node ``x`` above its parent; returns the root."""
    q = par[x]
    g = par[q]
    if lc[q] == x:
        lc[q] = rc[x]
        if rc[x] >= 0:
            par[rc[x]] = q
        rc[x] = q
    else:
        rc[q] = lc[x]
        if lc[x] >= 0:
            par[lc[x]] = q
        lc[x] = q
    par[q] = x
    par[x] = g
    if g < 0:
        return x
    if lc[g] == q:
        lc[g] = x
    else:
        rc[g] = x
    return root


@njit(cache=True)
def _neighbour(x, lc, rc, par, after):
    """In-order successor (``after``) or predecessor of node ``x``; -1 when none."""
    down, up = (rc, lc) if after else (lc, rc)
    if down[x] >= 0:
        y = down[x]
        while up[y] >= 0:
            y = up[y]
        return y
    y = x
    q = par[y]
    while q >= 0 and down[q] == y:
        y = q
        q = par[q]
    return q


@njit(cache=True)
def _crosses(p, lo, hi, a, b, buf):
    """True when edges ``a`` and ``b`` cross at a point inside both (two orientation pairs
    of strictly opposite signs)."""
    o1 = _orient(p, lo[a], hi[a], p[lo[b], 0], p[lo[b], 1], buf)
    o2 = _orient(p, lo[a], hi[a], p[hi[b], 0], p[hi[b], 1], buf)
    if o1 * o2 >= 0:
        return False
    o3 = _orient(p, lo[b], hi[b], p[lo[a], 0], p[lo[a], 1], buf)
    o4 = _orient(p, lo[b], hi[b], p[hi[a], 0], p[hi[a], 1], buf)
    return o3 * o4 < 0


@njit(cache=True)
def _found(v, y, on_edge, under, over, p, lo, hi, vx, vy, hits, near, cap, n_hang):
    """Record what the search of vertex ``v`` found: inside edge ``y`` (a hanging node), or
    between ``under`` and ``over``, maybe almost on one of them (``near`` keeps the
    nearest). Returns the numbers of hanging and near vertices found (0 or 1 each)."""
    if on_edge:
        if n_hang < cap:
            hits[n_hang, 0], hits[n_hang, 1] = v, y
        return 1, 0
    close = 0
    for e in (under, over):
        if e >= 0:
            d = _gap(p, lo[e], hi[e], vx, vy)
            if d < NEAR:
                if near[0] < 0 or d < near[2]:
                    near[0], near[1], near[2] = v, e, d
                close = 1
    return 0, close


@njit(cache=True)
def _gap(p, a, b, vx, vy):
    """Distance of ``(vx, vy)`` from the line of edge ``ab`` over the edge's length
    (float64; only compared with :data:`NEAR`)."""
    dx, dy = p[b, 0] - p[a, 0], p[b, 1] - p[a, 1]
    cross = dx * (vy - p[a, 1]) - dy * (vx - p[a, 0])
    return abs(cross) / (dx * dx + dy * dy)


@njit(cache=True)
def _sweep(p, lo, hi, delta, rep, by_start, start_at, by_end, end_at, covers, stop_first,
           cap):
    b = lo.shape[0]
    lc = np.full(b, -1, dtype=np.int64)
    rc = np.full(b, -1, dtype=np.int64)
    par = np.full(b, -1, dtype=np.int64)
    cover = np.zeros(b, dtype=np.int64)
    stamp = np.full(b, -1, dtype=np.int64)
    hits = np.empty((cap, 2), dtype=np.int64)
    crossing = np.array([0, -1, -1], dtype=np.int64)
    buf = np.empty(SCRATCH)
    root = -1
    n_near = 0
    near = np.full(3, -1.0)
    firsts = np.full(3, -1, dtype=np.int64)
    n_hang = 0
    hit = -1
    n_cov = 0
    first_cov = -1
    work = 0
    for k in range(rep.shape[0]):
        # 1. edges ending here
        for j in range(end_at[k], end_at[k + 1]):
            x = by_end[j]
            while lc[x] >= 0 or rc[x] >= 0:  # rotate x down to a leaf
                if lc[x] < 0:
                    c = rc[x]
                elif rc[x] < 0:
                    c = lc[x]
                else:
                    c = lc[x] if _priority(lc[x]) > _priority(rc[x]) else rc[x]
                root = _rotate_up(c, lc, rc, par, root)
            below = _neighbour(x, lc, rc, par, False)
            above = _neighbour(x, lc, rc, par, True)
            q = par[x]
            if q < 0:
                root = -1
            elif lc[q] == x:
                lc[q] = -1
            else:
                rc[q] = -1
            par[x] = -1
            if below >= 0 and above >= 0:
                work += 4
                if _crosses(p, lo, hi, below, above, buf):
                    crossing[0], crossing[1], crossing[2] = 1, below, above
                    firsts[2] = work
                    return (n_hang, hits[:min(n_hang, cap)], crossing, n_cov, first_cov,
                            n_near, near, firsts, work)
        # 2. the vertex against the edges that pass it: its search in the tree is the
        # descent of the first edge inserted in 3. (a search of its own without one)
        v = rep[k]
        vx, vy = p[v, 0], p[v, 1]
        under = over = -1
        on_edge = False
        if start_at[k] == start_at[k + 1]:
            y = root
            while y >= 0:
                work += 1
                o = _orient(p, lo[y], hi[y], vx, vy, buf)
                if o == 0:
                    on_edge = True
                    break
                if o > 0:
                    under = y
                    y = rc[y]
                else:
                    over = y
                    y = lc[y]
        # 3. edges starting here
        for j in range(start_at[k], start_at[k + 1]):
            s = by_start[j]
            search = j == start_at[k]
            stamp[s] = k
            q = -1
            y = root
            side = 0
            while y >= 0:
                work += 1
                o = _orient(p, lo[y], hi[y], vx, vy, buf)
                if o == 0:
                    if search:  # v inside edge y (no edge of this vertex is in yet)
                        on_edge = True
                        hit = y
                    work += 1
                    o = _orient(p, lo[y], hi[y], p[hi[s], 0], p[hi[s], 1], buf)
                    if o == 0:
                        if delta[s] == delta[y]:
                            crossing[0], crossing[1], crossing[2] = 2, y, s
                            firsts[2] = work
                            return (n_hang, hits[:min(n_hang, cap)], crossing, n_cov,
                                    first_cov, n_near, near, firsts, work)
                        o = delta[s]
                elif search:
                    if o > 0:
                        under = y
                    else:
                        over = y
                q = y
                side = o
                y = rc[y] if o > 0 else lc[y]
            if search and on_edge:
                y = hit
            if search:
                found = _found(v, y, on_edge, under, over, p, lo, hi, vx, vy, hits, near,
                               cap, n_hang)
                if found[0] and firsts[0] < 0:
                    firsts[0] = work
                n_hang += found[0]
                n_near += found[1]
                if on_edge and stop_first:
                    return (n_hang, hits[:min(n_hang, cap)], crossing, n_cov, first_cov,
                            n_near, near, firsts, work)
            par[s] = q
            if q < 0:
                root = s
            elif side > 0:
                rc[q] = s
            else:
                lc[q] = s
            ps = _priority(s)
            while par[s] >= 0 and ps > _priority(par[s]):
                root = _rotate_up(s, lc, rc, par, root)
            for nb in (_neighbour(s, lc, rc, par, False), _neighbour(s, lc, rc, par, True)):
                if nb >= 0:
                    work += 4
                    if _crosses(p, lo, hi, nb, s, buf):
                        crossing[0], crossing[1], crossing[2] = 1, nb, s
                        firsts[2] = work
                        return (n_hang, hits[:min(n_hang, cap)], crossing, n_cov, first_cov,
                                n_near, near, firsts, work)
        if start_at[k] == start_at[k + 1]:
            found = _found(v, y, on_edge, under, over, p, lo, hi, vx, vy, hits, near, cap,
                           n_hang)
            if found[0] and firsts[0] < 0:
                firsts[0] = work
            n_hang += found[0]
            n_near += found[1]
            if on_edge and stop_first:
                return (n_hang, hits[:min(n_hang, cap)], crossing, n_cov, first_cov, n_near,
                        near, firsts, work)
        if not covers:
            continue
        # covers of the new edges, each run of them from the edge below it upwards
        for j in range(start_at[k], start_at[k + 1]):
            s = by_start[j]
            below = _neighbour(s, lc, rc, par, False)
            if below >= 0 and stamp[below] == k:
                continue
            c = cover[below] if below >= 0 else 0
            x = s
            while x >= 0 and stamp[x] == k:
                c += delta[x]
                cover[x] = c
                if c < 0 or c > 1:
                    if n_cov == 0:
                        first_cov = x
                        firsts[1] = work
                    n_cov += 1
                    if stop_first:
                        return (n_hang, hits[:min(n_hang, cap)], crossing, n_cov, first_cov,
                                n_near, near, firsts, work)
                x = _neighbour(x, lc, rc, par, True)
    return (n_hang, hits[:min(n_hang, cap)], crossing, n_cov, first_cov, n_near, near, firsts,
            work)
