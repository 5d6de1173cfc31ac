"""Mesh construction and validation."""

import numpy as np
import pytest

from qdrefine import Mesh, examples

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
TRIS = np.array([[0, 1, 2], [0, 2, 3]])


def test_valid_mesh_is_read_only_and_normalized():
    mesh = Mesh(SQUARE, TRIS, [1, 2], [[0, 1]], [7])
    assert mesh.triangles.dtype == np.int32 and mesh.points.dtype == np.float64
    with pytest.raises(ValueError):
        mesh.points[0, 0] = 5.0
    assert "4 points, 2 triangles" in repr(mesh)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"points": SQUARE[:, :1]}, r"points must have shape \(N, 2\)"),
        ({"points": np.where(SQUARE == 1, np.nan, SQUARE)}, "point 1 has a non-finite"),
        ({"points": SQUARE * 1e101}, "point 1 has a coordinate .* outside the supported range"),
        ({"triangles": TRIS[:, :2]}, r"triangles must have shape \(M, 3\)"),
        ({"triangles": TRIS * 1.0}, "triangles must hold integers"),
        ({"triangles": np.empty((0, 3), int)}, "no triangles"),
        ({"triangles": [[0, 1, 2], [0, 2, 4]]}, r"triangle 1 \(0, 2, 4\) has a vertex index"),
        ({"triangles": [[0, 1, 2], [0, 3, 2]]}, r"triangle 1 \(0, 3, 2\) is clockwise"),
        ({"triangles": [[0, 1, 2], [0, 2, 0]]}, "triangle 1 .* has zero area"),
        ({"cell_tags": [1]}, r"cell_tags must have shape \(2,\)"),
        ({"edges": [[0, 1]]}, "edges and edge_tags must be given together"),
        ({"edges": [[0, 1]], "edge_tags": [1, 2]}, r"edge_tags must have shape \(1,\)"),
        ({"edges": [[1, 3]], "edge_tags": [1]}, r"edge 0 \(1, 3\) is not an edge"),
        ({"edges": [[1, 9]], "edge_tags": [1]}, r"edge 0 \(1, 9\) has a vertex index"),
    ],
)
def test_bad_input_names_the_problem(kwargs, message):
    args = {"points": SQUARE, "triangles": TRIS} | kwargs
    with pytest.raises(ValueError, match=message):
        Mesh(**args)


def test_examples_are_valid():
    mesh = examples.plate_with_hole()
    assert set(np.unique(mesh.edge_tags)) == {examples.OUTER, examples.HOLE}
    assert set(np.unique(mesh.cell_tags)) == {examples.LEFT, examples.RIGHT}
    assert examples.square(3).n_triangles == 18
