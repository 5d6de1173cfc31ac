"""The command line: every subcommand (in-process through ``qdrefine.cli.main``; the entry
point itself by ``python -m qdrefine``), and its error paths."""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import qdrefine
from cli_runner import cli, without_compile_note
from meshes import DATA
from qdrefine import examples, quality
from qdrefine.cli import main


def test_python_dash_m_runs():
    result = cli("--help")
    assert result.returncode == 0
    for name in ("refine", "info", "quality", "plot", "compare", "demo"):
        assert name in result.stdout


def test_demo_prints_a_summary_and_writes_files(tmp_path, capsys):
    assert main(["demo", str(tmp_path / "out"), "--levels", "1"]) == 0
    out = capsys.readouterr().out
    for scheme in ("7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"):
        assert scheme in out
    assert " NO " not in out
    # the schemes that gave the same meshes say so (measured here, not assumed)
    same = [[line.split(":")[0] for line in out.splitlines() if "the same meshes" in line]]
    finest = {s: qdrefine.refine(examples.plate_with_hole(), s) for s in qdrefine.scheme_names()}
    equal = [s for s in finest if np.array_equal(finest[s].triangles, finest["7t-qd"].triangles)
             and np.array_equal(finest[s].points, finest["7t-qd"].points)]
    assert same == [[", ".join(equal)]] if len(equal) > 1 else same == [[]]
    files = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert files == ["plate_with_hole.msh", "plate_with_hole_7t-qd.msh",
                     "plate_with_hole_7t-qd.png", "report.txt"]
    fine = qdrefine.read(tmp_path / "out" / "plate_with_hole_7t-qd.msh")
    assert fine.n_triangles == 7 * examples.plate_with_hole().n_triangles
    assert "similarity classes" in (tmp_path / "out" / "report.txt").read_text()
    assert (tmp_path / "out" / "plate_with_hole_7t-qd.png").read_bytes()[:4] == b"\x89PNG"


def test_demo_writes_all_of_its_files_or_none(tmp_path, monkeypatch, capsys):
    """A write refused half way (a full disk) left the meshes written before it, and the
    folder; ``paper`` left its first figures without a report (review). The files appear
    together, or none does: no folder made, an existing folder's files kept."""
    from qdrefine.cli import _common

    def full(path, text):
        raise OSError(28, "No space left on device", str(path))

    monkeypatch.setattr(_common, "write_text", full)
    assert main(["demo", str(tmp_path / "new"), "--levels", "1", "-q"]) == 1
    assert "No space left on device" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "report.txt").write_text("kept")
    assert main(["demo", str(tmp_path / "old"), "--levels", "1", "-q"]) == 1
    err = capsys.readouterr().err  # the file in its folder, not in the temporary one
    assert f"{tmp_path / 'old' / 'report.txt'}" in err and ".qdrefine-" not in err, err
    assert [p.name for p in (tmp_path / "old").iterdir()] == ["report.txt"]
    assert (tmp_path / "old" / "report.txt").read_text() == "kept"
    monkeypatch.undo()
    monkeypatch.chdir(tmp_path)
    # a name taken by a directory: refused before any file is moved in (three were)
    (tmp_path / "old" / "report.txt").unlink()
    (tmp_path / "old" / "report.txt").mkdir()
    assert main(["demo", "old", "--levels", "1", "-q"]) == 1
    assert "old/report.txt: is a directory" in capsys.readouterr().err
    assert [p.name for p in (tmp_path / "old").iterdir()] == ["report.txt"]
    # a replaced file keeps its permission bits (they became 0644)
    (tmp_path / "old" / "report.txt").rmdir()
    (tmp_path / "old" / "report.txt").write_text("mine")
    (tmp_path / "old" / "report.txt").chmod(0o640)
    assert main(["demo", "old", "--levels", "1", "-q"]) == 0
    assert (tmp_path / "old" / "report.txt").stat().st_mode & 0o777 == 0o640
    assert len(list((tmp_path / "old").iterdir())) == 4


