"""VTK XML unstructured grids (``.vtu``): appended binary, raw or zlib-compressed.

Written: one piece; points ``Float64`` with z = 0; triangles first (cells ``0..M-1``), then
the tagged edges as line cells; the cell array ``tag`` (cell tags on triangles, edge tags on
lines) when the mesh has tags; every point-data and cell-data field in its own dtype (cell
data is 0 on the line cells); and a field-data array ``qdrefine`` (JSON bytes: physical
names, and each field's shape and dtype) that qdrefine reads back and other readers
ignore. The data is appended raw (the fastest to write and read), or zlib-compressed with
``compress=True``; ParaView and meshio read both.

Read: appended raw, zlib or lzma data with 32- or 64-bit headers, little- or big-endian, in
one or several pieces (joined in order, as meshio joins them), a byte-order mark before the
XML too; any other VTU (inline ASCII or base64, other compressors) goes to meshio, and the
``qdrefine`` field data it reads restores the names, shapes and dtypes there as well.

One concern: the VTU layout, read and written around the same cells and the same field-data
record (its block decoding is :mod:`qdrefine.io.vtk_blocks`), which is why it passes 400
lines.
"""

from __future__ import annotations

import binascii
import json
import re
import xml.etree.ElementTree as ET
import zlib
from lzma import LZMAError
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..memory import check_needed
from ._core import TAG_NAMES, RawMesh, from_blocks, mesh_data, read_bytes, split_data, writable_data
from .atomic import atomic_path
from .recorded import record, record_of, restored
from .vtk_blocks import (
    DECOMPRESSORS,
    UNSIZED_LIMIT,
    VTK_TYPES,
    byte_order,
    check_base64_blocks,
    components,
    decompressed,
    header_dtype,
)
from .xml_names import check_xml_names

__all__ = ["read", "write"]

_NAMES = {np.dtype(v): k for k, v in VTK_TYPES.items()}
#: VTK cell types: (meshio's name, nodes per cell; 0: variable).
_CELLS = {1: ("vertex", 1), 3: ("line", 2), 5: ("triangle", 3), 9: ("quad", 4),
          10: ("tetra", 4), 12: ("hexahedron", 8), 13: ("wedge", 6), 14: ("pyramid", 5),
          21: ("line3", 3), 22: ("triangle6", 6), 23: ("quad8", 8), 24: ("tetra10", 10),
          2: ("poly_vertex", 0), 4: ("polyline", 0), 6: ("triangle_strip", 0),
          7: ("polygon", 0), 8: ("pixel", 4), 11: ("voxel", 8)}
_META = "qdrefine"
_CHUNK = 1 << 20  # bytes per compressed block


class _Fallback(Exception):
    """A VTU this reader does not handle: meshio reads it."""


# --------------------------------------------------------------------------------------------
# reading


def read(path: Path) -> RawMesh:
    data = read_bytes(path)
    try:
        return _read(path, data)
    except _Fallback:
        from .meshio_formats import read_with_meshio

        try:
            check_base64_blocks(data)
        except (ValueError, KeyError, IndexError, ET.ParseError, zlib.error, LZMAError,
                binascii.Error) as exc:
            raise ValueError(f"{path}: not a readable VTK XML unstructured grid file "
                             f"({str(exc)[:200] or type(exc).__name__})") from None
        read: list = []  # meshio's mesh, whose field data holds qdrefine's record

        def reader():
            import meshio

            read.append(meshio.read(path, file_format="vtu"))
            return read[0]

        raw = read_with_meshio(path, "vtu", "VTK XML unstructured grid", reader)
        return _recorded(raw, _meshio_meta(read[0].field_data.get(_META)))
    except (ValueError, KeyError, IndexError, ET.ParseError, zlib.error, LZMAError) as exc:
        if str(exc).startswith(str(path)):
            raise
        raise ValueError(f"{path}: not a readable VTK XML unstructured grid file "
                         f"({str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__})"
                         ) from None


