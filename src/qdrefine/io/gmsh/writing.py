"""Writing Gmsh MSH 4.1 (the default) and 2.2, text or binary, with physical names and
point and cell data as ``$NodeData``/``$ElementData`` views."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._core import MeshChunks, mesh_data
from .._text import format_floats, int_lines
from ..atomic import atomic_path
from ..recorded import record
from .common import EXACT_INT, VERSIONS

__all__ = ["write", "write_chunks", "Chunks", "GROUPED_PASSES"]

#: Rows per piece of a binary section: pieces go through one reused buffer (32 MiB of
#: elements), which costs less than building the whole section (page faults of a fresh
#: array as large as the file).
BINARY_ROWS = 1 << 20

#: Up to this many tag values, a chunked mesh is written with one element block per tag
#: (one pass over its chunks per tag, the layout of :func:`write`); beyond, one block per
#: tag in each chunk (two passes in all).
GROUPED_PASSES = 8


class Chunks(MeshChunks):
    """:class:`~qdrefine.io._core.MeshChunks` with the element blocks of MSH 4.1."""

    def groups(self, kind: str) -> tuple[list[int], int, Callable[[], Iterator]]:
        """The element blocks of MSH 4.1: ``(tags, n_blocks, blocks)``, the distinct tag
        values in increasing order (entity ``i + 1`` holds ``tags[i]``), the number of
        blocks, and ``blocks()`` yielding ``(entity, count, pieces)`` with ``pieces`` the
        ``(rows, cells)`` of the block in row order. Up to :data:`GROUPED_PASSES` tag values:
        one block per tag (one pass over the chunks per tag, as :func:`write` lays the file
        out); beyond: one block per tag in each chunk (two passes in all, whatever the
        number of tags)."""
        count = self.n_triangles if kind == "triangles" else self.n_edges
        if not count:
            return [], 0, lambda: iter(())
        if (self.cell_tags if kind == "triangles" else self.edge_tags) is None:
            return [0], 1, lambda: iter([(1, count, ((start + np.arange(len(c)), c)
                                                     for start, c, _ in self.cells(kind)))])
        totals: dict[int, int] = {}
        n_blocks = 0
        for _, _, tags in self.cells(kind):
            values, counts = np.unique(tags, return_counts=True)
            n_blocks += len(values)
            for v, c in zip(values.tolist(), counts.tolist(), strict=True):
                totals[v] = totals.get(v, 0) + c
        values = sorted(totals)
        entity = {v: i + 1 for i, v in enumerate(values)}
        if len(values) <= GROUPED_PASSES:
            def of_tag(value: int) -> Iterator[tuple[NDArray, NDArray]]:
                for start, c, tags in self.cells(kind):
                    sel = np.flatnonzero(tags == value)
                    if len(sel):
                        yield start + sel, c[sel]

            return values, len(values), lambda: ((entity[v], totals[v], of_tag(v))
                                                 for v in values)

        def per_chunk() -> Iterator[tuple[int, int, list]]:
            for start, c, tags in self.cells(kind):
                present, order, sizes = tag_groups(tags)
                if order is None:
                    order = np.arange(len(tags))
                ends = np.cumsum(sizes)
                for v, a, b in zip(present.tolist(), (ends - sizes).tolist(), ends.tolist(),
                                   strict=True):
                    rows = order[a:b]
                    yield entity[v], b - a, [(start + rows, c[rows])]

        return values, n_blocks, per_chunk


class _InMemory(Chunks):
    """A :class:`~qdrefine.Mesh` as one chunk, grouped by one sort of the tags."""

    def groups(self, kind: str) -> tuple[list[int], int, Callable[[], Iterator]]:
        if kind == "triangles":
            tags, cells, n = self.mesh.cell_tags, self.mesh.triangles, self.n_triangles
        else:
            tags, cells, n = self.mesh.edge_tags, self.mesh.edges, self.n_edges
        if not n:
            return [], 0, lambda: iter(())
        cells = np.asarray(cells)
        everything = (np.arange(n, dtype=np.int64), cells)
        if tags is None:
            return [0], 1, lambda: iter([(1, n, iter([everything]))])
        values, order, sizes = tag_groups(np.asarray(tags))
        if len(values) == 1:  # one tag: no gather
            return values.tolist(), 1, lambda: iter([(1, n, [everything])])
        ends = np.cumsum(sizes)
        blocks = []
        for i, (s, e) in enumerate(zip((ends - sizes).tolist(), ends.tolist(), strict=True)):
            blocks.append((i + 1, e - s, _gathered(order[s:e], cells)))
        return values.tolist(), len(blocks), lambda: iter(blocks)


def _gathered(rows: NDArray[np.int64], cells: NDArray) -> Iterator[tuple[NDArray, NDArray]]:
    """``(rows, cells[rows])`` in pieces of :data:`BINARY_ROWS` rows, gathered as they are
    written (no copy of the whole block)."""
    for a in range(0, len(rows), BINARY_ROWS):
        piece = rows[a:a + BINARY_ROWS]
        yield piece, cells[piece]


def tag_groups(tags: NDArray[np.integer]) -> tuple[NDArray[np.int64], NDArray[np.int64] | None,
                                                   NDArray[np.int64]]:
    """Rows grouped by integer tags (int64 or narrower): ``(values, order, sizes)``, the
    distinct values in increasing order, the rows in stable order of their values (``None``
    when there are fewer than two values) and the rows per value. Tags spanning fewer than
    65536 values (the usual case) are sorted as 8- or 16-bit keys, for which numpy's stable
    sort is a radix sort (7x faster than sorting the int64 tags of 7 M triangles here);
    others by a stable sort of the tags."""
    if tags.size == 0:
        empty = np.empty(0, dtype=np.int64)
        return empty, None, empty
    lo, hi = int(tags.min()), int(tags.max())
    if lo == hi:
        return np.array([lo], dtype=np.int64), None, np.array([tags.size], dtype=np.int64)
    if hi - lo < 1 << 16:
        keys = (tags - lo).astype(np.uint8 if hi - lo < 1 << 8 else np.uint16)
        counts = np.bincount(keys)
        present = np.flatnonzero(counts)
        return present + lo, np.argsort(keys, kind="stable"), counts[present]
    order = np.argsort(tags, kind="stable")
    values, first = np.unique(tags[order], return_index=True)
    return values.astype(np.int64), order, np.diff(np.append(first, tags.size))


def write(path: Path, mesh, *, binary: bool = False, version: str = "4.1") -> None:
    """Write ``mesh`` as Gmsh MSH ``version`` (``"4.1"`` or ``"2.2"``), text or binary."""
    _check_version(path, version)
    _check_tags_and_names(path, mesh)
    point_data, cell_data = mesh_data(mesh, path)
    sections = _data_sections(path, mesh, point_data, cell_data, binary)
    _write(path, _InMemory.of_mesh(mesh), binary, version, mesh.physical_names, sections)


def write_chunks(path: Path, source: Chunks, *, binary: bool = False,
                 version: str = "4.1") -> None:
    """Write a mesh given chunk by chunk (:class:`Chunks`) as Gmsh MSH ``version``: the same
    bytes as :func:`write` of the whole mesh (without data or names), in memory of one
    chunk at a time."""
    _check_version(path, version)
    for tags_of, n, what in ((source.cell_tags, source.n_triangles, "cell tag"),
                             (source.edge_tags, source.n_edges, "edge tag")):
        if tags_of is not None:  # one pass over the tags alone, before writing
            for start in range(0, n, 1 << 20):
                check_tag_range(path, what, tags_of(start, min(n, start + (1 << 20))))
    _write(path, source, binary, version, {}, [])


#: The tags an MSH file holds: Gmsh's tags are C ``int`` (binary files write int32), and
#: Gmsh reads a negative physical tag as its absolute value (text MSH 2.2 drops the element).
TAG_RANGE = (0, 2**31 - 1)


def check_tag_range(path: Path, what: str, tags: NDArray) -> None:
    """``ValueError`` naming the first of ``tags`` outside :data:`TAG_RANGE`."""
    lo, hi = TAG_RANGE
    tags = np.asarray(tags)
    if tags.size and (tags.min() < lo or tags.max() > hi):
        far = int(tags[np.flatnonzero((tags < lo) | (tags > hi))[0]])
        if far < 0:
            raise ValueError(f"{path}: {what} {far} is negative, which Gmsh reads as {-far} "
                             "(text MSH 2.2 loses the element); shift the tags, or write "
                             ".vtu or .xdmf")
        raise ValueError(f"{path}: {what} {far} does not fit the 32-bit tags of Gmsh files "
                         f"({lo} to {hi})")


def _check_tags_and_names(path: Path, mesh) -> None:
    """Refuse what an MSH file cannot hold: tags beyond 32-bit integers (binary 2.2 files
    would wrap them, text files would not read back), physical names with a line break
    (``$PhysicalNames`` is one name per line)."""
    for what, tags in (("cell tag", mesh.cell_tags), ("edge tag", mesh.edge_tags)):
        if tags is not None:
            check_tag_range(path, what, tags)
    for (dim, tag), name in (mesh.physical_names or {}).items():
        if "\n" in name or "\r" in name:
            raise ValueError(f"{path}: physical name {name!r} ({dim}, {tag}) contains a line "
                             "break, which MSH files cannot hold")
        if "$End" in name:  # readers find a section's end by its marker, quoted or not
            raise ValueError(f"{path}: physical name {name!r} ({dim}, {tag}) contains "
                             "'$End', which ends an MSH section where it stands")


def _check_version(path: Path, version: str) -> None:
    if version not in VERSIONS:
        raise ValueError(f"{path}: Gmsh MSH version must be one of {', '.join(VERSIONS)}, got "
                         f"{version!r}")


def _write(path: Path, source: Chunks, binary: bool, version: str, physical_names: dict,
           sections: list[bytes]) -> None:
    with atomic_path(path) as tmp, open(tmp, "wb") as out:
        out.write(f"$MeshFormat\n{version} {int(binary)} 8\n".encode())
        if binary:
            out.write(np.array([1], np.int32).tobytes() + b"\n")
        out.write(b"$EndMeshFormat\n")
        if physical_names:
            names = sorted(physical_names.items())
            out.write(f"$PhysicalNames\n{len(names)}\n".encode())
            for (dim, tag), name in names:
                out.write(f'{dim} {tag} "{name}"\n'.encode())
            out.write(b"$EndPhysicalNames\n")
        first = int(bool(sections) and sections[0].startswith(b"$QdrefineData"))
        out.write(b"".join(sections[:first]))  # the record before the mesh: a cut file says so
        if version == "4.1":
            _write41(out, source, binary)
        else:
            _write22(out, source, binary)
        out.write(b"".join(sections[first:]))


def _bounding_box(source: Chunks) -> list[float]:
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for _, p in source.points():
        if len(p):  # per column: numpy's axis-0 reduction of (n, 2) is ~15x slower
            lo = np.minimum(lo, [p[:, 0].min(), p[:, 1].min()])
            hi = np.maximum(hi, [p[:, 0].max(), p[:, 1].max()])
    if not source.n_points:
        return [0.0] * 6
    return [float(lo[0]), float(lo[1]), 0.0, float(hi[0]), float(hi[1]), 0.0]


def _write41(out, source: Chunks, binary: bool) -> None:
    n, m, k = source.n_points, source.n_triangles, source.n_edges
    surface_tags, n_surface_blocks, surface_blocks = source.groups("triangles")
    curve_tags, n_curve_blocks, curve_blocks = source.groups("edges")
    box = _bounding_box(source)
    # entities: one curve per edge tag, one surface per cell tag (physical tag = the tag)
    out.write(b"$Entities\n")
    if binary:
        out.write(np.array([0, len(curve_tags), len(surface_tags), 0], np.uint64).tobytes())
        for tags in (curve_tags, surface_tags):
            for i, tag in enumerate(tags):
                phys = [tag]
                out.write(np.array([i + 1], np.int32).tobytes() + np.array(box).tobytes()
                          + np.array([len(phys)], np.uint64).tobytes()
                          + np.array(phys, np.int32).tobytes()
                          + np.array([0], np.uint64).tobytes())
        out.write(b"\n")
    else:
        out.write(f"0 {len(curve_tags)} {len(surface_tags)} 0\n".encode())
        bbox = " ".join(repr(float(x)) for x in box)
        for tags in (curve_tags, surface_tags):
            for i, tag in enumerate(tags):
                out.write(f"{i + 1} {bbox} 1 {tag} 0\n".encode())
    out.write(b"$EndEntities\n$Nodes\n")
    if binary:
        out.write(np.array([1, n, 1, n], np.uint64).tobytes())
        out.write(np.array([2, 1, 0], np.int32).tobytes() + np.array([n], np.uint64).tobytes())
        tags = np.empty(min(n, BINARY_ROWS), np.uint64)
        for start, p in source.points():
            for a in range(0, len(p), BINARY_ROWS):
                b = min(a + BINARY_ROWS, len(p))
                np.add(np.arange(b - a, dtype=np.uint64), start + a + 1, out=tags[:b - a])
                out.write(memoryview(tags[:b - a]))
        xyz = np.zeros((min(n, BINARY_ROWS), 3))
        for _, p in source.points():
            for a in range(0, len(p), BINARY_ROWS):
                b = min(a + BINARY_ROWS, len(p))
                xyz[:b - a, :2] = p[a:b]
                out.write(memoryview(xyz[:b - a]).cast("B"))
        out.write(b"\n")
    else:
        out.write(f"1 {n} 1 {n}\n2 1 0 {n}\n".encode())
        for start, p in source.points():
            for piece in int_lines(np.arange(start + 1, start + len(p) + 1)):
                out.write(piece)
        for _, p in source.points():
            for piece in format_floats(p, " 0"):
                out.write(piece)
    out.write(b"$EndNodes\n$Elements\n")
    total = m + k
    n_blocks = n_surface_blocks + n_curve_blocks
    if binary:
        out.write(np.array([n_blocks, total, 1, total], np.uint64).tobytes())
    else:
        out.write(f"{n_blocks} {total} 1 {total}\n".encode())
    buffer = np.empty((min(max(m, k), BINARY_ROWS), 4), np.int64) if binary else None
    for dim, typ, first, blocks in ((2, 2, 0, surface_blocks), (1, 1, m, curve_blocks)):
        for ent, count, pieces in blocks():
            if binary:
                out.write(np.array([dim, ent, typ], np.int32).tobytes()
                          + np.array([count], np.uint64).tobytes())
            else:
                out.write(f"{dim} {ent} {typ} {count}\n".encode())
            for rows, cells in pieces:
                if binary:  # through one reused buffer: no array of the whole block
                    for a in range(0, len(rows), BINARY_ROWS):
                        b = min(a + BINARY_ROWS, len(rows))
                        block = _element_rows(rows[a:b], first, cells[a:b], buffer)
                        out.write(memoryview(block.view(np.uint64).reshape(-1)))
                else:
                    for piece in int_lines(_element_rows(rows, first, cells)):
                        out.write(piece)
    out.write(b"\n$EndElements\n" if binary else b"$EndElements\n")


def _element_rows(rows: NDArray[np.int64], first: int, cells: NDArray,
                  buffer: NDArray[np.int64] | None = None) -> NDArray[np.int64]:
    """``(k, 1 + nodes) int64``: element tag ``first + row + 1`` and the 1-based nodes (a
    contiguous view of the front of ``buffer`` when given)."""
    width = 1 + cells.shape[1]
    if buffer is None:
        block = np.empty((len(rows), width), np.int64)
    else:
        block = buffer.reshape(-1)[:len(rows) * width].reshape(len(rows), width)
    block[:, 0] = rows
    block[:, 0] += first + 1
    block[:, 1:] = cells
    block[:, 1:] += 1
    return block


def _write22(out, source: Chunks, binary: bool) -> None:
    n, m, k = source.n_points, source.n_triangles, source.n_edges
    out.write(f"$Nodes\n{n}\n".encode())
    for start, p in source.points():
        ids = np.arange(start + 1, start + len(p) + 1)
        if binary:
            rec = np.empty(len(p), dtype=[("tag", np.int32), ("xyz", np.float64, 3)])
            rec["tag"] = ids
            rec["xyz"][:, :2] = p
            rec["xyz"][:, 2] = 0
            out.write(rec.tobytes())
        else:
            for piece in format_floats(np.column_stack([ids, p]), " 0", "%d"):
                out.write(piece)
    out.write(b"\n$EndNodes\n" if binary else b"$EndNodes\n")
    out.write(f"$Elements\n{m + k}\n".encode())
    for typ, kind, first in ((2, "triangles", 0), (1, "edges", m)):
        if not (m if kind == "triangles" else k):
            continue
        if binary:  # one header for all elements of this type
            out.write(np.array([typ, m if kind == "triangles" else k, 2], np.int32).tobytes())
        for start, nodes, tags in source.cells(kind):
            ids = np.arange(first + start + 1, first + start + len(nodes) + 1)
            geom = np.where(tags == 0, 1, tags)  # 0 is not a valid elementary entity
            if binary:
                rows = np.column_stack([ids, tags, geom, nodes + 1])
                out.write(rows.astype(np.int32).tobytes())
            else:
                rows = np.column_stack([ids, np.full(len(ids), typ), np.full(len(ids), 2),
                                        tags, geom, nodes + 1])
                for piece in int_lines(rows):
                    out.write(piece)
    out.write(b"\n$EndElements\n" if binary else b"$EndElements\n")


def _data_sections(path: Path, mesh, point_data: dict, cell_data: dict, binary: bool
                   ) -> list[bytes]:
    """The ``$QdrefineData`` record (first, where there is one) and the ``$NodeData`` /
    ``$ElementData`` views (checked before the file is opened)."""
    parts, spec = [], {}
    for where, kind, fields, first in (("point", "NodeData", point_data, 1),
                                       ("cell", "ElementData", cell_data, 1)):
        for name, value in fields.items():
            a = np.asarray(value)
            if a.dtype.kind in "iu" and a.size and (a.max() >= EXACT_INT or a.min() <= -EXACT_INT):
                raise ValueError(f"{path}: {where} data {name!r} holds integers of 2**53 or "
                                 "more in magnitude, which Gmsh's double values cannot tell "
                                 "apart (2**53 + 1 is stored as 2**53)")
            if '"' in name or "\n" in name:
                raise ValueError(f"{path}: {where} data name {name!r} contains a quote or a "
                                 "line break, which MSH files cannot hold")
            if "$End" in name:
                raise ValueError(f"{path}: {where} data name {name!r} contains '$End', "
                                 "which ends an MSH section where it stands")
            flat = a.reshape(len(a), -1).astype(np.float64)
            if where == "cell" and mesh.edges is not None and len(mesh.edges):
                # values for the line elements too (0), as meshio expects one per element
                flat = np.concatenate([flat, np.zeros((len(mesh.edges), flat.shape[1]))])
            width = flat.shape[1]
            comps = 1 if width == 1 else (3 if width <= 3 else 9 if width <= 9 else width)
            if comps != width:
                flat = np.column_stack([flat, np.zeros((len(flat), comps - width))])
            spec.setdefault(where, {})[name] = record(a)
            head = f'${kind}\n1\n"{name}"\n1\n0\n3\n0\n{comps}\n{len(flat)}\n'.encode()
            ids = np.arange(first, first + len(flat))
            if binary:
                rec = np.empty(len(flat), dtype=[("tag", np.int32), ("v", np.float64, (comps,))])
                rec["tag"], rec["v"] = ids, flat
                body = rec.tobytes() + b"\n"
            else:
                body = b"".join(format_floats(np.column_stack([ids, flat]), first="%d"))
            parts.append(head + body + f"$End{kind}\n".encode())
    if spec:  # first: a file cut after it is missing views it records (the reader says so)
        parts.insert(0, b"$QdrefineData\n" + json.dumps(spec).encode() + b"\n$EndQdrefineData\n")
    return parts
