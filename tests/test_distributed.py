"""Refinement of a chunked store on a local Dask cluster equals refinement in memory, bit
for bit, at any URL; failures leave the old target and no temporaries."""

import importlib.util
import os
from pathlib import Path

import numpy as np
import pytest
import zarr

from meshes import crack, jittered_grid
from qdrefine import Mesh, examples, refine, store
from qdrefine.distributed import ClusterError, local_client, min_worker_memory, refine_store
from qdrefine.distributed import cluster as qd_cluster

SEVEN = ("7t-qd", "7t-le", "7t-d")
FIELDS = ("points", "triangles", "cell_tags", "edges", "edge_tags")


@pytest.fixture(scope="module")
def client():
    c = local_client(n_workers=2, processes=False)
    yield c
    c.close()


def assert_identical(mesh: Mesh, scheme: str, levels: int, out: Mesh) -> None:
    """``out`` equals ``qdrefine.refine(mesh, scheme, levels)`` array by array, bit for bit
    (same numbering of the new points, same dtypes)."""
    fine = refine(mesh, scheme, levels)
    for name in FIELDS:
        x, y = getattr(out, name), getattr(fine, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert x.dtype == y.dtype, name
            assert np.array_equal(x, y), name


def leftovers(path: Path) -> list[str]:
    return sorted(p.name for p in path.iterdir())


@pytest.mark.parametrize("levels", [1, 2])
@pytest.mark.parametrize("chunk", [500, 16384, 262144])
def test_identical_to_in_memory_for_the_chunk_sizes(tmp_path, client, chunk, levels):
    # 2450 triangles with shuffled numbering, cell tags and tagged edges: chunks of 500 give
    # 5, then 35 chunks; 16384 gives 1, then 2; 262144 one chunk at every level
    mesh = jittered_grid(35, seed=5)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=chunk)
    summary = refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", "7t-qd", levels,
                           client=client)
    assert_identical(mesh, "7t-qd", levels, store.to_mesh(tmp_path / "out.zarr"))
    assert summary.n_triangles == mesh.n_triangles * 7**levels
    assert leftovers(tmp_path) == ["in.zarr", "out.zarr"]  # no temporaries


@pytest.mark.parametrize("levels", [1, 2])
@pytest.mark.parametrize("scheme", SEVEN)
def test_every_scheme_on_many_small_chunks(tmp_path, client, scheme, levels):
    # 1 level: 32 triangles in 7 chunks; 2 levels: 8 in 3 chunks, then 56 in 19 chunks
    mesh, chunk = (jittered_grid(4, seed=11), 5) if levels == 1 else (jittered_grid(2, 7), 3)
    source = store.create(tmp_path / "in.zarr", mesh, chunk_size=chunk)
    calls = []
    summary = refine_store(source.path, tmp_path / "out.zarr", scheme, levels, client=client,
                           progress=lambda *a: calls.append(a))
    assert_identical(mesh, scheme, levels, store.to_mesh(tmp_path / "out.zarr"))
    assert (summary.scheme, summary.levels, len(summary.level_seconds)) == (scheme, levels,
                                                                            levels)
    assert store.open(tmp_path / "out.zarr").metadata["refinements"] == [
        {"scheme": scheme, "levels": levels}]
    done = [c[1] for c in calls]
    assert done == sorted(done) and calls[-1][1] == calls[-1][2] == 1 + 3 + 2 * (levels - 1)


def test_the_shuffle_path_for_many_chunks(tmp_path, client, monkeypatch):
    # exchanges of more than DIRECT_PIECES pieces go through Dask's P2P shuffle instead
    from qdrefine.distributed import level

    monkeypatch.setattr(level, "DIRECT_PIECES", 0)
    mesh = jittered_grid(3, seed=12)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=5)
    refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", "7t-qd", 2, client=client)
    assert_identical(mesh, "7t-qd", 2, store.to_mesh(tmp_path / "out.zarr"))


@pytest.mark.parametrize("group", [1, 3, 1000])
def test_any_number_of_edge_partitions(tmp_path, client, monkeypatch, group):
    # one edge partition per EDGE_GROUP triangle chunks: 35 chunks at level 2 give up to 35, 12
    # and 1 partitions; every edge's rank and so the output must not depend on it
    from qdrefine.distributed import level

    monkeypatch.setattr(level, "EDGE_GROUP", group)
    mesh = jittered_grid(10, seed=13)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=40)
    refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", "7t-qd", 2, client=client)
    assert_identical(mesh, "7t-qd", 2, store.to_mesh(tmp_path / "out.zarr"))


def test_four_triangle_scheme(tmp_path, client):
    mesh = examples.plate_with_hole(n_around=6, n_rings=1)  # tagged circle, square, regions
    refine_store(store.create(tmp_path / "in.zarr", mesh, chunk_size=4).path,
                 tmp_path / "out.zarr", "4t-red", client=client)
    assert_identical(mesh, "4t-red", 1, store.to_mesh(tmp_path / "out.zarr"))


def test_untagged_mesh_in_one_chunk_and_zero_levels(tmp_path, client):
    full = jittered_grid(3, seed=2, shear=0.5)
    mesh = Mesh(full.points, full.triangles)
    store.create(tmp_path / "in.zarr", mesh)  # default chunks: a single one
    refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", "7t-qd", client=client)
    out = store.open(tmp_path / "out.zarr")
    assert out.cell_tags is None and out.edges is None
    assert_identical(mesh, "7t-qd", 1, out.to_mesh())
    calls = []
    refine_store(tmp_path / "in.zarr", tmp_path / "same.zarr", levels=0, client=client,
                 progress=lambda *a: calls.append(a))
    assert_identical(mesh, "7t-qd", 0, store.to_mesh(tmp_path / "same.zarr"))
    assert calls[-1][1] == calls[-1][2] == 2


