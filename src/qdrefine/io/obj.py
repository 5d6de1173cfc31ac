"""Wavefront OBJ: written here (``v`` and ``f`` lines, with MeshLab's count comments
``# Vertices: N`` and ``# Faces: M`` in the header) and read here: vertices ``v x y [z]``
and faces ``f`` in every form the format has (``i``, ``i/t``, ``i//n``, ``i/t/n``; negative
indices count back from the latest vertex); texture coordinates, normals and other
statements are skipped (a warning names which; groups and materials silently). meshio's
reader refused a file with normals or texture coordinates (as Blender writes them) and
took negative indices for vertex numbers. A file whose header has the count comments must
hold exactly that many vertices and faces, so a file cut at a line end is refused instead
of read as a smaller mesh (OBJ itself declares no counts: a file without them that was cut
between two lines cannot be told from a whole one)."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from ._core import RawMesh, check_regular, from_blocks, read_bytes
from ._text import format_floats, int_lines
from .atomic import atomic_path

__all__ = ["read", "write"]

_COUNT = re.compile(rb"^#\s*(Vertices|Faces):\s*(\d+)\s*$")


def write(path: Path, mesh) -> None:
    """Points as ``v x y 0`` (shortest exact digits), triangles as 1-based ``f a b c``."""
    with atomic_path(path) as tmp, open(tmp, "wb") as f:
        f.write(f"# written by qdrefine\n# Vertices: {mesh.n_points}\n"
                f"# Faces: {mesh.n_triangles}\n".encode())
        for chunk in format_floats(mesh.points, suffix=" 0"):
            f.write(_prefixed(b"v ", bytes(chunk)))
        for chunk in int_lines(mesh.triangles.astype("int64") + 1):
            f.write(_prefixed(b"f ", chunk.tobytes()))


def _prefixed(prefix: bytes, lines: bytes) -> bytes:
    """``prefix`` in front of every line of ``lines`` (each ending with a newline)."""
    if not lines:
        return b""
    return prefix + lines[:-1].replace(b"\n", b"\n" + prefix) + b"\n"


def read(path: Path) -> RawMesh:
    """The vertices and faces of ``path``, then the counts of the header's ``# Vertices`` /
    ``# Faces`` comments (where present) checked against what was read."""
    check_regular(path)
    raw, n_faces = _parsed(path, read_bytes(path))
    counts = {}
    with open(path, "rb") as f:
        header = f.readline()
        f.seek(0)
        for line in f:  # the header: up to the first vertex or face line
            if line[:1] in (b"v", b"f"):
                break
            m = _COUNT.match(line.strip())
            if m:
                counts[m.group(1).decode()] = int(m.group(2))
    ours = b"written by qdrefine" in header
    if (counts or ours) and len(counts) < 2:
        missing = ", ".join(f"# {n}" for n in ("Vertices", "Faces") if n not in counts)
        raise ValueError(f"{path}: its header lacks {missing} (the other count is there, or "
                         "qdrefine wrote it): damaged?")
    found = {"Vertices": len(raw.points), "Faces": n_faces}
    for name, announced in counts.items():
        if found[name] != announced:
            raise ValueError(f"{path}: the file holds {found[name]} "
                             f"{name.lower().removesuffix('s')}{'s' if found[name] != 1 else ''}"
                             f", its header announces {announced} (# {name}: {announced}); "
                             "was it cut short?")
    return raw


#: Statements that carry no geometry of a triangle mesh, skipped without a word.
_QUIET = {b"g", b"o", b"s", b"usemtl", b"mtllib", b"vp"}
#: Cell names of faces by their number of vertices (as meshio names them).
_KINDS = {3: "triangle", 4: "quad"}


class _Bad(ValueError):
    """A line of an OBJ file that is not what its statement needs (the message says why)."""


def _parsed(path: Path, data: bytes) -> tuple[RawMesh, int]:
    """``(raw mesh, number of faces)`` of the OBJ text ``data``; errors name the line."""
    points: list[list[float]] = []
    faces: dict[int, list[list[int]]] = {}
    skipped: dict[str, int] = {}
    for number, line in enumerate(data.split(b"\n"), start=1):
        words = line.split(b"#", 1)[0].split()
        if not words:
            continue
        key = words[0]
        try:
            if b"_" in line and key in (b"v", b"f"):  # Python reads 1_0 as 10; C does not
                raise ValueError
            if key == b"v":
                if not 3 <= len(words) <= 5:  # x y z [w]; some tools write x y
                    raise _Bad(f"expected 'v x y z', got {len(words) - 1} numbers")
                xyz = [float(w) for w in words[1:4]]
                points.append(xyz + [0.0] * (3 - len(xyz)))
            elif key == b"f":
                if len(words) < 4:
                    raise _Bad(f"a face of {len(words) - 1} vertices")
                n = len(points)
                face = []
                for word in words[1:]:
                    i = int(word.split(b"/", 1)[0])
                    if i == 0 or not -n <= i <= n:
                        raise _Bad(f"vertex index {i} outside 1..{n} (or -{n}..-1, counted "
                                   "back from the latest vertex)")
                    face.append(i - 1 if i > 0 else n + i)
                faces.setdefault(len(face), []).append(face)
            elif key not in _QUIET:
                name = key.decode(errors="replace")
                skipped[name] = skipped.get(name, 0) + 1
        except ValueError as exc:
            text = line.strip().decode(errors="replace")[:60]
            message = str(exc) if isinstance(exc, _Bad) else f"not a number in {text!r}"
            raise ValueError(f"{path}, line {number}: {message}") from None
    if skipped:
        what = ", ".join(f"{n} '{k}'" for k, n in sorted(skipped.items()))
        warnings.warn(f"{path}: {what} line{'s' if sum(skipped.values()) > 1 else ''} "
                      "skipped (a Mesh holds the vertices and faces: texture coordinates, "
                      "normals and the like are not read)", stacklevel=4)
    coordinates = np.array(points, dtype=np.float64).reshape(-1, 3)
    blocks = [(_KINDS.get(k, "polygon"), np.array(f, dtype=np.int64).reshape(-1, k))
              for k, f in faces.items()]
    raw = from_blocks(path, coordinates, blocks, [None] * len(blocks))
    return raw, sum(len(f) for f in faces.values())
