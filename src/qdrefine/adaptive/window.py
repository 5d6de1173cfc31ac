"""Work proportional to the marks: a step runs on a window of the mesh around the marked
triangles, grown until no edge on the window's rim is split (and no transition waiting for
an upgrade is across it), and the result is stitched into the untouched rest.

The step's decisions are local (closure along split edges, patterns by a triangle's own
shape), so on a window whose rim keeps all its edges unsplit the step does exactly what it
does on the whole mesh, with one exception: a transition that an earlier step left waiting
for an upgrade is upgraded once the triangle across its ``NO`` edge changes, so such a
transition across the rim grows the window too. The window's points are renumbered in
increasing global order, so split edges, new points and centroids come out in the same
order too, and the stitched result is identical to the whole-mesh step (tested). The
window starts from an estimate of what the step reaches (:mod:`~qdrefine.adaptive.reach`)
on a mesh without transitions, from two vertex rings around the marks otherwise. The only
passes over the whole mesh are linear: the vertex-to-triangle table, the estimate's flags
(a few passes over ``(M,)`` arrays), the rings (by vertex flags), a changed flag per
triangle for the rim check on a mesh with transitions, and the copy of the untouched
triangles.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ..jit import threads_for
from ..memory import check_needed, local_memory_needed
from ..mesh import Mesh, index_dtype
from ..numbering import incidence
from ..schemes import Scheme
from .edgekeys import KEY, edge_keys, lookup
from .families import Families
from .output import changed_parents
from .reach import reached_triangles
from .rounds import waiting_upgrades
from .step import Step, step

#: Below this many triangles the step runs on the whole mesh.
WHOLE_BELOW = 20_000
#: A window holding more than this fraction of the mesh is given up for the whole mesh
#: (scattered marks: every retry would cost nearly a whole step).
WHOLE_ABOVE = 0.3


def windowed_step(mesh: Mesh, marked: NDArray[np.bool_], fam_marked: NDArray[np.bool_],
                  sch: Scheme, fam: Families) -> Step:
    """:func:`~qdrefine.adaptive.step.step` on a window around the marks, stitched."""
    m = mesh.n_triangles
    if m < WHOLE_BELOW:
        return step(mesh, marked, fam_marked, sch, fam)
    seed = marked.copy()
    seed[fam.member >= 0] |= fam_marked[fam.member[fam.member >= 0]]
    if seed.sum() > WHOLE_ABOVE * m:  # any window would be given up
        return step(mesh, marked, fam_marked, sch, fam)
    # the vertex-to-triangle table: built first without history, else once a window is tried
    start = tris_of = verdicts = None
    if fam.n_families == 0:
        # an estimate of what the step reaches (a few triangles per mark, while two rings
        # around scattered marks cover much of the mesh)
        start, tris_of = vertex_triangles(mesh.triangles, mesh.n_points)
        window, verdicts = reached_triangles(mesh, seed, sch, start, tris_of)
    else:
        window = _grown(mesh.triangles, mesh.n_points, seed, 2)
    while True:
        window = _whole_families(window, fam)
        if window.sum() > WHOLE_ABOVE * m:
            return step(mesh, marked, fam_marked, sch, fam, verdicts)
        if start is None:
            start, tris_of = vertex_triangles(mesh.triangles, mesh.n_points)
        res, verts = _sub_step(mesh, window, marked, fam_marked, sch, fam, verdicts)
        to_global = np.concatenate([verts, mesh.n_points
                                    + np.arange(res.mesh.n_points - verts.size)])
        registry = _global_registry(res, to_global)
        rim = _rim_to_grow(mesh, start, tris_of, window, registry[0], to_global, res, fam,
                           sch)
        if not rim.any():
            return _stitched(mesh, window, verts, to_global, res, fam, registry)
        window |= _grown(mesh.triangles, mesh.n_points, rim, 2)


def vertex_triangles(triangles: NDArray, n_points: int
                     ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Triangles around each vertex: ``tris_of[start[v]:start[v + 1]]`` (increasing)."""
    return incidence(triangles, n_points)


@njit(cache=True)
def _ring(triangles, inside, touched, out):
    """``out``: the triangles of ``inside`` and those sharing a vertex with one (two passes
    over the triangles; ``touched``, one flag per point, comes in all False)."""
    for t in range(triangles.shape[0]):
        if inside[t]:
            for j in range(3):
                touched[triangles[t, j]] = True
    for t in range(triangles.shape[0]):
        out[t] = inside[t] or touched[triangles[t, 0]] or touched[triangles[t, 1]] \
            or touched[triangles[t, 2]]


