"""Validation benchmark (not part of the test suite): what building a ``Mesh`` from arrays
costs next to refining it, against scikit-fem, and on hostile input.

Reports, as a table and as JSON (``--json FILE``):

* on the 2 M-triangle benchmark mesh of ``refine_bench.py`` (structured grid, and shuffled):
  ``Mesh(p, t)``, one 7T-QD level of an already built mesh (``refine(mesh)``, which numbers
  its edges itself) and ``refine(Mesh(p, t))`` (which reuses the validation's sorted
  edges), taken in turn, best of ``--repeat`` rounds, wall and CPU time, all threads and one
  thread; the ratio of the last to the second is issue 16's "at most 1.3x";
* in the same run, a fresh ``skfem.MeshTri(p, t).refined()`` and the ratio of output
  triangles per second, ``refine(Mesh(p, t))`` over scikit-fem's (issue 16: "at least 40x");
* adversarial soups of ``--soup`` triangles (issue 17: "under 5 s"): ``stacked``, separate
  long slivers whose bounding boxes all overlap (valid: the sweep runs to the end);
  ``slivers`` and ``scattered``, random separate triangles that overlap (refused at the
  first crossing); ``grid``, separate small triangles one per cell (valid): the time of
  ``Mesh(p, t)`` (or of its refusal) and of ``check.find`` (every problem), and the number of
  orientation tests of the sweep over ``B log2 B`` at a tenth and at the full size;
* near-duplicate points: the cell grid of ``check.near_duplicates`` against SciPy's
  ``cKDTree.query_pairs`` on 1 M points, some of them clustered (CPU seconds);
* the load average before and after (the development machine is shared: times are noisy).

Run: ``python benchmarks/validation_bench.py [--repeat 5] [--soup 300000] [--json out.json]``;
``--summarize A.json B.json`` prints the table of ``docs/performance.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numba
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from refine_bench import grid  # noqa: E402

from qdrefine import Mesh, check, refine  # noqa: E402
from qdrefine.predicates import orient_signs  # noqa: E402
from qdrefine.sweep import sweep  # noqa: E402


def best(f, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def timed(f) -> tuple[float, float]:
    """Wall and CPU seconds (CPU: all threads of the process) of one call."""
    c0, t0 = time.process_time(), time.perf_counter()
    f()
    return time.perf_counter() - t0, time.process_time() - c0


def construction(mesh: Mesh, repeat: int) -> dict:
    """The three timings taken in turn, ``repeat`` rounds, best of each (wall and CPU):
    on a shared machine a burst of load then hits all three alike."""
    p, t = np.array(mesh.points), np.array(mesh.triangles)
    out = {}
    for threads in (numba.config.NUMBA_NUM_THREADS, 1):
        numba.set_num_threads(threads)
        refine(Mesh(p, t))  # warm (compiled, caches)
        runs = {"refine": [], "mesh": [], "mesh_and_refine": []}
        for _ in range(repeat):
            runs["refine"].append(timed(lambda: refine(mesh)))
            runs["mesh"].append(timed(lambda: Mesh(p, t)))
            runs["mesh_and_refine"].append(timed(lambda: refine(Mesh(p, t))))
        row = {}
        for k, v in runs.items():
            row[f"{k}_s"] = min(w for w, _ in v)
            row[f"{k}_cpu_s"] = min(c for _, c in v)
        row["ratio"] = row["mesh_and_refine_s"] / row["refine_s"]
        row["ratio_cpu"] = row["mesh_and_refine_cpu_s"] / row["refine_cpu_s"]
        row["out_tri_per_s"] = 7 * mesh.n_triangles / row["mesh_and_refine_s"]
        out[f"{threads}_threads"] = row
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return out


def scikit_fem(mesh: Mesh, ours: float, repeat: int) -> dict:
    try:
        import skfem
    except ImportError:
        return {"scikit-fem": "not installed"}
    p, t = np.array(mesh.points), np.array(mesh.triangles)
    pt, tt = p.T.copy(), t.T.astype(np.int64).copy()
    s = best(lambda: skfem.MeshTri(pt, tt).refined(), max(1, repeat // 2))
    theirs = 4 * mesh.n_triangles / s
    return {"skfem_fresh_refined_s": s, "skfem_out_tri_per_s": theirs,
            "qdrefine_out_tri_per_s": ours, "ratio": ours / theirs}


def soup(kind: str, m: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``m`` separate triangles (3 points each), counter-clockwise."""
    rng = np.random.default_rng(seed)
    if kind == "stacked":  # long parallel slivers: every bounding box overlaps every other
        y = np.arange(m) * 1e-5
        tri = np.stack([np.stack([np.zeros(m), y], 1), np.stack([np.ones(m), y + 1], 1),
                        np.stack([np.full(m, 0.5), y + 0.5 + 1e-6], 1)], 1)
    elif kind == "slivers":  # random long slivers across the unit square
        a, b = rng.random((m, 2)), rng.random((m, 2))
        tri = np.stack([a, b, (a + b) / 2 + rng.normal(size=(m, 2)) * 1e-7], 1)
    elif kind == "scattered":  # small random triangles, overlapping here and there
        tri = rng.random((m, 1, 2)) + rng.random((m, 3, 2)) * 1e-3
    else:  # "grid": one small triangle per cell of a grid, none touching
        k = int(np.ceil(np.sqrt(m)))
        cell = np.stack(np.divmod(np.arange(m), k), 1).astype(float)
        tri = cell[:, None, :] + 0.1 + rng.random((m, 3, 2)) * 0.8
    p = tri.reshape(-1, 2)
    t = np.arange(3 * m).reshape(m, 3)
    s = orient_signs(p, t)
    t[s < 0] = t[s < 0][:, ::-1]
    return p, t[s != 0]


