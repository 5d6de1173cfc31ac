"""The refinement history a mesh carries (:attr:`qdrefine.Mesh.transitions`) as transition
families, and back.

A mesh stores, for each triangle made by a transition pattern, the vertex row of the
triangle the pattern replaced. That is all a later call needs: the family's members are the
triangles with the same row, and which edges the pattern split (and with which points) is
recovered from the members' vertices, whose coordinates are the refinement's own formula
applied to the parent's vertices, so they are matched exactly.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from ..jit import threads_for
from ..mesh import Mesh
from .edgekeys import oriented
from .families import Families, family_spans, smallest_first
from .labels import canonical_labels
from .patterns import canonical_corners, pattern_stencil, stencil_coordinates
from .working import with_edge_points


class HistoryMismatch(ValueError):
    """A mesh's refinement history (:attr:`~qdrefine.Mesh.transitions`) does not fit its
    points for the scheme at hand: made by a scheme with other points, or changed since.
    ``detail`` says what and where; ``triangle``, where given, is the row of the mesh
    it names, put in place of ``{triangle}`` in ``template``."""

    def __init__(self, template: str, triangle: int | None = None) -> None:
        self.template = template
        self.triangle = triangle
        self.detail = template if triangle is None else template.format(triangle=triangle)
        super().__init__(f"transitions: {self.detail} (refine and coarsen with the scheme "
                         "the mesh was refined with, or drop the history: "
                         "mesh.replace(transitions=None))")


def families_of(mesh: Mesh, k: int) -> tuple[Mesh, Families, NDArray[np.int64] | None]:
    """Transition families of ``mesh`` for a scheme with ``k`` points per edge.

    Returns
    -------
    mesh : Mesh
        ``mesh``, its triangles reordered so that each family's members are consecutive
        (only when they are not already, e.g. after a file round trip in another order).
    families : Families
    order : (M,) int64 or None
        Input triangle of each row of the returned mesh; ``None`` when not reordered.

    Raises
    ------
    HistoryMismatch
        A ``ValueError``: a family's members do not tile its parent with the pattern points
        the refinement would have made (a history that does not belong to these points).
    """
    rows = mesh.transitions
    m = mesh.n_triangles
    if rows is None or not (rows[:, 0] >= 0).any():
        return mesh, Families.empty(m, k), None
    kept = _kept_families(mesh, k)
    if kept is not None:
        return mesh, kept, None
    green = np.flatnonzero(rows[:, 0] >= 0)
    parent_rows, family = _unique_rows(smallest_first(rows[green]))
    first = np.full(parent_rows.shape[0], m, dtype=np.int64)
    np.minimum.at(first, family, green)
    key = np.arange(m, dtype=np.int64)
    key[green] = first[family]
    order = np.argsort(key, kind="stable")
    if (order == np.arange(m)).all():
        order = None
    else:
        mesh = _reordered(mesh, order)
        green = np.flatnonzero(mesh.transitions[:, 0] >= 0)
        parent_rows, family = _unique_rows(smallest_first(mesh.transitions[green]))
    # families numbered by first member, as the refinement numbers them
    first = np.full(parent_rows.shape[0], m, dtype=np.int64)
    np.minimum.at(first, family, green)
    rank = np.empty_like(first)
    rank[np.argsort(first)] = np.arange(first.size)
    member = np.full(m, -1, dtype=np.int64)
    member[green] = rank[family]
    parent_rows = parent_rows[np.argsort(first)]
    try:
        stencil = _stencils(mesh, parent_rows, member, k)
        _check_tiling(mesh.triangles, member, stencil, k)
    except HistoryMismatch as exc:
        if order is None or exc.triangle is None:
            raise
        raise HistoryMismatch(exc.template, int(order[exc.triangle])) from None
    return mesh, Families(member, parent_rows, stencil), order


def with_history(mesh: Mesh, families: Families, origins: NDArray | None = None) -> Mesh:
    """``mesh`` with :attr:`~qdrefine.Mesh.transitions` set from ``families`` (``None``
    when no triangle is a transition child) and :attr:`~qdrefine.Mesh.origins` to
    ``origins``."""
    member = families.member
    rows = None
    if families.n_families:
        rows = np.empty((member.size, 3), dtype=np.int64)
        with threads_for(member.size):
            _parent_rows(member, families.parent_triangles, rows)
    out = Mesh._trusted(mesh.points, mesh.triangles, mesh.cell_tags, mesh.edges,
                        mesh.edge_tags, mesh.point_data, mesh.cell_data,
                        mesh.physical_names, rows, origins=origins)
    if families.n_families:
        # what families_of would rebuild from the rows (their rotation included), kept for
        # the next call on this mesh: rebuilding took 0.21 s of a 2 s scattered second
        # cycle on the 864k L-shape (docs/adaptive.md, "Cost")
        kept = Families.trusted(member, smallest_first(families.parent_triangles),
                                families.stencil)
        object.__setattr__(out, "_families", kept)
    return out


def _kept_families(mesh: Mesh, k: int) -> Families | None:
    """The families :func:`with_history` kept on ``mesh`` for a scheme with ``k`` points per
    edge, or None: none kept, another ``k``, or an array of the mesh writeable now (an
    array changed in place and locked again is not seen: meshes are immutable)."""
    kept = mesh.__dict__.get("_families")
    if kept is None or kept.per_edge != k or kept.member.shape[0] != mesh.n_triangles:
        return None
    if any(a.flags.writeable for a in (mesh.points, mesh.triangles, mesh.transitions)):
        return None
    return kept


@njit(parallel=True, cache=True)
def _parent_rows(member, parent_triangles, rows):
    """``rows[t]``: the parent row of member ``t``'s family, ``-1`` for other triangles."""
    for t in prange(member.shape[0]):
        f = member[t]
        for j in range(3):
            rows[t, j] = parent_triangles[f, j] if f >= 0 else -1


