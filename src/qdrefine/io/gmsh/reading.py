"""Reading Gmsh MSH 2.0-2.2 and 4.1, text and binary (4.0 goes to meshio).

One concern, so one module although it is over 400 lines: each section of the format
(``$MeshFormat``, ``$PhysicalNames``, ``$Entities``, ``$PartitionedEntities``, ``$Nodes``,
``$Elements``, ``$NodeData``/``$ElementData``, ``$QdrefineData``) is parsed with
whole-array NumPy operations by its own handler, and :func:`read` assembles the mesh;
every error names the line (text) or byte (binary).
"""

from __future__ import annotations

import json
import math
import re
import tempfile
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._core import RawMesh, check_readable, from_blocks, read_bytes, split_data
from .._text import BadNumber, parse, parse_table
from ..recorded import record_of, restored
from .common import ELEMENTS, EXACT_INT, GmshError, element_dimension

__all__ = ["read"]

_SECTION = re.compile(rb"\$(\w+)[ \t\r]*\n")
_NAME = re.compile(r'^\s*(-?\d+)\s+(-?\d+)\s+"(.*)"\s*$')


class _File:
    """The bytes of an MSH file and a cursor; errors name the line (text) or byte (binary)."""

    def __init__(self, path: Path, data: bytes) -> None:
        self.path, self.data = path, data
        self.binary = False

    def where(self, offset: int) -> str:
        if self.binary:
            return f"byte {offset}"
        return f"line {self.line_number(offset)}"

    def line_number(self, offset: int) -> int:
        return self.data.count(b"\n", 0, offset) + 1

    def error(self, offset: int, message: str) -> GmshError:
        return GmshError(f"{self.where(offset)}: {message}")

    def end_of(self, name: str, start: int) -> int:
        """Offset of ``$End<name>`` after ``start`` (text sections)."""
        end = self.data.find(b"$End" + name.encode(), start)
        if end < 0:
            raise self.error(start, f"the file ends inside ${name} (no $End{name})")
        return end

    def numbers(self, start: int, end: int, dtype: type, what: str) -> NDArray:
        try:
            return parse(self.data[start:end], dtype, what)
        except BadNumber as exc:
            line = self.data.count(b"\n", 0, start) + exc.line
            raise GmshError(f"line {line}: expected {exc.what}, got {exc.token!r}") from None

    def line(self, pos: int, name: bool = False) -> tuple[str, int]:
        """The text line at ``pos`` (stripped) and the offset after it; ``name``: a name,
        read by :meth:`text` (other lines hold numbers, and their bad bytes are named by
        the error they make)."""
        end = self.data.find(b"\n", pos)
        if end < 0:
            end = len(self.data)
        text = self.text(pos, end) if name else self.data[pos:end].decode("utf-8", "replace")
        return text.strip(), end + 1

    def text(self, start: int, end: int) -> str:
        """The bytes ``start:end`` as UTF-8, or as Latin-1 with a warning where they are not
        UTF-8 (a name of an older tool: 'caf\\xe9' was read as 'caf\\ufffd', silently, and
        written back so)."""
        chunk = self.data[start:end]
        try:
            return chunk.decode("utf-8")
        except UnicodeDecodeError as exc:
            warnings.warn(f"{self.path}: {self.where(start + exc.start)}: not UTF-8; read as "
                          "Latin-1", stacklevel=4)
            return chunk.decode("latin-1")

    def take(self, pos: int, dtype: np.dtype, count: int, what: str) -> tuple[NDArray, int]:
        """``count`` binary items of ``dtype`` at ``pos`` (bounded by the file size)."""
        dtype = np.dtype(dtype)
        if count < 0 or pos + count * dtype.itemsize > len(self.data):
            raise self.error(pos, f"the file ends inside {what} ({count} items of "
                                  f"{dtype.itemsize} bytes announced)")
        return np.frombuffer(self.data, dtype=dtype, count=count, offset=pos), \
            pos + count * dtype.itemsize


def read(path: Path) -> RawMesh:
    """The content of a Gmsh MSH file (2.0-2.2 or 4.1; 4.0 through meshio)."""
    check_readable(path)
    data = read_bytes(path)
    f = _File(path, data)
    try:
        return _read(f)
    except GmshError as exc:
        raise ValueError(f"{path}: not a readable Gmsh MSH file ({exc})") from None


class _Content:
    def __init__(self) -> None:
        self.version = ""
        self.node_tags: NDArray | None = None
        self.points: NDArray | None = None
        # (type, physical tag(s), dimension, element tags, nodes) per element block
        self.blocks: list[tuple[int, object, int, NDArray, NDArray]] = []
        # physical tags of each (dimension, entity); (0,): none
        self.entities: dict[tuple[int, int], tuple[int, ...]] = {}
        # MSH 4.1 entities in several physical groups: (dimension, entity, tags, elements)
        self.several: list[tuple[int, int, tuple[int, ...], NDArray, NDArray]] = []
        self.names: dict[tuple[int, int], str] = {}
        self.node_data: dict[str, tuple[NDArray, NDArray]] = {}
        self.element_data: dict[str, tuple[NDArray, NDArray]] = {}
        self.dtypes: dict = {}


def _why_not(data: bytes) -> str:
    """Why a file that may hold ``$MeshFormat`` does not start with it, as a clause: a
    byte-order mark or lines ended by CR only (the message named only the section)."""
    head = data[:4096]
    if head.startswith(b"\xef\xbb\xbf"):
        return " (the file starts with a UTF-8 byte-order mark, which Gmsh does not read)"
    if b"\r" in head and b"\n" not in head:
        return " (its lines end in CR only; MSH lines end in LF or CR LF)"
    return ""