def test_memory_urls_and_xarray(client):
    import xarray as xr

    mesh = jittered_grid(3, seed=8)
    store.create("memory://qd-test/in.zarr", mesh, chunk_size=20)
    summary = refine_store("memory://qd-test/in.zarr", "memory://qd-test/out.zarr", levels=2,
                           client=client)
    assert summary.target == "memory://qd-test/out.zarr"
    assert_identical(mesh, "7t-qd", 2, store.to_mesh("memory://qd-test/out.zarr"))
    fs, root = store.filesystem("memory://qd-test")
    assert sorted(p.rsplit("/", 1)[-1] for p in fs.ls(root, detail=False)) == ["in.zarr",
                                                                               "out.zarr"]
    ds = xr.open_zarr("memory://qd-test/out.zarr")
    assert ds.sizes["face"] == mesh.n_triangles * 49 and ds.sizes["corner"] == 3
    assert ds["mesh"].attrs["cf_role"] == "mesh_topology"
    assert np.array_equal(ds["triangles"].values, refine(mesh, "7t-qd", 2).triangles)
    attrs = ds.attrs["qdrefine"]
    assert attrs["complete"] is True and attrs["chunk_size"] == 20 and attrs["version"] == 2
    fs.rm(root, recursive=True)


def test_relative_paths_are_made_absolute_for_the_workers(tmp_path, client, monkeypatch):
    mesh = jittered_grid(2, seed=3)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=3)
    monkeypatch.chdir(tmp_path)
    original = qd_cluster._visible  # a remote worker has another working directory:
    monkeypatch.setattr(qd_cluster, "_visible", lambda s, t: original(s, t) if
                        os.path.isabs(s) and os.path.isabs(t) else "relative")
    summary = refine_store("in.zarr", "out.zarr", client=client)
    assert summary.target == str(tmp_path / "out.zarr")
    assert_identical(mesh, "7t-qd", 1, store.to_mesh(tmp_path / "out.zarr"))


def test_scheduler_address(tmp_path, client):
    mesh = jittered_grid(2, seed=3)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=3)
    summary = refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr",
                           address=client.scheduler.address)
    assert summary.n_workers == 2 and not client.status == "closed"
    if importlib.util.find_spec("bokeh") is None:  # no dashboard is served without bokeh
        assert summary.dashboard is None
    else:
        assert summary.dashboard.startswith("http")
    assert_identical(mesh, "7t-qd", 1, store.to_mesh(tmp_path / "out.zarr"))


# bad input ----------------------------------------------------------------------------------


def raw_store(path: Path, points, triangles, edges=None, edge_tags=None, chunk=2) -> Path:
    """A store written without validation (as another tool might write one)."""
    group = zarr.create_group(store=str(path), attributes={
        "qdrefine": {"format": "mesh", "version": 2, "complete": True, "metadata": {}}})
    arrays = {"points": np.asarray(points, float), "triangles": np.asarray(triangles)}
    if edges is not None:
        arrays |= {"edges": np.asarray(edges), "edge_tags": np.asarray(edge_tags)}
    for name, value in arrays.items():
        group.create_array(name, data=value, chunks=(chunk,) + value.shape[1:])
    return path


SQUARE = [[0, 0], [1, 0], [1, 1], [0, 1], [2, 0], [2, 1]]
GOOD = [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]]


@pytest.mark.parametrize("points,triangles,edges,message", [
    (SQUARE, GOOD[:3] + [[1, 2, 5]], None, r"bad.zarr: triangle 3 \(1, 2, 5\) is clockwise"),
    (SQUARE, GOOD[:3] + [[1, 4, 9]], None,
     r"bad.zarr: triangles row 3 \(1, 4, 9\) has a vertex index outside 0..5: the store "
     "is damaged"),
    (SQUARE[:5] + [[2, np.nan]], GOOD, None, r"bad.zarr: point 5 has a non-finite"),
    (SQUARE, GOOD, [[0, 1], [3, 1]], r"bad.zarr: edge 1 \(1, 3\) is not an edge of any "),
])
def test_invalid_content_is_named(tmp_path, client, points, triangles, edges, message):
    tags = None if edges is None else np.ones(len(edges), dtype=np.int64)
    bad = raw_store(tmp_path / "bad.zarr", points, triangles, edges, tags)
    with pytest.raises(ValueError, match=message):
        refine_store(bad, tmp_path / "out.zarr", client=client)
    assert leftovers(tmp_path) == ["bad.zarr"]  # nothing left behind


def test_a_needle_far_from_the_origin_is_refused_as_in_memory(tmp_path, client):
    needle = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1e-9], [0.5, -1.0]]) + 1e7
    mesh = Mesh(needle, [[0, 1, 2], [0, 3, 1]])
    with pytest.raises(ValueError, match="too thin"):
        refine(mesh, "7t-qd")
    store.create(tmp_path / "in.zarr", mesh, chunk_size=1)
    with pytest.raises(ValueError, match=r"in.zarr: triangle 0 \(0, 1, 2\) is too thin for "
                                         r"its distance from the origin"):
        refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", client=client)
    assert leftovers(tmp_path) == ["in.zarr"]


