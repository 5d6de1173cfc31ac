"""``qdrefine refine`` with marks (--mark-tag, --mark-box, --mark-file, --cycles), in-process
through ``qdrefine.cli.main``, compared with the Python API."""

import os
import re
from pathlib import Path

import numpy as np
import pytest

import qdrefine
from meshes import DATA
from qdrefine.adaptive import refine_marked
from qdrefine.marking import mark_box, mark_tag
from qdrefine.quality import areas
from qdrefine.topology import conformity

SRC = DATA / "two_regions_22.msh"




def api(mesh, mark, cycles=1, scheme="7t-qd"):
    """What the command should do: ``mark(mesh, parents)`` then :func:`refine_marked`
    (the mesh carries its history); returns the mesh and the number of marked triangles."""
    parents = np.arange(mesh.n_triangles)
    total = 0
    for _ in range(cycles):
        marked = mark(mesh, parents)
        total += int(marked.sum())
        mesh, step = refine_marked(mesh, marked, scheme)
        parents = parents[step]
    return mesh, total


def summary(stdout):
    """``(triangles, marked, added, cycles)`` from the summary line."""
    m = re.fullmatch(r"\S+: (\d+) triangles, \d+ points \((\d+) triangles? marked, (\d+) "
                     r"added by 7t-qd in (\d+) cycles?; read [\d.]+ s, refined [\d.]+ s, "
                     r"written [\d.]+ s\)\n", stdout)
    assert m, stdout
    return tuple(int(g) for g in m.groups())


def same_mesh(a, b):
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.triangles, b.triangles)
    np.testing.assert_array_equal(a.cell_tags, b.cell_tags)
    np.testing.assert_array_equal(a.edges, b.edges)
    np.testing.assert_array_equal(a.edge_tags, b.edge_tags)


def test_mark_tag_refines_that_region_and_keeps_every_tag(tmp_path, run):
    out = tmp_path / "fine.msh"
    result = run("refine", SRC, out, "--mark-tag", "2", "--cycles", "2")
    assert result.returncode == 0, result.stderr
    coarse, fine = qdrefine.read(SRC), qdrefine.read(out)
    expected, marked = api(coarse, lambda m, _: mark_tag(m, 2), cycles=2)
    same_mesh(fine, qdrefine.read(_roundtrip(tmp_path, expected)))
    assert summary(result.stdout) == (fine.n_triangles, marked,
                                      fine.n_triangles - coarse.n_triangles, 2)
    assert conformity(fine).ok
    for tag in (1, 2):
        assert areas(fine)[fine.cell_tags == tag].sum() == pytest.approx(
            areas(coarse)[coarse.cell_tags == tag].sum(), rel=1e-13)
    # region 2 is refined twice everywhere: 49 times as many triangles at least
    assert (fine.cell_tags == 2).sum() >= 49 * (coarse.cell_tags == 2).sum()
    assert sorted(set(fine.edge_tags.tolist())) == sorted(set(coarse.edge_tags.tolist()))


def _roundtrip(tmp_path, mesh):
    path = tmp_path / "expected.msh"
    qdrefine.write(path, mesh)
    return path


def test_mark_box_is_evaluated_on_each_cycle(tmp_path, run):
    out = tmp_path / "fine.vtu"
    box = (0.0, 0.0, 0.1, 0.1)
    result = run("refine", SRC, out, "--mark-box", "0,0,0.1,0.1", "--cycles", "3", "--quiet")
    assert result.returncode == 0, result.stderr
    assert result.stdout == ""
    coarse, fine = qdrefine.read(SRC), qdrefine.read(out)
    expected, _ = api(coarse, lambda m, _: mark_box(m, box), cycles=3)
    np.testing.assert_array_equal(fine.triangles, expected.triangles)
    # refined three times at the corner: areas there at least 3^3 times smaller (a 7T
    # child holds at most a third of its parent's area)
    near = mark_box(fine, box)
    assert areas(fine)[near].max() <= areas(coarse)[mark_box(coarse, box)].min() / 27
    assert conformity(fine).ok


