"""The layout of a mesh store: its arrays, dimension names, fill values, chunks,
compression and attributes (UGRID 1.0 topology, the ``qdrefine`` attribute); creating an
empty store, marking it complete, and opening, checking and loading one (its rows are read
by :mod:`qdrefine.store.reading`).

The library reads :data:`ARRAYS`. For UGRID readers (xugrid), a store also holds the node
coordinates as two 1-D arrays (:data:`NODE_COORDINATES`: the columns of ``points``, written
with it); reading never needs them, so the stores of earlier versions, which lack them,
still open."""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..mesh import Mesh
from .locations import PathLike, filesystem, location
from .reading import FILL, read_rows, written

if TYPE_CHECKING:
    import dask.array

__all__ = ["DEFAULT_CHUNK_SIZE", "FORMAT", "VERSION", "READABLE", "ARRAYS", "COLUMNS",
           "NODE_COORDINATES", "CONVENTIONS", "DIMENSIONS", "FILL", "ATTRIBUTES",
           "MeshStore", "new_group", "node_coordinates", "ugrid", "finish", "is_store",
           "open", "to_mesh", "as_store", "chunk_size_of"]

#: Rows per chunk unless chosen: 262144 triangles are 3 MiB of int32 indices.
DEFAULT_CHUNK_SIZE = 1 << 18

#: Extensions that :func:`to_file` writes chunk by chunk (everything else: in memory).
STREAMING_EXPORT = (".msh", ".node", ".ele", ".poly")

FORMAT, VERSION = "mesh", 2
#: Versions :func:`open` reads (version 1: no completion attribute, written by rename only).
READABLE = (1, 2)
ARRAYS = ("points", "triangles", "cell_tags", "edges", "edge_tags")
COLUMNS = {"points": 2, "triangles": 3, "cell_tags": 0, "edges": 2, "edge_tags": 0}
#: The group attribute ``Conventions`` (as UGRID 1.0 recommends).
CONVENTIONS = "UGRID-1.0"
#: UGRID's node coordinates: the columns of ``points`` as 1-D arrays, in every store that
#: has ``points`` (chunked as it), never read by the library.
NODE_COORDINATES = ("node_x", "node_y")
#: Zarr dimension names of every array (xarray needs them; shared names share sizes).
DIMENSIONS = {"points": ("node", "xy"), "node_x": ("node",), "node_y": ("node",),
              "triangles": ("face", "corner"), "cell_tags": ("face",),
              "edges": ("edge", "end"), "edge_tags": ("edge",)}
#: Attributes of every array (UGRID 1.0 / CF). The tagged edges are a subset of the mesh's
#: edges (boundary and interface pieces), so they are not UGRID's ``edge_node_connectivity``,
#: which lists every edge: readers would take them for the mesh's edges (xugrid then refuses
#: to derive its face-edge connectivity).
ATTRIBUTES: dict[str, dict[str, Any]] = {
    "points": {"long_name": "node coordinates (x, y); the same as node_x, node_y"},
    "node_x": {"standard_name": "projection_x_coordinate",
               "long_name": "x coordinate of the mesh nodes"},
    "node_y": {"standard_name": "projection_y_coordinate",
               "long_name": "y coordinate of the mesh nodes"},
    "triangles": {"cf_role": "face_node_connectivity", "start_index": 0,
                  "long_name": "the three nodes of every triangle, counter-clockwise"},
    "cell_tags": {"mesh": "mesh", "location": "face", "long_name": "tag of every triangle"},
    "edges": {"start_index": 0,
              "long_name": "the two nodes of every tagged edge (not every edge of the mesh)"},
    "edge_tags": {"long_name": "tag of every tagged edge"},
}


