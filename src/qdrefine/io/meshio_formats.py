"""The long tail of formats through meshio (the only module that imports it, lazily).

VTK legacy, Medit, OFF, OBJ, STL and PLY, plus what the fast readers hand over (MSH 4.0,
VTU files in encodings other than appended raw / zlib). Tags are the cell data
``gmsh:physical``, ``medit:ref``, ``tag`` or ``cell_tags`` (the first found; the others
are read as cell data, as the VTU reader does, not dropped); VTK legacy files also carry
point and cell data.
"""

from __future__ import annotations

import contextlib
import io as io_module
import os
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._core import (
    SKIPPED_NAMES,
    TAG_NAMES,
    RawMesh,
    check_regular,
    from_blocks,
    mesh_data,
    split_data,
    writable_data,
)
from .atomic import atomic_path

__all__ = ["read_with_meshio", "write_with_meshio", "meshio_mesh", "raw_from_meshio"]

_WRITE_KEY = {"gmsh": "gmsh:physical", "medit": "medit:ref"}
_SKIP = set(SKIPPED_NAMES)
#: What meshio's readers of formats without data fields make up (Medit's vertex references,
#: OBJ's group ids, STL's facet normals): not data of the mesh, not read from those formats.
_READER_FIELDS = {"medit": {"medit:ref"}, "obj": {"obj:group_ids"}, "stl": {"facet_normals"}}


@contextlib.contextmanager
def quiet_meshio(path: Path) -> Iterator[None]:
    """Silence meshio's Python warnings and turn what it prints on stderr or stdout into
    one :class:`UserWarning` naming ``path``."""
    buffer = io_module.StringIO()
    try:
        with warnings.catch_warnings(), contextlib.redirect_stderr(buffer), \
                contextlib.redirect_stdout(buffer):
            warnings.simplefilter("ignore")
            yield
    except (Exception, SystemExit) as exc:  # what meshio printed before failing says why
        exc.meshio_output = buffer.getvalue()  # type: ignore[union-attr]
        raise
    text = " ".join(buffer.getvalue().split())
    if text:
        text = text.removeprefix("Warning:").strip()
        warnings.warn(f"{path}: meshio: {text}", stacklevel=4)


def unreadable(path: Path, name: str, exc: BaseException) -> ValueError:
    text = str(exc).strip()
    detail = text.splitlines()[0] if text else ""
    if isinstance(exc, SystemExit):  # meshio printed its reason, then exited
        said = getattr(exc, "meshio_output", "").split("Error: Couldn't read file")[0]
        printed = [line.strip() for line in said.splitlines() if line.strip()]
        detail = f"meshio: {printed[-1]}" if printed else "meshio refused it without a reason"
    elif not detail:
        detail = type(exc).__name__
    return ValueError(f"{path}: not a readable {name} file ({detail[:200]})")


#: Bytes of a file's head that :func:`_check_frame` looks at for a header.
HEAD = 1 << 20


