"""Test meshes: the folder of the mesh files (:data:`DATA`) and random conforming meshes."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from qdrefine import Mesh, examples

#: The test mesh files (``tests/data``).
DATA = Path(__file__).parent / "data"


def jittered_grid(n: int, seed: int, shear: float = 0.0, shuffle: bool = True) -> Mesh:
    """:func:`qdrefine.examples.jittered_square`, vertices and triangles shuffled or not."""
    return examples.jittered_square(n, seed, shear, "all" if shuffle else "none")


def crack(shift: int, along: float, offset: float, scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Two triangles: the second's vertex ``shift`` float steps (of its y) off the first's
    edge, outside it (``shift <= 0``: on or across it; not a mesh then)."""
    a = np.array([offset, 0.7 * offset])
    d, n = np.array([1.0, 0.37]) * scale, np.array([0.37, -1.0]) * scale
    v = a + along * d
    v[1] = v[1] - shift * np.spacing(v[1])
    points = np.array([a, a + d, a + 0.5 * d - 0.8 * n, v, v + n + 0.3 * d, v + n - 0.3 * d])
    return points, np.array([[0, 1, 2], [3, 5, 4]])
