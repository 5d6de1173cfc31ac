"""Triangulate the nine points with SciPy/Qhull, Triangle and qdrefine's exact 7T-D.

SciPy (``scipy.spatial.Delaunay``, Qhull with SciPy's default options) documents its 2D
simplices as counter-clockwise; Triangle (``triangle.triangulate``, Shewchuk's code with its
exact predicates, no switches: the Delaunay triangulation of the vertices) writes
counter-clockwise triangles. Both are called once per nine-point set.
"""

from __future__ import annotations

import importlib.util

import numpy as np
from numpy.typing import NDArray

import qdrefine

from .checks import pad

METHODS = ("scipy", "triangle", "qdrefine 7t-d")


def available(method: str) -> bool:
    """Whether the package behind ``method`` is installed."""
    module = {"scipy": "scipy", "triangle": "triangle"}.get(method)
    return module is None or importlib.util.find_spec(module) is not None


def version(method: str) -> str:
    if method == "scipy":
        import scipy

        return scipy.__version__
    if method == "triangle":
        from importlib.metadata import version as v

        return v("triangle")
    return qdrefine.__version__


def scipy_delaunay(points: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Qhull's triangles ``(K, T, 3)`` (padded with -1) of each ``(9, 2)`` set, and whether
    Qhull raised ``(K,)``."""
    from scipy.spatial import Delaunay, QhullError

    out, err = [], np.zeros(len(points), dtype=bool)
    for i, p in enumerate(points):
        try:
            out.append(Delaunay(p).simplices)
        except QhullError:
            out.append(np.zeros((0, 3), dtype=np.int64))
            err[i] = True
    return pad(out), err


def triangle_delaunay(points: NDArray[np.float64]) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Triangle's triangles ``(K, T, 3)`` (padded with -1) and failures ``(K,)`` (an
    exception, or output vertices that are not the input)."""
    import triangle

    out, err = [], np.zeros(len(points), dtype=bool)
    for i, p in enumerate(points):
        try:
            r = triangle.triangulate({"vertices": p})
            if not np.array_equal(r["vertices"], p):
                raise ValueError("Triangle changed the vertices")
            out.append(r["triangles"])
        except (RuntimeError, ValueError, KeyError):
            out.append(np.zeros((0, 3), dtype=np.int64))
            err[i] = True
    return pad(out), err


def qdrefine_7td(vertices: NDArray[np.float64]) -> NDArray[np.int64]:
    """qdrefine's 7T-D triangles ``(K, 7, 3)`` in local indices."""
    return qdrefine.partition_many(vertices, "7t-d", strict=False)[1]


def run(method: str, vertices: NDArray[np.float64], points: NDArray[np.float64]
        ) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """Triangles ``(K, T, 3)`` and failure flags ``(K,)`` of ``method`` on the nine points
    ``points (K, 9, 2)`` of triangles ``vertices (K, 3, 2)``."""
    if method == "scipy":
        return scipy_delaunay(points)
    if method == "triangle":
        return triangle_delaunay(points)
    if method == "qdrefine 7t-d":
        return qdrefine_7td(vertices), np.zeros(len(vertices), dtype=bool)
    raise ValueError(f"unknown method {method!r}; choose one of {METHODS}")
