"""qdrefine: refine 2D triangle meshes with longest-edge seven-triangle partitions.

The 7T-QD (Seven Triangle Quasi-Delaunay) partition, with 7T-LE, 7T-D and the classic
four-triangle schemes for comparison. See :func:`refine` and :func:`partition`.
"""

import os as _os
import sys as _sys


def _loading_for_the_command_line() -> bool:
    """Whether this import is the start of a ``qdrefine`` command (the console script or
    ``python -m qdrefine``), not of a program that uses the library."""
    script = _os.path.splitext(_os.path.basename(_sys.argv[0] if _sys.argv else ""))[0]
    orig = list(getattr(_sys, "orig_argv", []))
    return script in ("qdrefine", "qdrefine-script") or any(
        a == "-m" and b == "qdrefine" for a, b in zip(orig, orig[1:], strict=False))


def _ignore_interrupts_in_workers() -> None:
    """In the Dask worker processes of a ``qdrefine`` command (spawned with its arguments,
    so they import this first), ignore Ctrl-C: the terminal sends it to every process of
    the command, and the command stops its cluster itself and says so in one line, while
    a worker interrupted as it starts printed a traceback of Dask's imports."""
    import multiprocessing

    if multiprocessing.current_process().name != "MainProcess" \
            and _loading_for_the_command_line():
        import signal

        signal.signal(signal.SIGINT, signal.SIG_IGN)


_ignore_interrupts_in_workers()

try:
    from . import jit  # noqa: F401, I001  (first: where numba caches the kernels)
    from . import marking  # noqa: I001
    from .adaptive import coarsen, refine_cycles
    from .io import read, write
    from .mesh import Mesh
    from .partition import partition, partition_many
    from .refine import RefusedTriangle, refine, refine_with_parents
    from .schemes import SCHEMES, get_scheme, scheme_names
except KeyboardInterrupt:
    # Ctrl-C in the second or so a command spends loading numba: one line, like the
    # commands' own (qdrefine.cli.main), instead of the import's traceback
    if not _loading_for_the_command_line():
        raise
    print("qdrefine: interrupted", file=_sys.stderr)
    raise SystemExit(130) from None

__all__ = [
    "Mesh",
    "RefusedTriangle",
    "SCHEMES",
    "coarsen",
    "get_scheme",
    "marking",
    "partition",
    "partition_many",
    "read",
    "refine",
    "refine_cycles",
    "refine_with_parents",
    "scheme_names",
    "write",
]

__version__ = "0.1.0"
