"""The fast readers and writers (Gmsh MSH 2.2 / 4.1, VTU, XDMF): lossless round trips over
random meshes with data, files written by the Gmsh SDK itself, our files read by Gmsh and
meshio, and bad files named by line or byte."""

from __future__ import annotations

import contextlib
import re
import tempfile
import warnings
from pathlib import Path

import gmsh
import meshio
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import qdrefine
from meshes import jittered_grid
from qdrefine import Mesh, examples

#: (extension, write keywords) of every variant that holds tags, data and physical names.
LOSSLESS = [(".msh", {}), (".msh", {"binary": True}), (".msh", {"format_version": "2.2"}),
            (".msh", {"format_version": "2.2", "binary": True}), (".vtu", {}), (".xdmf", {})]
IDS = ["msh41", "msh41-binary", "msh22", "msh22-binary", "vtu", "xdmf"]


def same_everything(a: Mesh, b: Mesh) -> None:
    """Points bit for bit, triangles, tags, names, data (values, shape, dtype), transitions."""
    for name in ("points", "triangles", "cell_tags", "edges", "edge_tags", "transitions"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert np.array_equal(x, y), name
    assert a.points.tobytes() == b.points.tobytes()  # bit for bit, signed zeros included
    assert dict(a.physical_names) == dict(b.physical_names)
    for kind in ("point_data", "cell_data"):
        x, y = getattr(a, kind), getattr(b, kind)
        assert set(x) == set(y), kind
        for key in x:
            assert x[key].dtype == y[key].dtype and x[key].shape == y[key].shape, (kind, key)
            assert np.array_equal(x[key], y[key], equal_nan=x[key].dtype.kind == "f"), key


@st.composite
def meshes_with_data(draw) -> Mesh:
    """Random jittered meshes (shuffled numbering, random float coordinates) with random
    point and cell data of several shapes and dtypes, physical names and transitions."""
    n_side = draw(st.integers(1, 6))
    base = jittered_grid(n_side, seed=draw(st.integers(0, 2**16)),
                         shear=draw(st.sampled_from([0.0, 0.3])))
    scale = draw(st.sampled_from([1.0, 1e-7, 3.3e5, -2.0]))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    n, m = base.n_points, base.n_triangles
    shapes = draw(st.lists(st.sampled_from([(), (1,), (2,), (3,), (2, 2), (4,)]), max_size=3))
    dtypes = [np.float64, np.int64, np.int32, np.float32, np.uint8]

    def field(rows: int, shape: tuple, k: int):
        dtype = dtypes[k % len(dtypes)]
        if np.dtype(dtype).kind == "f":
            a = rng.standard_normal((rows, *shape)) * 10.0 ** rng.integers(-30, 30)
            a.ravel()[:1] = [np.nan][:a.size]
            return a.astype(dtype)
        return rng.integers(0, 200, (rows, *shape)).astype(dtype)

    point_data = {f"p {k}": field(n, s, k) for k, s in enumerate(shapes)}
    cell_data = {f"c{k}": field(m, s, k + 1) for k, s in enumerate(reversed(shapes))}
    transitions = None
    if draw(st.booleans()):
        transitions = np.full((m, 3), -1)
        transitions[0] = base.triangles[0]
    cell_tags = base.cell_tags if draw(st.booleans()) and base.cell_tags.any() else None
    names = {(2, 1): "left region", (1, 2): "wall"} if draw(st.booleans()) else {}
    return Mesh(base.points * scale, base.triangles, cell_tags, base.edges, base.edge_tags,
                point_data=point_data, cell_data=cell_data, physical_names=names,
                transitions=transitions)


@settings(max_examples=15, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(meshes_with_data())
def test_round_trips_are_lossless(mesh):
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("error")
        for ext, kwargs in LOSSLESS:
            path = Path(tmp) / f"m{ext}"
            qdrefine.write(path, mesh, **kwargs)
            try:
                same_everything(mesh, qdrefine.read(path))
            except AssertionError as exc:
                raise AssertionError(f"{ext} {kwargs}: {exc}") from None


def test_vtu_compressed_reads_back(tmp_path):
    from qdrefine.io import vtu

    mesh = jittered_grid(6, seed=1)
    mesh = mesh.replace(point_data={"u": mesh.points[:, 0]})
    vtu.write(tmp_path / "z.vtu", mesh, compress=True)
    same_everything(mesh, qdrefine.read(tmp_path / "z.vtu"))
    back = meshio.read(tmp_path / "z.vtu")
    assert np.array_equal(back.points[:, :2], mesh.points)


def _inline_base64(data: bytes) -> bytes:
    """A VTU of raw appended data (64-bit headers) with every array inline, base64, as
    VTK's other writers put it: what qdrefine reads through meshio."""
    import base64

    start = data.find(b"<AppendedData")
    blob = data[data.find(b"_", data.find(b">", start)) + 1:data.rfind(b"\n</AppendedData>")]

    def inline(match: re.Match) -> bytes:
        offset = int(re.search(rb'offset="(\d+)"', match.group(1)).group(1))
        n = int(np.frombuffer(blob, "<u8", 1, offset)[0])
        attributes = re.sub(rb'format="appended" offset="\d+"', b'format="binary"',
                            match.group(1))
        return (b"<DataArray" + attributes + b">"
                + base64.b64encode(blob[offset:offset + 8 + n]) + b"</DataArray>")

    return re.sub(rb"<DataArray([^>]*?)/>", inline, data[:start]) + b"</VTKFile>\n"


@pytest.mark.parametrize("change", ["byte-order mark", "inline base64"])
def test_a_vtu_read_through_any_path_keeps_names_and_dtypes(tmp_path, change):
    """A VTU with a byte-order mark, or with its arrays inline in base64, went to meshio,
    which ignores qdrefine's field data: the physical names were lost and float16, bool and
    (k, 2, 2) fields came back as float32, uint8 and (k, 4), silently (review)."""
    mesh = examples.plate_with_hole(8, 2)
    mesh = mesh.replace(point_data={"h": np.arange(mesh.n_points, dtype=np.float16),
                                    "b": np.arange(mesh.n_points) % 2 == 0},
                        cell_data={"v": np.ones((mesh.n_triangles, 2, 2), np.int16)})
    path = tmp_path / "m.vtu"
    qdrefine.write(path, mesh)
    data = path.read_bytes()
    path.write_bytes(b"\xef\xbb\xbf" + data if change == "byte-order mark"
                     else _inline_base64(data))
    assert meshio.read(path).points.shape == (mesh.n_points, 3)  # a file meshio reads
    same_everything(mesh, qdrefine.read(path))


def test_physical_names_in_another_tools_vtu_field_data_are_kept(tmp_path):
    """A VTU read through meshio with names in its own field data (``name -> [tag, dim]``)
    lost them once qdrefine's record was applied, which such a file does not have
    (review)."""
    path = tmp_path / "m.vtu"
    meshio.write(path, meshio.Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]),
                                   [("triangle", np.array([[0, 1, 2]]))],
                                   cell_data={"gmsh:physical": [np.array([1])]}), binary=False)
    path.write_text(path.read_text().replace("<Piece", '<FieldData><DataArray type="Int64" '
                                             'Name="left" NumberOfTuples="2" format="ascii">'
                                             "1 2</DataArray></FieldData>\n<Piece", 1))
    assert dict(meshio.read(path).field_data)["left"].tolist() == [1, 2]
    assert qdrefine.read(path).physical_names == {(2, 1): "left"}