def _check_frame(path: Path, meshio_name: str) -> int | None:
    """Refuse what meshio's readers would wait on forever or read short without a word:

    * OFF and PLY headers cut short (their readers skip blank and comment lines with a loop
      that never ends at the end of the file: a file that is only ``OFF`` or ``ply``);
    * an ASCII PLY file with more data lines than its header announces (the rest would be
      dropped);
    * an ASCII STL file without its closing ``endsolid`` line (cut between two facets, it
      would read as a smaller mesh).

    Returns the number of faces a PLY header announces (as many triangles must be read).
    """
    if meshio_name not in ("off", "ply", "stl"):
        return None
    with open(path, "rb") as f:
        head = f.read(HEAD)
        size = f.seek(0, os.SEEK_END)
        if meshio_name == "stl":
            f.seek(max(size - 1024, 0))
            tail = f.read()
    if meshio_name == "stl":
        binary = size >= 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little")
        last = tail.rstrip().rsplit(b"\n", 1)[-1].strip()
        if not binary and not last.startswith(b"endsolid"):
            raise ValueError(f"{path}: the file ends early (not a binary STL of its size, "
                             "and no endsolid line at its end)")
        return None
    lines = head.split(b"\n")
    if meshio_name == "off":
        if not any(line.strip() and not line.strip().startswith(b"#") for line in lines[1:]):
            raise ValueError(f"{path}: the file ends early (nothing after the OFF line)")
        return None
    end = next((i for i, line in enumerate(lines[:-1]) if line.strip() == b"end_header"), None)
    if end is None:
        raise ValueError(f"{path}: the file ends early (no end_header line in its first "
                         f"{HEAD} bytes)")
    header = [line.split() for line in lines[:end]]
    faces = next((int(w[2]) for w in header if len(w) == 3 and w[:2] == [b"element", b"face"]
                  and w[2].isdigit()), None)
    if [b"format", b"ascii", b"1.0"] not in header:
        return faces
    announced = sum(int(w[2]) for w in header if len(w) == 3 and w[0] == b"element"
                    and w[2].isdigit())
    start = sum(len(line) + 1 for line in lines[:end + 1])  # after the end_header line
    if size <= HEAD:
        body = head[start:]
    else:
        with open(path, "rb") as f:
            f.seek(start)
            body = f.read()
    found = sum(1 for line in body.split(b"\n") if line.strip())
    if found > announced:
        raise ValueError(f"{path}: the file holds {found} data lines after end_header, its "
                         f"header announces {announced}")
    return faces


def read_with_meshio(path: Path, meshio_name: str, name: str,
                     reader: Callable[[], Any] | None = None) -> RawMesh:
    """The content of ``path`` read by meshio as ``meshio_name`` (by ``reader()``, which
    returns a ``meshio.Mesh``, when given)."""
    check_regular(path)
    faces = _check_frame(path, meshio_name)
    import meshio

    try:
        with quiet_meshio(path):
            m = meshio.read(path, file_format=meshio_name) if reader is None else reader()
    except OSError as exc:
        raise OSError(f"{path}: {exc.strerror or exc}") from None
    except (Exception, SystemExit) as exc:  # meshio raises many kinds (even exits)
        raise unreadable(path, name, exc) from None
    try:
        arrays = _arrays(m, _READER_FIELDS.get(meshio_name, set()))
    except (TypeError, ValueError, IndexError, KeyError, AttributeError) as exc:
        raise unreadable(path, name, exc) from None  # meshio returned malformed data
    raw = _raw(path, arrays, m.field_data)
    if faces is not None and len(raw.triangles) != faces:
        raise ValueError(f"{path}: {len(raw.triangles)} triangles read, the header announces "
                         f"{faces} faces (a face of other than 3 vertices, or a miscount)")
    return raw


def _raw(path: Path, arrays: tuple, field_data: dict) -> RawMesh:
    """A :class:`RawMesh` of what :func:`_arrays` converted and of meshio's ``field_data``."""
    points, blocks, tags, point_data, cell_data = arrays
    raw = from_blocks(path, points, blocks, tags)
    if len(raw.triangles):
        split_data(raw, point_data, cell_data)
    raw.physical_names = _names(field_data)
    return raw


def _names(field_data: dict) -> dict[tuple[int, int], str]:
    """meshio's ``field_data`` (``name -> [tag, dim]``, as Gmsh and XDMF files give it) as
    physical names ``(dim, tag) -> name``."""
    names = {}
    for name, value in (field_data or {}).items():
        v = np.asarray(value).ravel()
        if len(v) == 2 and v.dtype.kind in "iu":
            names[(int(v[1]), int(v[0]))] = str(name)
    return names


