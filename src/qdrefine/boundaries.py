"""A mesh's boundary through refinement: its directed boundary edges, found once and kept
on the meshes that refinement makes from it, and the check that rounding the new boundary
points to float64 did not make the boundary cross itself.

Refined exactly, a mesh's boundary would be its input's, point for point, so a refined
boundary can only cross itself where two parts of the input come closer than the rounding
of their coordinates (a vertex a float step outside another part's edge: valid input,
decided exactly, but no float64 point lies between them). Uniform refinement checks each
level (:func:`qdrefine.uniform.check_boundary_rounding`), local refinement its output
(:func:`qdrefine.adaptive.api.refine_marked`), both by :func:`first_bad_edge`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .numbering import sort_edges
from .sweep import sweep

__all__ = ["boundary_edges", "keep_boundary", "first_bad_edge"]


def boundary_edges(mesh) -> NDArray[np.int64]:
    """``(B, 2) int64``: the edges of ``mesh`` on one triangle only, each as its triangle
    walks it (counter-clockwise), in no particular order. Kept on the mesh (refinement
    keeps its outputs' too, :func:`keep_boundary`); found otherwise from the sorted edges
    that validation left (about 3 ms per million triangles) or by sorting them."""
    kept = mesh.__dict__.get("_boundary")
    if kept is not None and not (mesh.points.flags.writeable or mesh.triangles.flags.writeable):
        return kept
    buckets = mesh.__dict__.get("_buckets") or sort_edges(mesh.triangles, mesh.n_points)
    edges = buckets.boundary_half_edges(mesh.triangles)[1]
    keep_boundary(mesh, edges)
    return edges


def keep_boundary(mesh, edges: NDArray[np.int64]) -> None:
    """Keep ``edges`` (:func:`boundary_edges` of ``mesh``, known to the caller) on
    ``mesh`` for the next call (not pickled: a private attribute)."""
    edges.flags.writeable = False
    object.__setattr__(mesh, "_boundary", edges)


def first_bad_edge(points: NDArray[np.float64], edges: NDArray[np.integer], new_from: int
                   ) -> int | None:
    """The row of ``edges (B, 2)`` (a mesh's directed boundary edges) where two of their
    points fall on one place or the plane sweep (:mod:`qdrefine.sweep`) finds the boundary
    crossing itself, a vertex inside an edge or an area covered twice: of two edges, the
    one with a new point (id ``>= new_from``) if either has one; None where there is
    none of these (``O(B log B)`` and a pass over a mask of the ``N`` points).
    """
    if not len(edges):
        return None
    pair: list[int] = []
    n_hang, hits, crossing, n_cov, first_cov = sweep(points, edges, True, True, 1,
                                                     same_place=pair)[:5]
    if pair:  # two ids at one place (a rounded point on another part's vertex), which the
        v = max(pair)  # sweep took for one vertex, a pinch
        return int(np.flatnonzero((edges == v).any(axis=1))[0])
    if n_hang:
        return int(hits[0, 1])
    if crossing[0]:
        first, second = int(crossing[1]), int(crossing[2])
        return second if edges[first].max() < new_from <= edges[second].max() else first
    if n_cov:
        return int(first_cov)
    return None
