"""The chunked mesh store: round trips, lazy opening, conversions from/to files, bad stores."""

import json
import os
import stat
import warnings
from pathlib import Path

import numpy as np
import pytest
import zarr
from hypothesis import given, settings
from hypothesis import strategies as st

import qdrefine
from meshes import jittered_grid
from qdrefine import Mesh, examples, io, store
from qdrefine.cli import main
from qdrefine.store import export

FIELDS = ("points", "triangles", "cell_tags", "edges", "edge_tags")


def same_mesh(a: Mesh, b: Mesh) -> None:
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert x.dtype == y.dtype, name
            np.testing.assert_array_equal(x, y, err_msg=name)


@settings(max_examples=20, deadline=None)
@given(n=st.integers(1, 6), seed=st.integers(0, 10**6), chunk=st.integers(1, 80),
       tags=st.booleans())
def test_create_open_to_mesh_round_trip(tmp_path_factory, n, seed, chunk, tags):
    mesh = jittered_grid(n, seed)
    if not tags:
        mesh = Mesh(mesh.points, mesh.triangles)
    path = tmp_path_factory.mktemp("s") / "m.zarr"
    s = store.create(path, mesh, chunk_size=chunk)
    assert (s.n_points, s.n_triangles) == (mesh.n_points, mesh.n_triangles)
    assert s.n_edges == (0 if mesh.edges is None else len(mesh.edges))
    assert all(c <= chunk for c in s.triangles.chunks[0]) and s.triangles.chunks[0][0] == min(
        chunk, mesh.n_triangles)
    same_mesh(mesh, store.to_mesh(path))
    same_mesh(mesh, s.to_mesh())


def test_open_is_lazy_and_keeps_metadata(tmp_path):
    mesh = examples.plate_with_hole()
    store.create(tmp_path / "p.zarr", mesh, chunk_size=100, metadata={"case": "plate"})
    s = store.open(tmp_path / "p.zarr")
    assert s.triangles.chunks[0] == (100, 100, 100, 84)
    assert s.points.dtype == np.float64 and s.cell_tags.dtype == np.int64
    assert s.metadata == {"case": "plate"}
    assert s.chunk_size == 100
    np.testing.assert_array_equal(s.triangles[250:260].compute(), mesh.triangles[250:260])
    assert "384 triangles" in repr(s)


def test_existing_store_is_replaced_and_permissions_are_normal(tmp_path):
    path = tmp_path / "m.zarr"
    store.create(path, jittered_grid(3, 1))
    store.create(path, examples.square(2))
    same_mesh(examples.square(2), store.to_mesh(path))
    assert [p.name for p in tmp_path.iterdir()] == ["m.zarr"]  # no temporary left
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o777 & ~umask


def test_create_refuses_to_replace_what_is_not_a_store(tmp_path):
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "keep.txt").write_text("mine")
    with pytest.raises(FileExistsError, match="not a qdrefine mesh store"):
        store.create(tmp_path / "data", examples.square(2))
    assert (tmp_path / "data" / "keep.txt").read_text() == "mine"
    with pytest.raises(FileNotFoundError, match="does not exist"):
        store.create(tmp_path / "nowhere" / "m.zarr", examples.square(2))
    with pytest.raises(ValueError, match="chunk_size must be a positive integer"):
        store.create(tmp_path / "m.zarr", examples.square(2), chunk_size=0)
    with pytest.raises(TypeError, match="needs a Mesh"):
        store.create(tmp_path / "m.zarr", np.zeros((3, 2)))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data"]


@pytest.mark.parametrize("ext", list(io.FORMATS))
def test_from_file_and_to_file_for_every_format(tmp_path, ext):
    mesh = jittered_grid(5, seed=2)  # shuffled, cell tags 0/1, edge tags 1..4
    tagged = io.FORMATS[ext].tags
    if not tagged:
        mesh = Mesh(mesh.points, mesh.triangles)
    qdrefine.write(tmp_path / f"in{ext}", mesh)
    s = store.from_file(tmp_path / f"in{ext}", tmp_path / "m.zarr", chunk_size=7)
    assert s.metadata["source"] == str(tmp_path / f"in{ext}")
    expected = qdrefine.read(tmp_path / f"in{ext}")
    same_mesh(expected, store.to_mesh(s))
    store.to_file(s, tmp_path / f"out{ext}")
    back = qdrefine.read(tmp_path / f"out{ext}")
    if ext == ".stl":  # float32 coordinates and merged points: compare the sizes only
        assert back.n_triangles == expected.n_triangles
    else:
        same_mesh(expected, back)


@pytest.mark.parametrize("name,binary,version", [
    ("m.msh", False, None), ("m.msh", True, None), ("m.msh", False, "2.2"),
    ("m.msh", True, "2.2"), ("m.node", None, None), ("m.ele", None, None),
    ("m.poly", None, None)])