def test_obj_files_as_other_tools_write_them(tmp_path):
    """meshio's OBJ reader refused a file with normals or texture coordinates, as Blender
    writes it ("len(points) = 4, but len(point_data['obj:vn']) = 1"), and took negative
    (relative) indices for vertex numbers; faces in every form, skipped lines named."""
    square = Mesh(np.array([[0.0, 0], [1, 0], [0, 1], [1, 1]]), np.array([[0, 1, 2], [1, 3, 2]]))
    vertices = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
    for faces in ("f 1/1/1 2/2/1 3/3/1\nf 2/2/1 4/4/1 3/3/1\n",  # Blender
                  "f 1//1 2//1 3//1\nf 2/2 4/4 3/3\n",
                  "f -4 -3 -2\nf -3 -1 -2\n"):  # counted back from the latest vertex
        path = tmp_path / "m.obj"
        path.write_text("# Blender\nmtllib m.mtl\no Plane\n" + vertices
                        + "vt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvn 0 0 1\nusemtl None\ns off\n"
                        + faces)
        with pytest.warns(UserWarning, match=r"m\.obj: 1 'vn', 4 'vt' lines skipped"):
            mesh = qdrefine.read(path)
        assert np.array_equal(mesh.points, square.points)
        assert np.array_equal(mesh.triangles, square.triangles), faces
    path.write_text(vertices + "f 1 2 3\nf 2 4 9\n")
    with pytest.raises(ValueError, match=r"m\.obj, line 6: vertex index 9 outside 1\.\.4"):
        qdrefine.read(path)
    path.write_text(vertices + "f 1 2 x\n")
    with pytest.raises(ValueError, match=r"m\.obj, line 5: not a number in 'f 1 2 x'"):
        qdrefine.read(path)


# files written by Gmsh itself (the SDK) -----------------------------------------------------

@pytest.fixture(scope="module")
def gmsh_model():
    """A Gmsh model: two rectangles with named physical surfaces and curves, meshed."""
    gmsh.initialize(interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add("two")
    occ = gmsh.model.occ
    a = occ.addRectangle(0, 0, 0, 1, 1)
    b = occ.addRectangle(1, 0, 0, 1.5, 1)
    occ.fragment([(2, a)], [(2, b)])
    occ.synchronize()
    surfaces = [t for _, t in gmsh.model.getEntities(2)]
    gmsh.model.addPhysicalGroup(2, [surfaces[0]], 7, name="left")
    gmsh.model.addPhysicalGroup(2, [surfaces[1]], 8, name="right")
    curves = [t for _, t in gmsh.model.getEntities(1)]
    gmsh.model.addPhysicalGroup(1, curves[:2], 3, name="some edges")
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.15)
    gmsh.model.mesh.generate(2)
    yield gmsh
    gmsh.finalize()


