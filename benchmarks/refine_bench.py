"""Uniform-refinement benchmark (not part of the test suite).

Builds structured and shuffled (random vertex and triangle order) meshes of about 0.2 M and
2 M triangles and reports, as a table and as JSON (``--json FILE``):

* qdrefine uniform refinement per scheme: seconds (best of ``--repeat``), output triangles/s,
  peak resident memory of a fresh process doing only that refinement;
* the time of each pass of 7T-QD refinement (edge numbering, new points, emission, best of
  ``--repeat``), all threads and one thread;
* the cost of the 7T-QD decision versus the exact 7T-D decision per triangle: emission time
  of each 7T scheme minus that of the same tables with no decision (always row 0);
* the memory-bandwidth bound: the time to write the output arrays (points and triangles) to
  fresh memory on this machine, and our time relative to it;
* first-call (compile) and cached-call cost of the kernels in a fresh process;
* thread-count independence: the output hashes with 1 and with all threads;
* a refinement to at least ``--scale`` million output triangles (7T-QD, two levels of a
  structured grid) in a fresh process: time, peak resident memory, bytes per output triangle;
* with ``--baseline SRC``: CPU time of each pass on one thread, this checkout against the
  qdrefine package under ``SRC`` (e.g. an older revision), in fresh processes taking turns;
* peers when installed (``pip install -e '.[bench]'``): scikit-fem ``MeshTri.refined()``
  (uniform, and adaptive with every triangle marked), Triangle's and SciPy's Delaunay of the
  same refined point set;
* the machine's load average before and after (other processes make the times noisy).

Run: ``python benchmarks/refine_bench.py [--sizes 0.2,2] [--scale 100] [--json out.json]``;
``--summarize A.json B.json ...`` prints the tables of ``docs/performance.md`` (best of runs).
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
from qdrefine import Mesh, examples, refine
from qdrefine.kernels import emit, number_edges
from qdrefine.mesh import index_dtype

SCHEMES = qdrefine.scheme_names()


def grid(n_triangles: float, shuffled: bool, seed: int = 0) -> Mesh:
    """:func:`qdrefine.examples.square` with about ``n_triangles`` million triangles;
    ``shuffled``: vertices renumbered and triangles reordered at random."""
    mesh = examples.square(int(round(np.sqrt(n_triangles * 1e6 / 2))))
    if not shuffled:
        return mesh
    rng = np.random.default_rng(seed)
    perm = rng.permutation(mesh.n_points)
    tris = np.argsort(perm)[mesh.triangles]
    return Mesh(mesh.points[perm], tris[rng.permutation(len(tris))])


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
from refine_bench import grid, status
from qdrefine import refine
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


# glibc serves blocks under its mmap threshold (which grows to 32 MiB as big blocks are
# freed) from a heap that stays resident: temporaries could then reuse memory freed before
# the measurement and not show in the peak. A fixed threshold returns every big block.
_MEASURE_ENV = dict(os.environ, MALLOC_MMAP_THRESHOLD_="131072")


def peak_memory(size: float, shuffled: bool, scheme: str) -> dict:
    code = _CHILD.format(bench=os.path.dirname(__file__), size=size, shuffled=shuffled,
                         scheme=scheme)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=_MEASURE_ENV).stdout.split()
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
    """Digests of every scheme's output with 1 and all threads; use a mesh without ties
    (where the schemes differ) of at least ``2 * 65536`` triangles, so that the edge
    numbering splits its work in chunks too."""
    import numba
    out = {}
    for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
        numba.set_num_threads(threads)
        out[threads] = {s: digest(refine(mesh, s)) for s in SCHEMES}
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return {"identical": len({json.dumps(v, sort_keys=True) for v in out.values()}) == 1,
            "digests": out}


def decision_cost(mesh: Mesh, repeat: int) -> dict:
    """Emission time per triangle of each 7T scheme, and of the 7T tables with no decision
    (labelling and writing only); the difference is the cost of the scheme's decision."""
    _, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    out = {}
    buf = np.empty((mesh.n_triangles * 7, 3), dtype=np.int32)
    qd = qdrefine.get_scheme("7t-qd")
    cases = {"none": (np.zeros((0, 3)), np.zeros(1, dtype=np.int8), qd.tables)}
    for name in ("7t-le", "7t-qd", "7t-d"):
        s = qdrefine.get_scheme(name)
        cases[name] = (s.forms, s.lut, s.tables)
    for name, (forms, lut, tables) in cases.items():
        t = best(lambda f=forms, lu=lut, tb=tables: emit(mesh.points, mesh.triangles, tri_edges,
                                                          2, f, lu, tb, buf), repeat)
        out[name] = {"ns_per_triangle": 1e9 * t / mesh.n_triangles, "forms": len(forms)}
    for name in ("7t-le", "7t-qd", "7t-d"):
        out[name]["decision_ns"] = out[name]["ns_per_triangle"] - out["none"]["ns_per_triangle"]
    return out