@pytest.mark.parametrize("chunk", [1, 3])
def test_a_clockwise_triangle_is_refused_before_a_thin_one_for_any_chunk_size(tmp_path,
                                                                             client, chunk):
    """Row 0 too thin at 1e7, row 2 clockwise: in memory the clockwise one is refused (the
    input's validation); here the thin one was when it came first in an earlier chunk
    (review)."""
    points = np.array([[0, 0], [1, 0], [0.5, 1e-9], [0.5, -1], [2, 0], [2, 1]]) + 1e7
    triangles = [[0, 1, 2], [0, 3, 1], [4, 1, 5]]
    with pytest.raises(ValueError) as exc:
        Mesh(points, triangles)
    path = raw_store(tmp_path / "in.zarr", points, triangles, chunk=chunk)
    with pytest.raises(ValueError) as info:
        refine_store(path, tmp_path / "out.zarr", client=client)
    assert str(info.value) == f"{path}: {exc.value}"


@pytest.mark.parametrize("levels", [1, 2])
def test_a_point_below_the_range_is_refused_after_every_level_as_in_memory(tmp_path, client,
                                                                           levels):
    """A needle too thin at level 2 beside a triangle whose new points fall below the
    coordinate range at level 1: in memory the range is checked after the last level, so
    the needle is refused at 2 levels; here the point was, at level 1 (review)."""
    needle = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 3.5e-9], [0.5, -1.0]]) + 1e7
    tiny = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1e-100]])
    mesh = Mesh(np.concatenate([needle, tiny]), [[0, 1, 2], [0, 3, 1], [4, 5, 6]])
    with pytest.raises(ValueError) as exc:
        refine(mesh, levels=levels)
    assert ("too thin" in str(exc.value)) == (levels == 2)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=3)
    with pytest.raises(ValueError) as info:
        refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", levels=levels, client=client)
    expected = str(exc.value).split(" is too thin")[0].split("; the mesh's smallest")[0]
    assert str(info.value).startswith(f"{tmp_path / 'in.zarr'}: {expected}")
    assert leftovers(tmp_path) == ["in.zarr"]


def test_a_refusal_at_the_second_level_names_the_source_as_in_memory(tmp_path, client):
    """Named the temporary store of level 1 (gone by then) and a triangle of it."""
    needle = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 3.5e-9], [0.5, -1.0]]) + 1e7
    mesh = Mesh(needle, [[0, 1, 2], [0, 3, 1]])
    refine(mesh)
    with pytest.raises(ValueError) as exc:
        refine(mesh, levels=2)
    expected = str(exc.value).split(" is too thin")[0]
    assert "cannot be refined 2 levels: its descendant" in expected
    store.create(tmp_path / "in.zarr", mesh, chunk_size=3)
    with pytest.raises(ValueError) as info:
        refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", levels=2, client=client)
    assert str(info.value).startswith(f"{tmp_path / 'in.zarr'}: {expected} is too thin")
    assert leftovers(tmp_path) == ["in.zarr"]


@pytest.mark.parametrize("direct", [True, False])
@pytest.mark.parametrize(("scheme", "levels", "along", "offset"), [
    ("7t-qd", 1, 0.375, 1e3),  # refused at the first level
    ("7t-qd", 2, 0.5, 1e3),  # at the second only
    ("4t-le", 1, 0.625, 1e7),  # refused
    ("7t-qd", 2, 0.625, 1e5),  # accepted
])
def test_parts_too_close_for_float64_are_refused_as_in_memory(tmp_path, client, monkeypatch,
                                                              direct, scheme, levels, along,
                                                              offset):
    """Two parts a float step apart inside a grid cut in chunks of 7: the rounded new points
    of one part's boundary cross the other. The store was refined without a check (and
    the output overlapped itself); now it refuses the same triangle as in memory."""
    from qdrefine.distributed import level
    from qdrefine.uniform import RefusedTriangle

    if not direct:
        monkeypatch.setattr(level, "DIRECT_PIECES", 0)
    grid = jittered_grid(6, seed=3)
    points, triangles = crack(1, along, offset, 1e-3)
    mesh = Mesh(np.concatenate([grid.points, points]),
                np.concatenate([grid.triangles[:30], triangles + grid.n_points,
                                grid.triangles[30:]]))
    store.create(tmp_path / "in.zarr", mesh, chunk_size=7)
    try:
        refine(mesh, scheme, levels)
    except RefusedTriangle as exc:
        with pytest.raises(ValueError) as info:
            refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", scheme, levels,
                         client=client)
        assert str(info.value) == f"{tmp_path / 'in.zarr'}: {exc}"
        assert leftovers(tmp_path) == ["in.zarr"]
    else:
        refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", scheme, levels,
                     client=client)
        assert_identical(mesh, scheme, levels, store.to_mesh(tmp_path / "out.zarr"))


def test_errors_before_any_work(tmp_path, client):
    good = store.create(tmp_path / "in.zarr", jittered_grid(2, seed=0)).path
    with pytest.raises(FileNotFoundError, match="missing.zarr: no such mesh store"):
        refine_store(tmp_path / "missing.zarr", tmp_path / "out.zarr", client=client)
    (tmp_path / "plain").mkdir()
    with pytest.raises(ValueError, match="plain: not a mesh store"):
        refine_store(tmp_path / "plain", tmp_path / "out.zarr", client=client)
    with pytest.raises(FileExistsError, match="plain: exists and is not a qdrefine mesh store"):
        refine_store(good, tmp_path / "plain", client=client)
    with pytest.raises(ValueError, match="overwrite the source"):
        refine_store(good, good, client=client)
    with pytest.raises(ValueError, match="unknown scheme 'nine'"):
        refine_store(good, tmp_path / "out.zarr", "nine", client=client)
    with pytest.raises(ValueError, match="levels must be >= 0"):
        refine_store(good, tmp_path / "out.zarr", levels=-1, client=client)
    with pytest.raises(ValueError, match="not both"):
        refine_store(good, tmp_path / "out.zarr", client=client, address="tcp://x:1")
    assert leftovers(tmp_path) == ["in.zarr", "plain"]


