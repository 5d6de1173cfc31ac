"""Point and cell data through uniform refinement (:mod:`qdrefine.fields`), in the API and
the command line."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import qdrefine
from meshes import jittered_grid
from qdrefine import Mesh, coarsen, examples, refine, scheme_names
from qdrefine.cli import main
from qdrefine.fields import centroid_value, edge_value, inherit_cell_data, interpolate_point_data


@settings(max_examples=20, deadline=None, derandomize=True)
@given(st.integers(1, 7), st.integers(0, 1000), st.sampled_from(scheme_names()),
       st.integers(1, 2), st.sampled_from([1.0, 1e-5, 7e4]),
       st.tuples(*[st.floats(-1e3, 1e3, allow_nan=False)] * 3))
def test_coordinates_and_linear_fields_are_reproduced(n, seed, scheme, levels, scale, c):
    """The coordinate fields come out bit for bit equal to the refined points (the same
    formula); a linear field ``c0 + c1 x + c2 y`` within a few ulps of its exact value."""
    base = jittered_grid(n, seed=seed, shear=0.2)
    p = base.points * scale
    linear = c[0] + c[1] * p[:, 0] + c[2] * p[:, 1]
    mesh = Mesh(p, base.triangles, base.cell_tags, base.edges, base.edge_tags,
                point_data={"x": p[:, 0], "xy": p, "f": linear},
                cell_data={"id": np.arange(base.n_triangles)},
                physical_names={(2, 1): "inside"})
    fine = refine(mesh, scheme, levels)
    assert fine.point_data["x"].tobytes() == fine.points[:, 0].tobytes()
    assert fine.point_data["xy"].tobytes() == fine.points.tobytes()
    exact = c[0] + c[1] * fine.points[:, 0] + c[2] * fine.points[:, 1]
    size = abs(c[0]) + (abs(c[1]) + abs(c[2])) * np.abs(fine.points).max()
    assert np.abs(fine.point_data["f"] - exact).max() <= 16 * np.finfo(float).eps * size
    t = fine.n_triangles // mesh.n_triangles
    assert np.array_equal(fine.cell_data["id"], np.repeat(np.arange(mesh.n_triangles), t))
    assert dict(fine.physical_names) == {(2, 1): "inside"}


def test_integer_and_vector_fields():
    base = jittered_grid(3, seed=1)
    mesh = base.replace(point_data={"i": np.arange(base.n_points),
                                    "v": np.ones((base.n_points, 2, 2))},
                        cell_data={"m": np.ones((base.n_triangles, 3), np.int32)})
    fine = refine(mesh, "7t-qd")
    assert fine.point_data["i"].dtype == np.float64
    assert fine.point_data["v"].shape == (fine.n_points, 2, 2)
    assert (fine.point_data["v"] == 1).all()
    assert fine.cell_data["m"].dtype == np.int32 and fine.cell_data["m"].shape == (
        fine.n_triangles, 3)


def test_helpers_for_local_refinement():
    """The helpers take any split edges (in the order of their new points) and parents."""
    values = {"u": np.array([0.0, 3.0, 6.0, 9.0])}
    ends = np.array([[0, 3], [1, 2]])
    assert interpolate_point_data(values, ends, 2)["u"].tolist() == [3.0, 6.0, 4.0, 5.0]
    assert interpolate_point_data(values, ends, 1)["u"].tolist() == [4.5, 4.5]
    with pytest.raises(ValueError, match="must be 1 or 2"):
        interpolate_point_data(values, ends, 3)
    cells = inherit_cell_data({"m": np.array([5, 6])}, np.array([1, 1, 0]))
    assert cells["m"].tolist() == [6, 6, 5]


@pytest.mark.parametrize("ext", [".msh", ".vtu", ".xdmf"])
def test_command_line_keeps_data_and_names(tmp_path, ext):
    base = jittered_grid(4, seed=6)
    mesh = base.replace(point_data={"T": 2.0 + 3.0 * base.points[:, 0]},
                        cell_data={"material": np.arange(base.n_triangles) % 3},
                        physical_names={(2, 1): "steel", (1, 2): "wall"})
    qdrefine.write(tmp_path / f"in{ext}", mesh)
    assert main(["refine", str(tmp_path / f"in{ext}"), str(tmp_path / f"out{ext}"), "-q"]) == 0
    fine = qdrefine.read(tmp_path / f"out{ext}")
    expected = refine(mesh, "7t-qd")
    assert fine.point_data["T"].tobytes() == expected.point_data["T"].tobytes()
    assert np.array_equal(fine.cell_data["material"], expected.cell_data["material"])
    assert dict(fine.physical_names) == dict(mesh.physical_names)


def test_command_line_format_version(tmp_path):
    qdrefine.write(tmp_path / "in.msh", jittered_grid(3, seed=2))
    for argv, head in ((["refine"], "4.1 0 8"), (["refine", "--format-version", "2.2"], "2.2 0 8"),
                       (["convert", "--format-version", "2.2", "--binary"], "2.2 1 8")):
        out = tmp_path / "out.msh"
        assert main([*argv, str(tmp_path / "in.msh"), str(out), "-q"]) == 0
        assert out.read_bytes().split(b"\n")[1].decode() == head
        out.unlink()
    assert main(["convert", str(tmp_path / "in.msh"), str(tmp_path / "o.vtu"),
                 "--format-version", "2.2", "-q"]) == 2  # options that do not go together
    assert not (tmp_path / "o.vtu").exists()


def test_local_refinement_and_coarsening_keep_floating_dtypes():
    """float32 and float16 fields stay so through local refinement and coarsening, as in
    uniform refinement (they became float64; data review, 2026-11-27); integers become
    float64 everywhere."""
    mesh = examples.gmsh_mesh("l_shape")
    x = mesh.points[:, 0]
    mesh = mesh.replace(point_data={"f4": x.astype(np.float32), "f2": x.astype(np.float16),
                                    "i": np.arange(mesh.n_points)})
    want = {"f4": np.float32, "f2": np.float16, "i": np.float64}
    fine = refine(mesh, marked=[0, 5])
    for out in (refine(mesh), fine, refine(mesh, marked=np.ones(mesh.n_triangles, bool)),
                coarsen(fine, np.ones(fine.n_triangles, bool))):
        assert {k: v.dtype for k, v in out.point_data.items()} == \
            {k: np.dtype(t) for k, t in want.items()}


def test_narrow_floats_are_interpolated_in_float64():
    """A float16 field of 60000 (representable) became inf at the new points: ``2 a + b``
    overflowed in the field's own dtype (review). Computed in float64, rounded once."""
    mesh = examples.square(2)
    big = np.full(mesh.n_points, 60000, dtype=np.float16)
    x = mesh.points[:, 0]
    mesh = mesh.replace(point_data={"big": big, "x": x.astype(np.float32)})
    for fine in (refine(mesh), refine(mesh, marked=[0]), refine(mesh, "4t-le")):
        assert fine.point_data["big"].dtype == np.float16
        assert (fine.point_data["big"] == 60000).all()
        want = fine.points[:, 0].astype(np.float32)  # one rounding of the float64 value
        assert np.array_equal(fine.point_data["x"], want)


