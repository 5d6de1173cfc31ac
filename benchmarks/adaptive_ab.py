"""One adaptive step of this checkout against another version's, alternating processes on
the same machine (the only fair comparison on a machine whose speed drifts).

The mesh and marks are those of ``adaptive_bench.py`` (864k-triangle Gmsh L-shape; 1% of
the triangles marked, clustered at the re-entrant corner or scattered at random). Each
process times, best of 5: one uniform 7T-QD level, the clustered step and the scattered
step; with ``--second``, best of 3, also the scattered second cycle (1% scattered marks
again on the scattered step's output, which carries its transitions) and a uniform level
of that mesh; with ``--coarsen``, best of 3, ``qdrefine.coarsen`` of the scattered step's
output, everything marked and the half ``x < 0``, and of a fan (``FAN`` thin triangles
around one vertex, all marked and refined, then everything coarsened: a vertex of degree
``FAN``, where the cost per vertex shows). Usage (a second source tree, e.g. ``git
worktree add /tmp/old REV``)::

    python benchmarks/adaptive_ab.py /tmp/old/src [--rounds 2] [--second] [--coarsen]
        [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).parent

#: Triangles of the fan that ``--coarsen`` also coarsens.
FAN = 32_000


def fan(n: int):
    """``n`` triangles around the origin, their outer corners on the unit circle."""
    import numpy as np

    from qdrefine import Mesh

    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    points = np.vstack([[0, 0], np.c_[np.cos(angle), np.sin(angle)]])
    ring = 1 + np.arange(n)
    return Mesh(points, np.c_[np.zeros(n, dtype=np.int64), ring, 1 + ring % n])


def measure(second: bool = False, coarsening: bool = False) -> dict:
    sys.path.insert(0, str(HERE))
    import numpy as np
    from adaptive_bench import big_l_shape, nearest_corner

    import qdrefine
    from qdrefine import examples
    from qdrefine.marking import mark_random

    mesh = big_l_shape()
    clustered = nearest_corner(mesh)
    marks = {"clustered": clustered, "scattered": mark_random(mesh, 0.01)}
    qdrefine.refine(examples.square(2), marked=[0])  # compiled outside the timings
    qdrefine.refine(mesh, "7t-qd", marked=marks["scattered"])

    def best(f, repeat=5):
        out = np.inf
        for _ in range(repeat):
            t = time.perf_counter()
            f()
            out = min(out, time.perf_counter() - t)
        return out

    row = {"source": str(Path(qdrefine.__file__).parent),
           "uniform_s": best(lambda: qdrefine.refine(mesh, "7t-qd"))}
    for name, marked in marks.items():
        row[f"{name}_s"] = best(lambda m=marked: qdrefine.refine(mesh, "7t-qd", marked=m))
    if second:
        first = qdrefine.refine(mesh, "7t-qd", marked=marks["scattered"])
        again = mark_random(first, 0.01, seed=1)
        row["second_uniform_s"] = best(lambda: qdrefine.refine(first, "7t-qd"), 3)
        row["second_cycle_s"] = best(lambda: qdrefine.refine(first, "7t-qd", marked=again), 3)
    if coarsening:
        from qdrefine.marking import mark_box

        fine = qdrefine.refine(mesh, "7t-qd", marked=marks["scattered"])
        for name, marked in (("everything", np.ones(fine.n_triangles, dtype=bool)),
                             ("half", mark_box(fine, (-1, -1, 0, 1)))):
            row[f"coarsen_{name}_s"] = best(lambda m=marked: qdrefine.coarsen(fine, m), 3)
        around = qdrefine.refine(fan(FAN), marked=np.arange(FAN))
        everything = np.ones(around.n_triangles, dtype=bool)
        row["coarsen_fan_s"] = best(lambda: qdrefine.coarsen(around, everything), 3)
    return row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("other", help="the other version's source folder (holds qdrefine/)")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--second", action="store_true",
                        help="also time the scattered second cycle (about a minute more)")
    parser.add_argument("--coarsen", action="store_true",
                        help="also time coarsening the scattered step's output: everything, "
                             "and the half x < 0")
    parser.add_argument("--measure", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.measure:
        print(json.dumps(measure(args.second, args.coarsen)))
        return
    rows = []
    for _ in range(args.rounds):
        for src in (None, args.other):
            env = dict(os.environ)
            if src is not None:
                env["PYTHONPATH"] = str(Path(src).resolve())
            flags = ["--measure"] + (["--second"] if args.second else []) \
                + (["--coarsen"] if args.coarsen else [])
            out = subprocess.run([sys.executable, __file__, args.other, *flags],
                                 env=env, capture_output=True, text=True, check=True)
            rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
            print(rows[-1])
    result = {"date": time.strftime("%Y-%m-%d"), "load_average": os.getloadavg(),
              "rows": rows}
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
        print("wrote", args.json)


if __name__ == "__main__":
    main()
