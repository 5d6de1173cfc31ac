"""Low-level support shared by the compiled kernels: where their compiled code is cached,
work sizes, the thread switch for small inputs, software prefetch (an LLVM intrinsic
numba does not expose), and the bisection of rows sorted by two keys."""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numba
import numpy as np
from llvmlite import binding as llvm
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = ["CHUNK", "AHEAD", "PARALLEL_MIN", "cache_directory", "compile_note",
           "one_thread", "threads_for",
           "prefetch", "prefetch_write", "unsigned"]


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return False
    return True


def _user_cache() -> Path:
    """numba's cache folder in the user's cache directory (its second choice)."""
    from numba.misc.appdirs import AppDirs

    return Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)


def cache_directory() -> str | None:
    """Make sure numba can cache the kernels (``cache=True``), also from a read-only install.

    numba caches next to the sources (``__pycache__``), else in the user's cache directory
    and fails at import when neither can be written. Then the cache goes to
    ``$TMPDIR/qdrefine-numba-<uid>`` (``NUMBA_CACHE_DIR`` when set always wins) and one
    line on stderr says so. Called once, when :mod:`qdrefine` is imported, before any kernel
    is defined. Returns the directory chosen here, ``None`` when numba's own choice works.
    """
    if numba.config.CACHE_DIR:
        return None
    if _writable(Path(__file__).parent / "__pycache__") or _writable(_user_cache()):
        return None
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    folder = Path(tempfile.gettempdir()) / f"qdrefine-numba-{uid}"
    if not _writable(folder):
        folder = Path(tempfile.mkdtemp(prefix="qdrefine-numba-"))
    numba.config.CACHE_DIR = str(folder)
    print(f"qdrefine: note: the install folder and the user cache are read-only; compiled "
          f"kernels are cached in {folder}", file=sys.stderr)
    return str(folder)


cache_directory()


@contextmanager
def compile_note(message: str) -> Iterator[None]:
    """Print ``message`` on stderr, once, when a kernel of qdrefine is compiled while the
    block runs (numba's ``numba:compile`` event, which fires on a cache miss only): a first
    run says so before it compiles for tens of seconds, and a run with nothing to compile
    says nothing, whatever the command and its options."""
    from numba.core import event

    class Note(event.Listener):
        said = False

        def on_start(self, ev: event.Event) -> None:
            function = getattr(ev.data.get("dispatcher"), "py_func", None)
            if not self.said and getattr(function, "__module__", "").startswith("qdrefine"):
                self.said = True
                print(message, file=sys.stderr, flush=True)

        def on_end(self, ev: event.Event) -> None:
            pass

    with event.install_listener("numba:compile", Note()):
        yield


CHUNK = 4096  # triangles per parallel work item
AHEAD = 8  # software prefetch distance (triangles or edges) for gathers of random rows
PARALLEL_MIN = 32768  # triangles below which a pass runs on the calling thread only


@contextmanager
def one_thread() -> Iterator[None]:
    """Run numba's parallel regions on the calling thread only (e.g. inside Dask tasks,
    which are the parallelism). ``numba.set_num_threads`` is per calling thread, so this is
    safe under threads."""
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(before)


@contextmanager
def threads_for(n_items: int) -> Iterator[None]:
    """One numba thread for small inputs: waking the pool costs more than the work (and far
    more on a busy machine, where a parallel region waits for every thread to be scheduled)."""
    if n_items >= PARALLEL_MIN:
        yield
        return
    with one_thread():
        yield


# the intrinsic's name carries the pointer type: opaque pointers from LLVM 15 on
_PREFETCH = "llvm.prefetch.p0" if llvm.llvm_version_info >= (15,) else "llvm.prefetch.p0i8"


def _prefetch_codegen(write: int):
    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        row = context.cast(builder, args[1], signature.args[1], types.intp)
        idx = [row] + [context.get_constant(types.intp, 0)] * (aryty.ndim - 1)
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, idx, wraparound=False)
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, _PREFETCH)
        # read or write access, high temporal locality, data cache
        builder.call(fn, [builder.bitcast(ptr, i8p), i32(write), i32(3), i32(1)])
        return context.get_dummy_value()

    return codegen


@intrinsic
def prefetch(typingctx, arr, i):
    """Hint the CPU to load row ``i`` of ``arr`` (LLVM ``llvm.prefetch``; never faults).

    Gathers of point rows through shuffled vertex indices are latency bound: one triangle's
    work is too long for the out-of-order window to overlap the next triangle's misses.
    """
    return types.void(arr, i), _prefetch_codegen(0)


@intrinsic
def prefetch_write(typingctx, arr, i):
    """:func:`prefetch` for a row about to be written (scatters through shuffled ids)."""
    return types.void(arr, i), _prefetch_codegen(1)




@njit(inline="always", cache=True)
def unsigned(i):
    """``i`` (known ``>= 0``) as ``uint64``, for hot array indices: numba checks every signed
    index for wraparound (a compare and a select per access), an unsigned one never."""
    return np.uint64(i)


@njit(cache=True)
def first_row_at_or_after(rows, lo, hi, x, y):
    """The first row ``h`` in ``[lo, hi)`` of ``rows (R, >= 2)``, sorted by their first two
    columns, with ``(rows[h, 0], rows[h, 1])`` not before ``(x, y)`` (``hi`` if none)."""
    while lo < hi:
        mid = (lo + hi) // 2
        if rows[mid, 0] < x or (rows[mid, 0] == x and rows[mid, 1] < y):
            lo = mid + 1
        else:
            hi = mid
    return lo
