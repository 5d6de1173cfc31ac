"""Per-triangle quality measures (vectorized; one value per triangle).

Every function takes either a :class:`~qdrefine.Mesh` or the two arrays
``points (N, 2) float64`` and ``triangles (M, 3) int`` and returns one value (or one row)
per triangle, in triangle order. Summaries and printing live in :mod:`qdrefine.report`.

Examples
--------
>>> from qdrefine import examples, quality
>>> mesh = examples.square(1)              # two right isosceles triangles
>>> quality.min_angles(mesh)
array([45., 45.])
>>> quality.radius_ratios(mesh).round(4)
array([0.8284, 0.8284])
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from .jit import first_row_at_or_after

if TYPE_CHECKING:  # a Mesh is told by its arrays, so this module needs no import of it
    from .mesh import Mesh

__all__ = [
    "angles",
    "corner_angles",
    "min_angles",
    "max_angles",
    "areas",
    "edge_lengths",
    "radius_ratios",
    "aspect_ratios",
    "similarity_classes",
    "min_angle_histogram",
    "SIMILARITY_TOLERANCE",
]

#: Default tolerance (degrees) of :func:`similarity_classes`.
SIMILARITY_TOLERANCE = 1e-6


def _arrays(mesh: Mesh | ArrayLike, triangles: ArrayLike | None) -> tuple[NDArray, NDArray]:
    is_mesh = hasattr(mesh, "points") and hasattr(mesh, "triangles")
    if triangles is None:
        if not is_mesh:
            raise TypeError("give a Mesh, or points (N, 2) and triangles (M, 3)")
        return mesh.points, mesh.triangles
    if is_mesh:
        raise TypeError("give a Mesh alone, or points and triangles")
    p = np.asarray(mesh, dtype=np.float64)
    t = np.asarray(triangles)
    if p.ndim != 2 or p.shape[1] != 2 or t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"points must be (N, 2) and triangles (M, 3), got {p.shape} and "
                         f"{t.shape}")
    if t.size and t.dtype.kind not in "iu":
        raise TypeError(f"triangles must be integer vertex indices, got {t.dtype}")
    if t.size:  # -1 would measure another triangle (NumPy wraps it around)
        bad = np.flatnonzero(((t < 0) | (t >= len(p))).any(axis=1))
        if bad.size:
            r = int(bad[0])
            raise ValueError(f"triangle {r} {tuple(t[r].tolist())} has a vertex index outside "
                             f"0..{len(p) - 1}")
    return p, t


def _sides(p: NDArray, t: NDArray) -> tuple[NDArray, NDArray]:
    """Edge vectors ``(M, 3, 2)``: row ``i`` goes from vertex ``i`` to vertex ``i + 1``,
    and twice the signed area ``(M,)``."""
    return _corner_sides(p[t])


def _corner_sides(v: NDArray) -> tuple[NDArray, NDArray]:
    """:func:`_sides` of triangles given by their corners ``v (M, 3, 2)``."""
    e = np.roll(v, -1, axis=1) - v
    cross = e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0]
    return e, cross


def _canonical_sides(p: NDArray, t: NDArray) -> tuple[NDArray, NDArray]:
    """:func:`_sides` of each triangle rotated to start at its lowest corner (smallest x,
    then y): values computed from them round the same whatever vertex a row starts with
    and however the points are numbered (the area of one triangle differed in its last
    bit between the rotations ``(a, b, c)`` and ``(b, c, a)``)."""
    v = p[t]
    x = v[..., 0]
    y = np.where(x == x.min(axis=1, keepdims=True), v[..., 1], np.inf)
    first = np.argmin(y, axis=1)  # distinct corners: one lowest (equal ones: any, equal)
    return _corner_sides(v[np.arange(len(v))[:, None], (first[:, None] + np.arange(3)) % 3])


def angles(mesh: Mesh | ArrayLike, triangles: ArrayLike | None = None) -> NDArray[np.float64]:
    """Interior angles ``(M, 3)`` in degrees; column ``i`` is the angle at ``triangles[:, i]``.

    Computed as ``atan2(|cross|, dot)`` of the two edge vectors, accurate also for needles.
    """
    p, t = _arrays(mesh, triangles)
    return corner_angles(p[t])


def corner_angles(corners: ArrayLike) -> NDArray[np.float64]:
    """Interior angles ``(..., 3)`` in degrees of triangles given by their corners.

    Parameters
    ----------
    corners : (..., 3, 2) float
        Corner coordinates; column ``i`` of the result is the angle at corner ``i``.
        Orientation does not matter.
    """
    v = np.asarray(corners, dtype=np.float64)
    a = np.roll(v, -1, axis=-2) - v
    b = np.roll(v, 1, axis=-2) - v
    cross = np.abs(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
    dot = (a * b).sum(axis=-1)
    return np.degrees(np.arctan2(cross, dot))


def min_angles(mesh: Mesh | ArrayLike, triangles: ArrayLike | None = None) -> NDArray[np.float64]:
    """Smallest interior angle ``(M,)`` of each triangle, degrees (60 at best)."""
    return angles(mesh, triangles).min(axis=1)


def max_angles(mesh: Mesh | ArrayLike, triangles: ArrayLike | None = None) -> NDArray[np.float64]:
    """Largest interior angle ``(M,)`` of each triangle, degrees (60 at best)."""
    return angles(mesh, triangles).max(axis=1)


def areas(mesh: Mesh | ArrayLike, triangles: ArrayLike | None = None) -> NDArray[np.float64]:
    """Signed area ``(M,)`` of each triangle (positive for counter-clockwise)."""
    p, t = _arrays(mesh, triangles)
    return 0.5 * _canonical_sides(p, t)[1]


def edge_lengths(mesh: Mesh | ArrayLike,
                 triangles: ArrayLike | None = None) -> NDArray[np.float64]:
    """Side lengths ``(M, 3)``; column ``i`` is the side from vertex ``i`` to vertex ``i + 1``."""
    p, t = _arrays(mesh, triangles)
    e, _ = _sides(p, t)
    return np.hypot(e[..., 0], e[..., 1])


def radius_ratios(mesh: Mesh | ArrayLike,
                  triangles: ArrayLike | None = None) -> NDArray[np.float64]:
    """Normalized radius ratio ``2 r / R`` ``(M,)``: 1 for equilateral, 0 for degenerate.

    ``r`` is the inradius and ``R`` the circumradius; with side lengths ``a, b, c`` and area
    ``A``, ``2 r / R = 16 A^2 / ((a + b + c) a b c)``.
    """
    p, t = _arrays(mesh, triangles)
    e, _ = _canonical_sides(p, t)
    # in units of the longest side, so that neither 4 cross^2 (size^4) nor the product of
    # the lengths underflows or overflows anywhere in the coordinate range (a triangle of
    # size 1e-81 gave 0, of size 1e90 NaN)
    scale = np.hypot(e[..., 0], e[..., 1]).max(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):  # a point triangle: 0/0, read as 0
        e = e / scale[:, None, None]
        lengths = np.hypot(e[..., 0], e[..., 1])
        cross = e[:, 0, 0] * e[:, 1, 1] - e[:, 0, 1] * e[:, 1, 0]
        # 16 A^2 = 4 cross^2; at most 1 exactly (rounding gave 1 + 1 ulp)
        ratio = 4.0 * cross**2 / (lengths.sum(axis=1) * lengths.prod(axis=1))
    return np.minimum(np.nan_to_num(ratio, nan=0.0), 1.0)


def aspect_ratios(mesh: Mesh | ArrayLike,
                  triangles: ArrayLike | None = None) -> NDArray[np.float64]:
    """Aspect ratio ``(M,)``: longest side over smallest altitude, scaled so that an
    equilateral triangle has 1 (``sqrt(3) l_max^2 / (4 A)``); grows without bound."""
    p, t = _arrays(mesh, triangles)
    e, cross = _canonical_sides(p, t)
    lmax2 = (e**2).sum(axis=-1).max(axis=1)
    with np.errstate(divide="ignore"):
        return np.maximum(np.sqrt(3.0) * lmax2 / (2.0 * np.abs(cross)), 1.0)  # >= 1 exactly


#: Similarity tolerances (degrees) that :func:`similarity_classes` takes: finer ones are
#: below the rounding of the angles (about 1e-13 degrees), and would count rounding noise
#: as shapes; coarser than 180 degrees means one class.
TOLERANCE_RANGE = (1e-12, 180.0)


def similarity_classes(
    mesh: Mesh | ArrayLike, triangles: ArrayLike | None = None, *,
    tolerance: float = SIMILARITY_TOLERANCE,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Group triangles by shape (similarity, mirror images included).

    The plane of (smallest, middle) interior angle is cut into square cells of side
    ``tolerance`` degrees; occupied cells that touch (by a side or a corner) form one class.
    So triangles whose two angles are within ``tolerance`` of each other's are always in one
    class (the third angle follows), and rounding noise below ``tolerance`` never splits a
    shape: rounding to the nearest multiple did, for angles near a cell boundary (4T red
    refinement of a Gmsh mesh moved 1e5 from the origin went from 1239 to 1321 classes).

    Returns
    -------
    labels : (M,) int64
        Class of each triangle, ``0 .. C-1``, classes ordered by their smallest angle.
    shapes : (C, 3) float64
        The sorted angles (degrees) of the first triangle of each class.
    """
    lo, hi = TOLERANCE_RANGE
    if not lo <= tolerance <= hi:
        raise ValueError(f"tolerance must be between {lo:g} and {hi:g} degrees, got "
                         f"{tolerance!r} (the angles themselves are computed to about 1e-13 "
                         "degrees)")
    a = np.sort(angles(mesh, triangles), axis=1)
    if not len(a):
        return np.zeros(0, dtype=np.int64), np.zeros((0, 3))
    key = np.floor(a[:, :2] / tolerance).astype(np.int64)
    cells, inverse = np.unique(key, axis=0, return_inverse=True)  # sorted lexicographically
    labels = _touching_cells(cells)[inverse.reshape(-1)]
    _, first = np.unique(labels, return_index=True)
    return labels, a[first]