def _arrays(m, made_up: set[str] = frozenset()) -> tuple:
    """Points ``(N, d) float64``, cell blocks ``(type, (k, nodes) int)``, their tags, point
    data and the triangles' cell data (not the fields named ``made_up``), converted from
    meshio's objects (malformed data raises here)."""
    points = np.asarray(m.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"points must have 2 or 3 coordinates, got shape {points.shape}")
    key = next((k for k in TAG_NAMES if k in m.cell_data), None)
    blocks, tags = [], []
    for i, block in enumerate(m.cells):
        data = np.asarray(block.data)
        if block.type in ("triangle", "line"):
            width = 3 if block.type == "triangle" else 2
            if data.ndim != 2 or data.shape[1] != width or \
                    (data.size and not np.issubdtype(data.dtype, np.integer)):
                raise ValueError(f"malformed {block.type} cells")
            data = data.astype(np.int64)
        blocks.append((block.type, data))
        tags.append(None if key is None else np.asarray(m.cell_data[key][i]).reshape(-1))
        if tags[-1] is not None and len(tags[-1]) != len(data):
            raise ValueError(f"{len(tags[-1])} tags for {len(data)} {block.type} cells")
    point_data = {name: _native(v) for name, v in m.point_data.items()
                  if np.asarray(v).dtype.kind in "biuf" and len(v) == len(points)
                  and name not in made_up}
    cell_data = {}
    triangles = [i for i, b in enumerate(m.cells) if b.type == "triangle"]
    for name, per_block in m.cell_data.items():
        if name == key or name in _SKIP or name in made_up or not triangles:
            continue
        parts = [_native(per_block[i]) for i in triangles]
        if all(p.dtype.kind in "biuf" for p in parts):
            cell_data[name] = np.concatenate(parts)
    return points, blocks, tags, point_data, cell_data


def _native(values) -> NDArray:
    """``values`` in this machine's byte order (meshio's VTK reader gives big-endian)."""
    a = np.asarray(values)
    return a.astype(a.dtype.newbyteorder("=")) if a.dtype.byteorder not in "=|" else a


def write_with_meshio(path: Path, mesh, meshio_name: str, *, tags: bool, data: bool,
                      binary: bool | None, options: dict | None = None) -> None:
    """Write ``mesh`` with meshio as ``meshio_name`` (tags and data where the format holds
    them)."""
    import meshio

    if data:
        mesh = _rows_of_numbers(path, mesh)
        if meshio_name == "vtk":
            _check_vtk_names(path, mesh)
    m = meshio_mesh(mesh, _WRITE_KEY.get(meshio_name, "tag"), tags=tags, data=data,
                    flat=meshio_name == "medit", path=path)
    kwargs = dict(options or {})
    if binary is not None:
        kwargs["binary"] = binary
    with atomic_path(path) as tmp, quiet_meshio(path):
        meshio.write(tmp, m, file_format=meshio_name, **kwargs)


def _check_vtk_names(path: Path, mesh) -> None:
    """VTK legacy files name a field by one word: an empty name, or one with a space or a
    tab, made meshio fail or write a file nothing reads."""
    for data in (mesh.point_data, mesh.cell_data):
        for name in data or {}:
            if not name or len(name.split()) != 1 or name.strip() != name:
                raise ValueError(f"{path}: data name {name!r} is not one word, which VTK "
                                 "legacy files need; rename it, or write .vtu")


def _rows_of_numbers(path: Path, mesh):
    """``mesh`` with every data field of more than one axis per row flattened to one
    (meshio's VTK writer declares a (2, 2) field per point as 4 numbers and writes an
    unreadable file otherwise), with one warning naming them."""
    def flat(data):
        return {name: np.asarray(v).reshape(len(v), -1) if np.ndim(v) > 2 else v
                for name, v in (data or {}).items()}

    shaped = [f"{name} {np.shape(v)}" for data in (mesh.point_data, mesh.cell_data)
              for name, v in (data or {}).items() if np.ndim(v) > 2]
    if not shaped:
        return mesh
    warnings.warn(f"{path}: this format holds one row of numbers per point or cell: "
                  f"{', '.join(shaped)} written flat (rows, product of the rest)", stacklevel=4)
    return mesh.replace(point_data=flat(mesh.point_data), cell_data=flat(mesh.cell_data))