def _read(f: _File) -> RawMesh:
    c = _Content()
    pos = 0
    data = f.data
    seen: set[str] = set()
    while True:
        while pos < len(data) and data[pos:pos + 1] in (b"\n", b"\r", b" ", b"\t"):
            pos += 1
        if pos >= len(data):
            break
        m = _SECTION.match(data, pos)
        if m is None:
            if not c.version:
                raise f.error(pos, "no $MeshFormat section at the start" + _why_not(data))
            raise f.error(pos, f"expected a section ($Name), got {f.line(pos)[0][:40]!r}")
        name = m.group(1).decode()
        start = m.end()
        if not c.version and name != "MeshFormat":
            raise f.error(pos, "no $MeshFormat section at the start" + _why_not(data))
        if name in _ONCE:
            if name in seen:  # the second replaced the first without a word
                raise f.error(pos, f"a second ${name} section (a file holds one)")
            seen.add(name)
        if name in ("Entities", "PartitionedEntities") and "Elements" in seen \
                and c.version != "4.0":  # its elements took physical group 0 (tags lost)
            raise f.error(pos, f"${name} after $Elements: the elements' physical groups "
                               f"are those of their entities, so ${name} must come first "
                               "(as Gmsh writes it)")
        handler = _HANDLERS.get(name)
        if c.version == "4.0" and (name not in ("MeshFormat", "Entities") or f.binary):
            handler = None  # meshio reads MSH 4.0; the entities only say what it loses
        if name == "ParametricNodes":  # MSH 2.2 with Mesh.SaveParametric: not $Nodes
            raise f.error(pos, "$ParametricNodes (a file saved with Mesh.SaveParametric) is "
                               "not read; save the mesh without it")
        if handler is None:
            end = f.end_of(name, start)
        else:
            try:
                end = handler(f, c, start)
            except GmshError:
                if c.version != "4.0" or name != "Entities":
                    raise
                c.entities.clear()  # read for the warning only: meshio reads the file
                end = f.end_of(name, start)
            except (OverflowError, ValueError) as exc:  # e.g. int() of an inf or nan count
                if str(exc).startswith(str(f.path)):
                    raise
                raise f.error(start, f"${name} holds a count or tag that is not an integer "
                                     f"({exc})") from None
        pos = _expect_end(f, name, end)
    if c.version == "4.0":
        for needed in ("Nodes", "Elements"):  # meshio said "cannot access local variable"
            if needed not in seen:
                raise f.error(len(data), f"no ${needed} section")
        return _meshio_fallback(f, c)
    if not c.version:
        raise f.error(0, "no $MeshFormat section (empty file?)")
    if c.points is None:
        raise f.error(len(data), "no $Nodes section")
    for where, views in (("point", c.node_data), ("cell", c.element_data)):
        recorded = c.dtypes.get(where)
        missing = [n for n in recorded if n not in views] if isinstance(recorded, dict) else []
        if missing:  # qdrefine writes the record before the mesh: the file was cut short
            raise f.error(len(data), f"$QdrefineData records the {where} data {missing[0]!r}, "
                                     "which the file does not hold (the file ends early, or "
                                     "the view was removed)")
    return _assemble(f, c)


def _expect_end(f: _File, name: str, pos: int) -> int:
    data = f.data
    while pos < len(data) and data[pos:pos + 1] in (b"\n", b"\r", b" ", b"\t"):
        pos += 1
    tag = b"$End" + name.encode()
    if not data.startswith(tag, pos):
        raise f.error(pos, f"expected $End{name}"
                           + (" (the file ends early)" if pos >= len(data) else ""))
    return pos + len(tag)


def _int(value: float) -> int:
    """A count or tag read as a float: an integer of 32 bits (``ValueError`` otherwise, which
    the section reader turns into one line naming the file)."""
    if not np.isfinite(value) or value != np.round(value) or abs(value) >= 2**31:
        raise ValueError(f"expected an integer of 32 bits, got {value:g}")
    return int(value)


def _count(value: float) -> int:
    """A count read as a float: :func:`_int`, and not negative."""
    n = _int(value)
    if n < 0:
        raise ValueError(f"expected a count, got {n}")
    return n


def _node_width(f: _File, pos: int, dim: int, parametric: int) -> int:
    """The numbers per node of an MSH 4.1 node block: x, y, z and, for a parametric block,
    ``dim`` parameters (``GmshError`` for a dimension or flag out of range)."""
    if not 0 <= dim <= 3 or parametric not in (0, 1):
        raise f.error(pos, f"$Nodes: a node block of dimension {dim}, parametric flag "
                           f"{parametric} (expected 0 to 3, and 0 or 1)")
    return 3 + (dim if parametric else 0)


def _mesh_format(f: _File, c: _Content, start: int) -> int:
    text, pos = f.line(start)
    words = text.split()
    if len(words) != 3 or words[2] != "8" or words[1] not in ("0", "1"):
        raise f.error(start, f"expected 'version file-type 8' after $MeshFormat, got {text!r}")
    version = words[0]
    if version not in ("2", "2.0", "2.1", "2.2", "4", "4.0", "4.1"):
        raise f.error(start, f"MSH version {version} is not supported (2.2 and 4.1 are)")
    c.version = "4.0" if version in ("4", "4.0") else ("4.1" if version == "4.1" else "2.2")
    if words[1] == "1":
        f.binary = True
        one, pos = f.take(pos, np.int32, 1, "$MeshFormat")
        if one[0] == 1 << 24:  # 1 as written by a big-endian machine
            raise f.error(pos - 4, "big-endian binary MSH files are not supported")
        if one[0] != 1:
            raise f.error(pos - 4, f"the binary format's marker is {int(one[0])}, not the "
                                   "integer 1")
    return pos


