"""``qdrefine compare IN``: refine with each scheme, level by level, and measure."""

from __future__ import annotations

import argparse

from .. import report
from ..io import read
from ..schemes import scheme_names
from . import _common

HELP = "refine with several schemes level by level: min angle, mean, similarity classes"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser, quiet_also=" (and the JSON that --json asks for)")
    parser.epilog = ("Similarity classes: triangles whose two smallest angles agree to "
                     "within --tolerance degrees have the same shape (mirror images "
                     "included; cells of that side in the plane of the two angles, touching "
                     "cells joined).")
    parser.add_argument("input", metavar="IN", help="mesh file to read")
    parser.add_argument("--levels", type=_common.non_negative, default=2, metavar="N",
                        help="refinement levels (default 2; 7T schemes multiply the triangles "
                             "by 7 per level)")
    parser.add_argument("--schemes", nargs="+", metavar="NAME", default=None,
                        type=_common.scheme_names_list,
                        help=f"schemes to compare, by spaces or commas (default all: "
                             f"{' '.join(scheme_names())})")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    parser.add_argument("--plot", metavar="FILE.png",
                        help="also save a plot of the three figures against the level")
    _common.similarity_tolerance(parser, "similarity tolerance")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        schemes = list(dict.fromkeys(name for names in args.schemes for name in names)) \
            if args.schemes else scheme_names()  # each once, in the order given
        if args.plot:
            _common.check_output(args.plot, (args.input,), kinds="picture")
        mesh = read(args.input)
        with _common.Progress(len(schemes) * (args.levels + 1), args.quiet) as progress:
            progress.step(f"{schemes[0]}, level 0")
            rows = report.compare(
                mesh, schemes, args.levels, tolerance=args.tolerance,
                step=lambda s, lv: progress.step(f"{s}, level {lv}"))
        if args.plot:
            import matplotlib.pyplot as plt

            from ..plot import COMPARE_METRICS
            from ..plot import compare as plot_compare

            fig, axes = plt.subplots(1, 3, figsize=(15, 4.5), layout="constrained")
            for ax, metric in zip(axes, COMPARE_METRICS, strict=True):
                plot_compare(rows, metric, ax)
            fig.suptitle(f"{args.input}: {mesh.n_triangles} triangles refined level by level")
            _common.save_figure(fig, args.plot)
        if args.json:
            print(_common.dumps({"input": args.input, "similarity_tolerance_degrees":
                                 args.tolerance, "rows": rows}))
        elif not args.quiet:
            print(report.format_compare(rows))
            print(f"similarity classes: two smallest angles in cells of {args.tolerance:g} "
                  "degrees, touching cells joined")
        if args.plot:
            levels = f"{args.levels} level{'s' if args.levels != 1 else ''}"
            _common.note_written(args.plot, f"{len(schemes)} schemes over {levels}", args)
    return 0
