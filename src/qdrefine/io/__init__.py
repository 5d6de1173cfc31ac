"""Reading and writing mesh files.

:func:`read` and :func:`write` choose the format from the file extension: one module per
format, registered in :data:`FORMATS`. Gmsh ``.msh`` (:mod:`.gmsh`), VTK XML ``.vtu``
(:mod:`.vtu`), XDMF + HDF5 (:mod:`.xdmf`) and Triangle's ``.node/.ele/.poly``
(:mod:`.triangle`) have readers and writers of their own, built for large meshes (whole
arrays at once); every other format goes through meshio (:mod:`.meshio_formats`, the only
module that imports it, lazily).

What each format keeps
----------------------
- Gmsh ``.msh``: **MSH 4.1** by default (``format_version="2.2"`` for 2.2), text unless
  ``binary=True``. The physical tag of each triangle is ``cell_tags``; line elements with a
  physical tag are tagged ``edges``; ``$PhysicalNames`` are ``physical_names``; point data
  and cell data are ``$NodeData`` / ``$ElementData`` views. 2.0-2.2 and 4.1 are read (4.0
  through meshio's 4.0 reader, which keeps one physical group per element).
- VTK XML ``.vtu``: binary (appended raw data) by default; line and triangle cells with the
  integer cell array ``tag``, point and cell data, physical names.
- XDMF ``.xdmf`` / ``.xmf``: XML plus an HDF5 file ``name.h5`` (both written as a set); tags,
  point and cell data, physical names.
- VTK legacy ``.vtk``: tags, point and cell data (no physical names).
- Medit ``.mesh``: the references of ``Triangles`` and ``Edges``.
- Triangle ``.node/.ele/.poly``: the first regional attribute of ``.ele`` is the cell tag;
  the segments of ``.poly`` with a nonzero boundary marker are the tagged edges.
- OFF, OBJ, STL, PLY hold triangles only.
What a format cannot hold is dropped on writing with one warning naming it.
:attr:`~qdrefine.Mesh.transitions` travels as the cell data ``qdrefine:transitions``
(3 integers per triangle), so the formats with cell data keep it.

A tag of 0 means "untagged", as in Gmsh (physical group 0) and Triangle (marker 0): line
cells or segments tagged 0 are not read as tagged edges, and triangles that are all tagged 0
give ``cell_tags = None``.

Checks on reading
-----------------
3D points are accepted when every z is 0; anything else is refused. Only linear triangles are
meshed; vertex and line cells are allowed alongside, any other cell type is refused.
Clockwise triangles are flipped to counter-clockwise with a warning. Every problem raises
``ValueError`` (bad content) or ``OSError`` (missing or unreadable file) whose message starts
with the file name (and the line or byte offset, where the reader knows it).

Writing is atomic: the data goes to temporary files in the target directory, which replace
the targets only once everything is written, so a failure never leaves a partial file.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..check import MIN_ANGLE, Checked, Problem, find
from ..memory import check_needed, reading_needed_for_bytes
from ..mesh import Mesh, _data, _names, history_rows, need_mesh
from . import gmsh, obj, triangle, vtu, xdmf
from ._core import RawMesh
from .atomic import (
    WRITE_ERRNOS,
    atomic_path,
    atomic_paths,
    cannot_write,
    make_directory,
    permission_bits,
)
from .meshio_formats import read_with_meshio, write_with_meshio

__all__ = ["read", "read_raw", "mesh_of", "check_file", "write", "FORMATS", "Format", "RawMesh",
           "atomic_path", "atomic_paths", "permission_bits", "GMSH_VERSIONS",
           "WRITE_ERRNOS", "cannot_write", "make_directory"]

PathLike = str | os.PathLike

#: The Gmsh MSH versions :func:`write` writes (the first is the default).
GMSH_VERSIONS = gmsh.VERSIONS


@dataclass(frozen=True)
class Format:
    """One file format: its name, meshio's name for it (``None``: not through meshio),
    whether it holds tags, whether it is written binary by default (``None``: text only),
    whether it holds point and cell data, and whether it holds physical names."""

    name: str
    meshio: str | None
    tags: bool
    binary: bool | None = None
    data: bool = False
    names: bool = False

    def reader(self) -> Callable[[Path], RawMesh]:
        own = _READERS.get(self.name)
        if own is not None:
            return own
        return lambda path: read_with_meshio(path, self.meshio, self.name)


_GMSH = Format("Gmsh MSH", "gmsh", True, False, True, True)
_VTU = Format("VTK XML unstructured grid", "vtu", True, True, True, True)
_XDMF = Format("XDMF", "xdmf", True, None, True, True)
_TRIANGLE = Format("Triangle .node/.ele/.poly", None, True)
_OBJ = Format("Wavefront OBJ", "obj", False)

#: Formats :func:`write` can compress (``compress=True``).
COMPRESSIBLE = (_VTU, _XDMF)

#: Known extensions (lower case) and their formats.
FORMATS: dict[str, Format] = {
    ".msh": _GMSH,
    ".vtk": Format("VTK legacy", "vtk", True, True, True),
    ".vtu": _VTU,
    ".xdmf": _XDMF,
    ".xmf": _XDMF,
    ".mesh": Format("Medit", "medit", True),
    ".off": Format("OFF", "off", False),
    ".obj": _OBJ,
    ".stl": Format("STL", "stl", False, False),
    ".ply": Format("PLY", "ply", False, True),
    ".node": _TRIANGLE,
    ".ele": _TRIANGLE,
    ".poly": _TRIANGLE,
}

_READERS: dict[str, Callable[[Path], RawMesh]] = {
    _GMSH.name: gmsh.read, _VTU.name: vtu.read, _XDMF.name: xdmf.read,
    _TRIANGLE.name: triangle.read, _OBJ.name: obj.read,
}


def _format_of(path: Path) -> Format:
    ext = path.suffix.lower()
    if ext not in FORMATS:
        known = ", ".join(FORMATS)
        what = f"extension '{path.suffix}'" if path.suffix else "no extension"
        if ext == ".zarr":  # a mesh store: another layer (qdrefine.store)
            raise ValueError(f"{path}: a Zarr mesh store, not a mesh file: qdrefine.store "
                             "reads it (command line: 'qdrefine convert STORE FILE' makes a "
                             "file of it; 'refine --dask' refines it)")
        raise ValueError(f"{path}: unknown file format ({what}); known extensions: {known}")
    return FORMATS[ext]


# --------------------------------------------------------------------------------------------
# reading


def read(path: PathLike) -> Mesh:
    """Read a triangle mesh from ``path``; the format follows the extension.

    Parameters
    ----------
    path : str or os.PathLike
        A file with an extension of :data:`FORMATS`. For Triangle files give any of
        ``name.node``, ``name.ele`` or ``name.poly``: ``name.node`` and ``name.ele`` are read,
        and ``name.poly`` too if it exists (its marked segments become tagged edges).

    Returns
    -------
    Mesh
        Points ``(N, 2)`` (z dropped when every z is 0), counter-clockwise triangles
        ``(M, 3)`` (clockwise ones flipped, with a warning), ``cell_tags (M,)`` and tagged
        ``edges (K, 2)``, ``point_data``, ``cell_data``, ``physical_names``,
        ``transitions`` and ``origins`` where the file has them.

    Raises
    ------
    OSError
        The file is missing or unreadable.
    ValueError
        Unknown extension, a corrupt file, or content that is not a valid flat triangle
        mesh (any error of :data:`qdrefine.check.KINDS`); the message starts with the file
        name (and the line or byte, where known) and names the first problem.
    """
    return mesh_of(read_raw(path))


def mesh_of(raw: RawMesh) -> Mesh:
    """The :class:`Mesh` of what a file (or a peer library's mesh) holds, checked as
    :func:`read` checks it."""
    for problem in raw.problems:
        if problem.severity == "error":
            raise ValueError(problem.message)
    found = find(raw.points, raw.triangles, raw.cell_tags, raw.edges, raw.edge_tags,
                 flip_clockwise=True, stop_at_error=True, warnings=False, base=raw.base,
                 point_numbers=raw.point_numbers, triangle_numbers=raw.triangle_numbers,
                 edge_numbers=raw.edge_numbers)
    problems = [raw.locate(p) for p in found.problems]
    for problem in problems:
        if problem.severity == "error":
            raise ValueError(problem.message)
        if problem.kind == "clockwise":
            warnings.warn(problem.message, stacklevel=3)
    point_data, cell_data, names, transitions, origins = _data_of(raw, found)
    return Mesh._trusted(found.points, found.triangles, found.cell_tags, found.edges,
                         found.edge_tags, point_data, cell_data, names, transitions,
                         buckets=found.buckets, origins=origins)


def _data_of(raw: RawMesh, found: Checked) -> tuple:
    """The point data, cell data, physical names, transitions and origins of ``raw``,
    checked against the mesh ``found`` in it; ``ValueError`` naming the file otherwise."""
    n, m = found.points.shape[0], found.triangles.shape[0]
    try:
        point_data = _data(raw.point_data, n, "point_data", "points")
        cell_data = _data(raw.cell_data, m, "cell_data", "triangles")
        names = _names(raw.physical_names)
        # a mirrored file: its history rows are flipped as its triangles are
        transitions, origins = history_rows(found.points, found.triangles, raw.transitions,
                                            raw.origins, flip=True)
    except ValueError as exc:
        raise ValueError(f"{raw.path}: {exc}") from None
    return point_data, cell_data, names, transitions, origins


def check_file(path: PathLike, min_angle: float = MIN_ANGLE) -> tuple[RawMesh, Checked]:
    """Every problem of a mesh file (:func:`qdrefine.check.find` on what the file holds).

    Raises ``OSError`` / ``ValueError`` only when the file cannot be read at all (missing,
    unknown format, corrupt); content problems are returned, each message starting with the
    file name (and line), as :func:`read` would raise them.
    """
    raw = read_raw(path)
    found = find(raw.points, raw.triangles, raw.cell_tags, raw.edges, raw.edge_tags,
                 flip_clockwise=True, min_angle=min_angle, geometry=raw.flat, base=raw.base,
                 point_numbers=raw.point_numbers, triangle_numbers=raw.triangle_numbers,
                 edge_numbers=raw.edge_numbers)
    seen = {p.kind for p in raw.problems}
    found.problems[:] = raw.problems + [raw.locate(p) for p in found.problems
                                        if p.kind not in seen]
    if found.ok:  # what read checks next: a file "usable" here was refused (review)
        try:
            _data_of(raw, found)
        except ValueError as exc:
            found.problems.append(Problem("data", str(exc)))
    return raw, found


def read_raw(path: PathLike) -> RawMesh:
    """The content of a mesh file without checking it as a mesh (see :func:`check_file`).

    Raises ``OSError`` (missing, unreadable) or ``ValueError`` (unknown format, corrupt or
    truncated file) with the file name first.
    """
    path = Path(path)
    reader = _format_of(path).reader()
    with contextlib.suppress(OSError):  # the reader says what is wrong
        if path.is_file() and path.stat().st_size == 0:  # each format said it its own way
            raise ValueError(f"{path}: the file is empty")  # ("meshio refused it ...")
    size = _bytes_of(path)
    check_needed(reading_needed_for_bytes(size),
                 f"reading {path} ({size / 2**20:.3g} MiB with the files it names)")
    return reader(path)


#: Companion files read with a mesh file: XDMF's HDF5 data, Triangle's three files.
_COMPANIONS = {".xdmf": (".h5",), ".xmf": (".h5",), ".node": (".ele", ".poly"),
               ".ele": (".node", ".poly"), ".poly": (".node", ".ele")}


def _bytes_of(path: Path) -> int:
    """Bytes of ``path`` and its companion files (0 for what does not exist: the reader
    says so)."""
    total = 0
    for p in (path, *(path.with_suffix(e) for e in _COMPANIONS.get(path.suffix.lower(), ()))):
        try:
            total += p.stat().st_size if p.is_file() else 0
        except OSError:
            pass
    return total


# --------------------------------------------------------------------------------------------
# writing


def write(path: PathLike, mesh: Mesh, *, binary: bool | None = None,
          format_version: str | None = None, compress: bool = False) -> None:
    """Write ``mesh`` to ``path``; the format follows the extension (see :data:`FORMATS`).

    Parameters
    ----------
    path : str or os.PathLike
    mesh : Mesh
    binary : bool, optional
        The binary variant of ``.msh``, ``.vtk``, ``.stl`` and ``.ply`` (other formats
        refuse ``binary=True``). By default ``.msh`` and ``.stl`` are text and ``.vtk``,
        ``.ply`` binary; ``.vtu`` is binary only (``binary=False`` is refused). Binary is
        several times faster for large meshes (``docs/performance.md``).
    format_version : {"4.1", "2.2"}, optional
        Gmsh ``.msh`` only: the MSH version (default 4.1, what current Gmsh writes).
    compress : bool
        ``.vtu`` (zlib-compressed appended data) and ``.xdmf`` (gzip-compressed HDF5
        datasets) only: smaller files, slower to write and read (``docs/performance.md``).

    Notes
    -----
    XDMF files come with their HDF5 file ``name.h5``. For Triangle files (``name.node``,
    ``name.ele`` or ``name.poly``) all three are written: ``.node`` (points), ``.ele``
    (triangles, with the cell tag as regional attribute) and ``.poly`` (no points of its own;
    the tagged edges as marked segments). Files written together replace their targets
    together, only once all are written.

    What the format cannot hold (tags; point and cell data; physical names) is dropped with
    a warning, as is any edge tag equal to 0 (0 reads as untagged).
    """
    need_mesh(mesh, "write")
    if os.fspath(path).endswith(("/", os.sep)):  # Path() drops it: "o.msh/" wrote o.msh
        raise ValueError(f"{os.fspath(path)}: a file name cannot end in '/' (it names a "
                         "directory)")
    path = Path(path)
    fmt = _format_of(path)
    if binary and fmt.binary is None:
        raise ValueError(f"{path}: {fmt.name} files have no binary variant")
    if format_version is not None and fmt is not _GMSH:
        raise ValueError(f"{path}: format_version applies to Gmsh .msh files only")
    if compress and fmt not in COMPRESSIBLE:
        raise ValueError(f"{path}: compression applies to .vtu and .xdmf files only")
    binary = fmt.binary if binary is None else bool(binary)
    if compress and fmt is _VTU and not binary:
        raise ValueError(f"{path}: compression applies to binary (appended) VTU only")
    if binary and path.suffix.lower() == ".stl":
        _check_float32(path, mesh)
    _warn_dropped(path, fmt, mesh)  # after the refusals: an error is one line
    if fmt is _GMSH:
        gmsh.write(path, mesh, binary=bool(binary),
                   version=format_version or GMSH_VERSIONS[0])
    elif fmt is _VTU:
        vtu.write(path, mesh, binary=bool(binary), compress=compress)
    elif fmt is _XDMF:
        xdmf.write(path, mesh, compress=compress)
    elif fmt is _TRIANGLE:
        triangle.write(path, mesh)
    elif fmt is _OBJ:
        obj.write(path, mesh)
    else:
        write_with_meshio(path, mesh, fmt.meshio, tags=fmt.tags, data=fmt.data,
                          binary=binary)


def _check_float32(path: Path, mesh: Mesh) -> None:
    """Binary STL stores float32: refuse points that would change (text STL is exact)."""
    p = np.asarray(mesh.points)
    changed = np.flatnonzero((p.astype(np.float32).astype(np.float64) != p).any(axis=1))
    if len(changed):
        i = int(changed[0])
        raise ValueError(f"{path}: binary STL stores float32 coordinates, and {len(changed)} "
                         f"of {len(p)} points would change (first: point {i} at "
                         f"{tuple(p[i].tolist())}); write text STL (without --binary) or "
                         "another format")


def _warn_dropped(path: Path, fmt: Format, mesh: Mesh) -> None:
    tagged = mesh.cell_tags is not None or mesh.edges is not None
    if tagged and not fmt.tags:
        warnings.warn(f"{path}: {fmt.name} files hold no tags; cell and edge tags are dropped",
                      stacklevel=3)
    elif mesh.edge_tags is not None and (mesh.edge_tags == 0).any():
        warnings.warn(f"{path}: {int((mesh.edge_tags == 0).sum())} edges have tag 0, which "
                      "reads back as untagged", stacklevel=3)
    data = [*(mesh.point_data or {}), *(mesh.cell_data or {})]
    if mesh.transitions is not None:
        data.append("transitions")
    if mesh.origins is not None:
        data.append("origins")
    if data and not fmt.data:
        held = ("hold no point or cell data" if fmt is not _TRIANGLE else  # attributes: read
                "are written without vertex attributes or any other data")
        warnings.warn(f"{path}: {fmt.name} files {held}; {', '.join(data)} dropped",
                      stacklevel=3)
    if mesh.physical_names and not fmt.names:
        warnings.warn(f"{path}: {fmt.name} files hold no physical names; they are dropped",
                      stacklevel=3)
