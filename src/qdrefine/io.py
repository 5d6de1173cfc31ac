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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .kernels import number_edges
from .mesh import Mesh, edge_ids
from .predicates import check_coordinates, orient_signs

__all__ = ["read", "write", "FORMATS", "Format", "atomic_path"]

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
    """Silence meshio's Python warnings and turn what it prints on stderr into one
    :class:`UserWarning` naming ``path``."""
    buffer = io_module.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stderr(buffer):
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
        ``(M, 3)``, ``cell_tags (M,)`` and tagged ``edges (K, 2)`` where the file has them.

    Raises
    ------
    OSError
        The file is missing or unreadable.
    ValueError
        Unknown extension, or the content is not a valid flat triangle mesh; the message
        names the file (and the line, for Triangle files).
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
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
        if isinstance(exc, SystemExit) or not detail:
            detail = type(exc).__name__ if not isinstance(exc, SystemExit) else "unreadable"
        raise ValueError(f"{path}: not a readable {fmt.name} file ({detail})") from None
    return _from_meshio(m, path)


def _from_meshio(m, path: Path) -> Mesh:
    points = np.asarray(m.points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] not in (2, 3):
        raise ValueError(f"{path}: points must have 2 or 3 coordinates, got shape "
                         f"{points.shape}")
    key = next((k for k in _TAG_KEYS if k in m.cell_data), None)
    tris, tri_tags, lines, line_tags = [], [], [], []
    others: dict[str, int] = {}
    for i, block in enumerate(m.cells):
        data = np.asarray(block.data)
        tags = None if key is None else np.asarray(m.cell_data[key][i]).reshape(-1)
        if block.type == "triangle":
            tris.append(data)
            tri_tags.append(tags)
        elif block.type == "line":
            if tags is not None:
                lines.append(data)
                line_tags.append(tags)
        elif block.type != "vertex":
            others[block.type] = others.get(block.type, 0) + len(data)
    if others:
        what = ", ".join(f"{n} {t}" for t, n in others.items())
        raise ValueError(f"{path}: holds {what} cells; qdrefine reads linear triangles "
                         "(with line and vertex cells) only")
    if not tris or sum(len(t) for t in tris) == 0:
        raise ValueError(f"{path}: holds no triangles")
    triangles = np.concatenate(tris)
    cell_tags = None
    if all(t is not None for t in tri_tags):
        cell_tags = _integer_tags(np.concatenate(tri_tags), path)
        if not cell_tags.any():
            cell_tags = None
    edges = edge_tags = None
    if lines:
        edges = np.concatenate(lines)
        edge_tags = _integer_tags(np.concatenate(line_tags), path)
        keep = edge_tags != 0
        edges, edge_tags = edges[keep], edge_tags[keep]
        if len(edges) == 0:
            edges = edge_tags = None
    return _build(path, points, triangles, cell_tags, edges, edge_tags)


def _integer_tags(tags: NDArray, path: Path) -> NDArray[np.int64]:
    t = np.asarray(tags)
    if not np.issubdtype(t.dtype, np.integer):
        as_int = np.round(t).astype(np.int64) if np.isfinite(t).all() else None
        if as_int is None or (as_int != t).any():
            raise ValueError(f"{path}: tags must be integers")
        t = as_int
    return t.astype(np.int64)


def _flat_points(path: Path, points: NDArray) -> NDArray:
    if points.shape[1] == 3:
        z = points[:, 2]
        bad = z != 0
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"{path}: the mesh is not flat: {int(bad.sum())} of "
                             f"{len(points)} points have z != 0 (first: point {i}, z = "
                             f"{z[i]!r}); qdrefine reads 2D meshes, or 3D ones with z = 0")
        points = points[:, :2]
    return np.ascontiguousarray(points)


def _build(path: Path, points: NDArray, triangles: NDArray, cell_tags, edges,
           edge_tags) -> Mesh:
    """A validated Mesh; clockwise triangles are flipped with a warning."""
    points = _flat_points(path, points)
    try:
        check_coordinates(points)
        t = np.asarray(triangles)
        if t.size and np.issubdtype(t.dtype, np.integer) and t.ndim == 2 and t.shape[1] == 3:
            n = len(points)
            out = (t < 0) | (t >= n)
            if out.any():
                i = int(np.flatnonzero(out.any(axis=1))[0])
                raise ValueError(f"triangle {i} {tuple(int(v) for v in t[i])} has a vertex "
                                 f"index outside 0..{n - 1}")
            signs = orient_signs(points, np.ascontiguousarray(t, dtype=np.int64))
            cw = signs < 0
            if cw.any():
                t = t.copy()
                t[cw] = t[cw][:, ::-1]
                warnings.warn(f"{path}: {int(cw.sum())} of {len(t)} triangles were clockwise "
                              "and have been flipped", stacklevel=3)
        return Mesh(points, t, cell_tags, edges, edge_tags)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


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
        os.chmod(tmp_path, _file_mode(path))
        yield tmp_path
        os.replace(tmp_path, path)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp_path.unlink()
        raise