def _api_mesh(g):
    """Points, triangles (as sets of node coordinates) and tags from Gmsh's API."""
    tags, coords, _ = g.model.mesh.getNodes()
    xyz = dict(zip(tags.tolist(), coords.reshape(-1, 3)[:, :2].tolist(), strict=True))
    triangles, lines = {}, {}
    for dim, target in ((2, triangles), (1, lines)):
        for _, phys in g.model.getPhysicalGroups(dim):
            for ent in g.model.getEntitiesForPhysicalGroup(dim, phys):
                _, _, nodes = g.model.mesh.getElements(dim, ent)
                k = dim + 1
                for row in nodes[0].reshape(-1, k).tolist():
                    target[frozenset(tuple(xyz[v]) for v in row)] = phys
    return triangles, lines


def _file_mesh(mesh: Mesh):
    p = mesh.points.tolist()
    tris = {frozenset(tuple(p[v]) for v in row): int(t)
            for row, t in zip(mesh.triangles.tolist(), mesh.cell_tags.tolist(), strict=True)}
    lines = {frozenset(tuple(p[v]) for v in row): int(t)
             for row, t in zip(mesh.edges.tolist(), mesh.edge_tags.tolist(), strict=True)}
    return tris, lines


@pytest.mark.parametrize("version", [4.1, 2.2])
@pytest.mark.parametrize("binary", [0, 1])
def test_files_written_by_gmsh_read_exactly(tmp_path, gmsh_model, version, binary):
    """Every triangle and tagged line of Gmsh's own file, with its physical tag and names;
    coordinates bit for bit (Gmsh writes text with 16 digits, so the text files are
    compared with the text's own values, read back by Python)."""
    g = gmsh_model
    g.option.setNumber("Mesh.MshFileVersion", version)
    g.option.setNumber("Mesh.Binary", binary)
    path = tmp_path / f"gmsh-{version}-{binary}.msh"
    g.write(str(path))
    mesh = qdrefine.read(path)
    api_tris, api_lines = _api_mesh(g)
    if not binary:  # compare with what the text says, parsed independently
        g.open(str(path))
        api_tris, api_lines = _api_mesh(g)
    tris, lines = _file_mesh(mesh)
    assert tris == api_tris and lines == api_lines
    assert dict(mesh.physical_names) == {(2, 7): "left", (2, 8): "right",
                                         (1, 3): "some edges"}


@pytest.mark.parametrize("kwargs", [k for _, k in LOSSLESS[:4]], ids=IDS[:4])
def test_gmsh_reads_our_files(tmp_path, gmsh_model, kwargs):
    """Gmsh opens our MSH files: the same nodes bit for bit, triangles, physical groups with
    their names, and one view per data field."""
    g = gmsh_model
    base = jittered_grid(5, seed=4)
    mesh = base.replace(physical_names={(2, 1): "one", (1, 2): "two"},
                        point_data={"u": base.points[:, 0] * 3},
                        cell_data={"w": np.arange(base.n_triangles) * 0.5})
    path = tmp_path / "ours.msh"
    qdrefine.write(path, mesh, **kwargs)
    g.open(str(path))
    tags, coords, _ = g.model.mesh.getNodes()
    xy = coords.reshape(-1, 3)[np.argsort(tags), :2]
    assert xy.tobytes() == mesh.points.tobytes()
    _, elements, nodes = g.model.mesh.getElements(2)
    order = np.argsort(elements[0])
    assert np.array_equal(nodes[0].reshape(-1, 3)[order] - 1, mesh.triangles)
    groups = {(d, t): g.model.getPhysicalName(d, t) for d, t in g.model.getPhysicalGroups()}
    assert groups[(2, 1)] == "one" and groups[(1, 2)] == "two"
    # untagged triangles (tag 0) are physical group 0 in MSH 4.1, so that Gmsh keeps them
    assert set(groups) - {(2, 0)} == {(2, 1)} | {(1, int(t)) for t in np.unique(mesh.edge_tags)}
    names = [g.option.getString(f"View[{i}].Name") for i in range(len(g.view.getTags()))]
    assert sorted(names) == ["u", "w"]
    for tag in g.view.getTags():
        g.view.remove(tag)


@pytest.mark.parametrize(("ext", "kwargs"), LOSSLESS[:5], ids=IDS[:5])
def test_meshio_reads_our_files(tmp_path, ext, kwargs):
    base = jittered_grid(4, seed=8)
    # meshio 5.3 cannot read $ElementData of MSH 2.2 files at all (it splits the values by
    # the length of (type, cells) tuples), so those files get point data only
    cell_data = {} if kwargs.get("format_version") == "2.2" else \
        {"w": np.arange(base.n_triangles) * 0.5}
    mesh = base.replace(point_data={"u": base.points[:, 1]}, cell_data=cell_data)
    path = tmp_path / f"m{ext}"
    qdrefine.write(path, mesh, **kwargs)
    back = meshio.read(path)
    assert back.points[:, :2].tobytes() == mesh.points.tobytes()
    tris = back.cells_dict["triangle"]
    assert {tuple(r) for r in tris.tolist()} == {tuple(r) for r in mesh.triangles.tolist()}
    assert len(back.cells_dict["line"]) == len(mesh.edges)
    assert np.array_equal(back.point_data["u"], mesh.point_data["u"])


# bad files ---------------------------------------------------------------------------------

def _msh41(mesh: Mesh, tmp_path: Path, binary: bool = False) -> bytes:
    qdrefine.write(tmp_path / "good.msh", mesh, binary=binary)
    return (tmp_path / "good.msh").read_bytes()


