"""Memory planning: refuse a refinement that cannot fit before allocating anything."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .arguments import as_count
from .numbering import index_dtype
from .schemes import Scheme, get_scheme

if TYPE_CHECKING:
    from .mesh import Mesh

__all__ = ["check_memory", "memory_needed", "available_memory", "MEMORY_LIMIT_VARIABLE",
           "validation_needed", "reading_needed_for_bytes", "check_needed",
           "local_memory_needed", "LOCAL_PER_WORKING", "LOCAL_PER_OUTPUT"]

#: Environment variable capping the memory qdrefine may plan to use (e.g. ``4GiB``).
MEMORY_LIMIT_VARIABLE = "QDREFINE_MEMORY_LIMIT"
_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}

#: Local refinement (:mod:`qdrefine.adaptive`): peak bytes per working triangle of one pass
#: before its output is emitted (the working tree, its edge numbering, the closure's
#: tables; two rounds' numberings while one advances to the next); at most 407 measured on
#: Gmsh meshes of 0.2 to 1.2 M triangles (``benchmarks/adaptive_memory.py``,
#: ``docs/performance.md``), 1.5 times that here.
LOCAL_PER_WORKING = 610
#: Local refinement: peak bytes per output triangle of emitting a pass and finishing the
#: step (output arrays, families, the stitched mesh, its history); at most 130 measured,
#: about 1.27 times that here.
LOCAL_PER_OUTPUT = 165


def local_memory_needed(n_working: int = 0, n_output: int = 0) -> int:
    """Peak bytes of a local refinement pass over ``n_working`` working triangles that
    emits ``n_output`` triangles (an estimate from above, from the measured constants
    :data:`LOCAL_PER_WORKING` and :data:`LOCAL_PER_OUTPUT`). A step's output size is known
    only once its closure is, so the adaptive code checks each phase before it allocates:
    the lower bound of the output before a step, the working mesh before a pass, the
    output before it is emitted and stitched."""
    return LOCAL_PER_WORKING * int(n_working) + LOCAL_PER_OUTPUT * int(n_output)


def validation_needed(n_points: int, n_triangles: int, n_boundary: int | None = None) -> int:
    """Peak bytes of validating a mesh (:func:`qdrefine.check.find`), an estimate from above.

    The normalized copies (``16`` bytes per point, ``3 x 4`` or ``3 x 8`` per triangle), the
    orientation signs and the sorted edges (``1 + 30`` bytes per triangle, more with
    ``int64`` indices), the boundary scan (``1`` byte per edge) and, with ``n_boundary``
    boundary edges (default: as many as there are sides, a soup of separate triangles),
    the plane sweep's tables (``160`` bytes per boundary edge).
    """
    n, m = int(n_points), int(n_triangles)
    b = 3 * m if n_boundary is None else int(n_boundary)
    idx = np.dtype(index_dtype(n)).itemsize
    return 16 * n + n + (3 * idx + 1 + 3 * (2 + 2 * idx) + 3 * idx + 3) * m + 160 * b


def reading_needed_for_bytes(size: int) -> int:
    """Peak bytes of reading mesh files of ``size`` bytes, before their counts are known (an
    estimate from above): the bytes themselves, a decoded copy of text, and the parsed
    arrays, which take no more than the file does (``int32`` indices of binary files become
    ``int64``: twice as many bytes, for at most half the file). Compressed VTU data can
    expand beyond this: the readers check the sizes it declares before decompressing."""
    return 3 * int(size)


def check_needed(need: int, what: str) -> None:
    """Raise ``MemoryError`` (``"{what} needs about X GiB; Y GiB available"``) when ``need``
    bytes exceed :func:`available_memory`; ``what`` says what, e.g. ``"reading F (10 M
    triangles)"``."""
    avail = available_memory()
    if avail is not None and need > avail[0]:
        source = f" ({avail[1]})" if avail[1] == MEMORY_LIMIT_VARIABLE else ""
        amount = f"about {_gib(need)}" if need < 2**100 else "more than 1e+21"
        raise MemoryError(f"{what} needs {amount} GiB; {_gib(avail[0])} GiB "
                          f"available{source}")