@dataclass(frozen=True, eq=False)
class MeshStore:
    """A mesh store opened lazily: Dask arrays over the Zarr arrays, no data read.

    Attributes
    ----------
    path : str
        The store's URL, or its absolute path for a local store (:func:`location`).
    points : (N, 2) float64 dask array
    triangles : (M, 3) int dask array
    cell_tags : (M,) int64 dask array or None
    edges : (K, 2) int dask array or None
    edge_tags : (K,) int64 dask array or None
    metadata : dict
        Free-form JSON metadata (:func:`qdrefine.distributed.refine_store` records the
        scheme and levels there).
    """

    path: str
    points: dask.array.Array
    triangles: dask.array.Array
    cell_tags: dask.array.Array | None
    edges: dask.array.Array | None
    edge_tags: dask.array.Array | None
    metadata: Mapping[str, Any]

    @property
    def n_points(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    @property
    def n_edges(self) -> int:
        """Number of tagged edges (0 without)."""
        return 0 if self.edges is None else int(self.edges.shape[0])

    @property
    def chunk_size(self) -> int:
        """Rows per chunk of ``triangles``."""
        return int(self.triangles.chunks[0][0])

    def zarr_array(self, name: str):
        """The Zarr array ``name`` (for chunk-wise reading in tasks)."""
        import zarr

        return zarr.open_group(self.path, mode="r")[name]

    def to_mesh(self) -> Mesh:
        return to_mesh(self)

    def __repr__(self) -> str:
        tags = "" if self.cell_tags is None else ", cell tags"
        edges = "" if self.edges is None else f", {self.n_edges} tagged edges"
        return (f"MeshStore({self.path!r}: {self.n_points} points, {self.n_triangles} "
                f"triangles{tags}{edges}, chunks of {self.chunk_size})")


def new_group(url: str, specs: Mapping[str, tuple[tuple[int, ...], Any] | None],
              chunk_size: int | Mapping[str, int], metadata: Mapping[str, Any] | None = None):
    """An empty, incomplete store at ``url``: ``specs`` maps array names to
    ``(shape, dtype)`` or None.

    ``chunk_size`` is the rows per chunk of every array, or a mapping per array name.
    With ``points``, the arrays :data:`NODE_COORDINATES` are created too (``(N,)`` float64,
    chunked as ``points``): whoever writes ``points`` writes them, from
    :func:`node_coordinates`. Returns the Zarr group, ready for chunk-wise writes;
    :func:`writing` marks it complete.
    """
    import zarr

    from .. import __version__

    rows = {name: chunk_size[name] if isinstance(chunk_size, Mapping) else chunk_size
            for name, spec in specs.items() if spec is not None}
    attrs = {"format": FORMAT, "version": VERSION, "complete": False,
             "chunk_size": chunk_size_of(rows["triangles"], False),
             "qdrefine_version": __version__,
             "metadata": dict(metadata or {})}
    group = zarr.create_group(store=url, attributes={"qdrefine": attrs,
                                                     "Conventions": CONVENTIONS})
    arrays = {name: spec for name, spec in specs.items() if spec is not None}
    if "points" in arrays:
        shape, _ = arrays["points"]
        arrays |= {name: ((shape[0],), np.float64) for name in NODE_COORDINATES}
        rows |= {name: rows["points"] for name in NODE_COORDINATES}
    for name, (shape, dtype) in arrays.items():
        chunks = (chunk_size_of(rows[name], False),) + tuple(shape[1:])  # create() limits
        group.create_array(name, shape=shape, chunks=chunks, dtype=dtype,
                           fill_value=FILL[name], compressors=compressor(),
                           dimension_names=DIMENSIONS[name], attributes=ATTRIBUTES[name])
    group.create_array("mesh", shape=(), dtype=np.int32, fill_value=0, attributes=ugrid())
    return group


def node_coordinates(points: Any) -> dict[str, Any]:
    """``{"node_x": points[:, 0], "node_y": points[:, 1]}``: what to write to the arrays
    :data:`NODE_COORDINATES` wherever ``points (N, 2)`` (NumPy or Dask) is written."""
    return {name: points[:, i] for i, name in enumerate(NODE_COORDINATES)}


def ugrid() -> dict[str, Any]:
    """UGRID 1.0 attributes of the ``mesh`` topology variable: a 2D mesh of triangles with
    node coordinates ``node_x node_y`` and face-node connectivity ``triangles``
    (0-based). No ``edge_node_connectivity``: see :data:`ATTRIBUTES`."""
    return {"cf_role": "mesh_topology", "long_name": "2D triangle mesh (qdrefine)",
            "topology_dimension": 2, "node_dimension": "node", "face_dimension": "face",
            "node_coordinates": "node_x node_y", "face_node_connectivity": "triangles"}


def compressor():
    """Blosc LZ4 with byte shuffle: several times faster than Zarr's default Zstandard
    here, and it compresses index arrays better."""
    from zarr.codecs import BloscCodec

    return BloscCodec(cname="lz4", clevel=5, shuffle="shuffle")


#: The most rows per chunk: a chunk is made whole in memory when it is written (one of
#: points takes 16 bytes a row, 256 MiB at this size), even for an array of fewer rows.
MAX_CHUNK_SIZE = 1 << 24


def chunk_size_of(value: object, limit: bool = True) -> int:
    """``value`` as rows per chunk; ``ValueError`` unless ``1 <= value <=``
    :data:`MAX_CHUNK_SIZE` (``2**32`` asked for 64 GiB for 5 points; review). ``limit=False``
    (a refined store chunked as its source, whatever wrote the source): no upper bound."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value <= 0:
        raise ValueError(f"chunk_size must be a positive integer, got {value!r}")
    if limit and value > MAX_CHUNK_SIZE:
        raise ValueError(f"chunk_size must be at most {MAX_CHUNK_SIZE} rows (2**24; a chunk is "
                         f"made whole in memory to be written), got {value}")
    return int(value)


def finish(url: str) -> None:
    """Mark the store at ``url`` complete and consolidate its metadata: the last write."""
    import zarr

    group = zarr.open_group(url, mode="r+", use_consolidated=False)
    attrs = dict(group.attrs["qdrefine"])
    attrs["complete"] = True
    group.attrs["qdrefine"] = attrs
    with warnings.catch_warnings():  # "consolidated metadata is not part of Zarr 3's spec"
        warnings.simplefilter("ignore", UserWarning)
        zarr.consolidate_metadata(url)


def is_store(path: PathLike, complete: bool = True) -> bool:
    """Whether ``path`` holds a qdrefine mesh store (``complete=False``: also one that a
    run did not finish)."""
    try:
        group_of(location(path), complete)
    except (OSError, ValueError):
        return False
    return True


def group_of(url: str, complete: bool = True):
    import zarr

    fs, root = filesystem(url)
    if not fs.exists(root):
        raise FileNotFoundError(f"{url}: no such mesh store")
    if fs.isfile(root):
        raise ValueError(f"{url}: not a mesh store (a store is a directory, this is a file)")
    try:
        group = zarr.open_group(url, mode="r")
    except (FileNotFoundError, ValueError, KeyError, TypeError):
        raise ValueError(f"{url}: not a mesh store (no Zarr group)") from None
    attrs = group.attrs.get("qdrefine")
    if not isinstance(attrs, dict) or attrs.get("format") != FORMAT:
        raise ValueError(f"{url}: not a qdrefine mesh store (Zarr group without the "
                         "'qdrefine' attribute)")
    if attrs.get("version") not in READABLE:
        raise ValueError(f"{url}: mesh store version {attrs.get('version')!r} is not "
                         f"supported (this qdrefine reads versions "
                         f"{', '.join(map(str, READABLE))})")
    if complete and attrs.get("version") != 1 and attrs.get("complete") is not True:
        raise ValueError(f"{url}: incomplete mesh store (the run writing it did not finish); "
                         "write it again, or remove it")
    return group


def open(path: PathLike) -> MeshStore:
    """Open the store at ``path`` (local path or URL) lazily (Dask arrays; nothing loaded).

    The arrays' names, shapes and dtypes are checked here; their content (index ranges,
    orientation, coordinates, tagged edges) when the mesh is loaded by :func:`to_mesh` or
    refined by :func:`qdrefine.distributed.refine_store`, chunk by chunk.

    Raises
    ------
    FileNotFoundError
        Nothing at ``path``.
    ValueError
        ``path`` is not a complete qdrefine mesh store, or an array is missing or
        malformed; the message names the store and the array.
    """
    import dask.array as da

    url = location(path)
    group = group_of(url)
    try:
        present = set(group.array_keys())
    except (ValueError, TypeError, KeyError) as exc:  # e.g. a damaged zarr.json
        raise ValueError(f"{url}: its arrays cannot be listed ({exc}): the store is "
                         "damaged") from None
    arrays: dict[str, Any] = {}
    for name in ARRAYS:
        try:
            arrays[name] = da.from_zarr(group[name]) if name in present else None
        except (ValueError, TypeError, KeyError) as exc:  # e.g. a damaged zarr.json
            raise ValueError(f"{url}: array '{name}' cannot be opened ({exc})") from None
    check_arrays(url, arrays)
    metadata = group.attrs["qdrefine"].get("metadata") or {}
    if not isinstance(metadata, dict):
        raise ValueError(f"{url}: the 'qdrefine' attribute's metadata is not a mapping: the "
                         "store is damaged")
    return MeshStore(url, metadata=dict(metadata), **arrays)


def check_arrays(path: str, arrays: Mapping[str, Any]) -> None:
    for name in ("points", "triangles"):
        if arrays[name] is None:
            raise ValueError(f"{path}: the store has no '{name}' array")
    if (arrays["edges"] is None) != (arrays["edge_tags"] is None):
        raise ValueError(f"{path}: 'edges' and 'edge_tags' must be stored together")
    for name, a in arrays.items():
        if a is None:
            continue
        cols = COLUMNS[name]
        shape_ok = a.ndim == 1 if cols == 0 else (a.ndim == 2 and a.shape[1] == cols)
        if not shape_ok:
            want = "(rows,)" if cols == 0 else f"(rows, {cols})"
            raise ValueError(f"{path}: array '{name}' has shape {a.shape}, expected {want}")
        kind = np.float64 if name == "points" else np.integer
        if not np.issubdtype(a.dtype, kind):
            raise ValueError(f"{path}: array '{name}' has dtype {a.dtype}, expected "
                             f"{'float64' if name == 'points' else 'integers'}")
    m = arrays["triangles"].shape[0]
    if m == 0:
        raise ValueError(f"{path}: the mesh has no triangles")
    if arrays["cell_tags"] is not None and arrays["cell_tags"].shape[0] != m:
        raise ValueError(f"{path}: 'cell_tags' has {arrays['cell_tags'].shape[0]} rows, "
                         f"'triangles' {m}")
    if arrays["edges"] is not None and arrays["edges"].shape[0] != arrays["edge_tags"].shape[0]:
        raise ValueError(f"{path}: 'edges' has {arrays['edges'].shape[0]} rows, 'edge_tags' "
                         f"{arrays['edge_tags'].shape[0]}")


def as_store(store: MeshStore | PathLike) -> MeshStore:
    return store if isinstance(store, MeshStore) else open(store)


def to_mesh(store: MeshStore | PathLike) -> Mesh:
    """Load a whole store into memory as a validated :class:`~qdrefine.Mesh`.

    Raises ``ValueError`` naming the store and the first invalid triangle or edge.
    """
    s = as_store(store)
    group = group_of(s.path)
    values = {name: written(s.path, s.n_points, name, 0,
                            read_rows(s.path, group[name], name, 0, group[name].shape[0]))
              if getattr(s, name) is not None else None for name in ARRAYS}
    try:
        return Mesh(**values)
    except ValueError as exc:
        raise ValueError(f"{s.path}: {exc}") from None