def _physical_names(f: _File, c: _Content, start: int) -> int:
    end = f.end_of("PhysicalNames", start)
    # lines end at "\n" only, as Gmsh reads them (str.splitlines also breaks at "\x0c",
    # "\u2028" and others, which a name may hold)
    lines = f.text(start, end).split("\n")
    lines = [x.removesuffix("\r") for x in lines if x.strip()]
    if not lines or not lines[0].strip().isdigit():
        raise f.error(start, "expected the number of physical names")
    count = int(lines[0])
    if count != len(lines) - 1:
        raise f.error(start, f"$PhysicalNames announces {count} names, holds {len(lines) - 1}")
    for i, line in enumerate(lines[1:]):
        m = _NAME.match(line)
        if m is None:
            raise f.error(start, f"physical name {i + 1}: expected 'dim tag \"name\"', got "
                                 f"{line.strip()[:60]!r}")
        key = (int(m.group(1)), int(m.group(2)))
        if key in c.names and c.names[key] != m.group(3):
            raise f.error(start, f"physical group {key[1]} of dimension {key[0]} is named "
                                 f"twice ({c.names[key]!r} and {m.group(3)!r})")
        c.names[key] = m.group(3)
    return end


def _entities(f: _File, c: _Content, start: int) -> int:
    if c.version == "2.2":
        return f.end_of("Entities", start)
    if f.binary:
        head, pos = f.take(start, np.uint64, 4, "$Entities")
        for dim, count in enumerate(head.tolist()):
            for _ in range(int(count)):
                tag, pos = f.take(pos, np.int32, 1, "$Entities")
                pos = _groups_binary(f, c, pos, dim, int(tag[0]), "$Entities")
        return pos
    end = f.end_of("Entities", start)
    v = f.numbers(start, end, np.float64, "a number")
    i = 4
    try:
        for dim in range(4):
            for _ in range(_count(v[dim])):
                box = 3 if dim == 0 and c.version == "4.1" else 6  # 4.0: a box for points
                i = _groups_text(v, i + 1, c, dim, _int(v[i]), box)
    except (IndexError, ValueError, OverflowError):
        raise f.error(start, "$Entities ends early, or a count in it is not a count") from None
    if i != len(v):
        raise f.error(start, f"$Entities holds {len(v) - i} numbers more than its counts "
                             "announce")
    return end


def _groups_text(v: NDArray, i: int, c: _Content, dim: int, tag: int, box: int) -> int:
    """From ``v[i]`` (text numbers): an entity's point or box (``box`` numbers), its
    physical groups (kept for entity ``(dim, tag)``) and bounding entities; the place
    after them."""
    i += box
    n_phys = _count(v[i])
    if i + 1 + n_phys > len(v):
        raise IndexError
    c.entities[(dim, tag)] = tuple(_int(p) for p in v[i + 1:i + 1 + n_phys]) or (0,)
    i += 1 + n_phys
    return i + 1 + _count(v[i]) if dim > 0 else i


def _groups_binary(f: _File, c: _Content, pos: int, dim: int, tag: int, what: str) -> int:
    """:func:`_groups_text` of a binary section, from byte ``pos``."""
    _, pos = f.take(pos, np.float64, 3 if dim == 0 else 6, what)
    n, pos = f.take(pos, np.uint64, 1, what)
    phys, pos = f.take(pos, np.int32, int(n[0]), what)
    c.entities[(dim, tag)] = tuple(int(p) for p in phys) or (0,)
    if dim > 0:
        n, pos = f.take(pos, np.uint64, 1, what)
        _, pos = f.take(pos, np.int32, int(n[0]), what)
    return pos


def _partitioned_entities(f: _File, c: _Content, start: int) -> int:
    """MSH 4.1 ``$PartitionedEntities`` (a mesh saved after ``gmsh.model.mesh.partition``):
    the elements belong to these entities, whose physical tags are given here (without
    them every tag read as 0 and the tagged edges were lost)."""
    if c.version != "4.1":
        return f.end_of("PartitionedEntities", start)
    if f.binary:
        head, pos = f.take(start, np.uint64, 2, "$PartitionedEntities")
        _, pos = f.take(pos, np.int32, 2 * int(head[1]), "$PartitionedEntities")  # ghosts
        counts, pos = f.take(pos, np.uint64, 4, "$PartitionedEntities")
        for dim, count in enumerate(counts.tolist()):
            for _ in range(int(count)):
                ids, pos = f.take(pos, np.int32, 3, "$PartitionedEntities")  # tag, parent
                n, pos = f.take(pos, np.uint64, 1, "$PartitionedEntities")
                _, pos = f.take(pos, np.int32, int(n[0]), "$PartitionedEntities")  # partitions
                pos = _groups_binary(f, c, pos, dim, int(ids[0]), "$PartitionedEntities")
        return pos
    end = f.end_of("PartitionedEntities", start)
    v = f.numbers(start, end, np.float64, "a number")
    try:
        i = 2 + 2 * _count(v[1])  # partitions, ghost entities and their pairs
        counts = [_count(x) for x in v[i:i + 4]]
        if len(counts) != 4:
            raise IndexError
        i += 4
        for dim, count in enumerate(counts):
            for _ in range(count):
                tag, at = _int(v[i]), i + 4 + _count(v[i + 3])  # parent, partitions
                i = _groups_text(v, at, c, dim, tag, 3 if dim == 0 else 6)
    except (IndexError, ValueError, OverflowError):
        raise f.error(start, "$PartitionedEntities ends early, or a count in it is not a "
                             "count") from None
    if i != len(v):
        raise f.error(start, f"$PartitionedEntities holds {len(v) - i} numbers more than its "
                             "counts announce")
    return end


