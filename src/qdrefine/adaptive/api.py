"""Public entry points of adaptive refinement: :func:`refine_marked`, :func:`refine_cycles`,
and the checks of their arguments."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray

from ..arguments import as_count
from ..boundaries import boundary_edges, first_bad_edge, keep_boundary
from ..jit import threads_for
from ..memory import check_needed, local_memory_needed
from ..mesh import Mesh
from ..schemes import Scheme, get_scheme
from ..uniform import check_rounding, too_close
from .edgekeys import edge_keys
from .families import Families
from .history import families_of, with_history
from .output import changed_parents, split_tagged, without_points
from .representatives import data_rows, inherited
from .step import Step
from .window import windowed_step


def is_integer_mask(ids: NDArray[np.integer], n_triangles: int) -> bool:
    """Whether triangle ids ``(K,)`` are one 0 or 1 per triangle (``K = M > 2``, so ids
    repeat): a mask stored as integers (e.g. read from a file), which as ids would mark
    triangles 0 and 1 only."""
    return ids.size == n_triangles > 2 and int(ids.min()) >= 0 and int(ids.max()) <= 1


def as_mask(marked: ArrayLike, n_triangles: int) -> NDArray[np.bool_]:
    """A boolean mask ``(M,)`` from a mask or an array of triangle indices; ``ValueError``
    for ``M > 2`` integers all 0 or 1 (a mask stored as integers, not indices), and for a
    NumPy masked array with masked entries (``np.asarray`` dropped its mask; review)."""
    if np.ma.is_masked(marked):
        raise ValueError("marked has masked entries; give a plain mask or index array (e.g. "
                         "marked.filled(False) or marked.compressed())")
    a = np.asarray(marked)
    if a.dtype == bool:
        if a.shape != (n_triangles,):
            raise ValueError(f"a boolean marked mask must have shape ({n_triangles},), "
                             f"got {a.shape}")
        return a.copy()
    if a.size == 0:
        return np.zeros(n_triangles, dtype=bool)
    if not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"marked must be a boolean mask or triangle indices, got dtype "
                         f"{a.dtype}")
    if a.ndim != 1:
        raise ValueError(f"marked indices must be one-dimensional, got shape {a.shape}")
    bad = (a < 0) | (a >= n_triangles)
    if bad.any():
        raise ValueError(f"marked index {int(a[bad][0])} is outside 0..{n_triangles - 1}")
    if is_integer_mask(a, n_triangles):
        raise ValueError(f"marked: {a.size} integers, all 0 or 1, one per triangle: a mask "
                         "stored as integers? Pass it as booleans (marked.astype(bool)) or "
                         "as indices (np.flatnonzero(marked))")
    mask = np.zeros(n_triangles, dtype=bool)
    mask[a] = True
    return mask


def refine_marked(mesh: Mesh, marked: ArrayLike, scheme: str | Scheme = "7t-qd",
                  levels: int = 1) -> tuple[Mesh, NDArray[np.int64]]:
    """Conforming local refinement of the ``marked`` triangles; see :func:`qdrefine.refine`.

    Red-green refinement with the scheme's partition as the red pattern: the marked
    triangles are partitioned, a longest-edge closure with transition ("green") patterns
    keeps the mesh conforming, and the output remembers its transitions
    (:attr:`qdrefine.Mesh.transitions`). A later call coarsens a transition before it
    refines any part of it, so cycle after cycle every triangle is a triangle of the
    uniform refinements of the input or a transition child of one (``docs/adaptive.md``).

    Parameters
    ----------
    mesh : Mesh
        May carry the history of an earlier call (``mesh.transitions``).
    marked : (M,) bool or (K,) int
        Mask or indices of the triangles to partition with ``scheme``. A marked transition
        child makes its family's parent partitioned, and the parent's children that meet
        the marked triangle and are not smaller than it are partitioned again.
    scheme : {"7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"}
    levels : int, >= 0
        With ``levels > 1`` the children of the marked triangles are marked again,
        ``levels`` times in all (of a marked transition child: the children of its
        parent's partition that meet it).

    Returns
    -------
    mesh : Mesh
        Points of ``mesh`` keep their indices, except the centroids of coarsened
        transitions, which are removed (later points move down); new points follow.
        Cell tags and ``cell_data`` are inherited (a coarsened family's new triangles:
        from the member with their vertices, else the member first in coordinate order,
        :mod:`~qdrefine.adaptive.representatives`), ``point_data`` is interpolated
        linearly, tagged edges are cut where split, physical names are kept.
    parents : (M',) int64
        The input triangle of each output triangle. Output triangles lie in it, except
        in a coarsened family: they lie in the family's parent and map to its first
        member.
    """
    sch = get_scheme(scheme)
    levels = as_count(levels, "levels")
    k = sch.stencil.per_edge
    mask = as_mask(marked, mesh.n_triangles)
    work, fam, order = families_of(mesh, k)
    if order is not None:
        mask = mask[order]
    fam_mask = np.zeros(fam.n_families, dtype=bool)
    _check_least_memory(work, mask & (fam.member < 0), sch, levels)
    parents = order  # None: the identity
    point_map = None  # input point ids -> output's, None: the identity
    boundary = boundary_edges(mesh)  # cut as the tagged edges are: checked at the end
    out = work
    for level in range(levels):
        if not (mask.any() or fam_mask.any()):
            break
        res = windowed_step(out, mask, fam_mask, sch, fam)
        if res.changed_rows is None:
            check_rounding(out.points, out.triangles, res.mesh.points, res.mesh.triangles,
                           k, res.parents, suspect=_changed(out, res))
        else:
            check_rounding(out.points, out.triangles, res.mesh.points, res.mesh.triangles,
                           k, res.parents, rows=res.changed_rows)
        rows = data_rows(out, fam, res.mesh, res.parents)
        if rows is not res.parents:  # a family's new triangles: data independent of the order
            res = replace(res, mesh=inherited(out, res.mesh, rows))
        out, fam, new_id = _finished(out, res)
        boundary = split_tagged(boundary, np.zeros(len(boundary), np.int8), res.split_keys,
                                res.split_points)[0]
        if new_id is not None:
            boundary = new_id[boundary]
        parents = res.parents if parents is None else parents[res.parents]
        if new_id is not None:
            point_map = new_id[:mesh.n_points] if point_map is None else new_id[point_map]
        if level + 1 < levels:  # the marks of the next level
            mask = res.inside & (fam.member < 0)
            fam_mask = np.zeros(fam.n_families, dtype=bool)
            fam_mask[fam.member[res.inside & (fam.member >= 0)]] = True
    if out is work:
        return mesh, np.arange(mesh.n_triangles, dtype=np.int64)
    kept = mesh.n_points if point_map is None else int((point_map >= 0).sum())
    bad = first_bad_edge(out.points, boundary, kept)  # points from ``kept`` on are new
    if bad is not None:  # rounding made the boundary cross itself: the input triangle's
        a, b = boundary[bad]
        t = out.triangles
        row = np.flatnonzero(((t == a) & (np.roll(t, -1, axis=1) == b)).any(axis=1))[0]
        raise too_close(mesh.points, mesh.triangles, int(parents[row]))
    out = with_history(out, fam, _origins(origin_rows(mesh), parents, point_map))
    keep_boundary(out, boundary)
    return out, parents


def origin_rows(mesh: Mesh) -> NDArray[np.int64]:
    """:attr:`~qdrefine.Mesh.origins` of ``mesh``, or where it has none, its triangles
    with each transition child's family parent in its place (the triangles a step
    works on: a transition's centroid can go, its parent's corners stay)."""
    if mesh.origins is not None:
        return mesh.origins
    if mesh.transitions is None:
        return mesh.triangles  # read as they are (int32 or int64)
    rows = mesh.triangles.astype(np.int64)
    green = mesh.transitions[:, 0] >= 0
    rows[green] = mesh.transitions[green]
    return rows


def _origins(rows: NDArray[np.integer], parents: NDArray[np.int64],
             point_map: NDArray[np.int64] | None) -> NDArray[np.int64]:
    """``point_map[rows[parents]]``, ``(M', 3) int64``: each output triangle's origin row
    (:func:`origin_rows` of the input, ``rows (M, 3)``) in output point ids (one compiled
    pass; NumPy's two fancy-index passes took a tenth of a scattered step); ``point_map``
    None: the ids are kept."""
    out = np.empty((parents.shape[0], 3), dtype=np.int64)
    with threads_for(parents.shape[0]):
        if point_map is None:
            _gather_rows(rows, parents, out)
        else:
            _gather_origins(rows, parents, point_map, out)
    if out.size and out.min() < 0:  # only where given origins name a removed centroid
        r = int(np.flatnonzero((out < 0).any(axis=1))[0])
        raise ValueError(f"origins: the row of input triangle {int(parents[r])} names the "
                         "centroid of a transition this refinement coarsens; origins are rows "
                         "of the mesh local refinement started from (mesh.replace(origins="
                         "None) starts the history anew)")
    return out


@njit(parallel=True, cache=True)
def _gather_origins(rows, parents, point_map, out):
    for r in prange(parents.shape[0]):
        p = parents[r]
        for j in range(3):
            out[r, j] = point_map[rows[p, j]]


@njit(parallel=True, cache=True)
def _gather_rows(rows, parents, out):
    for r in prange(parents.shape[0]):
        p = parents[r]
        for j in range(3):
            out[r, j] = rows[p, j]


def _changed(before: Mesh, res: Step) -> NDArray[np.bool_]:
    """``(M,) bool``: the input triangles whose output is not the triangle itself, as it was.

    Their children are all checked exactly for rounding (a coarsened family's children are
    not on its members' lattice, so the float suspect filter does not apply); an
    output triangle that is its parent's only child with the parent's own vertex row (the
    same points: the step keeps the input's point ids) was valid before and is skipped.
    """
    return changed_parents(res.parents, res.mesh.triangles, before.triangles)


def _check_least_memory(mesh: Mesh, plain_marked: NDArray[np.bool_], sch: Scheme,
                        levels: int) -> None:
    """``MemoryError`` before anything is allocated when even the least possible output
    cannot be emitted: every marked triangle that is not a transition child becomes at
    least ``T ** levels`` triangles (its children are marked again). The phases of each
    step check again once their sizes are known (:func:`qdrefine.memory.local_memory_needed`)."""
    marked = int(plain_marked.sum())
    if not marked or not levels:
        return
    least = mesh.n_triangles + marked * (sch.n_children ** levels - 1)
    check_needed(local_memory_needed(n_output=least),
                 f"refining {mesh.n_triangles} triangles locally ({marked} marked, "
                 f"{levels} level{'s' if levels != 1 else ''}, at least {least} triangles)")


def _finished(before: Mesh, res: Step) -> tuple[Mesh, Families, NDArray[np.int64] | None]:
    """The step's mesh with the tagged edges of ``before`` cut where split, and without
    the centroids of coarsened transitions (the other points keep their order); and the
    new id of each of the step's points (``-1``: removed), ``None`` if none was removed."""
    mesh, fam = res.mesh, res.families
    edges = edge_tags = None
    if before.edges is not None:
        edges, edge_tags = split_tagged(before.edges, before.edge_tags, res.split_keys,
                                        res.split_points)
    drop = res.centroids
    if drop.size:
        used = np.zeros(mesh.n_points, dtype=bool)
        used[mesh.triangles.reshape(-1)] = True
        drop = drop[~used[drop]]
    keep = np.ones(mesh.n_points, dtype=bool)
    keep[drop] = False
    if edges is not None and before.transitions is not None:
        _refuse_lost_tagged_edges(before, mesh, edges, keep)
    out, fam, new_id = without_points(mesh, fam, keep, edges, edge_tags)
    return out, fam, (new_id if drop.size else None)


def _refuse_lost_tagged_edges(before: Mesh, mesh: Mesh, edges: NDArray[np.int64],
                              keep: NDArray[np.bool_]) -> None:
    """``ValueError`` for a tagged edge ``(K, 2)`` (the step's numbering) between two
    triangles of a transition family of ``before`` that the step joins and refines again:
    no triangle of the step's ``mesh`` has it any more, or it ends at the family's removed
    centroid (``keep`` False). Such meshes were returned, with the edge ``(119, -1)``, and
    written to files that could not be read (review). Only edges of two old points that
    both lie on transition children are looked up (none in most steps)."""
    n = before.n_points
    on_family = np.zeros(n, dtype=bool)
    on_family[before.triangles[before.transitions[:, 0] >= 0].reshape(-1)] = True
    old = (edges < n).all(axis=1)
    suspects = np.flatnonzero(old)
    suspects = suspects[on_family[edges[suspects]].all(axis=1)]
    if not suspects.size:
        return
    ends = edges[suspects]
    lost = ~keep[ends].all(axis=1)
    near = np.zeros(mesh.n_points, dtype=bool)
    near[ends.reshape(-1)] = True
    t = mesh.triangles[near[mesh.triangles].sum(axis=1) >= 2]
    lost |= ~np.isin(edge_keys(ends[:, 0], ends[:, 1]), edge_keys(t, np.roll(t, -1, axis=1)))
    if lost.any():
        a, b = (int(v) for v in ends[np.argmax(lost)])
        raise ValueError(f"cannot refine: tagged edge ({a}, {b}) lies between two triangles "
                         "of a transition family that this step joins and refines again, so it "
                         "is no longer an edge of the mesh; tag only the family's outer edges, "
                         "or drop the history (mesh.replace(transitions=None))")


def refine_cycles(mesh: Mesh, mark: Callable[[Mesh], ArrayLike], cycles: int,
                  scheme: str | Scheme = "7t-qd") -> tuple[Mesh, NDArray[np.int64]]:
    """``cycles`` rounds of ``mesh = refine(mesh, marked=mark(mesh))``.

    Parameters
    ----------
    mesh : Mesh
    mark : callable
        ``mark(current_mesh)`` returns a mask ``(M,) bool`` or indices of the triangles to
        refine in this cycle (e.g. a :mod:`qdrefine.marking` helper with its arguments bound).
    cycles : int, >= 0
    scheme : str or Scheme

    Returns
    -------
    mesh : Mesh
        With its refinement history (:attr:`qdrefine.Mesh.transitions`).
    parents : (M',) int64
        The triangle of the input mesh each output triangle lies in.
    """
    cycles = as_count(cycles, "cycles")
    sch = get_scheme(scheme)
    parents = np.arange(mesh.n_triangles, dtype=np.int64)
    out = mesh
    for _ in range(cycles):
        out, cycle_parents = refine_marked(out, mark(out), sch)
        parents = parents[cycle_parents]
    return out, parents
