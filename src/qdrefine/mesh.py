"""The mesh data model: one small immutable dataclass of NumPy arrays."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .kernels import number_edges
from .predicates import check_coordinates, orient_signs

__all__ = ["Mesh", "index_dtype"]

def index_dtype(n_points: int) -> type[np.integer]:
    """``int32`` while vertex indices fit, ``int64`` beyond."""
    return np.int32 if n_points <= np.iinfo(np.int32).max else np.int64


def _readonly(a: NDArray | None) -> NDArray | None:
    if a is not None:
        a.flags.writeable = False
    return a


def _integer_array(value: ArrayLike, name: str) -> NDArray[np.int64]:
    a = np.asarray(value)
    if a.size == 0:
        return a.astype(np.int64)
    if not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"{name} must hold integers, got dtype {a.dtype}")
    return a.astype(np.int64, copy=False)


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

    Construction validates everything once and raises ``ValueError`` naming the first
    offending triangle or edge; the arrays are copied and made read-only. Functions of
    qdrefine return new meshes and never change one.
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
    p = np.array(points, dtype=np.float64, copy=True)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2), got {p.shape}")
    check_coordinates(p)
    n = p.shape[0]
    t = _integer_array(triangles, "triangles")
    if t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"triangles must have shape (M, 3), got {t.shape}")
    if t.shape[0] == 0:
        raise ValueError("the mesh has no triangles")
    out = (t < 0) | (t >= n)
    if out.any():
        i = int(np.flatnonzero(out.any(axis=1))[0])
        raise ValueError(f"triangle {i} {tuple(int(v) for v in t[i])} has a vertex index "
                         f"outside 0..{n - 1}")
    t = np.ascontiguousarray(t, dtype=index_dtype(n))
    signs = orient_signs(p, t)
    if (signs <= 0).any():
        i = int(np.flatnonzero(signs <= 0)[0])
        what = "has zero area" if signs[i] == 0 else "is clockwise"
        raise ValueError(f"triangle {i} {tuple(int(v) for v in t[i])} {what}; triangles must "
                         "be counter-clockwise with positive area")
    ct = None
    if cell_tags is not None:
        ct = _integer_array(cell_tags, "cell_tags").copy()
        if ct.shape != (t.shape[0],):
            raise ValueError(f"cell_tags must have shape ({t.shape[0]},), got {ct.shape}")
    e, et = _validated_edges(t, n, edges, edge_tags)
    return {"points": p, "triangles": t, "cell_tags": ct, "edges": e, "edge_tags": et}


def _validated_edges(t: NDArray, n: int, edges: ArrayLike | None,
                     edge_tags: ArrayLike | None) -> tuple[NDArray | None, NDArray | None]:
    if edges is None and edge_tags is None:
        return None, None
    if edges is None or edge_tags is None:
        raise ValueError("edges and edge_tags must be given together")
    e = _integer_array(edges, "edges")
    if e.size == 0:
        e = e.reshape(0, 2)
    if e.ndim != 2 or e.shape[1] != 2:
        raise ValueError(f"edges must have shape (K, 2), got {e.shape}")
    et = _integer_array(edge_tags, "edge_tags").copy()
    if et.shape != (e.shape[0],):
        raise ValueError(f"edge_tags must have shape ({e.shape[0]},), got {et.shape}")
    out = (e < 0) | (e >= n)
    if out.any():
        i = int(np.flatnonzero(out.any(axis=1))[0])
        raise ValueError(f"edge {i} {tuple(int(v) for v in e[i])} has a vertex index outside "
                         f"0..{n - 1}")
    e = np.ascontiguousarray(e, dtype=t.dtype)
    missing = edge_ids(number_edges(t, n)[0], e, n) < 0
    if missing.any():
        i = int(np.flatnonzero(missing)[0])
        raise ValueError(f"edge {i} {tuple(int(v) for v in e[i])} is not an edge of any triangle")
    return e, et


def edge_ids(mesh_edges: NDArray, query: NDArray, n: int) -> NDArray[np.int64]:
    """Ids of ``query (K,2)`` rows in the sorted ``mesh_edges (E,2)``; -1 where absent."""
    key = mesh_edges[:, 0].astype(np.int64) * n + mesh_edges[:, 1]
    lo = np.minimum(query[:, 0], query[:, 1]).astype(np.int64)
    q = lo * n + np.maximum(query[:, 0], query[:, 1])
    pos = np.searchsorted(key, q)
    pos = np.minimum(pos, len(key) - 1)
    found = key[pos] == q
    return np.where(found, pos, -1)
