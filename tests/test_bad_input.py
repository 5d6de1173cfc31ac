"""Every bad-input kind of the robustness issue, through the Python API and the command line.

Each case is a small file (or none) with the message it must produce. The API part calls
``qdrefine.read`` (and ``Mesh`` on the same arrays where the problem is in the content); the
command-line part runs ``qdrefine refine IN OUT`` and ``qdrefine check IN`` as subprocesses
(the later cases call ``qdrefine.cli.main`` in-process, except those about signals, memory
limits of a fresh process and files that could hang a reader) and checks the exit code,
the one-line message, that OUT does not exist and that the input files are unchanged byte
for byte (and no other file appeared).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

import qdrefine
from cli_runner import cli, finish, start, without_compile_note
from meshes import DATA, crack
from qdrefine import Mesh, check, examples
from qdrefine.memory import MEMORY_LIMIT_VARIABLE, memory_needed


def msh22(nodes, triangles=(), lines=(), quads=()) -> str:
    """A Gmsh 2.2 ASCII file; ``nodes`` are (x, y) or (x, y, z), cells 0-based."""
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", str(len(nodes))]
    for i, xyz in enumerate(nodes):
        x, y, z = (*xyz, 0.0)[:3]
        out.append(f"{i + 1} {x} {y} {z}")
    cells = [(2, c) for c in triangles] + [(1, c) for c in lines] + [(3, c) for c in quads]
    out += ["$EndNodes", "$Elements", str(len(cells))]
    out += [f"{i + 1} {typ} 2 5 5 " + " ".join(str(v + 1) for v in vs)
            for i, (typ, vs) in enumerate(cells)]
    return "\n".join(out + ["$EndElements", ""])


SQ = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
SQ_TRIS = [(0, 1, 2), (0, 2, 3)]
HANGING = [(0.0, 0.0), (2.0, 0.0), (1.0, 1.0), (1.0, 0.0), (1.0, -1.0)]
HANGING_TRIS = [(0, 1, 2), (0, 4, 3), (3, 4, 1)]  # vertex 3 inside edge (0, 1)

INNER = SQ + [(0.5, 0.5), (0.5, 0.5), (0.6, 0.5), (0.5, 0.6)]
INNER_TRIS = [(0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4), (5, 6, 7)]  # 5 copies inner 4


@dataclass
class Case:
    """Files to create, the input to give, the message expected everywhere (a substring),
    the error type of ``qdrefine.read``, the arrays ``Mesh`` must refuse with the same
    message (optional), and the kind ``qdrefine check`` must report (None: unreadable)."""

    files: dict[str, str | bytes]
    input: str
    message: str
    error: type[Exception] = ValueError
    arrays: tuple | None = None
    kind: str | None = None
    mesh_message: str | None = None
    extra: list[str] = field(default_factory=list)


def _content(kind, nodes, tris, message, mesh_message, **cells) -> Case:
    """A content problem: ``message`` in the file's numbering (Gmsh nodes and elements are
    numbered from 1 by :func:`msh22`), ``mesh_message`` in the arrays' (from 0)."""
    return Case({"in.msh": msh22(nodes, tris, **cells)}, "in.msh", message,
                arrays=(np.array(nodes, dtype=float)[:, :2], np.array(tris, dtype=int)),
                kind=kind, mesh_message=mesh_message)


CASES: dict[str, Case] = {
    "missing file": Case({}, "missing.msh", "missing.msh: no such file", FileNotFoundError),
    "unreadable file (a directory)": Case({"dir.msh/keep": "x"}, "dir.msh",
                                          "dir.msh: is a directory", IsADirectoryError),
    "unreadable file (not text)": Case({"b.node": b"\xff\xfe\x00\x01" * 20,
                                        "b.ele": "1 3 0\n0 0 1 2\n"}, "b.ele",
                                       "b.node: not a text file"),
    "unknown format": Case({"in.xyz": "0 0\n"}, "in.xyz", "in.xyz: unknown file format"),
    "truncated file": Case({"cut.msh": (DATA / "two_regions_22.msh").read_text()[:900]},
                           "cut.msh", "cut.msh: not a readable Gmsh"),
    "truncated Triangle file": Case({"t.node": "4 2 0 0\n0 0 0\n1 1 0\n",
                                     "t.ele": "1 3 0\n0 0 1 2\n"}, "t.ele",
                                    "t.node:1: file ends early"),
    "PLY file that is only 'ply'": Case({"t.ply": "ply\n"}, "t.ply",
                                        "t.ply: the file ends early"),
    "PLY header cut short": Case({"c.ply": "ply\nformat ascii 1.0\nelement vertex 3\n"},
                                 "c.ply", "c.ply: the file ends early"),
    "OFF file that is only 'OFF'": Case({"t.off": "OFF\n"}, "t.off",
                                        "t.off: the file ends early"),
    "OBJ cut at a line end (counts in its header)": Case(
        {"c.obj": "# Vertices: 4\n# Faces: 2\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\n"},
        "c.obj", "c.obj: the file holds 1 face, its header announces 2"),
    "ASCII STL cut between two facets": Case(
        {"c.stl": "solid s\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n"
                  "   vertex 1 0 0\n   vertex 0 1 0\n  endloop\n endfacet\n"},
        "c.stl", "c.stl: the file ends early"),
    "ASCII PLY with more lines than its header announces": Case(
        {"m.ply": "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\n"
                  "property double y\nproperty double z\nelement face 1\n"
                  "property list uint8 int32 vertex_indices\nend_header\n0 0 0\n1 0 0\n"
                  "0 1 0\n3 0 1 2\n3 0 2 1\n"},
        "m.ply", "m.ply: the file holds 5 data lines after end_header, its header announces 4"),
    "corrupt file": Case({"junk.vtu": np.random.default_rng(1).bytes(400)}, "junk.vtu",
                         "junk.vtu: not a readable VTK XML"),
    "no triangles": Case({"in.msh": msh22(SQ, lines=[(0, 1)])}, "in.msh",
                         "in.msh: holds no triangles", arrays=(np.array(SQ), np.empty((0, 3), int)),
                         kind="no-triangles", mesh_message="the mesh has no triangles"),
    "non-triangle cells": Case({"in.msh": msh22(SQ, SQ_TRIS, quads=[(0, 1, 2, 3)])}, "in.msh",
                               "in.msh: holds 1 quad cells", kind="cell-types"),
    "NaN coordinate": _content("non-finite", [(0, 0), (1, 0), ("nan", 1)], [(0, 1, 2)],
                               "point 3 has a non-finite coordinate (nan, 1.0)",
                               "point 2 has a non-finite coordinate (nan, 1.0)"),
    "infinite coordinate": Case({"i.node": "3 2 0 0\n1 0 0\n2 1 0\n3 inf 1\n",
                                 "i.ele": "1 3 0\n1 1 2 3\n"}, "i.ele",
                                "i.node:4: point 3 has a non-finite coordinate (inf, 1.0)",
                                arrays=(np.array([(0, 0), (1, 0), (np.inf, 1)]),
                                        np.array([(0, 1, 2)])),
                                kind="non-finite",
                                mesh_message="point 2 has a non-finite coordinate (inf, 1.0)"),
    "coordinate out of range": _content("coordinate-range", [(0, 0), (1e200, 0), (0, 1)],
                                        [(0, 1, 2)], "point 2 has a coordinate (1e+200, 0.0) "
                                        "outside the supported range",
                                        "point 1 has a coordinate (1e+200, 0.0) outside"),
    "index out of range": Case({"x.node": "3 2 0 0\n0 0 0\n1 1 0\n2 0 1\n",
                                "x.ele": "1 3 0\n0 0 1 9\n"}, "x.ele",
                               "x.ele:2: vertex 9 is not in x.node (vertices 0..2)",
                               arrays=(np.array([(0, 0), (1, 0), (0, 1)]), np.array([(0, 1, 9)])),
                               kind="index-range",
                               mesh_message="triangle 0 (0, 1, 9) has a vertex index outside "
                                            "0..2"),
    "duplicate vertices": _content("duplicate-points", SQ + [(1.0, 1.0)],
                                   [(0, 1, 2), (0, 4, 3)],
                                   "points 3 and 5 are both at (1.0, 1.0)",
                                   "points 2 and 4 are both at (1.0, 1.0)"),
    "zero-area triangle": _content("zero-area", [(0, 0), (1, 0), (2, 0)], [(0, 1, 2)],
                                   "triangle 1 (1, 2, 3) has zero area",
                                   "triangle 0 (0, 1, 2) has zero area"),
    "edge shared by three triangles": _content(
        "overused-edge", SQ + [(2.0, 0.5)], SQ_TRIS + [(0, 4, 2)],
        "edge (1, 3) is shared by 3 triangles (1, 2, 3)",
        "edge (0, 2) is shared by 3 triangles (0, 1, 2)"),
    "overlapping triangles (folded edge)": _content(
        "folded-edge", SQ + [(2.0, 0.5)], [(0, 1, 2), (0, 4, 2)],
        "triangles 1 and 2 lie on the same side of their common edge (1, 3)",
        "triangles 0 and 1 lie on the same side of their common edge (0, 2)"),
    "hanging node": _content("hanging-node", HANGING, HANGING_TRIS,
                             "vertex 4 lies inside edge (1, 2) of triangle 1",
                             "vertex 3 lies inside edge (0, 1) of triangle 0"),
    "boundary edges crossing (self-intersection)": _content(
        "self-intersection", [(0, 0), (2, 0), (0, 2), (1, -1), (1.5, -1), (1.2, 3)],
        [(0, 1, 2), (3, 4, 5)],
        "edge (1, 2) of triangle 1 and edge (6, 4) of triangle 2 cross: the mesh overlaps "
        "itself", "edge (0, 1) of triangle 0 and edge (5, 3) of triangle 1 cross"),
    "separate piece on top (overlap, no edges cross)": _content(
        "overlap", SQ + [(0.2, 0.2), (0.4, 0.2), (0.2, 0.4)], SQ_TRIS + [(4, 5, 6)],
        "triangle 3 (5, 6, 7) overlaps another part of the mesh",
        "triangle 2 (4, 5, 6) overlaps another part of the mesh"),
    "near-exact hanging node, inside the edge's triangle by 4e-18": _content(
        "overlap", HANGING[:3] + [(1.0, 4e-18)] + HANGING[4:], HANGING_TRIS,
        "triangle 1 (1, 2, 3) overlaps another part of the mesh",
        "triangle 0 (0, 1, 2) overlaps another part of the mesh"),
    "duplicate of an inner vertex": Case(
        {"in.msh": msh22(INNER, INNER_TRIS)}, "in.msh",
        "triangle 5 (6, 7, 8) overlaps another part of the mesh",
        arrays=(np.array(INNER), np.array(INNER_TRIS)), kind="duplicate-points",
        mesh_message="triangle 4 (5, 6, 7) overlaps another part of the mesh"),
    "3D non-flat input": Case({"in.msh": msh22([(0, 0, 0), (1, 0, 0), (0, 1, 0.5)],
                                               [(0, 1, 2)])}, "in.msh",
                              "in.msh: the mesh is not flat: 1 of 3 points have z != 0 "
                              "(first: point 3, z = 0.5)", kind="not-flat"),
    "tagged edge not in the mesh": Case({"in.msh": msh22(SQ, SQ_TRIS, lines=[(1, 3)])},
                                        "in.msh", "edge 3 (2, 4) is not an edge of any "
                                        "triangle", kind="edge-not-in-mesh"),
}


