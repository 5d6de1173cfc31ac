"""``qdrefine coarsen IN OUT``: undo local refinement where every child of a partition is
marked (:func:`qdrefine.coarsen`)."""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from ..adaptive import HistoryMismatch, coarsen_marked
from ..io import mesh_of, read_raw
from ..schemes import scheme_names
from . import _common, marks

HELP = "undo local refinement where every child of a partition is marked"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser)
    parser.epilog = ("IN must carry the refinement history that 'qdrefine refine --mark-...' "
                     "writes into formats with cell data (.msh, .vtu, .xdmf, .vtk). Each "
                     "cycle undoes one level where all children of a partition are marked; "
                     "transitions keep the mesh conforming. Examples: qdrefine coarsen "
                     "fine.msh coarse.msh --mark-box 0,0,0.5,1; qdrefine coarsen fine.msh "
                     "coarse.msh --all --cycles 3")
    _common.add_mesh_in_out(parser, lambda: parser.add_argument(
        "--scheme", default="7t-qd", metavar="NAME", type=_common.scheme_name,
        help=f"the scheme IN was refined with: one of {', '.join(scheme_names())} "
             "(default 7t-qd)"))
    group = parser.add_argument_group("marks", "The triangles that may go (one is needed).")
    mark = group.add_mutually_exclusive_group(required=True)
    marks.add_options(mark)
    mark.add_argument("--all", action="store_true", help="mark every triangle")
    group.add_argument("--cycles", type=_common.non_negative, default=None, metavar="K",
                       help="mark and coarsen K times, one level each (default 1); tags and "
                            "boxes are re-evaluated on each cycle's mesh")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        _common.check_mesh_output(args)
        cycles = 1 if args.cycles is None else args.cycles
        start = time.perf_counter()
        with _common.Progress(cycles + 2, args.quiet) as progress:
            progress.step(f"reading {args.input}")
            mesh = mesh_of(read_raw(args.input))
            if mesh.origins is None:
                raise ValueError(f"{args.input}: no refinement history to coarsen (the cell "
                                 "data qdrefine:origins that 'qdrefine refine --mark-...' "
                                 "writes into .msh, .vtu, .xdmf and .vtk files)")
            n0 = mesh.n_triangles
            mark, mesh = ((lambda m: np.ones(m.n_triangles, dtype=bool)), mesh) if args.all \
                else marks.marker(mesh, args)
            for cycle in range(1, cycles + 1):
                progress.step(f"coarsening, cycle {cycle}/{cycles}")
                try:
                    mesh = coarsen_marked(mesh, mark(mesh), args.scheme)[0]
                except HistoryMismatch as exc:
                    raise _common.history_mismatch(args.input, args.scheme, exc) from None
                except ValueError as exc:  # e.g. a tagged piece refinement did not cut
                    raise ValueError(f"{args.input}: {exc}") from None
            mesh = marks.without_marks(mesh, args)
            progress.step(f"writing {args.output}")
            _common.write_mesh(args, mesh)
        if not args.quiet:
            print(f"{args.output}: {_common.counted(mesh.n_triangles, 'triangle')}, "
                  f"{_common.counted(mesh.n_points, 'point')} ({n0 - mesh.n_triangles} fewer by "
                  f"{args.scheme} in {_common.counted(cycles, 'cycle')}, "
                  f"{time.perf_counter() - start:.2f} s in all)")
            if mesh.n_triangles == n0 and cycles:
                print(f"qdrefine: note: {nothing_coarsened(mesh, args.input, args.scheme)}",
                      file=sys.stderr)
    return 0


def nothing_coarsened(mesh, path: str, scheme: str) -> str:
    """Why coarsening ``mesh`` by ``scheme`` changed nothing: the marks, or the scheme (a
    mesh refined everywhere by 4T-LE has no 7T family, and the converse)."""
    everything = np.ones(mesh.n_triangles, dtype=bool)
    because_of_marks = (f"no partition of {path} had all its children marked (one is undone "
                        "only when every child is)")
    if coarsen_marked(mesh, everything, scheme)[0].n_triangles < mesh.n_triangles:
        return because_of_marks
    for other in scheme_names():
        try:
            smaller = coarsen_marked(mesh, everything, other)[0].n_triangles < mesh.n_triangles
        except (HistoryMismatch, ValueError):
            continue
        if smaller:
            return (f"no partition of {path} is a {scheme} partition, but some are {other} "
                    f"partitions: was it refined with {other}? (see --scheme)")
    return f"no partition of {path} can be undone (its history has none left)"