def test_demo_subprocess_default_directory(tmp_path):
    result = cli("demo", "--levels", "1", "--quiet", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert result.stdout == "" and result.stderr == ""
    assert (tmp_path / "qdrefine-demo" / "report.txt").exists()


def test_refine_gmsh_keeps_every_tag(tmp_path, run):
    """Acceptance: two physical surfaces and tagged lines, --levels 2."""
    src = DATA / "two_regions_22.msh"
    before = src.read_bytes()
    out = tmp_path / "fine.msh"
    result = run("refine", src, out, "--levels", "2")
    assert result.returncode == 0, result.stderr
    assert src.read_bytes() == before
    coarse, fine = qdrefine.read(src), qdrefine.read(out)
    assert fine.n_triangles == 49 * coarse.n_triangles
    area_c, area_f = quality.areas(coarse), quality.areas(fine)
    for tag in np.unique(coarse.cell_tags):
        assert area_f[fine.cell_tags == tag].sum() == pytest.approx(
            area_c[coarse.cell_tags == tag].sum(), rel=1e-13)
    p = fine.points
    used = np.zeros(len(fine.edges), bool)
    for (a, b), tag in zip(coarse.edges, coarse.edge_tags, strict=True):
        pa, pb = coarse.points[a], coarse.points[b]
        d = pb - pa
        # fine edges of this tag lying on the segment a-b
        s = ((p[fine.edges] - pa) @ d) / (d @ d)  # (K, 2) positions along a-b
        rel = p[fine.edges] - pa
        off = np.abs(d[0] * rel[..., 1] - d[1] * rel[..., 0]) / np.linalg.norm(d)
        on = (fine.edge_tags == tag) & (off < 1e-12).all(1) & (s > -1e-12).all(1) \
            & (s < 1 + 1e-12).all(1)
        assert on.sum() == 9
        used |= on
        pieces = np.sort(s[on], axis=1)
        pieces = pieces[np.argsort(pieces[:, 0])]
        np.testing.assert_allclose(pieces[0, 0], 0, atol=1e-12)
        np.testing.assert_allclose(pieces[-1, 1], 1, atol=1e-12)
        np.testing.assert_allclose(pieces[1:, 0], pieces[:-1, 1], atol=1e-12)  # no gap
    assert used.all() and len(fine.edges) == 9 * len(coarse.edges)


def test_info_json_and_text(tmp_path, run):
    result = run("info", DATA / "two_regions_41.msh", "--json")
    assert result.returncode == 0, result.stderr
    d = json.loads(result.stdout)
    assert d["triangles"] == 52 and d["conforming"] and d["counter_clockwise"]
    assert d["area"] == pytest.approx(2.0)
    assert d["cell_tags"]["1"]["area"] == pytest.approx(1.0)
    assert d["edge_tags"]["10"]["length"] == pytest.approx(2.0)
    assert d["bounding_box"] == {"xmin": 0.0, "ymin": 0.0, "xmax": 2.0, "ymax": 1.0}
    text = run("info", DATA / "two_regions_41.msh").stdout
    assert "conforming            yes" in text and "edge tags             10 (bottom):" in text
    assert d["edge_tags"]["20"]["name"] == "interface"  # Gmsh physical names label the tags
    # every tag has the same keys: "name" is null where there is none (it was left out)
    unnamed = tmp_path / "unnamed.msh"
    square = examples.square(2)
    qdrefine.write(unnamed, square.replace(cell_tags=np.ones(square.n_triangles, int)))
    tags = json.loads(run("info", unnamed, "--json").stdout)["cell_tags"]
    assert tags and all(entry["name"] is None for entry in tags.values())


def test_quality_json_and_histogram(tmp_path, run):
    png = tmp_path / "h.png"
    result = run("quality", DATA / "two_regions_22.msh", "--json", "--histogram", png)
    assert result.returncode == 0, result.stderr
    d = json.loads(result.stdout)
    mesh = qdrefine.read(DATA / "two_regions_22.msh")
    assert d["min_angle"]["min"] == pytest.approx(quality.min_angles(mesh).min())
    assert sum(d["min_angle_histogram"]["counts"]) == 52
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert result.stderr == f"{png}: histogram of 52 minimum angles written\n"  # not in JSON
    text = run("quality", DATA / "two_regions_22.msh", "--histogram", png).stdout
    assert text.endswith(f"{png}: histogram of 52 minimum angles written\n")


def test_plot_writes_a_png(tmp_path, run):
    for color in ("min-angle", "tag", "none"):
        png = tmp_path / f"{color}.png"
        result = run("plot", DATA / "two_regions_22.msh", png, "--color", color)
        assert result.returncode == 0, result.stderr
        assert png.read_bytes()[:4] == b"\x89PNG"


def test_compare_json_and_plot(tmp_path, run):
    png = tmp_path / "c.png"
    result = run("compare", DATA / "two_regions_22.msh", "--levels", "2", "--schemes",
                 "7t-qd", "4t-red", "--json", "--plot", png)
    assert result.returncode == 0, result.stderr
    rows = json.loads(result.stdout)["rows"]
    assert [(r["scheme"], r["level"]) for r in rows] == [
        ("7t-qd", 0), ("7t-qd", 1), ("7t-qd", 2), ("4t-red", 0), ("4t-red", 1), ("4t-red", 2)]
    assert [r["triangles"] for r in rows] == [52, 364, 2548, 52, 208, 832]
    red = [r["similarity_classes"] for r in rows[3:]]
    assert red[0] == red[1] == red[2]  # red refinement makes no new shapes
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert result.stderr.endswith(f"{png}: 2 schemes over 2 levels written\n")
    commas = run("compare", DATA / "two_regions_22.msh", "--levels", "2", "--schemes",
                 "7T-QD,4t-red", "--json")  # commas, any case: the same rows
    assert json.loads(commas.stdout)["rows"] == rows
    quiet = run("compare", DATA / "two_regions_22.msh", "--levels", "2", "--schemes",
                "7t-qd", "4t-red", "--json", "-q", "--plot", png)  # asked-for JSON, no note
    assert (json.loads(quiet.stdout)["rows"], quiet.stderr) == (rows, "")
    assert run("compare", DATA / "two_regions_22.msh", "--levels", "1", "-q").stdout == ""


# error paths ------------------------------------------------------------------------------

def bad_inputs(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    """One file per bad-input kind, with the expected message."""
    def msh(name, nodes, elements):
        lines = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", "$Nodes", str(len(nodes))]
        lines += [f"{i + 1} {x} {y} {z}" for i, (x, y, z) in enumerate(nodes)]
        lines += ["$EndNodes", "$Elements", str(len(elements))]
        lines += [f"{i + 1} {t} 2 1 1 " + " ".join(map(str, v))
                  for i, (t, v) in enumerate(elements)]
        path = tmp_path / name
        path.write_text("\n".join(lines + ["$EndElements", ""]))
        return path

    sq = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    cases = {
        "missing": (tmp_path / "missing.msh", "no such file"),
        "unknown format": (tmp_path / "a.xyz", "unknown file format"),
        "truncated": (tmp_path / "cut.msh", "not a readable Gmsh"),
        "no triangles": (msh("lines.msh", sq, [(1, (1, 2))]), "holds no triangles"),
        "non-triangle cells": (msh("quad.msh", sq, [(3, (1, 2, 3, 4))]), "1 quad cells"),
        "nan": (msh("nan.msh", [(0, 0, 0), (1, 0, 0), ("nan", 1, 0)], [(2, (1, 2, 3))]),
                "non-finite coordinate"),
        "index out of range": (tmp_path / "idx.ele", "vertex 9 is not in idx.node"),
        "zero area": (msh("flat.msh", [(0, 0, 0), (1, 0, 0), (2, 0, 0)], [(2, (1, 2, 3))]),
                      "has zero area"),
        "not flat": (msh("z.msh", [(0, 0, 0), (1, 0, 0), (0, 1, 1)], [(2, (1, 2, 3))]),
                     "not flat"),
    }
    src = (DATA / "two_regions_22.msh").read_text()
    (tmp_path / "cut.msh").write_text(src[: len(src) // 2])
    (tmp_path / "a.xyz").write_text("hello")
    (tmp_path / "idx.node").write_text("3 2 0 0\n0 0 0\n1 1 0\n2 0 1\n")
    (tmp_path / "idx.ele").write_text("1 3 0\n0 0 1 9\n")
    return cases


@pytest.mark.parametrize("kind", ["missing", "unknown format", "truncated", "no triangles",
                                  "non-triangle cells", "nan", "index out of range",
                                  "zero area", "not flat"])
def test_bad_input_gives_one_line_and_no_output(tmp_path, capsys, kind):
    path, message = bad_inputs(tmp_path)[kind]
    before = path.read_bytes() if path.exists() else None
    out = tmp_path / "out.vtu"
    for argv in (["refine", path, out], ["info", path], ["quality", path],
                 ["plot", path, tmp_path / "p.png"], ["compare", path, "--levels", "1"]):
        assert main([str(a) for a in argv]) == 1
        err = capsys.readouterr().err
        assert err.startswith("qdrefine: error: ") and message in err, err
        assert err.count("\n") == 1
    assert not out.exists() and not (tmp_path / "p.png").exists()
    assert (path.read_bytes() if path.exists() else None) == before


def test_bad_input_through_the_entry_point(tmp_path):
    path, _ = bad_inputs(tmp_path)["truncated"]
    result = cli("refine", path, tmp_path / "o.msh")
    assert result.returncode == 1
    assert result.stderr.startswith("qdrefine: error: ") and result.stderr.count("\n") == 1
    assert "Traceback" not in result.stderr and not (tmp_path / "o.msh").exists()


@pytest.mark.parametrize("argv, message", [
    (["refine", "IN.msh", "OUT.msh", "--levels", "x"], "expected a whole number"),
    (["refine", "IN.msh", "OUT.msh", "--levels", "-1"], "expected a number >= 0"),
    (["refine", "IN.msh", "OUT.msh", "--scheme", "8t"], "unknown scheme '8t'"),
    (["refine", "IN.msh", "OUT.abc"], "unknown file format (extension '.abc')"),
    (["refine", "IN.msh", "OUT"], "OUT: unknown file format (no extension)"),
    (["coarsen", "IN.msh", "OUT.msh", "--all", "--scheme", "7tqd"], "argument --scheme: "
                                                                   "unknown scheme '7tqd'"),
    (["refine", "IN.msh", "IN.msh"], "would overwrite the input"),
    (["refine", "IN.msh", "nodir/OUT.msh"], "does not exist"),
    (["plot", "IN.msh", "p.jpg"], "pictures are saved as"),
    (["plot", "IN.msh", "p.png", "--color", "pink"], "invalid choice"),
    (["compare", "IN.msh", "--schemes", "7t-qd", "zz"], "unknown scheme 'zz'"),
    (["compare", "IN.msh", "--schemes", "7t-qd,zz"], "unknown scheme 'zz'"),
    (["quality", "IN.msh", "--tolerance", "0"], "--tolerance: expected a number from 1e-12 to "
                                                "180, got 0 (the angles are computed to"),
    (["quality", "IN.msh", "--tolerance", "inf"], "expected a number from 1e-12 to 180, got "
                                                  "inf"),  # was exit 1, unlike 0 (review)
    # found by a review of the commands (2026-11-27): each was a traceback, two lines, or
    # silently accepted
    (["quality", "IN.msh", "--tolerance", "1e-20"], "expected a number from 1e-12 to 180"),
    (["compare", "IN.msh", "--schemes", ","], "expected scheme names, got ','"),
    (["demo", "OUT", "--levels", "0"], "argument --levels: expected a number >= 1, got 0"),
    (["info", "IN.msh", "--bogus"], "unrecognized arguments: --bogus (see 'qdrefine info "
                                    "--help')"),
    (["frobnicate"], "invalid choice: 'frobnicate'"),
    (["plot", "IN.msh", "p.png", "--dpi", "0"], "expected 10 to 2000, got 0"),
    (["check", "IN.msh", "--min-angle", "100"], "expected degrees above 0 and at most 60"),
    (["diagram", "--tol", "abc"], "argument --tol: expected a number, got 'abc'"),
    # ran out of memory (review): the error estimates stop falling at about 3e-14
    (["diagram", "--tol", "1e-300"], "--tol: expected a number from 1e-14 to 1e-06, got "
                                     "1e-300 (float64 rounding"),
    (["demo", "--afem", "--cycles", "-1"], "expected a number >= 1, got -1"),  # said >= 0
    # an empty argument was the path '.' (review): 'demo ""' wrote into the current folder
    (["info", ""], "argument IN: expected a value, got an empty string"),
    (["demo", ""], "argument OUTDIR: expected a value, got an empty string"),
    (["refine", "IN.msh", "OUT.msh", "--mark-file", ""], "argument --mark-file: expected a "
                                                         "value, got an empty string"),
    (["refine", "IN.msh", "OUT.zarr"], "OUT.zarr: a Zarr mesh store, which this command does "
                                       "not write ('refine --dask' refines into one"),
    (["plot", "IN.msh", "p.png", "--color", "tag"], "IN.msh: no cell tags to colour by"),
    (["demo", "--afem", "--levels", "2"], "--levels applies to the plate demo; --afem takes "
                                          "--cycles (see 'qdrefine demo --help')"),
    (["demo", "--cycles", "2"], "--cycles applies to --afem only (see 'qdrefine demo --help')"),
    (["demo", "--afem", "--cycles", "0"], "expected a number >= 1"),
    (["paper", "IN.msh"], "IN.msh: exists and is not a directory"),
    # an output directory that cannot be made: "[Errno 20] Not a directory: ..." (review)
    (["demo", "IN.msh/d"], "IN.msh/d: cannot write: Not a directory"),
    (["paper", "IN.msh/p"], "IN.msh/p: cannot write: Not a directory"),
    (["compare", "IN.msh", "--levels", "30"], "comparing the schemes (8 triangles, 30 levels) "
                                              "needs about"),  # was killed by the OOM killer
    (["demo", "--levels", "9"], "the demo (384 triangles, 9 levels) needs about"),
])
def test_bad_arguments(tmp_path, monkeypatch, capsys, argv, message):
    monkeypatch.chdir(tmp_path)
    qdrefine.write("IN.msh", examples.square(2))
    before = Path("IN.msh").read_bytes()
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse errors exit with 2
        code = exc.code
    assert code in (1, 2)
    err = without_compile_note(capsys.readouterr().err)
    assert err.startswith("qdrefine: error: ") and message in err and err.count("\n") == 1
    assert Path("IN.msh").read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["IN.msh"]


def test_clockwise_input_is_fixed_with_a_warning(tmp_path, capsys):
    path = tmp_path / "cw.msh"
    path.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 0 1 0\n"
                    "3 1 0 0\n$EndNodes\n$Elements\n1\n1 2 2 1 1 1 2 3\n$EndElements\n")
    assert main(["refine", str(path), str(tmp_path / "o.vtk"), "-q"]) == 0
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == f"qdrefine: warning: {path}: 1 of 1 triangles were clockwise " \
                           "and have been flipped\n"
    assert qdrefine.read(tmp_path / "o.vtk").n_triangles == 7


def _kernel(module: str):
    """A fresh numba kernel defined as if in ``module`` (never compiled, never cached)."""
    from numba import njit

    def add_one(x):
        return x + 1

    add_one.__module__ = module
    return njit(add_one)


def test_a_run_says_it_compiles_exactly_when_it_compiles(tmp_path, monkeypatch, capsys):
    """The note is said once, when a kernel of qdrefine is compiled (a cache miss), whatever
    the command: a command that compiles nothing says nothing (the note used to be
    predicted from lists of modules per command, which missed some and said it in vain for
    others), and a kernel of another package does not count."""
    import qdrefine.cli.info as info

    mesh = tmp_path / "m.msh"
    qdrefine.write(mesh, examples.square(2))
    main(["info", str(mesh)])  # warm: everything info runs is compiled in this process
    capsys.readouterr()
    ours, other = _kernel("qdrefine.probe"), _kernel("elsewhere")
    real = info.run
    for kernels, said in (((ours, ours), True), ((ours,), False), ((other,), False), ((), False)):
        def run(args, kernels=kernels):
            for kernel in kernels:
                kernel(1)
            return real(args)

        monkeypatch.setattr(info, "run", run)
        assert main(["info", str(mesh)]) == 0
        err = capsys.readouterr().err
        assert err.count("compiling the numerical kernels") == int(said), (kernels, err)


def test_scheme_lists_take_spaces_and_count_each_scheme_once(tmp_path, capsys):
    from qdrefine.cli._common import scheme_names_list

    assert scheme_names_list("7t-qd, 4T-LE") == ["7t-qd", "4t-le"]
    qdrefine.write(tmp_path / "in.msh", examples.square(2))
    assert main(["compare", str(tmp_path / "in.msh"), "--levels", "1", "--schemes",
                 "7t-qd, 4t-le", "7t-qd", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert [r["scheme"] for r in report["rows"] if r["level"] == 0] == ["7t-qd", "4t-le"]


def test_info_bounding_box_is_the_triangles_and_readable_far_away(tmp_path, capsys):
    """It took unused points in (a lone Gmsh point at (5, 5) beside a unit square) and
    printed a unit disk at 1e8 as [1e+08, 1e+08] (numbers review, 2026-11-27)."""
    square = examples.square(1)
    points = np.vstack([square.points + 1e8, [[5e8, 5e8]]])
    qdrefine.write(tmp_path / "far.vtu", qdrefine.Mesh(points, square.triangles))
    assert main(["info", str(tmp_path / "far.vtu")]) == 0
    out = capsys.readouterr().out
    assert "bounding box          [100000000, 100000001] x [100000000, 100000001] (of the " \
           "triangles)" in out
    assert "(1 unused)" in out


def test_info_edge_lengths_with_unused_points():
    """The bounding box's used points were taken for the edge lengths too: a wrong length,
    or an IndexError, with an unused point below a used one (review of the change)."""
    from qdrefine import report

    p = np.array([[0, 0], [1, 0], [9, 9], [0, 1], [1, 1]], float)  # point 2 unused
    mesh = qdrefine.Mesh(p, [[0, 1, 4], [0, 4, 3]], edges=np.array([[0, 1], [3, 0]]),
                         edge_tags=np.array([1, 2]))
    d = report.info(mesh)
    assert d["edge_tags"]["2"]["length"] == 1.0 and d["edge_tags"]["1"]["length"] == 1.0
    assert d["bounding_box"] == {"xmin": 0.0, "ymin": 0.0, "xmax": 1.0, "ymax": 1.0}


def test_info_says_how_many_triangles_reading_flipped(tmp_path, capsys):
    """It said "all counter-clockwise" of a file whose triangles were all clockwise (only
    the warning told; numbers review, 2026-11-27)."""
    path = tmp_path / "cw.msh"
    path.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 0 1 0\n"
                    "3 1 0 0\n4 1 1 0\n$EndNodes\n$Elements\n2\n1 2 2 1 1 1 2 3\n"
                    "2 2 2 1 1 2 4 3\n$EndElements\n")
    assert main(["info", str(path)]) == 0
    assert "orientation           all counter-clockwise (2 clockwise in the file, flipped " \
           "on reading)" in capsys.readouterr().out
    assert main(["info", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["flipped_on_reading"] == 2


TWO_GROUPS = """$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
4
1 0 0 0
2 1 0 0
3 1 1 0
4 0 1 0
$EndNodes
$Elements
4
1 2 2 20 1 1 2 3
2 2 2 20 1 1 3 4
3 2 2 30 1 1 2 3
4 2 2 30 1 1 3 4
$EndElements
"""


def test_check_reports_what_the_reader_warns(tmp_path, run):
    """The reader's warnings (a surface in two physical groups) were printed on stderr
    while the report said "0 warnings"."""
    (tmp_path / "two.msh").write_text(TWO_GROUPS)
    result = run("check", "--json", tmp_path / "two.msh")
    report = json.loads(result.stdout)
    assert result.returncode == 0 and report["warnings"] == 1, result
    assert report["problems"][0]["kind"] == "file"
    assert "given again with another physical tag" in report["problems"][0]["message"]
    assert result.stderr == ""


def test_review_of_the_command_line(tmp_path, run, monkeypatch):
    """A memory figure that stopped growing at 20 levels; a mark file's '3_0' read as 30 and
    Arabic-Indic digits as ids; Triangle files asked as T.Node written as T.node."""
    mesh = tmp_path / "p.msh"
    qdrefine.write(mesh, examples.plate_with_hole())
    figures = [run("refine", mesh, tmp_path / "o.msh", "--levels", n).stderr
               for n in (20, 40)]
    assert figures[0] != figures[1] and "more than 1e+21 GiB" in figures[1], figures
    for word in ("3_0", "\u0661\u0662", "1.5", "+-5"):
        (tmp_path / "marks.txt").write_text(f"{word}\n", encoding="utf-8")
        result = run("refine", mesh, tmp_path / "o.msh", "--mark-file", tmp_path / "marks.txt")
        assert result.returncode == 1 and "is not a triangle id" in result.stderr, result
    result = run("refine", mesh, tmp_path / "T.Node")
    assert result.returncode == 1 and "lower case" in result.stderr
    assert not list(tmp_path.glob("T.*"))


def test_afem_demo_of_one_cycle_fits_no_slope(tmp_path, run):
    """A slope of one point: NumPy's 'Polyfit may be poorly conditioned' on stderr."""
    pytest.importorskip("skfem")  # the fem extra: installed wherever the tests run
    result = run("demo", tmp_path / "af", "--afem", "--cycles", "1", "-q")
    assert result.returncode == 0 and result.stderr == "", result.stderr


def test_version():
    result = cli("--version")
    assert result.returncode == 0 and result.stdout == f"qdrefine {qdrefine.__version__}\n"


def _info_with_stdout(stdout, closed: bool = False) -> subprocess.CompletedProcess:
    """``qdrefine info`` with its standard output ``stdout`` (``closed``: none at all,
    as a shell's ``>&-`` leaves it)."""
    command = [sys.executable, "-m", "qdrefine", "info", str(DATA / "two_regions_41.msh")]
    if closed:  # a shell closes it (no preexec_fn: the test process has threads)
        command = ["sh", "-c", 'exec "$@" >&-', "sh", *command]
    process = subprocess.run(command, stdout=stdout, stderr=subprocess.PIPE, text=True,
                             timeout=300)
    return subprocess.CompletedProcess(process.args, process.returncode, None,
                                       without_compile_note(process.stderr))


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs Linux's /dev/full")
def test_a_full_standard_output_is_named():
    with open("/dev/full", "w") as full:
        result = _info_with_stdout(full)
    assert result.returncode == 1
    assert result.stderr == ("qdrefine: error: [Errno 28] No space left on device: "
                             "'standard output'\n")


def test_a_closed_pipe_is_not_an_error():  # `qdrefine info x.msh | head -1`
    read, write = os.pipe()
    os.close(read)
    try:
        result = _info_with_stdout(write)
    finally:
        os.close(write)
    assert result.returncode == 0 and result.stderr == ""


def test_a_report_to_a_closed_standard_output_is_an_error(tmp_path):
    """``qdrefine info x.msh >&-`` printed nothing and exited 0, where ``cat`` and ``ls``
    fail (review): the report is lost. A command that prints nothing runs as usual, and
    with standard error closed a command runs (it failed silently: its progress display
    asked the missing stream whether it is a terminal) and its report stays clean (its
    warnings went into the JSON)."""
    result = _info_with_stdout(None, closed=True)
    assert result.returncode == 1
    assert result.stderr == "qdrefine: error: [Errno 9] Bad file descriptor: 'standard output'\n"
    mesh = tmp_path / "m.msh"
    qdrefine.write(mesh, examples.square(2))

    def shell(line: str) -> subprocess.CompletedProcess:
        return subprocess.run(["sh", "-c", line, "sh", sys.executable, str(mesh), str(tmp_path)],
                              capture_output=True, text=True, timeout=300)

    quiet = shell('exec "$1" -m qdrefine refine "$2" "$3/q.msh" -q >&-')
    assert quiet.returncode == 0 and (tmp_path / "q.msh").exists()
    silent = shell('exec "$1" -m qdrefine refine "$2" "$3/s.msh" 2>&-')
    assert silent.returncode == 0 and (tmp_path / "s.msh").exists()
    assert silent.stdout.startswith(f"{tmp_path / 's.msh'}: 56 triangles")
    clockwise = tmp_path / "cw.msh"  # read with a warning: the triangle is flipped
    clockwise.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n"
                         "2 1 0 0\n3 0 1 0\n$EndNodes\n$Elements\n1\n1 2 2 1 1 1 3 2\n"
                         "$EndElements\n")
    warned = subprocess.run([sys.executable, "-m", "qdrefine", "info", str(clockwise),
                             "--json"], capture_output=True, text=True, timeout=300)
    assert "qdrefine: warning:" in warned.stderr  # what would have gone into the JSON
    report = subprocess.run(["sh", "-c", 'exec "$@" 2>&-', "sh", sys.executable, "-m",
                             "qdrefine", "info", str(clockwise), "--json"],
                            capture_output=True, text=True, timeout=300)
    assert report.returncode == 0 and json.loads(report.stdout)["triangles"] == 1


def test_reports_say_what_was_done(tmp_path, run):
    """Newcomer walkthrough: '--levels 0' said the triangles were refined, and the quality
    report read as if the angles equalled 1e-06 degrees."""
    mesh = tmp_path / "m.msh"
    qdrefine.write(mesh, examples.square(2))
    copied = run("refine", mesh, tmp_path / "o.msh", "--levels", "0")
    assert copied.returncode == 0 and "(8 triangles copied, 0 levels;" in copied.stdout
    report = run("quality", mesh)
    # and not as if a class's angles were all within 1e-06 degrees: touching cells chain
    # (a review counted one class spanning 140 times the tolerance)
    assert "(two smallest angles in cells of 1e-06 deg, touching cells joined)" in report.stdout


def test_check_json_has_the_same_keys_for_every_file(tmp_path, run):
    """A file without triangles gave a report without the mesh's figures, and a Gmsh file
    'numbered_from': 0 beside 'numbered_by': 'file' (review)."""
    good = tmp_path / "good.msh"
    qdrefine.write(good, examples.square(2))
    empty = tmp_path / "empty.msh"
    empty.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n1\n1 0 0 0\n"
                     "$EndNodes\n$Elements\n0\n$EndElements\n")
    row = tmp_path / "row.node"
    qdrefine.write(row, examples.square(2))
    reports = [json.loads(run("check", path, "--json").stdout) for path in (good, empty, row)]
    assert list(reports[0]) == list(reports[1]) == list(reports[2])
    assert reports[0]["numbered_by"] == "file" and reports[0]["numbered_from"] is None
    assert reports[1]["triangles"] is None and reports[1]["problems"][0]["count"] == 1
    assert reports[2]["numbered_by"] == "row" and reports[2]["numbered_from"] in (0, 1)


def test_the_guide_lists_every_option_of_every_command():
    """The guide's command table had lost options that --help shows (check --scheme,
    compare --tolerance, convert --binary ...; newcomer review)."""
    from qdrefine.cli import COMMANDS, _parser

    table = (Path(__file__).parents[1] / "docs" / "guide.md").read_text()
    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name in COMMANDS:
        rows = "\n".join(line for line in table.splitlines()
                         if line.startswith(f"| `qdrefine {name} "))
        assert rows, f"no row for {name}"
        for action in sub.choices[name]._actions:
            long = [o for o in action.option_strings if o.startswith("--")]
            if long and long[0] not in ("--help", "--quiet"):
                assert long[0] in rows, f"{name} {long[0]} is not in the guide's table"


def test_ctrl_c_while_the_commands_load_is_one_line(monkeypatch, capsys):
    """Ctrl-C while ``main`` imported the commands' modules printed a KeyboardInterrupt
    traceback (review; the guide says one line at any moment)."""
    import importlib

    def interrupted(name, *args):
        raise KeyboardInterrupt

    monkeypatch.setattr(importlib, "import_module", interrupted)
    assert main(["info", "x.msh"]) == 130
    assert capsys.readouterr().err == "qdrefine: interrupted\n"


def test_counts_of_one_are_singular(tmp_path, run):
    """"1 triangles" in the check header and the info tag lines (review)."""
    path = tmp_path / "one.msh"
    qdrefine.write(path, qdrefine.Mesh([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], cell_tags=[3],
                                       edges=[[0, 1]], edge_tags=[4]))
    assert "3 points (3 used), 1 triangle, 3 edges (3 on the boundary)" in \
        run("check", path).stdout
    info = run("info", path).stdout
    assert "3: 1 triangle, area 0.5" in info and "4: 1 edge, length 1" in info


@pytest.mark.parametrize("arguments", [["--version"], ["info", "--help"]])
def test_help_and_version_that_cannot_be_written_are_errors(arguments):
    """``qdrefine --version >&-`` and ``--help > /dev/full`` exited 0 with the text lost
    (argparse ignores write errors); a closed pipe stays no error."""
    command = [sys.executable, "-m", "qdrefine", *arguments]
    closed = subprocess.run(["sh", "-c", 'exec "$@" >&-', "sh", *command],
                            capture_output=True, text=True, timeout=300)
    assert closed.returncode == 1
    assert closed.stderr == "qdrefine: error: [Errno 9] Bad file descriptor: 'standard output'\n"
    if Path("/dev/full").exists():
        with open("/dev/full", "w") as full:
            lost = subprocess.run(command, stdout=full, stderr=subprocess.PIPE, text=True,
                                  timeout=300)
        assert lost.returncode == 1 and "No space left on device: 'standard output'" in lost.stderr
    read, write = os.pipe()
    os.close(read)
    try:
        piped = subprocess.run(command, stdout=write, stderr=subprocess.PIPE, text=True,
                               timeout=300)
    finally:
        os.close(write)
    assert piped.returncode == 0 and piped.stderr == ""