def test_mark_file_text_and_npy_agree(tmp_path, run):
    coarse = qdrefine.read(SRC)
    ids = [3, 17, 40, 41]
    (tmp_path / "ids.txt").write_text("# triangles to refine\n3 17\n\n40\t41  # last two\n")
    np.save(tmp_path / "ids.npy", np.array(ids))
    mask = np.zeros(coarse.n_triangles, bool)
    mask[ids] = True
    np.save(tmp_path / "mask.npy", mask)
    outs = []
    for name in ("ids.txt", "ids.npy", "mask.npy"):
        out = tmp_path / f"{name}.msh"
        result = run("refine", SRC, out, "--mark-file", tmp_path / name)
        assert result.returncode == 0, result.stderr
        assert summary(result.stdout)[1:] == (4, qdrefine.read(out).n_triangles
                                              - coarse.n_triangles, 1)
        outs.append(qdrefine.read(out))
    same_mesh(outs[0], outs[1])
    same_mesh(outs[0], outs[2])
    expected, _ = api(coarse, lambda m, _: mask)
    same_mesh(outs[0], qdrefine.read(_roundtrip(tmp_path, expected)))


def test_mark_file_cycles_refine_inside_the_listed_triangles_again(tmp_path, run):
    coarse = qdrefine.read(SRC)
    (tmp_path / "ids.txt").write_text("5\n")
    out = tmp_path / "fine.msh"
    result = run("refine", SRC, out, "--mark-file", tmp_path / "ids.txt", "--cycles", "2")
    assert result.returncode == 0, result.stderr
    fine = qdrefine.read(out)
    mask = np.zeros(coarse.n_triangles, bool)
    mask[5] = True
    expected, marked = api(coarse, lambda m, parents: mask[parents], cycles=2)
    same_mesh(fine, qdrefine.read(_roundtrip(tmp_path, expected)))
    assert marked == 1 + 7  # the triangle, then its seven children
    assert summary(result.stdout)[1] == marked


def test_uniform_refinement_is_unchanged(tmp_path, run):
    out = tmp_path / "u.msh"
    result = run("refine", SRC, out, "--levels", "1")
    assert result.returncode == 0, result.stderr
    assert "triangles refined by 7t-qd, 1 level; read " in result.stdout
    assert qdrefine.read(out).n_triangles == 7 * qdrefine.read(SRC).n_triangles