def _grown(triangles: NDArray, n_points: int, window: NDArray[np.bool_], rings: int
           ) -> NDArray[np.bool_]:
    """``window`` with ``rings`` layers of triangles sharing a vertex with it added (linear
    passes: no vertex-to-triangle table, so that a window too large to use costs little)."""
    for _ in range(rings):
        out = np.empty_like(window)
        _ring(triangles, window, np.zeros(n_points, dtype=bool), out)
        window = out
    return window


def _whole_families(window: NDArray[np.bool_], fam: Families) -> NDArray[np.bool_]:
    """``window`` with every family that has a member in it complete."""
    member = fam.member
    hit = np.zeros(fam.n_families + 1, dtype=bool)
    hit[member[window & (member >= 0)]] = True
    hit[-1] = False
    return window | hit[member]


def _sub_step(mesh: Mesh, window: NDArray[np.bool_], marked: NDArray[np.bool_],
              fam_marked: NDArray[np.bool_], sch: Scheme, fam: Families,
              verdicts: NDArray[np.int8] | None = None) -> tuple[Step, NDArray[np.int64]]:
    """The step on the window's triangles, with its points renumbered in increasing
    global order; returns the step and the window's points ``verts`` (global ids).
    ``verdicts (M, 2)``: upgrade verdicts known for a mesh without families."""
    rows = np.flatnonzero(window)
    tris = mesh.triangles[rows]
    in_window = np.zeros(mesh.n_points, dtype=bool)
    in_window[tris.reshape(-1)] = True
    verts = np.flatnonzero(in_window)  # increasing: the window's points in global order
    to_local = np.full(mesh.n_points + 1, -1, dtype=np.int64)  # -1 stays -1
    to_local[verts] = np.arange(verts.size)
    local = to_local[tris].astype(index_dtype(verts.size))
    point_data = {name: v[verts] for name, v in mesh.point_data.items()}
    cell_data = {name: v[rows] for name, v in mesh.cell_data.items()}
    tags = None if mesh.cell_tags is None else mesh.cell_tags[rows]
    sub = Mesh._trusted(mesh.points[verts], local, tags, None, None, point_data, cell_data,
                        mesh.physical_names)
    member = fam.member[rows]
    used = np.unique(member[member >= 0])
    new_fam = np.full(fam.n_families + 1, -1, dtype=np.int64)
    new_fam[used] = np.arange(used.size)
    sub_fam = Families(new_fam[member], to_local[fam.parent_triangles[used]],
                       to_local[fam.stencil[used]])
    known = None if verdicts is None else verdicts[rows]
    return step(sub, marked[rows], fam_marked[used], sch, sub_fam, known), verts


