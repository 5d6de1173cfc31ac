"""Triangle's ``.node`` / ``.ele`` / ``.poly`` files (J. R. Shewchuk's mesh generator).

The first regional attribute of ``.ele`` is the cell tag; the segments of ``.poly`` with a
nonzero boundary marker are the tagged edges; the vertex attributes of ``.node`` are the
point data :data:`ATTRIBUTES` (vertex boundary markers are not read). The three files are
written as one set: each goes to a temporary file, and they replace their targets only once
all three are written.
Each ends with the comment ``# qdrefine set DIGEST``, a hash of the three files' content:
a reader that finds two different stamps in one set refuses it (a mixed set, left by an
interrupted or concurrent write between the three renames), as it refuses a set where one
file has the stamp and another has none (a file cut short loses its last line). Files of
other tools carry no stamp and are read as they are.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ._core import MeshChunks, RawMesh, read_bytes
from .atomic import atomic_paths

__all__ = ["read", "write", "write_chunks", "base_of", "Stamping", "SET_STAMP", "ATTRIBUTES"]

#: The point data that a ``.node`` file's vertex attributes are read as (``(N,)`` for one
#: attribute, ``(N, A)`` for several); Triangle interpolates them linearly at new vertices,
#: as refinement interpolates point data.
ATTRIBUTES = "attributes"

#: The comment that ends every file of a set written by qdrefine (then the digest).
SET_STAMP = "# qdrefine set "


class Stamping:
    """Text files written through :meth:`wrap` feed one hash; :meth:`finish` appends the
    same ``# qdrefine set DIGEST`` line to each of them (the digest of everything written)."""

    def __init__(self) -> None:
        self.hash = hashlib.blake2b(digest_size=8)

    def wrap(self, f):
        return _Hashed(f, self.hash)

    def finish(self, paths: Iterable[Path]) -> None:
        line = f"{SET_STAMP}{self.hash.hexdigest()}\n"
        for path in paths:
            with open(path, "a") as f:
                f.write(line)


class _Hashed:
    def __init__(self, f, h) -> None:
        self.f, self.h = f, h

    def write(self, text: str) -> int:
        self.h.update(text.encode())
        return self.f.write(text)


def _stamp_of(path: Path) -> str | None:
    """The set stamp at the end of ``path`` (None: none, e.g. a file of another tool)."""
    try:
        with open(path, "rb") as f:
            f.seek(max(0, path.stat().st_size - 64))
            tail = f.read().decode("utf-8", "replace")
    except OSError:
        return None
    at = tail.rfind(SET_STAMP)
    if at < 0:
        return None
    return tail[at + len(SET_STAMP):].split()[0] if tail[at + len(SET_STAMP):].split() else None


def _check_set(paths: list[Path]) -> None:
    """Refuse a set whose stamped files come from different writes, or that has a stamped
    file and one without its stamp (cut short: the stamp is the last line written)."""
    present = [(p, _stamp_of(p)) for p in paths if p.is_file()]
    stamps = [(p, s) for p, s in present if s is not None]
    bare = [p for p, s in present if s is None]
    if stamps and bare:  # a file cut inside its last number read as a smaller one
        (a, sa), b = stamps[0], bare[0]
        raise ValueError(f"{b}: no '{SET_STAMP.strip()}' line at its end, which {a.name} "
                         f"has ({sa}): cut short, or changed by another tool since qdrefine "
                         "wrote the set; write the mesh again (or remove that line from "
                         "every file of the set to read them as they are)")
    if len({s for _, s in stamps}) > 1:
        (a, sa), (b, sb) = stamps[0], next((p, s) for p, s in stamps if s != stamps[0][1])
        raise ValueError(f"{b}: written by another run than {a.name} (qdrefine set {sb}, "
                         f"{a.name}: {sa}): a mixed set, left by an interrupted or concurrent "
                         "write; write the mesh again")


