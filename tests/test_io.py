"""Reading and writing every format: round trips, Gmsh files with tags, bad input."""

import os
import stat
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import qdrefine
from meshes import DATA, jittered_grid
from qdrefine import Mesh, examples, io, quality

TAGGED = [ext for ext, f in io.FORMATS.items() if f.tags]
UNTAGGED = [ext for ext, f in io.FORMATS.items() if not f.tags]


def same_mesh(a: Mesh, b: Mesh) -> None:
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.triangles, b.triangles)
    for name in ("cell_tags", "edges", "edge_tags"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y)


def triangle_set(m: Mesh) -> set:
    """Triangles as sets of coordinate tuples (independent of numbering and rotation)."""
    return {frozenset(map(tuple, m.points[t].tolist())) for t in m.triangles}


@pytest.mark.parametrize("ext", TAGGED)
def test_round_trip_keeps_everything(tmp_path, ext):
    mesh = jittered_grid(6, seed=3)  # shuffled, cell tags 0/1, edge tags 1..4
    path = tmp_path / f"m{ext}"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        qdrefine.write(path, mesh)
        back = qdrefine.read(path)
    same_mesh(mesh, back)


@pytest.mark.parametrize("ext", [ext for ext, f in io.FORMATS.items() if f.binary is not None])
def test_binary_round_trip(tmp_path, ext):
    mesh = jittered_grid(6, seed=5)
    if not io.FORMATS[ext].tags:
        mesh = Mesh(mesh.points, mesh.triangles)
    if ext == ".stl":  # float32 coordinates: only meshes whose points fit are written
        mesh = Mesh(mesh.points.astype(np.float32).astype(np.float64), mesh.triangles)
    qdrefine.write(tmp_path / f"m{ext}", mesh, binary=True)
    back = qdrefine.read(tmp_path / f"m{ext}")
    if ext == ".stl":  # points merged and renumbered
        assert triangle_set(back) == triangle_set(mesh)
        return
    same_mesh(mesh, back)


def test_binary_msh_written_in_pieces_is_the_same_file(tmp_path, monkeypatch):
    """The binary MSH 4.1 writer streams nodes and elements through one reused buffer of
    ``BINARY_ROWS`` rows: pieces of 7 rows (every section cut many times, tags and tagged
    edges included) give the same bytes as one piece."""
    from qdrefine.io.gmsh import writing

    mesh = qdrefine.refine(examples.plate_with_hole(8, 2))
    qdrefine.write(tmp_path / "whole.msh", mesh, binary=True)
    monkeypatch.setattr(writing, "BINARY_ROWS", 7)
    qdrefine.write(tmp_path / "pieces.msh", mesh, binary=True)
    assert (tmp_path / "whole.msh").read_bytes() == (tmp_path / "pieces.msh").read_bytes()
    back = qdrefine.read(tmp_path / "pieces.msh")
    np.testing.assert_array_equal(back.points, mesh.points)
    np.testing.assert_array_equal(back.triangles, mesh.triangles)
    np.testing.assert_array_equal(back.edges, mesh.edges)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(-3, 3), min_size=1, max_size=40),
       st.sampled_from([1, 300, 70_000, 2**40]))
def test_tag_groups_is_a_stable_grouping(small, scale):
    """The writer's grouping of rows by tag (8/16-bit radix keys for narrow tag ranges,
    a stable sort otherwise) against argsort and unique."""
    from qdrefine.io.gmsh.writing import tag_groups

    empty = tag_groups(np.empty(0, dtype=np.int64))
    assert empty[1] is None and empty[0].size == empty[2].size == 0
    tags = np.array(small, dtype=np.int64) * scale
    values, order, sizes = tag_groups(tags)
    expect = np.argsort(tags, kind="stable")
    distinct, counts = np.unique(tags, return_counts=True)
    np.testing.assert_array_equal(values, distinct)
    np.testing.assert_array_equal(sizes, counts)
    if order is None:
        assert distinct.size == 1
    else:
        np.testing.assert_array_equal(order, expect)


def test_binary_is_refused_where_there_is_none(tmp_path):
    with pytest.raises(ValueError, match="no binary variant"):
        qdrefine.write(tmp_path / "m.xdmf", examples.square(1), binary=True)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("ext", TAGGED)
