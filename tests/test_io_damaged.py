"""Damaged and unusual files: what the readers refuse (one line naming the file and the
place), warn about, or read right; and what the writers refuse before writing anything.

Each case was found by a review that edited real files (a count, a header, a record, a
name); the files here are made the same way from a small tagged mesh.
"""

from __future__ import annotations

import json
import os
import re
import struct
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import qdrefine
from qdrefine import Mesh, examples
from qdrefine.marking import mark_dorfler

P = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], dtype=float)
T = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4]])


def _tagged() -> Mesh:
    return Mesh(P, T, cell_tags=np.array([1, 1, 2, 2]), edges=np.array([[0, 1]]),
                edge_tags=np.array([3]), physical_names={(2, 1): "a"})


def _refused(path: Path, *fragments: str) -> str:
    with pytest.raises(ValueError) as info:
        qdrefine.read(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(path)), message
    for fragment in fragments:
        assert fragment in message, message
    return message


@pytest.mark.parametrize("edit, fragment", [
    (("$Entities\n0 1 2 0\n", "$Entities\n0 1 1 0\n"), "more than its counts announce"),
    (("0.0 1 3 0\n", "0.0 -1 3 0\n"), "not a count"),  # a negative number of groups
    (("0.0 1 3 0\n", "0.0 1 3 -2\n"), "not a count"),  # negative bounding entities
])
def test_msh41_entities_counts_are_checked(tmp_path, edit, fragment):
    """The counts of ``$Entities`` decide which physical groups the elements get: a count
    that is short, or negative, gave the triangles tag 0 and lost the tagged edges while
    ``check`` called the file usable."""
    good = tmp_path / "good.msh"
    qdrefine.write(good, _tagged())
    text = good.read_text()
    assert edit[0] in text
    bad = tmp_path / "bad.msh"
    bad.write_text(text.replace(edit[0], edit[1], 1))
    _refused(bad, "$Entities", fragment)


def test_negative_physical_tags_are_read_as_gmsh_reads_them(tmp_path):
    """MSH 2.2 physical tag -5 was read as -5 without a word; the Gmsh SDK reads it as
    group 5 (checked: its physical groups of this file are (1, 9), (2, 5), (2, 7))."""
    path = tmp_path / "neg.msh"
    path.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 -5 \"hole\"\n"
                    "1 -9 \"wall\"\n$EndPhysicalNames\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n"
                    "3 1 1 0\n4 0 1 0\n$EndNodes\n$Elements\n3\n1 2 2 -5 1 1 2 3\n"
                    "2 2 2 7 1 1 3 4\n3 1 2 -9 1 1 2\n$EndElements\n")
    with pytest.warns(UserWarning, match=r"neg\.msh: negative physical tags \(e\.g\. -9\), "
                                         r"which Gmsh reads as their absolute values"):
        mesh = qdrefine.read(path)
    assert mesh.cell_tags.tolist() == [5, 7] and mesh.edge_tags.tolist() == [9]
    # the names follow their tags (they stayed at -5 and -9, naming no element; review)
    assert mesh.physical_names == {(2, 5): "hole", (1, 9): "wall"}


def test_a_physical_name_that_is_not_utf8_is_read_as_latin1_with_a_warning(tmp_path):
    """'caf\\xe9' (Latin-1, from an older tool) read as 'caf\\ufffd' without a word, and
    convert wrote the replacement character back (review)."""
    path = tmp_path / "latin.msh"
    path.write_bytes(b'$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 5 "caf\xe9"\n'
                     b"$EndPhysicalNames\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n$EndNodes\n"
                     b"$Elements\n1\n1 2 2 5 1 1 2 3\n$EndElements\n")
    with pytest.warns(UserWarning, match=r"latin\.msh: line 6: not UTF-8; read as Latin-1"):
        mesh = qdrefine.read(path)
    assert mesh.physical_names == {(2, 5): "café"}
    path.write_bytes(path.read_bytes().replace(b"\xe9", b"e") + b'$NodeData\n1\n"caf\xe9"\n1\n'
                     b"0\n3\n0\n1\n3\n1 1\n2 2\n3 3\n$EndNodeData\n")  # a view's name
    with pytest.warns(UserWarning, match=r"latin\.msh: line 20: not UTF-8; read as Latin-1"):
        assert list(qdrefine.read(path).point_data) == ["café"]


@pytest.mark.parametrize("version", ["4.1", "2.2"])
@pytest.mark.parametrize("binary", [False, True])
def test_a_msh_file_cut_between_its_sections_says_so(tmp_path, binary, version):
    """A file qdrefine wrote, cut after ``$EndElements`` (or before its last view), read
    without its point and cell data (int32 data as float64), silently (review): the
    ``$QdrefineData`` record now comes before the mesh, and a view it records that the
    file does not hold is an error."""
    mesh = _tagged().replace(point_data={"u": np.arange(len(P), dtype=np.int32)},
                             cell_data={"k": np.arange(len(T), dtype=np.int32)})
    good = tmp_path / "good.msh"
    qdrefine.write(good, mesh, binary=binary, format_version=version)
    data = good.read_bytes()
    assert data.index(b"$QdrefineData") < data.index(b"$Nodes")
    read = qdrefine.read(good)
    assert read.point_data["u"].dtype == np.int32 and read.cell_data["k"].dtype == np.int32
    for cut, missing in ((data.index(b"$EndElements") + len(b"$EndElements\n"), "point"),
                         (data.index(b"$ElementData"), "cell")):
        bad = tmp_path / "bad.msh"
        bad.write_bytes(data[:cut])
        _refused(bad, f"$QdrefineData records the {missing} data", "the file ends early")