def _nodes(f: _File, c: _Content, start: int) -> int:
    if c.version == "2.2":
        return _nodes22(f, c, start)
    if f.binary:
        head, pos = f.take(start, np.uint64, 4, "$Nodes")
        n_blocks, n_nodes = int(head[0]), int(head[1])
        if n_nodes * 32 > len(f.data):
            raise f.error(start, f"$Nodes announces {n_nodes} nodes, more than the file holds")
        tags, coords = [], []
        for _ in range(n_blocks):
            b, pos = f.take(pos, np.int32, 3, "$Nodes")
            width = _node_width(f, pos - 12, int(b[0]), int(b[2]))
            count, pos = f.take(pos, np.uint64, 1, "$Nodes")
            n = int(count[0])
            t, pos = f.take(pos, np.uint64, n, "$Nodes")
            if n and int(t.max()) >= 2**63:  # read as negative tags before (review)
                raise f.error(start, f"node tag {int(t.max())} is beyond int64 (tags are "
                                     "integers below 2**63)")
            x, pos = f.take(pos, np.float64, n * width, "$Nodes")
            tags.append(t.astype(np.int64))
            coords.append(x.reshape(n, width)[:, :3])
        end = pos
    else:
        end = f.end_of("Nodes", start)
        fast = _nodes41_by_lines(f, start, end)
        if fast is not None:
            c.node_tags, c.points = fast
            return end
        v = f.numbers(start, end, np.float64, "a number")
        if len(v) < 4:
            raise f.error(start, "$Nodes ends early")
        n_blocks, n_nodes = int(v[0]), int(v[1])
        i = 4
        tags, coords = [], []
        for _ in range(n_blocks):
            if i + 4 > len(v):
                raise f.error(end, "$Nodes ends early (fewer node blocks than announced)")
            dim, parametric, n = int(v[i]), int(v[i + 2]), int(v[i + 3])
            i += 4
            width = _node_width(f, start, dim, parametric)
            if n < 0 or i + n * (1 + width) > len(v):
                raise f.error(end, f"$Nodes ends early (a block announces {n} nodes)")
            tags.append(v[i:i + n])
            i += n
            coords.append(v[i:i + n * width].reshape(n, width)[:, :3])
            i += n * width
        if i != len(v):
            raise f.error(end, f"$Nodes holds {len(v) - i} numbers more than announced")
    c.node_tags = _tag_array(f, np.concatenate(tags) if tags else np.empty(0), start, "node")
    c.points = np.concatenate(coords) if coords else np.empty((0, 3))
    del n_nodes  # Gmsh itself writes totals that differ from the blocks: the blocks count
    return end


def _line_index(data: bytes, start: int, end: int):
    """Offsets of the lines of ``data[start:end]`` and ``lines(first, count) -> bytes``."""
    newlines = np.flatnonzero(np.frombuffer(data, np.uint8, end - start, start) == 10) + start
    line_start = np.concatenate([[start], newlines + 1])

    def lines(first: int, count: int) -> bytes:
        if first + count >= len(line_start):
            raise IndexError
        return data[line_start[first]:line_start[first + count]]

    return line_start, lines


def _elements41_by_lines(f: _File, c: _Content, start: int, end: int) -> bool:
    """Text ``$Elements`` of MSH 4.1 with one element per line: each block parsed as a table
    (the fast path). False (and nothing stored) when the layout differs."""
    several = len(c.several)  # entities in several groups noted by _block41
    blocks = _element_tables(f, c, start, end)
    if blocks is None:
        del c.several[several:]  # the general parser notes them again
        return False
    c.blocks.extend(blocks)
    return True


def _element_tables(f: _File, c: _Content, start: int, end: int) -> list | None:
    line_start, lines = _line_index(f.data, start, end)
    blocks = []
    try:
        n_blocks = int(lines(0, 1).split()[0])
        at = 1
        for block in range(n_blocks):
            dim, ent, typ, n = (int(x) for x in lines(at, 1).split())
            if typ not in ELEMENTS:
                return None
            npe = ELEMENTS[typ][1]
            rows = parse_table(lines(at + 1, n), 1 + npe, dtype=np.int64) if n else \
                np.empty((0, 1 + npe), np.int64)
            if rows.shape != (n, 1 + npe):
                return None
            blocks.append(_block41(f, line_start[at], block, c, typ, dim, ent, rows[:, 0],
                                   rows[:, 1:]))
            at += 1 + n
        if f.data[line_start[at]:end].strip():
            return None
    except GmshError:  # a refusal, at its line
        raise
    except (IndexError, ValueError):
        return None
    return blocks


def _nodes41_by_lines(f: _File, start: int, end: int
                      ) -> tuple[NDArray[np.int64], NDArray[np.float64]] | None:
    """Text ``$Nodes`` of MSH 4.1 laid out one item per line (as Gmsh writes it): each
    block's tags parsed as integers and its coordinates as a table (the fast path). ``None``
    when the layout differs; the general parser then reads (and names any bad line)."""
    data = f.data
    line_start, lines = _line_index(data, start, end)
    try:
        head = lines(0, 1).split()
        n_blocks = int(head[0])
        at = 1
        tags, coords = [], []
        for _ in range(n_blocks):
            dim, _, parametric, n = (int(x) for x in lines(at, 1).split())
            if not 0 <= dim <= 3 or parametric not in (0, 1) or n < 0:
                return None  # the general parser names it
            width = 3 + (dim if parametric else 0)
            t = parse(lines(at + 1, n), np.int64) if n else np.empty(0, np.int64)
            x = parse_table(lines(at + 1 + n, n), width) if n else np.empty((0, width))
            if len(t) != n or x.shape != (n, width):
                return None
            tags.append(t)
            coords.append(x[:, :3])
            at += 1 + 2 * n
        if data[line_start[at]:end].strip():
            return None
    except (IndexError, ValueError):
        return None
    return (np.concatenate(tags) if tags else np.empty(0, np.int64),
            np.concatenate(coords) if coords else np.empty((0, 3)))


def _tag_array(f: _File, tags: NDArray, start: int, what: str) -> NDArray[np.int64]:
    if tags.dtype.kind == "f" and len(tags):
        beyond = np.abs(tags) >= 2.0**63
        if beyond.any():  # was "below 2**53", though the usual layout reads int64 exactly
            raise f.error(start, f"{what} tag {float(tags[beyond.argmax()]):.17g} is beyond "
                                 "int64 (tags are integers below 2**63)")
        bad = ~((tags == np.round(tags)) & (np.abs(tags) < EXACT_INT))
        if bad.any():
            raise f.error(start, f"{what} tags must be integers below 2**53 (the first "
                                 f"that is not: {float(tags[bad.argmax()]):.17g})")
    return tags.astype(np.int64)