def test_helpers_refuse_ids_outside_the_fields():
    """-1 took the last point or triangle silently, and k = 0 gave nothing (review)."""
    u = {"u": np.array([1.0, 2.0])}
    for ends, k, message in (([[0, -1]], 2, "edge_ends has id -1, outside the 2 rows"),
                             ([[0, 5]], 2, "edge_ends has id 5"),
                             ([[0.0, 1.0]], 2, "edge_ends must hold integers"),
                             ([[0, 1]], 0, "k must be 1 or 2")):
        with pytest.raises(ValueError, match=message):
            interpolate_point_data(u, ends, k)
    with pytest.raises(ValueError, match="parents has id -1, outside the 2 rows of cell_data"):
        inherit_cell_data({"c": np.array([1, 2])}, [-1])
    # a uint64 id of 2**63 or more is named as given (it wrapped to a negative id)
    with pytest.raises(ValueError, match="parents has id 9223372036854775809, outside"):
        inherit_cell_data({"c": np.array([1, 2])}, np.array([2**63 + 1], np.uint64))
    assert interpolate_point_data({"u": np.array([1.0, 4.0])}, [[0, 1]], 2)["u"].tolist() == \
        [2.0, 3.0]


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=3,
                max_size=3), st.sampled_from([(0, 1), (0, 2), (1, 2)]))
def test_new_values_do_not_overflow_where_the_old_ones_did_not(abc, jk):
    """A constant field of 1e308 became inf at every new point: 2 a + b overflowed
    (review). Where the formula overflows it is computed on the values scaled by 1/4 (a
    convex combination lies between its ends); elsewhere it is the formula, unchanged."""
    a, b, c = (np.array([v]) for v in abc)
    j, k = jk
    for got, ends in ((edge_value(a, b, j, k), abc[:2]), (centroid_value(a, b, c), abc)):
        assert np.isfinite(got[0])
        with np.errstate(over="ignore"):  # the spacing of the largest float is inf
            ulps = 4 * np.spacing(max(abs(v) for v in ends))  # roundings of the formula
            assert min(ends) - ulps <= got[0] <= max(ends) + ulps
    plain = {(0, 1): lambda a, b: (a + b) * 0.5, (0, 2): lambda a, b: (2.0 * a + b) / 3.0,
             (1, 2): lambda a, b: (a + 2.0 * b) / 3.0}[jk]
    with np.errstate(over="ignore"):
        want = plain(a, b)
    if np.isfinite(want).all():
        assert edge_value(a, b, j, k)[0] == want[0]
    big = np.full(4, np.finfo(np.float64).max)
    assert (edge_value(big, big, 0, 2) == big).all()
    assert (centroid_value(-big, -big, -big) == -big).all()


def test_a_field_of_1e308_stays_finite_through_refinement():
    mesh = examples.square(3)
    mesh = mesh.replace(point_data={"u": np.full(mesh.n_points, 1e308)})
    for kwargs in ({}, {"marked": [0]}):
        assert (refine(mesh, "7t-qd", **kwargs).point_data["u"] == 1e308).all()
    assert (refine(mesh, "4t-le").point_data["u"] == 1e308).all()