@pytest.mark.parametrize("binary", [False, True])
def test_msh41_entities_after_the_elements_are_refused(tmp_path, binary):
    """``$Entities`` after ``$Elements``: the elements had taken physical group 0, so the
    file read without cell tags or tagged edges (its physical names kept), silently
    (review). Gmsh writes ``$Entities`` first."""
    good = tmp_path / "good.msh"
    qdrefine.write(good, _tagged(), binary=binary)
    data = good.read_bytes()
    entities = re.search(rb"\$Entities\n.*?\$EndEntities\n", data, re.S).group(0)
    bad = tmp_path / "bad.msh"
    bad.write_bytes(data.replace(entities, b"").replace(b"$EndElements\n",
                                                         b"$EndElements\n" + entities))
    _refused(bad, "$Entities after $Elements")


@pytest.mark.parametrize("binary", [False, True])
def test_a_node_block_of_impossible_dimension_is_named(tmp_path, binary):
    """A parametric node block of dimension -3 has 0 numbers per node: a division by zero
    (text) or a message without a place (binary)."""
    path = tmp_path / "m.msh"
    qdrefine.write(path, _tagged(), binary=binary)
    data = path.read_bytes()
    start = data.index(b"$Nodes\n") + len(b"$Nodes\n")
    if binary:
        at = start + 4 * 8  # the four counts of the section
        block = struct.pack("<3i", -3, 1, 1)  # dimension, entity, parametric
        data = data[:at] + block + data[at + 12:]
    else:
        lines = data[start:].split(b"\n")
        lines[1] = b"-3 1 1 " + lines[1].split()[-1]
        data = data[:start] + b"\n".join(lines)
    path.write_bytes(data)
    _refused(path, "$Nodes", "dimension -3")


@pytest.mark.parametrize("ext", [".msh", ".vtu"])
@pytest.mark.parametrize("record, reason", [
    ({"shape": [], "dtype": "<,4"}, "is not a dtype"),
    ({"shape": [-1], "dtype": "<f8"}, "is not a list of sizes"),
    ({"shape": [], "dtype": "<i8"}, "are not int64 values"),
    ({"shape": [2], "dtype": "<f8"}, "does not fit"),
    ({"shape": [], "dtype": "|O"}, "is not numeric"),
])
def test_a_record_that_does_not_fit_the_values_is_ignored_with_a_warning(tmp_path, ext, record,
                                                                         reason):
    """The shape and dtype recorded beside a field (``$QdrefineData``, VTU's ``qdrefine``
    field data) are used only where they change no value: a damaged record raised a
    ``SyntaxError`` traceback, made the values vanish (shape ``[-1]``) or truncated
    ``0.5`` to ``0`` (an integer dtype)."""
    values = np.array([0.5, 1.5, 2.5, 3.5, 4.5])
    path = tmp_path / f"m{ext}"
    qdrefine.write(path, Mesh(P, T, point_data={"u": values}))
    data = path.read_bytes()
    old = json.dumps({"shape": [], "dtype": "<f8"}).encode()
    assert data.count(old) == 1
    # as long as the stored record (VTU's appended bytes keep their offsets)
    new = json.dumps(record, separators=(",", ":")).encode().ljust(len(old))
    assert len(new) == len(old)
    data = data.replace(old, new)
    path.write_bytes(data)
    with pytest.warns(UserWarning, match=reason) as caught:
        mesh = qdrefine.read(path)
    assert str(path) in str(caught[0].message) and "'u'" in str(caught[0].message)
    np.testing.assert_array_equal(mesh.point_data["u"], values)  # as stored


def test_records_that_fit_still_restore_shapes_and_dtypes(tmp_path):
    data = {"i": np.arange(5, dtype=np.int32), "b": np.array([1, 0, 1, 1, 0], bool),
            "h": np.linspace(0, 1, 5).astype(np.float16), "v": np.arange(10.).reshape(5, 2),
            "m": np.arange(20, dtype=np.int16).reshape(5, 2, 2)}
    for ext in (".msh", ".vtu"):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            qdrefine.write(tmp_path / f"m{ext}", Mesh(P, T, point_data=data))
            back = qdrefine.read(tmp_path / f"m{ext}")
        for name, value in data.items():
            assert back.point_data[name].dtype == value.dtype, (ext, name)
            np.testing.assert_array_equal(back.point_data[name], value)


NAMES = {(2, 1): "steel\u2028grade A", (2, 2): "a\x0bb\x0c\x1c\x1d\x1e\x85\u2029 z"}


@pytest.mark.parametrize("version", qdrefine.io.GMSH_VERSIONS)
@pytest.mark.parametrize("binary", [False, True])
def test_physical_names_with_unicode_line_breaks_read_back(tmp_path, version, binary):
    """Gmsh ends a line at ``\\n`` only; ``str.splitlines`` also broke a name at
    ``\\u2028``, ``\\x0c`` and the like (written fine, then refused on reading)."""
    path = tmp_path / "m.msh"
    qdrefine.write(path, Mesh(P, T, cell_tags=np.array([1, 1, 2, 2]), physical_names=NAMES),
                   format_version=version, binary=binary)
    assert qdrefine.read(path).physical_names == NAMES


