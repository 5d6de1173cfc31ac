"""Adaptive refinement study: L-shaped domain refined towards its re-entrant corner.

Methods, all from the same initial mesh and the same marking rule (every triangle with a
vertex at the corner ``(0, 0)``, plus, for the circle front, every triangle meeting the
circle of radius 0.5):

* ``7t-qd``            qdrefine, 7T-QD with the quality floor (``refine_cycles``, keep=0.5)
* ``7t-qd (no floor)`` qdrefine, 7T-QD closure with the floor switched off (min_angle=0)
* ``4t-le``            qdrefine, 4T-LE closure: local longest-edge bisection (Rivara)
* ``scikit-fem``       ``MeshTri.refined(marked)`` (red-green-blue), if scikit-fem is there

Prints a table per cycle (minimum angle, triangles added per marked triangle, seconds) and
writes ``docs/adaptive_study.png``. Usage::

    python benchmarks/adaptive_study.py [--cycles 20] [--png docs/adaptive_study.png]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from qdrefine import Mesh, refine
from qdrefine.adaptive import refine_marked
from qdrefine.quality import min_angles

try:  # optional: pip install qdrefine[bench]
    import skfem
except ImportError:  # pragma: no cover
    skfem = None


def lshape(times: int = 2, jitter: float = 0.0, seed: int = 0) -> Mesh:
    """scikit-fem's L-shape ``[-1, 1]^2`` minus ``(0, 1]^2``, uniformly refined ``times``
    times by red refinement, interior vertices moved by up to ``jitter`` of the mesh size."""
    p = np.array([[0, 0], [1, 0], [0, 1], [-1, 0], [0, -1], [-1, -1], [-1, 1], [1, -1]], float)
    t = np.array([[0, 1, 7], [0, 2, 6], [0, 3, 6], [0, 4, 7], [0, 4, 5], [0, 3, 5]])
    mesh = Mesh(p, _ccw(p, t))
    mesh = refine(mesh, "4t-red", times)
    if jitter:
        pts = mesh.points.copy()
        h = 2.0 ** -times
        on_boundary = np.zeros(len(pts), bool)
        from qdrefine.topology import boundary_edges

        on_boundary[boundary_edges(mesh).ravel()] = True
        rng = np.random.default_rng(seed)
        move = ~on_boundary
        pts[move] += rng.uniform(-jitter, jitter, (move.sum(), 2)) * h
        mesh = Mesh(pts, mesh.triangles)
    return mesh


def _ccw(p, t):
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    cw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    t = t.copy()
    t[cw] = t[cw][:, [0, 2, 1]]
    return t


def corner_marks(points, triangles):
    corner = np.flatnonzero((points == 0).all(axis=1))
    return np.isin(triangles, corner).any(axis=1)


def circle_marks(points, triangles, radius=0.5):
    """Triangles whose vertices are not all on one side of the circle."""
    r = np.linalg.norm(points[triangles], axis=2)
    return (r.min(axis=1) <= radius) & (r.max(axis=1) >= radius)


def _angles(points, triangles):
    from qdrefine.quality import angles

    return angles(points, triangles).min()


def run_qdrefine(mesh, cycles, marker, scheme, floor):
    rows = []
    for _ in range(cycles):
        marked = marker(mesh.points, mesh.triangles)
        t0 = time.perf_counter()
        fine, _ = refine_marked(mesh, marked, scheme, min_angle=floor)
        dt = time.perf_counter() - t0
        rows.append((min_angles(fine).min(), (fine.n_triangles - mesh.n_triangles)
                     / max(1, marked.sum()), dt, fine.n_triangles))
        mesh = fine
    return rows, mesh


def run_skfem(mesh, cycles, marker):
    m = skfem.MeshTri(mesh.points.T.copy(), mesh.triangles.T.astype(np.int64).copy())
    rows = []
    for _ in range(cycles):
        p, t = m.p.T, m.t.T
        marked = np.flatnonzero(marker(p, t))
        t0 = time.perf_counter()
        fine = m.refined(marked)
        dt = time.perf_counter() - t0
        rows.append((_angles(fine.p.T, fine.t.T), (fine.t.shape[1] - t.shape[0])
                     / max(1, marked.size), dt, fine.t.shape[1]))
        m = fine
    return rows, m


def study(mesh, cycles, marker, cap=400_000):
    a0 = min_angles(mesh).min()
    out = {
        "7t-qd": run_qdrefine(mesh, cycles, marker, "7t-qd", 0.5 * a0),
        "7t-qd (no floor)": run_qdrefine(mesh, cycles, marker, "7t-qd", 0.0),
        "4t-le": run_qdrefine(mesh, cycles, marker, "4t-le", 0.0),
    }
    if skfem is not None:
        out["scikit-fem"] = run_skfem(mesh, cycles, marker)
    return a0, out


def report(title, a0, results):
    print(f"\n## {title}: initial minimum angle {a0:.3f} deg")
    names = list(results)
    print("cycle | " + " | ".join(f"{n}: min angle (fraction), added/marked, ms, triangles"
                                  for n in names))
    cycles = len(next(iter(results.values()))[0])
    for c in range(cycles):
        cells = []
        for n in names:
            rows = results[n][0]
            if c < len(rows):
                a, s, dt, nt = rows[c]
                cells.append(f"{a:6.2f} ({a / a0:.3f}), {s:6.1f}, {1e3 * dt:7.1f}, {nt}")
            else:
                cells.append("-")
        print(f"{c + 1:5d} | " + " | ".join(cells))
    for n in names:
        rows = results[n][0]
        worst = min(r[0] for r in rows)
        spread = np.mean([r[1] for r in rows])
        print(f"{n:18s} worst min angle {worst:7.3f} deg = {worst / a0:.3f} of initial; "
              f"mean added per marked {spread:6.1f}; mean ms/cycle "
              f"{1e3 * np.mean([r[2] for r in rows]):.1f}")


def plot(studies, png):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(studies), 2, figsize=(11, 3.6 * len(studies)))
    axes = np.atleast_2d(axes)
    for (title, a0, results), (ax1, ax2) in zip(studies, axes, strict=True):
        styles = ("-", "--", "-", ":")  # overlapping curves stay visible
        for (name, (rows, _)), ls in zip(results.items(), styles, strict=False):
            c = np.arange(1, len(rows) + 1)
            ax1.plot(c, [r[0] / a0 for r in rows], ls=ls, marker="o", ms=3, label=name)
            ax2.plot(c, [r[1] for r in rows], ls=ls, marker="o", ms=3, label=name)
        ax1.set(title=f"{title}: min angle / initial", xlabel="cycle", ylim=(0, 1.05))
        ax2.set(title=f"{title}: added per marked", xlabel="cycle")
        ax2.set_yscale("log")
        ax1.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=20)
    parser.add_argument("--front-cycles", type=int, default=5)
    parser.add_argument("--png", default=str(Path(__file__).parents[1] / "docs"
                                             / "adaptive_study.png"))
    args = parser.parse_args(argv)
    refine(lshape(), "7t-qd", marked=[0])  # compile the kernels outside the timings
    studies = []
    for title, mesh in (("L-shape, right isosceles", lshape(2)),
                        ("L-shape, jittered", lshape(2, jitter=0.25, seed=1))):
        a0, res = study(mesh, args.cycles, corner_marks)
        report(f"{title}, corner", a0, res)
        studies.append((f"{title}, corner", a0, res))
    mesh = lshape(3, jitter=0.25, seed=2)
    a0, res = study(mesh, args.front_cycles, circle_marks)
    report("L-shape jittered, circle front r=0.5", a0, res)
    studies.append(("circle front", a0, res))
    plot(studies, args.png)
    print(f"\nwrote {args.png}")


if __name__ == "__main__":
    main()
