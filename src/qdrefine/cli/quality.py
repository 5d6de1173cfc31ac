"""``qdrefine quality IN``: per-triangle quality figures and their histogram."""

from __future__ import annotations

import argparse

from .. import report
from ..io import read
from . import _common

HELP = "quality figures: angles, radius and aspect ratios, shape classes, histogram"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser, quiet=False)
    parser.epilog = ("Radius ratio is 2r/R (1 for equilateral); aspect ratio is the longest "
                     "side over the smallest altitude scaled so equilateral is 1.")
    parser.add_argument("input", metavar="IN", help="mesh file to read")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    parser.add_argument("--histogram", metavar="FILE.png",
                        help="also save a histogram of the minimum angles (.png, .svg, .pdf)")
    _common.similarity_tolerance(parser, "angle tolerance of the similarity classes")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        if args.histogram:
            _common.check_output(args.histogram, (args.input,), kinds="picture")
        mesh = read(args.input)
        d = report.quality(mesh, tolerance=args.tolerance)
        if args.histogram:
            from ..plot import min_angle_histogram

            ax = min_angle_histogram(mesh, title=f"Minimum angles: {args.input}")
            _common.save_figure(ax.figure, args.histogram)
        print(_common.dumps(d) if args.json else report.format_quality(d))
        if args.histogram:
            _common.note_written(args.histogram, f"histogram of {mesh.n_triangles} minimum "
                                 "angles", args)
    return 0
