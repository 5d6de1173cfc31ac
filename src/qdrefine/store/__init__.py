"""Chunked meshes: a Zarr (v3) group of row-chunked arrays at any URL Zarr accepts, opened
lazily with Dask.

A store is a Zarr group (a local directory ``name.zarr``, or ``memory://``, ``s3://``,
``gs://`` ... through fsspec) holding the arrays of a :class:`~qdrefine.Mesh`::

    points     (N, 2) float64          dims (node, xy)       fill NaN
    node_x     (N,)   float64          dims (node,)          fill NaN, points[:, 0] (UGRID)
    node_y     (N,)   float64          dims (node,)          fill NaN, points[:, 1] (UGRID)
    triangles  (M, 3) int32 or int64   dims (face, corner)   fill -1, counter-clockwise
    cell_tags  (M,)   int64            dims (face,)          optional
    edges      (K, 2) int32 or int64   dims (edge, end)      fill -1, optional, with edge_tags
    edge_tags  (K,)   int64            dims (edge,)          optional, with edges
    mesh       ()     int32            UGRID mesh topology (attributes only)

chunked by ``C`` rows (:data:`DEFAULT_CHUNK_SIZE` unless chosen), Blosc LZ4 with byte
shuffle, with Zarr ``dimension_names`` and consolidated metadata. The layout is UGRID 1.0
(group attribute ``Conventions: UGRID-1.0``; ``mesh`` names ``node_x node_y`` as node
coordinates and ``triangles``, 0-based, as face-node connectivity), so that
``xarray.open_zarr`` opens a store as a Dataset and ``xugrid.open_zarr`` as a
``UgridDataset`` whose grid has exactly the mesh's points and triangles (both tested). The
tagged edges are plain variables, not UGRID's ``edge_node_connectivity``, which would list
every edge. qdrefine reads ``points``, never ``node_x``/``node_y``: stores of earlier
versions, which lack them, still open. The group attribute ``qdrefine`` holds ``{"format":
"mesh", "version": 2, "complete": true, "chunk_size": C, "qdrefine_version": ...,
"metadata": {...}}``; ``complete`` is written last, after every chunk, and :func:`open`
refuses a store without it. Unwritten chunks read as the fill values, which no valid mesh
has (a NaN coordinate, a vertex index -1).

:func:`create` writes a mesh, :func:`open` returns a :class:`MeshStore` of Dask arrays
without reading any data, :func:`to_mesh` loads (and validates) a store as a ``Mesh``.
:func:`from_file` and :func:`to_file` convert from and to every mesh file format of
:func:`qdrefine.read` / :func:`qdrefine.write`. Streaming (memory bounded by one chunk):

* writing a store to Gmsh ``.msh`` (MSH 4.1 or 2.2, text or binary) and to Triangle's
  ``.node/.ele/.poly`` goes chunk by chunk;
* every other conversion holds the whole mesh in memory (meshio reads and writes whole
  meshes; qdrefine validates a mesh file as a whole when reading it).

Stores are written through a temporary store next to the target, named
``.NAME~HOST~PID~TOKEN.tmp``, which replaces the target when complete (an existing *store*
is replaced; any other existing file or directory is refused). On a local filesystem the
replacement is a rename; on object stores, which cannot rename, the new store is moved
object by object with its root ``zarr.json`` last, after the old target's was removed: the
target is then complete or absent, never half-written. A run killed before the end leaves
its temporary store, which the next write to the same target removes when its process is
gone (same host), as does :func:`clean`. Dask and Zarr are imported only when a function
here is called.
"""

from __future__ import annotations

from .export import STREAMING_EXPORT, create, from_file, to_file
from .layout import (
    ARRAYS,
    DEFAULT_CHUNK_SIZE,
    DIMENSIONS,
    MAX_CHUNK_SIZE,
    NODE_COORDINATES,
    MeshStore,
    finish,
    is_store,
    new_group,
    node_coordinates,
    open,
    to_mesh,
)
from .lifecycle import clean, remove, writing
from .locations import PathLike, filesystem, is_local, location
from .reading import read_rows, written

__all__ = ["MeshStore", "create", "open", "to_mesh", "from_file", "to_file", "is_store",
           "clean", "location", "filesystem", "new_group", "finish", "remove", "writing",
           "node_coordinates", "DEFAULT_CHUNK_SIZE", "MAX_CHUNK_SIZE", "STREAMING_EXPORT", "ARRAYS",
           "NODE_COORDINATES", "DIMENSIONS", "PathLike", "is_local", "written",
           "read_rows"]
