"""Summaries of a mesh and of its quality, as plain dictionaries (JSON-ready) and as text.

:mod:`qdrefine.quality` gives one value per triangle; this module reduces them to figures.

Examples
--------
>>> from qdrefine import examples, report
>>> info = report.info(examples.plate_with_hole())
>>> info["triangles"], info["conforming"]
(384, True)
>>> print(report.format_quality(report.quality(examples.square(2))).splitlines()[0])
triangles                 8
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from . import quality as q
from .arguments import as_count
from .memory import check_needed, memory_needed
from .mesh import Mesh
from .refine import refine
from .schemes import get_scheme, scheme_names
from .topology import boundary_edges, conformity, euler_characteristic

__all__ = ["info", "quality", "compare", "format_info", "format_quality", "format_compare",
           "counted"]


def counted(n: int, noun: str) -> str:
    """``"1 triangle"``, ``"2 triangles"``: a count with its noun, plural unless one."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _sum(values: np.ndarray) -> float:
    """The sum rounded once (``math.fsum``): the same in any order of the values, so a
    report does not change when a mesh's triangles are numbered otherwise (NumPy's
    pairwise sum changed in its last digits)."""
    return math.fsum(values)


def _mean(values: np.ndarray) -> float:
    return _sum(values) / len(values) if len(values) else math.nan


def _sums_by(groups: np.ndarray, values: np.ndarray, n: int) -> list[float]:
    """:func:`_sum` of the ``values`` of each group ``0..n-1`` (``groups`` as
    ``np.unique``'s inverse)."""
    order = np.argsort(groups, kind="stable")
    cuts = np.searchsorted(groups[order], np.arange(1, n))
    return [_sum(part) for part in np.split(values[order], cuts)]


def _stats(values: np.ndarray) -> dict[str, float]:
    return {"min": float(values.min()), "max": float(values.max()),
            "mean": _mean(values), "median": float(np.median(values))}


def _apart(low: float, high: float) -> str:
    """``low, high`` with 6 significant digits, or as many more as show the interval's
    width to 6 digits (a disk of radius 1 at 1e8 showed [1e+08, 1e+08])."""
    for digits in range(6, 18):
        a, b = f"{low:.{digits}g}", f"{high:.{digits}g}"
        if max(abs(float(a) - low), abs(float(b) - high)) <= 1e-6 * (high - low):
            break
    return f"{a}, {b}"


def info(mesh: Mesh) -> dict[str, Any]:
    """Counts, bounding box, area, tags, conformity, orientation and angle figures."""
    used = np.unique(mesh.triangles)
    p = mesh.points
    box = p[used] if used.size else p  # the triangles' extent (not unused points)
    area = q.areas(mesh)
    conf = conformity(mesh)
    mins = q.min_angles(mesh)
    out: dict[str, Any] = {
        "points": mesh.n_points,
        "triangles": mesh.n_triangles,
        "unused_points": int(mesh.n_points - used.size),
        "boundary_edges": int(len(boundary_edges(mesh))),
        "euler_characteristic": euler_characteristic(mesh),
        "bounding_box": {"xmin": float(box[:, 0].min()), "ymin": float(box[:, 1].min()),
                         "xmax": float(box[:, 0].max()), "ymax": float(box[:, 1].max())},
        "area": _sum(area),
        "counter_clockwise": bool((area > 0).all()),
        "conforming": conf.ok,
        "conformity": {"overused_edges": conf.overused_edges,
                       "misoriented_edges": conf.misoriented_edges,
                       "hanging_nodes": conf.hanging_nodes,
                       "duplicate_points": conf.duplicate_points},
        "cell_tags": None,
        "edge_tags": None,
        "min_angle": {"min": float(mins.min()), "max": float(mins.max()),
                      "mean": _mean(mins)},
    }
    if mesh.cell_tags is not None:
        tags, inv = np.unique(np.asarray(mesh.cell_tags), return_inverse=True)
        inv = inv.reshape(-1)
        out["cell_tags"] = {
            str(int(t)): _named({"triangles": int(c), "area": float(a)}, mesh, 2, int(t))
            for t, c, a in zip(tags, np.bincount(inv), _sums_by(inv, area, len(tags)),
                               strict=True)}
    if mesh.edges is not None:
        tags, inv = np.unique(np.asarray(mesh.edge_tags), return_inverse=True)
        inv = inv.reshape(-1)
        seg = p[mesh.edges[:, 1]] - p[mesh.edges[:, 0]]
        length = np.hypot(seg[:, 0], seg[:, 1])
        out["edge_tags"] = {
            str(int(t)): _named({"edges": int(c), "length": float(s)}, mesh, 1, int(t))
            for t, c, s in zip(tags, np.bincount(inv), _sums_by(inv, length, len(tags)),
                               strict=True)}
    return out