def memory_needed(n_points: int, n_triangles: int, scheme: str | Scheme, levels: int,
                  tagged: bool = False) -> int:
    """Peak bytes of uniform refinement by ``levels`` levels (an estimate from above).

    At the last level the input mesh, the previous level, its edge tables and the output
    are alive at once: ``16`` bytes per point, ``3 x 4`` (or ``3 x 8``) per triangle, ``8`` per
    tag, ``72 + 6 x 4`` per triangle for the edge numbering and ``8`` per output triangle for
    the parents. Edges follow from Euler's formula (``E = N + M``, at most ``3 M``) and, per
    level, ``E' = (k + 1) E + I M`` with ``I`` inner edges per parent.
    """
    sch = get_scheme(scheme)
    k, t = sch.stencil.per_edge, sch.n_children
    inner = (3 * t - 3 * (k + 1)) // 2
    n, m = int(n_points), int(n_triangles)
    e = min(3 * m, n + m)

    def size(n_: int, m_: int) -> int:
        return 16 * n_ + (3 * np.dtype(index_dtype(n_)).itemsize + 8 * tagged) * m_

    first = size(n, m)
    prev_n, prev_m = n, m
    for _ in range(levels):
        prev_n, prev_m = n, m
        n, m, e = n + k * e, t * m, (k + 1) * e + inner * m  # exact Python integers
        if m > 2**100:  # beyond any memory (1e22 GiB): the message says "more than 1e+21"
            break
    if levels == 0:
        return 0
    work = (72 + 6 * np.dtype(index_dtype(prev_n)).itemsize) * prev_m
    previous = size(prev_n, prev_m) if levels > 1 else 0
    return first + previous + work + size(n, m) + 8 * m


def available_memory() -> tuple[int, str] | None:
    """Bytes this process may still allocate, and where the figure comes from: the least of
    ``MemAvailable`` (``/proc/meminfo``), the cgroup limit minus its usage and
    ``$QDREFINE_MEMORY_LIMIT``; ``os.sysconf`` where there is no ``/proc``; ``None`` when
    nothing is known."""
    found: list[tuple[int, str]] = []
    meminfo = _read("/proc/meminfo")
    for line in (meminfo or "").splitlines():
        if line.startswith("MemAvailable:"):
            found.append((int(line.split()[1]) * 1024, "MemAvailable"))
    for limit, usage in (("memory.max", "memory.current"),
                         ("memory/memory.limit_in_bytes", "memory/memory.usage_in_bytes")):
        lim, use = _read(f"/sys/fs/cgroup/{limit}"), _read(f"/sys/fs/cgroup/{usage}")
        if lim and use and lim.strip().isdigit() and int(lim) < 2**60:
            found.append((max(0, int(lim) - int(use)), "cgroup limit"))
    if not found:
        try:
            found.append((os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"),
                          "free memory"))
        except (ValueError, OSError, AttributeError):
            pass
    cap = os.environ.get(MEMORY_LIMIT_VARIABLE)
    if cap:
        found.append((_parse_bytes(cap), MEMORY_LIMIT_VARIABLE))
    return min(found) if found else None


def check_memory(mesh: Mesh, scheme: str | Scheme, levels: int) -> None:
    """Raise ``MemoryError`` when refining ``mesh`` ``levels`` times would need more memory
    than :func:`available_memory` says there is ("refining M triangles L levels needs about
    X GiB; Y GiB available")."""
    levels = as_count(levels, "levels")
    avail = available_memory()
    if levels == 0 or avail is None:
        return
    need = memory_needed(mesh.n_points, mesh.n_triangles, scheme, levels,
                         mesh.cell_tags is not None)
    check_needed(need, f"refining {mesh.n_triangles} triangles {levels} level"
                       f"{'s' if levels != 1 else ''}")


def _gib(n: int) -> str:
    return f"{n / 2**30:.3g}"


def _read(path: str) -> str | None:
    try:
        return Path(path).read_text()
    except (OSError, ValueError):
        return None


def _parse_bytes(text: str) -> int:
    value = text.strip().upper().removesuffix("B").removesuffix("I")
    unit = value[-1:] if value[-1:] in _UNITS and value[-1:] else ""
    try:
        number = float(value[:len(value) - len(unit)])
    except ValueError:
        raise ValueError(f"{MEMORY_LIMIT_VARIABLE}={text!r}: expected a size such as 4GiB, "
                         "512M or 1000000") from None
    size = number * _UNITS[unit]
    if not 0 <= size < float("inf"):  # nan, negative, inf or 1e400 (int(inf) raised)
        raise ValueError(f"{MEMORY_LIMIT_VARIABLE}={text!r}: expected a finite size >= 0")
    return int(size)
