"""``qdrefine diagram``: the areas of the mapping diagram's regions, recomputed."""

from __future__ import annotations

import argparse
import json
import math

from ..diagram.quadrature import SMALLEST_TOL
from . import _common

HELP = "areas of the regions of the paper's mapping diagram (exact arcs + quadrature)"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser, quiet=False)  # one-line argument errors; it prints only its table
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--tol", type=_common.float_between(
                            SMALLEST_TOL, 1e-6, "float64 rounding bounds the error estimates "
                            "at about 3e-14"), default=1e-10, metavar="T",
                        help=f"quadrature tolerance on each area, {SMALLEST_TOL:g} to 1e-6 "
                             "(default 1e-10)")
    parser.add_argument("--no-angle-measure", action="store_true",
                        help="skip the fractions under the two-smallest-angles measure")


def run(args: argparse.Namespace) -> int:
    from ..diagram import compute
    from ..paper import PAPER_CLAIMS

    res = compute(tol=args.tol, angle_measure=not args.no_angle_measure)
    obj = res.to_json()
    obj["paper_claims"] = {
        "note": "what the paper says (quoted, not computed)",
        **{k: v for k, v in PAPER_CLAIMS.items()},
    }
    if args.json:
        print(json.dumps(obj, indent=2, allow_nan=False,
                         default=lambda v: None if isinstance(v, float) and math.isnan(v)
                         else str(v)))
        return 0
    print(f"left half of the diagram: area {obj['diagram_area']:.12f} (pi/6 - sqrt(3)/8)")
    print(f"{'region':8} {'fraction':>14} {'area':>14} {'error':>9}  method")
    for k, v in obj["fractions"].items():
        print(f"{k:8} {v:>14.10f} {obj['areas'][k]:>14.10f} {obj['errors'][k]:>9.1e}  "
              f"{obj['method']['regions'][k]}")
    print(f"7T-LE min angle > 7T-QD min angle on {obj['le_min_above_qd']:.10f} of the half")
    for r, e in obj["worst_qd_over_d_by_reading"].items():
        print(f"worst 7T-QD / 7T-D min angle ({r}): {e['value']:.12f} "
              f"(certified bound {e['bound']:.1e}; {e['where']})")
    print(f"largest error estimate of any fraction: {obj['error_bound']:.1e}")
    return 0
