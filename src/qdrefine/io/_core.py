"""What every reader and writer shares: the raw content of a file (:class:`RawMesh`), the
conversion of cell blocks to triangles and tags, the chunks that writers stream
(:class:`MeshChunks`) and file checks (atomic writes: :mod:`.atomic`)."""

from __future__ import annotations

import os
import stat
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..check import Problem
from ..mesh import HISTORY_CELL_DATA
from .atomic import PathLike

#: The cell-data names under which :attr:`qdrefine.Mesh.transitions` and
#: :attr:`qdrefine.Mesh.origins` are stored in files (reserved: ``Mesh`` refuses them as
#: cell data of its own).
TRANSITIONS, ORIGINS = HISTORY_CELL_DATA


@dataclass
class RawMesh:
    """What a mesh file holds, before any check: ``points (N, 2) float64`` (z dropped),
    ``triangles (M, 3) int64`` (0-based), optional tags; ``point_data`` / ``cell_data``
    (one row per point / triangle), ``physical_names`` (``(dim, tag) -> name``) and
    ``transitions`` (``(M, 3)`` refinement history); the problems the reader itself found
    (non-flat points, other cell types, bad tags), whether the points are flat, the number
    of the first point and triangle in the file (or the file's own number of each, for
    messages), and for Triangle files the line of each point, triangle and tagged edge
    (``lines[kind] = (file, (K,) line numbers)``)."""

    path: Path
    points: NDArray[np.float64]
    triangles: NDArray[np.int64]
    cell_tags: NDArray | None = None
    edges: NDArray | None = None
    edge_tags: NDArray | None = None
    problems: list[Problem] = field(default_factory=list)
    flat: bool = True
    base: int = 0
    lines: dict[str, tuple[Path, NDArray]] = field(default_factory=dict)
    point_data: dict[str, NDArray] = field(default_factory=dict)
    cell_data: dict[str, NDArray] = field(default_factory=dict)
    physical_names: dict[tuple[int, int], str] = field(default_factory=dict)
    transitions: NDArray | None = None
    origins: NDArray | None = None
    #: The file's own number of every point, triangle and tagged edge (Gmsh node and element
    #: tags), for messages; None: numbered from ``base`` in the order of the file.
    point_numbers: NDArray | None = None
    triangle_numbers: NDArray | None = None
    edge_numbers: NDArray | None = None

    def problem(self, kind: str, message: str, count: int = 1, **where) -> None:
        """Record a problem found while reading (message prefixed with the file name)."""
        self.problems.append(self.locate(Problem(kind, message, count, where)))

    def locate(self, problem: Problem) -> Problem:
        """``problem`` with the file name (and line, for errors in Triangle files) in front
        of its message and in ``where``."""
        file, line = self._line(problem.where) if problem.severity == "error" else (
            self.path, None)
        where = {**problem.where, "file": str(file)} | ({"line": line} if line else {})
        message = problem.message
        if not message.startswith(str(file)):
            message = (f"{file}:{line}: " if line else f"{file}: ") + message
        return Problem(problem.kind, message, problem.count, where, problem.severity)

    def _line(self, where: dict) -> tuple[Path, int | None]:
        """The file and line of the first triangle, tagged edge or point named by ``where``."""
        for key, kind in (("triangle", "triangle"), ("triangles", "triangle"),
                          ("edge_row", "edge"), ("vertex", "point"), ("point", "point"),
                          ("points", "point")):
            if key in where and kind in self.lines:
                ident = where[key][0] if isinstance(where[key], list) else where[key]
                row = ident - (0 if kind == "edge" else self.base)
                file, numbers = self.lines[kind]
                if 0 <= row < len(numbers):
                    return file, int(numbers[row])
        return self.path, None


def check_readable(path: Path) -> None:
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.is_dir():
        raise IsADirectoryError(f"{path}: is a directory, not a mesh file")


