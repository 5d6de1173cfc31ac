"""Writing Gmsh MSH 4.1 (the default) and 2.2, text or binary, with physical names and
point and cell data as ``$NodeData``/``$ElementData`` views."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._core import atomic_path, mesh_data
from .._text import format_floats, int_lines
from .common import EXACT_INT, VERSIONS

__all__ = ["write"]


def write(path: Path, mesh, *, binary: bool = False, version: str = "4.1") -> None:
    """Write ``mesh`` as Gmsh MSH ``version`` (``"4.1"`` or ``"2.2"``), text or binary."""
    if version not in VERSIONS:
        raise ValueError(f"{path}: Gmsh MSH version must be one of {', '.join(VERSIONS)}, got "
                         f"{version!r}")
    point_data, cell_data = mesh_data(mesh)
    sections = _data_sections(path, mesh, point_data, cell_data, binary)
    with atomic_path(path) as tmp, open(tmp, "wb") as out:
        out.write(f"$MeshFormat\n{version} {int(binary)} 8\n".encode())
        if binary:
            out.write(np.array([1], np.int32).tobytes() + b"\n")
        out.write(b"$EndMeshFormat\n")
        if mesh.physical_names:
            names = sorted(mesh.physical_names.items())
            out.write(f"$PhysicalNames\n{len(names)}\n".encode())
            for (dim, tag), name in names:
                out.write(f'{dim} {tag} "{name}"\n'.encode())
            out.write(b"$EndPhysicalNames\n")
        if version == "4.1":
            _write41(out, mesh, binary)
        else:
            _write22(out, mesh, binary)
        for part in sections:
            out.write(part)


def _groups(tags: NDArray | None, n: int) -> list[tuple[int, NDArray[np.int64]]]:
    """``(tag value, rows)`` for each distinct tag, in increasing tag order (rows in order)."""
    if tags is None:
        return [(0, np.arange(n, dtype=np.int64))] if n else []
    order = np.argsort(tags, kind="stable")
    values, starts = np.unique(tags[order], return_index=True)
    ends = np.append(starts[1:], n)
    return [(int(v), order[s:e]) for v, s, e in zip(values, starts, ends, strict=True)]


def _write41(out, mesh, binary: bool) -> None:
    n, m = mesh.n_points, mesh.n_triangles
    k = 0 if mesh.edges is None else len(mesh.edges)
    surfaces = _groups(mesh.cell_tags, m)
    curves = _groups(mesh.edge_tags, k) if k else []
    p = np.asarray(mesh.points)
    box = [p[:, 0].min(), p[:, 1].min(), 0.0, p[:, 0].max(), p[:, 1].max(), 0.0] if n \
        else [0.0] * 6
    # entities: one curve per edge tag, one surface per cell tag (physical tag = the tag)
    out.write(b"$Entities\n")
    if binary:
        out.write(np.array([0, len(curves), len(surfaces), 0], np.uint64).tobytes())
        for groups in (curves, surfaces):
            for i, (tag, _) in enumerate(groups):
                phys = [tag]
                out.write(np.array([i + 1], np.int32).tobytes() + np.array(box).tobytes()
                          + np.array([len(phys)], np.uint64).tobytes()
                          + np.array(phys, np.int32).tobytes()
                          + np.array([0], np.uint64).tobytes())
        out.write(b"\n")
    else:
        out.write(f"0 {len(curves)} {len(surfaces)} 0\n".encode())
        bbox = " ".join(repr(float(x)) for x in box)
        for groups in (curves, surfaces):
            for i, (tag, _) in enumerate(groups):
                phys = f"1 {tag}"
                out.write(f"{i + 1} {bbox} {phys} 0\n".encode())
    out.write(b"$EndEntities\n$Nodes\n")
    xyz = np.zeros((n, 3))
    xyz[:, :2] = p
    if binary:
        out.write(np.array([1, n, 1, n], np.uint64).tobytes())
        out.write(np.array([2, 1, 0], np.int32).tobytes() + np.array([n], np.uint64).tobytes())
        out.write(np.arange(1, n + 1, dtype=np.uint64).tobytes())
        out.write(xyz.tobytes())
        out.write(b"\n")
    else:
        out.write(f"1 {n} 1 {n}\n2 1 0 {n}\n".encode())
        for piece in int_lines(np.arange(1, n + 1)):
            out.write(piece)
        for piece in format_floats(p, " 0"):
            out.write(piece)
    out.write(b"$EndNodes\n$Elements\n")
    blocks = [(2, i + 1, 2, rows, 0, np.asarray(mesh.triangles), len(surfaces) == 1)
              for i, (_, rows) in enumerate(surfaces)]
    blocks += [(1, i + 1, 1, rows, m, np.asarray(mesh.edges), len(curves) == 1)
               for i, (_, rows) in enumerate(curves)]
    total = m + k
    if binary:
        out.write(np.array([len(blocks), total, 1, total], np.uint64).tobytes())
    else:
        out.write(f"{len(blocks)} {total} 1 {total}\n".encode())
    for dim, ent, typ, rows, first, cells, everything in blocks:
        block = _element_rows(rows, first, cells, everything)
        if binary:
            out.write(np.array([dim, ent, typ], np.int32).tobytes()
                      + np.array([len(block)], np.uint64).tobytes())
            out.write(memoryview(block.view(np.uint64).reshape(-1)))
        else:
            out.write(f"{dim} {ent} {typ} {len(block)}\n".encode())
            for piece in int_lines(block):
                out.write(piece)
    out.write(b"\n$EndElements\n" if binary else b"$EndElements\n")


def _element_rows(rows: NDArray[np.int64], first: int, cells: NDArray, everything: bool
                  ) -> NDArray[np.int64]:
    """``(k, 1 + nodes) int64``: element tag ``first + row + 1`` and 1-based nodes of the
    ``cells`` at ``rows`` (all of them, without a gather, when ``everything``)."""
    block = np.empty((len(rows), 1 + cells.shape[1]), np.int64)
    block[:, 0] = rows
    block[:, 0] += first + 1
    block[:, 1:] = cells if everything else cells[rows]
    block[:, 1:] += 1
    return block


def _write22(out, mesh, binary: bool) -> None:
    n, m = mesh.n_points, mesh.n_triangles
    k = 0 if mesh.edges is None else len(mesh.edges)
    p = np.asarray(mesh.points)
    out.write(f"$Nodes\n{n}\n".encode())
    if binary:
        rec = np.empty(n, dtype=[("tag", np.int32), ("xyz", np.float64, 3)])
        rec["tag"] = np.arange(1, n + 1)
        rec["xyz"][:, :2] = p
        rec["xyz"][:, 2] = 0
        out.write(rec.tobytes() + b"\n")
    else:
        for piece in format_floats(np.column_stack([np.arange(1, n + 1), p]), " 0", "%d"):
            out.write(piece)
    out.write(b"$EndNodes\n")
    tri_tags = mesh.cell_tags if mesh.cell_tags is not None else np.zeros(m, np.int64)
    parts = [(2, np.arange(1, m + 1), tri_tags, np.asarray(mesh.triangles))]
    if k:
        parts.append((1, np.arange(m + 1, m + k + 1), mesh.edge_tags, np.asarray(mesh.edges)))
    out.write(f"$Elements\n{m + k}\n".encode())
    for typ, ids, tags, nodes in parts:
        tags = np.asarray(tags, np.int64)
        geom = np.where(tags == 0, 1, tags)  # 0 is not a valid elementary entity
        if binary:
            out.write(np.array([typ, len(ids), 2], np.int32).tobytes())
            rows = np.column_stack([ids, tags, geom, nodes + 1])
            out.write(rows.astype(np.int32).tobytes())
        else:
            rows = np.column_stack([ids, np.full(len(ids), typ), np.full(len(ids), 2), tags,
                                    geom, nodes + 1])
            for piece in int_lines(rows):
                out.write(piece)
    out.write(b"\n$EndElements\n" if binary else b"$EndElements\n")


def _data_sections(path: Path, mesh, point_data: dict, cell_data: dict, binary: bool
                   ) -> list[bytes]:
    """``$NodeData`` / ``$ElementData`` views and the ``$QdrefineData`` record (checked before
    the file is opened)."""
    parts, spec = [], {}
    for where, kind, fields, first in (("point", "NodeData", point_data, 1),
                                       ("cell", "ElementData", cell_data, 1)):
        for name, value in fields.items():
            a = np.asarray(value)
            if a.dtype.kind in "iub" and a.size and np.abs(a.astype(np.int64)).max() >= EXACT_INT:
                raise ValueError(f"{path}: {where} data {name!r} holds integers beyond 2**53, "
                                 "which Gmsh's double values cannot hold exactly")
            if '"' in name or "\n" in name:
                raise ValueError(f"{path}: {where} data name {name!r} contains a quote or a "
                                 "line break, which MSH files cannot hold")
            flat = a.reshape(len(a), -1).astype(np.float64)
            if where == "cell" and mesh.edges is not None and len(mesh.edges):
                # values for the line elements too (0), as meshio expects one per element
                flat = np.concatenate([flat, np.zeros((len(mesh.edges), flat.shape[1]))])
            width = flat.shape[1]
            comps = 1 if width == 1 else (3 if width <= 3 else 9 if width <= 9 else width)
            if comps != width:
                flat = np.column_stack([flat, np.zeros((len(flat), comps - width))])
            spec.setdefault(where, {})[name] = {"shape": list(a.shape[1:]),
                                                "dtype": a.dtype.str}
            head = f'${kind}\n1\n"{name}"\n1\n0\n3\n0\n{comps}\n{len(flat)}\n'.encode()
            ids = np.arange(first, first + len(flat))
            if binary:
                rec = np.empty(len(flat), dtype=[("tag", np.int32), ("v", np.float64, (comps,))])
                rec["tag"], rec["v"] = ids, flat
                body = rec.tobytes() + b"\n"
            else:
                body = b"".join(format_floats(np.column_stack([ids, flat]), first="%d"))
            parts.append(head + body + f"$End{kind}\n".encode())
    if spec:
        parts.append(b"$QdrefineData\n" + json.dumps(spec).encode() + b"\n$EndQdrefineData\n")
    return parts
