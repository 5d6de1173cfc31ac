"""``qdrefine paper OUTDIR``: every figure and claim of the 7T-QD paper, recomputed."""

from __future__ import annotations

import argparse

from . import _common

HELP = ("recompute the paper's figures, Table 1, claims, certified extrema and the iterated "
        "refinement study into OUTDIR (report.md, PNG, SVG)")


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser)
    parser.add_argument("outdir", metavar="OUTDIR", help="output directory (created if missing)")
    parser.add_argument("--no-figures", action="store_true", help="write report.md only")


def run(args: argparse.Namespace) -> int:
    from ..paper import CONTEXT_STEPS, write_all

    with _common.Progress(CONTEXT_STEPS + (1 if args.no_figures else 2), args.quiet) as bar:
        path = write_all(args.outdir, figures=not args.no_figures, progress=bar.step)
    if not args.quiet:
        print(f"wrote {path}" if args.no_figures else
              f"wrote {path} and the figures in {path.parent}")
    return 0
