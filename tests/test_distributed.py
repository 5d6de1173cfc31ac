"""Refinement of a chunked store on a local Dask cluster equals refinement in memory."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import zarr

from meshes import jittered_grid
from qdrefine import Mesh, examples, refine, store
from qdrefine.distributed import local_client, refine_store
from qdrefine.topology import conformity

SEVEN = ("7t-qd", "7t-le", "7t-d")


@pytest.fixture(scope="module")
def client():
    c = local_client(n_workers=2, processes=False)
    yield c
    c.close()


def coordinate_triples(points: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Cells as rows of coordinates, each rotated to start at its smallest vertex, sorted."""
    xy = points[cells]  # (M, c, 2)
    keys = [tuple(map(tuple, row)) for row in xy.tolist()]
    rotated = []
    for row in keys:
        r = row.index(min(row))
        rotated.append(row[r:] + row[:r])
    return np.array(sorted(rotated))


def assert_same_refinement(mesh: Mesh, scheme: str, levels: int, out: Mesh) -> None:
    """``out`` (from the store) equals the in-memory refinement: row by row in coordinates
    (children stay at ``t T ..``), as sets, in tags and edge pieces; no duplicated point."""
    fine = refine(mesh, scheme, levels)
    assert (out.n_points, out.n_triangles) == (fine.n_points, fine.n_triangles)
    assert out.triangles.dtype == fine.triangles.dtype
    np.testing.assert_array_equal(out.points[: mesh.n_points], mesh.points)  # old points kept
    np.testing.assert_array_equal(out.points[out.triangles], fine.points[fine.triangles])
    np.testing.assert_array_equal(coordinate_triples(out.points, out.triangles),
                                  coordinate_triples(fine.points, fine.triangles))
    np.testing.assert_array_equal(np.unique(out.points, axis=0), np.unique(fine.points, axis=0))
    for name in ("cell_tags", "edge_tags"):
        x, y = getattr(out, name), getattr(fine, name)
        assert (x is None) == (y is None)
        if x is not None:
            np.testing.assert_array_equal(x, y)
    if fine.edges is not None:
        np.testing.assert_array_equal(out.points[out.edges], fine.points[fine.edges])
    assert conformity(out).ok  # shared points across chunks are one point, not two


@pytest.mark.parametrize("levels", [1, 2])
@pytest.mark.parametrize("scheme", SEVEN)
def test_many_chunks_equal_in_memory(tmp_path, client, scheme, levels):
    # shuffled numbering: every chunk shares vertices and edges with the others;
    # 1 level: 32 triangles in 7 chunks; 2 levels: 8 in 3 chunks, then 56 in 19 chunks
    mesh, chunk = (jittered_grid(4, seed=11), 5) if levels == 1 else (jittered_grid(2, 7), 3)
    source = store.create(tmp_path / "in.zarr", mesh, chunk_size=chunk)
    calls = []
    summary = refine_store(source.path, tmp_path / "out.zarr", scheme, levels, client=client,
                           progress=lambda *a: calls.append(a))
    out = store.to_mesh(tmp_path / "out.zarr")
    assert_same_refinement(mesh, scheme, levels, out)
    assert summary.n_triangles == mesh.n_triangles * 7**levels
    assert (summary.scheme, summary.levels, len(summary.level_seconds)) == (scheme, levels,
                                                                            levels)
    assert store.open(tmp_path / "out.zarr").metadata["refinements"] == [
        {"scheme": scheme, "levels": levels}]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.zarr", "out.zarr"]  # no scratch
    done = [c[1] for c in calls]
    assert done == sorted(done) and calls[-1][1] == calls[-1][2] == 1 + 3 + 2 * (levels - 1)


def test_four_triangle_scheme(tmp_path, client):
    mesh = examples.plate_with_hole(n_around=6, n_rings=1)  # tagged circle, square, regions
    refine_store(store.create(tmp_path / "in.zarr", mesh, chunk_size=4).path,
                 tmp_path / "out.zarr", "4t-red", client=client)
    assert_same_refinement(mesh, "4t-red", 1, store.to_mesh(tmp_path / "out.zarr"))


def test_untagged_mesh_in_one_chunk_and_zero_levels(tmp_path, client):
    full = jittered_grid(3, seed=2, shear=0.5)
    mesh = Mesh(full.points, full.triangles)
    store.create(tmp_path / "in.zarr", mesh)  # default chunks: a single one
    refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", "7t-qd", client=client)
    out = store.open(tmp_path / "out.zarr")
    assert out.cell_tags is None and out.edges is None
    assert_same_refinement(mesh, "7t-qd", 1, out.to_mesh())
    calls = []
    refine_store(tmp_path / "in.zarr", tmp_path / "same.zarr", levels=0, client=client,
                 progress=lambda *a: calls.append(a))
    np.testing.assert_array_equal(store.to_mesh(tmp_path / "same.zarr").triangles,
                                  mesh.triangles)
    assert calls[-1][1] == calls[-1][2] == 2


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
    assert_same_refinement(mesh, "7t-qd", 1, store.to_mesh(tmp_path / "out.zarr"))


# bad input ----------------------------------------------------------------------------------


def raw_store(path: Path, points, triangles, edges=None, edge_tags=None, chunk=2) -> Path:
    """A store written without validation (as another tool might write one)."""
    group = zarr.create_group(store=str(path), attributes={
        "qdrefine": {"format": "mesh", "version": 1, "metadata": {}}})
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
     r"bad.zarr: triangle 3 \(1, 4, 9\) has a vertex index outside 0..5"),
    (SQUARE[:5] + [[2, np.nan]], GOOD, None, r"bad.zarr: point 5 has a non-finite"),
    (SQUARE, GOOD, [[0, 1], [3, 1]], r"bad.zarr: edge 1 \(1, 3\) is not an edge of any "),
])
def test_invalid_content_is_named(tmp_path, client, points, triangles, edges, message):
    tags = None if edges is None else np.ones(len(edges), dtype=np.int64)
    bad = raw_store(tmp_path / "bad.zarr", points, triangles, edges, tags)
    with pytest.raises(ValueError, match=message):
        refine_store(bad, tmp_path / "out.zarr", client=client)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.zarr"]  # nothing left behind


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
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.zarr", "plain"]


def test_paths_the_workers_cannot_see(tmp_path, client, monkeypatch):
    import qdrefine.distributed as qd

    good = store.create(tmp_path / "in.zarr", jittered_grid(2, seed=0)).path
    monkeypatch.setattr(qd, "_missing", lambda paths: paths[:1])  # as on a remote worker
    with pytest.raises(FileNotFoundError, match="in.zarr: not visible from the Dask worker"):
        refine_store(good, tmp_path / "out.zarr", client=client)


def test_a_failed_refinement_keeps_the_old_target(tmp_path, client):
    mesh = jittered_grid(2, seed=0)
    good = store.create(tmp_path / "in.zarr", mesh).path
    refine_store(good, tmp_path / "out.zarr", levels=0, client=client)
    bad = raw_store(tmp_path / "bad.zarr", SQUARE, GOOD[:3] + [[1, 2, 5]])
    with pytest.raises(ValueError, match="clockwise"):
        refine_store(bad, tmp_path / "out.zarr", client=client)
    np.testing.assert_array_equal(store.to_mesh(tmp_path / "out.zarr").points, mesh.points)
