"""The output of one step: the children of every working triangle in input order, the
output's families, and the tagged edges cut where they were split."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from ..fields import centroid_value, edge_value
from ..memory import check_needed, local_memory_needed
from ..mesh import Mesh, index_dtype
from .edgekeys import KEY, edge_keys, lookup, oriented, register
from .families import Families
from .labels import FULL
from .patterns import (
    PARTIAL,
    canonical_corners,
    choose,
    pattern,
    stencil_coordinates,
    stencil_ids,
    tables,
    uses_centroid,
)
from .plan import SplitPlan
from .rounds import new_points, unchanged
from .working import StepInput, Tree, emit_full


def emit_step(inp: StepInput, tree: Tree, cl: SplitPlan
              ) -> tuple[Mesh, NDArray[np.int64], Families, NDArray[np.bool_],
                         NDArray[np.bool_]]:
    """Children of every working triangle, in input order; unchanged families are copied.
    Returns ``(mesh, parents, families, inside, again, (keys, pts))`` (see ``step.step``);
    the mesh has no tagged edges (:func:`split_tagged` cuts them with the split edges
    ``keys (R,)``, ``pts (R, k)``)."""
    k, mesh = inp.k, inp.mesh
    points, ep = new_points(tree, cl, k)
    code = cl.codes()
    keep = unchanged(inp, tree, cl, code)
    nk = np.ones(code.shape[0], dtype=np.int64)
    nk[code == FULL] = inp.sch.n_children
    chosen = []  # (working triangles, code, candidate, stencil coordinates)
    for c in PARTIAL:
        sel = np.flatnonzero((code == c) & ~keep)
        if sel.size:
            coords = stencil_coordinates(canonical_corners(points, cl.triangles[sel],
                                                           cl.labels[sel]), k)
            choice = choose(coords, k, c)[0]
            nk[sel] = tables(k, c)[2][choice]
            chosen.append((sel, c, choice, coords))
    kept = np.flatnonzero(keep)
    kept_fam = tree.fam[cl.leaves[kept]]
    nk[kept] = inp.counts[kept_fam]
    start = np.concatenate([[0], np.cumsum(nk)])
    check_needed(local_memory_needed(n_output=int(start[-1])),
                 f"local refinement: emitting {int(start[-1])} triangles")
    tris = np.empty((int(start[-1]), 3), dtype=np.int64)
    parents = np.repeat(tree.key[cl.leaves], nk)

    _place_unchanged(tris, start, cl.triangles, code)
    full = np.flatnonzero(code == FULL)
    if full.size:
        kids = emit_full(points, cl.triangles[full], ep[cl.tri_edges[full]], inp.sch)
        tris[blocks(start[full], nk[full])] = kids.reshape(-1, 3)
    new_fam = []  # (working triangles, stencils)
    centroids = [points]
    centroid_of = []  # canonical corners (C, 3) of each new centroid, in id order
    n_points = points.shape[0]
    for sel, c, choice, coords in chosen:
        ids = stencil_ids(cl.triangles[sel], cl.labels[sel], cl.ce[sel], ep, k)
        if k == 2:  # the centroid, a new point where the chosen pattern uses it
            used = uses_centroid(k, c, choice)
            x = np.full((sel.size, 1), -1, dtype=np.int64)
            x[used, 0] = n_points + np.arange(int(used.sum()))
            n_points += int(used.sum())
            centroids.append(coords[used, -1])
            centroid_of.append(ids[used, :3])
            ids = np.concatenate([ids, x], axis=1)
        pattern(ids, cl.labels[sel], k, c, choice, tris, start[sel])
        new_fam.append((sel, ids))
    points = np.concatenate(centroids) if len(centroids) > 1 else points
    rows = blocks(start[kept], nk[kept])
    olds = blocks(inp.first[kept_fam], nk[kept])
    tris[rows] = mesh.triangles[olds]
    parents[rows] = olds
    families = _families(cl.triangles, start, nk, new_fam, kept, kept_fam, inp.fam)

    dtype = index_dtype(points.shape[0])
    cell_tags = None if mesh.cell_tags is None else mesh.cell_tags[parents]
    new = cl.split & ~cl.pre
    keys, pts = register(tree.reg_keys, tree.reg_pts, cl.keys[new], ep[new])
    point_data = {}
    if mesh.point_data:
        corners = np.concatenate(centroid_of) if centroid_of else np.empty((0, 3), np.int64)
        point_data = new_point_data(mesh.point_data, mesh.n_points, keys, pts, corners)
    cell_data = {name: value[parents] for name, value in mesh.cell_data.items()}
    out = Mesh._trusted(points, tris.astype(dtype), cell_tags, None, None, point_data,
                        cell_data, mesh.physical_names)
    inside = np.repeat(tree.user[cl.leaves] & ~keep, nk)
    again = np.repeat(tree.again[cl.leaves] & (code != FULL), nk)  # done when partitioned
    return out, parents, families, inside, again, (keys, pts)


@njit(cache=True)
def _place_unchanged(tris, start, triangles, code):
    """``tris[start[i]] = triangles[i]`` for every working triangle ``i`` of code 0 (one
    pass; most of the mesh in a step with scattered marks)."""
    for i in range(code.shape[0]):
        if code[i] == 0:
            for j in range(3):
                tris[start[i], j] = triangles[i, j]


def new_point_data(data: dict, n: int, keys: NDArray[np.int64], pts: NDArray[np.int64],
                   corners: NDArray[np.int64]) -> dict:
    """Point fields extended to the new points: on an edge ``(a, b)`` the refinement's own
    formula (``(2 f_a + f_b) / 3``, ``(f_a + 2 f_b) / 3``; ``(f_a + f_b) / 2`` for one point
    per edge), at a centroid the mean of the three corners, so linear fields stay exact to
    rounding. ``keys, pts`` are the split edges and their points (from the lower id), ids
    ``>= n`` new; ``corners (C, 3)`` are the corners of the new centroids, numbered after
    the edge points. An edge's ends may be new points themselves (edges of the children
    of a partitioned transition): values are filled in rounds, ends first."""
    k = pts.shape[1]
    a, b = keys // KEY, keys % KEY
    new = pts[:, 0] >= n
    a, b, ids = a[new], b[new], pts[new]
    total = n + ids.size + corners.shape[0]
    out = {}
    for name, f in data.items():
        # as uniform refinement (qdrefine.fields): floating fields keep their dtype
        v = np.zeros((total,) + f.shape[1:], dtype=f.dtype if f.dtype.kind == "f" else
                     np.float64)
        v[:n] = f
        known = np.zeros(total, dtype=bool)
        known[:n] = True
        todo_e = np.ones(a.size, dtype=bool)
        todo_c = np.ones(corners.shape[0], dtype=bool)
        while todo_e.any() or todo_c.any():
            ready = todo_e & known[a] & known[b]
            r = np.flatnonzero(ready)
            for j in range(k):
                v[ids[r, j]] = edge_value(v[a[r]], v[b[r]], j, k)
            known[ids[r].reshape(-1)] = True
            todo_e &= ~ready
            c = np.flatnonzero(todo_c & known[corners].all(axis=1))
            v[n + ids.size + c] = centroid_value(v[corners[c, 0]], v[corners[c, 1]],
                                                 v[corners[c, 2]])
            known[n + ids.size + c] = True
            todo_c[c] = False
            if not (r.size or c.size):
                raise RuntimeError("internal error: a new point's data depends on itself")
        out[name] = v
    return out


def blocks(start: NDArray[np.int64], size: NDArray[np.int64]) -> NDArray[np.int64]:
    """Concatenated ranges ``start[i] .. start[i] + size[i] - 1``."""
    total = int(size.sum())
    offset = np.arange(total) - np.repeat(np.cumsum(size) - size, size)
    return np.repeat(start, size) + offset


def _families(rows: NDArray[np.int64], start: NDArray[np.int64], nk: NDArray[np.int64],
              new: list[tuple[NDArray[np.int64], NDArray[np.int64]]], kept: NDArray[np.int64],
              kept_fam: NDArray[np.int64], old: Families) -> Families:
    """The output's families: the new transitions and the copied ones, by position."""
    items = np.concatenate([s for s, _ in new] + [kept]).astype(np.int64)
    parent = np.concatenate([rows[s] for s, _ in new] + [old.parent_triangles[kept_fam]])
    sten = np.concatenate([ids for _, ids in new] + [old.stencil[kept_fam]])
    order = np.argsort(items)
    items, parent, sten = items[order], parent[order], sten[order]
    member = np.full(int(start[-1]), -1, dtype=np.int64)
    _fill_members(start, nk, items, member)
    # valid by construction: each family's members are its triangle's consecutive children
    return Families.trusted(member, parent.reshape(-1, 3),
                            sten.reshape(-1, old.stencil.shape[1]))