def _snapshot(folder: Path) -> dict[str, bytes | None]:
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() else None)
            for p in sorted(folder.rglob("*"))}


def _make(tmp_path: Path, case: Case) -> Path:
    for name, content in case.files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
    return tmp_path / case.input








@pytest.mark.parametrize("name", list(CASES))
def test_python_api(tmp_path, name):
    case = CASES[name]
    path = _make(tmp_path, case)
    before = _snapshot(tmp_path)
    with pytest.raises(case.error) as info:
        qdrefine.read(path)
    assert str(info.value).startswith(str(path.with_suffix(""))), info.value
    assert case.message in str(info.value)
    if case.arrays is not None:
        with pytest.raises(ValueError) as info:
            Mesh(*case.arrays)
        assert (case.mesh_message or case.message) in str(info.value)
    if case.kind is not None:  # check_file lists the same problem, and does not stop there
        _, found = qdrefine.io.check_file(path)
        assert case.kind in {p.kind for p in found.errors}
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("name", list(CASES))
def test_command_line(tmp_path, name):
    case = CASES[name]
    path = _make(tmp_path, case)
    before = _snapshot(tmp_path)
    out = tmp_path / "out.vtu"
    both = start("refine", path, out), start("check", path)  # run side by side
    refined, checked = (finish(p) for p in both)
    assert refined.returncode == 1, refined
    assert refined.stdout == ""
    assert refined.stderr.startswith("qdrefine: error: ") and refined.stderr.count("\n") == 1
    assert case.message in refined.stderr, refined.stderr
    assert checked.returncode == 1, checked
    if case.kind is None:  # unreadable: the one-line error
        assert checked.stdout == "" and checked.stderr.startswith("qdrefine: error: ")
        assert case.message in checked.stderr and checked.stderr.count("\n") == 1
    else:
        assert checked.stderr == ""
        line = next(x for x in checked.stdout.splitlines() if x.startswith("error"))
        assert line.split()[1] == case.kind and case.message in checked.stdout, checked.stdout
        errors = sum(x.startswith("error ") for x in checked.stdout.splitlines())
        warns = sum(x.startswith("warning ") for x in checked.stdout.splitlines())
        assert checked.stdout.splitlines()[-1] == f"{path}: NOT usable ({errors} error" \
            f"{'' if errors == 1 else 's'}, {warns} warning{'' if warns == 1 else 's'})"
    assert not out.exists()
    assert _snapshot(tmp_path) == before


# orientation: fixed on reading (documented), refused by Mesh --------------------------------

CW = [(0, 2, 1)]
MIXED = [(0, 1, 2), (0, 3, 2)]


@pytest.mark.parametrize(("nodes", "tris", "count"), [(SQ[:3], CW, "1 of 1"),
                                                       (SQ, MIXED, "1 of 2")])
def test_clockwise_and_mixed_orientation(tmp_path, nodes, tris, count, run):
    path = tmp_path / "in.msh"
    path.write_text(msh22(nodes, tris))
    before = path.read_bytes()
    with pytest.raises(ValueError, match=r"triangle \d+ .* is clockwise"):
        Mesh(np.array(nodes), np.array(tris))
    with pytest.warns(UserWarning, match=f"in.msh: {count} triangles were clockwise"):
        mesh = qdrefine.read(path)
    assert (qdrefine.quality.areas(mesh) > 0).all()
    refined = run("refine", path, tmp_path / "out.vtu", "-q")
    assert refined.returncode == 0 and refined.stdout == ""
    assert refined.stderr == f"qdrefine: warning: {path}: {count} triangles were clockwise " \
                             "and have been flipped\n"
    checked = run("check", path, "--json")
    assert checked.returncode == 0, checked
    report = json.loads(checked.stdout)
    assert report["usable"] and [p["kind"] for p in report["problems"]] == ["clockwise"]
    assert path.read_bytes() == before
    assert qdrefine.read(tmp_path / "out.vtu").n_triangles == 7 * len(tris)


# a mesh too large for the memory ----------------------------------------------------------

def test_too_large_for_memory_python_api():
    mesh = examples.square(1)  # 2 triangles; 12 levels: 2.8e10 triangles, about 1.3 TB
    with pytest.raises(MemoryError, match=r"refining 2 triangles 12 levels needs about "
                                          r"[\d.e+]+ GiB; [\d.e+]+ GiB available"):
        qdrefine.refine(mesh, levels=12)


@pytest.mark.parametrize("suffix", [".vtu", ".xdmf"])
def test_compressed_arrays_are_checked_against_the_memory_before_they_expand(
        tmp_path, monkeypatch, suffix):
    """A 385 kB VTU (or an XDMF whose HDF5 dataset is gzip-compressed) expanded to 2.1 GB
    (0.9 GB) past ``QDREFINE_MEMORY_LIMIT``: only the file's own bytes were checked. The
    sizes the file declares are checked before anything is decompressed."""
    mesh = examples.square(3)
    field = np.zeros((mesh.n_points, 200_000))  # 25.6 MB of zeros, a few kB compressed
    path = tmp_path / f"m{suffix}"
    if suffix == ".vtu":
        qdrefine.write(path, mesh.replace(point_data={"big": field}), compress=True)
    else:  # as another writer may: one attribute in a gzip-compressed dataset
        import h5py

        qdrefine.write(path, mesh)
        with h5py.File(tmp_path / "m.h5", "a") as h5:
            h5.create_dataset("big", data=field, compression="gzip")
        path.write_text(path.read_text().replace("</Topology>", (
            '</Topology><Attribute Name="big" AttributeType="Matrix" Center="Node"><DataItem '
            f'DataType="Float" Precision="8" Dimensions="{mesh.n_points} 200000" '
            'Format="HDF">m.h5:/big</DataItem></Attribute>')))
    assert sum(p.stat().st_size for p in tmp_path.iterdir()) < 1 << 20
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, "8MiB")
    with pytest.raises(MemoryError, match=rf"reading {re.escape(str(path))} \(its compressed "
                                          r".*big.*\) needs about 0.02\d* GiB; 0.00781 GiB"):
        qdrefine.read(path)
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, "1GiB")
    assert qdrefine.read(path).point_data["big"].shape == field.shape
    if suffix == ".vtu":  # a miscount is said as such: the blocks' own sizes are reserved
        path.write_bytes(path.read_bytes().replace(f'NumberOfPoints="{mesh.n_points}"'.encode(),
                                                   b'NumberOfPoints="4000000000"'))
        with pytest.raises(ValueError, match="Points: expected 4000000000 points"):
            qdrefine.read(path)


def test_memory_limit_variable(monkeypatch):
    mesh = examples.square(4)
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, "1KiB")
    with pytest.raises(MemoryError, match=f"GiB available \\({MEMORY_LIMIT_VARIABLE}\\)"):
        qdrefine.refine(mesh)
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, "lots")
    with pytest.raises(ValueError, match="expected a size"):
        qdrefine.refine(mesh)
    for text in ("inf", "1e400", "1e300GiB", "nan", "-1"):  # inf: OverflowError (review)
        monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, text)
        with pytest.raises(ValueError, match=f"{text}'?: expected a finite size >= 0"):
            qdrefine.refine(mesh)
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, "1KiB")
    with pytest.raises(MemoryError, match=r"0 levels needs more than 1e\+21 GiB; "):
        qdrefine.refine(mesh, levels=10**22)  # said "needs about more than"
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, "1GiB")
    assert qdrefine.refine(mesh).n_triangles == 7 * mesh.n_triangles


@pytest.mark.parametrize("scheme", ["7t-qd", "4t-red"])
@pytest.mark.parametrize("levels", [1, 2, 3])
def test_memory_estimate_covers_the_arrays_made(scheme, levels):
    mesh = examples.plate_with_hole()
    fine, parents = qdrefine.refine_with_parents(mesh, scheme, levels)
    made = sum(a.nbytes for a in (fine.points, fine.triangles, fine.cell_tags, fine.edges,
                                  fine.edge_tags, parents) if a is not None)
    need = memory_needed(mesh.n_points, mesh.n_triangles, scheme, levels, tagged=True)
    assert made <= need <= 4 * made + 200 * mesh.n_triangles * 7 ** (levels - 1)


def test_too_large_for_memory_command_line(tmp_path):
    path = tmp_path / "in.msh"
    qdrefine.write(path, examples.square(1))
    before = _snapshot(tmp_path)
    out = tmp_path / "out.msh"
    result = cli("refine", path, out, "--levels", "6", env={MEMORY_LIMIT_VARIABLE: "1MiB"})
    assert result.returncode == 1
    # the check covers all six levels before the first one is refined
    assert result.stderr.startswith("qdrefine: error: refining 2 triangles 6 levels ")
    assert "GiB available (QDREFINE_MEMORY_LIMIT)" in result.stderr
    assert result.stderr.count("\n") == 1
    assert not out.exists() and _snapshot(tmp_path) == before


