"""Mesh topology: unique edges, boundary, conformity and Euler characteristic."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .boundaries import boundary_edges as kept_boundary
from .check import duplicate_pairs, edge_scan, hanging_nodes
from .kernels import number_edges
from .mesh import Mesh

__all__ = ["Conformity", "unique_edges", "boundary_edges", "conformity", "euler_characteristic"]


def unique_edges(mesh: Mesh) -> tuple[NDArray, NDArray[np.int64], NDArray[np.int64]]:
    """``edges (E,2)`` sorted with ``a < b``, ``tri_edges (M,3)`` (edge of ``v_i v_{i+1}``)
    and ``counts (E,)`` (triangles per edge)."""
    return number_edges(mesh.triangles, mesh.n_points)


def boundary_edges(mesh: Mesh) -> NDArray:
    """Edges ``(B, 2)`` used by exactly one triangle, oriented as in that triangle (in no
    particular order: :func:`qdrefine.boundaries.boundary_edges`, kept through
    refinement)."""
    return np.array(kept_boundary(mesh))


def euler_characteristic(mesh: Mesh) -> int:
    """``V - E + F`` counting only vertices used by some triangle."""
    edges, _, _ = unique_edges(mesh)
    used = np.unique(mesh.triangles).size
    return int(used - edges.shape[0] + mesh.n_triangles)


@dataclass(frozen=True)
class Conformity:
    """Outcome of :func:`conformity` (counts; zero everywhere means conforming)."""

    overused_edges: int  # edges shared by more than two triangles
    misoriented_edges: int  # interior edges walked the same way by both triangles
    hanging_nodes: int  # vertices inside a boundary edge (a non-conforming joint)
    duplicate_points: int  # used points with the coordinates of an earlier used point

    @property
    def ok(self) -> bool:
        return not (self.overused_edges or self.misoriented_edges or self.hanging_nodes
                    or self.duplicate_points)


def conformity(mesh: Mesh) -> Conformity:
    """Check that ``mesh`` is a conforming, consistently oriented triangulation.

    Every interior edge must be shared by exactly two triangles walking it in opposite
    directions, no two used points may coincide, and no vertex may lie inside a boundary
    edge (where a hanging node always sits when triangles do not overlap; exact test, see
    :func:`qdrefine.check.hanging_nodes`). The same kernels validate every :class:`Mesh`;
    this function also checks meshes built without validation (refinement output).
    """
    edges, tri_edges, counts = unique_edges(mesh)
    n_over, _, n_fold, _, bedges, _ = edge_scan(mesh.triangles, tri_edges, counts)
    hanging, _ = hanging_nodes(mesh.points, bedges)
    used = np.zeros(mesh.n_points, dtype=bool)
    used[mesh.triangles.ravel()] = True
    dup, _ = duplicate_pairs(mesh.points, np.flatnonzero(used), 1)
    return Conformity(int(n_over), int(n_fold), int(hanging), int(dup))