@pytest.mark.parametrize("name", ["temp\x0cK", "a\x00b", "x\ud800"])
def test_vtu_refuses_data_names_xml_cannot_hold(tmp_path, name):
    """XML 1.0 cannot hold these characters, not even escaped: the file was written and
    then could not be read."""
    path = tmp_path / "m.vtu"
    with pytest.raises(ValueError, match="control character"):
        qdrefine.write(path, Mesh(P, T, point_data={name: np.arange(5.)}))
    assert not path.exists()
    # physical names go into JSON, which holds anything
    mesh = Mesh(P, T, cell_tags=np.array([1, 1, 2, 2]), physical_names=NAMES)
    qdrefine.write(path, mesh)
    assert qdrefine.read(path).physical_names == NAMES


def test_xdmf_refuses_a_name_with_a_colon(tmp_path):
    """``run:1.xdmf`` referred to ``run:1.h5:/data0``, which readers split at the first
    colon: written, never read back."""
    path = tmp_path / "run:1.xdmf"
    with pytest.raises(ValueError, match="cannot hold ':'"):
        qdrefine.write(path, _tagged())
    assert not list(tmp_path.iterdir())


def _binary_xdmf(folder: Path, item: str) -> Path:
    path = folder / "bin.xdmf"
    path.write_text(
        '<?xml version="1.0"?>\n<Xdmf Version="3.0"><Domain><Grid Name="mesh" '
        'GridType="Uniform">\n<Geometry GeometryType="XY"><DataItem DataType="Float" '
        f'Precision="8" Dimensions="3 2" Format="Binary">{item}</DataItem></Geometry>\n'
        '<Topology TopologyType="Triangle" NumberOfElements="1"><DataItem DataType="Int" '
        'Precision="8" Dimensions="1 3" Format="XML">0 1 2</DataItem></Topology>\n'
        '</Grid></Domain></Xdmf>\n')
    return path


@pytest.mark.skipif(sys.platform == "win32", reason="FIFOs are POSIX")
def test_xdmf_binary_items_never_wait_on_a_fifo(tmp_path):
    os.mkfifo(tmp_path / "fifo.bin")
    with pytest.raises(OSError, match="not a regular file"):
        qdrefine.read(_binary_xdmf(tmp_path, "fifo.bin"))


def test_xdmf_binary_items_are_read_as_meshio_names_them(tmp_path, monkeypatch):
    """meshio opens a binary item's file by its name from the working directory (and
    writes it so): a name that leads elsewhere from the XDMF file's folder, to another
    file of the same name, was read silently; one written by meshio into a sub-folder
    reads."""
    import meshio

    sub = tmp_path / "sub"
    sub.mkdir()
    monkeypatch.chdir(tmp_path)
    meshio.xdmf.write("sub/m.xdmf", meshio.Mesh(P[:3], [("triangle", np.array([[0, 1, 2]]))]),
                      data_format="Binary")
    assert qdrefine.read(sub / "m.xdmf").n_triangles == 1  # items name "sub/m0.bin"
    (sub / "pts.bin").write_bytes(np.array([0, 0, 5, 0, 0, 5], "<f8").tobytes())
    (tmp_path / "pts.bin").write_bytes(np.array([0, 0, 1, 0, 0, 1], "<f8").tobytes())
    path = _binary_xdmf(sub, "pts.bin")
    with pytest.raises(ValueError, match="two different files"):
        qdrefine.read(Path("sub") / "bin.xdmf")
    (tmp_path / "pts.bin").unlink()
    with pytest.raises(ValueError, match="where there is none"):
        qdrefine.read(Path("sub") / "bin.xdmf")
    monkeypatch.chdir(sub)
    assert qdrefine.read(path).points.max() == 5
    monkeypatch.chdir(tmp_path)
    assert qdrefine.read(_binary_xdmf(sub, sub / "pts.bin")).points.max() == 5  # absolute


def test_dorfler_marking_of_indicators_near_the_float_limit():
    """The cumulative sum of values near 1e308 overflowed: too many or too few marks."""
    assert mark_dorfler([1e308, 9e307, 8e307, 7e307], 0.1).tolist() == [True] + [False] * 3
    assert mark_dorfler([1e308] * 4, 0.1).sum() == 4  # ties: all or none
    assert mark_dorfler([1.5e308, 1.5e308, 1e300], 1.0).sum() == 3
    eta = np.random.default_rng(0).random(1000)
    np.testing.assert_array_equal(mark_dorfler(eta * 2.0**1000, 0.5), mark_dorfler(eta, 0.5))


@pytest.mark.parametrize("call", [lambda: qdrefine.refine("m", marked=[0]),
                                  lambda: qdrefine.refine("m"),
                                  lambda: qdrefine.coarsen("m", [0])])
def test_mesh_functions_say_they_need_a_mesh(call):
    with pytest.raises(TypeError, match=r"\(\) needs a Mesh, got str"):
        call()


def test_a_physical_group_named_twice_is_refused(tmp_path):
    """The second name silently replaced the first."""
    path = tmp_path / "m.msh"
    qdrefine.write(path, _tagged())
    text = path.read_text()
    assert '$PhysicalNames\n1\n2 1 "a"\n' in text
    path.write_text(text.replace('$PhysicalNames\n1\n2 1 "a"\n',
                                 '$PhysicalNames\n2\n2 1 "a"\n2 1 "b"\n'))
    _refused(path, "named twice", "'a' and 'b'")