def test_local_refinement_checks_memory(monkeypatch):
    """Local refinement checks memory too, phase by phase, since its output size is known
    only once its closure is: before the first step, the least output it can make (one
    marked triangle 12 levels deep: refused at once, not after hours of refining); then
    the working mesh of each pass, and each output before it is emitted."""
    from qdrefine.memory import local_memory_needed

    mesh = examples.plate_with_hole()  # 384 triangles: the whole-mesh step, no window
    with pytest.raises(MemoryError, match=r"refining 384 triangles locally \(1 marked, 12 "
                                          r"levels, at least \d+ triangles\) needs about"):
        qdrefine.refine(mesh, marked=[0], levels=12)
    marked = np.zeros(mesh.n_triangles, dtype=bool)
    marked[::3] = True  # the closure more than doubles the least output
    out = qdrefine.refine(mesh, marked=marked)
    least = local_memory_needed(n_output=mesh.n_triangles + 6 * int(marked.sum()))
    working = local_memory_needed(n_working=mesh.n_triangles)
    emitted = local_memory_needed(n_output=out.n_triangles)
    assert max(least, working) < emitted
    made = sum(a.nbytes for a in (out.points, out.triangles, out.cell_tags, out.transitions)
               if a is not None)
    assert made < emitted  # the estimate covers the arrays made, at least
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, str((max(least, working) + emitted) // 2))
    with pytest.raises(MemoryError, match=f"local refinement: emitting {out.n_triangles} "
                                          "triangles needs about"):
        qdrefine.refine(mesh, marked=marked)
    least_one = local_memory_needed(n_output=mesh.n_triangles + 6)  # one mark
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, str((least_one + working) // 2))
    with pytest.raises(MemoryError, match=f"a pass over {mesh.n_triangles} working triangles"):
        qdrefine.refine(mesh, marked=[0])
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, str(emitted))
    np.testing.assert_array_equal(qdrefine.refine(mesh, marked=marked).triangles, out.triangles)


def test_local_refinement_too_large_for_memory_command_line(tmp_path):
    path = tmp_path / "in.msh"
    qdrefine.write(path, examples.plate_with_hole())
    before = _snapshot(tmp_path)
    out = tmp_path / "out.msh"
    # every triangle marked: at least 2688 triangles, more than reading and checking need
    result = cli("refine", path, out, "--mark-box=-1,-1,1,1", "--cycles", "3",
                 env={MEMORY_LIMIT_VARIABLE: "300KiB"})
    assert result.returncode == 1
    assert result.stderr.startswith("qdrefine: error: refining 384 triangles locally (")
    assert "GiB available (QDREFINE_MEMORY_LIMIT)" in result.stderr
    assert result.stderr.count("\n") == 1
    assert not out.exists() and _snapshot(tmp_path) == before


def test_every_kind_is_documented():
    guide = (Path(__file__).parents[1] / "docs" / "guide.md").read_text()
    for kind in check.KINDS:
        assert f"`{kind}`" in guide, kind


def test_too_thin_for_float64_children_command_line(tmp_path):
    """Exact decisions, but the rounded new points would flatten a child: refused."""
    path = tmp_path / "needle.msh"
    qdrefine.write(path, qdrefine.Mesh(np.array([[0, 0], [1, 0], [0.5, 1e-9]]) + 1e7,
                                       [[0, 1, 2]]))
    before = _snapshot(tmp_path)
    out = tmp_path / "out.msh"
    result = cli("refine", path, out)
    assert result.returncode == 1
    # named as in the file: element 1, nodes 1 2 3
    assert result.stderr.startswith(f"qdrefine: error: {path}: triangle 1 (1, 2, 3) is too "
                                    "thin for its distance from the origin")
    assert result.stderr.count("\n") == 1
    assert not out.exists() and _snapshot(tmp_path) == before


# geometry decided by the refinement's own predicates: passes check => refines -------------

def test_near_hanging_node_outside_is_a_warning_and_refines(tmp_path, run):
    """Off the edge by 4e-18 on the far side: a crack, not an overlap; check passes with a
    warning and the mesh refines (the same exact predicates decide both)."""
    path = tmp_path / "crack.msh"
    path.write_text(msh22(HANGING[:3] + [(1.0, -4e-18)] + HANGING[4:], HANGING_TRIS))
    before = _snapshot(tmp_path)
    checked = run("check", path, "--json")
    assert checked.returncode == 0, checked
    report = json.loads(checked.stdout)
    assert report["usable"] and "near-hanging-node" in {p["kind"] for p in report["problems"]}
    out = tmp_path / "out.vtu"
    refined = run("refine", path, out, "-q")
    assert refined.returncode == 0 and refined.stderr == "", refined
    assert qdrefine.read(out).n_triangles == 7 * len(HANGING_TRIS)
    out.unlink()
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("levels", [2, 3])
def test_refusal_at_level_k_names_the_input_triangle(tmp_path, levels, run):
    """A needle refined once fine but refused later: the message names the triangle of IN
    (the API: its row; the command line: the file's element and node numbers), not one of
    the intermediate mesh."""
    h = {2: 1e-8, 3: 3e-8}[levels]
    points = np.array([[0, 0], [1, 0], [0.5, 0.9], [0.5, -h]]) + 1e7
    path = tmp_path / "needles.msh"
    qdrefine.write(path, Mesh(points, [[0, 1, 2], [0, 3, 1]]))
    qdrefine.refine(qdrefine.read(path), levels=levels - 1)  # the earlier levels pass
    with pytest.raises(ValueError, match=rf"^triangle 1 \(0, 3, 1\) cannot be refined "
                                         rf"{levels} levels: its descendant \d+"):
        qdrefine.refine(qdrefine.read(path), levels=levels)
    before = _snapshot(tmp_path)
    result = run("refine", path, tmp_path / "out.msh", "--levels", levels)
    assert result.returncode == 1 and result.stderr.count("\n") == 1
    assert result.stderr.startswith(f"qdrefine: error: {path}: triangle 2 (1, 4, 2) cannot be "
                                    f"refined {levels} levels: its descendant ")
    assert _snapshot(tmp_path) == before


def test_json_outputs_are_valid_json(tmp_path, run):
    """NaN and infinities become null; NumPy numbers become plain numbers."""
    from qdrefine.cli._common import dumps

    text = dumps({"a": float("nan"), "b": np.float64(np.inf), "c": np.int64(3),
                  "d": (np.float32(0.5), [np.nan])})
    assert json.loads(text) == {"a": None, "b": None, "c": 3, "d": [0.5, [None]]}
    path = tmp_path / "in.msh"
    qdrefine.write(path, examples.square(2))

    def strict(word):
        raise AssertionError(f"invalid JSON constant {word}")

    for command in ("quality", "check", "info"):
        result = run(command, path, "--json")
        assert result.returncode == 0, result
        json.loads(result.stdout, parse_constant=strict)


def test_import_from_a_read_only_install(tmp_path):
    """Neither the install folder nor the user cache can hold numba's cache (here: both are
    files, so this holds even for root): import works, and one line says where it went."""
    import shutil

    pkg = tmp_path / "site" / "qdrefine"
    shutil.copytree(Path(qdrefine.__file__).parent, pkg,
                    ignore=shutil.ignore_patterns("__pycache__"))
    for folder in [pkg, *[p for p in pkg.rglob("*") if p.is_dir()]]:
        (folder / "__pycache__").write_text("not a folder")
    (tmp_path / "cache").write_text("not a folder")
    (tmp_path / "tmp").mkdir()
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env |= {"PYTHONPATH": str(tmp_path / "site"), "XDG_CACHE_HOME": str(tmp_path / "cache"),
            "HOME": str(tmp_path / "cache"), "TMPDIR": str(tmp_path / "tmp"),
            "PYTHONDONTWRITEBYTECODE": "1"}
    code = "import qdrefine, numba; print(qdrefine.__file__); print(numba.config.CACHE_DIR)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            env=env, timeout=120)
    assert result.returncode == 0, result.stderr
    where, cache = result.stdout.split()
    assert where.startswith(str(pkg)) and cache.startswith(str(tmp_path / "tmp"))
    assert result.stderr.count("\n") == 1
    assert result.stderr.startswith("qdrefine: note: ") and cache in result.stderr


def test_validation_memory_is_checked(monkeypatch):
    """Issue 17: the memory check covers validation too (before the edge sort, and before
    the sweep with the number of boundary edges known)."""
    from qdrefine.memory import validation_needed

    mesh = examples.square(30)
    p, t = np.array(mesh.points), np.array(mesh.triangles)
    need = validation_needed(len(p), len(t), 0)
    assert need > 16 * len(p) + 12 * len(t)
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, str(need // 2))
    with pytest.raises(MemoryError, match=rf"^validating {len(t)} triangles needs about "):
        Mesh(p, t)
    with pytest.raises(MemoryError, match="validating"):
        check.find(p, t)
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, str(need + 160 * 3 * len(t)))
    assert Mesh(p, t).n_triangles == len(t)
# files that would hang a reader, or outputs that would lose data ---------------------------

@pytest.mark.parametrize("ext", [".msh", ".vtu", ".vtk", ".node", ".xdmf"])
def test_fifo_is_refused_not_waited_on(tmp_path, ext):
    """A FIFO (or device) named as input: one line, at once, instead of waiting for a writer."""
    path = tmp_path / f"pipe{ext}"
    os.mkfifo(path)
    if ext == ".node":
        (tmp_path / "pipe.ele").write_text("1 3 0\n0 0 1 2\n")
    with pytest.raises(OSError, match="pipe.node: not a regular file" if ext == ".node"
                       else f"pipe{ext}: not a regular file"):
        qdrefine.read(tmp_path / f"pipe{ext if ext != '.node' else '.ele'}")
    result = cli("refine", path, tmp_path / "out.vtu")
    assert result.returncode == 1 and result.stderr.count("\n") == 1
    assert "not a regular file" in result.stderr and not (tmp_path / "out.vtu").exists()


@pytest.mark.parametrize("cut", [0.2, 0.5, 0.95])
@pytest.mark.parametrize("kwargs", [{}, {"binary": True}, {"format_version": "2.2"},
                                    {"format_version": "2.2", "binary": True}])
def test_short_msh_files_fail_with_one_line(tmp_path, cut, kwargs, run):
    """Files cut anywhere (counts announced beyond the end): one line naming the file and
    the line or byte, checked against the file size before anything is allocated."""
    qdrefine.write(tmp_path / "good.msh", examples.plate_with_hole(), **kwargs)
    data = (tmp_path / "good.msh").read_bytes()
    (tmp_path / "cut.msh").write_bytes(data[:int(len(data) * cut)])
    before = _snapshot(tmp_path)
    with pytest.raises(ValueError, match=r"cut\.msh: not a readable Gmsh MSH file \((line|byte) "
                                         r"\d+: "):
        qdrefine.read(tmp_path / "cut.msh")
    result = run("refine", tmp_path / "cut.msh", tmp_path / "out.msh")
    assert result.returncode == 1 and result.stderr.count("\n") == 1
    assert result.stderr.startswith(f"qdrefine: error: {tmp_path / 'cut.msh'}: not a readable")
    assert _snapshot(tmp_path) == before


def test_huge_declared_count_is_refused_before_allocating(tmp_path):
    """A binary $Nodes announcing 2**60 nodes fails on the file size, not on memory."""
    qdrefine.write(tmp_path / "good.msh", examples.square(2), binary=True)
    data = bytearray((tmp_path / "good.msh").read_bytes())
    at = data.index(b"$Nodes\n") + len(b"$Nodes\n")
    data[at + 8:at + 16] = np.array([2**60], np.uint64).tobytes()  # numNodes
    data[at + 32 + 12:at + 32 + 20] = np.array([2**60], np.uint64).tobytes()  # block size
    (tmp_path / "big.msh").write_bytes(bytes(data))
    with pytest.raises(ValueError, match=r"big\.msh: not a readable Gmsh MSH file \(byte \d+"):
        qdrefine.read(tmp_path / "big.msh")


def test_binary_stl_refuses_to_round_coordinates(tmp_path):
    """Binary STL holds float32: points that would change are refused (text STL is exact)."""
    mesh = Mesh(np.array([[0.0, 0.0], [1.0, 0.0], [0.1, 1.0]]), [[0, 1, 2]], cell_tags=[1])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the refusal alone: no warning of dropped tags first
        with pytest.raises(ValueError, match=r"m\.stl: binary STL stores float32 coordinates, "
                                             r"and 1 of 3 points would change \(first: point 2 "
                                             r"at \(0\.1, 1\.0\)\)"):
            qdrefine.write(tmp_path / "m.stl", mesh, binary=True)
    assert list(tmp_path.iterdir()) == []
    mesh = Mesh(mesh.points, mesh.triangles)
    exact = Mesh(np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]), [[0, 1, 2]])
    qdrefine.write(tmp_path / "m.stl", exact, binary=True)
    assert np.array_equal(qdrefine.read(tmp_path / "m.stl").points, exact.points)
    qdrefine.write(tmp_path / "t.stl", mesh)  # text STL keeps every digit
    assert qdrefine.read(tmp_path / "t.stl").n_triangles == 1