def test_round_trip_without_tags(tmp_path, ext):
    mesh = examples.square(3)
    qdrefine.write(tmp_path / f"m{ext}", mesh)
    same_mesh(mesh, qdrefine.read(tmp_path / f"m{ext}"))


@pytest.mark.parametrize("ext", TAGGED)
def test_round_trip_edges_without_cell_tags(tmp_path, ext):
    m = jittered_grid(3, seed=1)
    mesh = Mesh(m.points, m.triangles, None, m.edges, m.edge_tags)
    qdrefine.write(tmp_path / f"m{ext}", mesh)
    same_mesh(mesh, qdrefine.read(tmp_path / f"m{ext}"))


@pytest.mark.parametrize("ext", UNTAGGED)
def test_formats_without_tags_keep_the_geometry_and_warn(tmp_path, ext):
    mesh = jittered_grid(5, seed=7)
    with pytest.warns(UserWarning, match="hold no tags"):
        qdrefine.write(tmp_path / f"m{ext}", mesh)
    back = qdrefine.read(tmp_path / f"m{ext}")
    assert back.cell_tags is None and back.edges is None
    if ext == ".stl":  # STL stores each triangle's corners: points are merged and renumbered
        assert triangle_set(back) == triangle_set(mesh)
    else:
        np.testing.assert_array_equal(back.points, mesh.points)
        np.testing.assert_array_equal(back.triangles, mesh.triangles)


def test_gmsh_22_and_41_files_with_physical_groups():
    m22 = qdrefine.read(DATA / "two_regions_22.msh")
    m41 = qdrefine.read(DATA / "two_regions_41.msh")
    same_mesh(m22, m41)
    assert m22.points.shape == (36, 2)
    area = quality.areas(m22)
    for tag in (1, 2):  # two unit squares
        assert area[m22.cell_tags == tag].sum() == pytest.approx(1.0)
    lengths = np.linalg.norm(np.diff(m22.points[m22.edges], axis=1)[:, 0], axis=1)
    expected = {10: 2.0, 11: 1.0, 12: 2.0, 13: 1.0, 20: 1.0}  # bottom, outlet, top, inlet, mid
    assert sorted(np.unique(m22.edge_tags).tolist()) == sorted(expected)
    for tag, length in expected.items():
        assert lengths[m22.edge_tags == tag].sum() == pytest.approx(length)


def test_msh_output_is_version_41_by_default_and_22_on_request(tmp_path):
    mesh = examples.plate_with_hole()
    qdrefine.write(tmp_path / "a.msh", mesh)
    assert (tmp_path / "a.msh").read_text().startswith("$MeshFormat\n4.1 0 8\n")
    qdrefine.write(tmp_path / "b.msh", mesh, format_version="2.2")
    text = (tmp_path / "b.msh").read_text()
    assert text.startswith("$MeshFormat\n2.2 0 8\n")
    # element type 1 (line) with physical tag 2 (the hole)
    assert any(line.split()[1:4] == ["1", "2", "2"] for line in
               text.split("$Elements\n")[1].splitlines()[1:] if len(line.split()) > 3)
    for name in ("a.msh", "b.msh"):
        same_mesh(mesh, qdrefine.read(tmp_path / name))
    with pytest.raises(ValueError, match="version must be one of 4.1, 2.2"):
        qdrefine.write(tmp_path / "c.msh", mesh, format_version="3")
    with pytest.raises(ValueError, match="Gmsh .msh files only"):
        qdrefine.write(tmp_path / "c.vtu", mesh, format_version="2.2")
    assert not (tmp_path / "c.msh").exists() and not (tmp_path / "c.vtu").exists()


def msh22(nodes, elements) -> str:
    """A hand-made Gmsh 2.2 ASCII file: nodes (x, y, z), elements (type, physical, nodes)."""
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", str(len(nodes))]
    out += [f"{i + 1} {x!r} {y!r} {z!r}" for i, (x, y, z) in enumerate(nodes)]
    out += ["$EndNodes", "$Elements", str(len(elements))]
    out += [f"{i + 1} {typ} 2 {tag} {tag} " + " ".join(str(v) for v in vs)
            for i, (typ, tag, vs) in enumerate(elements)]
    out += ["$EndElements", ""]
    return "\n".join(out)


SQUARE_NODES = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0)]


