"""Mesh files into stores and stores into mesh files: :func:`create` from a ``Mesh``,
:func:`from_file`, and :func:`to_file`, which streams Gmsh MSH 2.2 and Triangle files
chunk by chunk."""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..io import FORMATS, atomic_path, read, write
from ..mesh import Mesh
from .layout import (
    ARRAYS,
    DEFAULT_CHUNK_SIZE,
    MeshStore,
    as_store,
    chunk_size_of,
    new_group,
    open,
    to_mesh,
)
from .lifecycle import writing
from .locations import PathLike, location

__all__ = ["create", "from_file", "to_file", "STREAMING_EXPORT", "rows"]

#: Extensions that :func:`to_file` writes chunk by chunk (everything else: in memory).
STREAMING_EXPORT = (".msh", ".node", ".ele", ".poly")


def create(path: PathLike, mesh: Mesh, chunk_size: int = DEFAULT_CHUNK_SIZE,
           metadata: Mapping[str, Any] | None = None) -> MeshStore:
    """Write ``mesh`` as a store at ``path`` (complete or absent) and open it.

    Parameters
    ----------
    path : str or os.PathLike
        Local directory to create (by convention ``name.zarr``) or URL; an existing store
        is replaced.
    mesh : Mesh
    chunk_size : int, > 0
        Rows per chunk of every array.
    metadata : mapping, optional
        JSON-serializable metadata kept with the mesh.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from qdrefine import examples, store
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "plate.zarr"
    >>> s = store.create(path, examples.plate_with_hole(), chunk_size=100)
    >>> s.triangles.chunks[0]
    (100, 100, 100, 84)
    """
    if not isinstance(mesh, Mesh):
        raise TypeError(f"create() needs a Mesh, got {type(mesh).__name__}")
    chunk_size = chunk_size_of(chunk_size)
    url = location(path)
    arrays = {name: getattr(mesh, name) for name in ARRAYS}
    with writing(url) as tmp:
        group = new_group(tmp, {k: spec_of(v) for k, v in arrays.items()}, chunk_size,
                          metadata)
        for name, value in arrays.items():
            if value is not None and len(value):
                group[name][...] = value
    return open(url)


def spec_of(value: NDArray | None) -> tuple[tuple[int, ...], np.dtype] | None:
    return None if value is None else (value.shape, value.dtype)


def from_file(mesh_path: PathLike, path: PathLike, chunk_size: int = DEFAULT_CHUNK_SIZE,
              metadata: Mapping[str, Any] | None = None) -> MeshStore:
    """Read any mesh file of :func:`qdrefine.read` (in memory) into a new store at ``path``."""
    mesh = read(mesh_path)
    meta = {"source": str(mesh_path), **dict(metadata or {})}
    return create(path, mesh, chunk_size, meta)


def to_file(store: MeshStore | PathLike, mesh_path: PathLike, *,
            binary: bool | None = None, compress: bool = False) -> None:
    """Write a store to a mesh file of :func:`qdrefine.write` (format by extension).

    ``.msh`` (Gmsh 2.2, text unless ``binary=True``) and Triangle's ``.node/.ele/.poly`` are
    written chunk by chunk, with the same content as :func:`qdrefine.write` would write for
    :func:`to_mesh` of the store; the rows are not validated again. Every other format loads
    the mesh (validated) and calls :func:`qdrefine.write`.
    """
    s = as_store(store)
    mesh_path = Path(mesh_path)
    ext = mesh_path.suffix.lower()
    if ext not in STREAMING_EXPORT:
        write(mesh_path, to_mesh(s), binary=binary, compress=compress)
        return
    if compress:
        raise ValueError(f"{mesh_path}: compression applies to .vtu and .xdmf files only")
    if binary and ext != ".msh":
        raise ValueError(f"{mesh_path}: {FORMATS[ext].name} files have no binary variant")
    if s.edge_tags is not None and any_zero(s, "edge_tags"):
        warnings.warn(f"{mesh_path}: some edges have tag 0, which reads back as untagged",
                      stacklevel=2)
    if ext == ".msh":
        write_gmsh(s, mesh_path, bool(binary))
    else:
        write_triangle(s, mesh_path)


def any_zero(s: MeshStore, name: str) -> bool:
    return any(bool((block == 0).any()) for _, block in rows(s, name))


def rows(s: MeshStore, name: str, step: int | None = None) -> Iterator[tuple[int, NDArray]]:
    """``(start, rows)`` of array ``name``, ``step`` rows (default: its chunk) at a time."""
    z = s.zarr_array(name)
    step = step or z.chunks[0]
    for start in range(0, z.shape[0], step):
        yield start, z[start:start + step]


