"""Digests of the outputs of many adaptive refinement scenarios, one line each.

Shows that a change keeps every output array bit for bit: run it on two source trees and
compare the lines.

Scenarios: the Gmsh examples (``l_shape``, ``plate_with_hole``, ``step``,
``boundary_layer``, ``graded``) with each of 7T-QD, 7T-LE, 4T-LE and 7T-D, six cycles of
``refine(mesh, marked=...)`` with 15% random marks (their parents included), then a
coarsening of half the triangles; with ``--big``, the 864k-triangle L-shape of
``adaptive_bench.py``: 1% scattered and 0.2% random marks, the second cycle of each, and
two levels. Each line is ``scenario digest`` (SHA-1 of the arrays' dtypes, shapes and
bytes: points, triangles, tags, edges, transitions, origins, cell and point data).
Usage (e.g. against ``git worktree add /tmp/old REV``)::

    python benchmarks/adaptive_digests.py [--big] > new.txt
    PYTHONPATH=/tmp/old/src python benchmarks/adaptive_digests.py [--big] > old.txt
    diff old.txt new.txt
"""

from __future__ import annotations

import argparse
import hashlib
import sys
from pathlib import Path

import numpy as np

import qdrefine
from qdrefine import examples
from qdrefine.marking import mark_random

EXAMPLES = ["l_shape", "plate_with_hole", "step", "boundary_layer", "graded"]
SCHEMES = ["7t-qd", "7t-le", "4t-le", "7t-d"]


def digest(mesh: qdrefine.Mesh, extra: tuple = ()) -> str:
    d = hashlib.sha1()
    arrays = [mesh.points, mesh.triangles, mesh.cell_tags, mesh.edges, mesh.edge_tags,
              mesh.transitions, mesh.origins, *extra]
    arrays += [mesh.cell_data[k] for k in sorted(mesh.cell_data)]
    arrays += [mesh.point_data[k] for k in sorted(mesh.point_data)]
    for a in arrays:
        if a is not None:
            a = np.ascontiguousarray(a)
            d.update(f"{a.dtype}{a.shape}".encode())
            d.update(a.tobytes())
    return d.hexdigest()[:12]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--big", action="store_true", help="the 864k L-shape cases too")
    args = parser.parse_args(argv)
    for name in EXAMPLES:
        base = examples.gmsh_mesh(name)
        for sch in SCHEMES:
            mesh = base
            for c in range(6):
                mesh, parents = qdrefine.refine_with_parents(
                    mesh, sch, marked=mark_random(mesh, 0.15, seed=c))
                print(f"{name} {sch} c{c}", digest(mesh, (parents,)), flush=True)
            coarse = qdrefine.coarsen(mesh, mark_random(mesh, 0.5, seed=9), sch)
            print(f"{name} {sch} coarsen", digest(coarse), flush=True)
    if args.big:
        sys.path.insert(0, str(Path(__file__).parent))
        from adaptive_bench import big_l_shape

        big = big_l_shape()
        for kind, marks in [("scattered", mark_random(big, 0.01)),
                            ("random 0.2%", mark_random(big, 0.002, seed=3))]:
            out = qdrefine.refine(big, "7t-qd", marked=marks)
            print(f"big {kind}", digest(out), flush=True)
            again = qdrefine.refine(out, "7t-qd", marked=mark_random(out, 0.01, seed=1))
            print(f"big {kind}, second cycle", digest(again), flush=True)
        two = qdrefine.refine(big, "7t-qd", marked=mark_random(big, 0.01), levels=2)
        print("big two levels", digest(two), flush=True)


if __name__ == "__main__":
    main()
