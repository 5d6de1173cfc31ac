"""Checks of the arrays themselves: shapes, coordinates, vertex indices, orientation, cell
tags and tagged edges (each adds to a :class:`~qdrefine.check.report.Findings`)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray

from ..arguments import as_coordinates, refuse_masked
from ..jit import threads_for
from ..numbering import edge_ids
from ..predicates import COORDINATE_RANGE, orient_signs
from ..quality import min_angles
from .edges import Topology
from .report import Findings

__all__ = ["points", "triangles", "in_range", "coordinates", "misoriented", "orientation",
           "cell_tags", "tagged_edges", "small_angles"]


def points(found: Findings, points: ArrayLike) -> NDArray | None:
    try:
        p = as_coordinates(points, "points")
    except ValueError as exc:
        found.add("points", str(exc))
        return None
    if p.ndim != 2 or p.shape[1] != 2:
        found.add("points", f"points must have shape (N, 2), got {p.shape}")
        return None
    return p


def triangles(found: Findings, triangles: ArrayLike) -> NDArray | None:
    try:  # np.asarray drops the mask: masked triangles would be kept
        refuse_masked(triangles, "triangles", "give a plain array of the triangles to keep")
    except ValueError as exc:
        found.add("triangles", str(exc))
        return None
    try:
        t = np.asarray(triangles)
    except (TypeError, ValueError) as exc:
        found.add("triangles", f"triangles must be an (M, 3) array of integers ({exc})")
        return None
    if t.size and not np.issubdtype(t.dtype, np.integer):
        found.add("triangles", f"triangles must hold integers, got dtype {t.dtype}")
        return None
    if t.size == 0 and t.ndim <= 2 and (t.ndim < 2 or t.shape[1] in (0, 3)):
        found.add("no-triangles", "the mesh has no triangles", 1)
        return None
    if t.ndim != 2 or t.shape[1] != 3:
        found.add("triangles", f"triangles must have shape (M, 3), got {t.shape}")
        return None
    return t


def in_range(found: Findings, t: NDArray, n: int) -> bool:
    if n and t.min() >= 0 and t.max() < n:
        return True
    bad = ((t < 0) | (t >= n)).any(axis=1)
    if not bad.any():
        return True
    i = int(np.flatnonzero(bad)[0])
    b = found.base
    vertices = [int(v) + b for v in t[i]]  # not all are points: numbered from the base
    found.add("index-range", f"triangle {found.triangle(i)} {tuple(vertices)} has a vertex "
              f"index outside {b}..{n - 1 + b}", np.count_nonzero(bad),
              triangle=found.triangle(i), vertices=vertices)
    return False


def coordinates(found: Findings, p: NDArray) -> bool:
    lo, hi = COORDINATE_RANGE
    a = np.abs(p)
    if len(p) == 0 or (a.max() <= hi and np.where(a == 0, hi, a).min() >= lo):
        return True  # also False for NaN: max() of an array with NaN is NaN
    ok = True
    bad = ~np.isfinite(p).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        found.add("non-finite", f"point {found.point(i)} has a non-finite coordinate "
                  f"{tuple(p[i].tolist())}", np.count_nonzero(bad), point=found.point(i))
        ok = False
    a = np.abs(np.where(np.isfinite(p), p, 0.0))
    bad = ((a > hi) | ((a < lo) & (a != 0))).any(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        found.add("coordinate-range",
                  f"point {found.point(i)} has a coordinate {tuple(p[i].tolist())} outside "
                  f"the supported range: each coordinate must be 0 or between {lo:g} and "
                  f"{hi:g} in magnitude (exact predicates; rescale the mesh or round tiny "
                  "values to 0)", np.count_nonzero(bad), point=found.point(i))
        ok = False
    return ok


def misoriented(triangle: int, vertices, zero: bool) -> str:
    """The message of a triangle with zero area (``zero``) or clockwise, named by
    ``triangle`` and its ``vertices``: the words of every refusal of one (``Mesh``, the GPU
    and the Dask paths)."""
    named = f"triangle {triangle} {tuple(int(v) for v in vertices)}"
    return f"{named} has zero area" if zero else \
        f"{named} is clockwise; triangles must be counter-clockwise with positive area"


def orientation(found: Findings, p: NDArray, t: NDArray, flip: bool) -> tuple[bool, bool]:
    """Zero-area and clockwise triangles; flips the clockwise rows of ``t`` when ``flip``.
    True when every triangle is (now) counter-clockwise, and True when none has zero area.

    Without ``flip`` the kind whose first triangle comes first is reported first, so that
    ``Mesh`` (which stops at the first error) names the first bad row, as the GPU and Dask
    paths do."""
    signs = orient_signs(p, t)
    zero = signs == 0
    cw = signs < 0
    reports = []  # (order, row named, kind, message, count, severity)
    if zero.any():
        i = int(np.flatnonzero(zero)[0])
        reports.append((i, i, "zero-area", misoriented(found.triangle(i), found.ids(t[i]), True),
                        np.count_nonzero(zero), ""))
    if cw.any():
        i = int(np.flatnonzero(cw)[0])
        k = int(np.count_nonzero(cw))
        if flip:  # a warning, after any error
            reports.append((len(t), i, "clockwise", f"{k} of {len(t)} triangles were clockwise "
                            "and have been flipped", k, "warning"))
        else:
            reports.append((i, i, "clockwise", misoriented(found.triangle(i), found.ids(t[i]),
                                                           False), k, ""))
    for _, i, kind, message, count, severity in sorted(reports, key=lambda r: r[0]):
        found.add(kind, message, count, severity, triangle=found.triangle(i),
                  vertices=found.ids(t[i]))
    if flip and cw.any():
        t[cw] = t[cw][:, ::-1]
    return not zero.any() and (flip or not cw.any()), not zero.any()


def _integers(found: Findings, kind: str, value: ArrayLike, name: str) -> NDArray | None:
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:
        found.add(kind, f"{name} must hold integers ({exc})")
        return None
    problem = not_int64(a, name)
    if problem is not None:
        found.add(kind, problem)
        return None
    return a.astype(np.int64)


def not_int64(a: NDArray, name: str) -> str | None:
    """Why the array ``a`` cannot be taken as int64 values (``name`` starts the message):
    not integers (1.7 would become 1), or unsigned beyond int64 (it would wrap to a
    negative); None when it can."""
    if a.size and not np.issubdtype(a.dtype, np.integer):
        return f"{name} must hold integers, got dtype {a.dtype}"
    if a.size and a.dtype.kind == "u" and a.max() > np.iinfo(np.int64).max:
        return f"{name} holds {int(a.max())}, beyond int64"
    return None


def cell_tags(found: Findings, cell_tags: ArrayLike | None, m: int) -> NDArray | None:
    if cell_tags is None:
        return None
    ct = _integers(found, "cell-tags", cell_tags, "cell_tags")
    if ct is not None and ct.shape != (m,):
        found.add("cell-tags", f"cell_tags must have shape ({m},), got {ct.shape}")
        return None
    return ct


def tagged_edges(found: Findings, edges, edge_tags, topo: Topology, n: int,
                  dtype) -> tuple[NDArray | None, NDArray | None]:
    if edges is None and edge_tags is None:
        return None, None
    if edges is None or edge_tags is None:
        found.add("edge-tags", "edges and edge_tags must be given together")
        return None, None
    e = _integers(found, "edge-tags", edges, "edges")
    et = _integers(found, "edge-tags", edge_tags, "edge_tags")
    if e is None or et is None:
        return None, None
    if e.size == 0:
        e = e.reshape(0, 2)
    if e.ndim != 2 or e.shape[1] != 2:
        found.add("edge-tags", f"edges must have shape (K, 2), got {e.shape}")
        return None, None
    if et.shape != (e.shape[0],):
        found.add("edge-tags", f"edge_tags must have shape ({e.shape[0]},), got {et.shape}")
        return None, None
    bad = ((e < 0) | (e >= n)).any(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        ends = tuple(int(v) + found.base for v in e[i])  # not all are points
        found.add("edge-tags", f"edge {found.edge(i)} {ends} has a vertex index outside "
                  f"{found.base}..{n - 1 + found.base}", np.count_nonzero(bad), edge_row=i)
        return None, None

    missing = edge_ids(topo.edges, e, n) < 0
    if missing.any():
        i = int(np.flatnonzero(missing)[0])
        found.add("edge-not-in-mesh", f"edge {found.edge(i)} {tuple(found.ids(e[i]))} is not "
                  "an edge of "
                  "any triangle", np.count_nonzero(missing), edge_row=i, edge=found.ids(e[i]))
        return None, None
    return np.ascontiguousarray(e, dtype=dtype), et


def small_angles(found: Findings, p: NDArray, t: NDArray, min_angle: float) -> None:
    angles = np.empty(t.shape[0])
    with threads_for(t.shape[0]):
        _smallest_angles(p, t, angles)
    small = angles < min_angle
    if small.any():
        i = int(np.argmin(angles))
        angle = float(min_angles(p, t[i:i + 1])[0])  # the value quality reports, bit for bit
        many = int(small.sum())
        found.add("small-angle", f"{many} triangle{' has' if many == 1 else 's have'} an "
                  "angle below "
                  f"{min_angle:g} degrees (smallest: {angle:.3g} degrees in triangle "
                  f"{found.triangle(i)})", int(small.sum()), triangle=found.triangle(i),
                  angle=angle)


@njit(parallel=True, cache=True)
def _smallest_angles(p, t, out):
    """Smallest angle (degrees) of every triangle, by the formula of
    :func:`qdrefine.quality.angles` without its temporaries."""
    for k in prange(t.shape[0]):
        best = np.inf
        for i in range(3):
            o, u, w = t[k, i], t[k, (i + 1) % 3], t[k, (i + 2) % 3]
            a0, a1 = p[u, 0] - p[o, 0], p[u, 1] - p[o, 1]
            b0, b1 = p[w, 0] - p[o, 0], p[w, 1] - p[o, 1]
            angle = math.atan2(abs(a0 * b1 - a1 * b0), a0 * b0 + a1 * b1)
            best = min(best, angle)
        out[k] = best * (180.0 / math.pi)