def _unique_rows(rows: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """``np.unique(rows, axis=0, return_inverse=True)`` for ``rows (R, 3)`` of ids, by one
    ``lexsort`` (``unique`` with an axis sorts rows as opaque records, several times
    slower). Equal rows usually come in runs (a family's members are consecutive): only
    the runs' rows are sorted then."""
    run = np.ones(rows.shape[0], dtype=bool)
    run[1:] = (rows[1:] != rows[:-1]).any(axis=1)
    heads = np.flatnonzero(run)
    uniq, inverse = _sorted_unique_rows(rows[heads])
    if uniq.shape[0] == heads.size:  # no row in two runs
        return uniq, inverse[np.cumsum(run) - 1]
    return _sorted_unique_rows(rows)


def _sorted_unique_rows(rows: NDArray[np.int64]) -> tuple[NDArray[np.int64],
                                                          NDArray[np.int64]]:
    """:func:`_unique_rows` by sorting every row."""
    order = np.lexsort((rows[:, 2], rows[:, 1], rows[:, 0]))
    srt = rows[order]
    new = np.ones(srt.shape[0], dtype=bool)
    new[1:] = (srt[1:] != srt[:-1]).any(axis=1)
    inverse = np.empty(srt.shape[0], dtype=np.int64)
    inverse[order] = np.cumsum(new) - 1
    return srt[new], inverse


def _reordered(mesh: Mesh, order: NDArray[np.int64]) -> Mesh:
    cell_data = {k: v[order] for k, v in mesh.cell_data.items()}
    tags = None if mesh.cell_tags is None else mesh.cell_tags[order]
    origins = None if mesh.origins is None else mesh.origins[order]
    return Mesh._trusted(mesh.points, mesh.triangles[order], tags, mesh.edges,
                         mesh.edge_tags, mesh.point_data, cell_data, mesh.physical_names,
                         mesh.transitions[order], origins=origins)


def _stencils(mesh: Mesh, parent_rows: NDArray[np.int64], member: NDArray[np.int64],
              k: int) -> NDArray[np.int64]:
    """Each family's pattern stencil ``(F, S)``: its canonical corners, and the members'
    other vertices matched to the points the refinement makes on the parent."""
    f = parent_rows.shape[0]
    width = len(pattern_stencil(k).names)
    labels = canonical_labels(mesh.points, parent_rows)
    corners = np.take_along_axis(parent_rows, labels.astype(np.int64), axis=1)
    # the points refinement would put on the parent's edges, and its centroid
    expected = np.empty((f, width - 3, 2))
    for e in range(3):
        a, b = corners[:, e], corners[:, (e + 1) % 3]
        ends = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
        pts, ids = with_edge_points(mesh.points, ends, k)
        ids = oriented(ids, a, b)
        expected[:, k * e: k * (e + 1)] = pts[ids]
    if width - 3 > 3 * k:
        expected[:, -1] = stencil_coordinates(canonical_corners(mesh.points, parent_rows,
                                                                labels), k)[:, -1]
    stencil = np.full((f, width), -1, dtype=np.int64)
    stencil[:, :3] = corners
    tri = np.flatnonzero(member >= 0)
    fam = np.repeat(member[tri], 3)
    vert = mesh.triangles[tri].astype(np.int64).reshape(-1)
    # (family, vertex) pairs as one key: f * n + v < F * N <= 2^31 * 2^31, no overflow
    n = max(mesh.n_points, 1)
    pairs = np.sort(fam * n + vert)  # nearly sorted already: families by first member
    pairs = pairs[np.r_[True, pairs[1:] != pairs[:-1]]]
    fam, vert = pairs // n, pairs % n
    corner = (corners[fam] == vert[:, None]).any(axis=1)
    fam, vert = fam[~corner], vert[~corner]
    hit = (mesh.points[vert][:, None, :] == expected[fam]).all(axis=2)  # (P, S - 3)
    found = hit.any(axis=1)
    if not found.all():
        bad = int(np.flatnonzero(member == fam[~found][0])[0])
        raise HistoryMismatch(f"triangle {{triangle}} is marked as a transition child, but "
                              f"point {int(vert[~found][0])} is not a point the refinement "
                              "makes on its parent", bad)
    stencil[fam, 3 + np.argmax(hit, axis=1)] = vert
    edge_pts = stencil[:, 3: 3 + 3 * k].reshape(f, 3, k)
    if ((edge_pts >= 0).any(axis=2) != (edge_pts >= 0).all(axis=2)).any():
        bad = int(np.flatnonzero(((edge_pts >= 0).any(axis=2)
                                  != (edge_pts >= 0).all(axis=2)).any(axis=1))[0])
        raise HistoryMismatch("the family of triangle {triangle} has an edge with only some "
                              "of its points", int(np.flatnonzero(member == bad)[0]))
    return stencil


def _check_tiling(triangles: NDArray[np.integer], member: NDArray[np.int64],
                  stencil: NDArray[np.int64], k: int) -> None:
    """Raise :class:`HistoryMismatch` unless the members of each family cover its parent:
    the edges that only one member of a family has must be exactly the parent's boundary,
    cut at the points of its split edges (``stencil (F, S)``). The mesh has no overlaps,
    so members whose free edges run along the parent's boundary fill it; a member removed
    (a submesh cut out of a refined mesh) leaves free edges inside it."""
    first, _, count = family_spans(member, stencil.shape[0])
    bad = _uncovered(triangles, first, count, stencil, k)
    if bad >= 0:
        raise HistoryMismatch("the family of triangle {triangle} does not cover the triangle "
                              "it replaced (a member was removed or added since the "
                              "refinement)", int(first[bad]))


@njit(cache=True)
def _uncovered(triangles, first, count, stencil, k):
    """The first family (members ``first[f] ..``, ``count[f]`` of them, consecutive) whose
    members' free edges are not its parent's boundary segments, or -1."""
    most = 3 * max(1, count.max()) if count.size else 3
    lo = np.empty(most, dtype=np.int64)
    hi = np.empty(most, dtype=np.int64)
    chain = np.empty(k + 2, dtype=np.int64)
    for f in range(first.shape[0]):
        n = 3 * count[f]
        for i in range(count[f]):
            for j in range(3):
                a = np.int64(triangles[first[f] + i, j])
                b = np.int64(triangles[first[f] + i, (j + 1) % 3])
                lo[3 * i + j] = min(a, b)
                hi[3 * i + j] = max(a, b)
        free = 0  # edges of one member only
        for i in range(n):
            shared = False
            for j in range(n):
                if j != i and lo[j] == lo[i] and hi[j] == hi[i]:
                    shared = True
                    break
            if not shared:
                free += 1
        segments = 0
        for e in range(3):
            chain[0] = stencil[f, e]
            m = 1
            if stencil[f, 3 + k * e] >= 0:
                for i in range(k):
                    chain[m] = stencil[f, 3 + k * e + i]
                    m += 1
            chain[m] = stencil[f, (e + 1) % 3]
            m += 1
            for s in range(m - 1):
                a, b = min(chain[s], chain[s + 1]), max(chain[s], chain[s + 1])
                uses = 0
                for i in range(n):
                    if lo[i] == a and hi[i] == b:
                        uses += 1
                if uses != 1:
                    return f
                segments += 1
        if free != segments:
            return f
    return -1