def test_sigterm_during_a_write_leaves_nothing_behind(tmp_path):
    """``kill`` (SIGTERM) while the output is being written: exit 143, one line, no
    temporary file, no output, the input untouched (as with Ctrl-C). A kill that lands
    just after the output was renamed into place leaves a complete output instead (that is
    checked too); the test tries until one lands inside the write."""
    import signal
    import time

    src = tmp_path / "in.msh"
    qdrefine.write(src, examples.plate_with_hole())
    before = src.read_bytes()
    out = tmp_path / "out.msh"
    inside = False
    for _ in range(4):
        proc = start("refine", src, out, "--levels", "4")
        deadline = time.monotonic() + 300
        while proc.poll() is None and not list(tmp_path.glob(".out.*")) \
                and time.monotonic() < deadline:
            time.sleep(0.001)
        assert proc.poll() is None, "the write finished before the signal: make it larger"
        proc.send_signal(signal.SIGTERM)
        err = finish(proc, timeout=120).stderr
        assert sorted(p.name for p in tmp_path.iterdir()) in (["in.msh"], ["in.msh", "out.msh"])
        assert src.read_bytes() == before
        if not out.exists():
            assert proc.returncode == 143, err
            assert err.strip().splitlines()[-1] == "qdrefine: terminated", err
            inside = True
            break
        assert qdrefine.read(out).n_triangles == 384 * 7**4  # complete, never partial
        out.unlink()
    assert inside


def test_messages_use_the_files_own_numbers(tmp_path, run):
    """A Gmsh file whose nodes are tagged 101.. and elements 1001..: every message names the
    tags the file uses, not the rows they became, in ``read``, ``check`` and ``check
    --json``."""
    path = tmp_path / "tags.msh"
    path.write_text(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n104 0 1 0\n101 0 0 0\n"
        "102 1 0 0\n103 2 0 0\n105 1 1 0\n$EndNodes\n$Elements\n3\n"
        "1003 2 2 5 5 101 102 103\n1001 2 2 5 5 101 102 105\n1002 1 2 7 7 104 103\n"
        "$EndElements\n")
    with pytest.raises(ValueError, match=r"triangle 1003 \(101, 102, 103\) has zero area"):
        qdrefine.read(path)
    result = run("check", path, "--json")
    report = json.loads(result.stdout)
    assert report["numbered_by"] == "file"
    by_kind = {p["kind"]: p for p in report["problems"]}
    assert by_kind["zero-area"]["where"]["triangle"] == 1003
    assert by_kind["zero-area"]["where"]["vertices"] == [101, 102, 103]
    assert "edge 1002 (104, 103) is not an edge of any triangle" in \
        by_kind["edge-not-in-mesh"]["message"]
    text = run("check", path).stdout
    assert "named by the file's own node and element numbers" in text


def test_reading_memory_is_checked_before_the_file_is_read(tmp_path, monkeypatch, run):
    """Issue 17: the memory check covers reading too, from the size of the file and the
    files it names (XDMF's HDF5 data), before anything is read."""
    from qdrefine.memory import reading_needed_for_bytes

    path = tmp_path / "m.xdmf"
    qdrefine.write(path, examples.square(30))
    size = path.stat().st_size + path.with_suffix(".h5").stat().st_size
    assert reading_needed_for_bytes(size) >= 3 * size
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, str(2 * size))
    with pytest.raises(MemoryError, match=rf"^reading {re.escape(str(path))} \([\d.]+ MiB "
                                          r"with the files it names\) needs about "):
        qdrefine.read(path)
    result = run("refine", path, tmp_path / "out.vtu")
    assert result.returncode == 1 and result.stderr.count("\n") == 1
    assert result.stderr.startswith(f"qdrefine: error: reading {path}")
    assert not (tmp_path / "out.vtu").exists()
    monkeypatch.setenv(MEMORY_LIMIT_VARIABLE, "1GiB")
    assert qdrefine.read(path).n_triangles == examples.square(30).n_triangles


@pytest.mark.parametrize("file, cut_after", [("m.ele", b"1"), ("m.node", b"0.98")])
def test_a_triangle_file_cut_short_in_a_stamped_set_is_refused(tmp_path, file, cut_after):
    """A file of a set qdrefine wrote, cut inside its last number, read as a smaller number
    (the last tag 17 as 1, the last y 0.987654321 as 0.98) with exit 0 (review): its stamp,
    the last line written, is gone while the others have theirs."""
    points = np.array([[0.0, 0], [1, 0], [1, 1], [0, 0.987654321]])
    mesh = Mesh(points, [[0, 1, 2], [0, 2, 3]], cell_tags=[15, 17], edges=[[0, 1]],
                edge_tags=[42])
    qdrefine.write(tmp_path / "m.node", mesh)
    data = (tmp_path / file).read_bytes()
    last = data.rindex(b"17\n" if file == "m.ele" else b"0.987654")
    (tmp_path / file).write_bytes(data[:last + len(cut_after)])
    with pytest.raises(ValueError, match=rf"{file}: no '# qdrefine set' line at its end"):
        qdrefine.read(tmp_path / "m.ele")


def test_a_mixed_triangle_set_is_refused(tmp_path, run):
    """Issue 17: Triangle's three files from two different writes (an interrupted or
    concurrent write between the renames) are refused with one line; a set written by
    another tool (no stamp), or edited by hand, is read as it is."""
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    qdrefine.write(a / "m.node", examples.square(2))
    qdrefine.write(b / "m.node", examples.square(3))
    stamps = {p.read_text().splitlines()[-1] for p in a.glob("m.*")}
    assert len(stamps) == 1 and stamps.pop().startswith("# qdrefine set ")
    (a / "m.ele").write_bytes((b / "m.ele").read_bytes())  # the new .ele, the old .node
    before = _snapshot(tmp_path)
    with pytest.raises(ValueError, match=r"m.ele: written by another run than m.node .*"
                                         r"a mixed set"):
        qdrefine.read(a / "m.ele")
    result = run("refine", a / "m.ele", tmp_path / "out.vtu")
    assert result.returncode == 1 and result.stderr.count("\n") == 1
    assert "a mixed set" in result.stderr and not (tmp_path / "out.vtu").exists()
    assert _snapshot(tmp_path) == before
    # without stamps (another tool) the same files are read, and fail on their content
    for p in a.glob("m.*"):
        p.write_text("\n".join(p.read_text().splitlines()[:-1]) + "\n")
    with pytest.raises(ValueError, match="is not in|outside|vertex"):
        qdrefine.read(a / "m.ele")
    # a hand edit of one file keeps the stamps equal: read as it is
    qdrefine.write(b / "m.node", examples.square(3))
    text = (b / "m.node").read_text().replace("# written by qdrefine", "# edited")
    (b / "m.node").write_text(text)
    assert qdrefine.read(b / "m.ele").n_triangles == examples.square(3).n_triangles


def test_a_mixed_xdmf_pair_is_refused(tmp_path):
    """The XDMF file and its HDF5 file from two different writes are refused with one line
    (both carry the same stamp when written together); equal writes give equal stamps."""
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir()
    b.mkdir()
    qdrefine.write(a / "m.xdmf", examples.square(2))
    qdrefine.write(b / "m.xdmf", examples.square(3))
    (tmp_path / "c").mkdir()
    qdrefine.write(tmp_path / "c" / "m.xdmf", examples.square(3))
    first = (b / "m.xdmf").read_text().splitlines()[1]
    assert first.startswith("<!-- qdrefine set ")
    assert first == (tmp_path / "c" / "m.xdmf").read_text().splitlines()[1]  # deterministic
    (a / "m.h5").write_bytes((b / "m.h5").read_bytes())
    with pytest.raises(ValueError, match=r"m.h5: written by another run than m.xdmf .*"
                                         r"a mixed set"):
        qdrefine.read(a / "m.xdmf")
    assert qdrefine.read(b / "m.xdmf").n_triangles == examples.square(3).n_triangles


