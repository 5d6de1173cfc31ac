"""``qdrefine info IN``: what a mesh file holds."""

from __future__ import annotations

import argparse

from .. import report
from ..io import read
from . import _common

HELP = "describe a mesh: counts, bounding box, area, tags, conformity, angles"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser, quiet=False)
    parser.add_argument("input", metavar="IN", help="mesh file to read")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        d = report.info(read(args.input))
        print(_common.dumps(d) if args.json else report.format_info(d))
    return 0
