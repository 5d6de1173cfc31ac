"""CPU thread scaling of one uniform 7T-QD level, and whether the output is the same bits
for every thread count (not part of the test suite).

Builds the structured grid of :func:`gpu_bench.grid` (``--millions`` million triangles,
default 20), refines it once with 16, 8, 4, 2 and 1 numba threads (at most the machine's),
best of ``--repeat`` runs each, and writes per thread count the seconds, output triangles/s
and the SHA-256 of the output's points and triangles, with the versions and load averages,
to the JSON file given.

Run: ``python benchmarks/cpu_threads.py --json benchmarks/results/cpu-threads-DATE.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from gpu_bench import grid  # noqa: E402

from qdrefine import refine  # noqa: E402


def main() -> None:
    """Time each thread count and write the JSON (rewritten after each count, so that a run
    cut short keeps what it measured)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--millions", type=float, default=20.0)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--json", required=True)
    args = ap.parse_args()
    mesh = grid(args.millions, False)
    refine(grid(0.01, False))  # load the kernels
    result = {"cpu_count": os.cpu_count(), "n_triangles": mesh.n_triangles,
              "numba": numba.__version__, "numpy": np.__version__,
              "load_before": os.getloadavg(), "repeat": args.repeat, "rows": []}
    counts = sorted({min(t, numba.config.NUMBA_NUM_THREADS) for t in (16, 8, 4, 2, 1)},
                    reverse=True)
    for threads in counts:
        numba.set_num_threads(threads)
        best = float("inf")
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            out = refine(mesh)
            best = min(best, time.perf_counter() - t0)
        digest = hashlib.sha256(out.points.tobytes() + out.triangles.tobytes()).hexdigest()
        result["rows"].append({"threads": threads, "seconds": best,
                               "out_triangles_per_s": out.n_triangles / best,
                               "sha256": digest})
        print(result["rows"][-1], flush=True)
        del out
        result["identical"] = len({r["sha256"] for r in result["rows"]}) == 1
        result["load_after"] = os.getloadavg()
        with open(args.json, "w") as fh:
            json.dump(result, fh, indent=1)


if __name__ == "__main__":
    main()