@pytest.mark.parametrize("binary", [False, True])
def test_a_node_given_two_values_in_a_view_is_refused(tmp_path, binary):
    """The last value silently won."""
    path = tmp_path / "m.msh"
    qdrefine.write(path, Mesh(P, T, point_data={"u": np.arange(5.)}), binary=binary)
    data = path.read_bytes()
    if binary:
        at = data.index(struct.pack("<id", 1, 0.0), data.index(b"$NodeData"))
        data = data[:at] + struct.pack("<i", 2) + data[at + 4:]
    else:
        assert data.count(b"\n1 0\n") == 1
        data = data.replace(b"\n1 0\n", b"\n2 0\n")
    path.write_bytes(data)
    _refused(path, "$NodeData 'u' gives node 2 two values")


def test_a_vtu_triangle_cell_of_four_points_is_named(tmp_path):
    """A cell of VTK type 5 (triangle) with another number of points was dropped, and the
    file refused as one without triangles."""
    path = tmp_path / "m.vtu"
    qdrefine.write(path, Mesh(P, T))
    data = path.read_bytes()
    offsets = np.array([3, 6, 9, 12], "<i8").tobytes()
    assert data.count(offsets) == 1
    path.write_bytes(data.replace(offsets, np.array([3, 6, 10, 12], "<i8").tobytes()))
    _refused(path, "cell 2 is a triangle (VTK type 5) of 4 points, not 3")


def test_a_second_tag_field_is_read_as_cell_data_not_dropped(tmp_path):
    """A VTK file with both ``gmsh:physical`` and ``tag`` cell data: the first is the
    tags, the other was silently dropped (the VTU reader kept it as cell data)."""
    import meshio

    path = tmp_path / "m.vtk"
    cells = [("triangle", T)]
    meshio.write(path, meshio.Mesh(np.c_[P, np.zeros(5)], cells, cell_data={
        "gmsh:physical": [np.array([1, 1, 2, 2])], "tag": [np.array([7, 8, 9, 10])]}),
        binary=True)
    mesh = qdrefine.read(path)
    np.testing.assert_array_equal(mesh.cell_tags, [1, 1, 2, 2])
    np.testing.assert_array_equal(mesh.cell_data["tag"], [7, 8, 9, 10])


def test_damaged_records_of_names_and_shapes_never_end_in_a_traceback(tmp_path):
    """A VTU physical-name record with a tag of 1e999 raised OverflowError (a traceback);
    a recorded shape of 10**24 rows beside a 0 (a zero-width field) refused the file
    without its name."""
    path = tmp_path / "m.vtu"
    qdrefine.write(path, Mesh(P, T, cell_tags=np.array([1, 1, 2, 2]),
                              physical_names={(2, 1): "abc"}))
    data = path.read_bytes()
    assert data.count(b'[[2, 1, "abc"]]') == 1
    path.write_bytes(data.replace(b'[[2, 1, "abc"]]', b'[[9e999,1,"a"]]'))
    _refused(path, "physical names are not (dim, tag, name) triples")
    path = tmp_path / "m.msh"
    qdrefine.write(path, Mesh(P, T, point_data={"e": np.zeros((5, 0))}))
    text = path.read_text()
    assert text.count('{"shape": [0], "dtype": "<f8"}') == 1
    path.write_text(text.replace('{"shape": [0], "dtype": "<f8"}',
                                 '{"shape": [1000000000000000000000000, 0], "dtype": "<f8"}'))
    with pytest.warns(UserWarning, match="cannot be made"):
        qdrefine.read(path)


def test_msh_refuses_unsigned_integers_beyond_2_53(tmp_path):
    """uint64 values near 2**64 wrapped to small ones in the check and were written as
    2**64."""
    path = tmp_path / "m.msh"
    big = np.array([0, 1, 2, 3, 2**64 - 1], dtype=np.uint64)
    with pytest.raises(ValueError, match=r"integers of 2\*\*53 or more in magnitude"):
        qdrefine.write(path, Mesh(P, T, point_data={"id": big}))
    assert not path.exists()
    qdrefine.write(path, Mesh(P, T, point_data={"id": big % 2**53}))  # within: kept
    assert qdrefine.read(path).point_data["id"].dtype == np.uint64


def _nested_metadata(path, ext: str) -> None:
    """Replace the qdrefine record of ``path`` with JSON nested 50,000 deep."""
    data = path.read_bytes()
    nested = b"[" * 50_000 + b"]" * 50_000
    if ext == ".msh":
        start = data.index(b"$QdrefineData\n") + len(b"$QdrefineData\n")
        path.write_bytes(data[:start] + nested + data[data.index(b"\n$EndQdrefineData", start):])
        return
    # VTU: the record is the first appended array (UInt64 size header); move the others
    at = data.index(b"_", data.index(b"<AppendedData")) + 1
    size = struct.unpack("<Q", data[at:at + 8])[0]
    shift = len(nested) - size
    head = re.sub(rb'offset="(\d+)"', lambda m: b'offset="%d"' % (
        int(m[1]) + shift if int(m[1]) else 0), data[:at])
    head = head.replace(b'NumberOfTuples="%d"' % size, b'NumberOfTuples="%d"' % len(nested))
    path.write_bytes(head + struct.pack("<Q", len(nested)) + nested + data[at + 8 + size:])