def test_an_xdmf_file_without_its_hdf5_file_names_it(tmp_path):
    """The XDMF file of a pair whose HDF5 file is gone: one line naming the missing file (not
    HDF5's own message, several lines of library detail)."""
    qdrefine.write(tmp_path / "m.xdmf", examples.square(2))
    (tmp_path / "m.h5").unlink()
    result = cli("info", tmp_path / "m.xdmf")
    assert result.returncode == 1
    assert result.stderr == (f"qdrefine: error: {tmp_path / 'm.h5'}: no such file (the heavy "
                             "data of m.xdmf)\n")


def _file_size_limit(limit: int):
    """For a child process: files may not grow beyond ``limit`` bytes (the kernel refuses
    the write with EFBIG, as a full disk refuses with ENOSPC: a real failure, not a mock)."""
    import resource
    import signal

    def apply():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # an error, not a killed process
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX resource limits")
@pytest.mark.parametrize("name", ["out.msh", "out.vtu", "out.node", "out.xdmf", "out.stl",
                                  "out.vtk"])
def test_a_write_the_kernel_refuses_leaves_the_old_output(tmp_path, name):
    """The kernel refuses the write half way (file size limit): one line naming the file,
    exit 1, the old output and the input untouched, no temporary file left (meshio's VTK
    writer gets NumPy's "N requested and M written", without errno or file: it named no
    file)."""
    src = tmp_path / "in.msh"
    qdrefine.write(src, examples.plate_with_hole())
    out = tmp_path / name
    qdrefine.write(out, examples.square(1))
    before = _snapshot(tmp_path)
    result = subprocess.run([sys.executable, "-m", "qdrefine", "refine", src, out, "--levels",
                             "2", "-q"], capture_output=True, text=True, timeout=300,
                            preexec_fn=_file_size_limit(200_000))
    assert result.returncode == 1, result.stderr
    error = result.stderr.strip().splitlines()[-1]  # after the notes on what STL drops
    assert error.startswith("qdrefine: error: ")
    assert ("File too large" if name != "out.vtk" else "bytes (a file size limit or a full "
            "disk)") in error, error
    assert f"{out.with_suffix('.h5') if name.endswith('.xdmf') else out}: cannot write" in error
    assert "Traceback" not in result.stderr
    assert _snapshot(tmp_path) == before


@settings(max_examples=40, deadline=None)
@given(st.floats(1e-11, 1e-7), st.floats(1e5, 1e9), st.sampled_from(["7t-qd", "4t-le"]),
       st.integers(0, 2**32 - 1))
def test_check_predicts_the_refusals_of_refine(height, offset, scheme, seed):
    """``uniform.refused`` (behind ``qdrefine check``'s too-thin warning) lists exactly the
    triangles one level of refinement refuses: refine raises for the first of them, and
    refines when there is none."""
    from qdrefine.predicates import orient_signs
    from qdrefine.schemes import get_scheme
    from qdrefine.uniform import RefusedTriangle, refine_arrays, refused

    rng = np.random.default_rng(seed)
    base = np.array([[0, 0], [1, 0], [0.5, 0.9], [0.5, -height], [1.5, 0.8]])
    points = base * rng.uniform(0.5, 2.0) + offset
    try:
        mesh = Mesh(points, [[0, 1, 2], [0, 3, 1], [1, 4, 2]])
    except ValueError:  # the needle rounded flat already: not a mesh
        assume(False)
    sch = get_scheme(scheme)
    rows = refused(mesh.points, mesh.triangles, sch)
    # every refused triangle: those whose children come out flat in the whole mesh
    points, children, _ = refine_arrays(mesh.points, mesh.triangles, sch, strict=False)
    flat = (orient_signs(points, children) <= 0).reshape(mesh.n_triangles, sch.n_children)
    np.testing.assert_array_equal(rows, np.flatnonzero(flat.any(axis=1)))
    if rows.size:
        with pytest.raises(RefusedTriangle) as info:
            qdrefine.refine(mesh, scheme)
        assert info.value.triangle == rows[0]
    else:
        assert qdrefine.refine(mesh, scheme).n_triangles > mesh.n_triangles


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 12), st.floats(0.2, 0.8), st.floats(1e3, 1e9), st.floats(1e-4, 1e-2),
       st.sampled_from(["7t-qd", "4t-le", "7t-d"]))
@example(1, 0.375, 1e3, 1e-3, "7t-qd")  # refused: the rounded boundary crosses (review)
@example(1, 0.625, 1e7, 1e-3, "4t-le")
def test_refine_refuses_exactly_the_meshes_whose_rounded_boundary_crosses(
        shift, along, offset, scale, scheme):
    """Two parts of a mesh a float step apart: valid (exact predicates), but the rounded
    new points of the first's edge may cross the second. ``refine`` returned that mesh,
    which it then refused to read back (review); it now refuses the input exactly when
    the unchecked refinement (``strict=False``) overlaps itself."""
    from qdrefine.uniform import RefusedTriangle

    points, triangles = crack(shift, along, offset, scale)
    try:
        mesh = Mesh(points, triangles)
    except ValueError:
        assume(False)
    loose = qdrefine.refine(mesh, scheme, strict=False)
    if check.find(loose.points, loose.triangles).errors:
        with pytest.raises(RefusedTriangle, match=r"^triangle 0 \(0, 1, 2\) is closer to "
                                                  "another part of the mesh than float64"):
            qdrefine.refine(mesh, scheme)
    else:
        fine = qdrefine.refine(mesh, scheme)
        assert np.array_equal(fine.points, loose.points)
        assert np.array_equal(fine.triangles, loose.triangles)


def test_a_rounded_point_on_another_parts_vertex_is_refused():
    """A new point rounded exactly onto a vertex of another part: the sweep took the two
    for one vertex (a pinch), and refine returned a mesh with duplicate points (review)."""
    RefusedTriangle = qdrefine.RefusedTriangle  # noqa: N806 (the documented name)
    mesh = Mesh(np.array([(0.0, 0.0), (1.5, -1.0), (3.0, 3.012e-16), (1.0, 1.004e-16),
                          (0.5, 1.0), (1.5, 1.0)]), [[0, 1, 2], [3, 5, 4]])
    loose = qdrefine.refine(mesh, strict=False)
    assert [p.kind for p in check.find(loose.points, loose.triangles).errors] == \
        ["duplicate-points"]
    for kwargs in ({}, {"marked": [0]}, {"levels": 2}):
        with pytest.raises(RefusedTriangle, match=r"^triangle 0 \(0, 1, 2\) is closer to "):
            qdrefine.refine(mesh, **kwargs)
    assert qdrefine.refine(mesh, marked=[1]).n_triangles == 8  # the edge stays whole


def test_check_warns_about_parts_too_close_to_refine(tmp_path, run):
    path = tmp_path / "crack.msh"
    qdrefine.write(path, Mesh(*crack(1, 0.375, 1e3, 1e-3)))
    result = run("check", path, "--json")
    assert result.returncode == 0  # a warning: the mesh is valid
    close = [p for p in json.loads(result.stdout)["problems"] if p["kind"] == "too-close"]
    assert close and close[0]["where"] == {"triangle": 1, "vertices": [1, 2, 3],
                                           "scheme": "7t-qd", "file": str(path)}
    refined = run("refine", path, tmp_path / "out.msh")
    assert refined.returncode == 1 and "triangle 1 (1, 2, 3) is closer to another part" \
        in refined.stderr
    assert not (tmp_path / "out.msh").exists()


def test_check_warns_about_what_refine_would_refuse(tmp_path, run):
    path = tmp_path / "needle.msh"
    qdrefine.write(path, Mesh(np.array([[0, 0], [1, 0], [0.5, 1e-9]]) + 1e7, [[0, 1, 2]]))
    result = run("check", path, "--json")
    assert result.returncode == 0  # a warning: the mesh is valid
    kinds = [p["kind"] for p in json.loads(result.stdout)["problems"]]
    assert "too-close" not in kinds  # one part: refine refuses the thin triangle (review)
    thin = [p for p in json.loads(result.stdout)["problems"] if p["kind"] == "too-thin"]
    assert thin and thin[0]["where"]["triangle"] == 1 and thin[0]["where"]["vertices"] == [1, 2, 3]
    refined = run("refine", path, tmp_path / "out.msh")
    assert refined.returncode == 1 and "triangle 1 (1, 2, 3) is too thin" in refined.stderr


def _interrupt_while_importing(command: list[str]) -> subprocess.CompletedProcess:
    """Run ``command`` (Python with ``-X importtime``) and send it Ctrl-C (SIGINT) as soon
    as numba has been imported, that is, while ``import qdrefine`` is still loading its
    compiled modules (a few hundred milliseconds more)."""
    import signal

    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = []
    for line in proc.stderr:
        lines.append(line)
        if line.split("|")[-1].strip() == "numba":
            proc.send_signal(signal.SIGINT)
            break
    else:
        raise AssertionError("numba's import was not seen: " + "".join(lines)[-2000:])
    out, err = proc.communicate(timeout=120)
    return subprocess.CompletedProcess(command, proc.returncode, out, "".join(lines) + err)


def test_ctrl_c_while_the_command_loads_is_one_line(tmp_path):
    """Ctrl-C in the second a command spends importing numba and the kernels: exit 130 and
    ``qdrefine: interrupted``, no traceback (the import is not yet inside ``main``'s
    handler); a program that imports the library still gets its ``KeyboardInterrupt``."""
    path = tmp_path / "m.msh"
    qdrefine.write(path, examples.square(2))
    result = _interrupt_while_importing(
        [sys.executable, "-X", "importtime", "-m", "qdrefine", "info", str(path)])
    assert result.returncode == 130, result.stderr[-2000:]
    assert "Traceback" not in result.stderr
    messages = [line for line in result.stderr.splitlines() if not line.startswith("import time:")]
    assert messages == ["qdrefine: interrupted"], messages
    library = _interrupt_while_importing(
        [sys.executable, "-X", "importtime", "-c", "import qdrefine; print('loaded')"])
    assert "loaded" not in library.stdout
    assert "KeyboardInterrupt" in library.stderr