def meshio_mesh(mesh, tag_key: str = "gmsh:physical", *, tags: bool = True,
                data: bool = True, flat: bool = False, names: bool = False,
                path: Path | None = None, for_files: bool = True):
    """``mesh`` as a ``meshio.Mesh``: points with ``z = 0`` (``flat``: 2 coordinates), a
    ``line`` block of the tagged edges and a ``triangle`` block, the tags as the cell data
    ``tag_key`` (untagged triangles: 0), point data, the triangles' cell data (the edges'
    rows zero) and, with ``names``, the physical names as ``field_data``
    (``name -> [tag, dim]``, as meshio's Gmsh reader gives them). Cell data under one of
    :data:`TAG_NAMES` or :data:`SKIPPED_NAMES` is refused (``path``: the file, for the
    message). ``for_files``: data in the dtypes files hold (:func:`writable_data`: booleans
    as ``uint8``, ``float16`` as ``float32``); else as it is (an object in memory)."""
    import meshio

    n = mesh.n_points
    points = np.asarray(mesh.points) if flat else np.column_stack([mesh.points, np.zeros(n)])
    tris = np.asarray(mesh.triangles)
    if not tags:
        return meshio.Mesh(points, [("triangle", tris)])
    cells, tag_blocks = [], []
    k = 0 if mesh.edges is None else len(mesh.edges)
    if k:
        cells.append(("line", np.asarray(mesh.edges, dtype=np.int64)))
        tag_blocks.append(np.asarray(mesh.edge_tags, dtype=np.int64))
    cells.append(("triangle", tris))
    cell_tags = mesh.cell_tags if mesh.cell_tags is not None else np.zeros(len(tris), np.int64)
    tag_blocks.append(np.asarray(cell_tags, dtype=np.int64))
    cell_data: dict[str, list[NDArray]] = {tag_key: tag_blocks}
    point_data: dict[str, NDArray] = {}
    if data:
        point_data, tri_data = mesh_data(mesh, path, TAG_NAMES + SKIPPED_NAMES)
        as_held = writable_data if for_files else np.asarray
        point_data = {k: as_held(v) for k, v in point_data.items()}
        for name, value in tri_data.items():
            value = as_held(value)
            pad = [np.zeros((k, *value.shape[1:]), value.dtype)] if k else []
            cell_data[name] = [*pad, value]
    field_data = _field_data(mesh.physical_names or {}) if names else None
    return meshio.Mesh(points, cells, point_data=point_data, cell_data=cell_data,
                       field_data=field_data)


def shared_name(physical_names) -> tuple[str, tuple[int, int], tuple[int, int]] | None:
    """The first physical name given to two groups ``(dim, tag)``, with the two groups, or
    None: formats whose names map to one group each (meshio's ``field_data``, XDMF's
    ``Information`` map that meshio reads as it) cannot hold it."""
    seen: dict[str, tuple[int, int]] = {}
    for group, name in sorted((physical_names or {}).items()):
        if name in seen:
            return name, seen[name], group
        seen[name] = group
    return None


def check_one_group_per_name(physical_names, where: str) -> None:
    """Refuse physical names that :func:`shared_name` finds (``where`` starts the line)."""
    found = shared_name(physical_names)
    if found is not None:
        name, first, second = found
        raise ValueError(f"{where}the physical name {name!r} names the groups (dim, tag) "
                         f"{first} and {second}; this format holds one group per name "
                         "(meshio's field_data): rename one")


def _field_data(physical_names: dict[tuple[int, int], str]) -> dict[str, NDArray]:
    """meshio's ``field_data`` (``name -> [tag, dim]``: one group per name) of the physical
    names; a name given to two groups is refused (one of them would be lost)."""
    check_one_group_per_name(physical_names, "")
    return {name: np.array([tag, dim]) for (dim, tag), name in physical_names.items()}


def raw_from_meshio(m, path: Path) -> RawMesh:
    """What a ``meshio.Mesh`` holds as a :class:`RawMesh` (``path`` names it in messages)."""
    try:
        arrays = _arrays(m)
    except (TypeError, ValueError, IndexError, KeyError, AttributeError) as exc:
        raise ValueError(f"{path}: {_one_line(exc)}") from None  # named, as in files
    return _raw(path, arrays, m.field_data)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__