@pytest.mark.parametrize("ext", [".msh", ".vtu"])
def test_a_record_nested_too_deep_is_a_clear_error(tmp_path, ext):
    """JSON nested deeper than Python's recursion limit: ``RecursionError`` and a traceback
    from the command line (review); now the error of any record that is not JSON."""
    path = tmp_path / f"m{ext}"
    qdrefine.write(path, Mesh(P, T, point_data={"u": np.arange(5.0)}))
    _nested_metadata(path, ext)
    with pytest.raises(ValueError, match=r"m\.(msh|vtu).*is not JSON"):
        qdrefine.read(path)


GMSH_VIEWS = """
import sys
import gmsh
gmsh.initialize(interruptible=False)
gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.add("t")
occ = gmsh.model.occ
occ.fragment([(2, occ.addRectangle(0, 0, 0, 1, 1))], [(2, occ.addRectangle(1, 0, 0, 1, 1))])
occ.synchronize()
gmsh.model.addPhysicalGroup(2, [1], name="left")  # the file holds this surface's mesh only
gmsh.model.mesh.setSize(gmsh.model.getEntities(0), 0.5)
gmsh.model.mesh.generate(2)
tags, xyz, _ = gmsh.model.mesh.getNodes()
u = gmsh.view.add("u")  # over every node of the model: x
gmsh.view.addHomogeneousModelData(u, 0, "t", "NodeData", tags, xyz[0::3].tolist())
_, elements, nodes = gmsh.model.mesh.getElements(2)
w = gmsh.view.add("w")  # over every triangle: its element tag
gmsh.view.addHomogeneousModelData(w, 0, "t", "ElementData", elements[0],
                                  elements[0].astype(float).tolist())
gmsh.option.setNumber("Mesh.MshFileVersion", float(sys.argv[3]))
gmsh.option.setNumber("PostProcessing.SaveMesh", 1)
gmsh.view.write(u, sys.argv[1])
gmsh.view.write(w, sys.argv[2])
gmsh.finalize()
"""


@pytest.mark.parametrize("version", ["4.1", "2.2"])
def test_a_view_of_the_whole_model_beside_a_mesh_of_its_groups_reads(tmp_path, version):
    """Gmsh writes a view's values for every node (element) of the model, and the mesh of
    its physical groups only: the values of nodes and elements not in the file are left
    out. A review's refusal of such values (to catch a damaged tag) refused Gmsh's own
    files (a review of the session). MSH 2.2 gives the nodes not in the file tag -1 (read
    as "two values for node -1" before)."""
    u, w = tmp_path / "u.msh", tmp_path / "w.msh"
    subprocess.run([sys.executable, "-c", GMSH_VIEWS, str(u), str(w), version], check=True,
                   timeout=120)
    mesh = qdrefine.read(u)
    assert mesh.cell_tags is not None and np.unique(mesh.cell_tags).tolist() == [1]
    assert mesh.points[:, 0].max() <= 1.0  # the left surface only
    np.testing.assert_array_equal(mesh.point_data["u"], mesh.points[:, 0])
    if version == "2.2":  # Gmsh 2.2 repeats the last element's tag for those not in the
        return  # file: "element 16 two values", refused (not ours to guess)
    cells = qdrefine.read(w)
    assert cells.n_triangles == mesh.n_triangles
    assert np.isfinite(cells.cell_data["w"]).all()


@pytest.mark.parametrize("binary", [False, True])
@pytest.mark.parametrize(("block", "header", "message"), [
    (0, (1, 1, 2), "element block 1 of $Elements holds triangles (dimension 2) in entity 1 "
                   "of dimension 1"),
    (1, (2, 1, 1), "element block 2 of $Elements holds lines (dimension 1) in entity 1 of "
                   "dimension 2"),
])
def test_an_element_block_in_an_entity_of_another_dimension_is_refused(tmp_path, binary,
                                                                       block, header, message):
    """MSH 4.1: triangles in curve 1 took curve 1's physical group as cell tag, lines in
    surface 1 became edges tagged with the surface's group, without a word (review)."""
    path = tmp_path / "e.msh"
    qdrefine.write(path, Mesh(P, T, cell_tags=np.ones(4, int), edges=[[0, 1]], edge_tags=[6]),
                   binary=binary)
    data = path.read_bytes()
    old = [(2, 1, 2), (1, 1, 1)][block]  # surface 1's triangles, curve 1's line
    if binary:
        assert data.count(struct.pack("<3i", *old)) == 1
        data = data.replace(struct.pack("<3i", *old), struct.pack("<3i", *header))
    else:
        count = [4, 1][block]
        line = b"\n%d %d %d %d\n" % (*old, count)
        assert data.count(line) == 1
        header_line = data[:data.index(line)].count(b"\n") + 2  # the block header's line
        data = data.replace(line, b"\n%d %d %d %d\n" % (*header, count))
    path.write_bytes(data)
    where = r"byte \d+" if binary else f"line {header_line}"
    with pytest.raises(ValueError, match=r"e\.msh: not a readable Gmsh MSH file \(" + where
                                         + ": " + re.escape(message)):
        qdrefine.read(path)


