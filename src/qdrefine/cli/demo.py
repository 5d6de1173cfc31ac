"""``qdrefine demo``: refine the built-in example with every scheme and summarize."""

from __future__ import annotations

import argparse

import numpy as np

from .. import examples
from ..quality import min_angles
from ..refine import refine
from ..schemes import scheme_names
from ..topology import conformity, euler_characteristic

HELP = "refine a built-in example (plate with a hole) with every scheme and summarize"


def add_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--levels", type=int, default=2, help="refinement levels (default 2)")


def run(args: argparse.Namespace) -> int:
    mesh = examples.plate_with_hole()
    print(f"example: plate with a hole, {mesh.n_points} points, {mesh.n_triangles} triangles, "
          f"min angle {min_angles(mesh).min():.2f} deg")
    header = (f"{'scheme':8} {'level':>5} {'triangles':>10} {'points':>9} {'conforming':>10} "
              f"{'euler':>5} {'min angle':>9} {'mean min':>9}")
    print(header)
    print("-" * len(header))
    chi0 = euler_characteristic(mesh)
    for name in scheme_names():
        fine = mesh
        for level in range(1, args.levels + 1):
            fine = refine(fine, name)
            chi = euler_characteristic(fine)
            ok = conformity(fine).ok and chi == chi0
            angles = min_angles(fine)
            print(f"{name:8} {level:>5} {fine.n_triangles:>10} {fine.n_points:>9} "
                  f"{'yes' if ok else 'NO':>10} {chi:>5} "
                  f"{angles.min():>9.3f} {np.mean(angles):>9.3f}")
    return 0
