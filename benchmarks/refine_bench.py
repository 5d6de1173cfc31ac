"""Uniform-refinement benchmark (not part of the test suite).

Builds structured and shuffled (random vertex and triangle order) meshes of about 0.2 M and
2 M triangles and reports, as a table and as JSON (``--json FILE``):

* qdrefine uniform refinement per scheme: seconds (best of ``--repeat``), output triangles/s,
  peak resident memory of a fresh process doing only that refinement;
* the cost of the 7T-QD decision versus the exact 7T-D decision per triangle;
* the memory-bandwidth bound: the time to write the output arrays (points and triangles) to
  fresh memory on this machine, and our time relative to it;
* first-call (compile) and cached-call cost of the kernels in a fresh process;
* thread-count independence: the output hashes with 1 and with all threads;
* peers when installed (``pip install -e '.[bench]'``): scikit-fem ``MeshTri.refined()``,
  Triangle's and SciPy's Delaunay of the same refined point set.

Run: ``python benchmarks/refine_bench.py [--sizes 0.2,2] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import qdrefine
from qdrefine import Mesh, refine
from qdrefine.kernels import emit, number_edges

SCHEMES = qdrefine.scheme_names()


def grid(n_triangles: float, shuffled: bool, seed: int = 0) -> Mesh:
    n = int(round(np.sqrt(n_triangles * 1e6 / 2)))
    x = np.linspace(0.0, 1.0, n + 1)
    pts = np.stack(np.meshgrid(x, x, indexing="xy"), -1).reshape(-1, 2)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    if shuffled:
        rng = np.random.default_rng(seed)
        perm = rng.permutation(len(pts))
        pts, tris = pts[perm], np.argsort(perm)[tris][rng.permutation(len(tris))]
    return Mesh(pts, tris)


def best(f, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def bandwidth_bound(n_points: int, n_triangles: int, itemsize: int, repeat: int) -> float:
    """Seconds to write the output arrays into fresh memory (np.empty + fill)."""
    def write():
        p = np.empty((n_points, 2))
        p.fill(1.0)
        t = np.empty((n_triangles, 3), dtype=np.int32 if itemsize == 4 else np.int64)
        t.fill(1)
    return best(write, repeat)


_CHILD = """
import gc, sys
sys.path.insert(0, {bench!r})
from refine_bench import grid
from qdrefine import refine
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
mesh = grid({size}, {shuffled})
refine(grid(0.001, False), {scheme!r})
gc.collect()
open("/proc/self/clear_refs", "w").write("5")  # reset the peak resident set size
base = status("VmRSS")
fine = refine(mesh, {scheme!r})
peak = status("VmHWM")
inp = mesh.points.nbytes + mesh.triangles.nbytes
print(base, peak, inp, fine.points.nbytes + fine.triangles.nbytes, fine.n_triangles)
"""


def peak_memory(size: float, shuffled: bool, scheme: str) -> dict:
    code = _CHILD.format(bench=os.path.dirname(__file__), size=size, shuffled=shuffled,
                         scheme=scheme)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    base, peak, inp, outp, n_out = (int(v) for v in out)
    # the input is resident before the call; refine's footprint = input + what it allocates
    return {"rss_before": base, "rss_peak": peak, "input_bytes": inp, "output_bytes": outp,
            "peak_over_in_out": (peak - base + inp) / (inp + outp),
            "bytes_per_output_triangle": (peak - base) / n_out}


def jit_cost() -> dict:
    code = ("import time; t0=time.perf_counter(); import qdrefine; from qdrefine import "
            "examples, refine; refine(examples.square(4), '7t-qd'); "
            "print(time.perf_counter()-t0)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        run = [sys.executable, "-c", code]
        first = float(subprocess.run(run, env=env, capture_output=True, text=True,
                                     check=True).stdout)
        cached = float(subprocess.run(run, env=env, capture_output=True, text=True,
                                      check=True).stdout)
    return {"first_call_s": first, "cached_call_s": cached}


def digest(mesh: Mesh) -> str:
    h = hashlib.sha256(mesh.points.tobytes())
    h.update(mesh.triangles.tobytes())
    return h.hexdigest()[:16]


def thread_independence(mesh: Mesh) -> dict:
    import numba
    out = {}
    for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
        numba.set_num_threads(threads)
        out[threads] = {s: digest(refine(mesh, s)) for s in SCHEMES}
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return {"identical": len({json.dumps(v, sort_keys=True) for v in out.values()}) == 1,
            "digests": out}


def decision_cost(mesh: Mesh, repeat: int) -> dict:
    """Emission time per triangle with the 7T-QD and the exact 7T-D decision (same tables)."""
    _, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    out = {}
    for name in ("7t-le", "7t-qd", "7t-d"):
        s = qdrefine.get_scheme(name)
        buf = np.empty((mesh.n_triangles * 7, 3), dtype=np.int32)
        t = best(lambda s=s, buf=buf: emit(mesh.points, mesh.triangles, tri_edges, 2, s.forms,
                                           s.lut, s.tables, buf), repeat)
        out[name] = {"ns_per_triangle": 1e9 * t / mesh.n_triangles, "forms": len(s.forms)}
    return out


def peers(mesh: Mesh, fine: Mesh, repeat: int) -> dict:
    res: dict = {}
    try:
        import skfem
        m = skfem.MeshTri(mesh.points.T.copy(), mesh.triangles.T.astype(np.int64).copy())
        t = best(lambda: m.refined(), repeat)
        res["scikit-fem refined()"] = {"s": t, "out_tri_per_s": 4 * mesh.n_triangles / t}
    except ImportError:
        res["scikit-fem refined()"] = "not installed"
    try:
        import triangle
        t = best(lambda: triangle.triangulate({"vertices": fine.points}), 1)
        res["Triangle Delaunay"] = {"s": t, "out_tri_per_s": fine.n_triangles / t}
    except ImportError:
        res["Triangle Delaunay"] = "not installed"
    try:
        from scipy.spatial import Delaunay
        if fine.n_points > 2e6:
            raise ImportError  # minutes of Qhull time; measured on the small mesh only
        t = best(lambda: Delaunay(fine.points), 1)
        res["SciPy Delaunay"] = {"s": t, "out_tri_per_s": fine.n_triangles / t}
    except ImportError:
        res["SciPy Delaunay"] = "not installed"
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="0.2,2", help="input sizes in millions of triangles")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", help="write the results to this JSON file")
    ap.add_argument("--no-peers", action="store_true")
    args = ap.parse_args()
    refine(grid(0.001, False), "7t-qd")  # warm up (compile or load the cache)
    report: dict = {"jit": jit_cost(), "runs": []}
    for size in (float(s) for s in args.sizes.split(",")):
        for shuffled in (False, True):
            mesh = grid(size, shuffled)
            label = f"{mesh.n_triangles / 1e6:.1f}M {'shuffled' if shuffled else 'structured'}"
            for scheme in SCHEMES:
                t = best(lambda s=scheme, mesh=mesh: refine(mesh, s), args.repeat)
                fine = refine(mesh, scheme)
                bound = bandwidth_bound(fine.n_points, fine.n_triangles,
                                        fine.triangles.itemsize, args.repeat)
                row = {"mesh": label, "scheme": scheme, "s": t,
                       "out_triangles": fine.n_triangles,
                       "out_tri_per_s": fine.n_triangles / t, "bandwidth_bound_s": bound,
                       "ratio_to_bound": t / bound,
                       "memory": peak_memory(size, shuffled, scheme)}
                report["runs"].append(row)
                print(f"{label:16} {scheme:7} {t:8.3f} s {row['out_tri_per_s'] / 1e6:8.1f} "
                      f"M tri/s  bound {bound:.3f} s  x{row['ratio_to_bound']:.1f}  "
                      f"peak {row['memory']['peak_over_in_out']:.2f} x (in+out)",
                      flush=True)
            if not shuffled:
                report.setdefault("decision", {})[label] = decision_cost(mesh, args.repeat)
                if not args.no_peers:
                    report.setdefault("peers", {})[label] = peers(
                        mesh, refine(mesh, "7t-qd"), args.repeat)
    report["threads"] = thread_independence(grid(0.05, True))
    print(json.dumps({k: v for k, v in report.items() if k != "runs"}, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1)


if __name__ == "__main__":
    main()