def physical_name(mesh: Mesh, dim: int, tag: int) -> str | None:
    """The name of tag ``tag`` of dimension ``dim`` (2: cell tags, 1: edge tags), or None."""
    return (mesh.physical_names or {}).get((dim, tag))


def tag_label(tag: int | str, name: str | None) -> str:
    """``"2"``, or ``"2 (hole)"`` for a named tag: how reports and plots show a tag."""
    return str(tag) if name is None else f"{tag} ({name})"


def _named(entry: dict[str, Any], mesh: Mesh, dim: int, tag: int) -> dict[str, Any]:
    """``entry`` with the tag's physical name (``"name"``, null where the mesh has none:
    the same keys for every tag)."""
    return {"name": physical_name(mesh, dim, tag), **entry}


def quality(mesh: Mesh, *, bin_width: float = 2.5,
            tolerance: float = q.SIMILARITY_TOLERANCE) -> dict[str, Any]:
    """Figures of every per-triangle measure of :mod:`qdrefine.quality`, the minimum-angle
    histogram and the number of similarity classes (up to ``tolerance`` degrees)."""
    mins = q.min_angles(mesh)
    counts, edges = q.min_angle_histogram(mesh, bin_width=bin_width)
    labels, _ = q.similarity_classes(mesh, tolerance=tolerance)
    return {
        "triangles": mesh.n_triangles,
        "min_angle": _stats(mins),
        "max_angle": _stats(q.max_angles(mesh)),
        "radius_ratio": _stats(q.radius_ratios(mesh)),
        "aspect_ratio": _stats(q.aspect_ratios(mesh)),
        "below_20_degrees": int((mins < 20).sum()),
        "above_120_degrees": int((q.max_angles(mesh) > 120).sum()),
        "similarity_classes": int(labels.max()) + 1,
        "similarity_tolerance_degrees": tolerance,
        "min_angle_histogram": {"bin_edges": edges.tolist(), "counts": counts.tolist()},
    }


#: Bytes per triangle that measuring a mesh adds at its peak: angles and their sort,
#: similarity keys and ``np.unique``'s work, conformity's edge tables (an estimate from
#: above, with :func:`qdrefine.memory.memory_needed` for the refinement itself).
MEASURE_BYTES = 200
#: Bytes per triangle of a refined mesh kept (points, ``(M, 3)`` ids, tags).
KEPT_BYTES = 40


def check_study_memory(mesh: Mesh, schemes: Sequence[str], levels: int, what: str,
                       keep_all: bool = False) -> None:
    """``MemoryError`` before any work when refining ``mesh`` ``levels`` times with each of
    ``schemes`` and measuring every level would need more memory than is available
    (``keep_all``: every scheme's finest mesh is kept to the end); ``what`` names the study
    in the message."""
    if levels <= 0:
        return
    worst = kept = 0
    for name in schemes:
        sch = get_scheme(name)
        final = mesh.n_triangles * sch.n_children ** min(levels, 40)
        worst = max(worst, memory_needed(mesh.n_points, mesh.n_triangles, sch, levels,
                                         mesh.cell_tags is not None) + MEASURE_BYTES * final)
        kept += KEPT_BYTES * final if keep_all else 0
    check_needed(worst + kept, f"{what} ({mesh.n_triangles} triangles, {levels} level"
                               f"{'s' if levels != 1 else ''})")


def compare(mesh: Mesh, schemes: Sequence[str] | None = None, levels: int = 2, *,
            tolerance: float = q.SIMILARITY_TOLERANCE,
            step: Callable[[str, int], None] | None = None) -> list[dict[str, Any]]:
    """Refine ``mesh`` with each scheme level by level, and measure every level.

    Returns one row per scheme and level ``0..levels`` (level 0 is ``mesh``) with keys
    ``scheme, level, triangles, points, min_angle, mean_min_angle, similarity_classes``.
    ``step(scheme, level)`` is called after each level (for progress bars).
    """
    if isinstance(schemes, str):  # one scheme, not its characters
        schemes = [schemes]
    names = [get_scheme(n).name for n in (scheme_names() if schemes is None else schemes)]
    levels = as_count(levels, "levels")
    check_study_memory(mesh, names, levels, "comparing the schemes")
    rows = []
    for name in names:
        fine = mesh
        for level in range(levels + 1):
            if level:
                fine = refine(fine, name)
            mins = q.min_angles(fine)
            labels, _ = q.similarity_classes(fine, tolerance=tolerance)
            rows.append({"scheme": name, "level": level, "triangles": fine.n_triangles,
                         "points": fine.n_points, "min_angle": float(mins.min()),
                         "mean_min_angle": _mean(mins),
                         "similarity_classes": int(labels.max()) + 1})
            if step is not None:
                step(name, level)
    return rows


