"""Partition single triangles (the building block, exposed for study and plots)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .arguments import as_coordinates
from .predicates import check_coordinates, orient_signs
from .schemes import Scheme, get_scheme
from .uniform import refine_arrays

__all__ = ["partition", "partition_many"]


def partition(vertices: ArrayLike, scheme: str | Scheme = "7t-qd", *, strict: bool = True
              ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Partition one triangle.

    Parameters
    ----------
    vertices : (3, 2) float
        The triangle, in either orientation.
    scheme : {"7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"}
    strict : bool
        ``False`` returns children that rounding the new points to float64 flattened or
        inverted instead of raising ``ValueError`` (see :func:`qdrefine.refine`).

    Returns
    -------
    points : (P, 2) float64
        The three vertices in the given order, then ``k`` points (2 for 7T schemes, 1 for
        4T) on each of the edges ``v0-v1``, ``v0-v2``, ``v1-v2``, each listed from its first
        vertex. ``P`` is 9 or 6.
    triangles : (T, 3) int64
        Indices into ``points``, counter-clockwise. ``T`` is 7 or 4.

    Examples
    --------
    >>> pts, tris = partition([[0, 0], [1, 0], [0.3, 0.5]], "7t-qd")
    >>> pts.shape, tris.shape
    ((9, 2), (7, 3))
    """
    v = as_coordinates(vertices, "vertices", "(3, 2)")
    pts, tris = partition_many(v[None], scheme, strict=strict)
    return pts[0], tris[0]


def partition_many(vertices: ArrayLike, scheme: str | Scheme = "7t-qd", *, strict: bool = True
                   ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Partition ``K`` triangles at once.

    Parameters
    ----------
    vertices : (K, 3, 2) float
    scheme : str or Scheme
    strict : bool
        ``False`` returns children that rounding the new points to float64 flattened or
        inverted instead of raising ``ValueError`` (see :func:`qdrefine.refine`).

    Returns
    -------
    points : (K, P, 2) float64
    triangles : (K, T, 3) int64
        Local indices, as for :func:`partition`.
    """
    sch = get_scheme(scheme)
    v = as_coordinates(vertices, "vertices", "(K, 3, 2)")
    if v.ndim != 3 or v.shape[1:] != (3, 2):
        raise ValueError(f"vertices must have shape (K, 3, 2), got {v.shape}")
    check_coordinates(v.reshape(-1, 2), "vertex")
    n_tri = v.shape[0]
    k = sch.stencil.per_edge
    n_children = sch.n_children
    points = v.reshape(-1, 2)
    triangles = np.arange(3 * n_tri, dtype=np.int64).reshape(-1, 3)
    signs = orient_signs(points, triangles)
    if (signs == 0).any():
        i = int(np.flatnonzero(signs == 0)[0])
        raise ValueError(f"triangle {i} has zero area: {v[i].tolist()}")
    cw = signs < 0
    triangles[cw] = triangles[cw][:, [0, 2, 1]]
    all_points, children, _ = refine_arrays(points, triangles, sch, strict)
    out = children.astype(np.int64)
    # edges of triangle i are 3i + (0: v0v1, 1: v0v2, 2: v1v2), sorted by (min, max) vertex
    owner = np.repeat(np.arange(n_tri), n_children)[:, None]
    old = out < 3 * n_tri
    local = np.where(old, out - 3 * owner, 3 + (out - 3 * n_tri) - 3 * k * owner)
    local = local.reshape(n_tri, n_children, 3)
    local_points = np.concatenate(
        [v, all_points[3 * n_tri:].reshape(n_tri, 3 * k, 2)], axis=1)
    return local_points, local
