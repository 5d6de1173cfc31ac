"""Reading and writing mesh files.

:func:`read` and :func:`write` choose the format from the file extension (table
:data:`FORMATS`). Triangle's ``.node/.ele/.poly`` files are handled here; every other format
goes through meshio, which this module alone imports (lazily, on first use).

Tags
----
- Gmsh ``.msh``: the physical tag of each triangle becomes ``cell_tags``; line elements with
  a physical tag become tagged ``edges``. Written as **MSH 2.2**, because meshio 5.3
  writes no line tags in MSH 4.1; Gmsh 4 and every meshio version read 2.2. Both 2.2 and 4.1
  are read.
- VTK ``.vtk``, VTU ``.vtu``, XDMF ``.xdmf``: line and triangle cells with the integer cell
  array ``tag``. XDMF is written with its data inline (XML), so it is a single file.
- Medit ``.mesh``: the references of ``Triangles`` and ``Edges``.
- Triangle ``.node/.ele/.poly``: the first regional attribute of ``.ele`` is the cell tag;
  the segments of ``.poly`` with a nonzero boundary marker are the tagged edges.
- OFF, OBJ, STL, PLY hold triangles only: tags are dropped on writing, with a warning.

A tag of 0 means "untagged", as in Gmsh (physical group 0) and Triangle (marker 0): line
cells or segments tagged 0 are not read as tagged edges, and triangles that are all tagged 0
give ``cell_tags = None``.

Checks on reading
-----------------
3D points are accepted when every z is 0; anything else is refused. Only linear triangles are
meshed; vertex and line cells are allowed alongside, any other cell type is refused.
Clockwise triangles are flipped to counter-clockwise with a warning. Every problem raises
``ValueError`` (bad content) or ``OSError`` (missing or unreadable file) whose message starts
with the file name (and, for Triangle files, the line number).

``write(..., binary=True)`` writes the binary variant of ``.msh``, ``.vtk``, ``.vtu``,
``.stl`` and ``.ply`` (much faster for large meshes); by default ``.msh`` and ``.stl`` are
text, the others binary.
Writing is atomic: the data goes to a temporary file in the target directory, which then
replaces the target, so a failure never leaves a partial file.
"""

from __future__ import annotations

import contextlib
import io as io_module
import os
import tempfile
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .check import MIN_ANGLE, Checked, Problem, find
from .mesh import Mesh

__all__ = ["read", "read_raw", "check_file", "write", "FORMATS", "Format", "RawMesh",
           "atomic_path"]

PathLike = str | os.PathLike


@dataclass(frozen=True)
class Format:
    """One file format: its name, meshio's name for it (``None``: our own code), whether
    it holds tags, and whether it is written binary by default (``None``: text only)."""

    name: str
    meshio: str | None
    tags: bool
    binary: bool | None = None


#: Known extensions (lower case) and their formats.
FORMATS: dict[str, Format] = {
    ".msh": Format("Gmsh MSH (read 2.2 and 4.1, write 2.2)", "gmsh", True, False),
    ".vtk": Format("VTK legacy", "vtk", True, True),
    ".vtu": Format("VTK XML unstructured grid", "vtu", True, True),
    ".xdmf": Format("XDMF", "xdmf", True),
    ".xmf": Format("XDMF", "xdmf", True),
    ".mesh": Format("Medit", "medit", True),
    ".off": Format("OFF", "off", False),
    ".obj": Format("Wavefront OBJ", "obj", False),
    ".stl": Format("STL", "stl", False, False),
    ".ply": Format("PLY", "ply", False, True),
    ".node": Format("Triangle .node/.ele/.poly", None, True),
    ".ele": Format("Triangle .node/.ele/.poly", None, True),
    ".poly": Format("Triangle .node/.ele/.poly", None, True),
}

#: Cell-data names read as tags, in order of preference; the first is written by meshio
#: formats without a convention of their own.
_TAG_KEYS = ("gmsh:physical", "medit:ref", "tag", "cell_tags")
_WRITE_KEY = {"gmsh": "gmsh:physical", "medit": "medit:ref"}


def _format_of(path: Path) -> Format:
    ext = path.suffix.lower()
    if ext not in FORMATS:
        known = ", ".join(FORMATS)
        what = f"extension '{path.suffix}'" if path.suffix else "no extension"
        raise ValueError(f"{path}: unknown file format ({what}); known extensions: {known}")
    return FORMATS[ext]