@njit(cache=True)
def _fill_members(start, nk, items, member):
    """``member[start[i]:start[i] + nk[i]] = f`` for each family ``f`` of working triangle
    ``i = items[f]``."""
    for f in range(items.shape[0]):
        i = items[f]
        for r in range(start[i], start[i] + nk[i]):
            member[r] = f


def without_points(mesh: Mesh, fam: Families, keep: NDArray[np.bool_],
                   edges: NDArray | None, edge_tags: NDArray | None
                   ) -> tuple[Mesh, Families, NDArray[np.int64]]:
    """``mesh`` and ``fam`` with only the points ``keep (N,)`` (in their order), tagged
    ``edges`` (``mesh``'s point ids) and ``edge_tags`` set; and the new id of every point
    ``(N + 1,)``, ``-1`` for removed ones and at the end (so ``-1`` stays ``-1``)."""
    new_id = np.full(keep.shape[0] + 1, -1, dtype=np.int64)
    new_id[:-1][keep] = np.arange(int(keep.sum()))
    dtype = index_dtype(int(keep.sum()))
    if edges is not None:
        edges = new_id[edges].astype(dtype)
    if keep.all():
        out = Mesh._trusted(mesh.points, mesh.triangles, mesh.cell_tags, edges, edge_tags,
                            mesh.point_data, mesh.cell_data, mesh.physical_names)
        return out, fam, new_id
    point_data = {name: v[keep] for name, v in mesh.point_data.items()}
    out = Mesh._trusted(mesh.points[keep], new_id[mesh.triangles].astype(dtype),
                        mesh.cell_tags, edges, edge_tags, point_data, mesh.cell_data,
                        mesh.physical_names)
    return out, Families.trusted(fam.member, new_id[fam.parent_triangles],
                                 new_id[fam.stencil]), \
        new_id