def _nodes22(f: _File, c: _Content, start: int) -> int:
    text, pos = f.line(start)
    if not text.isdigit():
        raise f.error(start, f"expected the number of nodes, got {text[:40]!r}")
    n = int(text)
    if f.binary:
        rec = np.dtype([("tag", np.int32), ("xyz", np.float64, 3)])
        nodes, end = f.take(pos, rec, n, "$Nodes")
        c.node_tags = nodes["tag"].astype(np.int64)
        c.points = np.array(nodes["xyz"])
        return end
    end = f.end_of("Nodes", pos)
    try:
        v = parse_table(f.data[pos:end], 4)
    except BadNumber:
        v = f.numbers(pos, end, np.float64, "a number").reshape(-1, 1)  # names the line
    if v.shape != (n, 4):
        raise f.error(start, f"$Nodes announces {n} nodes (4 numbers each), holds "
                             f"{v.size} numbers")
    c.node_tags = _tag_array(f, v[:, 0], start, "node")
    c.points = np.ascontiguousarray(v[:, 1:])
    return end


def _elements(f: _File, c: _Content, start: int) -> int:
    if c.version == "2.2":
        return _elements22(f, c, start)
    if f.binary:
        head, pos = f.take(start, np.uint64, 4, "$Elements")
        for block in range(int(head[0])):
            at = pos
            b, pos = f.take(pos, np.int32, 3, "$Elements")
            count, pos = f.take(pos, np.uint64, 1, "$Elements")
            kind = _kind(f, int(b[2]), pos)
            n, npe = int(count[0]), ELEMENTS[kind][1]
            v, pos = f.take(pos, np.uint64, n * (1 + npe), "$Elements")
            v = v.reshape(n, 1 + npe).view(np.int64)  # tags < 2**63
            c.blocks.append(_block41(f, at, block, c, kind, int(b[0]), int(b[1]), v[:, 0],
                                     v[:, 1:]))
        return pos
    end = f.end_of("Elements", start)
    if _elements41_by_lines(f, c, start, end):
        return end
    v = f.numbers(start, end, np.int64, "an integer")
    if len(v) < 4:
        raise f.error(start, "$Elements ends early")
    i = 4
    for block in range(int(v[0])):
        if i + 4 > len(v):
            raise f.error(end, "$Elements ends early (fewer element blocks than announced)")
        dim, ent, typ, n = (int(x) for x in v[i:i + 4])
        i += 4
        kind = _kind(f, typ, start)
        npe = ELEMENTS[kind][1]
        if n < 0 or i + n * (1 + npe) > len(v):
            raise f.error(end, f"$Elements ends early (a block announces {n} elements)")
        rows = v[i:i + n * (1 + npe)].reshape(n, 1 + npe)
        i += n * (1 + npe)
        c.blocks.append(_block41(f, start, block, c, kind, dim, ent, rows[:, 0], rows[:, 1:]))
    if i != len(v):
        raise f.error(end, f"$Elements holds {len(v) - i} numbers more than announced")
    return end


def _block41(f: _File, at: int, block: int, c: _Content, kind: int, dim: int, ent: int,
             ids: NDArray, nodes: NDArray) -> tuple[int, int, int, NDArray, NDArray]:
    """An MSH 4.1 element block (number ``block`` from 0; its header at offset ``at``, or
    the section's start where the parser does not know it) with its entity's physical
    tag; an entity in several physical groups is noted (:func:`_several_groups`) and takes
    the first. Elements of another dimension than their entity's are refused (they would
    take another entity's physical group: a triangle on curve 1, curve 1's)."""
    if element_dimension(kind) != dim:
        raise f.error(at, f"element block {block + 1} of $Elements holds "
                          f"{ELEMENTS[kind][0]}s (dimension {element_dimension(kind)}) in "
                          f"entity {ent} of dimension {dim}")
    tags = c.entities.get((dim, ent), (0,))
    if len(tags) > 1 and len(ids):
        c.several.append((dim, ent, tags, ids, nodes))
    return kind, tags[0], dim, ids, nodes


def _kind(f: _File, typ: int, pos: int) -> int:
    if typ not in ELEMENTS:
        raise f.error(pos, f"unknown element type {typ}")
    return typ