class _Lines:
    """The non-empty lines of a Triangle file, comments (``#``) removed, as numbers."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            text = read_bytes(path).decode("utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"{path}: not a text file") from None
        self.rows: list[tuple[int, list[str]]] = []
        for number, line in enumerate(text.splitlines(), start=1):
            words = line.split("#", 1)[0].split()
            for word in words:  # Python reads 1_0 as 10 and other scripts' digits as
                # digits; Triangle's C reader does neither
                if not word.isascii() or "_" in word:
                    raise self.error(f"expected a number, got {word[:40]!r}", number)
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

    def tag(self, line: int, word: str, what: str) -> int:
        """The integer tag ``word``: an integer literal exactly (any int64), or a number
        with an integral value under 2**53 in magnitude (where float64 text names one integer:
        Triangle itself reads attributes as floating-point numbers)."""
        try:
            value = int(word)
        except ValueError:
            try:
                number = float(word)
            except ValueError:
                raise self.error(f"expected a number in {what}, got {word!r}", line) from None
            if not (np.isfinite(number) and number == int(number)):
                raise self.error(f"{what} {word} is not an integer tag", line) from None
            if abs(number) >= 2**53:  # 1e16 is 10**16, but 1.152921504606847e+18 is not
                # 2**60, whose text it rounds (Triangle writes %.17g): no one integer
                raise self.error(f"{what} {word} is a number of 2**53 or more written as a "
                                 "float, which names no one integer; write tags as integers",
                                 line) from None
            value = int(number)
        if not -2**63 <= value < 2**63:
            raise self.error(f"{what} {word} is beyond int64", line)
        return value

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


def base_of(path: Path) -> Path:
    return path.with_suffix("")


def read(path: Path) -> RawMesh:
    """The content of ``name.node`` and ``name.ele`` (and ``name.poly`` if it exists)."""
    base = base_of(path)
    node_path, ele_path, poly_path = (base.with_suffix(s) for s in (".node", ".ele", ".poly"))
    _check_set([node_path, ele_path, poly_path])
    points, first, node_lines, attributes = _read_node(_Lines(node_path))
    raw = RawMesh(ele_path, points, np.empty((0, 3), dtype=np.int64), base=first)
    raw.lines["point"] = (node_path, node_lines)
    if attributes is not None:  # Triangle interpolates them linearly, as point data are
        raw.point_data[ATTRIBUTES] = attributes[:, 0] if attributes.shape[1] == 1 else \
            attributes
    _read_ele(_Lines(ele_path), raw, node_path)
    if poly_path.exists() and not any(p.kind == "no-triangles" for p in raw.problems):
        _read_poly(_Lines(poly_path), raw)
    return raw


def _read_node(nodes: _Lines) -> tuple[NDArray, int, NDArray, NDArray | None]:
    """Points ``(N, 2)``, the first vertex number, each vertex's line and its attributes
    ``(N, A)`` (None without any)."""
    n, dim, n_attr, n_mark = nodes.header("vertex", 4, (0, 2, 0, 0))
    if dim != 2:
        raise nodes.error(f"dimension must be 2, got {dim}", nodes.rows[0][0])
    points = np.empty((n, 2))
    if n and n_attr > 0 and 3 + n_attr > len(nodes.rows[nodes.pos][1]):  # before allocating
        raise nodes.error(f"the header announces {n_attr} attributes per vertex, vertex 1 "
                          f"has {len(nodes.rows[nodes.pos][1]) - 3}", nodes.rows[nodes.pos][0])
    attributes = np.empty((n, n_attr)) if n_attr > 0 else None
    lines = np.empty(n, dtype=np.int64)
    first = None
    for i in range(n):
        line, words = nodes.next(f"vertex {i + 1} of {n}", 3 + max(n_attr, 0))
        idx = nodes.ints(line, words[:1], "the vertex number")[0]
        first = nodes.numbering(line, idx, i, first, "vertex")
        points[i] = nodes.floats(line, words[1:3], "the coordinates")
        if attributes is not None:
            attributes[i] = nodes.floats(line, words[3:3 + n_attr], "the attributes")
        lines[i] = line
    return points, 0 if first is None else first, lines, attributes


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
            tags[i] = eles.tag(line, words[1 + per], "the regional attribute")
    if m == 0:
        raw.problem("no-triangles", "holds no triangles", 1)
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
        values = poly.ints(line, words[:3], "the segment")
        marker = poly.tag(line, words[3], "the boundary marker") if k_mark > 0 else 0
        if marker != 0:
            rows.append((values[1] - first, values[2] - first, line, marker))
    if not rows:
        return
    data = np.array(rows, dtype=np.int64)
    raw.lines["edge"] = (poly.path, data[:, 2])
    raw.edges, raw.edge_tags = data[:, :2], data[:, 3]


def write(path: Path, mesh, *, binary: bool = False) -> None:  # noqa: ARG001
    """Write ``name.node``, ``name.ele`` and ``name.poly`` as one set."""
    write_chunks(path, MeshChunks.of_mesh(mesh))


def write_chunks(path: Path, source: MeshChunks) -> None:
    """Write a mesh given chunk by chunk as Triangle's three files, one set (the same bytes
    as :func:`write` of the whole mesh)."""
    if path.suffix != path.suffix.lower():  # T.Node would be written as T.node, T.ele ...
        raise ValueError(f"{path}: Triangle files are written as NAME.node, NAME.ele and "
                         f"NAME.poly; give the extension in lower case "
                         f"({path.with_suffix(path.suffix.lower()).name})")
    base = base_of(path)
    targets = [base.with_suffix(s) for s in (".node", ".ele", ".poly")]
    stamping = Stamping()
    with atomic_paths(targets) as (node, ele, poly):
        with open(node, "w") as f:
            f = stamping.wrap(f)
            f.write(f"# written by qdrefine\n{source.n_points} 2 0 0\n")
            for start, p in source.points():
                np.savetxt(f, np.column_stack([np.arange(start, start + len(p)), p]),
                           fmt="%d %.17g %.17g")
        with open(ele, "w") as f:
            f = stamping.wrap(f)
            tagged = source.cell_tags is not None
            f.write(f"{source.n_triangles} 3 {int(tagged)}\n")
            for start, t, tags in source.cells("triangles"):
                cols = [np.arange(start, start + len(t)), np.asarray(t, dtype=np.int64)]
                np.savetxt(f, np.column_stack(cols + [tags] if tagged else cols), fmt="%d")
        with open(poly, "w") as f:
            f = stamping.wrap(f)
            f.write(f"# vertices are in the .node file\n0 2 0 0\n{source.n_edges} 1\n")
            if source.n_edges:
                for start, e, tags in source.cells("edges"):
                    np.savetxt(f, np.column_stack([np.arange(start, start + len(e)), e, tags]),
                               fmt="%d")
            f.write("0\n")
        stamping.finish([node, ele, poly])