def _read(path: Path, data: bytes) -> RawMesh:
    start = data.find(b"<AppendedData")
    if start < 0 or not data.removeprefix(b"\xef\xbb\xbf").lstrip().startswith(
            (b"<?xml", b"<VTKFile")):  # a byte-order mark too (meshio lost the names)
        raise _Fallback
    tag_end = data.find(b">", start)
    underscore = data.find(b"_", tag_end)
    if tag_end < 0 or underscore < 0:
        raise ValueError(f"byte {start}: no '_' opening the appended data")
    if b'encoding="raw"' not in data[start:tag_end]:
        raise _Fallback
    if b"</VTKFile>" not in data[-64:]:
        raise ValueError(f"byte {len(data)}: the file ends early (no </VTKFile>)")
    root = ET.fromstring(data[:start] + b"</VTKFile>")
    if root.tag != "VTKFile" or root.get("type") != "UnstructuredGrid":
        raise ValueError("not a VTKFile of type UnstructuredGrid")
    order = byte_order(root)
    header = header_dtype(root, order)
    compressor = root.get("compressor")
    if compressor is not None and compressor not in DECOMPRESSORS:
        raise _Fallback
    decompressor = None if compressor is None else DECOMPRESSORS[compressor]
    pieces = root.findall("./UnstructuredGrid/Piece")
    if not pieces:
        raise ValueError("no Piece")
    base = underscore + 1
    expanded = [0]  # bytes the compressed blocks may expand to, so far

    def array(item: ET.Element, rows: int | None) -> NDArray:
        """The values of ``item`` in native byte order; a compressed block decompresses to
        at most the bytes of its ``rows`` (None: :data:`UNSIZED_LIMIT`), so that a small
        file cannot expand into gigabytes before its sizes are checked."""
        if item.get("format") != "appended":
            raise _Fallback
        kind = VTK_TYPES.get(item.get("type", ""))
        if kind is None:
            raise ValueError(f"DataArray {item.get('Name')!r}: unknown type {item.get('type')}")
        kind = np.dtype(kind).newbyteorder(order)
        offset = base + int(item.get("offset", "-1"))
        comps = components(item)
        limit = UNSIZED_LIMIT if rows is None else max(rows, 0) * comps * kind.itemsize
        what = f"DataArray {item.get('Name')!r}" if item.get("Name") else "an unnamed DataArray"

        def reserve(size: int) -> None:  # the declared sizes fit the memory (a 385 kB file
            expanded[0] += size  # expanded to 2.1 GB past any limit)
            check_needed(expanded[0], f"reading {path} (its compressed arrays, up to {what})")

        raw = _block(data, offset, header, decompressor, limit, what,
                     reserve if rows is not None else None)
        a = np.frombuffer(raw, dtype=kind).astype(kind.newbyteorder("="), copy=False)
        if len(a) % comps:  # components() is at least 1
            raise ValueError(f"byte {offset}: {what} holds {len(a)} values, not a multiple "
                             f"of {comps} components")
        return a.reshape(-1, comps) if comps > 1 else a

    parts = []
    for i, piece in enumerate(pieces):
        try:
            parts.append(_piece(piece, array))
        except ValueError as exc:
            if len(pieces) == 1:
                raise
            raise ValueError(f"Piece {i}: {exc}") from None
    points, offsets, types, conn, cell_fields, point_data = _joined(parts)
    starts = np.concatenate([[0], offsets[:-1]])
    sizes = offsets - starts
    key = next((k for k in TAG_NAMES if k in cell_fields), None)
    cell_tags = cell_fields[key].ravel() if key else None
    if cell_tags is not None and len(cell_tags) != len(types):
        raise ValueError(f"CellData {key!r}: expected {len(types)} values")
    blocks, tags, triangle_cells = [], [], np.empty(0, np.int64)
    for t in np.unique(types).tolist():
        rows = np.flatnonzero(types == t)
        name, npe = _CELLS.get(t, (f"VTK type {t}", 0))
        if npe and (sizes[rows] != npe).any():
            bad = int(rows[np.argmax(sizes[rows] != npe)])
            raise ValueError(f"Cells: cell {bad} is a {name} (VTK type {t}) of "
                             f"{int(sizes[bad])} points, not {npe}")
        if npe == 0:
            blocks.append((name, np.empty((len(rows), 0), np.int64)))
        else:
            blocks.append((name, conn[starts[rows][:, None] + np.arange(npe)]))
        tags.append(None if cell_tags is None else cell_tags[rows])
        if t == 5:
            triangle_cells = rows
    raw = from_blocks(path, points, blocks, tags)
    if len(raw.triangles):
        split_data(raw, point_data, {name: values[triangle_cells]
                                     for name, values in cell_fields.items() if name != key})
    return _recorded(raw, _meta(root, array))