def test_streaming_export_reads_chunks_and_equals_write(tmp_path, monkeypatch, name, binary,
                                                        version):
    """Gmsh (4.1 by default, 2.2 on request) and Triangle files from a store, chunk by
    chunk: the very bytes ``qdrefine.write`` writes for the whole mesh."""
    mesh = jittered_grid(6, seed=4)
    assert mesh.cell_tags is not None and len(np.unique(mesh.cell_tags)) > 1
    s = store.create(tmp_path / "m.zarr", mesh, chunk_size=5)
    reads = []
    original = export.rows

    def counting(s_, array, step=None):
        for start, rows in original(s_, array, step):
            reads.append(len(rows))
            yield start, rows

    monkeypatch.setattr(export, "to_mesh", lambda *a: pytest.fail("loaded the whole mesh"))
    monkeypatch.setattr(export, "rows", counting)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        store.to_file(s, tmp_path / name, binary=binary, format_version=version)
    assert max(reads) == 5
    same_mesh(mesh, qdrefine.read(tmp_path / name))
    monkeypatch.undo()
    if name.endswith(".msh"):
        qdrefine.write(tmp_path / "ref.msh", mesh, binary=binary, format_version=version)
        assert (tmp_path / name).read_bytes() == (tmp_path / "ref.msh").read_bytes()
    else:
        qdrefine.write(tmp_path / "ref.node", mesh)
        for ext in (".node", ".ele", ".poly"):
            ours = (tmp_path / "m").with_suffix(ext).read_bytes()
            assert ours == (tmp_path / "ref").with_suffix(ext).read_bytes()


def test_streaming_export_of_an_untagged_mesh_and_tag_zero(tmp_path):
    mesh = Mesh([[0, 0], [1, 0], [0, 1], [1, 1]], [[0, 1, 2], [1, 3, 2]])
    store.to_file(store.create(tmp_path / "a.zarr", mesh), tmp_path / "a.msh", binary=True)
    same_mesh(mesh, qdrefine.read(tmp_path / "a.msh"))
    zero = Mesh(mesh.points, mesh.triangles, edges=[[0, 1]], edge_tags=[0])
    with pytest.warns(UserWarning, match="tag 0"):
        store.to_file(store.create(tmp_path / "b.zarr", zero), tmp_path / "b.node")
    with pytest.raises(ValueError, match="no binary variant"):
        store.to_file(tmp_path / "b.zarr", tmp_path / "b.node", binary=True)


# bad stores ---------------------------------------------------------------------------------


def _raw(path: Path, arrays: dict, version=2) -> Path:
    """A Zarr group written without qdrefine's checks."""
    group = zarr.create_group(store=str(path), attributes={
        "qdrefine": {"format": "mesh", "version": version, "complete": True, "metadata": {}}})
    for name, value in arrays.items():
        group.create_array(name, data=np.asarray(value))
    return path


GOOD = {"points": np.array([[0.0, 0], [1, 0], [0, 1]]), "triangles": np.array([[0, 1, 2]])}


