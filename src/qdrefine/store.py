"""Chunked meshes: a Zarr (v3) group of row-chunked arrays at any URL Zarr accepts, opened
lazily with Dask.

A store is a Zarr group (a local directory ``name.zarr``, or ``memory://``, ``s3://``,
``gs://`` ... through fsspec) holding the arrays of a :class:`~qdrefine.Mesh`::

    points     (N, 2) float64          dims (node, xy)       fill NaN
    triangles  (M, 3) int32 or int64   dims (face, corner)   fill -1, counter-clockwise
    cell_tags  (M,)   int64            dims (face,)          optional
    edges      (K, 2) int32 or int64   dims (edge, end)      fill -1, optional, with edge_tags
    edge_tags  (K,)   int64            dims (edge,)          optional, with edges
    mesh       ()     int32            UGRID mesh topology (attributes only)

chunked by ``C`` rows (:data:`DEFAULT_CHUNK_SIZE` unless chosen), Blosc LZ4 with byte
shuffle, with Zarr ``dimension_names`` and consolidated metadata, so that
``xarray.open_zarr`` opens a store. The group attribute ``qdrefine`` holds ``{"format":
"mesh", "version": 2, "complete": true, "chunk_size": C, "qdrefine_version": ...,
"metadata": {...}}``; ``complete`` is written last, after every chunk, and :func:`open`
refuses a store without it. Unwritten chunks read as the fill values, which no valid mesh
has (a NaN coordinate, a vertex index -1).

:func:`create` writes a mesh, :func:`open` returns a :class:`MeshStore` of Dask arrays
without reading any data, :func:`to_mesh` loads (and validates) a store as a ``Mesh``.
:func:`from_file` and :func:`to_file` convert from and to every mesh file format of
:func:`qdrefine.read` / :func:`qdrefine.write`. Streaming (memory bounded by one chunk):

* writing a store to Gmsh ``.msh`` (MSH 2.2, text or binary) and to Triangle's
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

import contextlib
import os
import socket
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .io import FORMATS, atomic_path, permission_bits, read, write
from .mesh import Mesh

if TYPE_CHECKING:
    import dask.array

__all__ = ["MeshStore", "create", "open", "to_mesh", "from_file", "to_file", "is_store",
           "clean", "location", "filesystem", "new_group", "finish", "remove", "writing",
           "DEFAULT_CHUNK_SIZE", "STREAMING_EXPORT"]

PathLike = str | os.PathLike

#: Rows per chunk unless chosen: 262144 triangles are 3 MiB of int32 indices.
DEFAULT_CHUNK_SIZE = 1 << 18

#: Extensions that :func:`to_file` writes chunk by chunk (everything else: in memory).
STREAMING_EXPORT = (".msh", ".node", ".ele", ".poly")

FORMAT, VERSION = "mesh", 2
#: Versions :func:`open` reads (version 1: no completion attribute, written by rename only).
READABLE = (1, 2)
ARRAYS = ("points", "triangles", "cell_tags", "edges", "edge_tags")
_COLUMNS = {"points": 2, "triangles": 3, "cell_tags": 0, "edges": 2, "edge_tags": 0}
#: Zarr dimension names of every array (xarray needs them; shared names share sizes).
DIMENSIONS = {"points": ("node", "xy"), "triangles": ("face", "corner"),
              "cell_tags": ("face",), "edges": ("edge", "end"), "edge_tags": ("edge",)}
#: Fill values of unwritten chunks: never valid (tags: the smallest int64).
FILL = {"points": float("nan"), "triangles": -1, "edges": -1,
        "cell_tags": int(np.iinfo(np.int64).min), "edge_tags": int(np.iinfo(np.int64).min)}
_TMP, _OLD = ".tmp", ".old"


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


# --------------------------------------------------------------------------------------------
# locations


def location(path: PathLike) -> str:
    """``path`` as the string every process can use: a URL (``scheme://...``) unchanged but
    for a trailing ``/``, a local path made absolute.

    >>> location("memory://a/b.zarr/")
    'memory://a/b.zarr'
    """
    text = os.fspath(path)
    if "://" in text:
        return text.rstrip("/")
    return os.path.abspath(text)


def is_local(url: str) -> bool:
    """Whether ``url`` (from :func:`location`) is a local path."""
    return "://" not in url or url.startswith("file://")


def filesystem(url: str):
    """``(fsspec filesystem, path within it)`` of ``url``, with no stale listings cached
    (object stores' filesystems cache directory listings that other writers change)."""
    import fsspec

    fs, root = fsspec.core.url_to_fs(url)
    fs.invalidate_cache()
    return fs, root


def _join(url: str, name: str) -> str:
    return f"{url}/{name}"


def _split(url: str) -> tuple[str, str]:
    """``(parent URL, name)``."""
    parent, _, name = url.rpartition("/")
    return parent, name


# --------------------------------------------------------------------------------------------
# creating


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
    chunk_size = _chunk_size(chunk_size)
    url = location(path)
    arrays = {name: getattr(mesh, name) for name in ARRAYS}
    with writing(url) as tmp:
        group = new_group(tmp, {k: _spec(v) for k, v in arrays.items()}, chunk_size,
                          metadata)
        for name, value in arrays.items():
            if value is not None and len(value):
                group[name][...] = value
    return open(url)


def _spec(value: NDArray | None) -> tuple[tuple[int, ...], np.dtype] | None:
    return None if value is None else (value.shape, value.dtype)


def new_group(url: str, specs: Mapping[str, tuple[tuple[int, ...], Any] | None],
              chunk_size: int | Mapping[str, int], metadata: Mapping[str, Any] | None = None):
    """An empty, incomplete store at ``url``: ``specs`` maps array names to
    ``(shape, dtype)`` or None.

    ``chunk_size`` is the rows per chunk of every array, or a mapping per array name.
    Returns the Zarr group, ready for chunk-wise writes; :func:`writing` marks it complete.
    """
    import zarr

    from . import __version__

    rows = {name: chunk_size[name] if isinstance(chunk_size, Mapping) else chunk_size
            for name, spec in specs.items() if spec is not None}
    attrs = {"format": FORMAT, "version": VERSION, "complete": False,
             "chunk_size": _chunk_size(rows["triangles"]), "qdrefine_version": __version__,
             "metadata": dict(metadata or {})}
    group = zarr.create_group(store=url, attributes={"qdrefine": attrs})
    for name, spec in specs.items():
        if spec is not None:
            shape, dtype = spec
            chunks = (_chunk_size(rows[name]),) + tuple(shape[1:])
            group.create_array(name, shape=shape, chunks=chunks, dtype=dtype,
                               fill_value=FILL[name], compressors=_compressor(),
                               dimension_names=DIMENSIONS[name])
    group.create_array("mesh", shape=(), dtype=np.int32, fill_value=0,
                       attributes=_ugrid(specs))
    return group


def _ugrid(specs: Mapping[str, Any]) -> dict[str, Any]:
    """UGRID-style attributes of the ``mesh`` topology variable (node coordinates are the
    two columns of ``points``, not separate ``node_x``/``node_y`` variables)."""
    attrs = {"cf_role": "mesh_topology", "long_name": "2D triangle mesh (qdrefine)",
             "topology_dimension": 2, "node_dimension": "node", "face_dimension": "face",
             "node_coordinates": "points", "face_node_connectivity": "triangles",
             "start_index": 0}
    if specs.get("edges") is not None:
        attrs |= {"edge_dimension": "edge", "edge_node_connectivity": "edges"}
    return attrs


def _compressor():
    """Blosc LZ4 with byte shuffle: several times faster than Zarr's default Zstandard
    here, and it compresses index arrays better."""
    from zarr.codecs import BloscCodec

    return BloscCodec(cname="lz4", clevel=5, shuffle="shuffle")


def _chunk_size(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value <= 0:
        raise ValueError(f"chunk_size must be a positive integer, got {value!r}")
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


@contextlib.contextmanager
def writing(path: PathLike) -> Iterator[str]:
    """Yield the URL of a fresh temporary store next to ``path``; on success it is marked
    complete and replaces ``path``.

    An existing store at ``path`` is replaced; an existing non-store is refused (before any
    work). Stale temporaries of earlier runs for the same target are removed first
    (:func:`clean`). On failure the temporary store is removed and ``path`` is left as it
    was.
    """
    url = location(path)
    _check_target(url)
    clean(url)
    tmp = _temporary(url, _TMP)
    fs, root = filesystem(tmp)
    try:
        if is_local(url):
            os.mkdir(root, permission_bits(Path(url), 0o777))
            os.chmod(root, permission_bits(Path(url), 0o777))
        yield tmp
        finish(tmp)
        _replace(tmp, url)
    except BaseException:
        remove(tmp)
        raise


def _temporary(url: str, suffix: str) -> str:
    """``.NAME~HOST~PID~TOKEN<suffix>`` next to ``url``: who made it, for :func:`clean`."""
    parent, name = _split(url)
    host = socket.gethostname().replace("~", "-").replace("/", "-")
    return _join(parent, f".{name}~{host}~{os.getpid()}~{os.urandom(4).hex()}{suffix}")


def _owner(entry: str, name: str) -> tuple[str, int] | None | bool:
    """For an entry of the target's parent: False if it is not a temporary of ``name``;
    ``(host, pid)`` of the run that made it; None when unknown (older qdrefine versions
    named them ``.NAME.XXXXXXXX.tmp`` / ``.work`` / ``.old``)."""
    if not entry.startswith(f".{name}"):
        return False
    rest = entry[len(name) + 1:]
    if rest.startswith("~") and rest.endswith((_TMP, _OLD)):
        fields = rest[1:].rsplit(".", 1)[0].split("~")
        if len(fields) == 3 and fields[1].isdigit():
            return fields[0], int(fields[1])
        return False
    if rest.startswith(".") and rest.endswith((_TMP, _OLD, ".work")) and rest.count(".") == 2:
        return None
    return False


def _alive(host: str, pid: int) -> bool:
    """Whether the run ``(host, pid)`` may still be going (another host: assumed so)."""
    if host != socket.gethostname().replace("~", "-").replace("/", "-"):
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean(path: PathLike, everything: bool = False) -> list[str]:
    """Remove the temporaries that runs writing ``path`` left behind; return their URLs.

    A temporary is removed when the process that made it is gone (same host) or its maker
    is unknown (older versions); with ``everything``, also those of running processes and
    of other hosts (when no run for ``path`` is in progress anywhere).
    """
    url = location(path)
    parent, name = _split(url)
    fs, root = filesystem(parent or "/")
    try:
        entries = [e.rstrip("/").rsplit("/", 1)[-1] for e in fs.ls(root, detail=False)]
    except (FileNotFoundError, NotADirectoryError):
        return []
    removed = []
    for entry in sorted(entries):
        owner = _owner(entry, name)
        if owner is False:
            continue
        if everything or owner is None or not _alive(*owner):
            remove(_join(parent, entry))
            removed.append(_join(parent, entry))
    return removed


def remove(url: str) -> None:
    """Remove whatever is at ``url`` (a store, a temporary), if anything."""
    fs, root = filesystem(url)
    with contextlib.suppress(FileNotFoundError, OSError):
        fs.rm(root, recursive=True)


def _check_target(url: str) -> None:
    fs, root = filesystem(url)
    if is_local(url):
        parent = os.path.dirname(root)
        if not os.path.isdir(parent):
            raise FileNotFoundError(f"{url}: directory {parent} does not exist")
    if fs.exists(root) and not is_store(url, complete=False):
        raise FileExistsError(f"{url}: exists and is not a qdrefine mesh store; refusing to "
                              "replace it")


def _replace(tmp: str, url: str) -> None:
    fs, root = filesystem(url)
    _, tmp_root = filesystem(tmp)
    if is_local(url):
        if not os.path.exists(root):
            os.rename(tmp_root, root)
            return
        old = filesystem(_temporary(url, _OLD))[1]
        os.rename(root, old)
        os.rename(tmp_root, root)
        remove(old)
        return
    # object stores: no rename. The old target's root zarr.json goes first (it is no longer
    # a store), the new one's last (it becomes one only when everything else is there).
    if fs.exists(root):
        with contextlib.suppress(FileNotFoundError):
            fs.rm(f"{root}/zarr.json")
        fs.rm(root, recursive=True)
    files = sorted(fs.find(tmp_root))
    head = f"{tmp_root}/zarr.json"
    for f in [f for f in files if f != head] + [head]:
        fs.mv(f, root + f[len(tmp_root):])
    remove(tmp)


# --------------------------------------------------------------------------------------------
# opening


def is_store(path: PathLike, complete: bool = True) -> bool:
    """Whether ``path`` holds a qdrefine mesh store (``complete=False``: also one that a
    run did not finish)."""
    try:
        _group(location(path), complete)
    except (OSError, ValueError):
        return False
    return True


def _group(url: str, complete: bool = True):
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
    group = _group(url)
    present = set(group.array_keys())
    arrays: dict[str, Any] = {}
    for name in ARRAYS:
        arrays[name] = da.from_zarr(group[name]) if name in present else None
    _check_arrays(url, arrays)
    metadata = dict(group.attrs["qdrefine"].get("metadata") or {})
    return MeshStore(url, metadata=metadata, **arrays)


def _check_arrays(path: str, arrays: Mapping[str, Any]) -> None:
    for name in ("points", "triangles"):
        if arrays[name] is None:
            raise ValueError(f"{path}: the store has no '{name}' array")
    if (arrays["edges"] is None) != (arrays["edge_tags"] is None):
        raise ValueError(f"{path}: 'edges' and 'edge_tags' must be stored together")
    for name, a in arrays.items():
        if a is None:
            continue
        cols = _COLUMNS[name]
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


def _as_store(store: MeshStore | PathLike) -> MeshStore:
    return store if isinstance(store, MeshStore) else open(store)


def to_mesh(store: MeshStore | PathLike) -> Mesh:
    """Load a whole store into memory as a validated :class:`~qdrefine.Mesh`.

    Raises ``ValueError`` naming the store and the first invalid triangle or edge.
    """
    s = _as_store(store)
    group = _group(s.path)
    values = {name: group[name][...] if getattr(s, name) is not None else None
              for name in ARRAYS}
    try:
        return Mesh(**values)
    except ValueError as exc:
        raise ValueError(f"{s.path}: {exc}") from None


# --------------------------------------------------------------------------------------------
# converting


def from_file(mesh_path: PathLike, path: PathLike, chunk_size: int = DEFAULT_CHUNK_SIZE,
              metadata: Mapping[str, Any] | None = None) -> MeshStore:
    """Read any mesh file of :func:`qdrefine.read` (in memory) into a new store at ``path``."""
    mesh = read(mesh_path)
    meta = {"source": str(mesh_path), **dict(metadata or {})}
    return create(path, mesh, chunk_size, meta)


def to_file(store: MeshStore | PathLike, mesh_path: PathLike, *,
            binary: bool | None = None) -> None:
    """Write a store to a mesh file of :func:`qdrefine.write` (format by extension).

    ``.msh`` (Gmsh 2.2, text unless ``binary=True``) and Triangle's ``.node/.ele/.poly`` are
    written chunk by chunk, with the same content as :func:`qdrefine.write` would write for
    :func:`to_mesh` of the store; the rows are not validated again. Every other format loads
    the mesh (validated) and calls :func:`qdrefine.write`.
    """
    s = _as_store(store)
    mesh_path = Path(mesh_path)
    ext = mesh_path.suffix.lower()
    if ext not in STREAMING_EXPORT:
        write(mesh_path, to_mesh(s), binary=binary)
        return
    if binary and ext != ".msh":
        raise ValueError(f"{mesh_path}: {FORMATS[ext].name} files have no binary variant")
    if s.edge_tags is not None and _any_zero(s, "edge_tags"):
        warnings.warn(f"{mesh_path}: some edges have tag 0, which reads back as untagged",
                      stacklevel=2)
    if ext == ".msh":
        _write_gmsh(s, mesh_path, bool(binary))
    else:
        _write_triangle(s, mesh_path)


def _any_zero(s: MeshStore, name: str) -> bool:
    return any(bool((block == 0).any()) for _, block in _rows(s, name))


def _rows(s: MeshStore, name: str, step: int | None = None) -> Iterator[tuple[int, NDArray]]:
    """``(start, rows)`` of array ``name``, ``step`` rows (default: its chunk) at a time."""
    z = s.zarr_array(name)
    step = step or z.chunks[0]
    for start in range(0, z.shape[0], step):
        yield start, z[start:start + step]


def _slice(s: MeshStore, name: str, start: int, stop: int) -> NDArray:
    return s.zarr_array(name)[start:stop]


def _cell_tags(s: MeshStore, start: int, stop: int) -> NDArray:
    if s.cell_tags is None:
        return np.zeros(stop - start, dtype=np.int64)
    return _slice(s, "cell_tags", start, stop)


def _write_gmsh(s: MeshStore, path: Path, binary: bool) -> None:
    with atomic_path(path) as tmp, tmp.open("wb") as f:
        f.write(f"$MeshFormat\n2.2 {int(binary)} 8\n".encode())
        if binary:
            np.array([1], dtype=np.int32).tofile(f)
            f.write(b"\n")
        f.write(f"$EndMeshFormat\n$Nodes\n{s.n_points}\n".encode())
        for start, p in _rows(s, "points"):
            ids = np.arange(start + 1, start + 1 + len(p))
            _gmsh_nodes(f, ids, p, binary)
        f.write(b"\n" if binary else b"")
        f.write(f"$EndNodes\n$Elements\n{s.n_edges + s.n_triangles}\n".encode())
        first = 1
        if s.edges is not None:
            for start, e in _rows(s, "edges"):
                tag = _slice(s, "edge_tags", start, start + len(e))
                _gmsh_elements(f, 1, first + start, tag, e, binary)
            first += s.n_edges
        for start, t in _rows(s, "triangles"):
            tag = _cell_tags(s, start, start + len(t))
            _gmsh_elements(f, 2, first + start, tag, t, binary)
        f.write(b"\n" if binary else b"")
        f.write(b"$EndElements\n")


def _gmsh_nodes(f, ids: NDArray, p: NDArray, binary: bool) -> None:
    if binary:
        rows = np.empty(len(p), dtype=[("id", np.int32), ("x", np.float64, (3,))])
        rows["id"] = ids
        rows["x"][:, :2] = p
        rows["x"][:, 2] = 0.0
        rows.tofile(f)
    else:
        np.savetxt(f, np.column_stack([ids, p]), fmt="%d %.17g %.17g 0")


def _gmsh_elements(f, kind: int, first: int, tag: NDArray, cells: NDArray,
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


def _write_triangle(s: MeshStore, path: Path) -> None:
    base = path.with_suffix("")
    with atomic_path(base.with_suffix(".node")) as tmp, tmp.open("w") as f:
        f.write(f"# written by qdrefine\n{s.n_points} 2 0 0\n")
        for start, p in _rows(s, "points"):
            ids = np.arange(start, start + len(p))
            np.savetxt(f, np.column_stack([ids, p]), fmt="%d %.17g %.17g")
    with atomic_path(base.with_suffix(".ele")) as tmp, tmp.open("w") as f:
        tagged = s.cell_tags is not None
        f.write(f"{s.n_triangles} 3 {int(tagged)}\n")
        for start, t in _rows(s, "triangles"):
            cols = [np.arange(start, start + len(t)), t]
            if tagged:
                cols.append(_cell_tags(s, start, start + len(t)))
            np.savetxt(f, np.column_stack(cols), fmt="%d")
    with atomic_path(base.with_suffix(".poly")) as tmp, tmp.open("w") as f:
        f.write(f"# vertices are in the .node file\n0 2 0 0\n{s.n_edges} 1\n")
        if s.edges is not None:
            for start, e in _rows(s, "edges"):
                tag = _slice(s, "edge_tags", start, start + len(e))
                np.savetxt(f, np.column_stack([np.arange(start, start + len(e)), e, tag]),
                           fmt="%d")
        f.write("0\n")
