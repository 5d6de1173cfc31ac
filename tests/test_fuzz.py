"""Fuzzing: random and mutated files and arrays fed to the readers, ``Mesh``, ``refine`` and
``main([...])``.

The only allowed outcomes are a valid result or the documented error: ``ValueError``,
``OSError`` or ``MemoryError`` whose message starts with the file name (the command line:
exit 1 and one line ``qdrefine: error: <file>...``); never another exception, a hang (each
example runs under an alarm), partial output, a stray file or a modified input.

``QDREFINE_FUZZ_EXAMPLES`` sets the examples per test (default 30, deterministic: the CI
budget); any value runs that many random examples, e.g. ``QDREFINE_FUZZ_EXAMPLES=2000``.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import tempfile
import warnings
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import qdrefine
from meshes import DATA, jittered_grid
from oracle import exact, orient
from qdrefine import Mesh, check, refine
from qdrefine.cli import main
from qdrefine.io import check_file
from qdrefine.io.meshio_formats import write_with_meshio
from qdrefine.kernels import rounding_suspects
from qdrefine.topology import conformity

_SET = os.environ.get("QDREFINE_FUZZ_EXAMPLES")
FUZZ = settings(max_examples=int(_SET) if _SET else 30, derandomize=not _SET, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
ALLOWED = (ValueError, OSError, MemoryError)
SECONDS = 20  # per example: anything slower is a hang


class Hang(BaseException):
    """Raised by :func:`alarm`: a ``BaseException``, so that no reader's ``except
    Exception`` (which turns a library's errors into one line naming the file) can take a
    hang for a refusal."""


@contextlib.contextmanager
def alarm(seconds: int = SECONDS):
    """Fail instead of hanging (Python-level code only; compiled kernels are bounded)."""
    def hang(signum, frame):
        raise Hang(f"no answer within {seconds} s")

    old = signal.signal(signal.SIGALRM, hang)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


# seed files --------------------------------------------------------------------------------

def _seeds() -> dict[str, dict[str, bytes]]:
    """Valid files of every readable kind: name -> {file name: bytes}."""
    mesh = jittered_grid(3, seed=2)
    plain = Mesh(mesh.points, mesh.triangles)
    out: dict[str, dict[str, bytes]] = {
        "msh41": {"m.msh": (DATA / "two_regions_41.msh").read_bytes()},
        "msh22": {"m.msh": (DATA / "two_regions_22.msh").read_bytes()},
    }
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, ext, m, binary in (("msh22-binary", ".msh", mesh, True),
                                     ("vtk", ".vtk", mesh, False), ("vtu", ".vtu", mesh, False),
                                     ("xdmf", ".xdmf", mesh, None), ("medit", ".mesh", mesh, None),
                                     ("off", ".off", plain, None), ("obj", ".obj", plain, None),
                                     ("stl", ".stl", plain, False), ("ply", ".ply", plain, False),
                                     ("triangle", ".ele", mesh, None)):
            if name == "vtu":  # a text VTU (meshio's; qdrefine writes binary only)
                write_with_meshio(Path(tmp) / "m.vtu", m, "vtu", tags=True, data=True,
                                  binary=False)
            else:
                qdrefine.write(Path(tmp) / f"m{ext}", m, binary=binary)
            out[name] = {p.name: p.read_bytes() for p in Path(tmp).iterdir()}
            for p in Path(tmp).iterdir():
                p.unlink()
    return out


SEEDS = _seeds()
MAIN = {"msh41": "m.msh", "msh22": "m.msh", "msh22-binary": "m.msh", "vtk": "m.vtk",
        "vtu": "m.vtu", "xdmf": "m.xdmf", "medit": "m.mesh", "off": "m.off", "obj": "m.obj",
        "stl": "m.stl", "ply": "m.ply", "triangle": "m.ele"}
TOKENS = [b"nan", b"inf", b"-1", b"0", b"1e308", b"99999999", b"1.5", b"", b"x", b"-0",
          b"4294967296", b"3"]


@st.composite
def mutation(draw) -> tuple[str, int, int, bytes]:
    kind = draw(st.sampled_from(["flip", "truncate", "delete-line", "duplicate-line",
                                 "token", "insert"]))
    return (kind, draw(st.integers(0, 2**31)), draw(st.integers(0, 255)),
            draw(st.sampled_from(TOKENS)))


def mutate(data: bytes, ops: list[tuple[str, int, int, bytes]]) -> bytes:
    for kind, pos, byte, token in ops:
        if not data:
            break
        i = pos % len(data)
        lines = data.split(b"\n")
        j = pos % len(lines)
        if kind == "flip":
            data = data[:i] + bytes([byte]) + data[i + 1:]
        elif kind == "truncate":
            data = data[:i]
        elif kind == "delete-line":
            data = b"\n".join(lines[:j] + lines[j + 1:])
        elif kind == "duplicate-line":
            data = b"\n".join(lines[:j + 1] + lines[j:])
        elif kind == "insert":
            data = data[:i] + bytes([byte]) * (1 + byte % 7) + data[i:]
        else:  # replace the k-th number-like token of a line with another token
            words = lines[j].split(b" ")
            k = byte % len(words)
            words[k] = token
            lines[j] = b" ".join(words)
            data = b"\n".join(lines)
    return data


@st.composite
def mutated_files(draw) -> tuple[str, dict[str, bytes]]:
    seed = draw(st.sampled_from(sorted(SEEDS)))
    files = dict(SEEDS[seed])
    target = draw(st.sampled_from(sorted(files)))
    ops = draw(st.lists(mutation(), min_size=1, max_size=3))
    files[target] = mutate(files[target], ops)
    return MAIN[seed], files


def _write(folder: Path, files: dict[str, bytes]) -> dict[str, bytes]:
    for name, data in files.items():
        (folder / name).write_bytes(data)
    return {p.name: p.read_bytes() for p in folder.iterdir()}


def _assert_valid(mesh: Mesh) -> None:
    found = check.find(mesh.points, mesh.triangles, mesh.cell_tags, mesh.edges, mesh.edge_tags)
    assert found.ok, found.errors
    assert conformity(mesh).ok


def names_file(message: str, path: Path) -> bool:
    """Whether ``message`` starts by naming ``path`` or a file of its set, or a file of its
    folder that it says is ``path``'s (an XDMF file's heavy data: "``d/x.h5``: no such file
    (the heavy data of m.xdmf)")."""
    return message.startswith(str(path.with_suffix(""))) or (
        message.startswith(str(path.parent)) and f"of {path.name}" in message)


# readers -----------------------------------------------------------------------------------

def _damaged(seed: str, name: str, ops) -> tuple[str, dict[str, bytes]]:
    files = dict(SEEDS[seed])
    files[name] = mutate(files[name], ops)
    return MAIN[seed], files


@FUZZ
@given(mutated_files())
# a damaged HDF5 file beside a stamped XDMF file (the long fuzzing run of 2026-11-26 found
# these three tracebacks in the set-stamp check)
@example(_damaged("xdmf", "m.h5", [("insert", 365750841, 41, b"inf")]))
@example(_damaged("xdmf", "m.h5", [("delete-line", 1770643436, 246, b"3"),
                                   ("token", 453441746, 194, b"4294967296"),
                                   ("duplicate-line", 876567150, 17, b"1.5")]))
@example(_damaged("xdmf", "m.h5", [("token", 679292338, 18, b"99999999"),
                                   ("flip", 1534469675, 117, b"4294967296"),
                                   ("duplicate-line", 2012030906, 28, b"0")]))
def test_readers_on_mutated_files(case):
    main_name, files = case
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        before = _write(folder, files)
        path = folder / main_name
        with alarm(), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                mesh = qdrefine.read(path)
            except ALLOWED as exc:
                assert names_file(str(exc), path), exc
                mesh = None
            try:
                _, found = check_file(path)
            except ALLOWED as exc:
                assert names_file(str(exc), path), exc
                assert mesh is None  # what check cannot read, read cannot either
                found = None
        if mesh is not None:
            _assert_valid(mesh)
        if found is not None:  # read succeeds exactly when check finds no error
            assert found.ok == (mesh is not None), found.errors
            assert all(names_file(p.message, path) for p in found.problems)
        assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


@FUZZ
@given(st.binary(max_size=600), st.sampled_from(sorted(qdrefine.io.FORMATS)))
def test_readers_on_random_bytes(data, ext):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"r{ext}"
        for e in (".node", ".ele", ".poly") if ext in (".node", ".ele", ".poly") else (ext,):
            path.with_suffix(e).write_bytes(data)
        with alarm(), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                _assert_valid(qdrefine.read(path))
            except ALLOWED as exc:
                assert names_file(str(exc), path), exc


# the command line --------------------------------------------------------------------------

@FUZZ
@given(mutated_files(), st.sampled_from(["out.vtu", "out.msh"]))
def test_main_on_mutated_files(case, out_name):
    main_name, files = case
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        before = _write(folder, files)
        path, out = folder / main_name, folder / out_name
        for argv in (["refine", str(path), str(out), "-q"], ["check", str(path)]):
            stdout, stderr = io.StringIO(), io.StringIO()
            with alarm(), contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
                code = main(argv)
            err = [x for x in stderr.getvalue().splitlines()
                   if not x.startswith("qdrefine: warning: ")]
            assert code in (0, 1), (code, stderr.getvalue())
            if code == 1 and argv[0] == "refine" or err:
                assert len(err) == 1 and err[0].startswith(f"qdrefine: error: "
                                                           f"{path.with_suffix('')}"), err
            if argv[0] == "check" and code == 1 and not err:
                assert "NOT usable" in stdout.getvalue()
            if argv[0] == "refine":
                assert out.exists() == (code == 0)
                if code == 0:
                    _assert_valid(qdrefine.read(out))
                    out.unlink()
        assert {p.name: p.read_bytes() for p in folder.iterdir()} == before


# arrays ------------------------------------------------------------------------------------

COORD = st.one_of(st.integers(-3, 3).map(float), st.floats(allow_nan=True, allow_infinity=True),
                  st.sampled_from([0.5, 1e-120, 1e120, -0.0]))


@st.composite
def raw_arrays(draw) -> tuple[np.ndarray, np.ndarray]:
    n = draw(st.integers(0, 8))
    points = np.array(draw(st.lists(st.tuples(COORD, COORD), min_size=n, max_size=n)),
                      dtype=float).reshape(-1, 2)
    m = draw(st.integers(0, 8))
    tris = np.array(draw(st.lists(st.tuples(*[st.integers(-1, n)] * 3), min_size=m,
                                  max_size=m)), dtype=np.int64).reshape(-1, 3)
    return points, tris


def _overlap(p: np.ndarray, t: np.ndarray) -> bool:
    """Do the interiors of two triangles intersect? (all pairs, rational arithmetic: two
    convex triangles are disjoint iff a side of one has the other on its outer side)"""
    q = [exact(x) for x in p]
    tris = [[q[v] for v in tri] for tri in t.tolist()]

    def separated(s, u):
        return any(all(orient(s[i], s[(i + 1) % 3], c) <= 0 for c in u) for i in range(3))

    return any(not separated(s, u) and not separated(u, s)
               for k, s in enumerate(tris) for u in tris[k + 1:])


def _refined_ok(mesh: Mesh) -> None:
    """Refinement works and its output passes every check: ``Mesh`` refuses overlapping
    triangles (the all-pairs oracle confirms that none got through)."""
    assert not _overlap(mesh.points, mesh.triangles)
    try:
        fine = refine(mesh, "7t-qd")
    except ValueError as exc:  # documented: a triangle too thin for float64 children
        assert "is too thin for its distance from the origin" in str(exc)
        assert rounding_suspects(mesh.points, mesh.triangles, 3).any()
        return
    assert fine.n_triangles == 7 * mesh.n_triangles
    _assert_valid(Mesh(fine.points, fine.triangles))


@FUZZ
@given(raw_arrays())
def test_mesh_and_refine_on_random_arrays(arrays):
    points, tris = arrays
    try:
        mesh = Mesh(points, tris)
    except ValueError as exc:
        assert str(exc)  # one clear message
        assert not check.find(points, tris).ok
        return
    assert check.find(points, tris).ok
    _refined_ok(mesh)


@st.composite
def broken_grids(draw) -> tuple[np.ndarray, np.ndarray]:
    """A valid jittered grid with one to three local mutations of its arrays."""
    mesh = jittered_grid(draw(st.integers(1, 4)), seed=draw(st.integers(0, 99)))
    p, t = np.array(mesh.points), np.array(mesh.triangles, dtype=np.int64)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["copy-point", "midpoint", "swap", "index", "drop",
                                     "repeat", "nan", "new-point"]))
        if len(t) == 0:
            break
        i, j = draw(st.integers(0, len(t) - 1)), draw(st.integers(0, 2))
        a, b = t[i, j], t[i, (j + 1) % 3]
        if not (0 <= a < len(p) and 0 <= b < len(p)):
            continue
        if kind == "copy-point":  # a triangle uses a copy of its vertex
            p = np.vstack([p, p[a]])
            t[i, j] = len(p) - 1
        elif kind == "midpoint":  # a new point in the middle of an edge: hanging or folded
            p = np.vstack([p, (p[a] + p[b]) / 2])
            t = np.vstack([t, [a, len(p) - 1, t[i, (j + 2) % 3]]])
        elif kind == "swap":
            t[i, [0, 1]] = t[i, [1, 0]]
        elif kind == "index":
            t[i, j] = draw(st.integers(-2, len(p) + 2))
        elif kind == "drop":
            t = np.delete(t, i, axis=0)
        elif kind == "repeat":
            t = np.vstack([t, t[i]])
        elif kind == "nan":
            p[a, 0] = np.nan
        else:
            p = np.vstack([p, draw(st.tuples(COORD, COORD))])
    return p, t


@FUZZ
@given(broken_grids())
def test_mesh_and_refine_on_broken_grids(arrays):
    points, tris = arrays
    found = check.find(points, tris)
    try:
        mesh = Mesh(points, tris)
    except ValueError as exc:
        assert not found.ok and str(exc) == found.errors[0].message
        return
    assert found.ok
    _refined_ok(mesh)
