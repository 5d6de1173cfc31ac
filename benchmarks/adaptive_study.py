"""Adaptive refinement study: 20 cycles on an L-shaped domain, towards its re-entrant corner
and along a moving circular front.

Cases (every method gets the same marking rule, evaluated on its own mesh each cycle):

* ``corner``: scikit-fem's L-shape ``[-1, 1]^2 \\ (0, 1]^2`` red-refined twice (96 right
  isosceles triangles), as is and with interior vertices jittered by 0.25 h; each cycle
  marks the triangles with a vertex at the corner ``(0, 0)``.
* ``front``: the jittered L refined three times (384 triangles); cycle ``c`` marks the
  triangles crossing the circle ``|x| = 0.2 + 0.7 c / 19`` whose longest edge exceeds 0.03
  (a front sweeping the domain, refined to a target size; it keeps hitting transitions).
* ``random``: the jittered 96-triangle L; each cycle marks about 5% of the triangles,
  picked by a hash of centroid and cycle (10 cycles; the adversarial case).

Methods:

* ``7t-qd``                 qdrefine, transitions coarsened before they are refined
  (``refine_step`` with its families), quality floor 0.5 x initial minimum angle
* ``7t-qd, no coarsening``  qdrefine, each cycle a plain ``refine_marked`` (the previous
  algorithm: transitions of transitions are possible), same floor
* ``7t-qd, no floor``       coarsening, floor switched off
* ``7t-qd, neither``        no coarsening and no floor
* ``4t-le (bisection)``     qdrefine's 4T-LE closure: local longest-edge bisection (Rivara)
* ``scikit-fem``            ``MeshTri.refined(marked)`` (red-green-blue)

Per cycle: minimum angle / initial, triangles added per marked triangle (spread), seconds
(best of ``--repeat`` runs of the same step; numba on one thread unless NUMBA_NUM_THREADS is
set, scikit-fem is single-threaded NumPy too). Writes ``docs/adaptive_study.png``,
``docs/img/adaptive_time.png``, ``docs/img/adaptive_front.png`` and
``benchmarks/results/adaptive-<date>.json``. Usage::

    python benchmarks/adaptive_study.py [--cycles 20] [--random-cycles 10] [--repeat 3]
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")  # before numba is imported

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import qdrefine  # noqa: E402
from qdrefine import Mesh, refine  # noqa: E402
from qdrefine.adaptive import refine_marked, refine_step  # noqa: E402
from qdrefine.quality import angles  # noqa: E402
from qdrefine.topology import boundary_edges  # noqa: E402

try:  # optional: pip install qdrefine[bench]
    import skfem
except ImportError:  # pragma: no cover
    skfem = None

ROOT = Path(__file__).parents[1]
Marker = Callable[[np.ndarray, np.ndarray, int], np.ndarray]


def lshape(times: int = 2, jitter: float = 0.0, seed: int = 0) -> Mesh:
    """scikit-fem's L-shape ``[-1, 1]^2`` minus ``(0, 1]^2``, uniformly refined ``times``
    times by red refinement, interior vertices moved by up to ``jitter`` of the mesh size."""
    p = np.array([[0, 0], [1, 0], [0, 1], [-1, 0], [0, -1], [-1, -1], [-1, 1], [1, -1]], float)
    t = np.array([[0, 1, 7], [0, 2, 6], [0, 3, 6], [0, 4, 7], [0, 4, 5], [0, 3, 5]])
    mesh = refine(Mesh(p, _ccw(p, t)), "4t-red", times)
    if jitter:
        pts = mesh.points.copy()
        move = np.ones(len(pts), bool)
        move[boundary_edges(mesh).ravel()] = False
        rng = np.random.default_rng(seed)
        pts[move] += rng.uniform(-jitter, jitter, (move.sum(), 2)) * 2.0 ** -times
        mesh = Mesh(pts, mesh.triangles)
    return mesh


def _ccw(p, t):
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    cw = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    t = t.copy()
    t[cw] = t[cw][:, [0, 2, 1]]
    return t


def corner_marks(points, triangles, cycle, cycles):  # noqa: ARG001
    corner = np.flatnonzero((points == 0).all(axis=1))
    return np.isin(triangles, corner).any(axis=1)


def front_marks(points, triangles, cycle, cycles, start=0.2, span=0.7, size=0.03):
    """Triangles crossing the circle of radius ``start + span * cycle / (cycles - 1)``
    (vertices on both sides, or on it) whose longest edge is longer than ``size``."""
    r = start + span * cycle / max(1, cycles - 1)
    d = np.linalg.norm(points[triangles], axis=2)
    cross = (d.min(axis=1) <= r) & (d.max(axis=1) >= r)
    p = points[triangles]
    longest = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2).max(axis=1)
    return cross & (longest > size)


def random_marks(points, triangles, cycle, cycles, fraction=0.05):  # noqa: ARG001
    """About ``fraction`` of the triangles, chosen by a hash of the centroid and the cycle
    (deterministic, the same rule for every method; the adversarial case: marks land on
    transition children as often as anywhere else)."""
    c = points[triangles].mean(axis=1)
    u = np.sin(c @ np.array([12.9898, 78.233]) + 3.7 * cycle) * 43758.5453
    return u - np.floor(u) < fraction


# ----------------------------------------------------------------------------------------
# one method = (state -> arrays, step(state, marked) -> state)


def timed(step, repeat):
    """Best time of ``repeat`` runs of a pure ``step()`` and its (last) result."""
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = step()
        best = min(best, time.perf_counter() - t0)
    return best, out


def run_qdrefine(mesh, cycles, marker, repeat, scheme, floor, coarsen):
    rows, fam = [], None
    for c in range(cycles):
        marked = marker(mesh.points, mesh.triangles, c, cycles)
        if coarsen:
            dt, (fine, _, new_fam) = timed(
                lambda m=mesh, k=marked, f=fam: refine_step(m, k, scheme, floor, f), repeat)
        else:
            dt, (fine, _) = timed(
                lambda m=mesh, k=marked: refine_marked(m, k, scheme, 1, floor), repeat)
            new_fam = None
        rows.append(_row(fine.points, fine.triangles, mesh.n_triangles, marked, dt))
        mesh, fam = fine, new_fam
    return rows, mesh


def run_skfem(mesh, cycles, marker, repeat):
    m = skfem.MeshTri(mesh.points.T.copy(), mesh.triangles.T.astype(np.int64).copy())
    rows = []
    for c in range(cycles):
        marked = marker(m.p.T, m.t.T, c, cycles)
        ids = np.flatnonzero(marked)
        dt, fine = timed(lambda m=m, k=ids: m.refined(k), repeat)
        rows.append(_row(fine.p.T, fine.t.T, m.t.shape[1], marked, dt))
        m = fine
    return rows, m


def _row(points, triangles, n_before, marked, seconds):
    return {"min_angle": float(angles(points, triangles).min()),
            "marked": int(marked.sum()), "triangles": int(triangles.shape[0]),
            "added_per_marked": (triangles.shape[0] - n_before) / max(1, int(marked.sum())),
            "seconds": seconds}


def study(mesh, cycles, marker, repeat):
    a0 = float(angles(mesh.points, mesh.triangles).min())
    out = {
        "7t-qd": run_qdrefine(mesh, cycles, marker, repeat, "7t-qd", 0.5 * a0, True),
        "7t-qd, no coarsening": run_qdrefine(mesh, cycles, marker, repeat, "7t-qd",
                                             0.5 * a0, False),
        "7t-qd, no floor": run_qdrefine(mesh, cycles, marker, repeat, "7t-qd", 0.0, True),
        "7t-qd, neither": run_qdrefine(mesh, cycles, marker, repeat, "7t-qd", 0.0, False),
        "4t-le (bisection)": run_qdrefine(mesh, cycles, marker, repeat, "4t-le", 0.0, False),
    }
    if skfem is not None:
        out["scikit-fem"] = run_skfem(mesh, cycles, marker, repeat)
    return a0, out


# ----------------------------------------------------------------------------------------
# report


def summarize(a0, results):
    """Per method: worst and last fraction of the initial minimum angle, mean spread, mean
    and total seconds per cycle, final triangles."""
    out = {}
    for name, (rows, _) in results.items():
        spread = [r["added_per_marked"] for r in rows if r["marked"]]
        out[name] = {
            "worst_fraction": min(r["min_angle"] for r in rows) / a0,
            "last_fraction": rows[-1]["min_angle"] / a0,
            "mean_added_per_marked": float(np.mean(spread)) if spread else 0.0,
            "mean_ms_per_cycle": 1e3 * float(np.mean([r["seconds"] for r in rows])),
            "triangles": rows[-1]["triangles"],
            "marked_total": sum(r["marked"] for r in rows),
        }
    return out


def report(title, a0, results):
    print(f"\n## {title}: initial minimum angle {a0:.3f} deg")
    print(f"{'method':22s} {'worst':>6s} {'last':>6s} {'added/marked':>12s} "
          f"{'ms/cycle':>9s} {'triangles':>9s}")
    for name, s in summarize(a0, results).items():
        print(f"{name:22s} {s['worst_fraction']:6.3f} {s['last_fraction']:6.3f} "
              f"{s['mean_added_per_marked']:12.1f} {s['mean_ms_per_cycle']:9.1f} "
              f"{s['triangles']:9d}")
    print("fraction per cycle: " + "; ".join(
        f"{name}: " + " ".join(f"{r['min_angle'] / a0:.2f}" for r in rows)
        for name, (rows, _) in results.items()))


STYLE = {"7t-qd": ("C0", "-", "o", 4), "7t-qd, no coarsening": ("C3", "--", "s", 3),
         "7t-qd, no floor": ("C9", ":", "x", 6), "7t-qd, neither": ("C4", ":", "v", 4),
         "4t-le (bisection)": ("C2", "-", "o", 4),
         "scikit-fem": ("C1", "-.", "+", 7)}  # coinciding curves stay visible


def _line(ax, x, y, name):
    color, ls, marker, ms = STYLE[name]
    ax.plot(x, y, color=color, ls=ls, marker=marker, ms=ms, mfc="none", label=name)


def plot_study(studies, png):
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    fig, axes = plt.subplots(2, len(studies), figsize=(4.6 * len(studies), 7.2),
                             squeeze=False)
    for j, (title, a0, results) in enumerate(studies):
        for name, (rows, _) in results.items():
            c = np.arange(1, len(rows) + 1)
            _line(axes[0, j], c, [r["min_angle"] / a0 for r in rows], name)
            spread = [r["added_per_marked"] if r["marked"] else np.nan for r in rows]
            _line(axes[1, j], c, spread, name)
        axes[0, j].set(title=f"{title}\nmin angle / initial ({a0:.1f} deg)", xlabel="cycle",
                       ylim=(0, 1.05))
        axes[1, j].set(title="triangles added per marked triangle", xlabel="cycle")
        axes[1, j].set_ylim(bottom=0)
        for ax in axes[:, j]:
            ax.grid(alpha=0.3)
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    axes[0, 0].legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def plot_time(studies, png, threads):
    """Milliseconds per cycle against the cycle, for the jittered corner and the front."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator, NullFormatter, ScalarFormatter

    fig, axes = plt.subplots(1, 2, figsize=(10.5, 4.0))
    for ax, (title, _, results) in zip(axes, studies[1:3], strict=True):
        for name in ("7t-qd", "7t-qd, no coarsening", "4t-le (bisection)", "scikit-fem"):
            if name in results:
                rows = results[name][0]
                _line(ax, np.arange(1, len(rows) + 1), [1e3 * r["seconds"] for r in rows],
                      name)
        final = ", ".join(f"{n.split(' ')[0]} {results[n][0][-1]['triangles']}"
                          for n in ("7t-qd", "4t-le (bisection)", "scikit-fem")
                          if n in results)
        n = len(results["7t-qd"][0])
        ms = [r["seconds"] for rows, _ in results.values() for r in rows]
        ax.set(title=f"{title}\n(triangles after {n} cycles: {final})", xlabel="cycle",
               ylabel="ms per cycle", yscale="log" if max(ms) > 20 * min(ms) else "linear")
        if ax.get_yscale() == "log":
            ax.yaxis.set_major_formatter(ScalarFormatter())
            ax.yaxis.set_minor_formatter(NullFormatter())
        else:
            ax.set_ylim(bottom=0)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(alpha=0.3, which="both")
        ax.title.set_fontsize(9)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"time per cycle, best of repeats (numba threads: {threads}; shared 2-core "
                 "machine, noisy below ~10 ms)", fontsize=9)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def plot_front(results, png, window=(-0.75, -0.45, -0.25, 0.05)):
    """Close-up of the front's final meshes with and without coarsening."""
    import matplotlib.pyplot as plt

    from qdrefine import plot

    names = ["7t-qd", "7t-qd, no coarsening"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
    for ax, name in zip(axes, names, strict=True):
        mesh = results[name][1]
        c = mesh.points[mesh.triangles].mean(axis=1)
        x0, y0, x1, y1 = window
        pad = 0.05
        keep = ((c[:, 0] > x0 - pad) & (c[:, 0] < x1 + pad) & (c[:, 1] > y0 - pad)
                & (c[:, 1] < y1 + pad))
        sub = Mesh(mesh.points, mesh.triangles[keep])
        plot.mesh(sub, ax=ax, color="min-angle", edges=True,
                  title=f"{name}: min {angles(sub).min():.1f} deg")
        ax.set(xlim=(x0, x1), ylim=(y0, y1))
    fig.tight_layout()
    fig.savefig(png, dpi=80)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=20)
    parser.add_argument("--random-cycles", type=int, default=10,
                        help="cycles of the random-mark case (the mesh grows ~2.7x a cycle)")
    parser.add_argument("--repeat", type=int, default=3, help="timing runs per step")
    parser.add_argument("--out", default=str(ROOT), help="repository root to write into")
    args = parser.parse_args(argv)
    out = Path(args.out)
    threads = os.environ["NUMBA_NUM_THREADS"]
    refine_step(lshape(), [0])  # compile the kernels outside the timings
    refine_marked(lshape(), [0], "4t-le")
    cases = [("L corner, right isosceles", lshape(2), corner_marks, args.cycles),
             ("L corner, jittered", lshape(2, jitter=0.25, seed=1), corner_marks, args.cycles),
             ("moving circle front", lshape(3, jitter=0.25, seed=2), front_marks, args.cycles),
             ("random 5% marks", lshape(2, jitter=0.25, seed=1), random_marks,
              args.random_cycles)]
    studies, data = [], {}
    t0 = time.perf_counter()
    for title, mesh, marker, cycles in cases:
        a0, res = study(mesh, cycles, marker, args.repeat)
        report(title, a0, res)
        studies.append((title, a0, res))
        data[title] = {"initial_min_angle": a0, "initial_triangles": mesh.n_triangles,
                       "summary": summarize(a0, res),
                       "cycles": {name: rows for name, (rows, _) in res.items()}}
    plot_study(studies, out / "docs" / "adaptive_study.png")
    plot_time(studies, out / "docs" / "img" / "adaptive_time.png", threads)
    plot_front(studies[2][2], out / "docs" / "img" / "adaptive_front.png")
    stamp = datetime.date.today().isoformat()
    meta = {"date": stamp, "cycles": args.cycles, "repeat": args.repeat,
            "numba_threads": threads, "python": platform.python_version(),
            "qdrefine": qdrefine.__version__, "numpy": np.__version__,
            "scikit-fem": getattr(skfem, "__version__", None),
            "cpus": os.cpu_count(), "load_average": os.getloadavg(),
            "wall_seconds": time.perf_counter() - t0}
    path = out / "benchmarks" / "results" / f"adaptive-{stamp}.json"
    path.write_text(json.dumps({"meta": meta, "cases": data}, indent=1))
    print(f"\nwrote docs/adaptive_study.png, docs/img/adaptive_time.png, "
          f"docs/img/adaptive_front.png, {path.relative_to(out)} "
          f"({meta['wall_seconds']:.0f} s, load average {meta['load_average'][0]:.1f})")


if __name__ == "__main__":
    main()