def test_paths_the_workers_cannot_see(tmp_path, client, monkeypatch):
    good = store.create(tmp_path / "in.zarr", jittered_grid(2, seed=0)).path
    monkeypatch.setattr(qd_cluster, "_visible", lambda s, t: s)  # as on a remote worker
    with pytest.raises(FileNotFoundError, match="in.zarr: not visible from the Dask worker"):
        refine_store(good, tmp_path / "out.zarr", client=client)
    assert leftovers(tmp_path) == ["in.zarr"]


def test_worker_memory_is_checked_before_starting(tmp_path):
    good = store.create(tmp_path / "in.zarr", jittered_grid(2, seed=0)).path
    # the mesh's 8 triangles are one chunk, stored in a Zarr chunk of the default rows
    need = min_worker_memory(8, store.DEFAULT_CHUNK_SIZE) / 2**20
    with local_client(n_workers=1, processes=False, memory_limit="200MiB",
                      dashboard_address=":0") as small, \
            pytest.raises(MemoryError, match=rf"memory limit of 200 MiB; chunks of 8 rows "
                                             rf"\(stored in Zarr chunks of 262144 rows\) "
                                             rf"need at least {need:.0f} MiB"):
        refine_store(good, tmp_path / "out.zarr", client=small)
    assert leftovers(tmp_path) == ["in.zarr"]
    # a store whose Zarr chunks are far longer than its arrays (10**8 rows: 6.7 GB were
    # taken past the check)
    big = store.create(tmp_path / "big.zarr", jittered_grid(2, seed=0), chunk_size=10**7).path
    assert min_worker_memory(8) < 900 * 2**20 < min_worker_memory(8, 10**7)
    with local_client(n_workers=1, processes=False, memory_limit="900MiB",
                      dashboard_address=":0") as enough_for_8_rows, \
            pytest.raises(MemoryError, match=r"stored in Zarr chunks of 10000000 rows"):
        refine_store(big, tmp_path / "out.zarr", client=enough_for_8_rows)


def test_stale_scheduler_info_does_not_hide_the_workers(tmp_path, client, monkeypatch):
    """Client.scheduler_info() returns a cache that its periodic refresh overwrites with a
    copy listing no workers (distributed 2026.7: a CI run failed with 'no workers'): the
    check asks the scheduler itself."""
    mesh = jittered_grid(2, seed=0)
    good = store.create(tmp_path / "in.zarr", mesh).path
    monkeypatch.setattr(type(client), "scheduler_info",
                        lambda self, *a, **k: {"services": {}, "workers": {}})
    refine_store(good, tmp_path / "out.zarr", client=client)
    assert_identical(mesh, "7t-qd", 1, store.to_mesh(tmp_path / "out.zarr"))


def test_paused_workers_stop_the_run_in_bounded_time(tmp_path, client):
    def pause_above(dask_worker, fraction):  # the workers' own memory monitor pauses them
        before = dask_worker.memory_manager.memory_pause_fraction
        dask_worker.memory_manager.memory_pause_fraction = fraction
        return before

    mesh = jittered_grid(2, seed=0)
    good = store.create(tmp_path / "in.zarr", mesh, chunk_size=3).path
    refine_store(good, tmp_path / "out.zarr", levels=0, client=client)
    before = client.run(pause_above, fraction=1e-9)  # as if their memory were full
    try:
        with pytest.raises(ClusterError, match="stayed paused for 1 s: its memory is full"):
            refine_store(good, tmp_path / "out.zarr", client=client, pause_timeout=1.0)
    finally:
        client.run(pause_above, fraction=next(iter(before.values())))
    assert_identical(mesh, "7t-qd", 0, store.to_mesh(tmp_path / "out.zarr"))  # old target
    assert leftovers(tmp_path) == ["in.zarr", "out.zarr"]


def test_a_failed_refinement_keeps_the_old_target(tmp_path, client):
    mesh = jittered_grid(2, seed=0)
    good = store.create(tmp_path / "in.zarr", mesh).path
    refine_store(good, tmp_path / "out.zarr", levels=0, client=client)
    bad = raw_store(tmp_path / "bad.zarr", SQUARE, GOOD[:3] + [[1, 2, 5]])
    with pytest.raises(ValueError, match="clockwise"):
        refine_store(bad, tmp_path / "out.zarr", client=client)
    assert_identical(mesh, "7t-qd", 0, store.to_mesh(tmp_path / "out.zarr"))
    assert leftovers(tmp_path) == ["bad.zarr", "in.zarr", "out.zarr"]


# fault injection ----------------------------------------------------------------------------
# Each run either completes with the identical output or fails with one clear error, leaving
# the old target as it was and no temporaries.


@pytest.fixture(scope="module")
def process_client():
    """Two single-thread worker processes under nannies (a killed worker is restarted)."""
    c = local_client(n_workers=2, processes=True, dashboard_address=":0")
    yield c
    c.close()


