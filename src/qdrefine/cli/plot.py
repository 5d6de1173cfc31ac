"""``qdrefine plot IN FILE.png``: draw a mesh coloured by quality or tag."""

from __future__ import annotations

import argparse

from ..io import read
from ..plot import COLORS
from ..plot import mesh as plot_mesh
from . import _common

HELP = "draw a mesh into a picture, coloured by minimum angle or by tag"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser)
    parser.add_argument("input", metavar="IN", help="mesh file to read")
    parser.add_argument("output", metavar="FILE.png", help="picture to write (.png, .svg, .pdf)")
    parser.add_argument("--color", default="min-angle", choices=COLORS,
                        help="fill triangles by their minimum angle (default), their cell tag, "
                             "or not at all")
    parser.add_argument("--dpi", type=_common.non_negative, default=150,
                        help="resolution of PNG files (default 150)")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        _common.check_output(args.output, (args.input,), kinds="picture")
        mesh = read(args.input)
        ax = plot_mesh(mesh, color=args.color, title=f"{args.input}: {mesh.n_triangles} "
                       f"triangles, {mesh.n_points} points")
        _common.save_figure(ax.figure, args.output, dpi=max(args.dpi, 10))
        if not args.quiet:
            colour = "" if args.color == "none" else f", coloured by {args.color}"
            print(f"{args.output}: {_common.counted(mesh.n_triangles, 'triangle')} drawn{colour}")
    return 0
