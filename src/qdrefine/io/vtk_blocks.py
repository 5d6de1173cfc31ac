"""VTK XML's compressed data blocks, decompressed within bounds: a header of block sizes,
then zlib or lzma blocks. Each block may expand to the size its header gives and all of an
array's blocks to the bytes of its rows, checked while decompressing, so that a small file
cannot expand into gigabytes before its sizes are checked (:mod:`qdrefine.io.vtu` reads
appended raw data with :func:`decompressed`; :func:`check_base64_blocks` checks, before
meshio reads them, the base64 arrays that meshio decompresses whole)."""

from __future__ import annotations

import base64
import lzma
import sys
import xml.etree.ElementTree as ET
import zlib

import numpy as np

__all__ = ["VTK_TYPES", "UNSIZED_LIMIT", "DECOMPRESSORS", "BYTE_ORDERS", "byte_order",
           "header_dtype", "decompressed", "check_base64_blocks", "components"]

#: VTK data types and their NumPy dtypes.
VTK_TYPES = {"Int8": "i1", "UInt8": "u1", "Int16": "<i2", "UInt16": "<u2", "Int32": "<i4",
             "UInt32": "<u4", "Int64": "<i8", "UInt64": "<u8", "Float32": "<f4",
             "Float64": "<f8"}

#: The most bytes a compressed array of unknown size (qdrefine's field data) may expand to.
UNSIZED_LIMIT = 1 << 26

#: VTK XML byte orders and NumPy's.
BYTE_ORDERS = {"LittleEndian": "<", "BigEndian": ">"}


def byte_order(root: ET.Element) -> str:
    """NumPy's byte order (``<`` or ``>``) of the VTKFile element ``root``; ``ValueError``
    for another."""
    order = BYTE_ORDERS.get(root.get("byte_order", "LittleEndian"))
    if order is None:
        raise ValueError(f"unknown byte_order {root.get('byte_order')!r}")
    return order


def header_dtype(root: ET.Element, order: str) -> np.dtype:
    """The dtype of the block headers of the VTKFile element ``root`` (``header_type``
    UInt32 or UInt64), in byte order ``order``."""
    return np.dtype("u8" if root.get("header_type") == "UInt64" else "u4").newbyteorder(order)


#: VTK's compressors that the readers decompress: their streams (``decompress(data,
#: max_length)``, ``eof``).
DECOMPRESSORS = {"vtkZLibDataCompressor": zlib.decompressobj,
                 "vtkLZMADataCompressor": lzma.LZMADecompressor}


def decompressed(data: bytes, pos: int, where: int | None, sizes: tuple[int, int],
               csizes: list[int], limit: int, what: str, decompressor) -> bytes:
    """The compressed blocks of ``csizes`` bytes from ``data[pos:]``, each at most its size
    in the header (``sizes``: full blocks, last block or 0), all at most ``limit`` bytes,
    checked while decompressing (``decompressor()``: a zlib or lzma stream object); errors
    name byte ``where`` (the block's place in the file), if given."""
    block_size, last_size = sizes
    at = "" if where is None else f"byte {where}: "
    out, left = [], limit
    for i, c in enumerate(csizes):
        declared = last_size if i == len(csizes) - 1 and last_size else block_size
        cap = max(min(declared, left, sys.maxsize - 1), 0)
        stream = decompressor()
        chunk = stream.decompress(data[pos:pos + c], cap + 1)
        if len(chunk) > cap:
            if cap == declared:
                raise ValueError(f"{at}compressed block {i} of {what} holds more "
                                 f"than the {declared} bytes its header declares")
            raise ValueError(f"{at}{what} decompresses to more than the {limit} "
                             "bytes its rows take")
        if not stream.eof:
            raise ValueError(f"{at}compressed block {i} of {what} is truncated")
        out.append(chunk)
        left -= len(chunk)
        pos += c
    return b"".join(out)