@njit(cache=True)
def _touching_cells(cells: NDArray[np.int64]) -> NDArray[np.int64]:
    """Component of each of the sorted, distinct ``cells (C, 2)`` under side-or-corner
    contact, numbered ``0 ..`` in the order of their first cell."""
    c = cells.shape[0]
    parent = np.arange(c)

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    def find(x, y):  # binary search for the cell (x, y)
        lo = first_row_at_or_after(cells, 0, c, x, y)
        return lo if lo < c and cells[lo, 0] == x and cells[lo, 1] == y else -1

    for i in range(c):
        for dx, dy in ((0, 1), (1, -1), (1, 0), (1, 1)):  # the other four by symmetry
            j = find(cells[i, 0] + dx, cells[i, 1] + dy)
            if j >= 0:
                a, b = root(i), root(j)
                if a != b:
                    parent[max(a, b)] = min(a, b)
    labels = np.empty(c, dtype=np.int64)
    count = 0
    for i in range(c):
        r = root(i)
        if r == i:
            labels[i] = count
            count += 1
        else:
            labels[i] = labels[r]  # r < i: numbered already
    return labels


#: The most bins :func:`min_angle_histogram` makes.
MAX_BINS = 1_000_000


def min_angle_histogram(
    mesh: Mesh | ArrayLike, triangles: ArrayLike | None = None, *, bin_width: float = 2.5,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Counts of per-triangle minimum angles in bins of ``bin_width`` degrees over ``[0, 60]``
    (at most :data:`MAX_BINS` bins).

    Returns ``counts (B,)`` and ``edges (B+1,)`` as :func:`numpy.histogram` does.
    """
    if not 60 / MAX_BINS <= bin_width <= 60:  # NaN included; 1e-8 asked for 45 GiB
        raise ValueError(f"bin_width must be in [{60 / MAX_BINS:g}, 60] degrees (at most "
                         f"{MAX_BINS} bins), got {bin_width!r}")
    n = int(np.ceil(60.0 / bin_width - 1e-9))
    edges = np.linspace(0.0, n * bin_width, n + 1)
    values = np.clip(min_angles(mesh, triangles), 0.0, edges[-1])  # 60 + rounding counts
    counts, edges = np.histogram(values, bins=edges)
    return counts.astype(np.int64), edges