@pytest.mark.parametrize(("argv0", "process", "ignored"), [
    ("qdrefine", "Dask Worker process (from Nanny)", True),  # the command's worker
    ("qdrefine", "MainProcess", False),  # the command: its handler says it in one line
    ("script.py", "Dask Worker process (from Nanny)", False),  # a program's worker
])
def test_ctrl_c_reaches_the_command_not_its_dask_workers(argv0, process, ignored):
    """Ctrl-C reaches every process of ``qdrefine refine --dask``; a worker interrupted
    while it imported Dask printed its traceback, one importing qdrefine a second
    ``qdrefine: interrupted``. The command's spawned workers (named by multiprocessing
    before they import the command's module) now ignore it; the command stops them."""
    code = ("import multiprocessing, signal, sys; "
            f"sys.argv[0] = {argv0!r}; multiprocessing.current_process().name = {process!r}; "
            "import qdrefine; print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN)")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120, check=True)
    assert result.stdout.split() == [str(ignored)]


@pytest.mark.parametrize("binary", [False, True])
def test_a_huge_tag_count_in_a_data_section_is_an_error_not_a_hang(tmp_path, binary):
    """``$NodeData`` announcing 10**13 real tags: the reader read empty lines past the end
    of the file 10**13 times (review); now one line at once."""
    mesh = examples.square(2).replace(point_data={"h": np.arange(9.0)})
    path = tmp_path / "d.msh"
    qdrefine.write(path, mesh, binary=binary)
    data = path.read_bytes()
    at = data.index(b"$NodeData\n") + len(b"$NodeData\n")
    path.write_bytes(data[:at] + b"1" * 14 + data[data.index(b"\n", at):])
    with pytest.raises(ValueError, match=r"d\.msh: not a readable Gmsh MSH file \(.*\$NodeData: "
                                         r"the section ends inside its 1{14} tags"):
        qdrefine.read(path)


def test_xdmf_and_xmf_of_one_name_are_one_output(tmp_path, monkeypatch, capsys):
    """``m.xdmf`` and ``m.xmf`` share ``m.h5``: refining one into the other would replace the
    input's heavy data (review); refused like any output that overwrites its input."""
    from qdrefine.cli import main

    monkeypatch.chdir(tmp_path)
    qdrefine.write("m.xdmf", examples.square(2))
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert main(["refine", "m.xdmf", "m.xmf"]) == 1
    assert capsys.readouterr().err == (
        "qdrefine: error: m.xmf: the output would overwrite the input (m.xdmf and m.xmf share "
        "the heavy-data file m.h5); choose another name\n")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def _xdmf_with_heavy_data_named(folder, h5_name: str) -> None:
    """``in.xdmf`` (written by meshio, unstamped) whose arrays are in ``h5_name``."""
    import meshio

    meshio.write(folder / "in.xdmf", meshio.Mesh(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
                                                 [("triangle", np.array([[0, 1, 2]]))]))
    (folder / "in.h5").rename(folder / h5_name)
    xml = folder / "in.xdmf"
    xml.write_text(xml.read_text().replace("in.h5:", f"{h5_name}:"))


def test_an_output_that_would_replace_an_hdf5_file_the_input_names_is_refused(tmp_path,
                                                                               monkeypatch,
                                                                               capsys):
    """An XDMF input whose heavy data is in ``data.h5``: ``refine in.xdmf data.xdmf``
    replaced ``data.h5`` and so changed the input (review): refused, nothing touched."""
    from qdrefine.cli import main

    monkeypatch.chdir(tmp_path)
    _xdmf_with_heavy_data_named(tmp_path, "data.h5")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert main(["refine", "in.xdmf", "data.xdmf"]) == 1
    assert capsys.readouterr().err == (
        "qdrefine: error: data.xdmf: the output would overwrite the input (in.xdmf and "
        "data.xdmf share the heavy-data file data.h5); choose another name\n")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    assert main(["refine", "in.xdmf", "out.xdmf"]) == 0  # another name: fine
    assert qdrefine.read("out.xdmf").n_triangles == 7


@pytest.mark.parametrize("spelling", ["single quotes", "CDATA"])
def test_heavy_data_items_are_found_however_the_xml_spells_them(tmp_path, monkeypatch,
                                                               capsys, spelling):
    """The heavy-data checks found data items by a regular expression that missed
    ``Format='HDF'`` and ``<![CDATA[...]]>``, which meshio reads: ``refine in.xdmf
    data.xdmf`` replaced the input's ``data.h5`` (exit 0), and a binary item naming a FIFO
    hung (review)."""
    from qdrefine.cli import main

    monkeypatch.chdir(tmp_path)
    _xdmf_with_heavy_data_named(tmp_path, "data.h5")
    xml = tmp_path / "in.xdmf"
    text = xml.read_text()
    if spelling == "single quotes":
        text = text.replace('Format="HDF"', "Format='HDF'")
    else:
        text = text.replace(">data.h5:", "><![CDATA[data.h5:").replace(
            "</DataItem>", "]]></DataItem>")
    xml.write_text(text)
    assert qdrefine.read(xml).n_triangles == 1  # meshio reads it
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert main(["refine", "in.xdmf", "data.xdmf"]) == 1
    assert "share the heavy-data file data.h5" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    os.mkfifo(tmp_path / "fifo.bin")
    (tmp_path / "f.xdmf").write_text(
        "<Xdmf Version='3.0'><Domain><Grid Name='m'><Geometry GeometryType='XY'><DataItem "
        "DataType='Float' Precision='8' Dimensions='3 2' Format='XML'>0 0 1 0 0 1</DataItem>"
        "</Geometry><Topology TopologyType='Triangle' NumberOfElements='1'><DataItem "
        "DataType='Int' Precision='8' Dimensions='1 3' Format='Binary'>fifo.bin</DataItem>"
        "</Topology></Grid></Domain></Xdmf>")
    assert main(["info", "f.xdmf"]) == 1  # not a hang
    assert "fifo.bin: not a regular file" in capsys.readouterr().err


def test_an_xdmf_name_with_an_xml_entity_reads_back(tmp_path):
    """``a&b.xdmf`` names ``a&amp;b.h5`` in its XML: the heavy-data check looked for a file
    named ``a&amp;b.h5`` and refused the pair (review)."""
    qdrefine.write(tmp_path / "a&b.xdmf", examples.square(2))
    assert qdrefine.read(tmp_path / "a&b.xdmf").n_triangles == examples.square(2).n_triangles
    result = cli("refine", tmp_path / "a&b.xdmf", tmp_path / "a&b.xmf")
    assert result.returncode == 1 and "share the heavy-data file a&b.h5" in result.stderr


def test_an_hdf5_dataset_of_another_size_than_the_xml_says_is_refused(tmp_path):
    """meshio reads a dataset whatever the size the XML gives: an HDF5 file replaced by
    another mesh's loaded as that mesh (review). One line naming the item."""
    _xdmf_with_heavy_data_named(tmp_path, "data.h5")
    qdrefine.write(tmp_path / "other.xdmf", examples.square(2))
    (tmp_path / "other.h5").replace(tmp_path / "data.h5")
    result = cli("info", tmp_path / "in.xdmf")
    assert result.returncode == 1
    assert result.stderr == (
        f"qdrefine: error: {tmp_path / 'in.xdmf'}: the data item data.h5:/data0 has "
        'Dimensions "3 2", but the HDF5 dataset holds 9 x 3 values (a replaced or '
        "mismatched HDF5 file)\n")


def test_an_xdmf_file_read_through_a_link_is_checked_against_the_data_read(tmp_path):
    """Through ``dir/link.xdmf -> ../other/real.xdmf`` the checks looked at
    ``dir/real.h5`` while meshio reads ``other/real.h5``: a mismatched file there was read
    (review). The checks look where meshio reads, beside the file linked to."""
    (tmp_path / "dir").mkdir()
    (tmp_path / "other").mkdir()
    qdrefine.write(tmp_path / "other" / "real.xdmf", examples.square(3))
    shutil.copy(tmp_path / "other" / "real.h5", tmp_path / "dir" / "real.h5")
    qdrefine.write(tmp_path / "other" / "small.xdmf", examples.square(2))
    (tmp_path / "other" / "small.h5").replace(tmp_path / "other" / "real.h5")
    (tmp_path / "dir" / "link.xdmf").symlink_to("../other/real.xdmf")
    for path in (tmp_path / "other" / "real.xdmf", tmp_path / "dir" / "link.xdmf"):
        with pytest.raises(ValueError, match="a replaced or mismatched HDF5 file|written by "
                                             "another run"):
            qdrefine.read(path)


@pytest.mark.parametrize("name, refused", [
    ("tag", (".vtu", ".xdmf", ".vtk")), ("gmsh:physical", (".vtu", ".xdmf", ".vtk")),
    ("medit:ref", (".vtu", ".xdmf", ".vtk")), ("cell_tags", (".vtu", ".xdmf", ".vtk")),
    ("gmsh:geometrical", (".xdmf", ".vtk")), ("gmsh:dim_tags", (".xdmf", ".vtk")),
])
def test_cell_data_named_like_the_tags_is_refused(tmp_path, name, refused):
    """A field named ``tag`` came back from .vtu, .xdmf and .vtk as the cell tags, every
    tagged edge lost, without a word (review): refused where the readers would take it,
    written where they do not (.msh: a view)."""
    from qdrefine import interop

    mesh = examples.jittered_square(3, 0, 0.0, "all")
    field = mesh.replace(cell_data={name: np.arange(mesh.n_triangles) % 5 + 10})
    for ext in (".vtu", ".xdmf", ".vtk", ".msh"):
        path = tmp_path / f"c{ext}"
        if ext in refused:
            with pytest.raises(ValueError, match=rf"c\{ext}: cell data {name!r} has a name that "
                                                 "readers of this format take as the cell tags"):
                qdrefine.write(path, field)
            assert not list(tmp_path.iterdir())
            continue
        back = qdrefine.read(_written(path, field))
        np.testing.assert_array_equal(back.cell_tags, mesh.cell_tags)
        np.testing.assert_array_equal(back.edge_tags, mesh.edge_tags)
        np.testing.assert_array_equal(back.cell_data[name], field.cell_data[name])
        path.unlink()
    with pytest.raises(ValueError, match=f"cell data {name!r} has a name"):
        interop.to_meshio(field)


