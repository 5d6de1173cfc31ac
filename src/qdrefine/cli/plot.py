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
    parser.add_argument("--dpi", type=_dpi, default=150,
                        help=f"resolution of PNG files, {DPI[0]} to {DPI[1]} (default 150)")


#: Resolutions --dpi takes: below 10 the picture is a few pixels; at 2000 a PNG of the
#: default figure is about 16000 x 15000 pixels (about 1 GB of memory to render).
DPI = (10, 2000)


def _dpi(text: str) -> int:
    value = _common.non_negative(text)
    if not DPI[0] <= value <= DPI[1]:
        raise argparse.ArgumentTypeError(f"expected {DPI[0]} to {DPI[1]}, got {value}")
    return value


def run(args: argparse.Namespace) -> int:
    with _common.session():
        _common.check_output(args.output, (args.input,), kinds="picture")
        mesh = read(args.input)
        if args.color == "tag" and mesh.cell_tags is None:
            raise ValueError(f"{args.input}: no cell tags to colour by; use --color min-angle "
                             "or --color none")
        ax = plot_mesh(mesh, color=args.color, title=f"{args.input}: "
                       f"{_common.counted(mesh.n_triangles, 'triangle')}, "
                       f"{_common.counted(mesh.n_points, 'point')}")
        _common.save_figure(ax.figure, args.output, dpi=args.dpi)
        if not args.quiet:
            colour = "" if args.color == "none" else f", coloured by {args.color}"
            print(f"{args.output}: {_common.counted(mesh.n_triangles, 'triangle')} drawn{colour}")
    return 0