def _elements22(f: _File, c: _Content, start: int) -> int:
    text, pos = f.line(start)
    if not text.isdigit():
        raise f.error(start, f"expected the number of elements, got {text[:40]!r}")
    total = int(text)
    if f.binary:
        done = 0
        look = 16  # blocks examined at once for a run of equal headers (doubled while found)
        while done < total:
            h, _ = f.take(pos, np.int32, 3, "$Elements")
            typ, n, ntags = (int(x) for x in h)
            kind = _kind(f, typ, pos)
            npe = ELEMENTS[kind][1]
            if n <= 0 or ntags < 0 or done + n > total:
                raise f.error(pos, f"bad element block header ({typ}, {n}, {ntags})")
            # Gmsh writes one block per element: take the run of blocks with this header
            width = 3 + n * (1 + ntags + npe)  # int32 per block, header included
            fit = min(look, (total - done) // n, (len(f.data) - pos) // (4 * width))
            if fit == 0:  # the file ends inside this block
                f.take(pos + 12, np.int32, n * (1 + ntags + npe), "$Elements")
            recs = np.frombuffer(f.data, np.int32, count=fit * width, offset=pos)
            recs = recs.reshape(fit, width)
            same = (recs[:, :3] == h).all(axis=1)
            run = fit if same.all() else int(np.argmin(same))
            look = 2 * look if run == fit else 16
            v = recs[:run, 3:].reshape(run * n, 1 + ntags + npe).astype(np.int64)
            phys = v[:, 1] if ntags else np.zeros(run * n, np.int64)
            c.blocks.append((kind, phys, -1, v[:, 0], v[:, 1 + ntags:]))
            done += run * n
            pos += 4 * width * run
        return pos
    end = f.end_of("Elements", pos)
    section = f.data[pos:end]
    v = f.numbers(pos, end, np.int64, "an integer")
    # the line of every number, from the bytes: numbers per line give each element's row
    b = np.frombuffer(section, dtype=np.uint8)
    space = (b == 32) | (b == 9) | (b == 13) | (b == 10)
    first = ~space & np.concatenate([[True], space[:-1]])
    # line (0-based, from pos) of each number
    line = np.searchsorted(np.flatnonzero(b == 10), np.flatnonzero(first))
    if len(line) != len(v):
        raise f.error(pos, "unreadable numbers in $Elements")
    cut = np.flatnonzero(np.diff(line)) + 1  # ``line`` is sorted: runs are lines
    lines = line[np.concatenate([[0], cut])] if len(line) else line
    counts = np.diff(np.concatenate([[0], cut, [len(line)]])) if len(line) else line
    if len(lines) != total:
        raise f.error(start, f"$Elements announces {total} elements, holds {len(lines)} lines")
    if total == 0:
        return end
    off = np.concatenate([[0], np.cumsum(counts)[:-1]])
    bad = counts < 3
    if not bad.any():
        typ, ntags = v[off + 1], v[off + 2]
        npe = np.zeros(len(typ), np.int64)
        known = np.isin(typ, list(ELEMENTS))
        if not known.all():
            k = int(np.flatnonzero(~known)[0])
            raise GmshError(f"line {f.line_number(pos) + int(lines[k])}: "
                            f"unknown element type {int(typ[k])}")
        table = np.zeros(max(ELEMENTS) + 1, np.int64)
        table[list(ELEMENTS)] = [n for _, n in ELEMENTS.values()]
        npe = table[typ]
        bad = (ntags < 0) | (counts != 3 + ntags + npe)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise GmshError(f"line {f.line_number(pos) + int(lines[k])}: an element "
                        "line with the wrong number of integers for its type")
    for t in np.unique(typ).tolist():
        rows = np.flatnonzero(typ == t)
        first_node = off[rows] + 3 + ntags[rows]
        nodes = v[first_node[:, None] + np.arange(ELEMENTS[t][1])]
        phys = np.where(ntags[rows] > 0, v[np.minimum(off[rows] + 3, len(v) - 1)], 0)
        c.blocks.append((t, phys, -1, v[off[rows]], nodes))
    return end


def _data_section(kind: str):
    def handler(f: _File, c: _Content, start: int) -> int:
        pos = start
        header: list[list[str]] = []
        for _ in range(3):
            text, pos = f.line(pos)
            if not text.lstrip("-").isdigit():
                raise f.error(pos, f"${kind}: expected a number of tags, got {text[:40]!r}")
            values = []
            for _ in range(int(text)):
                if pos >= len(f.data) or f.data.startswith(b"$End", pos):
                    raise f.error(start, f"${kind}: the section ends inside its {text} tags")
                if not header and not values:
                    name_at = pos  # the view's name, decoded once the section reads
                value, pos = f.line(pos)
                values.append(value)
            header.append(values)
        strings, _, ints = header
        try:
            components, count = int(ints[1]), int(ints[2])
        except (IndexError, ValueError):
            raise f.error(start, f"${kind}: expected 3 integer tags (step, components, "
                                 "count)") from None
        name = strings[0].strip('"') if strings else kind
        if components <= 0 or count < 0:
            raise f.error(start, f"${kind}: bad number of components or values")
        if f.binary:
            rec = np.dtype([("tag", np.int32), ("v", np.float64, (components,))])
            values, end = f.take(pos, rec, count, f"${kind}")
            tags, v = values["tag"].astype(np.int64), np.array(values["v"])
        else:
            end = f.end_of(kind, pos)
            numbers = f.numbers(pos, end, np.float64, "a number")
            if len(numbers) != count * (1 + components):
                raise f.error(start, f"${kind} announces {count} values of {components} "
                                     f"components, holds {len(numbers)} numbers")
            numbers = numbers.reshape(count, 1 + components)
            tags = _tag_array(f, numbers[:, 0], start, "node" if kind == "NodeData"
                              else "element")
            v = np.ascontiguousarray(numbers[:, 1:])
        target = c.node_data if kind == "NodeData" else c.element_data
        saved = tags > 0  # Gmsh 2.2 gives -1 to the nodes of a view not in the file
        if not saved.all():
            tags, v = tags[saved], v[saved]
        twice = _first_duplicate(tags)
        if twice is not None:
            what = "node" if kind == "NodeData" else "element"
            raise f.error(start, f"${kind} {name!r} gives {what} {twice} two values")
        if strings:
            name = f.line(name_at, name=True)[0].strip('"')  # not UTF-8: said here
        if name in target:  # a view's later time step: one field per name
            warnings.warn(f"{f.path}: ${kind} {name!r} is given more than once (time steps "
                          "of a view); the last one is kept", stacklevel=2)
        target[name] = (tags, v)
        return end
    return handler


def _qdrefine_data(f: _File, c: _Content, start: int) -> int:
    end = f.end_of("QdrefineData", start)
    try:
        c.dtypes = json.loads(f.data[start:end].decode())
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):  # nested too deep
        raise f.error(start, "$QdrefineData is not JSON") from None
    if not isinstance(c.dtypes, dict):
        c.dtypes = {}
    return end


#: Sections a file holds at most once.
_ONCE = ("MeshFormat", "PhysicalNames", "Entities", "PartitionedEntities", "Nodes",
         "Elements", "QdrefineData")

_HANDLERS = {
    "MeshFormat": _mesh_format, "PhysicalNames": _physical_names, "Entities": _entities,
    "PartitionedEntities": _partitioned_entities,
    "Nodes": _nodes, "Elements": _elements, "NodeData": _data_section("NodeData"),
    "ElementData": _data_section("ElementData"), "QdrefineData": _qdrefine_data,
}