def test_clockwise_triangles_are_flipped_with_a_warning(tmp_path):
    path = tmp_path / "cw.msh"
    path.write_text(msh22(SQUARE_NODES, [(2, 1, (1, 2, 3)), (2, 1, (1, 3, 4)[::-1])]))
    with pytest.warns(UserWarning, match="1 of 2 triangles were clockwise"):
        m = qdrefine.read(path)
    assert (quality.areas(m) > 0).all()


BAD_MSH = {
    "not flat": msh22([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.5)], [(2, 1, (1, 2, 3))]),
    "holds no triangles": msh22(SQUARE_NODES, [(1, 1, (1, 2))]),
    "4 quad cells": msh22(SQUARE_NODES, [(3, 1, (1, 2, 3, 4))] * 4),
    "zero area": msh22(SQUARE_NODES[:2] + [(2.0, 0.0, 0.0)], [(2, 1, (1, 2, 3))]),
    "non-finite": msh22([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (float("nan"), 1.0, 0.0)],
                        [(2, 1, (1, 2, 3))]),
    "not an edge of any triangle": msh22(SQUARE_NODES, [(2, 1, (1, 2, 3)), (2, 1, (1, 3, 4)),
                                                        (1, 5, (2, 4))]),
    "not a readable": "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n",
}


@pytest.mark.parametrize("problem", list(BAD_MSH))
def test_bad_gmsh_content_is_refused_naming_the_file(tmp_path, problem):
    path = tmp_path / "bad.msh"
    path.write_text(BAD_MSH[problem])
    with pytest.raises(ValueError, match=problem) as info:
        qdrefine.read(path)
    assert str(path) in str(info.value)


def test_bad_files_and_names(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.msh: no such file"):
        qdrefine.read(tmp_path / "missing.msh")
    with pytest.raises(ValueError, match=r"unknown file format \(extension '.xyz'\)"):
        qdrefine.read(tmp_path / "a.xyz")
    with pytest.raises(ValueError, match="unknown file format"):
        qdrefine.write(tmp_path / "a.xyz", examples.square(1))
    with pytest.raises(ValueError, match=r"a\.zarr: a Zarr mesh store, not a mesh file: "
                                         r"qdrefine\.store reads it \(command line: 'qdrefine "
                                         r"convert STORE FILE'"):
        qdrefine.read(tmp_path / "a.zarr")  # info, plot, ... on a store (review)
    (tmp_path / "junk.vtu").write_bytes(os.urandom(300))
    with pytest.raises(ValueError, match="junk.vtu: not a readable VTK XML"):
        qdrefine.read(tmp_path / "junk.vtu")
    (tmp_path / "dir.msh").mkdir()
    with pytest.raises(IsADirectoryError):
        qdrefine.read(tmp_path / "dir.msh")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        qdrefine.write(tmp_path / "nowhere" / "a.msh", examples.square(1))
    assert not (tmp_path / "nowhere").exists()


class _DiskFull:
    """A file whose writes fail after writing "partial"."""

    def __init__(self, path, mode="w", *args, **kwargs):
        self.f = open(path, mode)  # noqa: SIM115

    def write(self, data):
        self.f.write(b"partial" if "b" in self.f.mode else "partial")
        raise RuntimeError("disk full")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.f.close()


@pytest.mark.parametrize("ext", [".vtk", ".vtu", ".msh", ".node", ".xdmf"])
def test_write_is_atomic(tmp_path, monkeypatch, ext):
    """A failure while writing leaves the old files as they were and no stray file, for
    meshio's writers and ours (Triangle's and XDMF's file sets included)."""
    import meshio

    from qdrefine.io import triangle, vtu, xdmf
    from qdrefine.io.gmsh import writing as gmsh_writing

    names = {".node": ["keep.node", "keep.ele", "keep.poly"],
             ".xdmf": ["keep.xdmf", "keep.h5"]}.get(ext, [f"keep{ext}"])
    for name in names:
        (tmp_path / name).write_text("old content")

    def broken(filename, *args, **kwargs):
        with open(filename, "w") as f:
            f.write("partial")
        raise RuntimeError("disk full")

    monkeypatch.setattr(meshio, "write", broken)
    for module in (gmsh_writing, vtu, triangle):
        monkeypatch.setattr(module, "open", _DiskFull, raising=False)
    monkeypatch.setattr(Path, "write_text", lambda self, *a, **k: broken(self))
    with pytest.raises(RuntimeError, match="disk full"):
        qdrefine.write(tmp_path / names[0], jittered_grid(4, seed=2))
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names)
    assert all((tmp_path / name).read_text() == "old content" for name in names)
    del xdmf