class KillOnce:
    """A worker plugin: the first worker to start a task whose key contains ``name`` kills
    its own process with SIGKILL (once per ``marker`` file)."""

    def __init__(self, name: str, marker: str) -> None:
        self.name, self.marker = name, marker

    def setup(self, worker):
        self.worker = worker

    def transition(self, key, start, finish, **kwargs):
        import signal

        if finish != "executing" or self.name not in str(key):
            return
        try:
            os.close(os.open(self.marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            return
        os.kill(os.getpid(), signal.SIGKILL)

    def teardown(self, worker):
        pass


def outcome_is_clean(run, mesh, levels, tmp_path, old: Mesh) -> str:
    """``run()``: the new target identical to the in-memory refinement, or a one-line
    error with the old target kept; never a temporary."""
    try:
        run()
    except (ClusterError, OSError, ValueError) as exc:
        assert "\n" not in str(exc)
        assert_identical(old, "7t-qd", 0, store.to_mesh(tmp_path / "out.zarr"))
        result = "failed"
    else:
        assert_identical(mesh, "7t-qd", levels, store.to_mesh(tmp_path / "out.zarr"))
        result = "completed"
    assert leftovers(tmp_path) == ["in.zarr", "marker", "out.zarr"]
    return result


def _allow_failures(client, n: int) -> int:
    def set_allowed(dask_scheduler, n):
        before, dask_scheduler.allowed_failures = dask_scheduler.allowed_failures, n
        return before

    return client.run_on_scheduler(set_allowed, n=n)


@pytest.mark.parametrize("task,shuffle,retries,expected", [
    ("shuffle-transfer", True, None, "completed"),  # Dask reruns the P2P shuffle
    ("_number_pieces", False, None, "completed"),   # mid direct exchange: rerun elsewhere
    ("_emit_chunk", False, None, "completed"),      # the chunk is written again, elsewhere
    ("_emit_chunk", False, 0, "failed"),            # KilledWorker at once: one line
])
def test_a_worker_killed_mid_shuffle_or_mid_write(tmp_path, process_client, monkeypatch, task,
                                                  shuffle, retries, expected):
    from distributed.diagnostics.plugin import WorkerPlugin

    from qdrefine.distributed import level

    if shuffle:
        monkeypatch.setattr(level, "DIRECT_PIECES", 0)

    plugin = type("Kill", (KillOnce, WorkerPlugin), {})(task, str(tmp_path / "marker"))
    mesh = jittered_grid(3, seed=1)
    old = jittered_grid(2, seed=2)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=6)
    store.create(tmp_path / "out.zarr", old)
    process_client.register_plugin(plugin, name=f"kill-{task}")
    before = _allow_failures(process_client, retries) if retries is not None else None
    try:
        result = outcome_is_clean(lambda: refine_store(tmp_path / "in.zarr",
                                                       tmp_path / "out.zarr", levels=1,
                                                       client=process_client),
                                  mesh, 1, tmp_path, old)
    finally:
        process_client.unregister_worker_plugin(f"kill-{task}")
        if before is not None:
            _allow_failures(process_client, before)
    assert (tmp_path / "marker").exists()  # a worker was killed
    assert result == expected


def test_killed_worker_is_one_clear_line(tmp_path, process_client):
    from distributed.diagnostics.plugin import WorkerPlugin

    plugin = type("Kill", (KillOnce, WorkerPlugin), {})("_emit_chunk", str(tmp_path / "m"))
    store.create(tmp_path / "in.zarr", jittered_grid(3, seed=1), chunk_size=8)
    process_client.register_plugin(plugin, name="kill-once")
    before = _allow_failures(process_client, 0)
    try:
        with pytest.raises(ClusterError, match=r"^a Dask worker died while running .* \(killed, "
                                               r"or out of memory\); the run was stopped and "
                                               r"its temporaries removed$"):
            refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", client=process_client)
    finally:
        process_client.unregister_worker_plugin("kill-once")
        _allow_failures(process_client, before)
    assert leftovers(tmp_path) == ["in.zarr", "m"]


def test_a_full_disk_leaves_the_old_target(tmp_path, client, monkeypatch):
    import errno

    from zarr.storage import LocalStore

    mesh, old = jittered_grid(4, seed=1), jittered_grid(2, seed=2)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=5)
    store.create(tmp_path / "out.zarr", old)
    (tmp_path / "marker").touch()
    original = LocalStore.set

    async def full(self, key, value):  # the disk fills when the triangles are written
        if key.startswith("triangles/c"):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return await original(self, key, value)

    monkeypatch.setattr(LocalStore, "set", full)
    with pytest.raises(OSError, match="No space left on device"):
        refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", client=client)
    monkeypatch.undo()
    assert_identical(old, "7t-qd", 0, store.to_mesh(tmp_path / "out.zarr"))
    assert leftovers(tmp_path) == ["in.zarr", "marker", "out.zarr"]


KILLABLE = """
import sys
from qdrefine.distributed import local_client, refine_store
with local_client(n_workers=2, processes=False, dashboard_address=":0") as c:
    refine_store(sys.argv[1], sys.argv[2], levels=2, client=c)
"""


def _wait_for_temporary(tmp_path: Path, proc, seconds: float = 60.0) -> Path:
    import time

    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and proc.poll() is None:
        found = [p for p in tmp_path.iterdir() if p.name.startswith(".out.zarr~")]
        if found and (found[0] / "_work").exists():
            time.sleep(0.5)  # well into the run
            return found[0]
        time.sleep(0.05)
    raise AssertionError(f"the run did not start writing (exit {proc.poll()})")


