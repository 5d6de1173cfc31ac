"""``qdrefine info IN``: what a mesh file holds."""

from __future__ import annotations

import argparse

import numpy as np

from .. import report
from ..io import mesh_of, read_raw
from . import _common

HELP = "describe a mesh: counts, bounding box, area, tags, conformity, angles"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser, quiet=False)
    parser.add_argument("input", metavar="IN", help="mesh file to read")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        raw = read_raw(args.input)
        mesh = mesh_of(raw)  # flips clockwise triangles, with a warning
        d = report.info(mesh)
        # what the file holds: the rows reading turned around (same order, same points)
        rows = np.asarray(raw.triangles)
        d["flipped_on_reading"] = int((rows != mesh.triangles).any(axis=1).sum()) \
            if rows.shape == mesh.triangles.shape else 0
        print(_common.dumps(d) if args.json else report.format_info(d))
    return 0
