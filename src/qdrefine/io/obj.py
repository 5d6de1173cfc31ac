"""Wavefront OBJ: written here (``v`` and ``f`` lines, with MeshLab's count comments
``# Vertices: N`` and ``# Faces: M`` in the header), read by meshio; a file whose header
has those counts must hold exactly that many vertices and faces, so a file cut at a line
end is refused instead of read as a smaller mesh (OBJ itself declares no counts: a file
without them that was cut between two lines cannot be told from a whole one)."""

from __future__ import annotations

import re
from pathlib import Path

from ._core import RawMesh
from ._text import format_floats, int_lines
from .atomic import atomic_path
from .meshio_formats import read_with_meshio

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
    """meshio's reader, then the counts of the header's ``# Vertices`` / ``# Faces``
    comments (where present) checked against what was read."""
    raw = read_with_meshio(path, "obj", "Wavefront OBJ")
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
    found = {"Vertices": len(raw.points), "Faces": len(raw.triangles)}
    for name, announced in counts.items():
        if found[name] != announced:
            raise ValueError(f"{path}: the file holds {found[name]} "
                             f"{name.lower().removesuffix('s')}{'s' if found[name] != 1 else ''}"
                             f", its header announces {announced} (# {name}: {announced}); "
                             "was it cut short?")
    return raw
