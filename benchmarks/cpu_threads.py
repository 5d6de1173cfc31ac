"""CPU thread scaling of one uniform 7T-QD level, and whether the output is the same bits
for every thread count (not part of the test suite).

Builds the structured grid of :func:`gpu_bench.grid` (``MILLIONS`` million triangles, default
20), refines it once with 16, 8, 4, 2 and 1 numba threads (at most the machine's), best of
two runs (one for 1 and 2 threads), and writes seconds, output triangles/s and the SHA-256
of the output's points and triangles per thread count to the JSON file given.

Run: ``python benchmarks/cpu_threads.py benchmarks/results/cpu-threads-DATE.json``.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from pathlib import Path

import numba

sys.path.insert(0, str(Path(__file__).parent))
from gpu_bench import grid  # noqa: E402

from qdrefine import refine  # noqa: E402


def main() -> None:
    mesh = grid(float(os.environ.get("MILLIONS", "20")), False)
    refine(grid(0.01, False))  # load the kernels
    rows = []
    counts = sorted({min(t, numba.config.NUMBA_NUM_THREADS) for t in (16, 8, 4, 2, 1)},
                    reverse=True)
    for threads in counts:
        numba.set_num_threads(threads)
        best = float("inf")
        for _ in range(2 if threads > 2 else 1):
            t0 = time.perf_counter()
            out = refine(mesh)
            best = min(best, time.perf_counter() - t0)
        digest = hashlib.sha256(out.points.tobytes() + out.triangles.tobytes()).hexdigest()
        rows.append({"threads": threads, "seconds": best,
                     "out_triangles_per_s": out.n_triangles / best, "sha256": digest})
        print(rows[-1], flush=True)
        del out
        with open(sys.argv[1], "w") as fh:  # rewritten after each count: a timeout keeps some
            json.dump({"cpu_count": os.cpu_count(), "n_triangles": mesh.n_triangles,
                       "rows": rows, "identical": len({r["sha256"] for r in rows}) == 1},
                      fh, indent=1)


if __name__ == "__main__":
    main()
