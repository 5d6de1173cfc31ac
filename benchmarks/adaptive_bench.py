"""Cost of one adaptive step on a large Gmsh mesh, against uniform refinement of the same
mesh and scikit-fem's ``MeshTri.refined(marked)``, in the same run.

The mesh is Gmsh's Frontal-Delaunay mesh of the L-shape ``[-1, 1]^2 minus (0, 1]^2`` with
about 0.9 M triangles (made with the Gmsh SDK, ``pip install gmsh``, cached under
``benchmarks/.cache/``). Two markings of 1% of the triangles:

* ``clustered``: the 1% nearest the re-entrant corner (what an error estimator marks on a
  singular problem);
* ``scattered``: 1% picked by :func:`qdrefine.marking.mark_random` all over the mesh (the
  worst case for locality: every mark needs its own closure and transitions);
* ``scattered, second cycle``: 1% picked again (another seed) on the output of the
  scattered step, which carries its transitions (the natural loop's second call): marks
  on transition children coarsen and redo their families. Its uniform level and
  scikit-fem's refinement are of that mesh.

Then the natural loop on this mesh, ``--cycles`` calls of ``mesh = refine(mesh,
marked=...)`` with the 1% of the current mesh nearest the re-entrant corner marked (each
cycle's input carries the transitions of the one before), each cycle's step against a
uniform level of its input and scikit-fem's ``refined`` of the same marks on the same
triangles. Then ``qdrefine.coarsen`` of the scattered step's output, everything marked
(the input comes back) and the half ``x < 0``. Each time is the best of ``--repeat``
calls in alternating blocks with the uniform level it is compared with
(:func:`step_and_uniform`; numba on all threads). Usage::

    python benchmarks/adaptive_bench.py [--repeat 3] [--json benchmarks/results/F.json]
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

import qdrefine
from qdrefine import examples
from qdrefine.marking import mark_box, mark_random

CACHE = Path(__file__).parent / ".cache" / "l_shape_900k.npz"


def big_l_shape() -> qdrefine.Mesh:
    if not CACHE.exists():
        import gmsh

        gmsh.initialize(interruptible=False)
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("l")
        g = gmsh.model.geo
        h = 0.25 * np.sqrt(126 / 980000)
        pts = [g.addPoint(x, y, 0, h) for x, y in
               [(-1, -1), (1, -1), (1, 0), (0, 0), (0, 1), (-1, 1)]]
        lines = [g.addLine(pts[i], pts[(i + 1) % 6]) for i in range(6)]
        g.addPlaneSurface([g.addCurveLoop(lines)])
        g.synchronize()
        gmsh.model.mesh.generate(2)
        _, coords, _ = gmsh.model.mesh.getNodes()
        _, _, nodes = gmsh.model.mesh.getElements(2)
        gmsh.finalize()
        CACHE.parent.mkdir(exist_ok=True)
        np.savez(CACHE, points=coords.reshape(-1, 3)[:, :2],
                 triangles=nodes[0].reshape(-1, 3).astype(np.int64) - 1)
    data = np.load(CACHE)
    return qdrefine.Mesh(data["points"], data["triangles"])


def best(f, repeat):
    t_best, out = np.inf, None
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        t_best = min(t_best, time.perf_counter() - t)
    return t_best, out


#: Blocks of each timing in :func:`step_and_uniform` (alternated).
ROUNDS = 2


def step_and_uniform(step, uniform, repeat):
    """Best times of ``step()`` and ``uniform()`` (and the step's output), timed in
    alternating blocks of ``repeat`` calls, ``ROUNDS`` blocks each, so that both see the
    same minutes of this shared machine and each block can warm up after the other. The
    first uniform levels of a process, or those right after a step, often run 2 to 3
    times slower than the later ones (0.25-0.41 s against 0.10-0.13 s on the 864k mesh,
    in informal runs; the cause is not established: turning off NumPy's huge pages,
    ``NUMPY_MADVISE_HUGEPAGE=0``, removed it in one run and not in another), and a best
    of 3 taken once at the start of the run had given the steps a flattering baseline."""
    t_step = t_uniform = np.inf
    out = None
    for _ in range(ROUNDS):
        t_uniform = min(t_uniform, best(uniform, repeat)[0])
        t, out = best(step, repeat)
        t_step = min(t_step, t)
    return t_step, out, t_uniform


def _estimate(mesh: qdrefine.Mesh, marked: np.ndarray) -> dict:
    """Triangles in the estimate a window starts from (``adaptive/reach.py``) and triangles
    the step changes (not copied as they were), and how many of these the estimate
    misses."""
    from qdrefine.adaptive.reach import reached_triangles
    from qdrefine.adaptive.window import vertex_triangles
    from qdrefine.refine import refine_with_parents
    from qdrefine.schemes import get_scheme

    out, parents = refine_with_parents(mesh, "7t-qd", marked=marked)
    count = np.bincount(parents, minlength=mesh.n_triangles)
    rows = np.searchsorted(parents, np.arange(mesh.n_triangles))
    same = (count == 1) & (out.triangles[np.minimum(rows, out.n_triangles - 1)]
                           == mesh.triangles).all(axis=1)
    start, tris_of = vertex_triangles(mesh.triangles, mesh.n_points)
    reached, _ = reached_triangles(mesh, marked, get_scheme("7t-qd"), start, tris_of)
    return {"estimate_triangles": int(reached.sum()), "changed_triangles": int((~same).sum()),
            "changed_outside_estimate": int((~same & ~reached).sum())}


def nearest_corner(mesh: qdrefine.Mesh, fraction: float = 0.01) -> np.ndarray:
    """``(M,) bool``: the ``fraction`` of the triangles whose centroids are nearest the
    re-entrant corner ``(0, 0)`` (what an error estimator marks on a singular problem)."""
    centroids = mesh.points[mesh.triangles].mean(axis=1)
    marked = np.zeros(mesh.n_triangles, dtype=bool)
    k = int(fraction * mesh.n_triangles)
    marked[np.argsort(np.linalg.norm(centroids, axis=1), kind="stable")[:k]] = True
    return marked


def _clustered_loop(mesh: qdrefine.Mesh, cycles: int, repeat: int) -> list[dict]:
    """``cycles`` calls of ``mesh = refine(mesh, marked=nearest_corner(mesh))``, each
    step against a uniform level of its input (:func:`step_and_uniform`) and scikit-fem's
    ``refined`` of the same marks on the same triangles (best of ``repeat``; without the
    history, which scikit-fem does not have)."""
    import skfem

    rows = []
    for cycle in range(1, cycles + 1):
        marked = nearest_corner(mesh)
        t_step, out, t_base = step_and_uniform(
            lambda b=mesh, m=marked: qdrefine.refine(b, "7t-qd", marked=m),
            lambda b=mesh: qdrefine.refine(b, "7t-qd"), repeat)
        sk = skfem.MeshTri(np.ascontiguousarray(mesh.points.T),
                           np.ascontiguousarray(mesh.triangles.T, dtype=np.int64))
        ids = np.flatnonzero(marked)
        t_sk = best(lambda s=sk, i=ids: s.refined(i), repeat)[0]
        green = 0 if mesh.transitions is None else int((mesh.transitions[:, 0] >= 0).sum())
        row = {"cycle": cycle, "triangles": mesh.n_triangles,
               "transition_children": green, "marked": int(marked.sum()),
               "added": out.n_triangles - mesh.n_triangles, "step_seconds": t_step,
               "uniform_seconds": t_base, "step_over_uniform": t_step / t_base,
               "scikit_fem_seconds": t_sk, "scikit_fem_over_step": t_sk / t_step}
        rows.append(row)
        print(f"clustered loop, cycle {cycle}: {mesh.n_triangles} triangles ({green} "
              f"transition children), {row['marked']} marked, step {t_step:.3f} s "
              f"({row['step_over_uniform']:.2f} x uniform), scikit-fem {t_sk:.3f} s "
              f"({row['scikit_fem_over_step']:.1f} x the step)")
        mesh = out
    return rows


def _coarsening(mesh: qdrefine.Mesh, fine: qdrefine.Mesh, repeat: int) -> dict:
    """``qdrefine.coarsen`` of the scattered step's output ``fine``: everything marked
    (back to ``mesh``, checked) and the half ``x < 0``, against a uniform level of
    ``fine``."""
    rows = {}
    for name, marked in (("everything", np.ones(fine.n_triangles, dtype=bool)),
                         ("x < 0", mark_box(fine, (-1, -1, 0, 1)))):
        t, out, t_base = step_and_uniform(lambda m=marked: qdrefine.coarsen(fine, m),
                                          lambda: qdrefine.refine(fine, "7t-qd"), repeat)
        if name == "everything" and not (np.array_equal(out.points, mesh.points)
                                         and out.n_triangles == mesh.n_triangles):
            raise RuntimeError("coarsening everything did not give the input back")
        rows[name] = {"triangles": fine.n_triangles, "output_triangles": out.n_triangles,
                      "seconds": t, "uniform_seconds": t_base, "over_uniform": t / t_base}
        print(f"coarsening {name}: {fine.n_triangles} -> {out.n_triangles} triangles in "
              f"{t:.3f} s ({t / t_base:.1f} x a uniform level of that mesh)")
    return rows


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--cycles", type=int, default=6,
                        help="cycles of the clustered loop (0: none)")
    args = parser.parse_args(argv)
    import skfem

    mesh = big_l_shape()
    clustered = nearest_corner(mesh)
    scattered = mark_random(mesh, 0.01)
    second = qdrefine.refine(mesh, "7t-qd", marked=scattered)
    cases = {"clustered": (mesh, clustered), "scattered": (mesh, scattered),
             "scattered, second cycle": (second, mark_random(second, 0.01, seed=1))}
    qdrefine.refine(examples.square(2), marked=[0])  # compile outside the timings
    fine = qdrefine.refine(mesh, "7t-qd")
    result = {"date": datetime.date.today().isoformat(), "machine": platform.platform(),
              "cpus": os.cpu_count(), "load_average": os.getloadavg(),
              "triangles": mesh.n_triangles, "uniform_output_triangles": fine.n_triangles,
              "timing": f"best of {args.repeat} calls in {ROUNDS} alternating blocks "
                        "(step_and_uniform)", "cases": {}}
    del fine
    print(f"mesh: {mesh.n_triangles} triangles")
    for name, (base, marked) in cases.items():
        t_step, out, t_base = step_and_uniform(
            lambda b=base, m=marked: qdrefine.refine(b, "7t-qd", marked=m),
            lambda b=base: qdrefine.refine(b, "7t-qd"), args.repeat)
        sk = skfem.MeshTri(np.ascontiguousarray(base.points.T),
                           np.ascontiguousarray(base.triangles.T, dtype=np.int64))
        ids = np.flatnonzero(marked)
        t_sk, sk_out = best(lambda s=sk, i=ids: s.refined(i), args.repeat)
        row = {"triangles": base.n_triangles, "marked": int(marked.sum()),
               "step_seconds": t_step, "added": out.n_triangles - base.n_triangles,
               "uniform_seconds": t_base, "step_over_uniform": t_step / t_base,
               "scikit_fem_seconds": t_sk,
               "scikit_fem_added": int(sk_out.t.shape[1] - base.n_triangles),
               "scikit_fem_over_step": t_sk / t_step}
        if base.transitions is None:  # the window's starting estimate against the step
            row.update(_estimate(base, marked))
        result["cases"][name] = row
        print(f"{name}: {row['triangles']} triangles, {row['marked']} marked, step "
              f"{t_step:.3f} s "
              f"({row['step_over_uniform']:.2f} x uniform), scikit-fem {t_sk:.3f} s "
              f"({row['scikit_fem_over_step']:.1f} x the step)")
        if "estimate_triangles" in row:
            print(f"  window estimate {row['estimate_triangles']} triangles, the step changes "
                  f"{row['changed_triangles']} ({row['changed_outside_estimate']} outside it)")
    result["clustered_loop"] = _clustered_loop(mesh, args.cycles, args.repeat)
    result["coarsening"] = _coarsening(mesh, second, args.repeat)
    path = args.json or (Path(__file__).parent / "results"
                         / f"adaptive-bench-{result['date']}.json")
    path.write_text(json.dumps(result, indent=1))
    print("wrote", path)


if __name__ == "__main__":
    main()
