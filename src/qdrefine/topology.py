"""Mesh topology: unique edges, boundary, conformity and Euler characteristic."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .kernels import number_edges
from .mesh import Mesh
from .predicates import SCRATCH, orient_sign

__all__ = ["Conformity", "unique_edges", "boundary_edges", "conformity", "euler_characteristic"]


def unique_edges(mesh: Mesh) -> tuple[NDArray, NDArray[np.int64], NDArray[np.int64]]:
    """``edges (E,2)`` sorted with ``a < b``, ``tri_edges (M,3)`` (edge of ``v_i v_{i+1}``)
    and ``counts (E,)`` (triangles per edge)."""
    return number_edges(mesh.triangles, mesh.n_points)


def boundary_edges(mesh: Mesh) -> NDArray:
    """Edges ``(B, 2)`` used by exactly one triangle, oriented as in that triangle."""
    edges, tri_edges, counts = unique_edges(mesh)
    once = counts[tri_edges] == 1
    t, i = np.nonzero(once)
    tri = mesh.triangles
    return np.stack([tri[t, i], tri[t, (i + 1) % 3]], axis=1)


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
    duplicate_points: int  # points with identical coordinates

    @property
    def ok(self) -> bool:
        return not (self.overused_edges or self.misoriented_edges or self.hanging_nodes
                    or self.duplicate_points)


def conformity(mesh: Mesh) -> Conformity:
    """Check that ``mesh`` is a conforming, consistently oriented triangulation.

    Every interior edge must be shared by exactly two triangles walking it in opposite
    directions, and no vertex may lie inside another triangle's edge: a hanging node always
    sits inside an edge used by one triangle only, so the boundary edges are tested against
    every vertex with the exact orientation predicate (vertices are bucketed on a grid, so
    the cost is about linear for well-spread meshes).
    """
    edges, tri_edges, counts = unique_edges(mesh)
    tri = mesh.triangles
    forward = tri < np.roll(tri, -1, axis=1)
    n_forward = np.bincount(tri_edges[forward], minlength=len(edges))
    twice = counts == 2
    misoriented = int(np.count_nonzero(twice & (n_forward != 1)))
    b = boundary_edges(mesh)
    hanging = int(_hanging_nodes(mesh.points, b.astype(np.int64)))
    dup = mesh.n_points - np.unique(mesh.points, axis=0).shape[0]
    return Conformity(int(np.count_nonzero(counts > 2)), misoriented, hanging, int(dup))


@njit(cache=True)
def _hanging_nodes(points, bedges):
    """Number of (vertex, boundary edge) pairs with the vertex strictly inside the edge."""
    n = points.shape[0]
    if bedges.shape[0] == 0 or n == 0:
        return 0
    x0, y0 = points[:, 0].min(), points[:, 1].min()
    x1, y1 = points[:, 0].max(), points[:, 1].max()
    g = max(1, int(np.sqrt(n)))
    sx = (x1 - x0) / g if x1 > x0 else 1.0
    sy = (y1 - y0) / g if y1 > y0 else 1.0
    cell = np.empty(n, dtype=np.int64)
    for i in range(n):
        cx = min(g - 1, int((points[i, 0] - x0) / sx))
        cy = min(g - 1, int((points[i, 1] - y0) / sy))
        cell[i] = cx * g + cy
    order = np.argsort(cell)
    start = np.zeros(g * g + 1, dtype=np.int64)
    for i in range(n):
        start[cell[i] + 1] += 1
    for c in range(g * g):
        start[c + 1] += start[c]
    buf = np.empty(SCRATCH)
    found = 0
    for e in range(bedges.shape[0]):
        a, b = bedges[e, 0], bedges[e, 1]
        ax, ay, bx, by = points[a, 0], points[a, 1], points[b, 0], points[b, 1]
        cx0 = max(0, min(g - 1, int((min(ax, bx) - x0) / sx)) - 1)
        cx1 = min(g - 1, int((max(ax, bx) - x0) / sx) + 1)
        cy0 = max(0, min(g - 1, int((min(ay, by) - y0) / sy)) - 1)
        cy1 = min(g - 1, int((max(ay, by) - y0) / sy) + 1)
        for cx in range(cx0, cx1 + 1):
            for cy in range(cy0, cy1 + 1):
                c = cx * g + cy
                for p in range(start[c], start[c + 1]):
                    v = order[p]
                    if v == a or v == b:
                        continue
                    px, py = points[v, 0], points[v, 1]
                    if px < min(ax, bx) or px > max(ax, bx) or py < min(ay, by) \
                            or py > max(ay, by):
                        continue
                    if orient_sign(ax, ay, bx, by, px, py, buf) != 0:
                        continue
                    if (px, py) != (ax, ay) and (px, py) != (bx, by):
                        found += 1
    return found