def test_a_killed_client_leaves_garbage_the_next_run_removes(tmp_path, client):
    import signal
    import subprocess
    import sys

    mesh, old = jittered_grid(30, seed=1), jittered_grid(2, seed=2)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=400)
    store.create(tmp_path / "out.zarr", old)
    proc = subprocess.Popen([sys.executable, "-c", KILLABLE, str(tmp_path / "in.zarr"),
                             str(tmp_path / "out.zarr")], env={**os.environ},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    temporary = _wait_for_temporary(tmp_path, proc)
    proc.send_signal(signal.SIGKILL)  # what SLURM and Kubernetes send last
    proc.wait(timeout=30)
    assert temporary.exists()
    assert not store.is_store(temporary)  # never mistaken for a mesh
    assert_identical(old, "7t-qd", 0, store.to_mesh(tmp_path / "out.zarr"))
    small = jittered_grid(2, seed=4)
    store.create(tmp_path / "in.zarr", small, chunk_size=3)
    refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", client=client)  # the next run
    assert_identical(small, "7t-qd", 1, store.to_mesh(tmp_path / "out.zarr"))
    assert leftovers(tmp_path) == ["in.zarr", "out.zarr"]


# an object store --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def s3_bucket():
    """A local S3 (moto's server) with a bucket; s3:// URLs reach it through fsspec's
    configuration (this process: the cluster's workers are threads here)."""
    import logging

    import boto3
    import fsspec
    from moto.server import ThreadedMotoServer

    logging.getLogger("werkzeug").setLevel(logging.ERROR)
    server = ThreadedMotoServer(ip_address="127.0.0.1", port=0, verbose=False)
    server.start()
    host, port = server.get_host_and_port()
    url = f"http://{host}:{port}"
    credentials = {"aws_access_key_id": "testing", "aws_secret_access_key": "testing"}
    boto3.client("s3", endpoint_url=url, region_name="us-east-1",
                 **credentials).create_bucket(Bucket="qd-bucket")
    before = fsspec.config.conf.get("s3")
    fsspec.config.conf["s3"] = {"endpoint_url": url, "key": "testing", "secret": "testing",
                                "client_kwargs": {"region_name": "us-east-1"}}
    yield "s3://qd-bucket"
    if before is None:
        fsspec.config.conf.pop("s3")
    else:
        fsspec.config.conf["s3"] = before
    server.stop()


def test_stores_on_s3(s3_bucket, client):
    mesh, old = jittered_grid(3, seed=9), jittered_grid(2, seed=2)
    store.create(f"{s3_bucket}/in.zarr", mesh, chunk_size=20)
    store.create(f"{s3_bucket}/out.zarr", old)
    refine_store(f"{s3_bucket}/in.zarr", f"{s3_bucket}/out.zarr", levels=2, client=client)
    assert_identical(mesh, "7t-qd", 2, store.to_mesh(f"{s3_bucket}/out.zarr"))  # replaced
    fs, root = store.filesystem(s3_bucket)
    assert sorted(fs.ls(root, detail=False)) == ["qd-bucket/in.zarr", "qd-bucket/out.zarr"]
    group = zarr.create_group(store=f"{s3_bucket}/bad.zarr", attributes={
        "qdrefine": {"format": "mesh", "version": 2, "complete": True, "metadata": {}}})
    group.create_array("points", data=np.asarray(SQUARE, float))
    group.create_array("triangles", data=np.asarray(GOOD[:3] + [[1, 2, 5]]))
    with pytest.raises(ValueError, match="clockwise"):  # a failed run keeps the old target
        refine_store(f"{s3_bucket}/bad.zarr", f"{s3_bucket}/out.zarr", client=client)
    fs, root = store.filesystem(s3_bucket)
    assert sorted(fs.ls(root, detail=False)) == ["qd-bucket/bad.zarr", "qd-bucket/in.zarr",
                                                 "qd-bucket/out.zarr"]
    assert_identical(mesh, "7t-qd", 2, store.to_mesh(f"{s3_bucket}/out.zarr"))


def _profiling(dask_worker) -> bool:
    return "profile" in dask_worker.periodic_callbacks


@pytest.mark.parametrize("profile", [False, True])
def test_the_local_workers_profiler_is_off_unless_asked_for(profile):
    with local_client(n_workers=1, processes=False, dashboard_address=":0",
                      profile=profile) as c:
        on = c.run(_profiling)
    assert list(on.values()) == [profile]


def test_the_profiler_stays_off_in_a_restarted_worker_process():
    # a nanny restarts a worker that was killed (here: client.restart()) in a new process
    with local_client(n_workers=1, processes=True, dashboard_address=":0") as c:
        assert list(c.run(_profiling).values()) == [False]
        c.restart()
        assert list(c.run(_profiling).values()) == [False]


def _sigint_disposition():
    import signal

    return signal.getsignal(signal.SIGINT) == signal.SIG_IGN


def test_worker_processes_leave_ctrl_c_to_the_client(process_client):
    """A terminal's Ctrl-C reaches the whole process group: the worker processes of a
    local cluster ignore it (each printed a KeyboardInterrupt traceback, review), the
    client stops the run (restarted workers too: the preload runs in each)."""
    import signal

    assert all(process_client.run(_sigint_disposition).values())
    assert signal.getsignal(signal.SIGINT) is not signal.SIG_IGN  # not the client's


def test_signals_during_cluster_start_up_wait_for_it():
    """Ctrl-C or SIGTERM while a cluster starts is held until it has started (Dask logged
    tracebacks from its exit hooks); and the NameError that distributed's sync logs when
    an interrupt comes before its call started is dropped, nothing else."""
    import logging
    import signal

    from qdrefine.distributed.cluster import _DaskCancelError
    from qdrefine.interrupts import signals_held

    held: list[int] = []
    before = signal.getsignal(signal.SIGTERM)
    with signals_held(held):
        signal.raise_signal(signal.SIGINT)
        signal.raise_signal(signal.SIGTERM)
    assert held == [signal.SIGINT, signal.SIGTERM]
    assert signal.getsignal(signal.SIGTERM) is before
    with pytest.raises(KeyboardInterrupt):
        signal.raise_signal(signal.SIGINT)  # acts again once released

    def record(kind, message):
        try:
            raise kind("cannot access free variable 'future'")
        except kind:
            import sys

            return logging.LogRecord("tornado.application", logging.ERROR, __file__, 1,
                                     message, (), sys.exc_info())

    keep = _DaskCancelError().filter
    assert not keep(record(NameError, "Exception in callback functools.partial(<function "
                                      "sync.<locals>.cancel at 0x7f>)"))
    assert keep(record(NameError, "Exception in callback functools.partial(<function f>)"))
    assert keep(record(ValueError, "Exception in callback sync.<locals>.cancel"))


def test_a_script_without_a_main_guard_fails_instead_of_hanging(tmp_path):
    """The documented example run as a script without ``if __name__ == "__main__":`` hung
    forever, deaf to SIGTERM (docs review, 2026-11-27): each worker process imported the
    script again and waited for a cluster of its own. Now the workers fail at once, saying
    why, and the run stops."""
    import subprocess
    import sys

    script = tmp_path / "unguarded.py"
    script.write_text("from qdrefine.distributed import local_client\n"
                      "client = local_client(n_workers=1)\n"
                      "print('started')\n")
    run = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                         text=True, timeout=240)
    assert run.returncode != 0 and "started" not in run.stdout
    assert "put the script's code under 'if __name__ == \"__main__\":'" in run.stderr
    # the worker's one line, no traceback of multiprocessing's start-up or of Dask's nanny;
    # the script's own traceback ends in one line that points at it
    assert run.stderr.count("Traceback") == 1, run.stderr
    assert run.stderr.rstrip().endswith("worker processes failed to start (their messages "
                                        "are above)")


