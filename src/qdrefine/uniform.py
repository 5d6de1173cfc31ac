"""Uniform conforming refinement of a whole mesh: one level on plain arrays
(:func:`refine_arrays`), on a :class:`Mesh` with its tags and data, ``levels`` levels
(:func:`refine_uniform`), and the float64 rounding check with its error
(:class:`RefusedTriangle`). :mod:`qdrefine.refine` is the public front."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .boundaries import first_bad_edge, keep_boundary
from .fields import refine_point_data
from .kernels import emit, rounding_suspects
from .memory import check_memory
from .mesh import Mesh, edge_ids, index_dtype
from .numbering import EdgeBuckets, bucket_points, sort_edges
from .predicates import orient_signs, orient_signs_of_rows
from .schemes import Scheme

__all__ = ["RefusedTriangle", "refine_uniform", "refine_arrays", "check_rounding",
           "check_boundary_rounding", "too_close", "refused", "refused_at_boundary",
           "split_tagged_edges"]


def refine_uniform(mesh: Mesh, sch: Scheme, levels: int, strict: bool = True) -> Mesh:
    """``levels`` uniform levels of ``sch`` on ``mesh`` (memory checked first); a refusal
    names the input triangle. :func:`qdrefine.refine` is the public front."""
    check_memory(mesh, sch, levels)
    out = mesh
    for level in range(1, levels + 1):
        try:
            out = _refine_once(out, sch, strict)
        except RefusedTriangle as exc:  # named by the input triangle
            raise exc.at_input(mesh, level, sch.n_children) from None
        except ValueError as exc:
            raise ValueError(f"level {level}: {exc}" if levels > 1 else str(exc)) from None
    return out


def refine_arrays(points: NDArray[np.float64], triangles: NDArray[np.integer], sch: Scheme,
                  strict: bool = True, buckets: EdgeBuckets | None = None
                  ) -> tuple[NDArray[np.float64], NDArray, EdgeBuckets]:
    """One uniform level on plain arrays (counter-clockwise ``triangles (M, 3)`` with indices
    into ``points (N, 2)``): ``new_points (N + k E, 2)``, ``children (M T, 3)`` (``int32``
    while the points fit) and the sorted edges; see :func:`refine` for the numbering and
    ``strict``. ``buckets``: :func:`~qdrefine.numbering.sort_edges` of ``triangles`` if
    already known (validation builds them)."""
    k = sch.stencil.per_edge
    n = points.shape[0]
    if buckets is None:
        buckets = sort_edges(triangles, n)
    n_new = n + k * buckets.n_edges
    new_points = np.empty((n_new, 2), dtype=np.float64)
    bucket_points(points, buckets, k, new_points)
    children = np.empty((triangles.shape[0] * sch.n_children, 3), dtype=index_dtype(n_new))
    suspect = emit(points, triangles, buckets.local, k, sch.forms, sch.lut, sch.tables,
                   children, buckets)
    if strict:
        check_rounding(points, triangles, new_points, children, k, suspect=suspect)
    return new_points, children, buckets


def _refine_once(mesh: Mesh, sch: Scheme, strict: bool = True) -> Mesh:
    k = sch.stencil.per_edge
    n = mesh.n_points
    points, triangles, buckets = refine_arrays(mesh.points, mesh.triangles, sch, strict,
                                               mesh._take_buckets())
    boundary = None
    if strict:  # a mesh's parts do not overlap (partition's triangles may: not checked there)
        before, boundary = check_boundary_rounding(mesh.points, mesh.triangles, buckets,
                                                   points, k)
        keep_boundary(mesh, before)  # both kept, for a local refinement of either
    cell_tags = None if mesh.cell_tags is None else np.repeat(mesh.cell_tags, sch.n_children)
    new_edges, edge_tags = None, None
    edges = buckets.edges()[0] if mesh.edges is not None or mesh.point_data else None
    if mesh.edges is not None:
        new_edges, edge_tags = split_tagged_edges(mesh.edges, mesh.edge_tags, edges, n, k)
        new_edges = new_edges.astype(triangles.dtype)
    point_data = refine_point_data(mesh.point_data, edges, k) if mesh.point_data else None
    cell_data = {name: np.repeat(value, sch.n_children, axis=0)
                 for name, value in (mesh.cell_data or {}).items()}
    origins = None if mesh.origins is None else np.repeat(mesh.origins, sch.n_children, axis=0)
    out = Mesh._trusted(points, triangles, cell_tags, new_edges, edge_tags, point_data,
                        cell_data, mesh.physical_names, origins=origins)
    if boundary is not None:  # for a local refinement of it
        keep_boundary(out, boundary)
    return out


def check_rounding(points: NDArray[np.float64], triangles: NDArray, new_points: NDArray[np.float64],
                   children: NDArray, k: int, parents: NDArray[np.int64] | None = None,
                   everywhere: bool = False, suspect: NDArray[np.bool_] | None = None,
                   rows: NDArray[np.int64] | None = None) -> None:
    """Raise ``ValueError`` when rounding the new points to float64 flattened or inverted a
    child.

    The decisions are exact, but the trisection points (midpoints) are stored rounded; for a
    triangle tiny compared with its distance from the origin (a needle of width 1e-9 at 1e7,
    say) that rounding can move a point across a child's edge. The parents that might be
    affected are found by a certified float bound (:func:`kernels.rounding_suspects`, almost
    never any on ordinary meshes) and only their children are checked exactly.

    Parameters
    ----------
    points : (N, 2) float64 and triangles : (M, 3) int
        The mesh that was refined.
    new_points : (N', 2) float64 and children : (M', 3) int
        The refined mesh.
    k : int
        New points per split edge (2 for 7T schemes, 1 for 4T): the lattice step is
        ``1 / (k + 1)``.
    parents : (M',) int64, optional
        Parent of each child; default: ``M' / M`` contiguous children per parent.
    everywhere : bool
        Check every child exactly, not only those of suspects (for adaptive refinement, where
        a coarsened family's children are not on its first member's lattice).
    suspect : (M,) bool, optional
        :func:`kernels.rounding_suspects` if already known (:func:`kernels.emit` returns it).
    rows : (R,) int64, optional
        With ``parents``: the children to check exactly, increasing (those of the suspect
        parents, when the caller knows them without a pass over every child).
    """
    if rows is not None and parents is not None:
        if rows.size:
            _check_children(points, triangles, new_points, children, rows, parents[rows])
        return
    if everywhere:
        suspect = np.ones(triangles.shape[0], dtype=bool)
    elif suspect is None:
        suspect = rounding_suspects(points, triangles, k + 1)
    if not suspect.any():
        return
    if parents is None:
        rows = np.flatnonzero(np.repeat(suspect, children.shape[0] // triangles.shape[0]))
        parents = rows // (children.shape[0] // triangles.shape[0])
    else:
        rows = np.flatnonzero(suspect[parents])
        parents = parents[rows]
    _check_children(points, triangles, new_points, children, rows, parents)


def _check_children(points: NDArray[np.float64], triangles: NDArray,
                    new_points: NDArray[np.float64], children: NDArray,
                    rows: NDArray[np.int64], parents: NDArray[np.int64]) -> None:
    """:func:`check_rounding` of the children ``rows`` (their parents ``parents``)."""
    signs = orient_signs_of_rows(new_points, children, rows)
    bad = np.flatnonzero(signs <= 0)
    if bad.size:
        i = int(parents[bad[0]])
        corners = points[triangles[i]]
        u, w = corners[1] - corners[0], corners[2] - corners[0]
        edges = np.linalg.norm(corners - np.roll(corners, 1, axis=0), axis=1)
        height = abs(u[0] * w[1] - u[1] * w[0]) / edges.max()
        what = "zero area" if signs[bad[0]] == 0 else "clockwise orientation"
        raise RefusedTriangle(
            i, tuple(int(v) for v in triangles[i]), "is too thin for its distance from the "
            f"origin (height {height:.3g}, coordinates up to {np.abs(corners).max():.3g}): "
            f"its new points rounded to float64 give a child with {what} "
            f"({bad.size} such children in all); translate the mesh nearer the origin or "
            "refine less")


def refused(points: NDArray[np.float64], triangles: NDArray[np.integer], sch: Scheme
            ) -> NDArray[np.int64]:
    """Rows of the triangles that one uniform level by ``sch`` refuses (too thin for their
    distance from the origin: :func:`check_rounding`), all of them, in order.

    Only the suspects of :func:`kernels.rounding_suspects` are refined, as a mesh of their
    own whose vertices keep their order, so every new point is computed from the same end
    of its edge, and rounded the same, as in the refinement of the whole mesh.
    """
    k = sch.stencil.per_edge
    rows = np.flatnonzero(rounding_suspects(points, triangles, k + 1))
    if not rows.size:
        return rows
    verts = np.unique(triangles[rows])
    local = np.searchsorted(verts, triangles[rows]).astype(np.int64)
    new_points, children, _ = refine_arrays(points[verts], local, sch, strict=False)
    flat = (orient_signs(new_points, children) <= 0).reshape(rows.size, sch.n_children)
    return rows[flat.any(axis=1)]


def refused_at_boundary(points: NDArray[np.float64], triangles: NDArray[np.integer],
                        sch: Scheme) -> RefusedTriangle | None:
    """The refusal of :func:`check_boundary_rounding` that one uniform level by ``sch``
    meets, or None (a level's new points are computed: a check, not a refinement path)."""
    k = sch.stencil.per_edge
    buckets = sort_edges(triangles, points.shape[0])
    new_points = np.empty((points.shape[0] + k * buckets.n_edges, 2), dtype=np.float64)
    bucket_points(points, buckets, k, new_points)
    try:
        check_boundary_rounding(points, triangles, buckets, new_points, k)
    except RefusedTriangle as exc:
        return exc
    return None


class RefusedTriangle(ValueError):
    """A triangle that refinement refuses: ``triangle`` (its row), ``vertices`` and
    ``reason`` (the message is ``"triangle {triangle} {vertices} {reason}"``, or names them
    by a file's own numbers after :meth:`numbered`)."""

    def __init__(self, triangle: int, vertices: tuple[int, ...], reason: str) -> None:
        self.triangle, self.vertices, self.reason = triangle, vertices, reason
        super().__init__(f"triangle {triangle} {vertices} {reason}")

    def at_input(self, mesh: Mesh, level: int, n_children: int) -> RefusedTriangle:
        """The refusal at ``level`` (counted from 1) of refining ``mesh`` uniformly, told of
        ``mesh``'s triangle whose descendant was refused (children of row ``t`` are rows
        ``t T .. t T + T - 1``)."""
        if level <= 1:
            return self
        t = self.triangle // n_children ** (level - 1)
        return RefusedTriangle(t, tuple(int(v) for v in mesh.triangles[t]),
                               f"cannot be refined {level} levels: its descendant "
                               f"{self.triangle} {self.vertices} of level {level - 1} (rows "
                               f"and points of that level's mesh, from 0) {self.reason}")

    def numbered(self, triangle: int, vertices: tuple[int, ...]) -> RefusedTriangle:
        """The same refusal with the triangle and its vertices named by other numbers (a
        file's own element and node numbers)."""
        out = RefusedTriangle(triangle, vertices, self.reason)
        out.triangle, out.vertices = self.triangle, self.vertices  # rows, for the API
        return out


def split_tagged_edges(tagged: NDArray, tags: NDArray, edges: NDArray, n: int, k: int,
                       split: NDArray[np.bool_] | None = None,
                       rank: NDArray[np.int64] | None = None) -> tuple[NDArray, NDArray]:
    """Each tagged edge ``(a, b)`` that is split becomes ``k + 1`` edges ``a -> ... -> b``
    with its tag; the others are kept.

    ``split (E,)`` says which mesh edges get new points (default: all) and ``rank (E,)``
    numbers them (default: the edge id): the points of edge ``g`` are ``n + rank[g] k + j``.
    """
    ids = edge_ids(edges, tagged, n)
    pieces = edge_pieces(tagged, ids if rank is None else rank[ids], n, k)
    if split is None:
        return pieces.reshape(-1, 2), np.repeat(tags, k + 1)
    cut = split[ids]
    pieces[~cut, 0, 1] = tagged[~cut, 1]
    keep = np.ones((tagged.shape[0], k + 1), dtype=bool)
    keep[~cut, 1:] = False
    return pieces[keep], np.repeat(tags, keep.sum(axis=1))


def edge_pieces(ends: NDArray, rank: NDArray[np.int64], n: int, k: int) -> NDArray[np.int64]:
    """``(K, k + 1, 2)``: each edge ``ends[i] = (a, b)`` walked from ``a`` to ``b`` through
    its new points ``n + rank[i] k + j`` (numbered from its smaller end)."""
    a = ends[:, 0].astype(np.int64)
    b = ends[:, 1].astype(np.int64)
    forward = a < b
    chain = [a]
    for j in range(k):
        chain.append(np.where(forward, n + rank * k + j, n + rank * k + (k - 1 - j)))
    chain.append(b)
    return np.stack([np.stack([chain[j], chain[j + 1]], axis=1) for j in range(k + 1)],
                    axis=1)


def check_boundary_rounding(points: NDArray[np.float64], triangles: NDArray,
                            buckets: EdgeBuckets, new_points: NDArray[np.float64],
                            k: int) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Raise :class:`RefusedTriangle` when rounding the new points on the boundary to
    float64 made the refined boundary cross itself, put a new point on another boundary
    edge or cover an area twice (:mod:`qdrefine.boundaries`); else return the boundary
    edges, directed, of the mesh ``(B, 2)`` and of the refined mesh ``(B (k + 1), 2)``.

    Parameters
    ----------
    points : (N, 2) float64, triangles : (M, 3) int, buckets
        The mesh refined and its sorted edges.
    new_points : (N + k E, 2) float64
        The refined mesh's points.
    k : int
        New points per edge.
    """
    rows, walked, ids = buckets.boundary_half_edges(triangles)
    pieces = edge_pieces(walked, ids, points.shape[0], k).reshape(-1, 2)
    bad = first_bad_edge(new_points, pieces, points.shape[0])
    if bad is not None:
        raise too_close(points, triangles, int(rows[bad // (k + 1)]))
    return walked, pieces


def too_close(points: NDArray[np.float64], triangles: NDArray, i: int) -> RefusedTriangle:
    """The refusal of triangle ``i``, whose new boundary points, rounded, cross another
    part of the mesh."""
    return RefusedTriangle(i, tuple(int(v) for v in triangles[i]),
                           too_close_reason(points[triangles[i]]))


def too_close_reason(corners: NDArray[np.float64]) -> str:
    """Why a triangle with corners ``(3, 2)`` is refused by :func:`too_close`."""
    return ("is closer to another part of the mesh than float64 can resolve at its "
            f"coordinates (up to {np.abs(corners).max():.3g}): its new boundary points, "
            "rounded, make the boundary cross itself; translate the mesh nearer the origin, "
            "or separate the parts")
