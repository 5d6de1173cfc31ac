"""``qdrefine refine IN OUT``: refine every triangle of a mesh file and write the result."""

from __future__ import annotations

import argparse
import time

from ..io import read, write
from ..refine import refine
from ..schemes import get_scheme, scheme_names
from . import _common

HELP = "refine every triangle of a mesh file with a seven-triangle (or 4T) scheme"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser)
    parser.epilog = ("Formats follow the extensions (.msh, .vtk, .vtu, .xdmf, .mesh, .off, "
                     ".obj, .stl, .ply, Triangle's .node/.ele/.poly). Cell tags are inherited "
                     "and each tagged edge is split with its tag. Example: qdrefine refine "
                     "in.msh out.msh --levels 2")
    parser.add_argument("input", metavar="IN", help="mesh file to read (never modified)")
    parser.add_argument("output", metavar="OUT",
                        help="mesh file to write (written atomically; .msh is Gmsh 2.2)")
    parser.add_argument("--scheme", default="7t-qd", metavar="NAME",
                        help=f"one of {', '.join(scheme_names())} (default 7t-qd)")
    parser.add_argument("--binary", action="store_true",
                        help="write the binary variant of .msh, .vtk, .vtu, .stl or .ply "
                             "(much faster for large meshes)")
    parser.add_argument("--levels", type=_common.non_negative, default=1, metavar="N",
                        help="how many times to refine (default 1; 7T schemes multiply the "
                             "triangles by 7 per level)")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        get_scheme(args.scheme)  # an unknown name fails here, before any file is read
        _common.check_output(args.output, (args.input,), binary=args.binary)
        start = time.perf_counter()
        with _common.Progress(args.levels + 2, args.quiet) as progress:
            progress.step(f"reading {args.input}")
            mesh = read(args.input)
            n0 = mesh.n_triangles
            for level in range(1, args.levels + 1):
                progress.step(f"refining, level {level}/{args.levels}")
                mesh = refine(mesh, args.scheme)
            progress.step(f"writing {args.output}")
            write(args.output, mesh, binary=args.binary or None)
        if not args.quiet:
            print(f"{args.output}: {mesh.n_triangles} triangles, {mesh.n_points} points "
                  f"({n0} triangles refined by {args.scheme}, {args.levels} level"
                  f"{'s' if args.levels != 1 else ''}, {time.perf_counter() - start:.2f} s)")
    return 0