@pytest.mark.parametrize("extra, code, message", [
    (["--mark-box", "1,2,3"], 2, "expected four numbers x0,y0,x1,y1; got '1,2,3'"),
    (["--mark-box", "a,b,c,d"], 2, "expected four numbers"),
    (["--mark-box", "1,1,0,0"], 2, "expected x0 <= x1 and y0 <= y1"),
    (["--mark-box", "5,5,6,6"], 1, "the box 5.0,5.0,6.0,6.0 meets no triangle"),
    (["--mark-tag", "99"], 1, "no triangle has cell tag 99 (cell tags: 1, 2)"),
    (["--mark-tag", "one"], 2, "expected integer cell tags"),
    (["--mark-file", "{tmp}/range.txt"], 1, "range.txt, line 2: triangle id 9999 is outside"),
    (["--mark-file", "{tmp}/word.txt"], 1, "word.txt, line 1: 'x7' is not a triangle id"),
    (["--mark-file", "{tmp}/missing.txt"], 1, "missing.txt: no such file"),
    (["--mark-file", "{tmp}/short.npy"], 1, "short.npy: a boolean mask needs shape"),
    (["--mark-file", "{tmp}/neg.npy"], 1, "neg.npy, entry 1: triangle id -2 is outside"),
    # an empty list wrote the input unchanged (review, 2026-11-27)
    (["--mark-file", "{tmp}/empty.txt"], 1, "empty.txt: lists no triangle"),
    (["--mark-file", "{tmp}/none.npy"], 1, "none.npy: lists no triangle"),
    # a directory was "no such file", a text file named .npy got NumPy's pickle advice,
    # a FIFO would have waited for a writer (review, 2026-11-27)
    (["--mark-file", "{tmp}/dir"], 1, "dir: is a directory, not a file of triangle ids"),
    (["--mark-file", "{tmp}/text.npy"], 1, "text.npy: not a .npy file (no NumPy header)"),
    (["--mark-file", "{tmp}/fifo"], 1, "fifo: not a regular file"),
    (["--mark-file", "{tmp}/carried.txt"], 1, "has a cell data field named "
                                              "'qdrefine:mark-file'"),
    (["--mark-tag", "1", "--mark-box", "0,0,1,1"], 2, "not allowed with argument"),
    # options that do not go together: exit 2 and the --help hint, as argparse's (review)
    (["--cycles", "2"], 2, "--cycles needs a mark: --mark-tag, --mark-box or --mark-file "
                           "(see 'qdrefine refine --help')"),
    (["--mark-tag", "1", "--levels", "2"], 2, "with a mark use --cycles (see 'qdrefine refine "
                                              "--help')"),
    (["--mark-tag", "1", "--cycles", "-1"], 2, "expected a number >= 0"),
])
def test_bad_marks_give_one_line_and_no_output(tmp_path, extra, code, message, run):
    (tmp_path / "range.txt").write_text("1 2\n9999\n")
    (tmp_path / "word.txt").write_text("1 x7\n")
    np.save(tmp_path / "short.npy", np.ones(3, bool))
    np.save(tmp_path / "neg.npy", np.array([0, -2]))
    (tmp_path / "empty.txt").write_text("# nothing marked\n")
    np.save(tmp_path / "none.npy", np.zeros(qdrefine.read(SRC).n_triangles, bool))
    (tmp_path / "dir").mkdir()
    (tmp_path / "text.npy").write_text("1 2\n")
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "carried.txt").write_text("1 2\n")
    src = SRC
    if "carried" in extra[-1]:  # the field that carries the marks is not the user's
        mesh = qdrefine.read(SRC)
        src = tmp_path / "carried.vtu"
        qdrefine.write(src, mesh.replace(cell_data={"qdrefine:mark-file": np.zeros(
            mesh.n_triangles)}))
    out = tmp_path / "out.msh"
    result = run("refine", src, out, *[a.format(tmp=tmp_path) for a in extra])
    assert result.returncode == code, result.stderr
    assert result.stderr.startswith("qdrefine: error: "), result.stderr
    assert message in result.stderr and result.stderr.count("\n") == 1, result.stderr
    assert result.stdout == "" and not out.exists()
    if extra[0] == "--mark-file" and "carried" not in extra[-1]:  # named by the mark file
        # only (review: "in.msh: range.txt, line 2: ..." when the refinement read it)
        assert result.stderr.startswith(f"qdrefine: error: {extra[-1].format(tmp=tmp_path)}")
        # spelled otherwise, as Path spells it in the message (review)
        other = extra[-1].format(tmp=f"{tmp_path}/.//")
        again = run("refine", src, out, "--mark-file", other)
        assert again.stderr.startswith((f"qdrefine: error: {Path(other)}",
                                        f"qdrefine: error: {other}")), again.stderr


def test_negative_box_and_any_case_scheme_names(tmp_path):
    """``--mark-box -1,...`` needs no ``=``; scheme names are case-insensitive."""
    from qdrefine.cli import main

    src = tmp_path / "in.msh"
    qdrefine.write(src, qdrefine.examples.plate_with_hole())
    out = tmp_path / "out.msh"
    assert main(["refine", str(src), str(out), "--scheme", "7T-QD", "--mark-box",
                 "-1,-1,-0.5,-0.5", "-q"]) == 0
    expected = qdrefine.refine(qdrefine.read(src), "7t-qd",
                               marked=mark_box(qdrefine.read(src), (-1, -1, -0.5, -0.5)))
    same_mesh(qdrefine.read(out), expected)
    # abbreviated as argparse allows ("expected one argument" before; review)
    assert main(["refine", str(src), str(tmp_path / "ab.msh"), "--mark-b", "-1,-1,-0.5,-0.5",
                 "-q"]) == 0
    same_mesh(qdrefine.read(tmp_path / "ab.msh"), expected)


def test_coarsen_undoes_refine(tmp_path, run):
    """``qdrefine coarsen --all --cycles K`` after ``qdrefine refine --mark-box --cycles
    3``: the input again (points, triangles, tags); a box coarsens as the API does."""
    fine = tmp_path / "fine.msh"
    assert run("refine", SRC, fine, "--mark-box", "0,0,0.3,0.3", "--cycles", "3",
               "--quiet").returncode == 0
    back = tmp_path / "back.msh"
    result = run("coarsen", fine, back, "--all", "--cycles", "5")
    assert result.returncode == 0, result.stderr
    assert re.search(r"back\.msh: \d+ triangles, \d+ points \(\d+ fewer by 7t-qd in 5 "
                     r"cycles, [\d.]+ s in all\)", result.stdout)
    coarse, again = qdrefine.read(SRC), qdrefine.read(back)
    np.testing.assert_array_equal(again.points, coarse.points)
    np.testing.assert_array_equal(np.sort(again.triangles, axis=1),
                                  np.sort(coarse.triangles, axis=1))
    np.testing.assert_array_equal(again.cell_tags, coarse.cell_tags)
    half = tmp_path / "half.vtu"
    assert run("coarsen", fine, half, "--mark-box", "0,0,0.1,0.3", "--quiet").returncode == 0
    expected = qdrefine.coarsen(qdrefine.read(fine), mark_box(qdrefine.read(fine),
                                                              (0, 0, 0.1, 0.3)))
    np.testing.assert_array_equal(qdrefine.read(half).triangles, expected.triangles)