def passes(mesh: Mesh, repeat: int) -> dict:
    """Seconds of each pass of one 7T-QD level (best of ``repeat``), all threads and one."""
    import numba

    from qdrefine.numbering import bucket_points, sort_edges  # not in the baseline's tree
    sch = qdrefine.get_scheme("7t-qd")
    buckets = sort_edges(mesh.triangles, mesh.n_points)
    n_new = mesh.n_points + 2 * buckets.n_edges
    pts = np.empty((n_new, 2))
    tris = np.empty((mesh.n_triangles * 7, 3), dtype=index_dtype(n_new))
    out = {}
    for threads in sorted({numba.config.NUMBA_NUM_THREADS, 1}, reverse=True):
        numba.set_num_threads(threads)
        out[threads] = {  # the passes of refine (buckets: no global edge list or ids)
            "number_edges": best(lambda: sort_edges(mesh.triangles, mesh.n_points), repeat),
            "edge_points": best(lambda: bucket_points(mesh.points, buckets, 2, pts), repeat),
            "emit": best(lambda: emit(mesh.points, mesh.triangles, buckets.local, 2,
                                      sch.forms, sch.lut, sch.tables, tris, buckets), repeat),
            "refine": best(lambda: refine(mesh, sch), repeat),
        }
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return out


_SCALE = """
import sys, time
sys.path.insert(0, {bench!r})
from refine_bench import grid, status
from qdrefine import refine
mesh = grid({size}, False)
refine(grid(0.001, False), "7t-qd", levels=2)
open("/proc/self/clear_refs", "w").write("5")
base = status("VmRSS")
t0 = time.perf_counter()
fine = refine(mesh, "7t-qd", levels=2)
t = time.perf_counter() - t0
peak = status("VmHWM")
inp = mesh.points.nbytes + mesh.triangles.nbytes
print(t, base, peak, inp, fine.points.nbytes + fine.triangles.nbytes, fine.n_triangles,
      mesh.n_triangles)
"""


def status(key: str) -> int:
    """A field of ``/proc/self/status`` in bytes."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key):
                return int(line.split()[1]) * 1024
    raise KeyError(key)


def scale_run(out_millions: float) -> dict:
    """Two 7T-QD levels of a structured grid with ``>= out_millions`` M output triangles,
    in a fresh process: seconds, peak resident memory and bytes per output triangle."""
    size = out_millions / 49 * 1.01  # input M triangles (n^2 rounding)
    code = _SCALE.format(bench=os.path.dirname(os.path.abspath(__file__)), size=size)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=_MEASURE_ENV).stdout.split()
    t, base, peak, inp, outp, n_out, n_in = (float(v) for v in out)
    return {"levels": 2, "input_triangles": int(n_in), "out_triangles": int(n_out), "s": t,
            "out_tri_per_s": n_out / t, "rss_before": int(base), "rss_peak": int(peak),
            "input_bytes": int(inp), "output_bytes": int(outp),
            "peak_over_in_out": (peak - base + inp) / (inp + outp),
            "bytes_per_output_triangle": (peak - base + inp) / n_out}


_PROFILE = """
import json, sys, time
import numpy as np
import numba
numba.set_num_threads(1)
sys.path.insert(0, {bench!r})
from refine_bench import grid
import qdrefine
from qdrefine import refine
from qdrefine.kernels import number_edges, edge_points, emit
def best(f):
    w = []
    for _ in range({repeat}):
        t0 = time.process_time(); f(); w.append(time.process_time() - t0)
    return min(w)
refine(grid(0.001, False), "7t-qd")
out = {{}}
for shuffled in (False, True):
    mesh = grid({size}, shuffled)
    tri, n, m = mesh.triangles, mesh.n_points, mesh.n_triangles
    edges, te, _ = number_edges(tri, n)
    pts = np.empty((n + 2 * len(edges), 2))
    r = {{"number_edges": best(lambda: number_edges(tri, n)),
         "edge_points": best(lambda: edge_points(mesh.points, edges, 2, pts))}}
    for s in ("7t-qd", "7t-le", "7t-d", "4t-red"):
        sch = qdrefine.get_scheme(s)
        o = np.empty((m * sch.n_children, 3), dtype=np.int32)
        r["emit " + s] = best(lambda: emit(mesh.points, tri, te, sch.stencil.per_edge,
                                           sch.forms, sch.lut, sch.tables, o))
    r["refine 7t-qd"] = best(lambda: refine(mesh, "7t-qd"))
    out["shuffled" if shuffled else "structured"] = {{k: v * 1e9 / m for k, v in r.items()}}