def _damaged(tmp_path: Path, name: str, damage) -> Path:
    """A store of the plate (chunks of 100 rows) with ``damage(folder)`` done to it."""
    path = tmp_path / name
    store.create(path, examples.plate_with_hole(), chunk_size=100)
    damage(path)
    return path


@pytest.mark.parametrize("levels", [0, 1])
@pytest.mark.parametrize("array, damage, message", [
    ("cell_tags", lambda p: (p / "cell_tags" / "c" / "1").unlink(),
     "cell_tags row 100 holds the fill value"),
    ("triangles", lambda p: __import__("shutil").rmtree(p / "triangles" / "c" / "1"),
     "triangles row 100 holds the fill value"),
])
def test_a_store_with_a_missing_chunk_is_refused_not_refined(tmp_path, client, levels, array,
                                                             damage, message):
    """A chunk never written reads as the fill value: tags of -2**63 were refined into a
    store marked complete (and ``levels=0`` copied any damage), which ``to_mesh`` took as
    data or refused only later."""
    path = _damaged(tmp_path, "in.zarr", damage)
    with pytest.raises(ValueError, match=message):
        refine_store(path, tmp_path / "out.zarr", levels=levels, client=client)
    assert not (tmp_path / "out.zarr").exists()
    with pytest.raises(ValueError, match=message):
        store.to_mesh(path)


def test_unsigned_tags_beyond_int64_are_refused_as_in_memory(tmp_path, client):
    """They became tag -1 in the output."""
    mesh = examples.plate_with_hole()
    path = tmp_path / "u.zarr"
    store.create(path, mesh, chunk_size=100)
    group = zarr.open_group(path, mode="r+", use_consolidated=False)
    shape = group["cell_tags"].shape
    del group["cell_tags"]
    group.create_array("cell_tags", shape=shape, dtype=np.uint64, chunks=(100,),
                       fill_value=0)[...] = np.full(shape, 2**64 - 1, dtype=np.uint64)
    _consolidate(path)
    with pytest.raises(ValueError, match=r"cell_tags row \d+ holds 18446744073709551615"):
        refine_store(path, tmp_path / "out.zarr", client=client)
    assert not (tmp_path / "out.zarr").exists()


def test_new_points_below_the_coordinate_range_are_refused_as_in_memory(tmp_path, client):
    mesh = Mesh([[1.5e-100, 0], [1, 0], [-1e-100, 1]], [[0, 1, 2]])
    with pytest.raises(ValueError, match="below the supported range"):
        refine(mesh)
    store.create(tmp_path / "low.zarr", mesh)
    with pytest.raises(ValueError, match="below the supported range"):
        refine_store(tmp_path / "low.zarr", tmp_path / "out.zarr", client=client)
    assert not (tmp_path / "out.zarr").exists()