def _check_readable(path: Path) -> None:
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.is_dir():
        raise IsADirectoryError(f"{path}: is a directory, not a mesh file")


@contextlib.contextmanager
def _quiet_meshio(path: Path) -> Iterator[None]:
    """Silence meshio's Python warnings and turn what it prints on stderr or stdout into
    one :class:`UserWarning` naming ``path``."""
    buffer = io_module.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stderr(buffer), \
            contextlib.redirect_stdout(buffer):
        warnings.simplefilter("ignore")
        yield
    text = " ".join(buffer.getvalue().split())  # only reached on success
    if text:
        text = text.removeprefix("Warning:").strip()
        warnings.warn(f"{path}: meshio: {text}", stacklevel=4)


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
        ``edges (K, 2)`` where the file has them.

    Raises
    ------
    OSError
        The file is missing or unreadable.
    ValueError
        Unknown extension, a corrupt file, or content that is not a valid flat triangle
        mesh (any error of :data:`qdrefine.check.KINDS`); the message starts with the file
        name (and the line, for Triangle files) and names the first problem.
    """
    raw = read_raw(path)
    for problem in raw.problems:
        if problem.severity == "error":
            raise ValueError(problem.message)
    found = find(raw.points, raw.triangles, raw.cell_tags, raw.edges, raw.edge_tags,
                 flip_clockwise=True, stop_at_error=True, warnings=False, base=raw.base)
    problems = [raw.locate(p) for p in found.problems]
    for problem in problems:
        if problem.severity == "error":
            raise ValueError(problem.message)
        if problem.kind == "clockwise":
            warnings.warn(problem.message, stacklevel=2)
    return Mesh._trusted(found.points, found.triangles, found.cell_tags, found.edges,
                         found.edge_tags)


def check_file(path: PathLike, min_angle: float = MIN_ANGLE) -> tuple[RawMesh, Checked]:
    """Every problem of a mesh file (:func:`qdrefine.check.find` on what the file holds).

    Raises ``OSError`` / ``ValueError`` only when the file cannot be read at all (missing,
    unknown format, corrupt); content problems are returned, each message starting with the
    file name (and line), as :func:`read` would raise them.
    """
    raw = read_raw(path)
    found = find(raw.points, raw.triangles, raw.cell_tags, raw.edges, raw.edge_tags,
                 flip_clockwise=True, min_angle=min_angle, geometry=raw.flat, base=raw.base)
    seen = {p.kind for p in raw.problems}
    found.problems[:] = raw.problems + [raw.locate(p) for p in found.problems
                                        if p.kind not in seen]
    return raw, found


@dataclass
class RawMesh:
    """What a mesh file holds, before any check: ``points (N, 2) float64`` (z dropped),
    ``triangles (M, 3) int64`` (0-based), optional tags; the problems the reader itself
    found (non-flat points, other cell types, bad tags), whether the points are flat, the
    number of the first point and triangle in the file, and for Triangle files the line of
    each point, triangle and tagged edge (``lines[kind] = (file, (K,) line numbers)``)."""

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


def read_raw(path: PathLike) -> RawMesh:
    """The content of a mesh file without checking it as a mesh (see :func:`check_file`).

    Raises ``OSError`` (missing, unreadable) or ``ValueError`` (unknown format, corrupt or
    truncated file) with the file name first.
    """
    path = Path(path)
    fmt = _format_of(path)
    if fmt.meshio is None:
        return _read_triangle(path)
    _check_readable(path)
    import meshio

    try:
        with _quiet_meshio(path):
            m = meshio.read(path, file_format=fmt.meshio)
    except OSError as exc:
        raise OSError(f"{path}: {exc.strerror or exc}") from None
    except (Exception, SystemExit) as exc:  # meshio raises many kinds (even exits)
        raise _unreadable(path, fmt, exc) from None
    try:
        points, blocks, tags = _meshio_arrays(m)
    except (TypeError, ValueError, IndexError, KeyError, AttributeError) as exc:
        raise _unreadable(path, fmt, exc) from None  # meshio returned malformed data
    return _from_meshio(path, points, blocks, tags)


def _unreadable(path: Path, fmt: Format, exc: BaseException) -> ValueError:
    text = str(exc).strip()
    detail = text.splitlines()[0] if text else ""
    if isinstance(exc, SystemExit):
        detail = "unreadable"
    elif not detail:
        detail = type(exc).__name__
    return ValueError(f"{path}: not a readable {fmt.name} file ({detail[:200]})")


def _meshio_arrays(m) -> tuple[NDArray, list[tuple[str, NDArray]], list[NDArray | None]]:
    """Points ``(N, d) float64``, cell blocks ``(type, (k, nodes) int)`` and their tags,
    converted from meshio's objects (malformed data raises here)."""
    points = np.asarray(m.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"points must have 2 or 3 coordinates, got shape {points.shape}")
    key = next((k for k in _TAG_KEYS if k in m.cell_data), None)
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
    return points, blocks, tags