def check_base64_blocks(data: bytes) -> None:
    """Decompress, bounded, every compressed base64 array (inline or appended) of a VTU
    that meshio reads, before it does: meshio decompresses each block whole, so a 209 kB
    file took 2.3 GB (review). Each array may expand to its header's block sizes and to the
    bytes of its rows (points, cells, the connectivity's from the largest offset;
    qdrefine's field data :data:`UNSIZED_LIMIT`). Files this does not understand are left
    to meshio, which refuses them."""
    try:
        root = ET.fromstring(data)
    except ET.ParseError:
        return  # raw appended data (not XML): meshio refuses it, in its own words
    decompressor = DECOMPRESSORS.get(root.get("compressor", ""))
    if decompressor is None:
        return
    order = byte_order(root)
    header = header_dtype(root, order)
    appended = root.find("AppendedData")
    tail = (appended.text or "").strip()[1:] if appended is not None else ""
    for piece in root.iter("Piece"):
        counts = {"Points": int(piece.get("NumberOfPoints", "0")),
                  "PointData": int(piece.get("NumberOfPoints", "0")),
                  "CellData": int(piece.get("NumberOfCells", "0")),
                  "Cells": int(piece.get("NumberOfCells", "0"))}
        connectivity = None  # its rows: the offsets' largest, read first
        for section in piece:
            if section.tag == "FieldData":
                continue  # below, with every field data
            items = sorted(section.iter("DataArray"),
                           key=lambda item: item.get("Name") == "connectivity")
            for item in items:
                kind = VTK_TYPES.get(item.get("type", ""))
                text = _base64_text(item, tail)
                if kind is None or text is None:
                    continue
                name = item.get("Name")
                rows = connectivity if name == "connectivity" else counts.get(section.tag)
                limit = sys.maxsize if rows is None else \
                    max(rows, 0) * components(item) * np.dtype(kind).itemsize
                raw = _check_one(text, header, limit, f"DataArray {name!r}" if name else
                                 "an unnamed DataArray", decompressor)
                if name == "offsets" and section.tag == "Cells":  # in the file's byte order
                    values = np.frombuffer(raw, np.dtype(kind).newbyteorder(order),
                                           len(raw) // np.dtype(kind).itemsize)
                    connectivity = int(values.max(initial=0))
    for item in root.iter("FieldData"):
        for array in item.iter("DataArray"):
            text = _base64_text(array, tail)
            if text is not None:
                _check_one(text, header, UNSIZED_LIMIT, "field data", decompressor)


def _base64_text(item: ET.Element, tail: str) -> str | None:
    """The base64 text of a DataArray as meshio reads it: its own text (``binary``) or the
    appended data from its offset on; None for other formats."""
    if item.get("format") == "binary":
        return (item.text or "").strip()
    if item.get("format") == "appended":
        return tail[int(item.get("offset", "0")):]
    return None


def _check_one(text: str, header: np.dtype, limit: int, what: str, decompressor) -> bytes:
    """One compressed base64 array as meshio decodes it (its header, three sizes and one
    per block, in base64 of its own, then the blocks): its bytes."""
    size = header.itemsize
    first = np.frombuffer(base64.b64decode(text[:_b64_chars(size)])[:size], header)
    n_blocks = int(first[0]) if first.size else -1
    if not 0 <= n_blocks <= len(text):
        raise ValueError(f"{what}: bad compressed block header")
    head_chars = _b64_chars((3 + n_blocks) * size)
    head = np.frombuffer(base64.b64decode(text[:head_chars])[:(3 + n_blocks) * size],
                         header).astype(np.int64)
    if len(head) != 3 + n_blocks or head.min(initial=0) < 0:
        raise ValueError(f"{what}: bad compressed block header")
    csizes = head[3:].tolist()
    blocks = base64.b64decode(text[head_chars:head_chars + _b64_chars(sum(csizes))])
    if len(blocks) < sum(csizes):
        raise ValueError(f"{what}: the data ends inside its compressed blocks")
    return decompressed(blocks, 0, None, (int(head[1]), int(head[2])), csizes, limit, what,
                        decompressor)


def components(item: ET.Element) -> int:
    """``NumberOfComponents`` of a DataArray: 1 when absent or empty (Firedrake writes it
    empty; meshio reads that as 1)."""
    return max(int(item.get("NumberOfComponents") or "1"), 1)


def _b64_chars(n: int) -> int:
    """Base64 characters of ``n`` bytes, padding included."""
    return -(-n // 3) * 4