def split_tagged(edges: NDArray, tags: NDArray, keys: NDArray[np.int64],
                  pts: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Cut every tagged edge ``a -> b`` that has points (``keys``, ``pts`` from the lower
    id) into pieces with its tag and direction, again until no piece has points."""
    e, t = edges.astype(np.int64), np.asarray(tags)
    k = pts.shape[1] if pts.ndim == 2 else 1
    while e.size:
        pos = lookup(keys, edge_keys(e[:, 0], e[:, 1]))
        hit = pos >= 0
        if not hit.any():
            break
        a, b = e[hit, 0], e[hit, 1]
        chain = np.column_stack([a, oriented(pts[pos[hit]], a, b), b])
        size = np.where(hit, k + 1, 1)
        start = np.cumsum(size) - size
        out = np.empty((int(size.sum()), 2), dtype=np.int64)
        out[start[~hit]] = e[~hit]
        out[blocks(start[hit], size[hit])] = np.stack([chain[:, :-1], chain[:, 1:]],
                                                      axis=2).reshape(-1, 2)
        e, t = out, np.repeat(t, size)
    return e, t


def changed_parents(parents: NDArray[np.int64], children: NDArray, triangles: NDArray,
                    to_global: NDArray[np.int64] | None = None) -> NDArray[np.bool_]:
    """``(M,) bool``: the input triangles ``triangles (M, 3)`` whose output is not the
    triangle itself: more than one child, or a child ``children (M', 3)`` (its parent
    ``parents (M',)``) with another vertex row, its ids mapped by ``to_global`` if given
    (a window's ids to the mesh's)."""
    changed = np.ones(triangles.shape[0], dtype=bool)
    ids = np.empty(0, dtype=np.int64) if to_global is None else to_global
    _mark_unchanged(parents, children, triangles, ids,
                    np.zeros(triangles.shape[0], dtype=np.int64), changed)
    return changed


@njit(cache=True)
def _mark_unchanged(parents, children, triangles, to_global, count, changed):
    """``changed[p] = False`` for every parent ``p`` whose only child is its own row (two
    passes over the output: counts, then the rows of the only children)."""
    for r in range(parents.shape[0]):
        count[parents[r]] += 1
    mapped = to_global.shape[0] > 0
    for r in range(parents.shape[0]):
        p = parents[r]
        if count[p] != 1:
            continue
        same = True
        for j in range(3):
            v = to_global[children[r, j]] if mapped else children[r, j]
            same = same and v == triangles[p, j]
        if same:
            changed[p] = False