def _from_meshio(path: Path, points: NDArray, blocks: list, tags: list) -> RawMesh:
    tris, tri_tags, lines, line_tags = [], [], [], []
    others: dict[str, int] = {}
    for (kind, data), tag in zip(blocks, tags, strict=True):
        if kind == "triangle":
            tris.append(data)
            tri_tags.append(tag)
        elif kind == "line":
            if tag is not None:
                lines.append(data)
                line_tags.append(tag)
        elif kind != "vertex":
            others[kind] = others.get(kind, 0) + len(data)
    raw = RawMesh(path, np.empty((0, 2)), np.empty((0, 3), dtype=np.int64))
    _flat_points(raw, points)
    if others:
        what = ", ".join(f"{n} {t}" for t, n in others.items())
        raw.problem("cell-types", f"holds {what} cells; qdrefine reads linear triangles "
                    "(with line and vertex cells) only", sum(others.values()))
    if sum(len(t) for t in tris) == 0:
        raw.problem("no-triangles", "holds no triangles", 0)
        return raw
    raw.triangles = np.concatenate(tris)
    if all(t is not None for t in tri_tags):
        raw.cell_tags = _integer_tags(raw, np.concatenate(tri_tags), "cell")
        if raw.cell_tags is not None and not raw.cell_tags.any():
            raw.cell_tags = None
    if lines:
        edges = np.concatenate(lines)
        edge_tags = _integer_tags(raw, np.concatenate(line_tags), "edge")
        if edge_tags is not None and (edge_tags != 0).any():
            raw.edges, raw.edge_tags = edges[edge_tags != 0], edge_tags[edge_tags != 0]
    return raw


def _integer_tags(raw: RawMesh, tags: NDArray, what: str) -> NDArray[np.int64] | None:
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


def _flat_points(raw: RawMesh, points: NDArray) -> None:
    """Store ``points`` as 2D; a problem (and no geometric checks) unless every z is 0."""
    if points.shape[1] == 3:
        z = points[:, 2]
        bad = z != 0
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raw.flat = False
            raw.problem("not-flat", f"the mesh is not flat: {int(bad.sum())} of {len(points)} "
                        f"points have z != 0 (first: point {i}, z = {float(z[i])}); qdrefine reads "
                        "2D meshes, or 3D ones with z = 0", int(bad.sum()), point=i)
        points = points[:, :2]
    raw.points = np.ascontiguousarray(points, dtype=np.float64)


# --------------------------------------------------------------------------------------------
# writing