def soups(m: int) -> dict:
    out = {}
    for kind in ("stacked", "slivers", "scattered", "grid"):
        row: dict = {}
        for size in (m // 10, m):
            p, t = soup(kind, size)
            c0, t0 = time.process_time(), time.perf_counter()
            try:
                Mesh(p, t)
                verdict = "valid"
            except ValueError as exc:
                verdict = str(exc)[:100]
            build, build_cpu = time.perf_counter() - t0, time.process_time() - c0
            t0 = time.perf_counter()
            found = check.find(p, t)
            full = time.perf_counter() - t0
            bedges = t[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
            work = sweep(p, bedges, True, False)[-1]
            b = len(bedges)
            row[str(len(t))] = {"mesh_s": build, "mesh_cpu_s": build_cpu,
                                "check_find_s": full, "mesh": verdict,
                                "kinds": sorted({x.kind for x in found.problems}),
                                "sweep_tests_per_B_log2_B": work / (b * np.log2(b))}
        out[kind] = row
    return out


def near_duplicates_vs_scipy(n: int = 1_000_000) -> dict:
    """CPU seconds of ``check.near_duplicates`` (cell grid) and of SciPy's
    ``cKDTree(q).query_pairs(tol)`` on ``n`` random points, with ``k`` of them clustered
    within ``tol``: the pairs (and SciPy's time and memory) grow as ``k^2``."""
    try:
        from scipy.spatial import cKDTree
    except ImportError:
        return {"scipy": "not installed"}
    rng = np.random.default_rng(0)
    check.near_duplicates(rng.random((100, 2)), 1e-12)  # compiled
    out = {}
    for k in (0, 2000, 8000):
        q = rng.random((n, 2))
        q[:k] = 0.5 + rng.random((k, 2)) * 1e-13
        c0 = time.process_time()
        ours = check.near_duplicates(q, 1e-12)[0]
        c1 = time.process_time()
        pairs = len(cKDTree(q).query_pairs(1e-12, output_type="ndarray"))
        c2 = time.process_time()
        out[f"{n}_points_{k}_clustered"] = {"grid_cpu_s": c1 - c0, "ckdtree_cpu_s": c2 - c1,
                                            "near_points": int(ours), "ckdtree_pairs": pairs}
    return out


def summarize(paths: list[str]) -> str:
    """Markdown tables of several runs' JSON files, one column per run."""
    runs = [json.load(open(p)) for p in paths]
    names = [os.path.basename(p) for p in paths]
    w = ["| | " + " | ".join(names) + " |", "|---" * (len(runs) + 1) + "|",
         "| load average before / after | " + " | ".join(
             f"{r['load_before'][0]:.1f} / {r['load_after'][0]:.1f}" for r in runs) + " |"]
    for mesh in [k for k in runs[0] if k.startswith(("grid_", "shuffled_"))]:
        for th in [k for k in runs[0][mesh] if k.endswith("_threads")]:
            def cell(r, m=mesh, t=th):
                if m not in r:
                    return "-"
                x = r[m][t]
                return (f"{x['refine_s']:.3f} / {x['mesh_s']:.3f} / "
                        f"{x['mesh_and_refine_s']:.3f} s: **{x['ratio']:.2f}x** "
                        f"(CPU {x['ratio_cpu']:.2f}x)")
            w.append(f"| {mesh}, {th.replace('_', ' ')}: refine / Mesh / refine(Mesh) | "
                     + " | ".join(cell(r) for r in runs) + " |")
        w.append(f"| {mesh}: refine(Mesh(p, t)) vs fresh skfem MeshTri(p, t).refined() | "
                 + " | ".join(
                     f"{r[mesh]['scikit-fem']['qdrefine_out_tri_per_s'] / 1e6:.1f} vs "
                     f"{r[mesh]['scikit-fem']['skfem_out_tri_per_s'] / 1e6:.2f} M/s: "
                     f"**{r[mesh]['scikit-fem']['ratio']:.1f}x**" if mesh in r else "-"
                     for r in runs) + " |")
    for kind in runs[0]["soups"]:
        for size in runs[0]["soups"][kind]:
            w.append(f"| soup `{kind}` {int(size):,}: Mesh wall (CPU) s, check.find s | "
                     + " | ".join(
                         f"{r['soups'][kind][size]['mesh_s']:.2f} "
                         f"({r['soups'][kind][size].get('mesh_cpu_s', float('nan')):.2f}), "
                         f"{r['soups'][kind][size]['check_find_s']:.2f}" for r in runs) + " |")
    for key in runs[-1].get("near_duplicates", {}):
        w.append(f"| near duplicates, {key.replace('_', ' ')}: grid vs cKDTree CPU s | "
                 + " | ".join(
                     (f"{r['near_duplicates'][key]['grid_cpu_s']:.2f} vs "
                      f"{r['near_duplicates'][key]['ckdtree_cpu_s']:.2f} "
                      f"({r['near_duplicates'][key]['ckdtree_pairs']:,} pairs)")
                     if key in r.get("near_duplicates", {}) else "-" for r in runs) + " |")
    return "\n".join(w)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--summarize", nargs="+", metavar="JSON",
                    help="print the tables of docs/performance.md from these runs, run nothing")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--size", type=float, default=2.0, help="million triangles (default 2)")
    ap.add_argument("--soup", type=int, default=300_000)
    ap.add_argument("--no-shuffled", action="store_true", help="the structured mesh only")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()
    if args.summarize:
        print(summarize(args.summarize))
        return
    res: dict = {"load_before": os.getloadavg(), "threads": numba.config.NUMBA_NUM_THREADS}
    for shuffled in (False,) if args.no_shuffled else (False, True):
        mesh = grid(args.size, shuffled)
        name = f"{'shuffled' if shuffled else 'grid'}_{mesh.n_triangles}"
        res[name] = construction(mesh, args.repeat)
        ours = res[name][f"{numba.config.NUMBA_NUM_THREADS}_threads"]["out_tri_per_s"]
        res[name]["scikit-fem"] = scikit_fem(mesh, ours, args.repeat)
    res["soups"] = soups(args.soup)
    res["near_duplicates"] = near_duplicates_vs_scipy()
    res["load_after"] = os.getloadavg()
    print(json.dumps(res, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