@pytest.mark.parametrize("levels", [0, 1])
def test_unsigned_tags_within_int64_are_refined_and_copied(tmp_path, client, levels):
    """``levels=0`` copied uint64 tags into an array whose fill value is int64's smallest:
    an OverflowError traceback (refinement wrote them as int64 already)."""
    mesh = examples.plate_with_hole()
    path = tmp_path / "u.zarr"
    store.create(path, mesh, chunk_size=100)
    group = zarr.open_group(path, mode="r+", use_consolidated=False)
    tags = group["cell_tags"][...]
    del group["cell_tags"]
    group.create_array("cell_tags", shape=tags.shape, dtype=np.uint64, chunks=(100,),
                       fill_value=0)[...] = tags.astype(np.uint64)
    _consolidate(path)
    refine_store(path, tmp_path / "out.zarr", levels=levels, client=client)
    out = store.to_mesh(tmp_path / "out.zarr")
    np.testing.assert_array_equal(out.cell_tags, refine(mesh, levels=levels).cell_tags
                                  if levels else mesh.cell_tags)


def _consolidate(path: Path) -> None:
    """Zarr's consolidated listing again after an array was replaced (Zarr warns that the
    listing is not part of its format 3 specification; qdrefine's stores have it)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        zarr.consolidate_metadata(path)


def _grid(n: int = 4) -> tuple[np.ndarray, list[list[int]]]:
    """An ``n x n`` grid of the unit square, two triangles per cell."""
    xs = np.linspace(0, 1, n)
    points = np.array([[x, y] for y in xs for x in xs])
    triangles = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            triangles += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    return points, triangles


@pytest.mark.parametrize("direct", [True, False])
@pytest.mark.parametrize("case, message", [
    # a duplicated interior triangle: every edge of it shared by 3, nothing on the boundary
    ("duplicate", r"bad.zarr: edge \(5, 6\) is shared by 3 triangles; at most two"),
    # a third triangle on an interior edge
    ("stacked", r"bad.zarr: edge \(5, 6\) is shared by 3 triangles; at most two"),
    # two triangles on one side of their only edge
    ("fold", r"bad.zarr: the two triangles of edge \(0, 1\) lie on the same side of it: "
             "they overlap"),
    # a hanging node, an overlap: the boundary as given meets itself
    ("hanging", r"bad.zarr: triangle 2 \(0, 2, 4\) has a boundary edge that meets another "
                r"part of the mesh's boundary, before any refinement: the mesh overlaps "
                "itself, has a hanging node"),
])
def test_a_mesh_that_is_not_valid_is_refused_and_named(tmp_path, client, monkeypatch, direct,
                                                       case, message):
    """The distributed path does not validate the mesh as a whole, as ``to_mesh`` does: a
    duplicated interior triangle was refined into a store marked complete, and overused
    edges, folds, hanging nodes and overlaps were refused as "closer to another part of
    the mesh than float64 can resolve" (review). Edges of more than two half-edges, or of
    two walking them the same way, are found while the edges are numbered (any chunk
    size, shuffled or not); a boundary that meets itself before any refinement is named
    as such."""
    from qdrefine.distributed import level

    if not direct:
        monkeypatch.setattr(level, "DIRECT_PIECES", 0)
    points, triangles = _grid()
    if case == "duplicate":
        triangles = triangles + [triangles[8]]
    elif case == "stacked":
        points = np.vstack([points, [[0.5, 0.45]]])
        triangles = triangles + [[5, 6, 16]]
    elif case == "fold":
        points, triangles = [[0, 0], [1, 0], [0.5, 1], [0.5, 2]], [[0, 1, 2], [0, 1, 3]]
    else:
        points = [[0, 0], [1, 0], [2, 0], [1, -1], [2, 1]]
        triangles = [[0, 3, 1], [1, 3, 2], [0, 2, 4]]
    for chunk in (1, 5, 100):
        bad = raw_store(tmp_path / "bad.zarr", points, triangles, chunk=chunk)
        with pytest.raises(ValueError, match=message):
            refine_store(bad, tmp_path / "out.zarr", client=client)
        assert leftovers(tmp_path) == ["bad.zarr"]  # nothing left behind
        __import__("shutil").rmtree(bad)


def test_levels_0_copies_unsigned_indices_and_names_an_undecodable_chunk(tmp_path, client):
    """``levels=0`` kept a uint64 source's triangles as uint64, whose fill value -1 did not
    fit (an OverflowError traceback), and read chunks through Dask's own reader, so a
    truncated chunk was the codec's RuntimeError traceback (review). Indices are copied
    as the signed integers a refined level writes; every chunk is read as ``to_mesh``
    reads it."""
    mesh = examples.plate_with_hole()
    path = tmp_path / "u.zarr"
    store.create(path, mesh, chunk_size=100)
    group = zarr.open_group(path, mode="r+", use_consolidated=False)
    del group["triangles"]
    group.create_array("triangles", data=mesh.triangles.astype(np.uint64), chunks=(100, 3))
    _consolidate(path)
    refine_store(path, tmp_path / "out.zarr", levels=0, client=client)
    out = store.to_mesh(tmp_path / "out.zarr")
    assert np.array_equal(out.triangles, mesh.triangles) and out.triangles.dtype.kind == "i"
    chunk = tmp_path / "u.zarr" / "points" / "c" / "1" / "0"
    chunk.write_bytes(chunk.read_bytes()[:10])
    with pytest.raises(ValueError, match=r"u.zarr: array 'points' rows 100..199 cannot be "
                                         r"read .*: the store is damaged"):
        refine_store(path, tmp_path / "again.zarr", levels=0, client=client)
    assert not (tmp_path / "again.zarr").exists()