def _table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    rows = [[str(c) for c in r] for r in rows]
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(header)]
    line = "  ".join(h.ljust(w) if i == 0 else h.rjust(w)
                     for i, (h, w) in enumerate(zip(header, widths, strict=True)))
    out = [line, "-" * len(line)]
    for r in rows:
        out.append("  ".join(c.ljust(w) if i == 0 else c.rjust(w)
                             for i, (c, w) in enumerate(zip(r, widths, strict=True))))
    return "\n".join(out)


def format_info(d: dict[str, Any]) -> str:
    """Text for :func:`info`'s dictionary."""
    b = d["bounding_box"]
    c = d["conformity"]
    a = d["min_angle"]
    lines = [
        f"points                {d['points']} ({d['unused_points']} unused)",
        f"triangles             {d['triangles']}",
        f"boundary edges        {d['boundary_edges']}",
        f"Euler characteristic  {d['euler_characteristic']}",
        f"bounding box          [{_apart(b['xmin'], b['xmax'])}] x "
        f"[{_apart(b['ymin'], b['ymax'])}] (of the triangles)",
        f"area                  {d['area']:.10g}",
        f"orientation           "
        f"{'all counter-clockwise' if d['counter_clockwise'] else 'NOT all counter-clockwise'}"
        + (f" ({d['flipped_on_reading']} clockwise in the file, flipped on reading)"
           if d.get("flipped_on_reading") else ""),
        f"conforming            {'yes' if d['conforming'] else 'NO'} "
        f"({c['overused_edges']} overused edges, {c['misoriented_edges']} misoriented, "
        f"{c['hanging_nodes']} hanging nodes, {c['duplicate_points']} duplicate points)",
        f"minimum angle         smallest {a['min']:.4f}, largest {a['max']:.4f}, "
        f"mean {a['mean']:.4f} degrees",
    ]
    if d["cell_tags"] is None:
        lines.append("cell tags             none")
    else:
        lines.append("cell tags             " + ", ".join(
            f"{tag_label(t, v.get('name'))}: {counted(v['triangles'], 'triangle')}, area "
            f"{v['area']:.6g}"
            for t, v in d["cell_tags"].items()))
    if d["edge_tags"] is None:
        lines.append("edge tags             none")
    else:
        lines.append("edge tags             " + ", ".join(
            f"{tag_label(t, v.get('name'))}: {counted(v['edges'], 'edge')}, length "
            f"{v['length']:.6g}"
            for t, v in d["edge_tags"].items()))
    return "\n".join(lines)


def format_quality(d: dict[str, Any]) -> str:
    """Text for :func:`quality`'s dictionary: a table of measures and a text histogram."""
    head = [f"{'triangles':<25} {d['triangles']}"]
    rows = []
    for key, label in (("min_angle", "minimum angle (deg)"), ("max_angle", "maximum angle (deg)"),
                       ("radius_ratio", "radius ratio 2r/R"),
                       ("aspect_ratio", "aspect ratio")):
        s = d[key]
        rows.append([label, f"{s['min']:.4f}", f"{s['mean']:.4f}", f"{s['median']:.4f}",
                     f"{s['max']:.4f}"])
    table = _table(["measure", "min", "mean", "median", "max"], rows)
    tail = [
        f"{'min angle < 20 deg':<25} {d['below_20_degrees']}",
        f"{'max angle > 120 deg':<25} {d['above_120_degrees']}",
        f"{'similarity classes':<25} {d['similarity_classes']} "
        f"(two smallest angles in cells of {d['similarity_tolerance_degrees']:g} deg, "
        "touching cells joined)",
        "",
        "minimum-angle histogram (degrees)",
    ]
    h = d["min_angle_histogram"]
    counts, edges = h["counts"], h["bin_edges"]
    top = max(max(counts), 1)
    for i, c in enumerate(counts):
        if c:
            bar = "#" * max(1, round(40 * c / top))
            tail.append(f"  {edges[i]:5.1f} - {edges[i + 1]:5.1f}  {c:>9}  {bar}")
    return "\n".join(head + [table] + tail)


def format_compare(rows: Sequence[dict[str, Any]]) -> str:
    """Text table for :func:`compare`'s rows."""
    return _table(
        ["scheme", "level", "triangles", "points", "min angle", "mean min angle",
         "similarity classes"],
        [[r["scheme"], r["level"], r["triangles"], r["points"], f"{r['min_angle']:.4f}",
          f"{r['mean_min_angle']:.4f}", r["similarity_classes"]] for r in rows])
