"""Coarsening: undo the partitions whose children are all marked, and keep the mesh
conforming with the transitions the remaining points need.

The *red families* (:mod:`~qdrefine.adaptive.red_families`: working triangles, transition
families counted as their parents, that are exactly the scheme's partition of a triangle
``P`` of an origin's uniform refinements) whose children are all marked (a transition
parent: all its members marked) and carry one cell tag are replaced by ``P``. Then, as in
a refinement step (:mod:`~qdrefine.adaptive.step`), a closure decides which edges keep
their points: those whose other side is finer (its pieces are working edges), closed
under the longest-edge rule, with the upgrade rule where the ``NO`` edge has its points
already, so no edge gets new points; the transitions are chosen as a refinement would
choose them (one that uses its centroid gets it as a new point, at the end, as in a
refinement step). A ``P`` with an edge whose pieces have points too (a neighbour two
levels finer) keeps its children (the step's conflict rule). Points no triangle uses any
more are removed (later points move down), tagged edges are joined again across them.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from ..memory import check_needed, local_memory_needed
from ..mesh import Mesh, index_dtype, need_mesh
from ..schemes import Scheme, get_scheme
from .api import as_mask
from .edgekeys import edge_keys, lookup, oriented
from .families import Families
from .history import families_of, with_history
from .longest_edge import closure
from .output import blocks, emit_step, without_points
from .plan import SplitPlan, working_edges
from .red_families import red_families
from .representatives import data_rows, first_in_coordinate_order, inherited, same_triangles
from .rounds import UPGRADE_LAYERS, Upgrades, conflicts, one_sided_pieces
from .working import Tree, start, working_rows


def coarsen(mesh: Mesh, marked: ArrayLike, scheme: str | Scheme = "7t-qd") -> Mesh:
    """Undo the partitions whose children are all marked: the inverse of
    ``refine(mesh, scheme, marked=...)``, for time-dependent problems whose refined
    region moves.

    Parameters
    ----------
    mesh : Mesh
        With its history (:attr:`~qdrefine.Mesh.origins`, set by local refinement and
        kept by every refinement and by files that hold cell data): only triangles of
        the uniform refinements of an origin are restored. Without it nothing changes.
    marked : (M,) bool or (K,) int
        Mask or indices of the triangles that may go. A partition is undone when all its
        children are marked (a child refined by a transition: all of the transition's
        triangles) and carry one cell tag; one level per call.
    scheme : {"7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"}
        The scheme the mesh was refined with.

    Returns
    -------
    Mesh
        Conforming: the restored triangles and their neighbours get the transitions the
        remaining points need, chosen as refinement chooses them (no edge gets new
        points; a transition that uses its centroid gets it as a new point, after the
        others). A restored triangle with a neighbour two levels finer keeps its
        children, each with its own cell data (a child that was a transition family:
        its member's that comes first in coordinate order). Points no triangle uses any more are
        removed (the others keep their order); tags, tagged edges (joined again), cell
        data (a restored triangle's: that of the child whose vertices come first in
        coordinate order, so independent of the triangle order), point data
        and the history are kept. ``coarsen(refine(m,
        marked=k), all)`` is ``m`` again, with the history added. Details:
        ``docs/adaptive.md``, "Coarsening".

    Raises
    ------
    ValueError
        For a mesh whose transitions do not fit ``scheme`` (refined with another one),
        and for a tagged edge that cannot be joined again.
    """
    return coarsen_marked(mesh, marked, scheme)[0]


def coarsen_marked(mesh: Mesh, marked: ArrayLike, scheme: str | Scheme = "7t-qd"
                   ) -> tuple[Mesh, NDArray[np.int64]]:
    """:func:`coarsen`, also returning ``parents (M',) int64``: an input triangle of each
    output triangle (a restored triangle maps to its child with the lowest row, a
    transition to its family's first member; their cell data: see
    :mod:`~qdrefine.adaptive.representatives`)."""
    need_mesh(mesh, "coarsen")
    sch = get_scheme(scheme)
    mask = as_mask(marked, mesh.n_triangles)
    check_needed(local_memory_needed(n_working=mesh.n_triangles, n_output=mesh.n_triangles),
                 f"coarsening {mesh.n_triangles} triangles")
    work, fam, order = families_of(mesh, sch.stencil.per_edge)
    if order is not None:
        mask = mask[order]
    base = np.arange(mesh.n_triangles, dtype=np.int64) if order is None else order
    found = red_families(work, fam, mask, sch)
    if not found.shape[0]:
        return mesh, np.arange(mesh.n_triangles, dtype=np.int64)
    out, parents = _coarsened(work, fam, found, sch)
    return out, base[parents]


def _coarsened(mesh: Mesh, fam: Families, found: NDArray[np.int64], sch: Scheme
               ) -> tuple[Mesh, NDArray[np.int64]]:
    """The mesh with the red families ``found`` (rows of :func:`red_families`) restored,
    closed; ``parents`` in ``mesh``'s triangle order."""
    k = sch.stencil.per_edge
    owner = working_rows(mesh, fam)[1]
    n_plain = int((fam.member < 0).sum())
    children = found[:, 3 + 3 * k:]
    # the mesh triangles that go: plain children, and the members of children's families
    gone = np.zeros(mesh.n_triangles, dtype=bool)
    child_plain = children[children < n_plain]
    gone[owner[child_plain]] = True
    child_fam = children[children >= n_plain] - n_plain
    dropped = np.zeros(fam.n_families + 1, dtype=bool)  # the last: "no family"
    dropped[child_fam] = True
    gone |= dropped[fam.member]
    dropped = dropped[:-1]
    # each restored triangle takes the place of its first mesh triangle, and the cell data
    # of the one that comes first in coordinate order
    first_of = owner[children].min(axis=1)
    kept = np.flatnonzero(~gone)
    position = np.concatenate([kept, first_of])
    order = np.argsort(position, kind="stable")
    stands_for = position[order]  # the input triangle each coarse row stands for
    data_of = np.concatenate([kept, _representatives(mesh, fam, children, n_plain)])[order]
    coarse_rows = np.concatenate([mesh.triangles[kept].astype(np.int64),
                                  found[:, :3]])[order]
    # families that stay, renumbered in their order (members stay consecutive)
    member = np.concatenate([fam.member[kept], np.full(found.shape[0], -1)])[order]
    stay = np.flatnonzero(~dropped)
    renum = np.full(fam.n_families + 1, -1, dtype=np.int64)
    renum[stay] = np.arange(stay.size)
    coarse_fam = Families(renum[member], fam.parent_triangles[stay], fam.stencil[stay])
    dtype = index_dtype(mesh.n_points)
    tags = None if mesh.cell_tags is None else mesh.cell_tags[data_of]
    cell_data = {name: v[data_of] for name, v in mesh.cell_data.items()}
    coarse = Mesh._trusted(mesh.points, coarse_rows.astype(dtype), tags, None, None,
                           mesh.point_data, cell_data, mesh.physical_names)
    no = np.zeros(coarse.n_triangles, dtype=bool)
    inp, tree, _ = start(coarse, no, np.zeros(coarse_fam.n_families, dtype=bool), sch,
                         coarse_fam)
    # every edge that has points: the input's transitions' and the restored triangles'
    keys, pts = fam.registry()
    tri3 = found[:, :3]
    a, b = tri3.reshape(-1), np.roll(tri3, -1, axis=1).reshape(-1)
    restored_pts = oriented(found[:, 3:3 + 3 * k].reshape(-1, k), a, b)
    all_keys = np.concatenate([keys, edge_keys(a, b)])
    all_keys, first = np.unique(all_keys, return_index=True)
    tree.reg_keys = all_keys
    tree.reg_pts = np.concatenate([pts.reshape(-1, k), restored_pts])[first]
    tree.earlier_keys = all_keys
    upgrades = Upgrades(inp, tree)
    while True:
        cl = _coarse_plan(tree, upgrades)
        if not conflicts(inp, tree, cl):  # a restored triangle with a neighbour two
            break  # levels finer keeps its children (it is expanded again)
    if (cl.split & ~cl.pre).any():
        raise RuntimeError("qdrefine internal error: coarsening split an edge without points")
    out, parents, fam2, _, _, _ = emit_step(inp, tree, cl)
    data = data_of[data_rows(coarse, inp.fam, out, parents)]
    restored = order[parents] >= kept.size  # children of a restored (or re-expanded) row
    parents = stands_for[parents]
    gone_rows = np.flatnonzero(gone)
    same = same_triangles(out.points, out.triangles[restored], mesh.points,
                          mesh.triangles[gone_rows])
    # a re-expanded family's children are the input's: each stands for itself (its cell
    # data, its origin), not for the family's first child
    again = np.flatnonzero(restored)[same >= 0]
    parents[again] = data[again] = gone_rows[same[same >= 0]]
    # a child that was a transition family comes back as its parent: it stands for a member
    # (the first in coordinate order, as refinement's rule), not for a triangle beside it
    rest = np.flatnonzero(restored)[same < 0]
    whole = same_triangles(out.points, out.triangles[rest], mesh.points,
                           fam.parent_triangles[child_fam])
    if (whole >= 0).any():
        rest, whole = rest[whole >= 0], whole[whole >= 0]
        parents[rest] = data[rest] = _family_representatives(mesh, fam, child_fam[whole])
    if mesh.cell_data or mesh.cell_tags is not None:  # emitted with the coarse rows' data
        out = inherited(mesh, out, data)
    origins = mesh.origins[parents]
    return _without_unused(mesh, _origin_rows(out, fam2, origins), fam2, origins), parents


def _representatives(mesh: Mesh, fam: Families, children: NDArray[np.int64], n_plain: int
                     ) -> NDArray[np.int64]:
    """For each restored triangle (its working children ``(F, T)``, plain ones first, then
    families), the mesh triangle among those it replaces that comes first in coordinate
    order (:mod:`~qdrefine.adaptive.representatives`)."""
    owner = working_rows(mesh, fam)[1]
    restored = np.repeat(np.arange(children.shape[0]), children.shape[1])
    flat = children.ravel()
    plain = flat < n_plain
    families = flat[~plain] - n_plain
    counts = fam.counts()[families]
    rows = np.concatenate([owner[flat[plain]], blocks(fam.first()[families], counts)])
    group = np.concatenate([restored[plain], np.repeat(restored[~plain], counts)])
    return first_in_coordinate_order(mesh.points, mesh.triangles, rows, group)[1]


def _family_representatives(mesh: Mesh, fam: Families, families: NDArray[np.int64]
                            ) -> NDArray[np.int64]:
    """For each of ``families``, its member that comes first in coordinate order."""
    counts = fam.counts()[families]
    rows = blocks(fam.first()[families], counts)
    group = np.repeat(np.arange(families.size), counts)
    return first_in_coordinate_order(mesh.points, mesh.triangles, rows, group)[1]


def _origin_rows(out: Mesh, fam: Families, origins: NDArray[np.int64]) -> Mesh:
    """``out`` with every triangle that is its own origin (its row rotated) written
    as the origin's row, its rotation included (a restored triangle's row otherwise starts
    at its canonical first vertex), so that coarsening everything gives the input's rows
    back; ``origins (M', 3)`` in ``out``'s point ids."""
    rows = out.triangles
    rotations = [np.roll(origins, shift, axis=1) for shift in (1, 2)]
    # a rotation of the row, never a reflection: the origin row is counter-clockwise too
    same = ((rows == rotations[0]).all(axis=1) | (rows == rotations[1]).all(axis=1)) \
        & (fam.member < 0)
    if not same.any():
        return out
    rows = rows.copy()
    rows[same] = origins[same]
    return Mesh._trusted(out.points, rows, out.cell_tags, out.edges, out.edge_tags,
                         out.point_data, out.cell_data, out.physical_names)


def _coarse_plan(tree: Tree, upgrades: Upgrades) -> SplitPlan:
    """The split edges of the coarse working mesh: those whose other side is finer (their
    pieces are working edges), closed under the longest-edge rule, with upgrades only
    where the ``NO`` edge has its points already."""
    cl = working_edges(tree)
    hanging = np.zeros(cl.edges.shape[0], dtype=bool)
    cand, sub = one_sided_pieces(tree, cl)
    hanging[cand[(lookup(cl.keys, sub) >= 0).any(axis=1)]] = True
    leaves, ce, has_points = cl.leaves, cl.ce, cl.pre

    def upgrade(t: NDArray[np.int64], code: NDArray[np.int64]) -> NDArray[np.bool_]:
        return upgrades(leaves[t], code) & has_points[ce[t, 1]]

    n_edges = cl.edges.shape[0]
    cl.split, _ = closure(ce, np.zeros(leaves.size, dtype=bool), n_edges, presplit=hanging,
                          upgrade=upgrade, layers=UPGRADE_LAYERS,
                          earlier=np.zeros(n_edges, dtype=bool), around=cl.around)
    return cl


def _without_unused(before: Mesh, out: Mesh, fam: Families, origins: NDArray[np.int64]
                    ) -> Mesh:
    """``out`` without the points no triangle uses (the others keep their order), its
    tagged edges those of ``before`` joined across the removed points, its history
    (``fam``, ``origins`` in ``out``'s point ids)."""
    used = np.zeros(out.n_points, dtype=bool)
    used[out.triangles.reshape(-1)] = True
    before_used = np.zeros(before.n_points, dtype=bool)
    before_used[before.triangles.reshape(-1)] = True
    used[:before.n_points] |= ~before_used  # points that were never in a triangle
    edges = edge_tags = None
    if before.edges is not None:
        edges, edge_tags = _joined(before.edges.astype(np.int64), before.edge_tags,
                                   ~used[:before.n_points])
    mesh, fam, new_id = without_points(out, fam, used, edges, edge_tags)
    return with_history(mesh, fam, new_id[origins])


def _joined(edges: NDArray[np.int64], tags: NDArray, removed: NDArray[np.bool_]
            ) -> tuple[NDArray[np.int64], NDArray]:
    """Tagged edges joined across the ``removed`` points: ``a -> v`` and ``v -> b`` with
    one tag become ``a -> b`` in the first piece's row, as refinement had cut them (the
    next row first, as refinement lists the pieces; any other piece from ``v`` with that
    tag otherwise; an edge in two groups, two tags, is two chains). Pieces that another
    tool turned around (``v -> a``, e.g. each edge listed as ``(min, max)``) are joined
    too, once the chains as refinement cut them are found: through a removed point, a
    chain goes on by a piece of its tag that ends there; the joined edge keeps the
    direction of its row's piece."""
    if not removed[edges.reshape(-1)].any():
        return edges, tags
    tags = np.asarray(tags)
    rows = np.arange(edges.shape[0])
    by_start = np.lexsort((rows, tags, edges[:, 0]))
    by_end = np.lexsort((rows, tags, edges[:, 1]))
    out = np.empty_like(edges)
    keep = np.zeros(edges.shape[0], dtype=bool)
    bad = _join(edges, tags.astype(np.int64), removed, by_start, by_end, out, keep)
    if bad >= 0:
        raise ValueError(f"cannot coarsen: tagged edge {bad} ({edges[bad, 0]}, "
                         f"{edges[bad, 1]}) meets a point that coarsening removes, where no "
                         "other tagged edge of its tag goes on")
    return out[keep], tags[keep]


@njit(cache=True)
def _next_piece(edges, side, tags, order, used, v, tag):
    """An unused edge whose end ``side`` (0: start, 1: end) is ``v``, with ``tag``
    (``order``: rows by that end, then tag), or -1."""
    lo, hi = 0, order.shape[0]
    while lo < hi:  # the first row with (end, tag) >= (v, tag)
        mid = (lo + hi) // 2
        r = order[mid]
        if edges[r, side] < v or (edges[r, side] == v and tags[r] < tag):
            lo = mid + 1
        else:
            hi = mid
    while lo < order.shape[0]:
        r = order[lo]
        if edges[r, side] != v or tags[r] != tag:
            break
        if not used[r]:
            return r
        lo += 1
    return -1


@njit(cache=True)
def _join(edges, tags, removed, by_start, by_end, out, keep):
    """Chains of tagged edges through removed points into ``out`` (the first piece's row,
    ``keep``): first as refinement cut them (each piece from where the last one ended),
    then, among the pieces left, also through pieces turned around; the first edge that
    fits no chain, or -1."""
    n = edges.shape[0]
    used = np.zeros(n, dtype=np.bool_)
    chain = np.empty(n, dtype=np.int64)
    for turned in (False, True):
        for i in range(n):
            if used[i]:
                continue
            a, end, flipped = edges[i, 0], edges[i, 1], False
            if removed[a]:
                if not turned or removed[end]:
                    continue  # a later piece of a chain
                a, end, flipped = end, a, True  # a last piece turned around: walk back
            used[i] = True
            k, last = 0, i
            while removed[end]:
                j = last + 1
                if not (j < n and not used[j] and edges[j, 0] == end and tags[j] == tags[i]):
                    j = _next_piece(edges, 0, tags, by_start, used, end, tags[i])
                if j >= 0:
                    nxt = edges[j, 1]
                elif turned:
                    j = _next_piece(edges, 1, tags, by_end, used, end, tags[i])
                    nxt = edges[j, 0] if j >= 0 else -1
                if j < 0:
                    break
                used[j] = True
                chain[k] = j
                k += 1
                end, last = nxt, j
            if removed[end]:  # the chain stops at a removed point
                if turned:
                    return i
                used[i] = False  # left to the second pass
                for q in range(k):
                    used[chain[q]] = False
                continue
            if flipped:
                out[i, 0], out[i, 1] = end, a
            else:
                out[i, 0], out[i, 1] = a, end
            keep[i] = True
    for i in range(n):
        if not used[i]:
            return i
    return -1