@contextlib.contextmanager
def atomic_path(path: PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success it replaces ``path``.

    On any exception the temporary file is removed and ``path`` is left as it was. The
    temporary name keeps the extension, so tools that look at it still work.
    """
    path = Path(path)
    parent = path.parent
    if not parent.is_dir():
        raise FileNotFoundError(f"{path}: directory {parent} does not exist")
    if path.is_dir():
        raise IsADirectoryError(f"{path}: is a directory")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}",
                                   dir=parent)
    except OSError as exc:
        raise OSError(f"{path}: cannot write: {exc.strerror or exc}") from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        os.chmod(tmp_path, permission_bits(path))
        yield tmp_path
        os.replace(tmp_path, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        raise


def permission_bits(path: Path, new: int = 0o666) -> int:
    """The permission bits of ``path`` if it exists, else ``new`` less the umask (``0o666``
    for a new file, ``0o777`` for a new directory)."""
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return new & ~umask


def write(path: PathLike, mesh: Mesh, *, binary: bool | None = None) -> None:
    """Write ``mesh`` to ``path``; the format follows the extension (see :data:`FORMATS`).

    ``.msh`` files are Gmsh MSH 2.2 (the version that keeps line tags with meshio).
    ``binary`` chooses the variant of ``.msh``, ``.vtk``, ``.vtu``, ``.stl`` and ``.ply``
    (other formats refuse ``binary=True``). By default ``.msh`` and ``.stl`` are text and
    ``.vtk``, ``.vtu``, ``.ply`` binary (meshio's text VTK is for debugging and VTU text
    loses digits). Binary is much faster for large meshes: a million triangles take about
    0.1 s instead of 10 s as ``.msh``.
    XDMF is written with its data inline (XML), so it is a single file.
    For Triangle files (``name.node``, ``name.ele`` or ``name.poly``) all three are written:
    ``.node`` (points), ``.ele`` (triangles, with the cell tag as regional attribute) and
    ``.poly`` (no points of its own; the tagged edges as marked segments).

    Each file is written atomically. Formats without tags (OFF, OBJ, STL, PLY) drop them
    with a warning, as does any format for edge tags equal to 0 (0 reads as untagged).
    """
    if not isinstance(mesh, Mesh):
        raise TypeError(f"write() needs a Mesh, got {type(mesh).__name__}")
    path = Path(path)
    fmt = _format_of(path)
    if binary and fmt.binary is None:
        raise ValueError(f"{path}: {fmt.name} files have no binary variant")
    tagged = mesh.cell_tags is not None or mesh.edges is not None
    if tagged and not fmt.tags:
        warnings.warn(f"{path}: {fmt.name} files hold no tags; cell and edge tags are dropped",
                      stacklevel=2)
    elif mesh.edge_tags is not None and (mesh.edge_tags == 0).any():
        warnings.warn(f"{path}: {int((mesh.edge_tags == 0).sum())} edges have tag 0, which "
                      "reads back as untagged", stacklevel=2)
    if fmt.meshio is None:
        _write_triangle(path, mesh)
        return
    import meshio

    m = _to_meshio(mesh, fmt)
    with atomic_path(path) as tmp, _quiet_meshio(path):
        meshio.write(tmp, m, file_format=_MESHIO_WRITE.get(fmt.meshio, fmt.meshio),
                     **_write_options(fmt, binary))


_MESHIO_WRITE = {"gmsh": "gmsh22"}


def _write_options(fmt: Format, binary: bool | None) -> dict[str, object]:
    if fmt.meshio == "xdmf":
        return {"data_format": "XML"}
    if fmt.binary is None:
        return {}
    return {"binary": fmt.binary if binary is None else bool(binary)}


def _to_meshio(mesh: Mesh, fmt: Format):
    import meshio

    n = mesh.n_points
    if fmt.meshio == "medit":
        points = np.asarray(mesh.points)
    else:
        points = np.column_stack([mesh.points, np.zeros(n)])
    tris = np.asarray(mesh.triangles)
    if not fmt.tags:
        return meshio.Mesh(points, [("triangle", tris)])
    cells, tags = [], []
    if mesh.edges is not None and len(mesh.edges):
        cells.append(("line", np.asarray(mesh.edges, dtype=np.int64)))
        tags.append(np.asarray(mesh.edge_tags, dtype=np.int64))
    cells.append(("triangle", tris))
    cell_tags = mesh.cell_tags if mesh.cell_tags is not None else np.zeros(len(tris), np.int64)
    tags.append(np.asarray(cell_tags, dtype=np.int64))
    key = _WRITE_KEY.get(fmt.meshio, "tag")
    cell_data = {key: tags}
    if fmt.meshio == "gmsh":
        cell_data["gmsh:geometrical"] = [np.where(t == 0, 1, t) for t in tags]  # 0: invalid
    return meshio.Mesh(points, cells, cell_data=cell_data)


# --------------------------------------------------------------------------------------------
# Triangle's .node / .ele / .poly


class _Lines:
    """The non-empty lines of a Triangle file, comments (``#``) removed, as numbers."""

    def __init__(self, path: Path) -> None:
        self.path = path
        _check_readable(path)
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"{path}: not a text file") from None
        except OSError as exc:
            raise OSError(f"{path}: {exc.strerror or exc}") from None
        self.rows: list[tuple[int, list[str]]] = []
        for number, line in enumerate(text.splitlines(), start=1):
            words = line.split("#", 1)[0].split()
            if words:
                self.rows.append((number, words))
        self.pos = 0

    def error(self, message: str, line: int | None = None) -> ValueError:
        where = f"{self.path}:{line}" if line is not None else f"{self.path}"
        return ValueError(f"{where}: {message}")

    def next(self, what: str, min_count: int) -> tuple[int, list[str]]:
        if self.pos >= len(self.rows):
            last = self.rows[-1][0] if self.rows else 0
            raise self.error(f"file ends early: expected {what}", last if last else None)
        line, words = self.rows[self.pos]
        self.pos += 1
        if len(words) < min_count:
            raise self.error(f"expected {what} ({min_count} numbers), got {len(words)}", line)
        return line, words

    def ints(self, line: int, words: list[str], what: str) -> list[int]:
        try:
            values = [int(w) for w in words]
        except ValueError:
            raise self.error(f"expected integers in {what}, got {' '.join(words)!r}",
                             line) from None
        if any(abs(v) >= 2**62 for v in values):
            raise self.error(f"integer too large in {what}: {' '.join(words)!r}", line)
        return values

    def floats(self, line: int, words: list[str], what: str) -> list[float]:
        try:
            return [float(w) for w in words]
        except ValueError:
            raise self.error(f"expected numbers in {what}, got {' '.join(words)!r}",
                             line) from None

    def header(self, what: str, count: int, defaults: tuple[int, ...]) -> list[int]:
        line, words = self.next(f"the {what} header", 1)
        values = self.ints(line, words[:count], f"the {what} header")
        values += list(defaults[len(values):])
        if values[0] < 0:
            raise self.error(f"negative count {values[0]} in the {what} header", line)
        if values[0] > len(self.rows) - self.pos:
            raise self.error(f"file ends early: the header announces {values[0]} {what} "
                             f"lines, {len(self.rows) - self.pos} follow", line)
        return values

    def numbering(self, line: int, index: int, row: int, base: int | None, what: str) -> int:
        if base is None:
            if index not in (0, 1):
                raise self.error(f"{what} numbers must start at 0 or 1, got {index}", line)
            return index
        if index != base + row:
            raise self.error(f"expected {what} {base + row}, got {index}", line)
        return base


def _triangle_base(path: Path) -> Path:
    return path.with_suffix("")


def _read_triangle(path: Path) -> RawMesh:
    base = _triangle_base(path)
    node_path, ele_path, poly_path = (base.with_suffix(s) for s in (".node", ".ele", ".poly"))
    points, first, node_lines = _read_node(_Lines(node_path))
    raw = RawMesh(ele_path, points, np.empty((0, 3), dtype=np.int64), base=first)
    raw.lines["point"] = (node_path, node_lines)
    _read_ele(_Lines(ele_path), raw, node_path)
    if poly_path.exists() and not any(p.kind == "no-triangles" for p in raw.problems):
        _read_poly(_Lines(poly_path), raw)
    return raw


def _read_node(nodes: _Lines) -> tuple[NDArray, int, NDArray]:
    n, dim, n_attr, n_mark = nodes.header("vertex", 4, (0, 2, 0, 0))
    if dim != 2:
        raise nodes.error(f"dimension must be 2, got {dim}", nodes.rows[0][0])
    points = np.empty((n, 2))
    lines = np.empty(n, dtype=np.int64)
    first = None
    for i in range(n):
        line, words = nodes.next(f"vertex {i + 1} of {n}", 3)
        idx = nodes.ints(line, words[:1], "the vertex number")[0]
        first = nodes.numbering(line, idx, i, first, "vertex")
        points[i] = nodes.floats(line, words[1:3], "the coordinates")
        lines[i] = line
    return points, 0 if first is None else first, lines


def _read_ele(eles: _Lines, raw: RawMesh, node_path: Path) -> None:
    m, per, n_tattr = eles.header("triangle", 3, (0, 3, 0))
    if per not in (3, 6):
        raise eles.error(f"nodes per triangle must be 3 or 6, got {per}", eles.rows[0][0])
    triangles = np.empty((m, 3), dtype=np.int64)
    tags = np.empty(m, dtype=np.int64) if n_tattr > 0 else None
    lines = np.empty(m, dtype=np.int64)
    tri_first = None
    for i in range(m):
        line, words = eles.next(f"triangle {i + 1} of {m}", 1 + per + n_tattr)
        idx = eles.ints(line, words[:1], "the triangle number")[0]
        tri_first = eles.numbering(line, idx, i, tri_first, "triangle")
        triangles[i] = eles.ints(line, words[1:4], "the triangle's vertices")
        lines[i] = line
        if tags is not None:
            attr = eles.floats(line, words[1 + per:2 + per], "the regional attribute")[0]
            if not np.isfinite(attr) or attr != int(attr) or abs(attr) >= 2**62:
                raise eles.error(f"the regional attribute {words[1 + per]} is not an integer "
                                 "tag", line)
            tags[i] = int(attr)
    if m == 0:
        raw.problem("no-triangles", "holds no triangles", 0)
        return
    if tri_first is not None and tri_first != raw.base:
        raise eles.error(f"triangles are numbered from {tri_first} but the vertices of "
                         f"{node_path.name} from {raw.base}", eles.rows[1][0])
    raw.lines["triangle"] = (eles.path, lines)
    n, first = len(raw.points), raw.base
    bad = ((triangles < first) | (triangles >= first + n)).any(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        v = next(int(v) for v in triangles[i] if not first <= v < first + n)
        raw.problem("index-range", f"vertex {v} is not in {node_path.name} (vertices "
                    f"{first}..{first + n - 1})", int(bad.sum()), triangle=i + first,
                    vertices=triangles[i].tolist())
    raw.triangles = triangles - first
    raw.cell_tags = tags if tags is not None and tags.any() else None


def _read_poly(poly: _Lines, raw: RawMesh) -> None:
    """Marked segments become the tagged edges of ``raw``; the lines are kept."""
    points, first = raw.points, raw.base
    n_pts, dim, n_attr, n_mark = poly.header("vertex", 4, (0, 2, 0, 0))
    for i in range(n_pts):
        line, words = poly.next(f"vertex {i + 1} of {n_pts}", 3)
        xy = poly.floats(line, words[1:3], "the coordinates")
        if i >= len(points) or tuple(points[i]) != tuple(xy):
            raise poly.error(f"vertex {i + first} differs from the .node file's", line)
    k, k_mark = poly.header("segment", 2, (0, 0))
    rows = []
    for i in range(k):
        line, words = poly.next(f"segment {i + 1} of {k}", 3 + (k_mark > 0))
        values = poly.ints(line, words[:3 + (k_mark > 0)], "the segment")
        marker = values[3] if k_mark > 0 else 0
        if marker != 0:
            rows.append((values[1] - first, values[2] - first, line, marker))
    if not rows:
        return
    data = np.array(rows, dtype=np.int64)
    raw.lines["edge"] = (poly.path, data[:, 2])
    raw.edges, raw.edge_tags = data[:, :2], data[:, 3]


def _write_triangle(path: Path, mesh: Mesh) -> None:
    base = _triangle_base(path)
    n, m = mesh.n_points, mesh.n_triangles
    with atomic_path(base.with_suffix(".node")) as tmp, open(tmp, "w") as f:
        f.write(f"# written by qdrefine\n{n} 2 0 0\n")
        np.savetxt(f, np.column_stack([np.arange(n), mesh.points]), fmt="%d %.17g %.17g")
    with atomic_path(base.with_suffix(".ele")) as tmp, open(tmp, "w") as f:
        t = np.asarray(mesh.triangles, dtype=np.int64)
        if mesh.cell_tags is None:
            f.write(f"{m} 3 0\n")
            np.savetxt(f, np.column_stack([np.arange(m), t]), fmt="%d")
        else:
            f.write(f"{m} 3 1\n")
            np.savetxt(f, np.column_stack([np.arange(m), t, mesh.cell_tags]), fmt="%d")
    with atomic_path(base.with_suffix(".poly")) as tmp, open(tmp, "w") as f:
        f.write("# vertices are in the .node file\n0 2 0 0\n")
        k = 0 if mesh.edges is None else len(mesh.edges)
        f.write(f"{k} 1\n")
        if k:
            np.savetxt(f, np.column_stack([np.arange(k), mesh.edges, mesh.edge_tags]), fmt="%d")
        f.write("0\n")