def rows_between(s: MeshStore, name: str, start: int, stop: int) -> NDArray:
    return s.zarr_array(name)[start:stop]


def cell_tags_between(s: MeshStore, start: int, stop: int) -> NDArray:
    if s.cell_tags is None:
        return np.zeros(stop - start, dtype=np.int64)
    return rows_between(s, "cell_tags", start, stop)


def write_gmsh(s: MeshStore, path: Path, binary: bool) -> None:
    with atomic_path(path) as tmp, tmp.open("wb") as f:
        f.write(f"$MeshFormat\n2.2 {int(binary)} 8\n".encode())
        if binary:
            np.array([1], dtype=np.int32).tofile(f)
            f.write(b"\n")
        f.write(f"$EndMeshFormat\n$Nodes\n{s.n_points}\n".encode())
        for start, p in rows(s, "points"):
            ids = np.arange(start + 1, start + 1 + len(p))
            gmsh_nodes(f, ids, p, binary)
        f.write(b"\n" if binary else b"")
        f.write(f"$EndNodes\n$Elements\n{s.n_edges + s.n_triangles}\n".encode())
        first = 1
        if s.edges is not None:
            for start, e in rows(s, "edges"):
                tag = rows_between(s, "edge_tags", start, start + len(e))
                gmsh_elements(f, 1, first + start, tag, e, binary)
            first += s.n_edges
        for start, t in rows(s, "triangles"):
            tag = cell_tags_between(s, start, start + len(t))
            gmsh_elements(f, 2, first + start, tag, t, binary)
        f.write(b"\n" if binary else b"")
        f.write(b"$EndElements\n")


def gmsh_nodes(f, ids: NDArray, p: NDArray, binary: bool) -> None:
    if binary:
        rows = np.empty(len(p), dtype=[("id", np.int32), ("x", np.float64, (3,))])
        rows["id"] = ids
        rows["x"][:, :2] = p
        rows["x"][:, 2] = 0.0
        rows.tofile(f)
    else:
        np.savetxt(f, np.column_stack([ids, p]), fmt="%d %.17g %.17g 0")


def gmsh_elements(f, kind: int, first: int, tag: NDArray, cells: NDArray,
                   binary: bool) -> None:
    """Gmsh 2.2 elements (1: line, 2: triangle) with physical and geometrical tags, as
    :func:`qdrefine.write` writes them (geometrical = physical, 0 replaced by 1)."""
    ids = np.arange(first, first + len(cells), dtype=np.int64)
    geom = np.where(tag == 0, 1, tag)
    if binary:
        np.array([kind, len(cells), 2], dtype=np.int32).tofile(f)
        rows = np.column_stack([ids, tag, geom, cells.astype(np.int64) + 1])
        rows.astype(np.int32).tofile(f)
    else:
        rows = np.column_stack([ids, np.full(len(cells), kind), np.full(len(cells), 2),
                                tag, geom, cells.astype(np.int64) + 1])
        np.savetxt(f, rows, fmt="%d")


def write_triangle(s: MeshStore, path: Path) -> None:
    base = path.with_suffix("")
    with atomic_path(base.with_suffix(".node")) as tmp, tmp.open("w") as f:
        f.write(f"# written by qdrefine\n{s.n_points} 2 0 0\n")
        for start, p in rows(s, "points"):
            ids = np.arange(start, start + len(p))
            np.savetxt(f, np.column_stack([ids, p]), fmt="%d %.17g %.17g")
    with atomic_path(base.with_suffix(".ele")) as tmp, tmp.open("w") as f:
        tagged = s.cell_tags is not None
        f.write(f"{s.n_triangles} 3 {int(tagged)}\n")
        for start, t in rows(s, "triangles"):
            cols = [np.arange(start, start + len(t)), t]
            if tagged:
                cols.append(cell_tags_between(s, start, start + len(t)))
            np.savetxt(f, np.column_stack(cols), fmt="%d")
    with atomic_path(base.with_suffix(".poly")) as tmp, tmp.open("w") as f:
        f.write(f"# vertices are in the .node file\n0 2 0 0\n{s.n_edges} 1\n")
        if s.edges is not None:
            for start, e in rows(s, "edges"):
                tag = rows_between(s, "edge_tags", start, start + len(e))
                np.savetxt(f, np.column_stack([np.arange(start, start + len(e)), e, tag]),
                           fmt="%d")
        f.write("0\n")
