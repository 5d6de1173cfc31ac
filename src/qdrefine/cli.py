"""The ``qdrefine`` command line."""

from __future__ import annotations

import argparse
import sys

import numpy as np

from . import examples
from .quality import min_angles
from .refine import refine
from .schemes import scheme_names
from .topology import conformity, euler_characteristic

__all__ = ["main"]


def _demo(args: argparse.Namespace) -> int:
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
            ok = conformity(fine).ok and euler_characteristic(fine) == chi0
            angles = min_angles(fine)
            print(f"{name:8} {level:>5} {fine.n_triangles:>10} {fine.n_points:>9} "
                  f"{'yes' if ok else 'NO':>10} {euler_characteristic(fine):>5} "
                  f"{angles.min():>9.3f} {np.mean(angles):>9.3f}")
    return 0


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="qdrefine",
        description="Refine 2D triangle meshes with seven-triangle partitions (7T-QD).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    demo = sub.add_parser("demo", help="refine a built-in example with every scheme")
    demo.add_argument("--levels", type=int, default=2, help="refinement levels (default 2)")
    demo.set_defaults(handler=_demo)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if getattr(args, "handler", None) is None:
        parser.print_help()
        return 2
    return int(args.handler(args))