def test_coarsen_needs_the_history(tmp_path, run):
    out = tmp_path / "out.msh"
    result = run("coarsen", SRC, out, "--all")
    assert result.returncode == 1
    assert result.stderr.startswith(f"qdrefine: error: {SRC}: no refinement history")
    assert result.stderr.count("\n") == 1 and not out.exists()
    result = run("coarsen", SRC, out)
    assert result.returncode == 2 and "--all is required" in result.stderr
    # another scheme than the mesh was made with: transitions that do not fit, or nothing
    fine = tmp_path / "fine.msh"
    assert run("refine", SRC, fine, "--mark-box", "0,0,0.3,0.3", "--quiet").returncode == 0
    result = run("coarsen", fine, out, "--all", "--scheme", "4t-red")
    assert result.returncode == 1 and result.stderr.startswith(
        f"qdrefine: error: {fine}: its refinement history (cell data qdrefine:transitions) "
        "does not fit scheme 4t-red: ") and result.stderr.count("\n") == 1
    assert "mesh.replace" not in result.stderr  # the command line's terms, not Python's
    result = run("refine", fine, out, "--mark-box", "0,0,0.3,0.3", "--scheme", "4t-le")
    assert result.returncode == 1 and "does not fit scheme 4t-le" in result.stderr
    assert run("refine", SRC, fine, "--mark-box", "0,0,2,1", "--quiet").returncode == 0
    result = run("coarsen", fine, out, "--all", "--scheme", "4t-red")
    assert result.returncode == 0 and "no partition of" in result.stderr


def test_coarsen_says_why_nothing_changed(tmp_path, run):
    """The note names the cause: marks that cover no whole partition, or another scheme
    (it used to ask "was it refined with 7t-qd?" of a mesh that was)."""
    out = tmp_path / "out.msh"
    fine = tmp_path / "fine.msh"
    assert run("refine", SRC, fine, "--mark-box", "0,0,1,1", "--quiet").returncode == 0
    some = tmp_path / "one.txt"
    some.write_text("0\n")  # one child of a partition: nothing can go
    result = run("coarsen", fine, out, "--mark-file", some)
    assert result.returncode == 0 and result.stderr == (
        f"qdrefine: note: no partition of {fine} had all its children marked (one is undone "
        "only when every child is)\n")
    quad = tmp_path / "quad.msh"
    mesh = qdrefine.read(SRC)
    qdrefine.write(quad, qdrefine.refine(mesh, "4t-le", marked=np.ones(mesh.n_triangles, bool)))
    result = run("coarsen", quad, out, "--all")
    assert result.returncode == 0 and result.stderr == (
        f"qdrefine: note: no partition of {quad} is a 7t-qd partition, but some are 4t-le "
        "partitions: was it refined with 4t-le? (see --scheme)\n")


def test_a_users_field_named_like_the_carried_marks_stays_without_mark_file(tmp_path, run):
    """The field that carries --mark-file's marks was removed after every local refinement
    and coarsening, a user's field of that name too (review): only --mark-file, which
    refuses such an input, removes it."""
    mesh = qdrefine.read(SRC)
    values = np.arange(mesh.n_triangles, dtype=float)
    qdrefine.write(tmp_path / "in.vtu", mesh.replace(cell_data={"qdrefine:mark-file": values}))
    result = run("refine", tmp_path / "in.vtu", tmp_path / "out.vtu", "--mark-box", "0,0,1,1",
                 "-q")
    assert result.returncode == 0, result.stderr
    assert "qdrefine:mark-file" in qdrefine.read(tmp_path / "out.vtu").cell_data
