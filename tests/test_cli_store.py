"""``qdrefine convert`` and ``qdrefine refine --dask`` through the real entry point."""

import subprocess
import sys

import numpy as np

import qdrefine
from qdrefine import examples, store
from qdrefine.cli import main


def cli(*args):
    return subprocess.run([sys.executable, "-m", "qdrefine", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


def _same(a: qdrefine.Mesh, b: qdrefine.Mesh) -> None:
    """Equal as sets of triangles by coordinates, with their cell tags."""
    def rows(m):
        xy = m.points[m.triangles]                      # (M, 3, 2)
        order = np.lexsort((xy[:, :, 1], xy[:, :, 0]))  # corners in a fixed order
        xy = np.take_along_axis(xy, order[:, :, None], axis=1).reshape(len(xy), 6)
        key = np.column_stack([xy, m.cell_tags])
        return key[np.lexsort(key.T[::-1])]

    np.testing.assert_array_equal(rows(a), rows(b))


def test_convert_round_trip_through_a_store(tmp_path):
    mesh = examples.plate_with_hole()
    qdrefine.write(tmp_path / "in.msh", mesh)
    result = cli("convert", tmp_path / "in.msh", tmp_path / "in.zarr", "--chunk-size", "50")
    assert result.returncode == 0 and result.stdout.endswith("written from "
                                                             f"{tmp_path / 'in.msh'}\n")
    assert store.open(tmp_path / "in.zarr").triangles.chunks[0][0] == 50
    assert main(["convert", str(tmp_path / "in.zarr"), str(tmp_path / "back.vtu"), "-q"]) == 0
    back = qdrefine.read(tmp_path / "back.vtu")
    np.testing.assert_array_equal(back.points, mesh.points)
    np.testing.assert_array_equal(back.triangles, mesh.triangles)
    np.testing.assert_array_equal(back.cell_tags, mesh.cell_tags)


def test_convert_refuses_chunk_size_for_a_file(tmp_path, capsys):
    qdrefine.write(tmp_path / "in.msh", examples.square(2))
    assert main(["convert", str(tmp_path / "in.msh"), str(tmp_path / "out.vtk"),
                 "--chunk-size", "5"]) == 1
    assert "--chunk-size applies to a .zarr output only" in capsys.readouterr().err
    assert not (tmp_path / "out.vtk").exists()


def test_refine_on_a_local_dask_cluster_equals_in_memory(tmp_path):
    mesh = examples.plate_with_hole()
    store.create(tmp_path / "in.zarr", mesh, chunk_size=64)
    result = cli("refine", tmp_path / "in.zarr", tmp_path / "out.zarr", "--levels", "2",
                 "--dask")
    assert result.returncode == 0, result.stderr
    assert "2 levels on" in result.stdout and "Dask worker" in result.stdout
    assert result.stderr.startswith("dask ")  # the dashboard link, or "dask cluster ready"
    _same(store.to_mesh(tmp_path / "out.zarr"), qdrefine.refine(mesh, "7t-qd", levels=2))


def test_dask_needs_stores_and_no_marks(tmp_path, capsys):
    qdrefine.write(tmp_path / "in.msh", examples.square(2))
    store.create(tmp_path / "in.zarr", examples.square(2))
    cases = [
        (("in.msh", "out.zarr"), "--dask needs a Zarr mesh store as IN"),
        (("in.zarr", "out.msh"), "expected a Zarr mesh store"),
        (("in.zarr", "out.zarr", "--mark-tag", "1"), "--dask refines every triangle"),
    ]
    for (src, dst, *extra), message in cases:
        capsys.readouterr()
        code = main(["refine", str(tmp_path / src), str(tmp_path / dst), "--dask", *extra])
        err = capsys.readouterr().err
        assert code == 1 and err.startswith("qdrefine: error: ") and message in err, err
        assert err.count("\n") == 1
        assert not (tmp_path / dst).exists()


def test_missing_optional_package_is_one_line(tmp_path, capsys, monkeypatch):
    qdrefine.write(tmp_path / "in.msh", examples.square(2))
    monkeypatch.setitem(sys.modules, "zarr", None)  # import zarr now fails
    assert main(["convert", str(tmp_path / "in.msh"), str(tmp_path / "in.zarr")]) == 1
    err = capsys.readouterr().err
    assert err == ("qdrefine: error: this needs the optional package 'zarr': "
                   "pip install 'qdrefine[dask]'\n")
    assert not (tmp_path / "in.zarr").exists()