def test_new_files_get_ordinary_permissions(tmp_path):
    """A new file, and an output that is a link to a device, which is replaced by an ordinary
    file (it took the device's 0666; review)."""
    (tmp_path / "b.msh").symlink_to("/dev/null")
    umask = os.umask(0o022)
    try:
        for name in ("a.vtk", "b.msh"):
            qdrefine.write(tmp_path / name, examples.square(1))
    finally:
        os.umask(umask)
    for name in ("a.vtk", "b.msh"):
        assert stat.S_IMODE((tmp_path / name).stat().st_mode) == 0o644


# Triangle's own files -------------------------------------------------------------------

NODE = """# a unit square with its centre, numbered from 1
5 2 0 1
1 0 0 1
2 1 0 1
3 1 1 1
4 0 1 1
5 0.5 0.5 0
"""
ELE = """4 3 1
1 1 2 5 7
2 2 3 5 7
3 3 4 5 8   # a comment
4 4 1 5 8
"""
POLY = """0 2 0 1
4 1
1 1 2 3
2 2 3 3
3 3 4 0
4 4 1 9
0
"""


def test_triangle_files_numbered_from_one(tmp_path):
    for ext, text in ((".node", NODE), (".ele", ELE), (".poly", POLY)):
        (tmp_path / f"sq{ext}").write_text(text)
    for name in ("sq.ele", "sq.node", "sq.poly"):
        m = qdrefine.read(tmp_path / name)
        np.testing.assert_array_equal(m.triangles, [[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])
        np.testing.assert_array_equal(m.cell_tags, [7, 7, 8, 8])
        np.testing.assert_array_equal(m.edges, [[0, 1], [1, 2], [3, 0]])  # marker 0 dropped
        np.testing.assert_array_equal(m.edge_tags, [3, 3, 9])


@pytest.mark.parametrize("n_attr", [1, 2])
def test_triangle_vertex_attributes_are_point_data(tmp_path, n_attr):
    """The vertex attributes of a ``.node`` file were dropped silently (review). They are
    point data now, which refinement interpolates linearly, as Triangle does: a linear
    attribute is linear on the refined mesh; writing Triangle files drops them with the
    formats' warning."""
    p = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]])
    values = np.c_[p[:, 0] + 2 * p[:, 1], 3 - p[:, 0]][:, :n_attr]
    rows = [f"{i + 1} {x:g} {y:g} " + " ".join(f"{v:g}" for v in values[i]) + " 1"
            for i, (x, y) in enumerate(p)]
    (tmp_path / "a.node").write_text(f"5 2 {n_attr} 1\n" + "\n".join(rows) + "\n")
    (tmp_path / "a.ele").write_text(ELE)
    m = qdrefine.read(tmp_path / "a.ele")
    assert np.array_equal(m.point_data["attributes"], values[:, 0] if n_attr == 1 else values)
    fine = qdrefine.refine(m)
    want = np.c_[fine.points[:, 0] + 2 * fine.points[:, 1], 3 - fine.points[:, 0]][:, :n_attr]
    np.testing.assert_allclose(fine.point_data["attributes"].reshape(-1, n_attr), want,
                               rtol=0, atol=1e-15)
    # read, but not written back (a gap: the warning says so, review)
    with pytest.warns(UserWarning, match="are written without vertex attributes or any other "
                                         "data; attributes dropped"):
        qdrefine.write(tmp_path / "b.node", m)


def test_a_triangle_attribute_count_beyond_its_lines_is_refused_before_allocating(tmp_path):
    """10**12 attributes per vertex in the header would have allocated them for each vertex
    before reading a line (review of the attributes' reading)."""
    (tmp_path / "h.node").write_text("4 2 1000000000000 0\n1 0 0 5\n2 1 0 7\n3 1 1 9\n"
                                     "4 0 1 11\n")
    (tmp_path / "h.ele").write_text("2 3 0\n1 1 2 3\n2 1 3 4\n")
    with pytest.raises(ValueError, match=r"h.node:2: the header announces 1000000000000 "
                                         "attributes per vertex, vertex 1 has 1"):
        qdrefine.read(tmp_path / "h.node")