def test_a_binary_marker_that_is_not_one_is_named(tmp_path):
    """A damaged marker (7) was reported as a big-endian file (review)."""

    path = tmp_path / "b.msh"
    qdrefine.write(path, Mesh(P, T), binary=True)
    data = path.read_bytes()
    assert data.count(b"4.1 1 8\n" + struct.pack("<i", 1)) == 1
    for marker, message in ((7, r"the binary format's marker is 7, not the integer 1"),
                            (1 << 24, "big-endian binary MSH files are not supported")):
        path.write_bytes(data.replace(b"4.1 1 8\n" + struct.pack("<i", 1),
                                      b"4.1 1 8\n" + struct.pack("<i", marker)))
        with pytest.raises(ValueError, match=r"b\.msh: not a readable Gmsh MSH file \(byte "
                                             r"\d+: " + message):
            qdrefine.read(path)


@pytest.mark.parametrize("section", ["Nodes", "Elements", "PhysicalNames"])
def test_a_section_given_twice_is_refused(tmp_path, section):
    """MSH 2.2 with two ``$Nodes``: the second replaced the first and the error named a
    node missing from it (review)."""
    path = tmp_path / "t.msh"
    qdrefine.write(path, Mesh(P, T, cell_tags=np.ones(4, int), physical_names={(2, 1): "a"}),
                   format_version="2.2")
    text = path.read_text()
    block = text[text.index(f"${section}\n"):text.index(f"$End{section}\n")]
    path.write_text(text.replace(block, block + f"$End{section}\n" + block, 1))
    with pytest.raises(ValueError, match=rf"t\.msh: not a readable Gmsh MSH file \(line \d+: "
                                         rf"a second \${section} section"):
        qdrefine.read(path)


def test_heavy_data_that_is_not_a_regular_file_is_named(tmp_path):
    """An XDMF item naming ``/dev/zero`` said "/dev/zero: no such file" (review)."""
    path = tmp_path / "m.xdmf"
    qdrefine.write(path, Mesh(P, T))
    text = path.read_text()
    h5 = re.search(r">\s*([^<>:\s]+\.h5):", text)[1]
    path.write_text(text.replace(f"{h5}:", "/dev/zero:"))
    with pytest.raises(OSError, match="/dev/zero: not a regular file"):
        qdrefine.read(path)


def _vtu_with_points_block(points: int, block: bytes,
                           compressor: str = "vtkZLibDataCompressor") -> bytes:
    """A compressed VTU whose Points array (UInt8, 3 components, ``points`` rows) is the
    appended ``block`` (header and compressed data)."""
    xml = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
           'byte_order="LittleEndian" header_type="UInt64" '
           f'compressor="{compressor}">\n<UnstructuredGrid>\n'
           f'<Piece NumberOfPoints="{points}" NumberOfCells="1">\n<Points>\n'
           '<DataArray type="UInt8" Name="Points" NumberOfComponents="3" format="appended" '
           'offset="0"/>\n</Points>\n<Cells>\n'
           '<DataArray type="Int64" Name="connectivity" format="appended" offset="0"/>\n'
           '<DataArray type="Int64" Name="offsets" format="appended" offset="0"/>\n'
           '<DataArray type="UInt8" Name="types" format="appended" offset="0"/>\n'
           '</Cells>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding="raw">\n_')
    return xml.encode() + block + b"\n</AppendedData>\n</VTKFile>\n"


@pytest.mark.parametrize("compressor", ["zlib", "lzma"])
@pytest.mark.parametrize("points, declared, message", [
    (5, None, "byte .*: DataArray 'Points' decompresses to more than the 15 bytes its rows "
              "take"),
    (10_000, 45, "compressed block 0 of DataArray 'Points' holds more than the 45 bytes its "
                 "header declares"),
])
def test_a_compressed_vtu_block_cannot_expand_past_its_sizes(tmp_path, points, declared,
                                                            message, compressor):
    """A 65 kB file whose Points block decompresses to 64 MiB took 3.6 GB and 12 s before
    its sizes were checked (review): the block stops at the bytes its rows take or its
    header declares, whichever is less. Raw lzma data went to meshio, which decompressed
    it whole; it is read here now."""
    import lzma
    import tracemalloc
    import zlib

    pack, name = {"zlib": (zlib.compress, "vtkZLibDataCompressor"),
                  "lzma": (lzma.compress, "vtkLZMADataCompressor")}[compressor]
    body = pack(bytes(1 << 26))
    size = 1 << 26 if declared is None else declared
    head = struct.pack("<4Q", 1, size, size, len(body))
    (tmp_path / "bomb.vtu").write_bytes(_vtu_with_points_block(points, head + body, name))
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=message):
            qdrefine.read(tmp_path / "bomb.vtu")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20  # 64 MiB were made before (lzma keeps an 8 MiB dictionary)


@pytest.mark.parametrize("kind", ["NodeData", "ElementData"])
def test_a_view_of_absurdly_many_components_is_refused_before_it_is_made(tmp_path, kind):
    """A 300-byte file whose view had no values and 1e8 components took 4 GB: the field was
    made that wide, filled with NaN (review). Gmsh views have 1, 3 or 9 components; wider
    ones must give every row a value, as qdrefine writes them."""
    mesh = examples.square(1)
    rows = mesh.n_points if kind == "NodeData" else mesh.n_triangles
    data = {"u": np.arange(rows, dtype=float)}
    mesh = mesh.replace(**({"point_data": data} if kind == "NodeData" else {"cell_data": data}))
    qdrefine.write(tmp_path / "m.msh", mesh)
    text = (tmp_path / "m.msh").read_text()
    head = f'${kind}\n1\n"u"\n1\n0\n3\n0\n1\n{rows}\n'
    assert head in text
    body = text[text.index(head):text.index(f"$End{kind}")]
    text = text.replace(body, f'${kind}\n1\n"u"\n1\n0\n3\n0\n100000000\n0\n')
    (tmp_path / "m.msh").write_text(text)
    where = "point" if kind == "NodeData" else "cell"
    with pytest.raises(ValueError, match=rf"m.msh: {where} data 'u' has 100000000 components "
                                         rf"but values for 0 of the {rows} rows"):
        qdrefine.read(tmp_path / "m.msh")
    # a field wider than 9 that qdrefine wrote whole still reads back (review of the first
    # version of this check, which refused it)
    wide = {"w": np.arange(rows * 12, dtype=float).reshape(rows, 3, 4)}
    mesh = mesh.replace(**({"point_data": wide} if kind == "NodeData" else {"cell_data": wide}))
    for binary in (False, True):
        qdrefine.write(tmp_path / "w.msh", mesh, binary=binary)
        back = qdrefine.read(tmp_path / "w.msh")
        got = back.point_data if kind == "NodeData" else back.cell_data
        np.testing.assert_array_equal(got["w"], wide["w"])


