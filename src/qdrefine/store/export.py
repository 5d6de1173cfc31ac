"""Mesh files into stores and stores into mesh files: :func:`create` from a ``Mesh``,
:func:`from_file`, and :func:`to_file`, which streams Gmsh MSH (4.1 or 2.2, by the Gmsh
writer itself) and Triangle files chunk by chunk."""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..io import FORMATS, GMSH_VERSIONS, read, triangle, write
from ..io.gmsh import writing as gmsh_writing
from ..mesh import Mesh, need_mesh
from .layout import (
    ARRAYS,
    DEFAULT_CHUNK_SIZE,
    FILL,
    MeshStore,
    as_store,
    chunk_size_of,
    new_group,
    node_coordinates,
    open,
    to_mesh,
)
from .lifecycle import writing
from .locations import PathLike, location, overlap
from .reading import read_rows, written

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
    chunk_size : int, 1 .. 2**24
        Rows per chunk of every array (a chunk is made whole in memory to be written).
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
    need_mesh(mesh, "create")
    chunk_size = chunk_size_of(chunk_size)
    url = location(path)
    arrays = {name: getattr(mesh, name) for name in ARRAYS}
    for name in ("cell_tags", "edge_tags"):
        if arrays[name] is not None and (np.asarray(arrays[name]) == FILL[name]).any():
            raise ValueError(f"{url}: {name} holds {FILL[name]}, the store's mark of chunks "
                             "that were never written; it cannot be stored")
    dropped = [what for what, held in (
        ("point data", mesh.point_data), ("cell data", mesh.cell_data),
        ("physical names", mesh.physical_names),
        ("the refinement history", mesh.transitions is not None or mesh.origins is not None))
        if held]
    with writing(url) as tmp:  # the target checked first: no warning before a refusal
        if dropped:  # as qdrefine.write warns for a format that cannot hold them
            warnings.warn(f"{url}: mesh stores hold points, triangles, cell tags and tagged "
                          f"edges; {', '.join(dropped)} {'are' if _plural(dropped) else 'is'} "
                          "dropped", stacklevel=2)
        group = new_group(tmp, {k: spec_of(v) for k, v in arrays.items()}, chunk_size,
                          metadata)
        for name, value in (arrays | node_coordinates(mesh.points)).items():
            if value is not None and len(value):
                group[name][...] = value
    return open(url)


def _plural(things: list[str]) -> bool:
    """Whether the list ``things`` takes "are": several, or one plural noun ("physical
    names is dropped"; review)."""
    return len(things) > 1 or things[0].endswith("names")


def spec_of(value: NDArray | None) -> tuple[tuple[int, ...], np.dtype] | None:
    return None if value is None else (value.shape, value.dtype)


def from_file(mesh_path: PathLike, path: PathLike, chunk_size: int = DEFAULT_CHUNK_SIZE,
              metadata: Mapping[str, Any] | None = None) -> MeshStore:
    """Read any mesh file of :func:`qdrefine.read` (in memory) into a new store at ``path``
    (not one that holds ``mesh_path``: writing replaces the store as a whole)."""
    clash = overlap(location(path), mesh_path)
    if clash:
        raise ValueError(f"{location(path)}: {clash}; choose another path")
    mesh = read(mesh_path)
    meta = {"source": str(mesh_path), **dict(metadata or {})}
    return create(path, mesh, chunk_size, meta)


def to_file(store: MeshStore | PathLike, mesh_path: PathLike, *,
            binary: bool | None = None, compress: bool = False,
            format_version: str | None = None) -> None:
    """Write a store to a mesh file of :func:`qdrefine.write` (format by extension).

    ``.msh`` (Gmsh MSH ``format_version``, 4.1 unless ``"2.2"``, text unless ``binary=True``)
    and Triangle's ``.node/.ele/.poly`` are written chunk by chunk, with the same content as
    :func:`qdrefine.write` would write for :func:`to_mesh` of the store; each block is
    checked for what would make the file unreadable (unwritten chunks, vertex indices
    outside the points, coordinates that are not finite), not validated as a mesh again.
    Every other format loads the mesh (validated) and calls :func:`qdrefine.write`.
    """
    s = as_store(store)
    clash = overlap(location(mesh_path), s.path)
    if clash:
        raise ValueError(f"{mesh_path}: {clash}; choose another path")
    mesh_path = Path(mesh_path)
    ext = mesh_path.suffix.lower()
    if format_version is not None and ext != ".msh":
        raise ValueError(f"{mesh_path}: format_version applies to Gmsh .msh files only")
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
        gmsh_writing.write_chunks(mesh_path, _chunks(s), binary=bool(binary),
                                  version=format_version or GMSH_VERSIONS[0])
    else:
        triangle.write_chunks(mesh_path, _chunks(s))


def _chunks(s: MeshStore) -> gmsh_writing.Chunks:
    """The store as :class:`qdrefine.io.gmsh.writing.Chunks` (its own chunks; tags read by
    rows, however they are chunked)."""
    def of(name: str):
        return None if getattr(s, name) is None else (lambda: rows(s, name))

    def tags(name: str):
        return None if getattr(s, name) is None else (
            lambda a, b: rows_between(s, name, a, b))

    return gmsh_writing.Chunks(s.n_points, s.n_triangles, s.n_edges, of("points"),
                               of("triangles"), tags("cell_tags"), of("edges"),
                               tags("edge_tags"))


def any_zero(s: MeshStore, name: str) -> bool:
    return any(bool((block == 0).any()) for _, block in rows(s, name))


def rows(s: MeshStore, name: str, step: int | None = None) -> Iterator[tuple[int, NDArray]]:
    """``(start, rows)`` of array ``name``, ``step`` rows (default: its chunk) at a time;
    rows that hold the fill value of unwritten chunks are refused."""
    z = s.zarr_array(name)
    step = step or z.chunks[0]
    for start in range(0, z.shape[0], step):
        block = read_rows(s.path, z, name, start, min(start + step, z.shape[0]))
        yield start, written(s.path, s.n_points, name, start, block)


def rows_between(s: MeshStore, name: str, start: int, stop: int) -> NDArray:
    block = read_rows(s.path, s.zarr_array(name), name, start, stop)
    return written(s.path, s.n_points, name, start, block)