def _recorded(raw: RawMesh, meta: dict) -> RawMesh:
    """``raw`` with what qdrefine's field data ``meta`` records: the physical names, and
    each data field in its recorded shape and dtype."""
    try:
        if "names" in meta:  # else those meshio read from a file's own field data stay
            raw.physical_names = {(int(d), int(t)): str(nm) for d, t, nm in meta["names"]}
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{raw.path}: not a readable VTK XML unstructured grid file (field "
                         f"data {_META!r}: its physical names are not (dim, tag, name) "
                         "triples)") from None
    shapes = meta.get("shapes")
    for where, data, rows in (("point", raw.point_data, len(raw.points)),
                              ("cell", raw.cell_data, len(raw.triangles))):
        for name, values in data.items():
            out = restored(values, record_of(shapes, where, name), rows,
                           f"{raw.path}: {where} data {name!r}")
            data[name] = np.array(values) if out is None else out
    return raw


class _Piece(NamedTuple):
    """The arrays of one ``Piece``: points, cells (offsets, types, connectivity) and its
    cell and point data by name."""

    points: NDArray[np.float64]
    offsets: NDArray[np.int64]
    types: NDArray[np.int64]
    conn: NDArray[np.int64]
    cell_fields: dict[str, NDArray]
    point_fields: dict[str, NDArray]


def _piece(piece: ET.Element, array) -> _Piece:
    """The arrays of ``piece``, each checked against its ``NumberOfPoints`` and
    ``NumberOfCells`` (``array(item, rows)``: a DataArray's values)."""
    n, n_cells = (int(piece.get(f"NumberOf{what}", "-1")) for what in ("Points", "Cells"))
    points_item = piece.find("./Points/DataArray")
    if points_item is None:
        raise ValueError("no Points")
    points = array(points_item, n).astype(np.float64)
    if points.ndim != 2 or len(points) != n:
        raise ValueError(f"Points: expected {n} points")
    cells = {item.get("Name"): item for item in piece.findall("./Cells/DataArray")}
    if {"connectivity", "offsets", "types"} - set(cells):
        raise ValueError("Cells needs connectivity, offsets and types")
    offsets = array(cells["offsets"], n_cells).astype(np.int64).ravel()
    types = array(cells["types"], n_cells).astype(np.int64).ravel()
    if len(offsets) != n_cells or len(types) != n_cells:
        raise ValueError(f"Cells: expected {n_cells} offsets and types")
    conn = array(cells["connectivity"], int(offsets.max(initial=0))).astype(np.int64).ravel()
    if n_cells and (np.diff(offsets, prepend=0).min() < 0 or offsets[-1] > len(conn)):
        raise ValueError("Cells: offsets do not fit the connectivity")
    fields = []
    for kind, rows in (("CellData", n_cells), ("PointData", n)):
        found = {}  # each piece's own rows: pieces joined with a row too many shifted data
        for item in piece.findall(f"./{kind}/DataArray"):
            name = item.get("Name", "")
            found[name] = array(item, rows)
            if len(found[name]) != rows:
                raise ValueError(f"{kind} {name!r}: expected {rows} rows")
        fields.append(found)
    return _Piece(points, offsets, types, conn[:int(offsets[-1]) if n_cells else 0], *fields)