def test_a_binary_node_tag_beyond_int64_is_refused(tmp_path):
    """A uint64 node tag of 2**63 or more was read as a negative tag (review)."""
    qdrefine.write(tmp_path / "m.msh", examples.square(1), binary=True)
    data = bytearray((tmp_path / "m.msh").read_bytes())
    first_tag = data.index(b"$Nodes\n") + len(b"$Nodes\n") + 4 * 8 + 3 * 4 + 8
    data[first_tag:first_tag + 8] = struct.pack("<Q", 2**63 + 1)
    (tmp_path / "m.msh").write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"node tag 9223372036854775809 is beyond int64"):
        qdrefine.read(tmp_path / "m.msh")


@pytest.mark.parametrize("change, why", [
    (lambda text: "\ufeff" + text, "starts with a UTF-8 byte-order mark"),
    (lambda text: text.replace("\n", "\r"), "lines end in CR only"),
])
def test_a_msh_file_that_does_not_start_as_gmsh_reads_says_why(tmp_path, change, why):
    """Both said only "no $MeshFormat section at the start", which the file has (review)."""
    qdrefine.write(tmp_path / "m.msh", examples.square(1))
    text = (tmp_path / "m.msh").read_text()
    (tmp_path / "m.msh").write_bytes(change(text).encode())
    with pytest.raises(ValueError, match=f"no \\$MeshFormat section at the start .*{why}"):
        qdrefine.read(tmp_path / "m.msh")


@pytest.mark.parametrize("compressor", ["zlib", "lzma"])
def test_vtu_files_meshio_reads_are_bounded_too(tmp_path, compressor):
    """Inline or base64 VTU goes to meshio, which decompressed every block whole: a 209 kB
    file took 2.3 GB before the error (review). The blocks are decompressed, bounded by
    their rows and header sizes, before meshio reads the file; meshio's own files of either
    compressor still read bit for bit."""
    import base64
    import lzma
    import tracemalloc
    import zlib

    import meshio

    mesh = examples.plate_with_hole()
    theirs = meshio.Mesh(np.c_[mesh.points, np.zeros(mesh.n_points)],
                         [("triangle", mesh.triangles)], point_data={"u": mesh.points[:, 0]})
    meshio.write(tmp_path / "ok.vtu", theirs, compression=compressor)
    back = qdrefine.read(tmp_path / "ok.vtu")
    assert np.array_equal(back.points, mesh.points)
    assert np.array_equal(back.point_data["u"], mesh.points[:, 0])

    pack = zlib.compress if compressor == "zlib" else lzma.compress
    body = pack(bytes(1 << 26))
    head = struct.pack("<4Q", 1, 1 << 26, 1 << 26, len(body))
    inline = (base64.b64encode(head) + base64.b64encode(body)).decode()
    name = {"zlib": "vtkZLibDataCompressor", "lzma": "vtkLZMADataCompressor"}[compressor]
    (tmp_path / "bomb.vtu").write_text(
        '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
        f'byte_order="LittleEndian" header_type="UInt64" compressor="{name}">\n'
        '<UnstructuredGrid>\n<Piece NumberOfPoints="5" NumberOfCells="1">\n<Points>\n'
        '<DataArray type="UInt8" Name="Points" NumberOfComponents="3" format="binary">\n'
        f'{inline}\n</DataArray>\n</Points>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n')
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match="bomb.vtu: not a readable VTK XML unstructured "
                                             "grid file .DataArray 'Points' decompresses to "
                                             "more than the 15 bytes its rows take"):
            qdrefine.read(tmp_path / "bomb.vtu")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20  # 64 MiB were made before, whole