print(json.dumps(out))
"""


def baseline_comparison(baseline_src: str, size: float, repeat: int, rounds: int) -> dict:
    """CPU ns per input triangle of each pass, one thread, for this checkout's ``src`` and
    ``baseline_src`` (e.g. ``git archive <rev> src | tar -x -C /tmp/base``: ``/tmp/base/src``),
    in fresh processes taking turns (``rounds`` each); the minimum over rounds and repeats.
    CPU time of one thread is far less sensitive to other processes than wall time."""
    here = os.path.dirname(os.path.abspath(__file__))
    trees = {"this": os.path.join(here, os.pardir, "src"), "baseline": baseline_src}
    code = _PROFILE.format(bench=here, repeat=repeat, size=size)
    runs: dict = {name: [] for name in trees}
    for _ in range(rounds):
        for name, src in trees.items():
            env = dict(os.environ, PYTHONPATH=os.path.abspath(src))
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                 text=True, check=True).stdout
            runs[name].append(json.loads(out))
    result = {}
    for name, rows in runs.items():
        result[name] = {mesh: {k: min(r[mesh][k] for r in rows) for k in rows[0][mesh]}
                        for mesh in rows[0]}
    return {"input_M_triangles": size, "ns_per_triangle_cpu_1_thread": result}


def peers(mesh: Mesh, fine: Mesh, repeat: int) -> dict:
    """Peers on the same input (scikit-fem) or the same refined point set (Delaunay); the
    throughput counts the triangles each one outputs."""
    res: dict = {}
    try:
        import skfem
        m = skfem.MeshTri(mesh.points.T.copy(), mesh.triangles.T.astype(np.int64).copy())
        t = best(lambda: m.refined(), repeat)
        res["scikit-fem refined()"] = {"s": t, "out_tri_per_s": 4 * mesh.n_triangles / t}
        t = best(lambda: m.refined(np.arange(m.t.shape[1])), 1)
        res["scikit-fem refined(all marked)"] = {"s": t,
                                                 "out_tri_per_s": 4 * mesh.n_triangles / t}
    except ImportError:
        res["scikit-fem refined()"] = "not installed"
    try:
        import triangle
        t0 = time.perf_counter()
        n_out = len(triangle.triangulate({"vertices": fine.points.copy()})["triangles"])
        t = time.perf_counter() - t0
        res["Triangle Delaunay"] = {"s": t, "out_tri_per_s": n_out / t}
    except ImportError:
        res["Triangle Delaunay"] = "not installed"
    try:
        from scipy.spatial import Delaunay
        if fine.n_points > 2e6:
            raise ImportError  # minutes of Qhull time; measured on the small mesh only
        t0 = time.perf_counter()
        n_out = len(Delaunay(fine.points).simplices)
        t = time.perf_counter() - t0
        res["SciPy Delaunay"] = {"s": t, "out_tri_per_s": n_out / t}
    except ImportError:
        res["SciPy Delaunay"] = "not installed (or skipped above 2 M points)"
    return res


def summarize(paths: list[str]) -> str:
    """Markdown tables of several runs' JSON files: each figure is the best over the runs
    (shortest time), with the range over the runs in parentheses."""
    reports = [json.load(open(p)) for p in paths]

    def cell(values: list[float], fmt: str, best=max) -> str:
        b = best(values)
        return f"{b:{fmt}}" + (f" ({min(values):{fmt}}-{max(values):{fmt}})"
                               if len(values) > 1 else "")

    lines = ["| input | " + " | ".join(SCHEMES) + " |", "|---|" + "---|" * len(SCHEMES)]
    meshes = list(dict.fromkeys(r["mesh"] for r in reports[0]["runs"]))
    for m in meshes:
        row = []
        for s in SCHEMES:
            v = [next(r["out_tri_per_s"] for r in rep["runs"]
                      if r["mesh"] == m and r["scheme"] == s) / 1e6 for rep in reports]
            row.append(cell(v, ".1f"))
        lines.append(f"| {m} | " + " | ".join(row) + " |")
    lines += ["", "| input | 7t-qd s | bound s | time / bound | peak / (in+out), 7T-QD | "
              "peak / (in+out), 4T-red |", "|---|---|---|---|---|---|"]
    for m in meshes:
        qd = [next(r for r in rep["runs"] if r["mesh"] == m and r["scheme"] == "7t-qd")
              for rep in reports]
        red = [next(r for r in rep["runs"] if r["mesh"] == m and r["scheme"] == "4t-red")
               for rep in reports]
        lines.append(f"| {m} | {cell([r['s'] for r in qd], '.3f', min)} | "
                     f"{cell([r['bandwidth_bound_s'] for r in qd], '.3f', min)} | "
                     f"{cell([r['ratio_to_bound'] for r in qd], '.1f', min)} | "
                     f"{cell([r['memory']['peak_over_in_out'] for r in qd], '.2f', min)} | "
                     f"{cell([r['memory']['peak_over_in_out'] for r in red], '.2f', min)} |")
    lines += ["", "| input | threads | number_edges | edge_points | emit (7t-qd) | refine |",
              "|---|---|---|---|---|---|"]
    for m in reports[0]["passes"]:
        for t in reports[0]["passes"][m]:
            row = [cell([1e3 * rep["passes"][m][t][k] for rep in reports], ".0f", min)
                   for k in ("number_edges", "edge_points", "emit", "refine")]
            lines.append(f"| {m} | {t} | " + " ms | ".join(row) + " ms |")
    lines += ["", "| input | no decision | 7t-le | 7t-qd | 7t-d |", "|---|---|---|---|---|"]
    for m in reports[0]["decision"]:
        row = [cell([rep["decision"][m][k]["ns_per_triangle"] for rep in reports], ".0f", min)
               for k in ("none", "7t-le", "7t-qd", "7t-d")]
        lines.append(f"| {m} | " + " ns | ".join(row) + " ns |")
    lines += ["", "| input | peer | output triangles/s |", "|---|---|---|"]
    for m in reports[0].get("peers", {}):
        for k, v in reports[0]["peers"][m].items():
            if isinstance(v, dict):
                vals = [rep["peers"][m][k]["out_tri_per_s"] / 1e6 for rep in reports]
                lines.append(f"| {m} | {k} | {cell(vals, '.2f')} M/s |")
    base = [rep["baseline"]["ns_per_triangle_cpu_1_thread"] for rep in reports
            if "baseline" in rep]
    if base:
        lines += ["", "| input | pass | baseline | this | speed-up |", "|---|---|---|---|---|"]
        for m in base[0]["this"]:
            for k in base[0]["this"][m]:
                old = [b["baseline"][m][k] for b in base]
                new = [b["this"][m][k] for b in base]
                lines.append(f"| {m} | {k} | {cell(old, '.0f', min)} ns | "
                             f"{cell(new, '.0f', min)} ns | {min(old) / min(new):.1f}x |")
    lines += ["", "| run | JIT first call | cached call | scale run | peak RSS | peak / (in+out) "
              "| bytes / output triangle | load average before, after |",
              "|---|---|---|---|---|---|---|---|"]
    for p, rep in zip(paths, reports, strict=True):
        sc = rep.get("scale", {})
        scale = (f"{sc['out_triangles'] / 1e6:.0f} M in {sc['s']:.2f} s" if sc else "-")
        peak = f"{sc['rss_peak'] / 2**30:.2f} GiB" if sc else "-"
        lines.append(f"| {os.path.basename(p)} | {rep['jit']['first_call_s']:.1f} s | "
                     f"{rep['jit']['cached_call_s']:.2f} s | {scale} | {peak} | "
                     f"{sc.get('peak_over_in_out', 0):.2f} | "
                     f"{sc.get('bytes_per_output_triangle', 0):.1f} | "
                     f"{rep['load_average_before'][0]:.1f}, {rep['load_average_after'][0]:.1f} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="0.2,2", help="input sizes in millions of triangles")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--scale", type=float, default=100.0,
                    help="million output triangles of the scale run (0: skip)")
    ap.add_argument("--json", help="write the results to this JSON file")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--baseline", metavar="SRC",
                    help="also compare per-pass CPU time with the qdrefine package under SRC")
    ap.add_argument("--rounds", type=int, default=3, help="turns of the baseline comparison")
    ap.add_argument("--summarize", nargs="+", metavar="JSON",
                    help="only print markdown tables of these result files (best of runs)")
    args = ap.parse_args()
    if args.summarize:
        print(summarize(args.summarize))
        return
    refine(grid(0.001, False), "7t-qd")  # warm up (compile or load the cache)
    report: dict = {"load_average_before": os.getloadavg(), "jit": jit_cost(), "runs": []}
    sizes = [float(s) for s in args.sizes.split(",")]
    for size in sizes:
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
            report.setdefault("passes", {})[label] = passes(mesh, args.repeat)
            if not shuffled:
                report.setdefault("decision", {})[label] = decision_cost(mesh, args.repeat)
                if not args.no_peers:
                    report.setdefault("peers", {})[label] = peers(
                        mesh, refine(mesh, "7t-qd"), args.repeat)
    report["threads"] = thread_independence(examples.jittered_square(316))  # 0.2 M
    if args.scale > 0:
        report["scale"] = scale_run(args.scale)
    if args.baseline:
        report["baseline"] = baseline_comparison(args.baseline, max(sizes), args.repeat,
                                                 args.rounds)
    report["load_average_after"] = os.getloadavg()
    print(json.dumps({k: v for k, v in report.items() if k != "runs"}, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1)


if __name__ == "__main__":
    main()
