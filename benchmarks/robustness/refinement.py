"""Uniform refinement of small meshes built on hard triangles, checked exactly per level.

Each triangle ``abc`` becomes a conforming four-triangle patch: ``abc`` and its point
reflections through the midpoints of its edges (apexes ``b + c - a`` etc.; they never
overlap, the patch is the triangle with vertices ``b + c - a, c + a - b, a + b - c``).
Every level is checked with :func:`qdrefine.topology.conformity`, the exact orientation of
every triangle, and the exact total area compared with the patch's.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from numpy.typing import NDArray

import qdrefine
from qdrefine.topology import conformity

from .exact import orient_sign, triangles_area2

PATCH_TRIANGLES = np.array([[0, 1, 2], [3, 2, 1], [2, 4, 0], [1, 0, 5]])


def patch(v: NDArray[np.float64]) -> qdrefine.Mesh | None:
    """The four-triangle patch of triangle ``v (3, 2)``; None when rounding makes it invalid
    (``Mesh`` refuses it)."""
    a, b, c = v
    pts = np.array([a, b, c, b + c - a, c + a - b, a + b - c])
    tris = PATCH_TRIANGLES.copy()
    if orient_sign(a, b, c) < 0:
        tris = tris[:, ::-1]
    try:
        return qdrefine.Mesh(pts, tris)
    except ValueError:
        return None


def study(vertices: NDArray[np.float64], scheme: str, levels: int = 4) -> dict:
    """Refine the patch of each triangle ``vertices (K, 3, 2)`` ``levels`` times.

    Returns per level (list index ``level - 1``) counts over patches: ``non_conforming``
    (and its parts), ``zero_area``, ``inverted``, ``area_changed`` (exact total differs
    from the patch's), the largest relative area change, and the number of patches.
    """
    meshes = [m for m in (patch(v) for v in vertices) if m is not None]
    out = {"patches": len(meshes), "patches_refused": len(vertices) - len(meshes), "levels": []}
    current = meshes
    for _ in range(levels):
        current = [qdrefine.refine(m, scheme, 1, strict=False) for m in current]
        out["levels"].append(_check_level(meshes, current))
    return out


def _check_level(patches: list[qdrefine.Mesh], fine: list[qdrefine.Mesh]) -> dict:
    conf = [conformity(m) for m in fine]
    pts = np.stack([m.points for m in fine])
    tris = np.stack([m.triangles for m in fine]).astype(np.int64)
    rows = np.arange(len(fine))[:, None]
    s = orient_sign(pts[rows, tris[..., 0]], pts[rows, tris[..., 1]], pts[rows, tris[..., 2]])
    area, ex = triangles_area2(pts, tris)
    base, ex0 = triangles_area2(pts, np.stack([m.triangles for m in patches]).astype(np.int64))
    assert (ex == ex0).all()
    rel = [abs(Fraction(int(a) - int(b), int(b))) for a, b in zip(area, base, strict=True)]
    return {
        "triangles_per_patch": int(tris.shape[1]),
        "non_conforming": sum(not c.ok for c in conf),
        "overused_edges": sum(c.overused_edges > 0 for c in conf),
        "misoriented_edges": sum(c.misoriented_edges > 0 for c in conf),
        "hanging_nodes": sum(c.hanging_nodes > 0 for c in conf),
        "duplicate_points": sum(c.duplicate_points > 0 for c in conf),
        "zero_area": int((s == 0).any(axis=1).sum()),
        "inverted": int((s < 0).any(axis=1).sum()),
        "zero_area_triangles": int((s == 0).sum()),
        "inverted_triangles": int((s < 0).sum()),
        "area_changed": int(sum(r != 0 for r in rel)),
        "max_relative_area_change": float(max(rel, default=0)),
    }