def test_a_raw_lzma_vtu_reads_bit_for_bit(tmp_path):
    """ParaView can write appended raw data compressed by lzma: read here now (bounded),
    where meshio read it before: our zlib file with every block recompressed by lzma."""
    import lzma
    import zlib

    mesh = examples.plate_with_hole()
    qdrefine.write(tmp_path / "z.vtu", mesh, compress=True)
    data = (tmp_path / "z.vtu").read_bytes()
    start = data.index(b"_", data.index(b"<AppendedData")) + 1
    xml, offsets = data[:start], [int(o) for o in re.findall(rb'offset="(\d+)"', data[:start])]
    blocks = b""
    for old in offsets:
        n, full, last = struct.unpack_from("<3Q", data, start + old)
        sizes = struct.unpack_from(f"<{n}Q", data, start + old + 24)
        pos, out = start + old + 24 + 8 * n, []
        for c in sizes:
            out.append(lzma.compress(zlib.decompress(data[pos:pos + c])))
            pos += c
        xml = xml.replace(f'offset="{old}"'.encode(), f'offset="@{len(blocks)}"'.encode(), 1)
        blocks += struct.pack(f"<{3 + n}Q", n, full, last, *map(len, out)) + b"".join(out)
    xml = xml.replace(b"@", b"").replace(b"vtkZLibDataCompressor", b"vtkLZMADataCompressor")
    (tmp_path / "x.vtu").write_bytes(xml + blocks + b"\n</AppendedData>\n</VTKFile>\n")
    back = qdrefine.read(tmp_path / "x.vtu")
    assert np.array_equal(back.points, mesh.points)
    assert np.array_equal(back.triangles, mesh.triangles)
    assert np.array_equal(back.cell_tags, mesh.cell_tags)


@pytest.mark.parametrize("body, missing", [("", "Nodes"),
                                           ("$Nodes\n1 1\n1 0 0 1\n1 0 0 0\n$EndNodes\n",
                                            "Elements")])
def test_a_msh40_file_without_its_sections_says_which(tmp_path, body, missing):
    """MSH 4.0 goes to meshio, which said "cannot access local variable 'cells' where it is
    not associated with a value" for a file of its header alone (review)."""
    path = tmp_path / "m.msh"
    path.write_text("$MeshFormat\n4 0 8\n$EndMeshFormat\n" + body)
    _refused(path, f"no ${missing} section")


def test_check_reports_a_history_that_reading_refuses(tmp_path):
    """A history row out of range: every command refused the file ("transitions: each row
    is a vertex row or all -1") while ``qdrefine check`` called it usable (review)."""
    from qdrefine.io import check_file

    base = examples.plate_with_hole()
    local = qdrefine.refine(base, marked=[0, 1])
    rows = local.transitions.copy()
    rows[np.flatnonzero(rows[:, 0] >= 0)[0], 1] = 99999
    path = tmp_path / "m.vtu"
    qdrefine.write(path, local)
    good = check_file(path)[1]
    assert good.ok
    qdrefine.write(path, local.replace(transitions=None).replace(
        cell_data={"qdrefine:transitionz": rows}))  # a name of the same length, renamed
    data = path.read_bytes().replace(b"qdrefine:transitionz", b"qdrefine:transitions")
    path.write_bytes(data)
    with pytest.raises(ValueError, match="transitions: each row is a vertex row or all -1"):
        qdrefine.read(path)
    found = check_file(path)[1]
    assert not found.ok
    assert [p.kind for p in found.problems if p.severity == "error"] == ["data"]


@pytest.mark.parametrize("value", [1e300, 2.0**63, 2**63])
def test_a_history_value_beyond_int64_is_refused_without_a_cast_warning(tmp_path, value):
    """1e300 in a history row printed NumPy's "invalid value encountered in cast" beside the
    refusal (review)."""
    from qdrefine.io._core import RawMesh, split_data

    raw = RawMesh(tmp_path / "m.msh", np.zeros((3, 2)), np.array([[0, 1, 2]]))
    rows = np.array([[0, 1, value]], dtype=np.float64 if isinstance(value, float) else
                    np.uint64)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="'qdrefine:transitions' must be 3 integers per "
                                             "triangle"):
            split_data(raw, {}, {"qdrefine:transitions": rows})


def test_a_big_endian_base64_vtu_is_bounded_by_its_own_offsets(tmp_path):
    """The check before meshio read a big-endian file's offsets in little-endian order, so
    its connectivity's bound was 3 * 2**56 instead of 3 entries (final read): a block of
    64 MiB behind it was decompressed. Bounded by the offsets as the file gives them."""
    import base64
    import tracemalloc
    import zlib

    def block(raw: bytes) -> str:
        body = zlib.compress(raw)
        return (base64.b64encode(struct.pack(">4Q", 1, len(raw), len(raw), len(body)))
                + base64.b64encode(body)).decode()

    def item(kind: str, name: str, raw: bytes, comps: int = 1) -> str:
        return (f'<DataArray type="{kind}" Name="{name}" NumberOfComponents="{comps}" '
                f'format="binary">{block(raw)}</DataArray>\n')

    points = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], ">f8").tobytes()

    def vtu(connectivity: bytes) -> str:
        return ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
                'byte_order="BigEndian" header_type="UInt64" '
                'compressor="vtkZLibDataCompressor">\n<UnstructuredGrid>\n'
                '<Piece NumberOfPoints="3" NumberOfCells="1">\n<Points>\n'
                + item("Float64", "Points", points, 3) + "</Points>\n<Cells>\n"
                + item("Int64", "connectivity", connectivity)
                + item("Int64", "offsets", np.array([3], ">i8").tobytes())
                + item("UInt8", "types", bytes([5]))
                + "</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n")

    (tmp_path / "ok.vtu").write_text(vtu(np.array([0, 1, 2], ">i8").tobytes()))
    assert qdrefine.read(tmp_path / "ok.vtu").triangles.tolist() == [[0, 1, 2]]
    (tmp_path / "big.vtu").write_text(vtu(bytes(1 << 26)))
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match="DataArray 'connectivity' decompresses to more "
                                             "than the 24 bytes its rows take"):
            qdrefine.read(tmp_path / "big.vtu")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 16 << 20
