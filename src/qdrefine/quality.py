"""Per-triangle quality measures (vectorized; one value per triangle)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .mesh import Mesh

__all__ = ["angles", "min_angles"]


def angles(points: NDArray[np.float64], triangles: NDArray[np.integer]) -> NDArray[np.float64]:
    """Interior angles ``(M, 3)`` in degrees; column ``i`` is the angle at ``triangles[:, i]``.

    Computed as ``atan2(|cross|, dot)`` of the two edge vectors, accurate also for needles.
    """
    p = points[triangles]  # (M, 3, 2)
    a = np.roll(p, -1, axis=1) - p
    b = np.roll(p, 1, axis=1) - p
    cross = np.abs(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
    dot = (a * b).sum(axis=-1)
    return np.degrees(np.arctan2(cross, dot))


def min_angles(mesh: Mesh) -> NDArray[np.float64]:
    """Smallest interior angle ``(M,)`` of each triangle, degrees."""
    return angles(mesh.points, mesh.triangles).min(axis=1)