def test_what_msh_and_xdmf_files_cannot_hold_is_refused(tmp_path):
    """Tags beyond 32 bits (binary MSH 2.2 wrapped them to other tags, text MSH wrote files
    it could not read), a physical name with a line break in MSH, a control character in
    XDMF's XML: refused before anything is written (review)."""
    square = examples.square(2)
    big = square.replace(cell_tags=np.full(square.n_triangles, 2**31))
    # negative tags: Gmsh (the SDK, 2026-11-27) read -3 as physical group 3 from every
    # variant, and text MSH 2.2 loaded with no triangle at all
    for tag, why in ((2**31, "does not fit the 32-bit tags of Gmsh files"),
                     (-3, r"is negative, which Gmsh reads as 3 \(text MSH 2\.2 loses"),
                     (-(2**63), "is negative")):
        big = square.replace(cell_tags=np.full(square.n_triangles, tag))
        for kwargs in ({}, {"binary": True}, {"format_version": "2.2"},
                       {"format_version": "2.2", "binary": True}):
            with pytest.raises(ValueError, match=rf"t\.msh: cell tag {tag} {why}"):
                qdrefine.write(tmp_path / "t.msh", big, **kwargs)
    big = square.replace(cell_tags=np.full(square.n_triangles, 2**31))
    from qdrefine import store

    store.create(tmp_path / "big.zarr", big)  # a store's streamed export checks them too
    with pytest.raises(ValueError, match=r"s\.msh: cell tag 2147483648 does not fit"):
        store.to_file(tmp_path / "big.zarr", tmp_path / "s.msh", binary=True,
                      format_version="2.2")
    with pytest.raises(ValueError, match="the store's mark of chunks that were never"):
        store.create(tmp_path / "fill.zarr", square.replace(
            cell_tags=np.full(square.n_triangles, -(2**63))))
    import shutil

    shutil.rmtree(tmp_path / "big.zarr")
    assert qdrefine.read(_written(tmp_path / "t.vtu", big)).cell_tags.max() == 2**31
    named = square.replace(cell_tags=np.ones(square.n_triangles, np.int64),
                           physical_names={(2, 1): "two\nlines"})
    with pytest.raises(ValueError, match=r"contains a line break, which MSH files cannot"):
        qdrefine.write(tmp_path / "n.msh", named)
    assert qdrefine.read(_written(tmp_path / "n.vtu", named)).physical_names[(2, 1)] == \
        "two\nlines"
    for mesh in (named.replace(physical_names={(2, 1): "a\x01b"}),
                 square.replace(point_data={"a\x1fb": np.zeros(9)})):
        with pytest.raises(ValueError, match="contains a control character, which XML files"):
            qdrefine.write(tmp_path / "c.xdmf", mesh)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["n.vtu", "t.vtu"]


def _written(path, mesh):
    qdrefine.write(path, mesh)
    return path


def test_half_floats_and_text_vtu(tmp_path):
    """float16 data: VTU and VTK have no 16-bit floats; they are written as float32 (every
    value exact; VTU reads back float16) instead of failing with a KeyError (review). Text
    VTU is refused, as documented (meshio's would round the points and drop the names)."""
    square = examples.square(2)
    mesh = square.replace(point_data={"h": (np.arange(9) / 7).astype(np.float16)})
    back = qdrefine.read(_written(tmp_path / "h.vtu", mesh))
    assert back.point_data["h"].dtype == np.float16
    assert np.array_equal(back.point_data["h"], mesh.point_data["h"])
    for ext in (".vtk", ".xdmf"):  # XDMF refused float16 (data review, 2026-11-27)
        back = qdrefine.read(_written(tmp_path / f"h{ext}", mesh)).point_data["h"]
        assert back.dtype == np.float32
        assert np.array_equal(back, mesh.point_data["h"].astype(np.float32))


def test_vtk_fields_with_several_axes_per_row_read_back(tmp_path):
    """meshio's VTK writer declared a (2, 2) field per point as 4 numbers and wrote N x 4
    values under it: an unreadable file (data review). Now written flat, with a warning;
    point data read through meshio comes back in native byte order (it was big-endian)."""
    square = examples.square(2)
    n, m = square.n_points, square.n_triangles
    mesh = square.replace(point_data={"T": np.arange(4 * n, dtype=np.float64).reshape(n, 2, 2),
                                      "i": np.arange(n, dtype=np.int16)},
                          cell_data={"c": np.ones((m, 3, 2))})
    with pytest.warns(UserWarning, match=r"T \(9, 2, 2\), c \(8, 3, 2\) written flat"):
        qdrefine.write(tmp_path / "d.vtk", mesh)
    back = qdrefine.read(tmp_path / "d.vtk")
    np.testing.assert_array_equal(back.point_data["T"], mesh.point_data["T"].reshape(n, 4))
    np.testing.assert_array_equal(back.cell_data["c"], np.ones((m, 6)))
    assert back.point_data["i"].dtype == np.dtype(np.int16)  # native order, not '>i2'
    for name in ("a b", "", "a\tb"):  # meshio's raw WriteError, or an unreadable file
        with pytest.raises(ValueError, match=r"s\.vtk: data name .* is not one word"):
            qdrefine.write(tmp_path / "s.vtk", square.replace(point_data={name: np.zeros(n)}))
    assert not (tmp_path / "s.vtk").exists()
    with pytest.raises(ValueError, match=r"t\.vtu: VTU files are written with binary data only"):
        qdrefine.write(tmp_path / "t.vtu", square, binary=False)


def test_a_number_with_an_underscore_is_named(tmp_path):
    """``1_0``: NumPy's parser stops at it, Python's ``float`` reads it as 10; the message
    named the whole section instead of the word (review)."""
    path = tmp_path / "u.msh"
    path.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1_0 0 0\n"
                    "3 0 1 0\n$EndNodes\n$Elements\n1\n1 2 2 1 1 1 2 3\n$EndElements\n")
    with pytest.raises(ValueError, match=r"u\.msh: not a readable Gmsh MSH file \(line 7: "
                                         r"expected a number, got '1_0'\)$"):
        qdrefine.read(path)


NODES41 = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 3 1 {max}\n2 1 0 3\n1\n2\n{last}\n" \
          "0 0 0\n1 0 0\n0 1 0\n$EndNodes\n$Elements\n1 1 1 {tag}\n2 1 2 1\n{tag} 1 2 {last}\n" \
          "$EndElements\n"


@pytest.mark.parametrize("last, tag, message", [
    # NumPy's text parser saturates: 10**20 read as 2**63 - 1 and the mesh loaded (review)
    ("99999999999999999999", "1", r"line 5: node tag 1e\+20 is beyond int64 \(tags are "
                                  r"integers below 2\*\*63\)"),
    ("3", "99999999999999999999", r"line 15: expected a 64-bit integer, got "
                                  r"'99999999999999999999'"),
    ("3", "-99999999999999999999", r"line 15: expected a 64-bit integer"),
])
def test_integers_beyond_int64_are_refused(tmp_path, last, tag, message):
    path = tmp_path / "big.msh"
    path.write_text(NODES41.format(max=last, last=last, tag=tag))
    with pytest.raises(ValueError, match=r"big\.msh: not a readable Gmsh MSH file \(" + message):
        qdrefine.read(path)


def test_int64_limits_themselves_still_read(tmp_path):
    path = tmp_path / "max.msh"
    path.write_text(NODES41.format(max=3, last=3, tag=2**63 - 1))
    assert qdrefine.read(path).n_triangles == 1
    from qdrefine.io._text import parse  # the minimum too (review of the change)

    assert parse(b"1 2 -9223372036854775808", np.int64).tolist() == [1, 2, -(2**63)]


def test_parametric_nodes_and_repeated_views(tmp_path):
    """MSH 2.2 saved with Mesh.SaveParametric has ``$ParametricNodes`` instead of
    ``$Nodes``: said so (it said 'no $Nodes section'). A view with two time steps: the last
    is kept, with a warning (silently before; review)."""
    head = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
    tail = "$Elements\n1\n1 2 2 1 1 1 2 3\n$EndElements\n"
    (tmp_path / "p.msh").write_text(head + "$ParametricNodes\n3\n1 0 0 0 0 0\n2 1 0 0 0 0\n"
                                    "3 0 1 0 0 0\n$EndParametricNodes\n" + tail)
    with pytest.raises(ValueError, match=r"p\.msh: .*\$ParametricNodes \(a file saved with "
                                         r"Mesh\.SaveParametric\) is not read"):
        qdrefine.read(tmp_path / "p.msh")

    def step(t, value):
        return (f'$NodeData\n1\n"u"\n1\n{t}\n3\n{t}\n1\n3\n1 {value}\n2 {value}\n3 {value}\n'
                "$EndNodeData\n")

    (tmp_path / "s.msh").write_text(head + "$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n$EndNodes\n"
                                    + tail + step(0, 1.5) + step(1, 2.5))
    with pytest.warns(UserWarning, match=r"s\.msh: \$NodeData 'u' is given more than once "
                                         r"\(time steps of a view\); the last one is kept"):
        mesh = qdrefine.read(tmp_path / "s.msh")
    assert mesh.point_data["u"].tolist() == [2.5, 2.5, 2.5]


def test_names_and_shapes_a_format_cannot_hold(tmp_path):
    """Found by the data review (2026-11-27): VTU turned a tab or a line break in a data
    name into a space (two fields became one, silently); a field of shape (N, 0) made an
    unreadable VTU; '$End...' in an MSH name made a file no reader could read."""
    square = examples.square(2)
    n = square.n_points
    tabs = square.replace(point_data={"a\tb": np.zeros(n), "a b": np.ones(n),
                                      "x\ny\rz": np.arange(n) * 1.0})
    back = qdrefine.read(_written(tmp_path / "t.vtu", tabs))
    assert sorted(back.point_data) == sorted(tabs.point_data)
    np.testing.assert_array_equal(back.point_data["a b"], np.ones(n))
    with pytest.raises(ValueError, match=r"z\.vtu: data 'none' has no values per row \(shape "
                                         r"\(9, 0\)\)"):
        qdrefine.write(tmp_path / "z.vtu", square.replace(point_data={"none": np.zeros((n, 0))}))
    named = square.replace(cell_tags=np.ones(square.n_triangles, np.int64),
                           physical_names={(2, 1): "a $EndPhysicalNames b"})
    with pytest.raises(ValueError, match=r"physical name .* contains '\$End'"):
        qdrefine.write(tmp_path / "e.msh", named)
    with pytest.raises(ValueError, match=r"point data name 'q\$EndQdrefineData' contains"):
        qdrefine.write(tmp_path / "e.msh", square.replace(
            point_data={"q$EndQdrefineData": np.zeros(n)}))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.vtu"]


