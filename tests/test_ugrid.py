"""UGRID readers open a mesh store: xugrid finds the topology (node_x, node_y, triangles),
for stores written in memory and by the distributed refinement; stores without node_x and
node_y (written by earlier versions) still open with qdrefine."""

import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest
import zarr

from meshes import jittered_grid
from qdrefine import Mesh, examples, refine, store
from qdrefine.distributed import local_client, refine_store


@pytest.fixture(scope="module")
def client():
    c = local_client(n_workers=2, processes=False)
    yield c
    c.close()


def untagged(mesh: Mesh) -> Mesh:
    return Mesh(mesh.points, mesh.triangles)


def open_with_xugrid(url: str | Path):
    """``xugrid.open_zarr(url)``, with any warning (no CRS, no standard_name) an error."""
    import xugrid

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return xugrid.open_zarr(url)


def distinct_edges(mesh: Mesh) -> int:
    t = mesh.triangles
    pairs = np.stack([t, np.roll(t, -1, axis=1)], axis=-1).reshape(-1, 2)
    return len(np.unique(np.sort(pairs, axis=1), axis=0))


def assert_xugrid_sees(url: str | Path, mesh: Mesh) -> None:
    """xugrid's grid of the store at ``url`` has ``mesh``'s nodes and triangles exactly;
    the tags come along on the grid's dimensions, the tagged edges as plain variables."""
    uds = open_with_xugrid(url)
    grid = uds.ugrid.grid
    assert grid.node_x.dtype == np.float64 and grid.node_y.dtype == np.float64
    assert np.array_equal(grid.node_x, mesh.points[:, 0])
    assert np.array_equal(grid.node_y, mesh.points[:, 1])
    assert np.array_equal(grid.node_coordinates, mesh.points)
    assert np.array_equal(grid.face_node_connectivity, mesh.triangles)
    assert (grid.n_node, grid.n_face) == (mesh.n_points, mesh.n_triangles)
    assert (grid.node_dimension, grid.face_dimension) == ("node", "face")
    # xugrid derives the edges of the mesh itself (the tagged edges are not declared as them)
    assert grid.n_edge == distinct_edges(mesh)
    assert grid.face_edge_connectivity.shape == mesh.triangles.shape
    if mesh.cell_tags is None:
        assert "cell_tags" not in uds
    else:
        assert np.array_equal(uds["cell_tags"].values, mesh.cell_tags)
        assert uds["cell_tags"].dims == ("face",)
    if mesh.edges is None:
        assert "edges" not in uds and "edge_tags" not in uds
    else:
        assert np.array_equal(uds["edges"].values, mesh.edges)
        assert np.array_equal(uds["edge_tags"].values, mesh.edge_tags)


@pytest.mark.parametrize("tagged", [True, False])
def test_xugrid_opens_a_store_written_in_memory(tmp_path, tagged):
    mesh = examples.plate_with_hole()  # tagged circle and square, two regions
    mesh = mesh if tagged else untagged(mesh)
    store.create(tmp_path / "m.zarr", mesh, chunk_size=100)
    assert_xugrid_sees(tmp_path / "m.zarr", mesh)


def test_node_x_and_node_y_are_written_as_points(tmp_path):
    mesh = jittered_grid(6, seed=3)
    store.create(tmp_path / "m.zarr", mesh, chunk_size=10)
    group = zarr.open_group(tmp_path / "m.zarr", mode="r")
    for i, name in enumerate(store.NODE_COORDINATES):
        a = group[name]
        assert (a.shape, a.chunks, a.dtype) == ((mesh.n_points,), (10,), np.float64)
        assert np.isnan(a.fill_value) and a.metadata.dimension_names == ("node",)
        assert a.attrs["standard_name"] == f"projection_{'xy'[i]}_coordinate"
        assert np.array_equal(a[...], mesh.points[:, i])


@pytest.mark.parametrize("levels", [0, 1, 2])
@pytest.mark.parametrize("tagged", [True, False])
def test_xugrid_opens_a_store_refined_on_dask(tmp_path, client, tagged, levels):
    # chunks of 7 triangles (and points): 18 points chunks at 2 levels, each written with
    # its node_x, node_y by a different task
    mesh = jittered_grid(3, seed=4)
    mesh = mesh if tagged else untagged(mesh)
    store.create(tmp_path / "in.zarr", mesh, chunk_size=7)
    refine_store(tmp_path / "in.zarr", tmp_path / "out.zarr", "7t-qd", levels, client=client)
    assert_xugrid_sees(tmp_path / "out.zarr", refine(mesh, "7t-qd", levels))


def test_xugrid_opens_a_store_refined_at_a_memory_url(client):
    mesh = jittered_grid(3, seed=9)
    store.create("memory://qd-ugrid/in.zarr", mesh, chunk_size=5)
    refine_store("memory://qd-ugrid/in.zarr", "memory://qd-ugrid/out.zarr", "7t-le",
                 client=client)
    assert_xugrid_sees("memory://qd-ugrid/out.zarr", refine(mesh, "7t-le"))
    fs, root = store.filesystem("memory://qd-ugrid")
    fs.rm(root, recursive=True)


def make_old(path: Path) -> None:
    """Make the store at ``path`` look written by an earlier version: no node_x, node_y,
    the old ``mesh`` attributes, metadata consolidated again."""
    for name in store.NODE_COORDINATES:
        shutil.rmtree(path / name)
    group = zarr.open_group(path, mode="r+", use_consolidated=False)
    attrs = dict(group["mesh"].attrs)
    attrs["node_coordinates"] = "points"
    group["mesh"].attrs.put(attrs)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        zarr.consolidate_metadata(str(path))


def test_a_store_without_node_x_and_node_y_still_opens(tmp_path, client):
    import xarray as xr

    mesh = examples.plate_with_hole()
    store.create(tmp_path / "old.zarr", mesh, chunk_size=50)
    make_old(tmp_path / "old.zarr")
    assert "node_x" not in zarr.open_group(tmp_path / "old.zarr", mode="r")
    s = store.open(tmp_path / "old.zarr")
    assert (s.n_points, s.n_triangles) == (mesh.n_points, mesh.n_triangles)
    out = store.to_mesh(tmp_path / "old.zarr")
    for name in ("points", "triangles", "cell_tags", "edges", "edge_tags"):
        assert np.array_equal(getattr(out, name), getattr(mesh, name)), name
    store.to_file(tmp_path / "old.zarr", tmp_path / "old.msh")  # streamed, chunk by chunk
    assert np.array_equal(store.to_mesh(
        store.from_file(tmp_path / "old.msh", tmp_path / "back.zarr")).points, mesh.points)
    assert "node_x" not in xr.open_zarr(tmp_path / "old.zarr")
    # refining it (or copying it: zero levels) writes node_x, node_y from its points
    for levels in (0, 1):
        refine_store(tmp_path / "old.zarr", tmp_path / "new.zarr", "7t-qd", levels,
                     client=client)
        assert_xugrid_sees(tmp_path / "new.zarr", refine(mesh, "7t-qd", levels))
