"""The mesh data model: one small immutable dataclass of NumPy arrays."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .check import find, index_dtype

__all__ = ["Mesh", "edge_ids", "index_dtype"]


def _readonly(a: NDArray | None) -> NDArray | None:
    if a is not None:
        a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Mesh:
    """A 2D triangle mesh.

    Parameters
    ----------
    points : (N, 2) float64
        Vertex coordinates: each 0 or of magnitude in ``[1e-100, 1e100]`` (the range in
        which every predicate is exact).
    triangles : (M, 3) int
        Vertex indices, counter-clockwise, positive area (checked exactly). Stored as
        ``int32`` while ``N`` fits, ``int64`` beyond.
    cell_tags : (M,) int64, optional
        One tag per triangle (e.g. a Gmsh physical group).
    edges : (K, 2) int, optional
        Tagged boundary or interface edges; each must be an edge of some triangle.
    edge_tags : (K,) int64, optional
        One tag per row of ``edges``; given together with ``edges``.

    Construction validates everything once with :func:`qdrefine.check.find` and raises
    ``ValueError`` naming the first problem and where (triangle, vertex or edge ids): shapes,
    non-finite or out-of-range coordinates, indices, zero-area or clockwise triangles, two
    used points at the same coordinates, an edge shared by more than two triangles, two
    triangles folded onto one side of their edge, hanging nodes, tags. Unused points are
    allowed (kept). The arrays are copied and made read-only. Functions of qdrefine return
    new meshes and never change one.
    """

    points: NDArray[np.float64]
    triangles: NDArray[np.integer]
    cell_tags: NDArray[np.int64] | None = None
    edges: NDArray[np.integer] | None = None
    edge_tags: NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        fields = _validated(self.points, self.triangles, self.cell_tags, self.edges,
                            self.edge_tags)
        for name, value in fields.items():
            object.__setattr__(self, name, _readonly(value))

    @classmethod
    def _trusted(cls, points: NDArray, triangles: NDArray, cell_tags: NDArray | None = None,
                 edges: NDArray | None = None, edge_tags: NDArray | None = None) -> Mesh:
        """A mesh from arrays already known to be valid (output of qdrefine's kernels)."""
        mesh = object.__new__(cls)
        for name, value in (("points", points), ("triangles", triangles),
                            ("cell_tags", cell_tags), ("edges", edges),
                            ("edge_tags", edge_tags)):
            object.__setattr__(mesh, name, _readonly(value))
        return mesh

    @property
    def n_points(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    def replace(self, **changes: Any) -> Mesh:
        """A validated copy with some fields replaced (``dataclasses.replace``)."""
        return replace(self, **changes)

    def __repr__(self) -> str:
        tags = "" if self.cell_tags is None else f", {len(np.unique(self.cell_tags))} cell tags"
        edges = "" if self.edges is None else f", {len(self.edges)} tagged edges"
        return f"Mesh({self.n_points} points, {self.n_triangles} triangles{tags}{edges})"


def _validated(points: ArrayLike, triangles: ArrayLike, cell_tags: ArrayLike | None,
               edges: ArrayLike | None, edge_tags: ArrayLike | None) -> dict[str, NDArray | None]:
    found = find(points, triangles, cell_tags, edges, edge_tags, stop_at_error=True,
                 warnings=False)
    found.raise_first()
    return {"points": found.points, "triangles": found.triangles, "cell_tags": found.cell_tags,
            "edges": found.edges, "edge_tags": found.edge_tags}


def edge_ids(mesh_edges: NDArray, query: NDArray, n: int) -> NDArray[np.int64]:
    """Ids of ``query (K,2)`` rows in the sorted ``mesh_edges (E,2)``; -1 where absent."""
    key = mesh_edges[:, 0].astype(np.int64) * n + mesh_edges[:, 1]
    lo = np.minimum(query[:, 0], query[:, 1]).astype(np.int64)
    q = lo * n + np.maximum(query[:, 0], query[:, 1])
    pos = np.searchsorted(key, q)
    pos = np.minimum(pos, len(key) - 1)
    found = key[pos] == q
    return np.where(found, pos, -1)