BAD_TEXT = {
    "a bad number names its line": (lambda t: t.replace(b"\n2 1 0 ", b"\n2 1 x ", 1),
                                    r"bad\.msh: not a readable Gmsh MSH file \(line \d+: "
                                    r"expected a number, got 'x'\)"),
    "truncated inside $Nodes": (lambda t: t[:t.index(b"$EndNodes") - 20],
                                r"bad\.msh: not a readable Gmsh MSH file \(line \d+: the file "
                                r"ends inside \$Nodes"),
    "unknown element type": (lambda t: t.replace(b"\n2 1 2 ", b"\n2 1 77 ", 1),
                             r"line \d+: unknown element type 77"),
    "no $MeshFormat": (lambda t: t[t.index(b"$EndMeshFormat") + 15:],
                       r"line 1: no \$MeshFormat section"),
    "version 3": (lambda t: t.replace(b"4.1 0 8", b"3.0 0 8"),
                  r"line 2: MSH version 3.0 is not supported"),
}


@pytest.mark.parametrize("problem", list(BAD_TEXT))
def test_bad_text_msh_names_file_and_line(tmp_path, problem):
    edit, message = BAD_TEXT[problem]
    text = _msh41(jittered_grid(3, seed=2), tmp_path)
    bad = edit(text)
    (tmp_path / "bad.msh").write_bytes(bad)
    with pytest.raises(ValueError, match=message or "bad.msh: ") as info:
        qdrefine.read(tmp_path / "bad.msh")
    assert str(info.value).startswith(str(tmp_path / "bad.msh"))
    assert "\n" not in str(info.value)


