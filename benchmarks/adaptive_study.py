"""Adaptive refinement study on Gmsh-made meshes: the natural loop
``mesh = qdrefine.refine(mesh, marked=...)`` cycle after cycle, against scikit-fem.

Parts (each writes its results into one JSON file and figures under ``docs/img/``):

* ``afem``: the singular Poisson problem on the Gmsh L-shape (:mod:`qdrefine.afem`):
  solve (scikit-fem P1), estimate (residual indicator), Doerfler 0.5, refine; 7T-QD, 7T-LE,
  4T-LE and scikit-fem's ``MeshTri.refined(marked)``. Energy error against DOFs, its rate
  over the last six cycles, the error at 10,000 DOFs, the smallest angle per cycle and the
  triangles added per marked triangle.
* ``loops``: the same natural loop with the residual indicator of ``-Laplace u = 1``,
  ``u = 0`` on the boundary, Doerfler 0.3 (the solution is smooth away from corners, so 0.5
  marks nearly everything), on the Gmsh plate with a hole, backward-facing step and graded
  square and boundary-layer channel (the L-shape is the ``afem`` part), and with Doerfler
  0.5 (which marks 12-25% of the triangles per cycle, so the runs stop at 400,000
  triangles) on the plate and the step: the smallest angle per cycle over the initial
  one, the median of the triangles added per marked one.
* ``bounds``: the worst child/parent angle ratio of every transition pattern over the
  mapping diagram, and the computed bound of :func:`qdrefine.adaptive.bounds.quality_bound`
  on each Gmsh example mesh.
* ``history``: what keeping the history in the mesh buys: the L-shape AFEM loop with the
  history dropped every cycle (``mesh.replace(transitions=None)``, the previous behaviour).

Usage::

    python benchmarks/adaptive_study.py [--cycles 12] [--parts afem,loops,history,bounds]
    python benchmarks/adaptive_study.py --plot-only benchmarks/results/adaptive-DATE.json
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import qdrefine  # noqa: E402
from qdrefine import afem, examples  # noqa: E402
from qdrefine.marking import mark_dorfler  # noqa: E402
from qdrefine.quality import min_angles  # noqa: E402

ROOT = Path(__file__).parents[1]
IMG = ROOT / "docs" / "img"


def source_loop(mesh, cycles, theta=0.3, drop_history=False, cap=400_000):
    """Doerfler loop on the residual indicator of -Laplace u = 1, u = 0 on the boundary
    (stops early when the mesh passes ``cap`` triangles)."""
    import skfem
    from skfem.models.poisson import laplace, unit_load

    a0 = float(min_angles(mesh).min())
    rows = []
    for c in range(cycles):
        m = skfem.MeshTri(np.ascontiguousarray(mesh.points.T),
                          np.ascontiguousarray(mesh.triangles.T, dtype=np.int64))
        basis = skfem.Basis(m, skfem.ElementTriP1())
        u = skfem.solve(*skfem.condense(skfem.asm(laplace, basis),
                                        skfem.asm(unit_load, basis), D=m.boundary_nodes()))
        eta = afem.estimate(basis, u) + _interior(basis)
        marked = mark_dorfler(eta, theta)
        t = time.perf_counter()
        fine = qdrefine.refine(mesh, "7t-qd", marked=marked)
        seconds = time.perf_counter() - t
        if drop_history:
            fine = fine.replace(transitions=None)
        angle = float(min_angles(fine).min())
        rows.append({"cycle": c, "triangles": fine.n_triangles, "marked": int(marked.sum()),
                     "added": fine.n_triangles - mesh.n_triangles, "min_angle": angle,
                     "min_angle_ratio": angle / a0, "refine_seconds": seconds})
        mesh = fine
        if mesh.n_triangles > cap:
            break
    return rows


def _interior(basis):
    """``h_T^2 |f|^2 |T|`` for ``f = 1``."""
    import skfem

    @skfem.Functional
    def residual(w):
        return w.h ** 2

    return residual.elemental(basis)


def part_afem(cycles):
    mesh = examples.gmsh_mesh("l_shape")
    results = afem.study(mesh, afem.METHODS, cycles)
    summary = {}
    for method, rows in results.items():
        ratios = [r["min_angle_ratio"] for r in rows]
        added = [r["added"] / r["marked"] for r in rows if r["marked"]]
        summary[method] = {
            "rate": afem.rate(rows), "error_at_10k": afem.error_at(rows, 1e4),
            "min_ratio": min(ratios), "first4_min": min(ratios[:4]), "last4_min": min(ratios[-4:]),
            "median_added_per_marked": float(np.median(added)),
            "refine_seconds_total": float(sum(r["refine_seconds"] for r in rows))}
    ref = summary["scikit-fem"]["error_at_10k"]
    for s in summary.values():
        s["error_at_10k_over_scikit_fem"] = s["error_at_10k"] / ref
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    afem.plot_error(results, axes[0])
    afem.plot_min_angle(results, axes[1])
    fig.tight_layout()
    fig.savefig(IMG / "afem_lshape.png", dpi=110)
    plt.close(fig)
    return {"cycles": results, "summary": summary}


def part_loops(cycles):
    out = {}
    runs = [(name, name, 0.3) for name in ("plate_with_hole", "step", "graded",
                                           "boundary_layer")]
    runs += [(f"{name} (Doerfler 0.5)", name, 0.5) for name in ("plate_with_hole", "step")]
    for key, name, theta in runs:
        rows = source_loop(examples.gmsh_mesh(name), cycles, theta=theta)
        ratios = [r["min_angle_ratio"] for r in rows]
        out[key] = {"cycles": rows, "theta": theta, "min_ratio": min(ratios),
                    "first4_min": min(ratios[:4]), "last4_min": min(ratios[-4:]),
                    "median_added_per_marked": float(np.median(
                        [r["added"] / r["marked"] for r in rows if r["marked"]]))}
    return out


def part_history(cycles):
    mesh = examples.gmsh_mesh("l_shape")
    cycles = min(cycles, 10)
    out = {}
    for keep in (True, False):
        rows, m = [], mesh
        a0 = float(min_angles(mesh).min())
        for c in range(cycles):
            basis, u = afem.solve(m)
            marked = mark_dorfler(afem.estimate(basis, u), 0.5)
            fine = qdrefine.refine(m, "7t-qd", marked=marked)
            if not keep:
                fine = fine.replace(transitions=None)
            rows.append({"cycle": c, "min_angle_ratio": float(min_angles(fine).min()) / a0,
                         "triangles": fine.n_triangles})
            m = fine
        out["with history" if keep else "history dropped"] = rows
    return out


def part_bounds(cycles):  # noqa: ARG001
    """The worst child/parent ratio of every transition over the mapping diagram, and the
    computed bound on each Gmsh mesh (qdrefine.adaptive.bounds)."""
    from qdrefine.adaptive.bounds import pattern_ratios, quality_bound

    out = {"patterns": pattern_ratios("7t-qd", n=200), "meshes": {}}
    for name in examples.GMSH_MESHES:
        b = quality_bound(examples.gmsh_mesh(name), levels=10)
        out["meshes"][name] = {"initial": b.initial, "red": b.red, "transition": b.transition,
                               "ratio": b.ratio, "upgraded": b.upgraded, "classes": b.classes}
    return out


def plot_loops(loops, history, png):
    """The smallest angle per cycle over the initial one. The rows' ``cycle`` counts the
    refinements from 0 (row ``c``: the mesh after ``c + 1`` of them); the figure numbers
    cycles as the AFEM figure does (0: the initial mesh, ratio 1; ``c``: after ``c``
    refinements)."""
    fig, ax = plt.subplots(figsize=(10, 4.5))
    styles = iter([("o", "-"), ("s", "--"), ("^", "-."), ("D", ":"), ("v", "-"), ("P", "--"),
                   ("*", "-.")])

    def curve(rows):
        return ([0] + [r["cycle"] + 1 for r in rows],
                [1.0] + [r["min_angle_ratio"] for r in rows])

    for name, res in loops.items():
        marker, line = next(styles)
        ax.plot(*curve(res["cycles"]), marker=marker, linestyle=line,
                label=f"{name.split(' (')[0]}, f = 1, Doerfler {res['theta']}")
    if history:
        for key, line in (("with history", "-"), ("history dropped", ":")):
            ax.plot(*curve(history[key]), marker="x", linestyle=line, color="black",
                    label=f"L-shape AFEM, {key}")
    ax.axhline(0.4, color="gray", linewidth=0.8, label="0.4 (acceptance)")
    ax.set_xlabel("cycle (0: the initial mesh)")
    ax.set_ylabel("smallest angle / initial smallest angle")
    ax.set_ylim(0, 1.05)
    ax.set_title("7T-QD, mesh = refine(mesh, marked=...) on Gmsh meshes")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1))  # beside the data
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cycles", type=int, default=12)
    parser.add_argument("--parts", default="afem,loops,history,bounds")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--plot-only", type=Path, default=None, metavar="JSON",
                        help="redraw the loops' figure from a results file, run nothing")
    args = parser.parse_args(argv)
    if args.plot_only:
        done = json.loads(args.plot_only.read_text())
        plot_loops(done["loops"], done.get("history"), IMG / "adaptive_loops.png")
        return
    parts = args.parts.split(",")
    IMG.mkdir(parents=True, exist_ok=True)
    result = {"date": datetime.date.today().isoformat(), "machine": platform.platform(),
              "qdrefine": qdrefine.__version__ if hasattr(qdrefine, "__version__") else None,
              "cycles": args.cycles}
    path = args.json or ROOT / "benchmarks" / "results" / f"adaptive-{result['date']}.json"
    for part in parts:
        t = time.perf_counter()
        result[part] = globals()[f"part_{part}"](args.cycles)
        print(f"{part}: {time.perf_counter() - t:.1f} s", flush=True)
        path.write_text(json.dumps(result, indent=1))  # after each part
    if "loops" in result:
        plot_loops(result["loops"], result.get("history"), IMG / "adaptive_loops.png")
    print("wrote", path)
    for key in ("afem", "loops"):
        if key in result:
            summ = result[key]["summary"] if key == "afem" else result[key]
            for name, s in summ.items():
                print(key, name, {k: round(v, 4) if isinstance(v, float) else v
                                  for k, v in s.items() if k != "cycles"})


if __name__ == "__main__":
    main()
