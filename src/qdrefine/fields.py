"""Point and cell data through refinement: per-point fields interpolated linearly to the new
points, per-triangle fields inherited by the children.

The new points of an edge are computed exactly as their coordinates are
(:func:`qdrefine.kernels.edge_point`): ``(2 a + b) / 3`` and ``(a + 2 b) / 3`` for the two
trisection points of edge ``(a, b)`` listed from ``a``, ``(a + b) / 2`` for a midpoint. A
field that is a linear function of the coordinates, ``f = c0 + c1 x + c2 y``, is therefore
reproduced on the refined mesh up to the rounding of that formula.

Examples
--------
>>> import numpy as np
>>> from qdrefine.fields import interpolate_point_data
>>> new = interpolate_point_data({"u": np.array([0.0, 3.0, 6.0])}, np.array([[0, 1], [1, 2]]), 2)
>>> new["u"].tolist()
[1.0, 2.0, 4.0, 5.0]
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .arguments import as_ids

__all__ = ["interpolate_point_data", "refine_point_data", "inherit_cell_data", "edge_value",
           "centroid_value"]


def edge_value(a: NDArray, b: NDArray, j: int, k: int) -> NDArray:
    """A field's value at point ``j`` of ``k`` on the segments from values ``a`` to ``b``:
    the kernels' formula for the points themselves, so a linear field stays exact to
    rounding. Fields narrower than float64 are computed in float64 (``2 a + b`` of two
    float16 values of 60000 overflowed) and rounded once when stored; values whose sums
    overflow float64 (near 1e308) are computed scaled by a power of two, which gives the
    same rounding."""
    if k not in (1, 2):
        raise ValueError(f"k (new points per edge) must be 1 or 2, got {k}")
    if k == 1:
        return _scaled_if_overflowing(lambda a, b: (a + b) * 0.5, a, b)
    if j == 0:
        return _scaled_if_overflowing(lambda a, b: (2.0 * a + b) / 3.0, a, b)
    return _scaled_if_overflowing(lambda a, b: (a + 2.0 * b) / 3.0, a, b)


def centroid_value(a: NDArray, b: NDArray, c: NDArray) -> NDArray:
    """A field's value at the centroid of the points with values ``a, b, c`` (the mean;
    narrow floats and overflowing sums computed as in :func:`edge_value`)."""
    return _scaled_if_overflowing(lambda a, b, c: (a + b + c) / 3.0, a, b, c)


def _scaled_if_overflowing(formula, *values: NDArray) -> NDArray:
    """``formula(*values)`` (narrow floats widened to float64), with the entries that
    overflow from finite values computed again on the values scaled by 1/4 and scaled back:
    scaling by a power of two is exact, so the result is the correctly scaled one."""
    values = tuple(_wide(v) for v in values)
    with np.errstate(over="ignore", invalid="ignore"):  # inf - inf of complex overflow
        out = formula(*values)
    if out.dtype.kind not in "fc":
        return out
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(out)
        for v in values:
            bad &= np.isfinite(v)
    if bad.any():
        out = np.array(out)
        out[bad] = formula(*(v[bad] * 0.25 for v in values)) * 4.0
    return out


def _wide(v: NDArray) -> NDArray:
    return v.astype(np.float64) if v.dtype.kind == "f" and v.dtype.itemsize < 8 else v


def interpolate_point_data(point_data: Mapping[str, ArrayLike], edge_ends: ArrayLike, k: int
                           ) -> dict[str, NDArray]:
    """The values of each point field at the new points of split edges.

    Parameters
    ----------
    point_data : mapping of str to (N, ...) array
        Per-point fields of the coarse mesh (numeric; integers are interpolated as float64).
    edge_ends : (E, 2) int
        The two ends of each split edge, in the order its new points were computed from
        (qdrefine's kernels: smaller vertex first), in the order of the new points.
    k : int
        New points per edge: 2 (7T schemes, trisection) or 1 (4T, midpoint).

    Returns
    -------
    dict of str to (E k, ...) array
        Row ``g k + j`` is new point ``j`` of edge ``g``; floating fields keep their dtype.
    """
    ends = np.asarray(edge_ends)
    if ends.ndim != 2 or ends.shape[1] != 2:
        raise ValueError(f"edge_ends must have shape (E, 2), got {ends.shape}")
    if k not in (1, 2):
        raise ValueError(f"k must be 1 or 2 new points per edge, got {k}")
    out = {}
    for name, value in point_data.items():
        v = np.asarray(value)
        as_ids(ends, len(v), "edge_ends", f"rows of point_data {name!r}")
        if v.dtype.kind not in "f":
            v = v.astype(np.float64)
        a, b = v[ends[:, 0]], v[ends[:, 1]]
        rows = np.empty((len(ends), k, *v.shape[1:]), dtype=v.dtype)
        for j in range(k):
            rows[:, j] = edge_value(a, b, j, k)
        out[name] = rows.reshape(len(ends) * k, *v.shape[1:])
    return out


def refine_point_data(point_data: Mapping[str, ArrayLike], edge_ends: ArrayLike, k: int
                      ) -> dict[str, NDArray]:
    """Each field on the refined points: the old rows, then
    :func:`interpolate_point_data` (floating dtype: integer fields become float64)."""
    new = interpolate_point_data(point_data, edge_ends, k)
    return {name: np.concatenate([np.asarray(value, dtype=new[name].dtype), new[name]])
            for name, value in point_data.items()}


def inherit_cell_data(cell_data: Mapping[str, ArrayLike], parents: ArrayLike
                      ) -> dict[str, NDArray]:
    """Each per-triangle field on the children: ``value[parents]``.

    Parameters
    ----------
    cell_data : mapping of str to (M, ...) array
    parents : (M',) int
        The coarse triangle of each child.
    """
    p = np.asarray(parents)
    out = {}
    for name, value in cell_data.items():
        v = np.asarray(value)
        as_ids(p, len(v), "parents", f"rows of cell_data {name!r}")
        out[name] = v[p]
    return out