def test_triangle_without_poly_has_no_edges(tmp_path):
    (tmp_path / "sq.node").write_text(NODE)
    (tmp_path / "sq.ele").write_text(ELE)
    assert qdrefine.read(tmp_path / "sq.ele").edges is None


def test_triangle_write_replaces_a_stale_poly(tmp_path):
    (tmp_path / "m.poly").write_text(POLY)
    qdrefine.write(tmp_path / "m.ele", examples.square(2))
    assert qdrefine.read(tmp_path / "m.ele").edges is None


@pytest.mark.parametrize("tag", [2**53 + 1, 2**62, 2**63 - 1, -2**63])
def test_triangle_files_keep_any_int64_tag(tmp_path, tag):
    """Tags went through float64: 2**53 + 1 came back as 2**53, and tags from 2**62 on were
    written but refused on reading (review)."""
    mesh = examples.plate_with_hole()
    mesh = mesh.replace(cell_tags=np.full(mesh.n_triangles, tag),
                        edge_tags=np.full(len(mesh.edges), tag))
    qdrefine.write(tmp_path / "m.node", mesh)
    back = qdrefine.read(tmp_path / "m.node")
    assert back.cell_tags.tolist() == mesh.cell_tags.tolist()
    assert back.edge_tags.tolist() == mesh.edge_tags.tolist()


def test_triangle_tags_written_as_floats_read_exactly(tmp_path):
    """Triangle writes attributes as floating-point numbers: 1e3 and 7.0 are tags."""
    (tmp_path / "sq.node").write_text(NODE)
    (tmp_path / "sq.ele").write_text(ELE.replace("5 7\n", "5 1e3\n", 1).replace("5 7\n",
                                                                                   "5 7.0\n"))
    assert qdrefine.read(tmp_path / "sq.ele").cell_tags.tolist() == [1000, 7, 8, 8]


BAD_TRIANGLE = {
    "bad number": (".node", NODE.replace("2 1 0 1", "2 1 x 1"), "sq.node:4: expected numbers"),
    "truncated": (".node", "\n".join(NODE.splitlines()[:4]), "sq.node:2: file ends early"),
    "dimension": (".node", NODE.replace("5 2 0 1", "5 3 0 1"), "sq.node:2: dimension must be 2"),
    "numbering": (".node", NODE.replace("4 0 1 1", "7 0 1 1"), "sq.node:6: expected vertex 4"),
    "out of range": (".ele", ELE.replace("1 1 2 5 7", "1 1 2 6 7"),
                     "sq.ele:2: vertex 6 is not in sq.node"),
    "not integer tag": (".ele", ELE.replace("5 7\n", "5 7.5\n", 1),
                        "sq.ele:2: the regional attribute 7.5"),
    # a float literal beyond 2**53 names no one integer (review: such tags were rounded)
    "float tag beyond 2**53": (".ele", ELE.replace("5 7\n", "5 9007199254740993.0\n", 1),
                               "sq.ele:2: the regional attribute 9007199254740993.0 is a "
                               "number of 2\\*\\*53 or more written as a float"),
    "tag beyond int64": (".ele", ELE.replace("5 7\n", f"5 {2**63}\n", 1),
                         f"sq.ele:2: the regional attribute {2**63} is beyond int64"),
    # Python's int() read 1_0 as 10 and Arabic-Indic digits as digits (review)
    "underscore": (".ele", ELE.replace("1 1 2 5 7", "1 1 2 5 1_0"),
                   "sq.ele:2: expected a number, got '1_0'"),
    "other digits": (".node", NODE.replace("2 1 0 1", "2 \u0661 0 1"),
                     "sq.node:4: expected a number, got '\u0661'"),
    "marker": (".poly", POLY.replace("1 1 2 3", "1 1 2 x"),
               "sq.poly:3: expected a number in the boundary marker, got 'x'"),
    "no triangles": (".ele", "0 3 0\n", "sq.ele: holds no triangles"),
    "segment": (".poly", POLY.replace("1 1 2 3", "1 1 3 3"),
                "sq.poly:3: edge 0 \\(1, 3\\) is not an edge"),
    "zero area": (".node", NODE.replace("5 0.5 0.5 0", "5 0.5 0 0"),
                  "sq.ele:2: triangle 1 \\(1, 2, 5\\) has zero area"),
}