def check_regular(path: Path) -> None:
    """:func:`check_readable`, and refuse a FIFO or device (reading one could wait forever)."""
    check_readable(path)
    try:
        mode = os.stat(path).st_mode
    except OSError as exc:
        raise OSError(f"{path}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(mode):
        raise OSError(f"{path}: not a regular file")


def read_bytes(path: Path) -> bytes:
    """The whole content of a regular file (``OSError`` naming ``path`` otherwise; a FIFO or
    device is refused before it is opened, so reading never waits on one)."""
    check_regular(path)
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError as exc:
        if str(exc).startswith(str(path)):
            raise
        raise OSError(f"{path}: {exc.strerror or exc}") from None


def flat_points(raw: RawMesh, points: NDArray) -> None:
    """Store ``points`` as 2D; a problem (and no geometric checks) unless every z is 0."""
    if points.shape[1] == 3:
        z = points[:, 2]
        bad = z != 0
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            number = int(raw.point_numbers[i]) if raw.point_numbers is not None else i + raw.base
            raw.flat = False
            raw.problem("not-flat", f"the mesh is not flat: {int(bad.sum())} of {len(points)} "
                        f"points have z != 0 (first: point {number}, z = {float(z[i])!r}); "
                        "qdrefine reads 2D meshes, or 3D ones with z = 0", int(bad.sum()),
                        point=number)
        points = points[:, :2]
    raw.points = np.ascontiguousarray(points, dtype=np.float64)


def integer_tags(raw: RawMesh, tags: NDArray, what: str) -> NDArray[np.int64] | None:
    t = np.asarray(tags)
    if np.issubdtype(t.dtype, np.integer):
        return t.astype(np.int64)
    try:
        values = t.astype(np.float64)
    except (TypeError, ValueError):
        values = np.array([np.nan])
    ok = np.isfinite(values) & (np.abs(values) < 2.0**62)
    if ok.all() and (np.round(values) == values).all():
        return values.astype(np.int64)
    raw.problem(f"{what}-tags", f"{what} tags must be integers")
    return None


def from_blocks(path: Path, points: NDArray, blocks: list[tuple[str, NDArray]],
                tags: list[NDArray | None], point_numbers: NDArray | None = None) -> RawMesh:
    """A :class:`RawMesh` from points ``(N, 2|3)`` and cell blocks ``(type, (k, nodes))`` with
    their tags (``None``: untagged); triangles keep the order of the blocks.
    ``point_numbers``: the file's own number of every point (for messages)."""
    tris, tri_tags, lines, line_tags = [], [], [], []
    others: dict[str, int] = {}
    tagged_vertices = 0
    for (kind, data), tag in zip(blocks, tags, strict=True):
        if kind == "triangle":
            tris.append(data)
            tri_tags.append(tag)
        elif kind == "line":
            if tag is not None:
                lines.append(data)
                line_tags.append(tag)
        elif kind == "vertex":
            tagged_vertices += 0 if tag is None else int(np.count_nonzero(tag))
        else:
            others[kind] = others.get(kind, 0) + len(data)
    if tagged_vertices:  # the points stay; their tags (a pin, a load point) would go unsaid
        one = tagged_vertices == 1
        warnings.warn(f"{path}: {tagged_vertices} tagged point cell{'' if one else 's'} (such "
                      f"as Gmsh's physical points) {'is' if one else 'are'} dropped: a Mesh "
                      "holds cell tags and tagged edges only", stacklevel=3)
    raw = RawMesh(path, np.empty((0, 2)), np.empty((0, 3), dtype=np.int64),
                  point_numbers=point_numbers)
    flat_points(raw, points)
    if others:
        what = ", ".join(f"{n} {t}" for t, n in others.items())
        raw.problem("cell-types", f"holds {what} cells; qdrefine reads linear triangles "
                    "(with line and vertex cells) only", sum(others.values()))
    if sum(len(t) for t in tris) == 0:
        raw.problem("no-triangles", "holds no triangles", 1)
        return raw
    raw.triangles = (tris[0] if len(tris) == 1 else np.concatenate(tris)).astype(
        np.int64, copy=False)
    if all(t is not None for t in tri_tags):
        raw.cell_tags = integer_tags(raw, np.concatenate(tri_tags), "cell")
        if raw.cell_tags is not None and not raw.cell_tags.any():
            raw.cell_tags = None
    if lines:
        edges = np.concatenate(lines)
        edge_tags = integer_tags(raw, np.concatenate(line_tags), "edge")
        if edge_tags is not None and (edge_tags != 0).any():
            keep = edge_tags != 0
            raw.edges, raw.edge_tags = edges[keep].astype(np.int64, copy=False), edge_tags[keep]
    return raw


def split_data(raw: RawMesh, point_data: Mapping[str, NDArray],
               cell_data: Mapping[str, NDArray]) -> None:
    """Store point and cell data on ``raw``; the cell data named :data:`TRANSITIONS` and
    :data:`ORIGINS` become ``raw.transitions`` and ``raw.origins`` (``(M, 3) int64``)."""
    raw.point_data.update(point_data)
    for name, value in cell_data.items():
        if name in (TRANSITIONS, ORIGINS):
            t = np.asarray(value)
            # integral and within int64's range (a cast of 1e300 said "invalid value
            # encountered in cast" beside the refusal; review)
            if t.ndim != 2 or t.shape[1] != 3 or (t.dtype.kind == "f" and not (
                    (np.round(t) == t) & (np.abs(t) < 2.0**63)).all()) or (
                    t.dtype.kind == "u" and t.size and t.max() > np.iinfo(np.int64).max):
                raise ValueError(f"{raw.path}: cell data {name!r} must be 3 integers per "
                                 "triangle")
            setattr(raw, "transitions" if name == TRANSITIONS else "origins",
                    t.astype(np.int64))
        else:
            raw.cell_data[name] = value


def writable_data(value) -> NDArray:
    """Data as the binary writers take it: booleans as ``uint8``, 16-bit floats as
    ``float32`` (which holds each of their values exactly; VTK has no 16-bit floats)."""
    a = np.asarray(value)
    if a.dtype == bool:
        return a.astype(np.uint8)
    return a.astype(np.float32) if a.dtype.kind == "f" and a.dtype.itemsize == 2 else a


#: Cell-data names that the VTU and meshio readers take as the cell tags (the first present,
#: in this order: a file meshio wrote from a Gmsh mesh may hold several), and those meshio's
#: readers skip (Gmsh's entity tags). A mesh's
#: own cell data under one of them would come back as its tags (its tagged edges lost) or
#: not at all, so the writers refuse it (``mesh_data``'s ``reserved``).
TAG_NAMES = ("gmsh:physical", "medit:ref", "tag", "cell_tags")
SKIPPED_NAMES = ("gmsh:geometrical", "gmsh:dim_tags")


def mesh_data(mesh, path: PathLike | None = None, reserved: tuple[str, ...] = ()
              ) -> tuple[dict[str, NDArray], dict[str, NDArray]]:
    """Point data and cell data of ``mesh`` to write, the history (transitions, origins)
    as cell data; ``ValueError`` naming ``path`` for cell data under a ``reserved`` name
    (the format's names of the tags, :data:`TAG_NAMES`)."""
    where = f"{path}: " if path is not None else ""
    clash = next((name for name in mesh.cell_data or {} if name in reserved), None)
    if clash is not None:
        raise ValueError(f"{where}cell data {clash!r} has a name that readers of this format "
                         "take as the cell tags (it would come back as the tags, or not at "
                         "all); rename it" + (", or write .msh" if path is not None else ""))
    for data in (mesh.point_data or {}, mesh.cell_data or {}):
        for name, value in data.items():
            kind, size = value.dtype.kind, value.dtype.itemsize
            if kind not in "biuf" or (kind == "f" and size > 8):
                raise ValueError(f"{where}data {name!r} of dtype {value.dtype} cannot be "
                                 "written: files hold integers and floats of up to 64 bits")
    cell_data = dict(mesh.cell_data or {})
    if mesh.transitions is not None:
        cell_data[TRANSITIONS] = np.asarray(mesh.transitions, dtype=np.int64)
    if getattr(mesh, "origins", None) is not None:
        cell_data[ORIGINS] = np.asarray(mesh.origins, dtype=np.int64)
    return dict(mesh.point_data or {}), cell_data


# --------------------------------------------------------------------------------------------
# writing


class MeshChunks:
    """A mesh given chunk by chunk (e.g. a Zarr store), for the writers that stream it
    (:func:`qdrefine.io.gmsh.writing.write_chunks`, :func:`qdrefine.io.triangle.write_chunks`);
    :meth:`of_mesh` makes a whole mesh one chunk.

    ``points()``, ``triangles()`` and ``edges()`` each return a new iterator of
    ``(first row, rows)`` (``(k, 2)`` float64 points; ``(k, 3)`` / ``(k, 2)`` 0-based
    cells); every iterator may be asked for again (MSH 4.1 groups elements by tag).
    ``cell_tags(start, stop)`` and ``edge_tags(start, stop)`` return the tags of those rows
    (``None``: no tags), whatever the chunks of the tags.
    """

    def __init__(self, n_points: int, n_triangles: int, n_edges: int, points, triangles,
                 cell_tags=None, edges=None, edge_tags=None) -> None:
        self.n_points, self.n_triangles, self.n_edges = n_points, n_triangles, n_edges
        self.points, self.triangles, self.edges = points, triangles, edges
        self.cell_tags, self.edge_tags = cell_tags, edge_tags

    @classmethod
    def of_mesh(cls, mesh):
        """``mesh`` as one chunk (``.mesh`` keeps it)."""
        k = 0 if mesh.edges is None else len(mesh.edges)
        out = cls(mesh.n_points, mesh.n_triangles, k,
                  lambda: iter([(0, np.asarray(mesh.points))]),
                  lambda: iter([(0, np.asarray(mesh.triangles))]),
                  None if mesh.cell_tags is None else lambda a, b: mesh.cell_tags[a:b],
                  (lambda: iter([(0, np.asarray(mesh.edges))])) if k else None,
                  (lambda a, b: mesh.edge_tags[a:b]) if k else None)
        out.mesh = mesh
        return out

    def cells(self, kind: str) -> Iterator[tuple[int, NDArray, NDArray]]:
        """``(first row, cells, tags)`` of ``"triangles"`` or ``"edges"`` (tags 0 where
        there are none)."""
        cells = self.triangles() if kind == "triangles" else self.edges()
        tags = self.cell_tags if kind == "triangles" else self.edge_tags
        for start, rows in cells:
            if tags is None:
                yield start, rows, np.zeros(len(rows), np.int64)
            else:
                yield start, rows, np.asarray(tags(start, start + len(rows)), np.int64)