def _file_mode(path: Path) -> int:
    """The permission bits of ``path`` if it exists, else those of a new file (umask)."""
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


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
            return [int(w) for w in words]
        except ValueError:
            raise self.error(f"expected integers in {what}, got {' '.join(words)!r}",
                             line) from None

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


def _read_triangle(path: Path) -> Mesh:
    base = _triangle_base(path)
    node_path, ele_path, poly_path = (base.with_suffix(s) for s in (".node", ".ele", ".poly"))
    nodes = _Lines(node_path)
    n, dim, n_attr, n_mark = nodes.header("vertex", 4, (0, 2, 0, 0))
    if dim != 2:
        raise nodes.error(f"dimension must be 2, got {dim}", nodes.rows[0][0])
    points = np.empty((n, 2))
    first = None
    for i in range(n):
        line, words = nodes.next(f"vertex {i + 1} of {n}", 3)
        idx = nodes.ints(line, words[:1], "the vertex number")[0]
        first = nodes.numbering(line, idx, i, first, "vertex")
        points[i] = nodes.floats(line, words[1:3], "the coordinates")
    first = 0 if first is None else first

    eles = _Lines(ele_path)
    m, per, n_tattr = eles.header("triangle", 3, (0, 3, 0))
    if per not in (3, 6):
        raise eles.error(f"nodes per triangle must be 3 or 6, got {per}", eles.rows[0][0])
    triangles = np.empty((m, 3), dtype=np.int64)
    tags = np.empty(m, dtype=np.int64) if n_tattr > 0 else None
    tri_first = None
    for i in range(m):
        line, words = eles.next(f"triangle {i + 1} of {m}", 1 + per + n_tattr)
        idx = eles.ints(line, words[:1], "the triangle number")[0]
        tri_first = eles.numbering(line, idx, i, tri_first, "triangle")
        corners = eles.ints(line, words[1:4], "the triangle's vertices")
        for v in corners:
            if not first <= v < first + n:
                raise eles.error(f"vertex {v} is not in {node_path.name} (vertices "
                                 f"{first}..{first + n - 1})", line)
        triangles[i] = corners
        if tags is not None:
            attr = eles.floats(line, words[1 + per:2 + per], "the regional attribute")[0]
            if not np.isfinite(attr) or attr != int(attr):
                raise eles.error(f"the regional attribute {words[1 + per]} is not an integer "
                                 "tag", line)
            tags[i] = int(attr)
    if m == 0:
        raise eles.error("holds no triangles")
    triangles -= first
    if tags is not None and not tags.any():
        tags = None

    edges = edge_tags = None
    if poly_path.exists():
        edges, edge_tags = _read_poly(poly_path, points, first)
    mesh = _build(ele_path, points, triangles, tags, None, None)
    if edges is None:
        return mesh
    e, _, _ = number_edges(mesh.triangles, mesh.n_points)
    missing = edge_ids(e, edges[:, :2], mesh.n_points) < 0
    if missing.any():
        i = int(np.flatnonzero(missing)[0])
        a, b = (int(v) + first for v in edges[i, :2])
        raise ValueError(f"{poly_path}:{int(edges[i, 2])}: segment ({a}, {b}) is not an edge of "
                         f"any triangle of {ele_path.name}")
    return Mesh(mesh.points, mesh.triangles, mesh.cell_tags, edges[:, :2], edge_tags)


def _read_poly(path: Path, points: NDArray, first: int) -> tuple[NDArray | None, NDArray | None]:
    """Marked segments ``(K, 3)`` (a, b, line number) and their markers, 0-based indices."""
    poly = _Lines(path)
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
        a, b = values[1] - first, values[2] - first
        for v in (a, b):
            if not 0 <= v < len(points):
                raise poly.error(f"vertex {v + first} is not in the .node file", line)
        marker = values[3] if k_mark > 0 else 0
        if marker != 0:
            rows.append((a, b, line, marker))
    if not rows:
        return None, None
    data = np.array(rows, dtype=np.int64)
    return data[:, :3], data[:, 3]


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