def _rim_to_grow(mesh: Mesh, start: NDArray[np.int64], tris_of: NDArray[np.int64],
                 window: NDArray[np.bool_], split_keys: NDArray[np.int64],
                 to_global: NDArray[np.int64], res: Step, fam: Families, sch: Scheme
                 ) -> NDArray[np.bool_]:
    """Triangles outside the window where the whole mesh's step may differ from the
    window's: across a rim edge that the step split (its split edges' keys ``split_keys``,
    sorted, in global ids), and waiting transitions across a rim edge from a triangle that
    the step changed (:func:`~qdrefine.adaptive.rounds.waiting_upgrades`: the whole mesh's
    step upgrades them, while the window's does not see them)."""
    triangles = mesh.triangles
    if not (fam.n_families and sch.stencil.per_edge == 2):  # only split rim edges matter
        out = np.zeros(window.shape[0], dtype=bool)
        _across_split(triangles, start, tris_of, window, split_keys, out)
        return out
    rows = np.flatnonzero(window)
    t = triangles[rows].astype(np.int64)
    a, b = t.reshape(-1), np.roll(t, -1, axis=1).reshape(-1)
    keys, count = np.unique(edge_keys(a, b), return_counts=True)
    once = keys[count == 1]
    inner = np.full(once.size, -1, dtype=np.int64)
    outer = np.full(once.size, -1, dtype=np.int64)
    _rim_sides(triangles, start, tris_of, window, once // KEY, once % KEY, inner, outer)
    across = outer >= 0  # not on the mesh's boundary
    is_split = lookup(split_keys, once) >= 0
    out = np.zeros(window.shape[0], dtype=bool)
    out[outer[across & is_split]] = True
    if fam.n_families and sch.stencil.per_edge == 2:
        changed = np.zeros(window.shape[0], dtype=bool)
        changed[rows] = changed_parents(res.parents, res.mesh.triangles, t, to_global)
        cand = across & ~is_split
        cand[cand] = changed[inner[cand]] & (fam.member[outer[cand]] >= 0)
        idx = np.flatnonzero(cand)
        waiting = waiting_upgrades(mesh.points, fam, fam.member[outer[idx]], once[idx], sch)
        out[outer[idx[waiting]]] = True
    return out


@njit(cache=True)
def _across_split(triangles, start, tris_of, window, keys, out):
    """``out[u] = True`` for every triangle ``u`` outside the window across a rim edge
    that is split (``keys``: the split edges' keys; those between two of the mesh's points
    are looked up in the vertex-to-triangle table, in key order)."""
    n = start.shape[0] - 1
    for e in range(keys.shape[0]):
        a, b = keys[e] // KEY, keys[e] % KEY
        if b >= n:  # a new point: not an edge of the mesh
            continue
        inside, outside = False, -1
        for s in range(start[a], start[a + 1]):
            t = tris_of[s]
            if triangles[t, 0] == b or triangles[t, 1] == b or triangles[t, 2] == b:
                if window[t]:
                    inside = True
                else:
                    outside = t
        if inside and outside >= 0:
            out[outside] = True


@njit(cache=True)
def _rim_sides(triangles, start, tris_of, window, a, b, inner, outer):
    """For each rim edge ``(a[e], b[e])`` (``a, b (E,)``): the triangle inside the window
    with that edge into ``inner (E,)`` and the one outside into ``outer (E,)`` (both come
    in -1; ``outer[e]`` stays -1 on the mesh's boundary)."""
    for e in range(a.shape[0]):
        for i in range(start[a[e]], start[a[e] + 1]):
            t = tris_of[i]
            for j in range(3):
                if triangles[t, j] == b[e]:
                    if window[t]:
                        inner[e] = t
                    else:
                        outer[e] = t


def _stitched(mesh: Mesh, window: NDArray[np.bool_], verts: NDArray[np.int64],
              to_global: NDArray[np.int64], res: Step, fam: Families,
              registry: tuple[NDArray[np.int64], NDArray[np.int64]]) -> Step:
    """The whole mesh's step from the window's: untouched triangles copied, the window's
    output in their place (input order), its new points after the mesh's points;
    ``registry``: the window's split edges in global ids (:func:`_global_registry`)."""
    sub = res.mesh
    n_sub = verts.size
    rows = np.flatnonzero(window)
    if res.parents.size > 1 and (res.parents[1:] < res.parents[:-1]).any():
        # _place_window takes each window triangle's children as one run, in order
        raise RuntimeError("internal error: the window's step listed its children out of "
                           "parent order")
    per_row = np.bincount(res.parents, minlength=rows.size)
    sub_first = np.concatenate([[0], np.cumsum(per_row)])
    first = np.empty(mesh.n_triangles, dtype=np.int64)  # output row of each triangle's first
    total = _output_rows(window, per_row, first)
    check_needed(local_memory_needed(n_output=total),
                 f"local refinement: emitting {total} triangles")
    # families: the untouched ones keep their members, the window's come from the step,
    # all numbered by first member (the window holds whole families: a family's members
    # are all outside or all inside, and the outside ones keep their order)
    new_fam = res.families
    old = np.empty(0, dtype=np.int64)
    old_first = old
    if fam.n_families:
        fam_first = fam.first()
        old = np.flatnonzero(~window[fam_first])
        old_first = first[fam_first[old]]
    sub_head = new_fam.first()
    new_first = first[rows[res.parents[sub_head]]] - sub_first[res.parents[sub_head]] \
        + sub_head
    ids = np.concatenate([old, fam.n_families + np.arange(new_fam.n_families)])
    order = np.argsort(np.concatenate([old_first, new_first]), kind="stable")
    renum = np.full(fam.n_families + new_fam.n_families, -1, dtype=np.int64)
    renum[ids[order]] = np.arange(ids.size)
    rows_all = np.concatenate([fam.parent_triangles[old],
                               to_global[new_fam.parent_triangles]])
    sten_all = np.concatenate([fam.stencil[old],
                               np.where(new_fam.stencil >= 0,
                                        to_global[np.maximum(new_fam.stencil, 0)], -1)])

    parents = np.empty(total, dtype=np.int64)
    points = np.concatenate([mesh.points, sub.points[n_sub:]])
    dtype = index_dtype(points.shape[0])
    tris = np.empty((total, 3), dtype=dtype)
    member = np.empty(total, dtype=np.int64)
    inside = np.empty(total, dtype=bool)
    out_rows = np.empty(sub.n_triangles, dtype=np.int64)
    changed = np.empty(rows.size, dtype=bool)
    with threads_for(mesh.n_triangles):
        _copy_outside(window, first, mesh.triangles, fam.member, renum, tris, parents,
                      member, inside)
        _place_window(first, rows, sub_first, sub.triangles, to_global, new_fam.member,
                      renum[fam.n_families:], res.inside, mesh.triangles, tris, parents,
                      member, inside, out_rows, changed)
    tags = None
    if mesh.cell_tags is not None:
        tags = mesh.cell_tags[parents]
    cell_data = {}
    if mesh.cell_data:
        keep = np.flatnonzero(~window)
        for name, v in mesh.cell_data.items():
            c = np.empty((total,) + v.shape[1:], dtype=v.dtype)
            c[first[keep]] = v[keep]
            c[out_rows] = sub.cell_data[name]
            cell_data[name] = c
    point_data = {name: np.concatenate([v.astype(sub.point_data[name].dtype, copy=False),
                                        sub.point_data[name][n_sub:]])
                  for name, v in mesh.point_data.items()}
    out = Mesh._trusted(points, tris, tags, None, None, point_data, cell_data,
                        mesh.physical_names)
    families = Families.trusted(member, rows_all[order], sten_all[order])
    # the children of the changed window triangles (checked for rounding exactly)
    return Step(out, parents, families, inside, to_global[res.centroids], *registry,
                out_rows[changed[res.parents]])


@njit(cache=True)
def _output_rows(window, per_row, first):
    """``first[t]``: the output row of triangle ``t``'s first child (one row for a triangle
    outside the window, ``per_row[p]`` for the ``p``-th window triangle); the total."""
    r = 0
    p = 0
    for t in range(window.shape[0]):
        first[t] = r
        if window[t]:
            r += per_row[p]
            p += 1
        else:
            r += 1
    return r


@njit(parallel=True, cache=True)
def _copy_outside(window, first, triangles, member, renum, tris, parents, member_out,
                  inside):
    """Each triangle outside the window to its output row ``first[t]``: its vertex row,
    itself as parent, its family renumbered by ``renum`` (one parallel pass; most of the
    mesh when marks are scattered)."""
    for t in prange(window.shape[0]):
        if not window[t]:
            r = first[t]
            for j in range(3):
                tris[r, j] = triangles[t, j]
            parents[r] = t
            f = member[t]
            member_out[r] = renum[f] if f >= 0 else -1
            inside[r] = False


@njit(parallel=True, cache=True)
def _place_window(first, rows, sub_first, sub_triangles, to_global, sub_member, renum,
                  sub_inside, triangles, tris, parents, member, inside, out_rows, changed):
    """The output triangles ``sub_first[p] .. sub_first[p + 1] - 1`` of the window's step
    (the children of window triangle ``p``, its parents being increasing) to the rows from
    ``first[rows[p]]`` on: their vertices in global ids, their parent, their family
    renumbered by ``renum``, their inside flag; ``changed[p]``: whether they are not the
    triangle itself, ``triangles[rows[p]]`` (parallel over the window's triangles)."""
    for p in prange(rows.shape[0]):
        r = first[rows[p]] - sub_first[p]
        same = sub_first[p + 1] - sub_first[p] == 1
        for i in range(sub_first[p], sub_first[p + 1]):
            out_rows[i] = r + i
            for j in range(3):
                v = to_global[sub_triangles[i, j]]
                tris[r + i, j] = v
                same = same and v == triangles[rows[p], j]
            parents[r + i] = rows[p]
            f = sub_member[i]
            member[r + i] = renum[f] if f >= 0 else -1
            inside[r + i] = sub_inside[i]
        changed[p] = not same


def _global_registry(res: Step, to_global: NDArray[np.int64]
                     ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    lo, hi = res.split_keys // KEY, res.split_keys % KEY
    keys = to_global[lo] * KEY + to_global[hi]
    order = np.argsort(keys)
    return keys[order], to_global[res.split_points][order]
