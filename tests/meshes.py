"""Test meshes: the folder of the mesh files (:data:`DATA`) and random conforming meshes."""

from __future__ import annotations

from pathlib import Path

from qdrefine import Mesh, examples

#: The test mesh files (``tests/data``).
DATA = Path(__file__).parent / "data"


def jittered_grid(n: int, seed: int, shear: float = 0.0, shuffle: bool = True) -> Mesh:
    """:func:`qdrefine.examples.jittered_square`, vertices and triangles shuffled or not."""
    return examples.jittered_square(n, seed, shear, "all" if shuffle else "none")