@pytest.mark.parametrize("problem", list(BAD_TRIANGLE))
def test_bad_triangle_files_name_file_and_line(tmp_path, problem):
    ext, text, message = BAD_TRIANGLE[problem]
    files = {".node": NODE, ".ele": ELE, ".poly": POLY}
    files[ext] = text
    for e, t in files.items():
        (tmp_path / f"sq{e}").write_text(t)
    with pytest.raises(ValueError, match=message):
        qdrefine.read(tmp_path / "sq.ele")
    with pytest.raises(FileNotFoundError, match="other.node: no such file"):
        qdrefine.read(tmp_path / "other.ele")


def test_check_file_lists_every_problem_with_its_line(tmp_path):
    """A Triangle file with a duplicate point (line of the first) and unused points."""
    (tmp_path / "b.node").write_text(NODE.replace("5 0.5 0.5 0", "5 0.5 0.5 0\n6 1 1 0\n7 9 9 0")
                                     .replace("5 2 0 1", "7 2 0 1"))
    (tmp_path / "b.ele").write_text("3 3 0\n1 1 2 5\n2 2 3 5\n3 6 4 5  # 6 is vertex 3 again\n")
    _, found = io.check_file(tmp_path / "b.ele")
    got = {p.kind: (p.message, p.count) for p in found.problems}
    assert got["duplicate-points"][0] == f"{tmp_path / 'b.node'}:5: points 3 and 6 are both at " \
                                         "(1.0, 1.0)"
    assert got["unused-points"] == (f"{tmp_path / 'b.ele'}: 1 of 7 points are used by no "
                                    "triangle (first: point 7); they are kept", 1)
    with pytest.raises(ValueError, match="b.node:5: points 3 and 6"):
        qdrefine.read(tmp_path / "b.ele")


@pytest.mark.parametrize("ext", [".vtu", ".xdmf", ".xmf"])  # .xmf: refused by --compress
def test_compressed_output_is_smaller_and_reads_back_the_same(tmp_path, ext, run):
    """``compress=True`` (``--compress``): zlib VTU, gzip HDF5; qdrefine and meshio read it
    back bit for bit; other formats refuse it with one line."""
    import meshio

    mesh = qdrefine.refine(examples.plate_with_hole(), levels=2)
    plain, packed = tmp_path / f"plain{ext}", tmp_path / f"packed{ext}"
    qdrefine.write(plain, mesh)
    qdrefine.write(packed, mesh, compress=True)

    def size(p):
        return p.stat().st_size + (p.with_suffix(".h5").stat().st_size if ext != ".vtu" else 0)

    assert size(packed) < 0.8 * size(plain)
    same_mesh(mesh, qdrefine.read(packed))
    theirs = meshio.read(packed)
    assert np.array_equal(theirs.points[:, :2], mesh.points)
    assert np.array_equal(theirs.cells_dict["triangle"], mesh.triangles)
    result = run("refine", DATA / "two_regions_22.msh", tmp_path / f"cli{ext}", "--compress",
                 "-q")
    assert result.returncode == 0, result.stderr
    assert qdrefine.read(tmp_path / f"cli{ext}").n_triangles == 7 * 52
    with pytest.raises(ValueError, match="compression applies to .vtu and .xdmf"):
        qdrefine.write(tmp_path / "m.msh", mesh, compress=True)
    result = run("refine", DATA / "two_regions_22.msh", tmp_path / "o.msh", "--compress")
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "--compress applies to .vtu and .xdmf (.xmf) output only" in result.stderr


def test_only_refused_writes_are_named_as_writes(tmp_path):
    """``atomic_paths`` names the target of a write the system refuses (ENOSPC, EFBIG, ...),
    and lets any other error of its body (reading a source, say) through unchanged."""
    import errno

    from qdrefine.io import atomic_paths

    target = tmp_path / "out.msh"
    with pytest.raises(OSError) as info, atomic_paths([target]):
        raise OSError(errno.ENOSPC, "No space left on device")
    assert str(info.value) == f"{target}: cannot write: No space left on device"
    assert info.value.errno == errno.ENOSPC
    with pytest.raises(OSError) as info, atomic_paths([target]):
        raise OSError(errno.EIO, "Input/output error")
    assert str(info.value) == "[Errno 5] Input/output error"
    with pytest.raises(PermissionError), atomic_paths([target]):
        raise PermissionError(errno.EACCES, "Permission denied", "/elsewhere/source.zarr")
    assert list(tmp_path.iterdir()) == []