@pytest.mark.parametrize("ext", [".mesh", ".obj", ".stl"])
def test_what_meshio_makes_up_for_formats_without_data_is_not_read(tmp_path, ext):
    """Medit's vertex references, OBJ's group ids and STL's facet normals came back as
    point or cell data (and went on into .msh files) from formats documented to hold
    none (docs review, 2026-11-27)."""
    import warnings

    mesh = examples.jittered_square(3, 0, 0.0, "all")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the tags and edges these formats drop
        qdrefine.write(tmp_path / f"m{ext}", mesh)
    back = qdrefine.read(tmp_path / f"m{ext}")
    assert dict(back.point_data) == {} and dict(back.cell_data) == {}
    assert back.n_triangles == mesh.n_triangles


def test_fields_with_those_names_still_read_from_formats_with_data(tmp_path):
    """Only the readers that make the fields up lose them: a user's field named
    ``facet_normals`` came back from .vtk and .xdmf no more (review of the change)."""
    square = examples.square(2)
    n, m = square.n_points, square.n_triangles
    mesh = square.replace(point_data={"obj:group_ids": np.arange(n) * 1.0,
                                      "medit:ref": np.ones(n)},
                          cell_data={"facet_normals": np.ones(m)})
    for ext in (".vtk", ".xdmf"):
        back = qdrefine.read(_written(tmp_path / f"f{ext}", mesh))
        assert sorted(back.point_data) == ["medit:ref", "obj:group_ids"]
        assert sorted(back.cell_data) == ["facet_normals"]


def test_floats_wider_than_64_bits_are_refused_naming_the_file(tmp_path):
    """float128 data: VTU failed with a buffer error naming no file, MSH would have stored
    doubles (docs review, 2026-11-27)."""
    square = examples.square(2)
    wide = square.replace(point_data={"q": np.ones(square.n_points, np.longdouble)})
    if wide.point_data["q"].dtype.itemsize <= 8:
        return  # a platform whose long double is a double: nothing to refuse
    for ext in (".vtu", ".msh", ".xdmf", ".vtk"):
        with pytest.raises(ValueError, match=rf"q\{ext}: data 'q' of dtype float\d+ cannot be "
                                             "written: files hold integers and floats of up"):
            qdrefine.write(tmp_path / f"q{ext}", wide)
    assert not list(tmp_path.iterdir())


def test_an_hdf5_dataset_never_written_is_refused(tmp_path):
    """HDF5 reads fill values for chunks never written: a 2.6 kB pair declaring 150 M
    points took 7.7 GB before the checks refused it (review). Refused from the storage the
    file holds, before anything is read, beyond 64 MiB (a small one may be a writer's lazy
    zeros); a virtual dataset, whose data is in its sources, is read."""
    import h5py

    qdrefine.write(tmp_path / "m.xdmf", examples.square(2))
    with h5py.File(tmp_path / "m.h5", "r+") as h5:
        points = h5["data0"][()]
        del h5["data0"]
        h5.create_dataset("data0", shape=(3_000_000, 3), dtype=points.dtype, chunks=True)
    xml = (tmp_path / "m.xdmf").read_text()
    (tmp_path / "m.xdmf").write_text(xml.replace('Dimensions="9 3"', 'Dimensions="3000000 3"'))
    with pytest.raises(ValueError, match=r"m.xdmf: the data item m.h5:/data0 declares 3000000 "
                                         r"x 3 values, but the HDF5 file holds 0 of their "
                                         r"72000000 bytes \(data never written\)"):
        qdrefine.read(tmp_path / "m.xdmf")
    qdrefine.write(tmp_path / "v.xdmf", examples.square(2))
    with h5py.File(tmp_path / "v.h5", "r+") as h5:  # data0 as a view of a source dataset
        h5["source"] = h5["data0"][()]
        layout = h5py.VirtualLayout(shape=h5["source"].shape, dtype=h5["source"].dtype)
        layout[:] = h5py.VirtualSource(h5["source"])
        del h5["data0"]
        h5.create_virtual_dataset("data0", layout)
    assert np.array_equal(qdrefine.read(tmp_path / "v.xdmf").points, examples.square(2).points)
    qdrefine.write(tmp_path / "z.xdmf", examples.square(2), compress=True)  # filtered: fine
    assert qdrefine.read(tmp_path / "z.xdmf").n_triangles == examples.square(2).n_triangles


def test_heavy_data_that_is_not_hdf5_is_named(tmp_path):
    """The message was HDF5's "Unable to synchronously open file (file signature not
    found)", naming neither the heavy-data file nor the format (review)."""
    qdrefine.write(tmp_path / "m.xdmf", examples.square(2))
    (tmp_path / "m.h5").write_text("root:x:0:0:root:/root:/bin/bash\n")
    result = cli("info", tmp_path / "m.xdmf")
    assert result.returncode == 1
    assert result.stderr == (f"qdrefine: error: {tmp_path / 'm.h5'}: not an HDF5 file (the "
                             "heavy data of m.xdmf)\n")


@pytest.mark.parametrize("compress", [False, True])
def test_an_xdmf_write_past_the_file_size_limit_is_one_line(tmp_path, compress):
    """Under ``ulimit -f`` HDF5 failed mid-write: h5py printed four tracebacks while it
    cleaned up and the process crashed (exit 139; review). Uncompressed, the size is
    checked before; compressed, the file is made in memory and written by Python."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (1 << 16, 1 << 16))

    qdrefine.write(tmp_path / "in.msh", examples.plate_with_hole())
    args = ["refine", tmp_path / "in.msh", tmp_path / "out.xdmf", "--levels", "2"]
    done = subprocess.run([sys.executable, "-m", "qdrefine", *map(str, args),
                           *(["--compress"] if compress else [])], capture_output=True,
                          text=True, preexec_fn=limit, timeout=300)
    err = without_compile_note(done.stderr)
    assert (done.returncode, err.count("\n")) == (1, 1), err
    assert err.startswith(f"qdrefine: error: {tmp_path / 'out.h5'}: cannot write: File too "
                          "large")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.msh"]
    # a small mesh fits (the first estimate, 64 kB per dataset, refused 7.5 kB files)
    small = ("import qdrefine, sys; from qdrefine import examples; "
             "qdrefine.write(sys.argv[1], examples.square(2), compress=sys.argv[2] == '1')")
    done = subprocess.run([sys.executable, "-c", small, str(tmp_path / "s.xdmf"),
                           str(int(compress))], capture_output=True, text=True,
                          preexec_fn=limit, timeout=300)
    assert done.returncode == 0, done.stderr
    assert qdrefine.read(tmp_path / "s.xdmf").n_triangles == examples.square(2).n_triangles


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX resource limits")
def test_a_store_write_the_kernel_refuses_names_the_store(tmp_path):
    """A full disk or a file size limit while a store was written said only "[Errno 27]
    File too large" (review): named as a file's refused write is, with nothing left."""
    src = tmp_path / "in.msh"
    qdrefine.write(src, qdrefine.refine(examples.plate_with_hole(), levels=2))
    before = _snapshot(tmp_path)
    result = subprocess.run([sys.executable, "-m", "qdrefine", "convert", src,
                             tmp_path / "out.zarr", "-q"],
                            capture_output=True, text=True, timeout=300,
                            preexec_fn=_file_size_limit(20_000))
    assert result.returncode == 1, result.stderr
    assert result.stderr.strip().splitlines()[-1] == (
        f"qdrefine: error: {tmp_path / 'out.zarr'}: cannot write: File too large")
    assert _snapshot(tmp_path) == before


@pytest.mark.skipif(not hasattr(os, "statvfs"), reason="POSIX statvfs")
def test_an_xdmf_write_to_a_read_only_filesystem_says_so(tmp_path, monkeypatch):
    """A read-only filesystem with little free space was reported as "No space left on
    device" by the size check before HDF5 starts (review, on a 64 kB read-only tmpfs)."""
    import collections
    import shutil

    real = os.statvfs
    monkeypatch.setattr(shutil, "disk_usage", lambda path: collections.namedtuple(
        "usage", "total used free")(65536, 65536, 0))
    monkeypatch.setattr(os, "statvfs", lambda path: type("V", (), {
        "f_flag": real(path).f_flag | os.ST_RDONLY})())
    with pytest.raises(OSError, match=r"m\.h5: cannot write: Read-only file system$"):
        qdrefine.write(tmp_path / "m.xdmf", examples.plate_with_hole())
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("ext", [".msh", ".vtu", ".xdmf", ".off", ".obj", ".node", ".vtk",
                                 ".stl", ".ply", ".mesh"])
def test_an_empty_file_is_said_to_be_empty(tmp_path, ext):
    """Each format said it its own way: "meshio refused it without a reason" (.vtu),
    "nothing after the OFF line", "no $MeshFormat section (empty file?)" (review)."""
    (tmp_path / f"e{ext}").write_bytes(b"")
    with pytest.raises(ValueError, match=rf"^{re.escape(str(tmp_path / f'e{ext}'))}: the file "
                                         "is empty$"):
        qdrefine.read(tmp_path / f"e{ext}")


def test_an_output_name_ending_in_a_slash_is_refused(tmp_path):
    """``refine in.msh out.msh/`` wrote the file out.msh (review): a name ending in '/'
    names a directory."""
    src = tmp_path / "in.msh"
    qdrefine.write(src, examples.square(1))
    result = cli("refine", src, f"{tmp_path}/out.msh/")
    assert result.returncode == 1
    assert result.stderr == (f"qdrefine: error: {tmp_path}/out.msh/: a file name cannot end "
                             "in '/' (it names a directory)\n")
    with pytest.raises(ValueError, match="a file name cannot end in '/'"):
        qdrefine.write(f"{tmp_path}/out.vtu/", examples.square(1))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.msh"]