def _is_range(tags: NDArray[np.int64]) -> bool:
    """Whether ``tags`` is ``1, 2, ..., len(tags)`` (what Gmsh and qdrefine write)."""
    n = len(tags)
    return n == 0 or (tags[0] == 1 and tags[-1] == n and bool((np.diff(tags) == 1).all()))


def _first_duplicate(tags: NDArray[np.int64]) -> int | None:
    if _is_range(tags):
        return None
    s = np.sort(tags)
    same = np.flatnonzero(s[1:] == s[:-1])
    return int(s[same[0]]) if len(same) else None


def _rows_of(tags: NDArray[np.int64], query: NDArray[np.int64], contiguous: bool | None = None
             ) -> NDArray[np.int64]:
    """Row of each ``query`` tag in ``tags`` (-1 where absent); ``tags`` unique. ``query``
    keeps its shape."""
    n = len(tags)
    if n == 0:
        return np.full(query.shape, -1, np.int64)
    if contiguous if contiguous is not None else _is_range(tags):
        rows = np.subtract(query, 1, dtype=np.int64)
        if len(rows) and (rows.min() < 0 or rows.max() >= n):
            rows[(rows < 0) | (rows >= n)] = -1
        return rows
    order = np.argsort(tags, kind="stable")
    sorted_tags = tags[order]
    pos = np.minimum(np.searchsorted(sorted_tags, query), n - 1)
    found = sorted_tags[pos] == query
    return np.where(found, order[pos], -1)


def _positive(names: dict[tuple[int, int], str]) -> dict[tuple[int, int], str]:
    """Physical names keyed by the absolute values of their tags, as the elements' tags
    are read (a name given to the tag itself wins over one given to its negative)."""
    out = {key: name for key, name in names.items() if key[1] >= 0}
    for (dim, tag), name in names.items():
        out.setdefault((dim, abs(tag)), name)
    return out


def _assemble(f: _File, c: _Content) -> RawMesh:
    tags = c.node_tags
    twice = _first_duplicate(tags)
    if twice is not None:
        raise GmshError(f"node tag {twice} is given twice in $Nodes")
    contiguous = _is_range(tags)
    blocks, block_tags, element_ids = [], [], []
    negative = 0  # the first negative physical tag
    for kind, phys, _dim, ids, nodes in c.blocks:
        rows = _rows_of(tags, nodes, contiguous)
        if (rows < 0).any():
            k = np.argwhere(rows < 0)[0]
            raise GmshError(f"element {int(ids[k[0]])} uses node {int(nodes[k[0], k[1]])}, "
                            "which is not in $Nodes")
        name = ELEMENTS[kind][0]
        blocks.append((name, rows))
        phys = np.asarray(phys, np.int64)
        if phys.size and phys.min() < 0:  # read as Gmsh reads it (it was kept negative)
            negative = negative or int(phys.min())
            phys = np.abs(phys)
        block_tags.append(np.broadcast_to(phys, (len(rows),)))
        element_ids.append(ids)
    if negative:
        warnings.warn(f"{f.path}: negative physical tags (e.g. {negative}), which Gmsh reads "
                      f"as their absolute values ({-negative}): read so", stacklevel=3)
    if element_ids:
        twice = _first_duplicate(np.concatenate(element_ids).astype(np.int64))
        if twice is not None:
            raise GmshError(f"element tag {twice} is given twice in $Elements")
    for kind, tag, ids, nodes in _several_groups(f, c):  # lines once per physical group
        blocks.append((ELEMENTS[kind][0], _rows_of(tags, nodes, contiguous)))
        block_tags.append(np.full(len(ids), tag, np.int64))
        element_ids.append(ids)
    # sort each kind by element tag (keeps the order of files written grouped by entity)
    by_kind: dict[str, list[int]] = {}
    for i, (name, _) in enumerate(blocks):
        by_kind.setdefault(name, []).append(i)
    merged, merged_tags, tri_ids = [], [], np.empty(0, np.int64)
    line_ids, line_tags = np.empty(0, np.int64), np.empty(0, np.int64)
    for name, members in by_kind.items():
        rows = np.concatenate([blocks[i][1] for i in members])
        tg = np.concatenate([block_tags[i] for i in members])
        ids = np.concatenate([element_ids[i] for i in members])
        if len(ids) > 1 and (np.diff(ids) < 0).any():
            order = np.argsort(ids, kind="stable")
            rows, tg, ids = rows[order], tg[order], ids[order]
        if name == "triangle" and c.version == "2.2":
            rows, tg, ids = _once_per_triangle(f, rows, tg, ids)
        merged.append((name, rows))
        merged_tags.append(tg)
        if name == "triangle":
            tri_ids = ids
        elif name == "line":
            line_ids, line_tags = ids, tg
    # messages name points and triangles by the file's node and element tags
    raw = from_blocks(f.path, c.points, merged, merged_tags,
                      point_numbers=np.asarray(tags, dtype=np.int64))
    raw.physical_names = _positive(c.names) if negative else dict(c.names)
    if len(tri_ids) == len(raw.triangles):
        raw.triangle_numbers = np.asarray(tri_ids, dtype=np.int64)
    kept_lines = line_ids[np.asarray(line_tags) != 0]  # the lines that are tagged edges
    if raw.edges is not None and len(kept_lines) == len(raw.edges):
        raw.edge_numbers = np.asarray(kept_lines, dtype=np.int64)
    # values of nodes (elements) that the file does not hold are left out: Gmsh writes a
    # view over the whole model beside a mesh of its physical groups only
    point_data = {name: _field(f, c, "point", name, v, _rows_of(tags, t, contiguous), len(tags))
                  for name, (t, v) in c.node_data.items()}
    cell_data = {}
    if len(tri_ids) and c.element_data:
        if _first_duplicate(tri_ids) is not None:
            raise GmshError(f"element tag {_first_duplicate(tri_ids)} is given to two "
                            "triangles")
        for name, (t, v) in c.element_data.items():
            cell_data[name] = _field(f, c, "cell", name, v, _rows_of(tri_ids, t), len(tri_ids))
    split_data(raw, point_data, cell_data)
    return raw


