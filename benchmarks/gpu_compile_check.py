"""Compile every CUDA kernel of :mod:`qdrefine.gpu` to PTX without a GPU (not a test).

The CUDA simulator runs the kernels as Python, so it does not prove that they compile for a
real device. This script does, on any machine with ``pip install -e '.[gpu]'`` (numba-cuda
with the CUDA 12 toolkit wheels, which bring NVVM; no driver or GPU needed): it compiles
each kernel with the argument types of a 7T-QD level on an ``int32`` mesh for compute
capability ``--cc`` (default 9.0, H100), twice: with numba-cuda's NVVM options (``-fma=1``,
NVVM's default) and with ``-fma=0``. Per kernel it prints the PTX size, the
double-precision FMAs (all, and ``contracted``: the difference between the two builds, the
``a * b + c`` that NVVM fused by itself), the ``mul.rn.f64`` (the error-free transforms'
products, which neither NVVM nor ptxas fuses: see :mod:`qdrefine.gpu.predicates`), the plain
``mul.f64`` (which ptxas may still fuse into a following addition) and the divisions (every
one must be ``div.rn``: IEEE division, as on the CPU). Exit status 1 if any kernel fails
to compile.

Run: ``python benchmarks/gpu_compile_check.py [--cc 9.0]`` (not under NUMBA_ENABLE_CUDASIM).
"""

from __future__ import annotations

import argparse
import re
import sys
from contextlib import contextmanager

import numba.cuda.dispatcher as dispatcher
from numba import cuda
from numba import types as T


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cc", default="9.0", help="compute capability, e.g. 8.0 or 9.0")
    cc = tuple(int(x) for x in ap.parse_args().cc.split("."))

    class Device:  # device functions ask the current device for its compute capability
        compute_capability = cc

    dispatcher.get_current_device = lambda: Device()

    from qdrefine.gpu import kernels as k
    from qdrefine.gpu import numbering as nb
    from qdrefine.gpu import refine as r

    i32, i64, f64, i8, u8 = T.int32, T.int64, T.float64, T.int8, T.uint8

    def a(t, nd=1):
        return T.Array(t, nd, "C")

    signatures = {
        nb._zero: (a(i32),),
        nb._count: (a(i32, 2), a(i32)),
        nb._scatter: (a(i32, 2), a(i64), a(i32), a(i32)),
        nb._sort_runs: (a(i64), a(i32), a(i32)),
        nb._serial_scan: (a(i32), a(i64)),
        nb._chunk_sums: (a(i32), a(i64)),
        nb._chunk_scan: (a(i32), a(i64), a(i64)),
        k.new_points: (a(f64, 2), a(i64), a(i64), a(i32), i64, a(f64, 2)),
        k.emit: (a(f64, 2), a(i32, 2), a(i64), a(i64), a(i32), i64, a(f64, 2), a(f64, 2),
                 a(i8), a(u8), i64, a(i32), a(i64), a(i64), a(i64), i64),
        k.decide_rows: (a(f64, 2), a(i32, 2), a(i64), a(f64, 2), a(f64, 2), a(i8), i64,
                        a(i64, 2)),
        k.check_points: (a(f64, 2), f64, f64, a(i64)),
        k.emit_rows: (i64, a(i32, 2), a(i64), a(i64), a(i32), i64, a(u8), i64, a(i64),
                      a(i64, 2), a(i32)),
        k.repeat: (a(i64), i64, a(i64)),
        k.split_edges: (a(i32, 2), i64, a(i64), a(i64), a(i32), i64, a(i32, 2), a(i64)),
        r._index_range: (a(i32, 2), a(i64)),
        r._first_out_of_range: (a(i32, 2), i64, a(i64)),
    }
    failed = 0
    print(f"compute capability {cc[0]}.{cc[1]}")
    for kernel, sig in signatures.items():
        name = kernel.py_func.__name__
        try:
            ptx, _ = cuda.compile_ptx(kernel.py_func, sig, cc=cc)
            with _no_contraction():
                strict, _ = cuda.compile_ptx(kernel.py_func, sig, cc=cc)
        except Exception as exc:  # report every kernel, then fail
            failed += 1
            print(f"{name:20} FAILED: {type(exc).__name__}: {str(exc)[:2000]}")
            continue
        divs = re.findall(r"\bdiv\.\w+\.f64", ptx)
        kinds = ", ".join(sorted(set(divs))) or "-"
        fma = ptx.count("fma.rn.f64")
        plain = len(re.findall(r"\bmul\.f64", ptx))
        print(f"{name:20} ok {len(ptx):7d} B  fma.f64 {fma:3d} (contracted "
              f"{fma - strict.count('fma.rn.f64'):2d})  mul.rn.f64 {ptx.count('mul.rn.f64'):3d}"
              f"  mul.f64 {plain:3d}  div {len(divs)} ({kinds})")
    return 1 if failed else 0


@contextmanager
def _no_contraction():
    """NVVM compiles with ``-fma=0`` inside the block (numba-cuda has no option for it)."""
    from numba.cuda.cudadrv import nvvm

    original = nvvm.CompilationUnit.__init__

    def init(self, options):
        original(self, dict(options, fma=False))

    nvvm.CompilationUnit.__init__ = init
    try:
        yield
    finally:
        nvvm.CompilationUnit.__init__ = original


if __name__ == "__main__":
    sys.exit(main())