def _joined(parts: list[_Piece]) -> _Piece:
    """One piece of ``parts``, in order: points numbered on from the previous pieces', cells
    after theirs; every piece must hold the same cell and point data (as meshio reads
    them)."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    for i, part in enumerate(parts[1:], 1):
        for what, mine, theirs in (("cell", part.cell_fields, first.cell_fields),
                                   ("point", part.point_fields, first.point_fields)):
            if sorted(mine) != sorted(theirs):
                raise ValueError(f"Piece {i} has {what} data {sorted(mine)}, Piece 0 "
                                 f"{sorted(theirs)}")
    point_start = np.cumsum([0] + [len(p.points) for p in parts[:-1]])
    conn_start = np.cumsum([0] + [len(p.conn) for p in parts[:-1]])

    def fields(which: str) -> dict[str, NDArray]:
        return {name: np.concatenate([getattr(p, which)[name] for p in parts])
                for name in getattr(first, which)}

    return _Piece(np.concatenate([p.points for p in parts]),
                  np.concatenate([p.offsets + s for p, s in zip(parts, conn_start, strict=True)]),
                  np.concatenate([p.types for p in parts]),
                  np.concatenate([p.conn + s for p, s in zip(parts, point_start, strict=True)]),
                  fields("cell_fields"), fields("point_fields"))


def _meta(root: ET.Element, array) -> dict:
    for item in root.findall("./UnstructuredGrid/FieldData/DataArray"):
        if item.get("Name") == _META:
            return _decoded_meta(array(item, None))
    return {}


def _meshio_meta(values: NDArray | None) -> dict:
    """qdrefine's field data as meshio read it; ``{}`` where it is not (a file of another
    tool, or a damaged record: read as stored)."""
    try:
        return {} if values is None else _decoded_meta(values)
    except (TypeError, ValueError):
        return {}


def _decoded_meta(values: NDArray) -> dict:
    """qdrefine's field data ``values`` (the bytes of a JSON mapping; ``{}`` for another
    JSON value); ``ValueError`` when they are not JSON."""
    try:
        meta = json.loads(np.asarray(values).astype(np.uint8).tobytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):  # too deep
        raise ValueError(f"field data {_META!r} is not JSON") from None
    return meta if isinstance(meta, dict) else {}


def _block(data: bytes, offset: int, header: np.dtype, decompressor, limit: int,
           what: str, reserve=None) -> bytes:
    """The bytes of the appended block at ``offset``: raw ones (``decompressor`` None)
    bounded by the file size, compressed ones by ``limit`` (what the data ``what`` can
    hold) and by the sizes of its header, checked while decompressing (at most
    ``limit + 1`` bytes are ever made). ``reserve(n)`` is told the bytes a compressed
    block will make (the least of ``limit`` and its header's sizes) before it is made."""
    size = header.itemsize
    if offset < 0 or offset + size > len(data):
        raise ValueError(f"byte {offset}: appended data offset outside the file")
    if decompressor is None:
        nbytes = int(np.frombuffer(data, header, 1, offset)[0])
        if offset + size + nbytes > len(data):
            raise ValueError(f"byte {offset}: the file ends inside an appended block of "
                             f"{nbytes} bytes")
        return data[offset + size:offset + size + nbytes]
    if offset + 3 * size > len(data):
        raise ValueError(f"byte {offset}: bad compressed block header")
    head = np.frombuffer(data, header, 3, offset).astype(np.int64)
    n_blocks, block_size, last_size = (int(v) for v in head)
    if min(n_blocks, block_size, last_size) < 0 or offset + (3 + n_blocks) * size > len(data):
        raise ValueError(f"byte {offset}: bad compressed block header")
    if reserve is not None:  # a miscounted NumberOfPoints is then said as such, not as memory
        made = (n_blocks - 1) * block_size + (last_size or block_size) if n_blocks else 0
        reserve(min(limit, made))  # a last size of 0: a full last block
    csizes = np.frombuffer(data, header, n_blocks, offset + 3 * size).astype(np.int64)
    pos = offset + (3 + n_blocks) * size
    if pos + int(csizes.sum()) > len(data):
        raise ValueError(f"byte {offset}: the file ends inside compressed data")
    return decompressed(data, pos, offset, (block_size, last_size), csizes.tolist(), limit,
                        what, decompressor)


# --------------------------------------------------------------------------------------------
# writing


def write(path: Path, mesh, *, binary: bool = True, compress: bool = False) -> None:
    """Write ``mesh`` as a VTU file with appended binary data (raw, or zlib with
    ``compress=True``); ``binary=False`` is refused: text VTU (meshio's) would round the
    points and lose the physical names and some fields."""
    if not binary:
        raise ValueError(f"{path}: VTU files are written with binary data only (text VTU "
                         "would not keep every bit of the points, nor the physical names); "
                         "leave binary at its default")
    check_xml_names(path, mesh, physical=False)  # the physical names are JSON in the file
    m, n = mesh.n_triangles, mesh.n_points
    k = 0 if mesh.edges is None else len(mesh.edges)
    tris = np.asarray(mesh.triangles)
    edges = np.asarray(mesh.edges, dtype=tris.dtype) if k else np.empty((0, 2), tris.dtype)
    conn = np.concatenate([tris.ravel(), edges.ravel()])
    offsets = np.concatenate([np.arange(1, m + 1, dtype=np.int64) * 3,
                              3 * m + np.arange(1, k + 1, dtype=np.int64) * 2])
    types = np.concatenate([np.full(m, 5, np.uint8), np.full(k, 3, np.uint8)])
    xyz = np.zeros((n, 3))
    xyz[:, :2] = mesh.points
    point_data, cell_data = mesh_data(mesh, path, TAG_NAMES)
    cell_fields = {}
    if mesh.cell_tags is not None or k:
        cell_tags = mesh.cell_tags if mesh.cell_tags is not None else np.zeros(m, np.int64)
        edge_tags = mesh.edge_tags if k else np.zeros(0, np.int64)
        cell_fields["tag"] = np.concatenate([np.asarray(cell_tags, np.int64),
                                             np.asarray(edge_tags, np.int64)])
    shapes: dict[str, dict] = {"point": {}, "cell": {}}
    for name, value in cell_data.items():
        a = np.asarray(value)
        cell_fields[name] = np.concatenate([a, np.zeros((k, *a.shape[1:]), a.dtype)])
        shapes["cell"][name] = record(a)
    for name, value in point_data.items():
        a = np.asarray(value)
        shapes["point"][name] = record(a)
    meta = {"names": [[d, t, nm] for (d, t), nm in sorted((mesh.physical_names or {}).items())],
            "shapes": shapes}
    blocks: list = []
    offset = [0]

    def item(name: str, a: NDArray) -> str:
        a = writable_data(a)  # other dtypes were refused by mesh_data
        if a.ndim > 1 and not np.prod(a.shape[1:]):
            raise ValueError(f"{path}: data {name!r} has no values per row (shape "
                             f"{a.shape}), which a VTK DataArray cannot hold")
        a = np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<"))
        comps = f' NumberOfComponents="{int(np.prod(a.shape[1:]))}"' if a.ndim > 1 else ""
        body = _encode(a, compress)
        text = (f'<DataArray type="{_NAMES[a.dtype.newbyteorder("=")]}" '
                f'Name="{_attr(name)}"{comps} format="appended" offset="{offset[0]}"/>\n')
        blocks.extend(body)
        offset[0] += sum(memoryview(b).nbytes for b in body)
        return text

    xml = ['<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
           'byte_order="LittleEndian" header_type="UInt64"'
           + (' compressor="vtkZLibDataCompressor"' if compress else "") + '>\n'
           '<UnstructuredGrid>\n<FieldData>\n',
           item(_META, np.frombuffer(json.dumps(meta).encode(), np.uint8)).replace(
               "<DataArray", f'<DataArray NumberOfTuples="{len(json.dumps(meta).encode())}"'),
           f'</FieldData>\n<Piece NumberOfPoints="{n}" NumberOfCells="{m + k}">\n<Points>\n',
           item("Points", xyz), "</Points>\n<Cells>\n", item("connectivity", conn),
           item("offsets", offsets), item("types", types), "</Cells>\n<PointData>\n"]
    xml += [item(name, value) for name, value in point_data.items()]
    xml.append("</PointData>\n<CellData>\n")
    xml += [item(name, value) for name, value in cell_fields.items()]
    xml.append('</CellData>\n</Piece>\n</UnstructuredGrid>\n<AppendedData encoding="raw">\n_')
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write("".join(xml).encode())
        for body in blocks:
            f.write(body)
        f.write(b"\n</AppendedData>\n</VTKFile>\n")


def _encode(a: NDArray, compress: bool) -> list:
    """The appended block of the contiguous array ``a``: header and data buffers."""
    if not compress:
        return [np.array([a.nbytes], "<u8").tobytes(), memoryview(a.reshape(-1)).cast("B")]
    raw = a.tobytes()
    chunks = [zlib.compress(raw[i:i + _CHUNK], 1) for i in range(0, len(raw), _CHUNK)] or \
        [zlib.compress(b"", 1)]
    last = len(raw) - _CHUNK * (len(chunks) - 1) if raw else 0
    head = np.array([len(chunks), _CHUNK, last, *map(len, chunks)], "<u8")
    return [head.tobytes(), *chunks]


def _attr(text: str) -> str:
    """``text`` for an XML attribute value (tabs and line breaks too: XML reads them in an
    attribute as spaces, so "a\tb" came back as "a b")."""
    return re.sub(r'[&<>"\t\n\r]', lambda m: {"&": "&amp;", "<": "&lt;", ">": "&gt;",
                                              '"': "&quot;", "\t": "&#9;", "\n": "&#10;",
                                              "\r": "&#13;"}[m.group()], text)