def _groups(c: _Content, dim: int, tags) -> str:
    return ", ".join(f"{t} ({c.names[(dim, t)]!r})" if (dim, t) in c.names else str(t)
                     for t in tags)


def _several_groups(f: _File, c: _Content):
    """MSH 4.1 entities in several physical groups: their lines once more per further
    group, as ``(kind, tag, element tags, nodes)`` (MSH 2.2 files hold such lines once per
    group already); a warning for surfaces, whose triangles keep the first group's tag."""
    for dim, ent, tags, ids, nodes in c.several:
        if dim == 1:
            for tag in tags[1:]:
                yield 1, tag, ids, nodes
        elif dim == 2:
            warnings.warn(f"{f.path}: surface {ent} is in physical groups "
                          f"{_groups(c, dim, tags)}; a triangle holds one tag, so its "
                          f"{len(ids)} elements take {tags[0]}", stacklevel=2)


def _once_per_triangle(f: _File, rows: NDArray, tags: NDArray, ids: NDArray
                       ) -> tuple[NDArray, NDArray, NDArray]:
    """MSH 2.2: Gmsh writes a triangle once per physical group it is in. A triangle given
    again with another tag is dropped, with a warning: a triangle holds one tag (the
    first). A repetition with the same tag is left for the mesh checks to refuse."""
    if len(tags) < 2 or (tags == tags[0]).all():
        return rows, tags, ids
    srt = np.sort(rows, axis=1)
    order = np.lexsort((srt[:, 2], srt[:, 1], srt[:, 0]))
    same = (srt[order[1:]] == srt[order[:-1]]).all(axis=1)
    if not same.any():
        return rows, tags, ids
    again = np.zeros(len(rows), dtype=bool)  # a later copy of a triangle (stable sort)
    again[order[1:][same]] = True
    first = order[:-1][same]
    other = tags[order[1:][same]] != tags[first]
    again[order[1:][same][~other]] = False
    if not again.any():
        return rows, tags, ids
    pairs = sorted({(int(a), int(b)) for a, b in zip(tags[first][other],
                                                    tags[order[1:][same]][other], strict=True)})
    warnings.warn(f"{f.path}: {int(again.sum())} triangles are given again with another "
                  f"physical tag (tags {', '.join(f'{a} and {b}' for a, b in pairs[:3])}: a "
                  "surface in several physical groups); a triangle holds one tag, so each "
                  "keeps its first", stacklevel=2)
    keep = ~again
    return rows[keep], tags[keep], ids[keep]


def _field(f: _File, c: _Content, where: str, name: str, values: NDArray, rows: NDArray,
           size: int) -> NDArray:
    """One field: ``values (k, components)`` at ``rows`` (-1: not a point / triangle) spread
    over ``size`` rows (NaN where the file gives none), restored to the shape and dtype that
    ``$QdrefineData`` records where the record fits (:mod:`..recorded`; the writer pads a
    field to 1, 3 or 9 components with zeros)."""
    ok = rows >= 0
    if values.shape[1] > 9 and np.count_nonzero(ok) < size:  # made that wide from a few
        # values, or none: a 300-byte view of 1e8 components took 4 GB (review)
        raise ValueError(f"{f.path}: {where} data {name!r} has {values.shape[1]} components "
                         f"but values for {np.count_nonzero(ok)} of the {size} rows; Gmsh "
                         "views have 1, 3 or 9 components, and qdrefine writes wider fields "
                         "whole")
    out = np.full((size, values.shape[1]), np.nan)
    out[rows[ok]] = values[ok]
    spec = record_of(c.dtypes, where, name)
    stored = out
    shape = spec.get("shape") if isinstance(spec, dict) else None
    if isinstance(shape, list) and all(type(s) is int and s >= 0 for s in shape):
        width = math.prod(shape)
        rest = out[:, width:]
        if width <= out.shape[1] and ((rest == 0) | np.isnan(rest)).all():
            stored = out[:, :width]
    kept = restored(stored, spec, size, f"{f.path}: {where} data {name!r}")
    if kept is not None:
        return kept
    return out[:, 0] if out.shape[1] == 1 else out


def _meshio_fallback(f: _File, c: _Content) -> RawMesh:
    """MSH 4.0, read by meshio's MSH 4.0 reader (meshio takes the version "4", which Gmsh
    writes for MSH 4.0, as 4.1: the header is given to it as "4.0"); a warning when a
    curve is in several physical groups (meshio keeps each line's first group, where MSH
    4.1 and 2.2 give a tagged edge per group; a surface keeps one tag in every version)."""
    from ..meshio_formats import read_with_meshio

    several = sorted(key for key, tags in c.entities.items() if len(tags) > 1 and key[0] == 1)
    if several:
        _, tag = several[0]
        count = "a curve is" if len(several) == 1 else f"{len(several)} curves are"
        warnings.warn(f"{f.path}: {count} in several physical groups (the first: curve "
                      f"{tag}, groups {_groups(c, 1, c.entities[several[0]])}); MSH 4.0 is "
                      "read by meshio, which keeps each line's first group (from MSH 4.1 and "
                      "2.2 files, a tagged edge per group)", stacklevel=2)

    def msh40():  # a copy with the header "4.0" (meshio's reader needs a real file)
        import meshio

        data = re.sub(rb"^(\s*\$MeshFormat\s+)4(\s)", rb"\g<1>4.0\2", f.data, count=1)
        with tempfile.TemporaryDirectory(prefix="qdrefine-msh40-") as folder:
            copy = Path(folder) / "mesh.msh"
            copy.write_bytes(data)
            return meshio.read(copy, file_format="gmsh")

    return read_with_meshio(f.path, "gmsh", "Gmsh MSH", msh40)