def test_open_names_what_is_wrong(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such mesh store"):
        store.open(tmp_path / "missing.zarr")
    (tmp_path / "plain").mkdir()
    with pytest.raises(ValueError, match="plain: not a mesh store"):
        store.open(tmp_path / "plain")
    (tmp_path / "file.zarr").write_text("x")
    with pytest.raises(ValueError, match="file.zarr: not a mesh store"):
        store.open(tmp_path / "file.zarr")
    zarr.create_group(store=str(tmp_path / "other.zarr"))
    with pytest.raises(ValueError, match="without the 'qdrefine' attribute"):
        store.open(tmp_path / "other.zarr")
    with pytest.raises(ValueError, match="version 9 is not supported"):
        store.open(_raw(tmp_path / "v9.zarr", GOOD, version=9))
    assert not store.is_store(tmp_path / "plain") and store.is_store(_raw(tmp_path / "ok.zarr",
                                                                          GOOD))


@pytest.mark.parametrize("change,message", [
    ({"triangles": None}, "no 'triangles' array"),
    ({"points": np.zeros((3, 3))}, "'points' has shape \\(3, 3\\)"),
    ({"points": np.zeros((3, 2), dtype=np.float32)}, "'points' has dtype float32"),
    ({"triangles": np.array([[0.0, 1, 2]])}, "'triangles' has dtype float64"),
    ({"triangles": np.zeros((0, 3), dtype=np.int64)}, "has no triangles"),
    ({"cell_tags": np.array([1, 2])}, "'cell_tags' has 2 rows, 'triangles' 1"),
    ({"edges": np.array([[0, 1]])}, "'edges' and 'edge_tags' must be stored together"),
    ({"edges": np.array([[0, 1]]), "edge_tags": np.array([1, 1])}, "'edges' has 1 rows"),
])
def test_open_refuses_malformed_arrays(tmp_path, change, message):
    arrays = {k: v for k, v in {**GOOD, **change}.items() if v is not None}
    with pytest.raises(ValueError, match=message):
        store.open(_raw(tmp_path / "bad.zarr", arrays))


def test_to_mesh_validates_the_content(tmp_path):
    path = _raw(tmp_path / "cw.zarr", {**GOOD, "triangles": np.array([[0, 2, 1]])})
    store.open(path)  # opening is lazy: the content is not read
    with pytest.raises(ValueError, match="cw.zarr: triangle 0 .* clockwise"):
        store.to_mesh(path)


def test_store_layout_is_documented(tmp_path):
    store.create(tmp_path / "m.zarr", jittered_grid(2, 0), chunk_size=4)
    meta = json.loads((tmp_path / "m.zarr" / "zarr.json").read_text())
    assert meta["attributes"]["qdrefine"] == {
        "format": "mesh", "version": 2, "complete": True, "chunk_size": 4,
        "qdrefine_version": qdrefine.__version__, "metadata": {}}
    assert meta["attributes"]["Conventions"] == "UGRID-1.0"
    consolidated = meta["consolidated_metadata"]["metadata"]
    assert consolidated["mesh"]["attributes"] == {
        "cf_role": "mesh_topology", "long_name": "2D triangle mesh (qdrefine)",
        "topology_dimension": 2, "node_dimension": "node", "face_dimension": "face",
        "node_coordinates": "node_x node_y", "face_node_connectivity": "triangles"}
    assert {k: consolidated["triangles"]["attributes"][k] for k in ("cf_role", "start_index")
            } == {"cf_role": "face_node_connectivity", "start_index": 0}
    assert consolidated["triangles"]["fill_value"] == -1  # UGRID's fill, as Zarr's fill_value
    assert "_FillValue" not in consolidated["triangles"]["attributes"]  # xarray: float64
    assert "cf_role" not in consolidated["edges"]["attributes"]  # not every edge: see ATTRIBUTES
    for name, dims in store.DIMENSIONS.items():
        assert consolidated[name]["dimension_names"] == list(dims)
    names = sorted(p.name for p in (tmp_path / "m.zarr").iterdir() if p.is_dir())
    assert names == sorted(FIELDS + store.NODE_COORDINATES + ("mesh",))


def test_xarray_opens_a_store(tmp_path):
    import xarray as xr

    mesh = examples.plate_with_hole()
    store.create(tmp_path / "m.zarr", mesh, chunk_size=100)
    ds = xr.open_zarr(tmp_path / "m.zarr")
    assert dict(ds.sizes) == {"node": mesh.n_points, "xy": 2, "face": mesh.n_triangles,
                              "corner": 3, "edge": len(mesh.edges), "end": 2}
    assert ds["triangles"].dtype == mesh.triangles.dtype  # not decoded as float (no mask)
    np.testing.assert_array_equal(ds["triangles"].values, mesh.triangles)
    np.testing.assert_array_equal(ds["cell_tags"].values, mesh.cell_tags)
    np.testing.assert_array_equal(ds["node_x"].values, mesh.points[:, 0])
    np.testing.assert_array_equal(ds["node_y"].values, mesh.points[:, 1])
    assert ds["mesh"].attrs["face_node_connectivity"] == "triangles"


def test_unwritten_chunks_fail_validation_and_incomplete_stores_are_refused(tmp_path):
    group = store.new_group(str(tmp_path / "half.zarr"), {
        "points": ((3, 2), np.float64), "triangles": ((2, 3), np.int32)}, 1)
    group["points"][:] = GOOD["points"]
    group["triangles"][:1] = GOOD["triangles"]  # row 1 never written
    with pytest.raises(ValueError, match="half.zarr: incomplete mesh store"):
        store.open(tmp_path / "half.zarr")
    assert not store.is_store(tmp_path / "half.zarr")
    assert store.is_store(tmp_path / "half.zarr", complete=False)  # may be replaced
    store.finish(str(tmp_path / "half.zarr"))  # even if marked complete by mistake:
    with pytest.raises(ValueError, match="half.zarr: triangles row 1 holds the fill value"):
        store.to_mesh(tmp_path / "half.zarr")
    for out in ("half.msh", "half.node"):  # streamed exports check every chunk (review)
        with pytest.raises(ValueError, match="half.zarr: triangles row 1 holds the fill value "
                                             "of a chunk that was never written"):
            store.to_file(tmp_path / "half.zarr", tmp_path / out)
    assert not list(tmp_path.glob("half.[mne]*")) and not list(tmp_path.glob(".half*"))
    group = store.new_group(str(tmp_path / "nan.zarr"), {
        "points": ((3, 2), np.float64), "triangles": ((1, 3), np.int32)}, 2)
    group["triangles"][:] = GOOD["triangles"]
    store.finish(str(tmp_path / "nan.zarr"))
    with pytest.raises(ValueError, match="nan.zarr: points row 0 .* is not finite"):
        store.to_mesh(tmp_path / "nan.zarr")


@pytest.mark.parametrize("out", ["bad.msh", "bad.node"])
@pytest.mark.parametrize("array, row, value, message", [
    ("triangles", 5, 10**6, r"triangles row 5 \(1000000, \d+, \d+\) has a vertex index "
                            r"outside 0\.\.223: the store is damaged"),
    ("triangles", 300, -5, r"triangles row 300 \(-5, \d+, \d+\) has a vertex index outside "
                           r"0\.\.223"),
    ("edges", 7, 224, r"edges row 7 \(224, \d+\) has a vertex index outside 0\.\.223"),
    ("points", 9, np.inf, r"points row 9 \(inf, [-\d.e]+\) is not finite"),
])
def test_a_damaged_store_is_not_streamed_into_an_unreadable_file(tmp_path, out, array, row,
                                                                  value, message):
    """A vertex index beyond the points written into a store by another tool: the streamed
    .msh and Triangle exports wrote files that no reader takes, and exited 0 (review). One
    line naming the store, the array and the row; no file."""
    import zarr

    store.create(tmp_path / "s.zarr", examples.plate_with_hole(), chunk_size=100)
    z = zarr.open_group(str(tmp_path / "s.zarr"), mode="r+")[array]
    block = z[...]
    block[row, 0] = value
    z[...] = block
    with pytest.raises(ValueError, match=f"s.zarr: {message}"):
        store.to_file(tmp_path / "s.zarr", tmp_path / out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.zarr"]


def test_a_store_path_with_a_double_colon_is_refused(tmp_path):
    """fsspec reads '::' as URL chaining: ``e::f.zarr`` failed naming '.e/zarr.json', a path
    the user never gave (review). One line naming the path; nothing left."""
    with pytest.raises(ValueError, match=r"e::f\.zarr: a local store path cannot contain "
                                         r"'::' \(fsspec reads it as URL chaining\)"):
        store.create(tmp_path / "e::f.zarr", examples.square(2))
    assert list(tmp_path.iterdir()) == []


def test_a_store_that_cannot_be_created_names_the_target(tmp_path, monkeypatch):
    """A directory that refuses new entries: the message named qdrefine's temporary
    (``.y.zarr~host~pid~token.tmp``), not the store (review)."""
    import errno
    import os

    def refuse(path, *args, **kwargs):
        raise PermissionError(errno.EPERM, "Operation not permitted", path)

    monkeypatch.setattr(os, "mkdir", refuse)
    with pytest.raises(OSError, match=r"^\S+y\.zarr: cannot write: Operation not permitted$"):
        store.create(tmp_path / "y.zarr", examples.square(2))


def test_stores_at_memory_urls(tmp_path):
    mesh = jittered_grid(3, seed=5)
    s = store.create("memory://qd-store-test/m.zarr/", mesh, chunk_size=7)
    assert s.path == "memory://qd-store-test/m.zarr"
    same_mesh(mesh, store.to_mesh("memory://qd-store-test/m.zarr"))
    store.create("memory://qd-store-test/m.zarr", examples.square(2))  # replaced
    same_mesh(examples.square(2), store.to_mesh("memory://qd-store-test/m.zarr"))
    fs, root = store.filesystem("memory://qd-store-test")
    assert fs.ls(root, detail=False) == ["/qd-store-test/m.zarr"]  # no temporary left
    store.to_file("memory://qd-store-test/m.zarr", tmp_path / "m.msh")
    same_mesh(examples.square(2), qdrefine.read(tmp_path / "m.msh"))
    fs.rm(root, recursive=True)


def test_relative_paths_become_absolute(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    s = store.create("m.zarr", examples.square(2))
    assert s.path == str(tmp_path / "m.zarr")
    assert store.location("s3://bucket/a.zarr/") == "s3://bucket/a.zarr"


def test_temporaries_of_dead_runs_are_cleaned(tmp_path):
    import socket
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    host = socket.gethostname()
    names = {
        f".m.zarr~{host}~{dead}~0a1b2c3d.tmp": True,         # this host, process gone
        f".m.zarr~{host}~{os.getpid()}~0a1b2c3d.tmp": False,  # a live run
        f".m.zarr~elsewhere~{dead}~0a1b2c3d.tmp": False,     # another host: unknown
        ".m.zarr.ab12cd34.tmp": True,                        # older versions' names
        ".m.zarr.ab12cd34.work": True,
        ".other.zarr.ab12cd34.tmp": False,                   # another target's
        "m.zarr.bak": False,
        # a user's, only looking like ours (review: all three were removed)
        ".m.zarr.backup.old": False,
        ".m.zarr.2024.work": False,
        f".m.zarr~backup~{dead}~mine.old": False,
        # a temporary of m.zarr.zarr, not of m.zarr
        f".m.zarr.zarr~{host}~{dead}~0a1b2c3d.tmp": False,
    }
    for name in names:
        (tmp_path / name).mkdir()
        (tmp_path / name / "zarr.json").write_text("{}")
    # older versions' names are theirs only when they hold what those versions left: a
    # store, nothing, or (.work) .npy files; a user's folder of that name is kept (review:
    # .m.zarr.backup_1.tmp was removed, .m.zarr.20240101.old renamed to m.zarr, with the
    # user's notes inside)
    (tmp_path / ".m.zarr.ab12cd34.tmp" / "zarr.json").unlink()
    (tmp_path / ".m.zarr.ab12cd34.tmp").rmdir()
    store.create(tmp_path / ".m.zarr.ab12cd34.tmp", examples.square(1))
    (tmp_path / ".m.zarr.ab12cd34.work" / "zarr.json").rename(
        tmp_path / ".m.zarr.ab12cd34.work" / "keys.npy")
    (tmp_path / ".m.zarr.00000000.old").mkdir()  # empty
    names[".m.zarr.00000000.old"] = True
    for name in (".m.zarr.20240101.old", ".m.zarr.backup_1.tmp", ".m.zarr.ab12cd35.work"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "notes.txt").write_text("precious")
        names[name] = False
    (tmp_path / ".m.zarr.ab12cd34.old").write_text("a user's file: only directories are ours")
    names[".m.zarr.ab12cd34.old"] = False
    removed = store.clean(tmp_path / "m.zarr")
    assert sorted(Path(r).name for r in removed) == sorted(n for n, gone in names.items()
                                                           if gone)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(n for n, gone in names.items()
                                                               if not gone)
    store.create(tmp_path / "m.zarr", examples.square(2))  # the next write cleans too
    removed = store.clean(tmp_path / "m.zarr", everything=True)
    assert sorted(Path(r).name for r in removed) == sorted(
        [f".m.zarr~{host}~{os.getpid()}~0a1b2c3d.tmp", f".m.zarr~elsewhere~{dead}~0a1b2c3d.tmp"])
    assert store.is_store(tmp_path / "m.zarr")
    # cleaning store "m" leaves every temporary of "m.zarr" (review: a live run's went)
    (tmp_path / f".m.zarr~{host}~{dead}~0a1b2c3d.tmp").mkdir()
    assert store.clean(tmp_path / "m", everything=True) == []


@pytest.mark.parametrize("binary", [False, True])
def test_msh_export_of_many_tags_takes_two_passes(tmp_path, monkeypatch, binary):
    """More tag values than writing.GROUPED_PASSES: one element block per tag in each chunk,
    two passes over the store in all (not one per tag); qdrefine and the Gmsh SDK read
    the file back (tags included); tags chunked unlike the triangles are read by rows."""
    import gmsh

    from qdrefine.io.gmsh import writing

    mesh = jittered_grid(6, seed=4)
    mesh = mesh.replace(cell_tags=np.arange(mesh.n_triangles) % 23 + 1)
    s = store.create(tmp_path / "m.zarr", mesh, chunk_size=5)
    z = zarr.open_group(str(tmp_path / "m.zarr"), mode="r+")  # tags in chunks of 3 rows
    tags = z["cell_tags"][...]
    del z["cell_tags"]
    z.create_array("cell_tags", data=tags, chunks=(3,), dimension_names=["face"])
    with warnings.catch_warnings():  # "consolidated metadata is not part of Zarr 3's spec"
        warnings.simplefilter("ignore", UserWarning)
        zarr.consolidate_metadata(str(tmp_path / "m.zarr"))
    assert store.open(s.path).cell_tags.chunks[0][0] == 3
    reads = []
    original = export.rows

    def counting(s_, array, step=None):
        for start, rows in original(s_, array, step):
            reads.append(array)
            yield start, rows

    monkeypatch.setattr(export, "rows", counting)
    assert len(np.unique(tags)) > writing.GROUPED_PASSES
    store.to_file(store.open(s.path), tmp_path / "m.msh", binary=binary)
    monkeypatch.undo()
    n_chunks = -(-mesh.n_triangles // 5)
    assert reads.count("triangles") <= 2 * n_chunks + 2 * -(-len(mesh.edges) // 5)
    same_mesh(mesh, qdrefine.read(tmp_path / "m.msh"))
    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(str(tmp_path / "m.msh"))
        types, elements, _ = gmsh.model.mesh.getElements(2)
        assert sum(len(e) for e in elements) == mesh.n_triangles
        assert len(gmsh.model.getEntities(2)) == len(np.unique(tags))
    finally:
        gmsh.finalize()


def test_file_urls_are_local_paths(tmp_path):
    """``file://`` URLs are local paths (review: a store could not be created at one, and a
    source spelled ``file://...`` was replaced by its own refinement when the target was
    the same store spelled as a path); a target inside the source store is refused."""
    from qdrefine.distributed import refine_store

    url = f"file://{tmp_path}/m.zarr"
    assert store.location(url) == str(tmp_path / "m.zarr")
    store.create(url, examples.square(2))
    assert store.is_store(tmp_path / "m.zarr")
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    with pytest.raises(ValueError, match="the target would overwrite the source"):
        refine_store(url, tmp_path / "m.zarr")
    with pytest.raises(ValueError, match="the target would be inside the source "):
        refine_store(tmp_path / "m.zarr", f"{url}/inner.zarr")
    (tmp_path / "link").symlink_to(tmp_path)  # through a link: replaced its source too
    with pytest.raises(ValueError, match="the target would overwrite the source"):
        refine_store(url, tmp_path / "link" / "m.zarr")
    (tmp_path / "link").unlink()
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before
    memory = f"memory://same-{os.getpid()}/x.zarr"
    store.create(memory, examples.square(2))
    with pytest.raises(ValueError, match="the target would overwrite the source"):
        refine_store(memory, memory.replace("memory://", "memory:///"))
    store.remove(memory)
    for argv in (["convert", url, f"file://{tmp_path}/m.zarr/"],
                 ["refine", url, f"file://{tmp_path}/m.zarr", "--dask"]):
        assert main(argv) == 1  # refused before any work: no cluster starts
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_an_input_inside_the_output_store_or_an_output_inside_an_input_store_is_refused(
        tmp_path, monkeypatch, capsys):
    """A store is replaced as a whole: ``convert out.zarr/in.zarr out.zarr`` and
    ``refine_store`` of the same pair deleted their input, exit 0 (review); an output
    written inside an input store changed the input. Each is refused before any work, for
    stores and mesh files, in the CLI and the API, and nothing changes on disk."""
    from qdrefine.distributed import refine_store

    monkeypatch.chdir(tmp_path)
    mesh = examples.square(2)
    store.create("out.zarr", mesh)
    store.create("out.zarr/in.zarr", mesh)
    qdrefine.write("out.zarr/m.msh", mesh)
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    held = "is inside the output, which writing replaces as a whole"
    inside = "the output would be inside the input"
    for argv, message in ((["convert", "out.zarr/in.zarr", "out.zarr"], held),
                          (["convert", "out.zarr/m.msh", "out.zarr"], held),
                          (["convert", f"file://{tmp_path}/out.zarr/in.zarr",
                            f"file://{tmp_path}/out.zarr"], held),
                          (["refine", "out.zarr/in.zarr", "out.zarr", "--dask"], held),
                          (["convert", "out.zarr", "out.zarr/sub.zarr"], inside),
                          (["convert", "out.zarr", "out.zarr/x.msh"], inside),
                          (["refine", "out.zarr", "out.zarr/x.msh"], inside)):
        assert main(argv) == 1, argv
        err = capsys.readouterr().err
        assert message in err and err.count("\n") == 1, (argv, err)
    with pytest.raises(ValueError, match="the source .*in.zarr is inside the target"):
        refine_store("out.zarr/in.zarr", "out.zarr")
    with pytest.raises(ValueError, match=held):
        store.from_file("out.zarr/m.msh", "out.zarr")
    for name in ("y.msh", "y.vtu"):  # streamed, or through a mesh in memory
        with pytest.raises(ValueError, match=inside):
            store.to_file("out.zarr", f"out.zarr/{name}")
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def test_refine_dask_says_why_a_store_is_not_one(tmp_path, monkeypatch, capsys):
    """``refine IN.zarr OUT.zarr --dask`` with an incomplete store: the store's own reason,
    not 'make one with qdrefine convert' (review); before any cluster is started."""
    from qdrefine.cli import main

    monkeypatch.chdir(tmp_path)
    group = store.new_group(str(tmp_path / "half.zarr"), {
        "points": ((3, 2), np.float64), "triangles": ((1, 3), np.int32)}, 1)
    group["points"][:] = GOOD["points"]
    assert main(["refine", "half.zarr", "out.zarr", "--dask"]) == 1
    assert "half.zarr: incomplete mesh store" in capsys.readouterr().err
    assert main(["refine", "none.zarr", "out.zarr", "--dask"]) == 1
    assert "none.zarr: no such mesh store" in capsys.readouterr().err


def test_what_a_store_cannot_hold_is_dropped_with_a_warning(tmp_path):
    """Point and cell data, physical names and the history: dropped with one warning, as
    ``qdrefine.write`` warns for formats that cannot hold them (review: silently)."""
    mesh = examples.square(2).replace(point_data={"u": np.zeros(9)},
                                      physical_names={(2, 1): "a"})
    with pytest.warns(UserWarning, match=r"m\.zarr: mesh stores hold points, triangles, cell "
                                         r"tags and tagged edges; point data, physical names "
                                         r"are dropped"):
        store.create(tmp_path / "m.zarr", mesh)
    # one plural noun takes "are" ("physical names is dropped"; review)
    with pytest.warns(UserWarning, match=r"edges; physical names are dropped$"):
        store.create(tmp_path / "n.zarr", examples.square(2).replace(
            physical_names={(2, 1): "a"}))
    with pytest.warns(UserWarning, match=r"edges; point data is dropped$"):
        store.create(tmp_path / "d.zarr", examples.square(2).replace(
            point_data={"u": np.zeros(9)}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        store.create(tmp_path / "plain.zarr", examples.square(2))


def test_a_target_lost_between_two_renames_is_put_back(tmp_path):
    """A run killed between renaming the old target away and its new store into place
    (review): the next clean (every write cleans first) renames the old target back
    instead of removing it as a leftover."""
    import socket
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    store.create(tmp_path / "m.zarr", examples.square(2))
    old = tmp_path / f".m.zarr~{socket.gethostname()}~{dead}~0a1b2c3d.old"
    (tmp_path / "m.zarr").rename(old)
    assert store.clean(tmp_path / "m.zarr") == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.zarr"]
    same_mesh(examples.square(2), store.to_mesh(tmp_path / "m.zarr"))


def test_names_with_pattern_characters_touch_only_their_own_store():
    """fsspec's ``rm`` and ``mv`` read ``[``, ``?`` and ``*`` as patterns: replacing
    ``out[1].zarr`` on an object store removed the unrelated ``out1.zarr`` and left the
    temporary behind; ``x?.zarr`` was left broken."""
    import fsspec

    fs = fsspec.filesystem("memory")
    root = f"/glob-{os.getpid()}"
    mesh = examples.square(3)
    try:
        store.create(f"memory://{root}/out1.zarr", mesh, chunk_size=5)
        for name in ("out[1].zarr", "x?.zarr", "a*.zarr"):
            for chunk in (7, 4):  # a new store, then a replaced one
                store.create(f"memory://{root}/{name}", mesh, chunk_size=chunk)
                back = store.open(f"memory://{root}/{name}")
                assert back.chunk_size == chunk
                np.testing.assert_array_equal(back.to_mesh().triangles, mesh.triangles)
        assert store.is_store(f"memory://{root}/out1.zarr")
        assert sorted(p.rsplit("/", 1)[-1] for p in fs.ls(root, detail=False)) == \
            ["a*.zarr", "out1.zarr", "out[1].zarr", "x?.zarr"]  # no temporaries left
    finally:
        fs.rm(root, recursive=True)


def test_a_url_name_with_a_double_colon_is_refused():
    """``memory://b/a::b.zarr`` is read by fsspec as a chain and was written under
    ``memory://b/a``."""
    with pytest.raises(ValueError, match="cannot contain '::'"):
        store.create("memory://b/a::b.zarr", examples.square(2))


def test_the_same_store_spelled_otherwise_is_the_same_place(tmp_path):
    from qdrefine.store.locations import canonical, location

    (tmp_path / "s.zarr").mkdir()
    (tmp_path / "link").symlink_to(tmp_path)
    same = [tmp_path / "s.zarr", f"file://{tmp_path}/s.zarr", tmp_path / "link" / "s.zarr"]
    assert len({canonical(location(p)) for p in same}) == 1
    assert canonical(location("memory:///b/x.zarr")) == canonical(location("memory://b/x.zarr"))


def test_local_paths_are_split_and_compared_by_the_platform_separators(monkeypatch):
    """Temporaries' names and the input/output overlap check cut local paths at '/':
    a Windows path (``C:\\data\\out.zarr``) had no parent, so its temporary went to
    ``/.C:...``, and an output inside the input was not seen. Checked with ``ntpath``."""
    import ntpath
    import types

    from qdrefine.store import lifecycle, locations

    monkeypatch.setattr(locations, "os", types.SimpleNamespace(path=ntpath, fspath=os.fspath))
    assert locations.split(r"C:\data\out.zarr") == ("C:\\data", "out.zarr")
    assert locations.join("C:\\data", "x.zarr") == r"C:\data\x.zarr"
    assert locations.split("memory://a/b.zarr") == ("memory://a", "b.zarr")
    assert "inside the input" in locations.overlap(r"C:\d\in.zarr\o.zarr", r"C:\d\in.zarr")
    assert "is inside the output" in locations.overlap(r"C:\d\o.zarr", r"C:\d\o.zarr\i")
    assert locations.overlap(r"C:\d\in.zarr2", r"C:\d\in.zarr") is None
    assert locations._inside("file://C:/a/b.zarr", "file://C:/a")  # fsspec's local root
    temporary = lifecycle.temporary(r"C:\data\out.zarr", ".tmp")
    assert temporary.startswith("C:\\data\\.out.zarr~") and temporary.endswith(".tmp")


@pytest.mark.parametrize("damage, message", [
    ("truncate", "array 'triangles' rows .* cannot be read"),
    ("metadata list", "metadata is not a mapping"),
    ("metadata string", "metadata is not a mapping"),
    ("array json", "its arrays cannot be listed"),
])
def test_damaged_stores_are_one_line_naming_the_store(tmp_path, damage, message):
    """A truncated chunk (a codec's RuntimeError), metadata of the wrong type (TypeError)
    and an unreadable array description ended in tracebacks or named no store."""
    path = tmp_path / "m.zarr"
    store.create(path, examples.plate_with_hole(), chunk_size=100)
    if damage == "truncate":
        chunk = next((path / "triangles" / "c").rglob("*"))
        while chunk.is_dir():
            chunk = next(chunk.iterdir())
        with open(chunk, "r+b") as f:
            f.truncate(10)
    elif damage == "array json":
        (path / "triangles" / "zarr.json").write_text("{bad")
        for name in ("zarr.json",):  # no consolidated listing to fall back on
            meta = json.loads((path / name).read_text())
            meta.pop("consolidated_metadata", None)
            (path / name).write_text(json.dumps(meta))
    else:
        meta = json.loads((path / "zarr.json").read_text())
        meta["attributes"]["qdrefine"]["metadata"] = \
            [1, 2] if damage == "metadata list" else "7T twice"
        meta.pop("consolidated_metadata", None)
        (path / "zarr.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match=f"m.zarr: .*{message}"):
        store.to_mesh(path)
    assert main(["convert", str(path), str(tmp_path / "out.msh")]) == 1
    assert not (tmp_path / "out.msh").exists()


def test_a_long_store_name_gets_a_temporary_that_fits(tmp_path):
    """The temporary ``.NAME~HOST~PID~TOKEN.tmp`` of a 245-character name went past the
    255 bytes of a file name: the write was refused."""
    from qdrefine.store.lifecycle import TMP, maker_of, temporary

    name = "n" * 240 + ".zarr"
    target = tmp_path / name
    store.create(target, examples.square(2))
    assert store.is_store(target)
    leftover = temporary(store.location(target), TMP)
    assert len(leftover.rsplit("/", 1)[-1].encode()) <= 255
    assert maker_of(leftover.rsplit("/", 1)[-1], name) is not False  # clean finds it
    assert maker_of(leftover.rsplit("/", 1)[-1], "n" * 239 + "x.zarr") is False


def test_file_urls_are_taken_as_fsspec_takes_them(tmp_path):
    """No part of the path is dropped or decoded: ``#`` and ``?`` are characters of the
    name (a parser of URLs took them for a fragment and a query and wrote to ``run``), and
    ``%C3%BC`` stays as written, as fsspec and Zarr read it."""
    for name in ("run#1.zarr", "a?b.zarr", "x%41.zarr"):
        assert store.location(f"file://{tmp_path}/{name}") == str(tmp_path / name)
    store.create(f"file://{tmp_path}/run#1.zarr", examples.square(2))
    assert store.is_store(tmp_path / "run#1.zarr") and not (tmp_path / "run").exists()


def test_chained_urls_are_not_names_with_double_colons(tmp_path):
    """``zip://x.zarr::a.zip`` and ``simplecache::s3://...`` are fsspec chains; only after
    a storage protocol is ``::`` part of a name (and refused)."""
    import zipfile

    from qdrefine.store.locations import canonical, filesystem

    store.create(tmp_path / "x.zarr", examples.square(2))
    with zipfile.ZipFile(tmp_path / "a.zip", "w") as z:
        for f in (tmp_path / "x.zarr").rglob("*"):
            z.write(f, f.relative_to(tmp_path))
    for url in (f"zip://x.zarr::{tmp_path}/a.zip", f"zip://x.zarr::file://{tmp_path}/a.zip"):
        assert store.open(url).n_triangles == 8
        assert canonical(url) == url  # a chain is compared as written
    with pytest.raises(ValueError, match="cannot contain '::'"):
        filesystem("memory://b/a::b.zarr")
    with pytest.raises(ValueError, match="cannot contain '::'"):
        filesystem(f"{tmp_path}/a::b.zarr")


def test_clean_finds_the_full_name_temporaries_of_older_versions():
    """Versions before the shortened names wrote ``.{the whole name}~HOST~PID~TOKEN.tmp``
    for names of 121 bytes or more too."""
    from qdrefine.store.lifecycle import maker_of

    name = "m" * 150 + ".zarr"
    assert maker_of(f".{name}~vm~5395~0123abcd.tmp", name) == ("vm", 5395)
    assert maker_of(f".{name}~vm~5395~0123abcd.old", name) == ("vm", 5395)


def test_metadata_of_any_kind_is_kept_through_refinement(tmp_path):
    """``create`` takes any JSON mapping as metadata; a ``refinements`` that is not a list
    made the store unopenable, and refinement turned a string into its characters."""
    from qdrefine.distributed import _metadata
    from qdrefine.schemes import get_scheme

    source = store.create(tmp_path / "in.zarr", examples.square(2),
                          metadata={"refinements": "7T twice by hand"})
    assert store.open(source.path).metadata == {"refinements": "7T twice by hand"}
    assert _metadata(store.open(source.path), get_scheme("7t-qd"), 1)["refinements"] == \
        ["7T twice by hand", {"scheme": "7t-qd", "levels": 1}]


def test_format_version_is_refused_for_a_store_output_on_dask(tmp_path, capsys):
    store.create(tmp_path / "in.zarr", examples.square(2))
    assert main(["refine", str(tmp_path / "in.zarr"), str(tmp_path / "out.zarr"), "--dask",
                 "--format-version", "2.2"]) == 2
    assert "--format-version applies to Gmsh .msh output only" in capsys.readouterr().err


def test_a_chunk_size_beyond_the_largest_is_refused(tmp_path, capsys):
    """A chunk is made whole in memory to be written: ``--chunk-size 67108864`` took 1.6 GB
    and 8 s for a mesh of 5 points, 2**32 asked for 64 GiB and 10**24 said "Maximum allowed
    dimension exceeded", naming nothing (review). At most 2**24 rows, said before any work."""
    mesh = examples.square(1)
    for size in (store.MAX_CHUNK_SIZE + 1, 2**32, 10**24):
        with pytest.raises(ValueError, match=rf"chunk_size must be at most 16777216 rows "
                                             rf"\(2\*\*24; .*got {size}$"):
            store.create(tmp_path / "m.zarr", mesh, chunk_size=size)
    assert not (tmp_path / "m.zarr").exists()
    # a refined store is chunked as its source, whatever wrote it: no limit there (review:
    # a source of longer chunks, from an older qdrefine or another tool, was refused)
    group = store.new_group(str(tmp_path / "long.zarr"), {"points": ((9, 2), np.float64),
                                                          "triangles": ((8, 3), np.int32)},
                            store.MAX_CHUNK_SIZE + 1)
    assert group["triangles"].chunks == (store.MAX_CHUNK_SIZE + 1, 3)
    qdrefine.write(tmp_path / "m.msh", mesh)
    assert main(["convert", str(tmp_path / "m.msh"), str(tmp_path / "m.zarr"),
                 "--chunk-size", str(2**32)]) == 1
    assert "chunk_size must be at most 16777216 rows" in capsys.readouterr().err
    assert not (tmp_path / "m.zarr").exists()


def test_a_url_whose_filesystem_is_not_installed_is_one_line(tmp_path, monkeypatch, capsys):
    """``gs://`` without gcsfs: fsspec's ImportError ended the command in a traceback (final
    read of the session's diff, where the new overlap check met it first)."""
    import importlib

    registry = importlib.import_module("fsspec.registry")  # fsspec.registry is a mapping
    monkeypatch.setitem(registry.known_implementations, "qdnone",
                        {"class": "qd_missing_module.FileSystem",
                         "err": "Please install qd-missing to access qdnone"})
    with pytest.raises(ValueError, match="^qdnone://b/x.zarr: Please install qd-missing"):
        store.open("qdnone://b/x.zarr")
    for argv in (["convert", "qdnone://b/in.zarr", str(tmp_path / "out.msh")],
                 ["convert", str(tmp_path / "in.msh"), "qdnone://b/out.zarr"]):
        assert main(argv) == 1
        err = capsys.readouterr().err
        assert err.startswith("qdrefine: error: qdnone://b/") and "Please install qd-missing" \
            in err and err.count("\n") == 1, err
