"""What the Gmsh reader and writer share: the versions written, the element types, the
error type."""

from __future__ import annotations

__all__ = ["VERSIONS", "ELEMENTS", "EXACT_INT", "GmshError"]

#: Versions written (the first is the default).
VERSIONS = ("4.1", "2.2")

#: Gmsh element types: (meshio's name, nodes per element).
ELEMENTS: dict[int, tuple[str, int]] = {
    1: ("line", 2), 2: ("triangle", 3), 3: ("quad", 4), 4: ("tetra", 4), 5: ("hexahedron", 8),
    6: ("wedge", 6), 7: ("pyramid", 5), 8: ("line3", 3), 9: ("triangle6", 6),
    10: ("quad9", 9), 11: ("tetra10", 10), 12: ("hexahedron27", 27), 13: ("wedge18", 18),
    14: ("pyramid14", 14), 15: ("vertex", 1), 16: ("quad8", 8), 17: ("hexahedron20", 20),
    18: ("wedge15", 15), 19: ("pyramid13", 13), 20: ("triangle9", 9), 21: ("triangle10", 10),
    22: ("triangle12", 12), 23: ("triangle15", 15), 24: ("triangle15", 15),
    25: ("triangle21", 21), 26: ("line4", 4), 27: ("line5", 5), 28: ("line6", 6),
    29: ("tetra20", 20), 30: ("tetra35", 35), 31: ("tetra56", 56), 36: ("quad16", 16),
    37: ("quad25", 25), 38: ("quad36", 36), 92: ("hexahedron64", 64),
}


def element_dimension(typ: int) -> int:
    """The dimension of Gmsh element type ``typ`` (a key of :data:`ELEMENTS`)."""
    name = ELEMENTS[typ][0]
    return 0 if name == "vertex" else 1 if name.startswith("line") else \
        2 if name.startswith(("triangle", "quad")) else 3


#: Integers stored as doubles are exact below this.
EXACT_INT = 2**53


class GmshError(ValueError):
    """A structural problem of an MSH file; ``where`` is ``"line N"`` or ``"byte N"``."""
