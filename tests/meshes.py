"""Random conforming test meshes."""

from __future__ import annotations

from qdrefine import Mesh, examples


def jittered_grid(n: int, seed: int, shear: float = 0.0, shuffle: bool = True) -> Mesh:
    """:func:`qdrefine.examples.jittered_square`, vertices and triangles shuffled or not."""
    return examples.jittered_square(n, seed, shear, "all" if shuffle else "none")