def test_element_using_an_unknown_node(tmp_path):
    text = _msh41(jittered_grid(3, seed=2), tmp_path).decode()
    head, rest = text.split("$Elements\n")
    lines = rest.splitlines()
    lines[2] = " ".join(lines[2].split()[:-1] + ["999"])
    (tmp_path / "bad.msh").write_text(head + "$Elements\n" + "\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"bad\.msh: not a readable Gmsh MSH file \(element "
                                         r"\d+ uses node 999, which is not in \$Nodes\)"):
        qdrefine.read(tmp_path / "bad.msh")


@pytest.mark.parametrize("cut", [0.3, 0.6, 0.9, 0.999])
def test_truncated_binary_files_name_the_byte(tmp_path, cut):
    mesh = jittered_grid(6, seed=3)
    for ext, kwargs in ((".msh", {"binary": True}),
                        (".msh", {"binary": True, "format_version": "2.2"}), (".vtu", {})):
        qdrefine.write(tmp_path / f"good{ext}", mesh, **kwargs)
        data = (tmp_path / f"good{ext}").read_bytes()
        (tmp_path / f"bad{ext}").write_bytes(data[:int(len(data) * cut)])
        with pytest.raises(ValueError, match=rf"bad\{ext}: not a readable .*(byte|line) \d+"
                           if ext == ".msh" else rf"bad\{ext}: not a readable"):
            qdrefine.read(tmp_path / f"bad{ext}")


def test_fifo_is_refused_without_waiting(tmp_path):
    import os

    fifo = tmp_path / "pipe.msh"
    os.mkfifo(fifo)
    with pytest.raises(OSError, match="pipe.msh: not a regular file"):
        qdrefine.read(fifo)


# exact text numbers ------------------------------------------------------------------------

@pytest.mark.parametrize("arrow", [True, False], ids=["pyarrow", "python"])
@pytest.mark.parametrize("seed", [0, 1])
def test_text_floats_read_back_bit_for_bit(monkeypatch, arrow, seed):
    """Every double (random bit patterns: subnormals, extremes, -0.0, inf, nan) formatted by
    either formatter reads back bit for bit through either parser (pandas' table reader, or
    np.fromstring where pandas declines, as for inf and nan), with an id column as written
    in data sections."""
    from qdrefine.io import _text

    rng = np.random.default_rng(seed)
    values = rng.integers(0, 2**64, 20000, dtype=np.uint64).view(np.float64)
    values[:8] = [0.0, -0.0, 5e-324, -2.2250738585072014e-308, 1.7976931348623157e308,
                  np.inf, -np.inf, 0.1]
    values = values[~np.isnan(values)]
    values[-1] = np.nan
    rows = values[: len(values) // 2 * 2].reshape(-1, 2)
    if not arrow:
        monkeypatch.setattr(_text, "_arrow", lambda: None)
    ids = np.arange(1, len(rows) + 1)
    text = b"".join(bytes(p) for p in _text.format_floats(np.column_stack([ids, rows]),
                                                          first="%d"))
    for parsed in (_text.parse_table(text, 3), _text.parse(text, np.float64).reshape(-1, 3)):
        assert np.array_equal(parsed[:, 0], ids)
        assert parsed[:, 1:].tobytes() == rows.tobytes() or (
            np.array_equal(parsed[:, 1:], rows, equal_nan=True)
            and np.array_equal(np.signbit(parsed[:, 1:]), np.signbit(rows)))
    # the fast path itself (pandas leaves inf and nan to np.fromstring): finite rows
    finite = rows[np.isfinite(rows).all(axis=1)]
    text = b"".join(bytes(p) for p in _text.format_floats(finite))
    table = _text._pandas_table(text, 2, np.float64)
    assert table is not None and table.tobytes() == finite.tobytes()


def test_binary_msh22_with_one_block_per_element(tmp_path):
    """Gmsh writes binary MSH 2.2 with a block header per element; runs of equal headers
    are read at once (a 202k-triangle Gmsh file took 9.2 s, one block at a time, against
    0.09 s for its MSH 4.1 twin): alternating headers, runs and blocks of several
    elements give the same mesh as the text file, and a file cut inside a run is refused."""
    import struct

    nodes = [(1, 0.0, 0.0), (2, 1.0, 0.0), (3, 1.0, 1.0), (4, 0.0, 1.0), (5, 2.0, 0.0),
             (6, 2.0, 1.0)]
    # (type, [(id, physical, entity, node ...), ...]): triangles 2, lines 1
    blocks = [(2, [(1, 7, 1, 1, 2, 3)]), (1, [(2, 3, 1, 1, 2)]), (2, [(3, 7, 1, 1, 3, 4)]),
              (2, [(4, 8, 2, 2, 5, 6)]), (2, [(5, 8, 2, 2, 6, 3)]),
              (1, [(6, 3, 1, 2, 5), (7, 3, 1, 5, 6)]), (1, [(8, 4, 2, 4, 1)])]
    count = sum(len(rows) for _, rows in blocks)
    head = b"$MeshFormat\n2.2 1 8\n" + struct.pack("<i", 1) + b"\n$EndMeshFormat\n"
    head += f"$Nodes\n{len(nodes)}\n".encode()
    head += b"".join(struct.pack("<i3d", t, x, y, 0.0) for t, x, y in nodes)
    body = b"".join(struct.pack("<3i", typ, len(rows), 2)
                    + b"".join(struct.pack(f"<{len(r)}i", *r) for r in rows)
                    for typ, rows in blocks)
    text = "".join(f"{r[0]} {typ} 2 {' '.join(map(str, r[1:]))}\n"
                   for typ, rows in blocks for r in rows)
    binary = head + f"\n$EndNodes\n$Elements\n{count}\n".encode() + body + \
        b"\n$EndElements\n"
    (tmp_path / "b.msh").write_bytes(binary)
    (tmp_path / "t.msh").write_text(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n6\n"
        + "".join(f"{t} {x!r} {y!r} 0\n" for t, x, y in nodes)
        + f"$EndNodes\n$Elements\n{count}\n{text}$EndElements\n")
    a, b = qdrefine.read(tmp_path / "b.msh"), qdrefine.read(tmp_path / "t.msh")
    for name in ("points", "triangles", "cell_tags", "edges", "edge_tags"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.cell_tags.tolist() == [7, 7, 8, 8] and sorted(a.edge_tags.tolist()) == [3, 3, 3, 4]
    cut = binary.index(b"$Elements\n") + 40
    (tmp_path / "c.msh").write_bytes(binary[:cut])
    with pytest.raises(ValueError, match=r"c\.msh: not a readable Gmsh MSH file \(byte \d+: "
                                         r"the file ends inside \$Elements"):
        qdrefine.read(tmp_path / "c.msh")


@contextlib.contextmanager
def own_gmsh_model(name: str):
    """A Gmsh model of this test's own, beside the module's ``gmsh_model`` if that one is
    open (finalizing Gmsh here would close it under the other tests)."""
    started = not gmsh.isInitialized()
    if started:
        gmsh.initialize(interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    before = None if started else gmsh.model.getCurrent()
    gmsh.model.add(name)
    try:
        yield gmsh
    finally:
        gmsh.model.remove()
        if before:
            gmsh.model.setCurrent(before)
        if started:
            gmsh.finalize()


def test_entities_in_several_physical_groups(tmp_path):
    """A curve in two physical groups ("boundary" and "inlet") and a surface in two
    ("domain" and "everything"), as Gmsh writes them: MSH 2.2 repeats the elements once per
    group, MSH 4.1 lists the groups on the entity. Both versions, text and binary, give the
    same mesh: every tagged line once per group, each triangle once with its first group's
    tag and a warning for the other (review: 2.2 was refused as 'edge shared by 4
    triangles', 4.1 dropped the inlet's lines silently)."""
    with own_gmsh_model("groups"):
        r = gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.synchronize()
        curves = [t for _, t in gmsh.model.getEntities(1)]
        gmsh.model.addPhysicalGroup(2, [r], 1, "domain")
        gmsh.model.addPhysicalGroup(1, curves, 2, "boundary")
        gmsh.model.addPhysicalGroup(1, curves[:1], 3, "inlet")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        gmsh.model.mesh.generate(2)
        plain = {}
        gmsh.option.setNumber("Mesh.Binary", 0)  # options are global: another test's stay
        for version in (2.2, 4.1):
            gmsh.option.setNumber("Mesh.MshFileVersion", version)
            gmsh.write(str(tmp_path / f"curve-{version}.msh"))
        gmsh.model.addPhysicalGroup(2, [r], 5, "everything")
        for version in (2.2, 4.1):
            for binary in (0, 1):
                gmsh.option.setNumber("Mesh.MshFileVersion", version)
                gmsh.option.setNumber("Mesh.Binary", binary)
                gmsh.write(str(tmp_path / f"surface-{version}-{binary}.msh"))
    # the general parser (elements not one per line) notes the groups once, as the fast one
    text = (tmp_path / "curve-4.1.msh").read_text()
    end = text.rindex("\n$EndElements")
    cut = text.rindex("\n", 0, end)
    (tmp_path / "joined-4.1.msh").write_text(text[:cut] + " " + text[cut + 1:])
    for version in (2.2, 4.1, "joined-4.1"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            name = version if isinstance(version, str) else f"curve-{version}"
            plain[version] = qdrefine.read(tmp_path / f"{name}.msh")
    reference = plain[2.2]
    assert np.bincount(reference.edge_tags).tolist()[2:] == [32, 8]
    assert set(reference.cell_tags.tolist()) == {1}
    for path in sorted(tmp_path.glob("*.msh")):
        if path.name.startswith("surface"):
            with pytest.warns(UserWarning, match=rf"{path.name}: .*physical .*a triangle "
                                                 "holds one tag"):
                mesh = qdrefine.read(path)
        else:
            mesh = plain["joined-4.1" if "joined" in path.name else
                         2.2 if "2.2" in path.name else 4.1]
        # text files hold 16 digits (not every bit): points to rounding
        assert np.allclose(mesh.points, reference.points, rtol=0, atol=1e-15), path.name
        for name in ("triangles", "cell_tags"):
            assert np.array_equal(getattr(mesh, name), getattr(reference, name)), path.name
        edges = sorted(zip(map(tuple, np.sort(mesh.edges, axis=1).tolist()),
                           mesh.edge_tags.tolist(), strict=True))
        assert edges == sorted(zip(map(tuple, np.sort(reference.edges, axis=1).tolist()),
                                   reference.edge_tags.tolist(), strict=True)), path.name


def test_msh40_written_by_gmsh_reads(tmp_path):
    """Gmsh writes MSH 4.0 with the version "4", which meshio took for 4.1 (the file did
    not read: "parametric nodes not implemented"); an entity in two physical groups is
    named in a warning, since meshio's 4.0 reader keeps each element's first group."""
    with own_gmsh_model("old"):
        r = gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [r], 11, "plate")
        gmsh.model.addPhysicalGroup(1, [1], 21, "bottom")
        gmsh.model.addPhysicalGroup(1, [1, 2], 22, "bottom and right")
        gmsh.model.addPhysicalGroup(0, [1], 31, "corner")  # a point in two groups: no loss
        gmsh.model.addPhysicalGroup(0, [1], 32, "origin")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.Binary", 0)
        for version in (4.1, 4.0):
            gmsh.option.setNumber("Mesh.MshFileVersion", version)
            gmsh.write(str(tmp_path / f"m{version}.msh"))
    old, new = tmp_path / "m4.0.msh", tmp_path / "m4.1.msh"
    assert old.read_text().split("\n")[1].split()[0] == "4"
    with pytest.warns(UserWarning) as caught:  # both said: matching one re-emits the other
        old = qdrefine.read(old)
    groups = [str(w.message) for w in caught if "several physical groups" in str(w.message)]
    assert len(groups) == 1 and "a curve is" in groups[0] and "groups 21" in groups[0], groups
    assert any("1 tagged point cell" in str(w.message) for w in caught)  # the corner
    with pytest.warns(UserWarning, match="1 tagged point cell"):
        new = qdrefine.read(new)
    np.testing.assert_array_equal(old.points, new.points)
    np.testing.assert_array_equal(old.triangles, new.triangles)
    np.testing.assert_array_equal(old.cell_tags, new.cell_tags)
    assert old.physical_names == new.physical_names
    # the entities are read for the warning only: a layout this reader does not know (here
    # a number more than its counts, which meshio skips) must not refuse what meshio reads
    path = tmp_path / "m4.0.msh"
    path.write_text(path.read_text().replace("$EndEntities", "0\n$EndEntities", 1))
    with pytest.warns(UserWarning, match="1 tagged point cell"):
        assert qdrefine.read(path).n_triangles == new.n_triangles


@pytest.mark.parametrize("binary", [0, 1])
def test_a_partitioned_gmsh_file_keeps_its_physical_groups(tmp_path, binary):
    """After ``gmsh.model.mesh.partition`` the elements belong to the partition entities of
    ``$PartitionedEntities``, whose physical tags were not read: every triangle tag 0, the
    tagged edges lost, without a word (a review)."""
    with own_gmsh_model("partitioned"):
        r = gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [r], 11, "plate")
        gmsh.model.addPhysicalGroup(1, [1], 21, "bottom")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", binary)
        gmsh.write(str(tmp_path / "plain.msh"))
        gmsh.model.mesh.partition(3)
        gmsh.write(str(tmp_path / "part.msh"))
        gmsh.model.mesh.unpartition()
        gmsh.option.setNumber("Mesh.Binary", 0)
    assert b"$PartitionedEntities" in (tmp_path / "part.msh").read_bytes()
    plain, part = qdrefine.read(tmp_path / "plain.msh"), qdrefine.read(tmp_path / "part.msh")

    def tagged(mesh, rows, tags):  # (corners in coordinate order, tag), in order
        corners = [tuple(sorted(map(tuple, mesh.points[r].tolist()))) for r in rows]
        return sorted(zip(corners, tags.tolist(), strict=True))

    assert tagged(part, part.triangles, part.cell_tags) == \
        tagged(plain, plain.triangles, plain.cell_tags)
    assert tagged(part, part.edges, part.edge_tags) == tagged(plain, plain.edges, plain.edge_tags)
    assert part.physical_names == plain.physical_names


def test_every_reader_takes_the_same_field_as_the_tags(tmp_path):
    """A file with several cell fields that readers take as tags (meshio writes Gmsh's
    ``gmsh:physical`` beside a ``tag``): our VTU reader and meshio's readers take the same
    one (ours took ``tag``, meshio's ``gmsh:physical``)."""
    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    mesh = Mesh(points, np.array([[0, 1, 2], [0, 2, 3]]), cell_tags=np.array([7, 8]),
                cell_data={"gmsh_physical": np.array([1, 2])})
    qdrefine.write(tmp_path / "ours.vtu", mesh)  # our reader's format: appended raw data
    path = tmp_path / "ours.vtu"
    path.write_bytes(path.read_bytes().replace(b'Name="gmsh_physical"', b'Name="gmsh:physical"'))
    meshio.write(tmp_path / "m.vtk", meshio.Mesh(points, [("triangle", mesh.triangles)], cell_data={
        "tag": [np.array([7, 8])], "gmsh:physical": [np.array([1, 2])]}))
    for name in ("ours.vtu", "m.vtk"):
        read = qdrefine.read(tmp_path / name)
        assert read.cell_tags.tolist() == [1, 2], name
        assert read.cell_data["tag"].tolist() == [7, 8], name


def _pieces_vtu(pieces: list[tuple[np.ndarray, np.ndarray]], order: str = "<",
                compress: bool = False, point_names=("u",), point_rows=None) -> bytes:
    """A VTU of several pieces with raw appended data in byte order ``order``, as VTK writes
    it: each piece's points (z = 0), triangles, a cell array ``tag`` (the triangle's number
    in its piece + 1) and point arrays ``point_names`` (x + 2y; ``point_rows``: as many
    rows in each piece, cut or repeated)."""
    import struct
    import zlib

    big = order == ">"
    head = "".join(["<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" ",
                    f"version=\"1.0\" byte_order=\"{'BigEndian' if big else 'LittleEndian'}\" ",
                    'header_type="UInt64"', ' compressor="vtkZLibDataCompressor"' * compress,
                    ">\n<UnstructuredGrid>\n"])
    blocks = []

    def item(name: str, values: np.ndarray, vtk: str, comps: int = 1) -> str:
        raw = np.ascontiguousarray(values, values.dtype.newbyteorder(order)).tobytes()
        offset = sum(map(len, blocks))
        if compress:
            body = zlib.compress(raw)
            blocks.append(struct.pack(f"{order}4Q", 1, len(raw), len(raw), len(body)) + body)
        else:
            blocks.append(struct.pack(f"{order}Q", len(raw)) + raw)
        return (f'<DataArray type="{vtk}" Name="{name}" NumberOfComponents="{comps}" '
                f'format="appended" offset="{offset}"/>\n')

    for i, (points, triangles) in enumerate(pieces):
        m = len(triangles)
        values = points[:, 0] + 2 * points[:, 1]
        if point_rows is not None:
            values = np.resize(values, point_rows[i])
        head += (f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{m}">\n<PointData>\n'
                 + "".join(item(name, values, "Float64") for name in point_names)
                 + "</PointData>\n<CellData>\n"
                 + item("tag", np.arange(1, m + 1, dtype=np.int32), "Int32")
                 + "</CellData>\n<Points>\n"
                 + item("Points", np.c_[points, np.zeros(len(points))], "Float64", 3)
                 + "</Points>\n<Cells>\n"
                 + item("connectivity", triangles.astype(np.int64).ravel(), "Int64")
                 + item("offsets", 3 * np.arange(1, m + 1, dtype=np.int64), "Int64")
                 + item("types", np.full(m, 5, np.uint8), "UInt8")
                 + "</Cells>\n</Piece>\n")
    head += '</UnstructuredGrid>\n<AppendedData encoding="raw">\n_'
    return head.encode() + b"".join(blocks) + b"\n</AppendedData>\n</VTKFile>\n"


@pytest.mark.parametrize("compress", [False, True], ids=["raw", "zlib"])
@pytest.mark.parametrize("order", ["<", ">"], ids=["little", "big"])
def test_a_vtu_of_several_pieces_in_either_byte_order_reads_as_meshio_reads_it(
        tmp_path, order, compress):
    """VTK writes a parallel or multi-block result as several pieces, and big-endian machines
    wrote big-endian files: both went to meshio, which keeps the triangles of the last piece
    only (its ``_organize_cells`` appends the blocks after its loop over the pieces), or
    fails on the others' cell data: a silently wrong mesh or a refusal (review). Read here
    now, bounded: points joined in order (as meshio joins them), each piece's triangles
    numbered on from the previous pieces' points, its cell and point data joined the same
    way."""
    a, b = jittered_grid(3, seed=1), jittered_grid(2, seed=2)
    parts = [(a.points, a.triangles), (b.points + 5, b.triangles),
             (np.array([[9.0, 9], [10, 9], [9, 10]]), np.array([[0, 1, 2]]))]
    (tmp_path / "p.vtu").write_bytes(_pieces_vtu(parts, order, compress))
    ours = qdrefine.read(tmp_path / "p.vtu")
    theirs = meshio.read(tmp_path / "p.vtu")
    assert np.array_equal(ours.points, theirs.points[:, :2])
    assert np.array_equal(ours.point_data["u"], theirs.point_data["u"].ravel())
    assert ours.point_data["u"].dtype == np.float64  # native order
    points = np.concatenate([p for p, _ in parts])
    assert np.array_equal(ours.points, points)
    assert np.array_equal(ours.point_data["u"], points[:, 0] + 2 * points[:, 1])
    starts = np.cumsum([0] + [len(p) for p, _ in parts[:-1]])
    assert np.array_equal(ours.triangles,
                          np.concatenate([t + s for (_, t), s in zip(parts, starts, strict=True)]))
    assert np.array_equal(ours.cell_tags,
                          np.concatenate([np.arange(1, len(t) + 1) for _, t in parts]))


def test_a_compressed_block_of_a_later_piece_is_bounded_and_named(tmp_path):
    """A zip bomb in the second piece's points went to meshio, which made its 64 MiB whole
    (review); pieces whose data differ are named."""
    import struct
    import tracemalloc
    import zlib

    one = (np.array([[0.0, 0], [1, 0], [0, 1]]), np.array([[0, 1, 2]]))
    data = _pieces_vtu([one, one], compress=True)
    body = zlib.compress(bytes(1 << 26))
    bomb = struct.pack("<4Q", 1, 1 << 26, 1 << 26, len(body)) + body
    start = data.index(b"_", data.index(b"<AppendedData")) + 1
    points = [int(o) for o in re.findall(rb'Name="Points" NumberOfComponents="3" '
                                         rb'format="appended" offset="(\d+)"', data)][1]
    # the second piece's points are followed by its cells: move those behind the bomb
    n, full, last, c = struct.unpack_from("<4Q", data, start + points)
    end = start + points + 32 + c
    xml = data[:start]
    shift = len(bomb) - (end - start - points)
    for old in [int(o) for o in re.findall(rb'offset="(\d+)"', xml)]:
        if old > points:
            xml = xml.replace(f'offset="{old}"'.encode(), f'offset="{old + shift}"'.encode())
    (tmp_path / "bomb.vtu").write_bytes(xml + data[start:start + points] + bomb + data[end:])
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=r"bomb\.vtu: not a readable VTK XML unstructured "
                                             r"grid file \(Piece 1: byte \d+: DataArray "
                                             r"'Points' decompresses to more than the 72 bytes"):
            qdrefine.read(tmp_path / "bomb.vtu")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20
    (tmp_path / "names.vtu").write_bytes(
        _pieces_vtu([one, one], point_names=("u",))
        .replace(b'Name="u"', b'Name="v"', 1))
    with pytest.raises(ValueError, match=r"names\.vtu: .*Piece 1 has point data \['u'\], "
                                         r"Piece 0 \['v'\]"):
        qdrefine.read(tmp_path / "names.vtu")
    # a row too many in one piece and too few in the next: joined, each value one point off
    (tmp_path / "rows.vtu").write_bytes(_pieces_vtu([one, one], point_rows=(4, 2)))
    with pytest.raises(ValueError, match=r"rows\.vtu: .*Piece 0: PointData 'u': expected 3 "
                                         r"rows"):
        qdrefine.read(tmp_path / "rows.vtu")


def test_gmsh_physical_points_are_dropped_with_a_warning(tmp_path):
    """A physical point (a pin, a load point) was dropped silently, its name kept without
    an element (review): dropped with one warning now, in every version Gmsh writes; the
    triangles, tags and tagged lines read as without it."""
    with own_gmsh_model("pin"):
        r = gmsh.model.occ.addRectangle(0, 0, 0, 1, 1)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(2, [r], 1, "domain")
        gmsh.model.addPhysicalGroup(1, [t for _, t in gmsh.model.getEntities(1)], 2, "wall")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.3)
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.write(str(tmp_path / "plain.msh"))
        gmsh.model.addPhysicalGroup(0, [gmsh.model.getEntities(0)[0][1]], 3, "pin")
        for version in (2.2, 4.1):
            for binary in (0, 1):
                gmsh.option.setNumber("Mesh.MshFileVersion", version)
                gmsh.option.setNumber("Mesh.Binary", binary)
                gmsh.write(str(tmp_path / f"pin-{version}-{binary}.msh"))
        gmsh.option.setNumber("Mesh.Binary", 0)
    plain = qdrefine.read(tmp_path / "plain.msh")
    for path in sorted(tmp_path.glob("pin-*.msh")):
        with pytest.warns(UserWarning, match=rf"{path.name}: 1 tagged point cell \(such as "
                                             "Gmsh's physical points\\) is dropped") as said:
            mesh = qdrefine.read(path)
        assert len(said) == 1, path.name
        assert np.allclose(mesh.points, plain.points, rtol=0, atol=1e-15)
        for name in ("triangles", "cell_tags", "edges", "edge_tags"):
            assert np.array_equal(getattr(mesh, name), getattr(plain, name)), (path, name)
