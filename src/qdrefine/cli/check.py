"""``qdrefine check IN``: every problem of a mesh file, not just the first."""

from __future__ import annotations

import argparse
import warnings
from typing import Any

import numpy as np

from ..check import MIN_ANGLE, Checked, Problem
from ..check.report import Findings
from ..io import RawMesh, check_file
from ..schemes import get_scheme
from ..uniform import refused, refused_at_boundary
from . import _common

HELP = "check a mesh file: list every problem (exit 0 when usable, 1 when not)"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser, quiet=False)
    parser.epilog = ("Errors make the mesh unusable (qdrefine refuses to read it); warnings "
                     "do not (clockwise triangles are flipped on reading, unused points are "
                     "kept). Unreadable files end with one line 'qdrefine: error: ...'.")
    parser.add_argument("input", metavar="IN", help="mesh file to check (never modified)")
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")
    parser.add_argument("--min-angle", type=_angle, default=MIN_ANGLE, metavar="DEG",
                        help="warn about triangles with a smaller angle, above 0 and at most "
                        f"60 (default {MIN_ANGLE:g})")
    parser.add_argument("--scheme", default="7t-qd", metavar="NAME", type=_common.scheme_name,
                        help="warn about triangles that refining by this scheme would refuse "
                        "(too thin for float64 children; default 7t-qd)")


def _angle(text: str) -> float:
    """argparse type of ``--min-angle``: degrees in (0, 60]; every triangle's smallest angle
    is at most 60 degrees, so a larger threshold would flag every triangle."""
    value = _common.positive_float(text)
    if not value <= 60:
        raise argparse.ArgumentTypeError(f"expected degrees above 0 and at most 60 (every "
                                         f"triangle has an angle of 60 or less), got {text}")
    return value


def run(args: argparse.Namespace) -> int:
    with _common.session():
        with warnings.catch_warnings(record=True) as said:  # the reader's: in the report
            warnings.simplefilter("always")
            raw, found = check_file(args.input, min_angle=args.min_angle)
        for w in said:  # a library's deprecation notice and the like is not about the file
            if issubclass(w.category, UserWarning):
                found.problems.append(Problem("file", str(w.message)))
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        if found.ok:  # what refine would refuse: one level of the scheme, exactly
            refused_by_refine(raw, found, args.scheme)
        report = summary(args.input, found)
        print(_common.dumps(report) if args.json else format_report(report))
    return 0 if found.ok else 1


def refused_by_refine(raw: RawMesh, found: Checked, scheme: str) -> None:
    """Add the warnings of what one level of ``scheme`` refuses (numbered as the other
    problems of the file): ``too-close`` (two parts closer than float64 resolves, whose
    rounded boundary points would cross) and ``too-thin`` (triangles whose rounded new
    points would give a flat child)."""
    sch = get_scheme(scheme)
    names = Findings(False, raw.base, raw.point_numbers, raw.triangle_numbers)
    rows = refused(found.points, found.triangles, sch)
    if not rows.size:  # refine checks the thin triangles first: the boundary only then
        close = refused_at_boundary(found.points, found.triangles, sch)
        if close is not None:
            tri, verts = names.triangle(close.triangle), tuple(names.ids(close.vertices))
            scale = np.abs(found.points[found.triangles[close.triangle]]).max()
            found.problems.append(raw.locate(Problem(
                "too-close", f"triangle {tri} {verts} is closer to another part of the mesh "
                f"than float64 can resolve at its coordinates (up to {scale:.3g}): refining by "
                f"{sch.name} would round its new boundary points across the other part, and "
                "refine refuses it (translate the mesh nearer the origin, or separate the "
                "parts)", 1, {"triangle": tri, "vertices": list(verts), "scheme": sch.name})))
        return
    i = int(rows[0])
    tri, verts = names.triangle(i), tuple(names.ids(found.triangles[i]))
    found.problems.append(raw.locate(Problem(
        "too-thin", f"triangle {tri} {verts} is too thin for its distance from the origin: "
        f"refining it by {sch.name} would round its new points into a flat child, and "
        f"refine refuses it ({rows.size} such triangles; translate the mesh nearer the "
        "origin)", int(rows.size), {"triangle": tri, "vertices": list(verts),
                                    "scheme": sch.name})))


#: The mesh figures of a report, always present (null where the checks could not get
#: that far, e.g. a file without triangles); ``numbered_from`` is null where the file's own
#: numbers name points and triangles.
FIGURES = ("points", "used_points", "triangles", "edges", "boundary_edges",
           "euler_characteristic", "numbered_from", "numbered_by")


def summary(path: str, found: Checked) -> dict[str, Any]:
    """The JSON-ready report: file, usable, counts by severity, mesh figures, problems."""
    problems = [p.to_json() for p in found.problems]
    count = {s: sum(p["severity"] == s for p in problems) for s in ("error", "warning", "note")}
    figures = {key: found.summary.get(key) for key in FIGURES}
    if figures["numbered_by"] == "file":
        figures["numbered_from"] = None
    return {"file": str(path), "usable": found.ok, "errors": count["error"],
            "warnings": count["warning"], "notes": count["note"], **figures,
            "problems": problems}


def format_report(report: dict[str, Any]) -> str:
    """The report as text: one line of figures, one line per problem, the verdict."""
    lines = []
    if report.get("triangles") is not None:
        lines.append(f"{report['file']}: {_common.counted(report['points'], 'point')} "
                     f"({report['used_points']} used), "
                     f"{_common.counted(report['triangles'], 'triangle')}, "
                     f"{_common.counted(report['edges'], 'edge')} "
                     f"({report['boundary_edges']} on the boundary), Euler characteristic "
                     f"{report['euler_characteristic']}; " + (
                         "points and triangles named by the file's own node and element "
                         "numbers" if report.get("numbered_by") == "file" else
                         f"points and triangles numbered from {report.get('numbered_from', 0)}"
                         " in the order of the file"))
    width = max((len(p["kind"]) for p in report["problems"]), default=0)
    for p in report["problems"]:  # the widest kind sets the column (near-duplicate-points)
        lines.append(f"{p['severity']:8} {p['kind']:{width}} {p['count']:>8}  {p['message']}")
    verdict = "usable" if report["usable"] else "NOT usable"
    lines.append(f"{report['file']}: {verdict} ({_common.counted(report['errors'], 'error')}, "
                 f"{_common.counted(report['warnings'], 'warning')})")
    return "\n".join(lines)
