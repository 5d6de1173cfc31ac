"""Every check a triangle mesh can fail, on raw arrays: one place for :class:`~qdrefine.Mesh`,
the readers of :mod:`qdrefine.io` and ``qdrefine check``.

:func:`find` returns *all* problems of ``points (N, 2)`` and ``triangles (M, 3)`` (with the
optional tags), each a :class:`Problem` naming its kind, how many instances there are and
where the first one is. ``Mesh`` calls it with ``stop_at_error=True`` and raises the first
error as ``ValueError``; ``qdrefine check`` prints the whole list. :data:`KINDS` lists every
kind with its severity: an ``"error"`` makes the mesh unusable (``Mesh`` refuses it), a
``"warning"`` does not, a ``"note"`` says that a check was skipped.

Examples
--------
>>> from qdrefine import check
>>> found = check.find([[0, 0], [1, 0], [0, 1], [0, 1]], [[0, 1, 2], [1, 3, 2]])
>>> [p.kind for p in found.errors]
['zero-area', 'duplicate-points']
>>> found.errors[1].message
'points 2 and 3 are both at (0.0, 1.0)'
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray

from .jit import threads_for
from .memory import check_needed, validation_needed
from .numbering import EdgeBuckets, edge_ids, sort_edges
from .predicates import COORDINATE_RANGE, orient_signs
from .quality import min_angles
from .sweep import CROSSING, sweep, vertices_of

__all__ = ["KINDS", "MIN_ANGLE", "Checked", "Problem", "bucket_scan", "duplicate_pairs",
           "edge_scan", "find", "hanging_nodes", "index_dtype", "near_duplicates"]

#: Every kind of problem: its severity and what it means (the guide's table).
KINDS: dict[str, tuple[str, str]] = {
    "cell-types": ("error", "the file holds cells other than triangles, lines and vertices "
                            "(quads, tetrahedra, quadratic elements: refused)"),
    "not-flat": ("error", "3D points with some z != 0"),
    "points": ("error", "points are not an (N, 2) array of numbers"),
    "triangles": ("error", "triangles are not an (M, 3) array of integers"),
    "no-triangles": ("error", "the mesh has no triangles"),
    "non-finite": ("error", "a coordinate is NaN or infinite"),
    "coordinate-range": ("error", "a nonzero coordinate is outside [1e-100, 1e100] in "
                                  "magnitude (exact predicates)"),
    "index-range": ("error", "a triangle uses a vertex index that is not a point"),
    "zero-area": ("error", "a triangle has zero area (collinear or repeated corners)"),
    "clockwise": ("error", "a triangle is clockwise (readers flip it and warn instead)"),
    "duplicate-points": ("error", "two points used by triangles have identical coordinates"),
    "overused-edge": ("error", "an edge is shared by more than two triangles"),
    "folded-edge": ("error", "two triangles lie on the same side of their common edge "
                             "(they overlap)"),
    "hanging-node": ("error", "a vertex lies inside a boundary edge of another triangle "
                              "(non-conforming input)"),
    "self-intersection": ("error", "two boundary edges cross, or run along each other with "
                                   "their triangles on the same side (the mesh overlaps "
                                   "itself; the first one found is reported)"),
    "overlap": ("error", "part of the mesh lies on top of another part without any edges "
                         "crossing (e.g. a separate piece inside a triangle)"),
    "cell-tags": ("error", "cell_tags is not one integer per triangle"),
    "edge-tags": ("error", "tagged edges are not (K, 2) vertex indices with one integer tag "
                           "each"),
    "edge-not-in-mesh": ("error", "a tagged edge is not an edge of any triangle"),
    "near-hanging-node": ("warning", "a boundary vertex off another triangle's boundary edge "
                                     "by less than 1e-12 times its length, outside it (a "
                                     "crack; inside it would be an overlap)"),
    "near-duplicate-points": ("warning", "two used points closer than 1e-12 times the "
                                         "mesh's extent (not identical: that is an error)"),
    "unused-points": ("warning", "points used by no triangle (kept, carried through "
                                 "refinement)"),
    "pinched-vertex": ("warning", "a vertex where separate fans of triangles touch"),
    "small-angle": ("warning", "triangles with a smallest angle below the threshold"),
    "skipped": ("note", "checks that could not run because of an earlier error"),
}

#: Default threshold (degrees) of the ``small-angle`` warning.
MIN_ANGLE = 5.0

_CAP = 64  # instances kept per kind by the compiled searches (all are counted)


def index_dtype(n_points: int) -> type[np.integer]:
    """``int32`` while vertex indices fit, ``int64`` beyond."""
    return np.int32 if n_points <= np.iinfo(np.int32).max else np.int64


@dataclass(frozen=True)
class Problem:
    """One kind of problem found in a mesh.

    ``message`` names the first instance (e.g. ``"points 3 and 17 are both at (0.5, 0.25)"``),
    ``count`` the number of instances, ``where`` the ids of the first instance (JSON-ready;
    numbered as in the message), ``severity`` is ``KINDS[kind][0]`` unless said otherwise.
    """

    kind: str
    message: str
    count: int = 1
    where: dict[str, Any] = field(default_factory=dict)
    severity: str = ""

    def __post_init__(self) -> None:
        if not self.severity:
            object.__setattr__(self, "severity", KINDS[self.kind][0])

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "severity": self.severity, "count": self.count,
                "message": self.message, "where": self.where}


@dataclass
class Checked:
    """What :func:`find` found, and the normalized arrays: ``points (N, 2) float64`` (a copy),
    ``triangles (M, 3)`` of :func:`index_dtype` (clockwise rows flipped when asked), tags as
    ``int64``; arrays are ``None`` where they could not be normalized."""

    problems: list[Problem]
    points: NDArray[np.float64] | None = None
    triangles: NDArray[np.integer] | None = None
    cell_tags: NDArray[np.int64] | None = None
    edges: NDArray[np.integer] | None = None
    edge_tags: NDArray[np.int64] | None = None
    summary: dict[str, Any] = field(default_factory=dict)
    buckets: EdgeBuckets | None = None  # the sorted edges of ``triangles``, for refinement

    @property
    def errors(self) -> list[Problem]:
        return [p for p in self.problems if p.severity == "error"]

    @property
    def ok(self) -> bool:
        """True when nothing makes the mesh unusable."""
        return not self.errors

    def raise_first(self, prefix: str = "") -> None:
        """Raise ``ValueError(prefix + message)`` of the first error, if any."""
        if self.errors:
            raise ValueError(prefix + self.errors[0].message)


class _Stop(Exception):
    """Raised inside :func:`find` at the first error when ``stop_at_error``."""


class _Found:
    def __init__(self, stop: bool, base: int) -> None:
        self.problems: list[Problem] = []
        self.stop = stop
        self.base = base

    def add(self, kind: str, message: str, count: int = 1, severity: str = "",
            **where: Any) -> None:
        problem = Problem(kind, message, int(count), where, severity)
        self.problems.append(problem)
        if self.stop and problem.severity == "error":
            raise _Stop

    def skip(self, what: str, because: str) -> None:
        self.add("skipped", f"{what} not checked: {because}", severity="note")

    def ids(self, values: ArrayLike) -> list[int]:
        return [int(v) + self.base for v in np.ravel(values)]


def find(points: ArrayLike, triangles: ArrayLike, cell_tags: ArrayLike | None = None,
         edges: ArrayLike | None = None, edge_tags: ArrayLike | None = None, *,
         flip_clockwise: bool = False, stop_at_error: bool = False, warnings: bool = True,
         min_angle: float = MIN_ANGLE, geometry: bool = True, base: int = 0) -> Checked:
    """All problems of a mesh given as arrays.

    Parameters
    ----------
    points : (N, 2) float
    triangles : (M, 3) int
    cell_tags : (M,) int, optional
    edges : (K, 2) int, optional
        Tagged edges, given together with ``edge_tags (K,) int``.
    flip_clockwise : bool
        Flip clockwise triangles (a warning) instead of refusing them (an error); the
        readers do this.
    stop_at_error : bool
        Return at the first error (what :class:`~qdrefine.Mesh` needs).
    warnings : bool
        Also look for warnings (unused points, pinched vertices, small angles).
    min_angle : float
        Threshold of the ``small-angle`` warning, degrees.
    geometry : bool
        False skips every check that uses coordinates (e.g. for non-flat input).
    base : int
        Number of the first point and triangle in messages (files numbered from 1).

    Returns
    -------
    Checked
        Problems in the order checked (shape, coordinates, indices, orientation, topology,
        tags, warnings) and the normalized arrays.
    """
    found = _Found(stop_at_error, base)
    out = Checked(found.problems)
    try:
        _run(found, out, points, triangles, cell_tags, edges, edge_tags, flip_clockwise,
             warnings, min_angle, geometry)
    except _Stop:
        pass
    return out


def _run(found: _Found, out: Checked, points, triangles, cell_tags, edges, edge_tags,
         flip: bool, warnings: bool, min_angle: float, geometry: bool) -> None:
    p = _points(found, points)
    t = _triangles(found, triangles)
    if p is None or t is None:
        return
    out.points = p
    n = len(p)
    if not _in_range(found, t, n):
        return found.skip("orientation, topology and tags", "vertex indices out of range")
    t = out.triangles = np.array(t, dtype=index_dtype(n), order="C")
    geometry = geometry and _coordinates(found, p)
    if not geometry:
        found.skip("orientation, duplicate points, overlaps, hanging nodes and angles",
                   "no valid flat coordinates")
    check_needed(validation_needed(n, len(t), 0), f"validating {len(t)} triangles")
    oriented = flat = False
    if geometry:
        oriented, flat = _orientation(found, p, t, flip)
    topo = _Topology(t, n, sort_edges(t, n))
    used = None
    if not found.stop:
        used = _used(t, n)
        out.summary = _summary(t, used, topo) | {"numbered_from": found.base}
    manifold = _overused(found, topo)
    if oriented:
        oriented = _folded(found, topo) and manifold
    if geometry:
        # validation: duplicates among boundary vertices; one at an inner vertex is always
        # an overlap too, which the sweep finds
        _duplicates(found, p, vertices_of(topo.bedges, n) if used is None else
                    np.flatnonzero(used))
        if flat:
            _boundary(found, p, topo, oriented)
        else:
            found.skip("overlaps and hanging nodes", "triangles with zero area")
    out.cell_tags = _cell_tags(found, cell_tags, len(t))
    out.edges, out.edge_tags = _tagged_edges(found, edges, edge_tags, topo, n, t.dtype)
    if warnings:
        _unused(found, _used(t, n) if used is None else used)
        if geometry:
            _near_duplicates(found, p, np.flatnonzero(_used(t, n) if used is None else used))
        if oriented:
            _pinched(found, topo.bedges)
        if geometry:
            _small_angles(found, p, t, min_angle)
    out.buckets = topo.buckets


# shapes, coordinates, indices ---------------------------------------------------------------


def _points(found: _Found, points: ArrayLike) -> NDArray | None:
    try:
        p = np.array(points, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        found.add("points", f"points must be an (N, 2) array of numbers ({exc})")
        return None
    if p.ndim != 2 or p.shape[1] != 2:
        found.add("points", f"points must have shape (N, 2), got {p.shape}")
        return None
    return p


def _triangles(found: _Found, triangles: ArrayLike) -> NDArray | None:
    try:
        t = np.asarray(triangles)
    except (TypeError, ValueError) as exc:
        found.add("triangles", f"triangles must be an (M, 3) array of integers ({exc})")
        return None
    if t.size and not np.issubdtype(t.dtype, np.integer):
        found.add("triangles", f"triangles must hold integers, got dtype {t.dtype}")
        return None
    if t.size == 0 and t.ndim <= 2 and (t.ndim < 2 or t.shape[1] in (0, 3)):
        found.add("no-triangles", "the mesh has no triangles", 0)
        return None
    if t.ndim != 2 or t.shape[1] != 3:
        found.add("triangles", f"triangles must have shape (M, 3), got {t.shape}")
        return None
    return t


def _in_range(found: _Found, t: NDArray, n: int) -> bool:
    if n and t.min() >= 0 and t.max() < n:
        return True
    bad = ((t < 0) | (t >= n)).any(axis=1)
    if not bad.any():
        return True
    i = int(np.flatnonzero(bad)[0])
    b = found.base
    found.add("index-range", f"triangle {i + b} {tuple(found.ids(t[i]))} has a vertex index "
              f"outside {b}..{n - 1 + b}", np.count_nonzero(bad), triangle=i + b,
              vertices=found.ids(t[i]))
    return False


def _coordinates(found: _Found, p: NDArray) -> bool:
    lo, hi = COORDINATE_RANGE
    a = np.abs(p)
    if len(p) == 0 or (a.max() <= hi and np.where(a == 0, hi, a).min() >= lo):
        return True  # also False for NaN: max() of an array with NaN is NaN
    ok = True
    bad = ~np.isfinite(p).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        found.add("non-finite", f"point {i + found.base} has a non-finite coordinate "
                  f"{tuple(p[i].tolist())}", np.count_nonzero(bad), point=i + found.base)
        ok = False
    a = np.abs(np.where(np.isfinite(p), p, 0.0))
    bad = ((a > hi) | ((a < lo) & (a != 0))).any(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        found.add("coordinate-range",
                  f"point {i + found.base} has a coordinate {tuple(p[i].tolist())} outside "
                  f"the supported range: each coordinate must be 0 or between {lo:g} and "
                  f"{hi:g} in magnitude (exact predicates; rescale the mesh or round tiny "
                  "values to 0)", np.count_nonzero(bad), point=i + found.base)
        ok = False
    return ok


def _orientation(found: _Found, p: NDArray, t: NDArray, flip: bool) -> tuple[bool, bool]:
    """Zero-area and clockwise triangles; flips the clockwise rows of ``t`` when ``flip``.
    True when every triangle is (now) counter-clockwise, and True when none has zero area."""
    signs = orient_signs(p, t)
    zero = signs == 0
    if zero.any():
        i = int(np.flatnonzero(zero)[0])
        found.add("zero-area", f"triangle {i + found.base} {tuple(found.ids(t[i]))} has zero "
                  "area", np.count_nonzero(zero), triangle=i + found.base,
                  vertices=found.ids(t[i]))
    cw = signs < 0
    if cw.any():
        i = int(np.flatnonzero(cw)[0])
        k = int(np.count_nonzero(cw))
        where = {"triangle": i + found.base, "vertices": found.ids(t[i])}
        if flip:
            found.add("clockwise", f"{k} of {len(t)} triangles were clockwise and have been "
                      "flipped", k, "warning", **where)
            t[cw] = t[cw][:, ::-1]
        else:
            found.add("clockwise", f"triangle {i + found.base} {tuple(found.ids(t[i]))} is "
                      "clockwise; triangles must be counter-clockwise with positive area", k,
                      **where)
    return not zero.any() and (flip or not cw.any()), not zero.any()


# topology -------------------------------------------------------------------------------


class _Topology:
    """The sorted edges of ``t`` and one scan of them; the edge list and global ids are built
    only when a message or the tagged edges need them."""

    def __init__(self, t: NDArray, n: int, buckets: EdgeBuckets) -> None:
        self.t, self.n, self.buckets = t, n, buckets
        b = buckets
        (self.n_over, self.first_over, self.n_fold, self.first_fold, self.bedges,
         self.btris) = bucket_scan(t, b.local, b.starts, b.first, b.shift, b.mult)
        self._edges: tuple[NDArray, NDArray] | None = None

    @property
    def edges(self) -> NDArray:
        """``(E, 2)`` sorted edges."""
        if self._edges is None:
            self._edges = self.buckets.edges()
        return self._edges[0]

    def count(self, g: int) -> int:
        if self._edges is None:
            self._edges = self.buckets.edges()
        return int(self._edges[1][g])

    def triangles_of(self, g: int) -> list[int]:
        return np.flatnonzero((self.buckets.global_ids(self.t) == g).any(axis=1)).tolist()


@njit(parallel=True, cache=True)
def _mark_used(t, used):
    for k in prange(t.shape[0]):
        for i in range(3):
            used[t[k, i]] = True


def _used(t: NDArray, n: int) -> NDArray[np.bool_]:
    used = np.zeros(n, dtype=np.bool_)
    with threads_for(t.shape[0]):
        _mark_used(t, used)
    return used


def _summary(t: NDArray, used: NDArray, topo: _Topology) -> dict[str, Any]:
    n_used = int(np.count_nonzero(used))
    n_edges = topo.buckets.n_edges
    return {"points": len(used), "used_points": n_used, "triangles": len(t), "edges": n_edges,
            "boundary_edges": len(topo.bedges),
            "euler_characteristic": n_used - n_edges + len(t)}


@njit(cache=True)
def bucket_scan(t, local, starts, first, shift, mult):
    """:func:`edge_scan` from the sorted edges of :func:`qdrefine.numbering.sort_edges`
    (``local``, ``starts``, ``first``, ``shift`` and the multiplicities ``mult``)."""
    ne = first[first.shape[0] - 1]
    n_boundary = 0
    for b in range(first.shape[0] - 1):
        for u in range(first[b + 1] - first[b]):
            if mult[starts[b] + u] == 1:
                n_boundary += 1
    bedges = np.empty((n_boundary, 2), dtype=np.int64)
    btris = np.empty(n_boundary, dtype=np.int64)
    forward = np.zeros(ne, dtype=np.int8)
    j = 0
    for k in range(t.shape[0]):
        for i in range(3):
            u, v = t[k, i], t[k, (i + 1) % 3]
            b = min(u, v) >> shift
            cnt = mult[starts[b] + local[k, i]]
            if cnt == 1:
                bedges[j, 0], bedges[j, 1] = u, v
                btris[j] = k
                j += 1
            elif cnt == 2 and u < v:
                g = first[b] + local[k, i]
                forward[g] = min(forward[g] + 1, 3)
    n_over = n_fold = 0
    first_over = first_fold = -1
    for b in range(first.shape[0] - 1):
        for u in range(first[b + 1] - first[b]):
            g = first[b] + u
            cnt = mult[starts[b] + u]
            if cnt > 2:
                n_over += 1
                if first_over < 0:
                    first_over = g
            elif cnt == 2 and forward[g] != 1:
                n_fold += 1
                if first_fold < 0:
                    first_fold = g
    return n_over, first_over, n_fold, first_fold, bedges, btris


@njit(cache=True)
def edge_scan(t, tri_edges, counts):
    """One pass over the triangles' sides: the number of edges used more than twice and the
    first one, of edges walked the same way by both of their two triangles and the first one,
    and the boundary edges ``(B, 2)`` as oriented in their triangle ``(B,)``."""
    ne = counts.shape[0]
    n_boundary = 0
    for g in range(ne):
        if counts[g] == 1:
            n_boundary += 1
    bedges = np.empty((n_boundary, 2), dtype=np.int64)
    btris = np.empty(n_boundary, dtype=np.int64)
    forward = np.zeros(ne, dtype=np.int8)
    b = 0
    for k in range(t.shape[0]):
        for i in range(3):
            g = tri_edges[k, i]
            u, v = t[k, i], t[k, (i + 1) % 3]
            if u < v:
                forward[g] = min(forward[g] + 1, 3)
            if counts[g] == 1:
                bedges[b, 0], bedges[b, 1] = u, v
                btris[b] = k
                b += 1
    n_over = n_fold = 0
    first_over = first_fold = -1
    for g in range(ne):
        if counts[g] > 2:
            n_over += 1
            if first_over < 0:
                first_over = g
        elif counts[g] == 2 and forward[g] != 1:
            n_fold += 1
            if first_fold < 0:
                first_fold = g
    return n_over, first_over, n_fold, first_fold, bedges, btris


def _overused(found: _Found, topo: _Topology) -> bool:
    """True when no edge is shared by more than two triangles."""
    if not topo.n_over:
        return True
    g = topo.first_over
    e = topo.edges
    tris = [i + found.base for i in topo.triangles_of(g)]
    found.add("overused-edge", f"edge {tuple(found.ids(e[g]))} is shared by "
              f"{topo.count(g)} triangles {tuple(tris)}; at most two may share an edge",
              topo.n_over, edge=found.ids(e[g]), triangles=tris)
    return False


def _folded(found: _Found, topo: _Topology) -> bool:
    """True when every interior edge is walked both ways."""
    if not topo.n_fold:
        return True
    g = topo.first_fold
    e = topo.edges
    tris = [i + found.base for i in topo.triangles_of(g)]
    found.add("folded-edge", f"triangles {tris[0]} and {tris[1]} lie on the same side of "
              f"their common edge {tuple(found.ids(e[g]))}: they overlap",
              topo.n_fold, edge=found.ids(e[g]), triangles=tris)
    return False


def _duplicates(found: _Found, p: NDArray, ids: NDArray) -> None:
    count, pairs = duplicate_pairs(p, ids, _CAP)
    if count:
        a, b = (int(v) for v in pairs[np.lexsort(pairs[:, ::-1].T)[0]])
        xy = tuple(p[a].tolist())
        found.add("duplicate-points", f"points {a + found.base} and {b + found.base} are both "
                  f"at {xy}", count, points=[a + found.base, b + found.base], at=list(xy))


@njit(cache=True)
def duplicate_pairs(p, ids, cap):
    """Number of points ``p[ids]`` equal to one before them, and up to ``cap`` pairs
    ``(earlier, later)``: the points are bucketed on a grid (a counting sort), each bucket is
    compared pairwise when small and sorted when large, ``O(N log N)`` at worst."""
    k = ids.shape[0]
    pairs = np.empty((cap, 2), dtype=np.int64)
    if k < 2:
        return 0, pairs[:0]
    x, y = p[ids, 0], p[ids, 1]
    x0, x1, y0, y1 = x.min(), x.max(), y.min(), y.max()
    g = max(1, int(np.sqrt(k)))
    sx = (x1 - x0) / g if x1 > x0 else 1.0
    sy = (y1 - y0) / g if y1 > y0 else 1.0
    cell = np.empty(k, dtype=np.int64)
    start = np.zeros(g * g + 1, dtype=np.int64)
    for i in range(k):
        cell[i] = min(g - 1, int((x[i] - x0) / sx)) * g + min(g - 1, int((y[i] - y0) / sy))
        start[cell[i] + 1] += 1
    for c in range(g * g):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(k, dtype=np.int64)
    for i in range(k):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    count = 0
    for c in range(g * g):
        s, e = start[c], start[c + 1]
        if e - s < 2:
            continue
        run = order[s:e]
        if e - s > 16:  # sort by x, then by y within runs of equal x
            run = run[np.argsort(x[run])]
            q = 0
            while q < e - s:
                r = q + 1
                while r < e - s and x[run[r]] == x[run[q]]:
                    r += 1
                if r - q > 1:
                    run[q:r] = run[q:r][np.argsort(y[run[q:r]])]
                q = r
            for j in range(1, e - s):
                a, b = run[j - 1], run[j]
                if x[a] == x[b] and y[a] == y[b]:
                    if count < cap:
                        pairs[count, 0], pairs[count, 1] = ids[min(a, b)], ids[max(a, b)]
                    count += 1
            continue
        for j in range(1, e - s):
            for i in range(j):
                a, b = run[i], run[j]
                if x[a] == x[b] and y[a] == y[b]:
                    if count < cap:
                        pairs[count, 0], pairs[count, 1] = ids[min(a, b)], ids[max(a, b)]
                    count += 1
                    break
    return count, pairs[:min(count, cap)]


#: Two distinct used points closer than this times the mesh's extent are near duplicates.
NEAR_DUPLICATE = 1e-12


def _near_duplicates(found: _Found, p: NDArray, ids: NDArray) -> None:
    q = p[ids]
    if len(q) < 2:
        return
    extent = float(max(np.ptp(q[:, 0]), np.ptp(q[:, 1])))
    if not extent > 0:
        return
    tol = NEAR_DUPLICATE * extent
    count, a, b = near_duplicates(q, tol)
    if count:
        a, b = int(ids[a]), int(ids[b])
        d = float(np.hypot(*(p[a] - p[b])))
        found.add("near-duplicate-points", f"points {a + found.base} and {b + found.base} are "
                  f"only {d:.2g} apart ({d / extent:.2g} of the mesh's extent) at "
                  f"{tuple(p[a].tolist())}", count, points=[a + found.base, b + found.base],
                  distance=d)


def near_duplicates(q: NDArray, tol: float) -> tuple[int, int, int]:
    """Points of ``q (K, 2)`` with another point at a distance in ``(0, tol]``: their number
    and one such pair ``(i, j)`` (rows of ``q``; ``-1`` when none).

    The points are bucketed in square cells of side ``tol / sqrt(2)`` (sorted by cell): two
    different points in one cell are near; a point alone in its cell (or with copies only)
    looks at the 24 cells at most two away, each scanned by at most 24 such points, so the
    work is ``O(K log K)`` for the sort and ``O(K)`` after it, on any input.
    """
    h = tol / np.sqrt(2.0)
    cx = np.floor((q[:, 0] - q[:, 0].min()) / h).astype(np.int64)
    cy = np.floor((q[:, 1] - q[:, 1].min()) / h).astype(np.int64)
    order = np.lexsort((cy, cx))
    return _near_scan(np.ascontiguousarray(q[order]), cx[order], cy[order], order, tol * tol)


@njit(cache=True)
def _near_scan(q, cx, cy, order, tol2):
    k = q.shape[0]
    near = np.zeros(k, dtype=np.bool_)
    first_a = first_b = -1
    s = 0
    while s < k:  # cells: runs of equal (cx, cy)
        e = s + 1
        while e < k and cx[e] == cx[s] and cy[e] == cy[s]:
            e += 1
        mixed = -1
        for i in range(s + 1, e):
            if q[i, 0] != q[s, 0] or q[i, 1] != q[s, 1]:
                mixed = i
                break
        if mixed >= 0:
            for i in range(s, e):
                near[i] = True
            if first_a < 0:
                first_a, first_b = order[s], order[mixed]
        else:  # one position: look for a different point in the neighbouring cells
            for dx in range(-2, 3):  # a cell's side is tol / sqrt(2): two cells away
                x = cx[s] + dx
                lo = np.searchsorted(cx, x)  # the row of cells with this x
                hi = np.searchsorted(cx, x + 1)
                a = lo + np.searchsorted(cy[lo:hi], cy[s] - 2)
                b = lo + np.searchsorted(cy[lo:hi], cy[s] + 3)
                for j in range(a, b):
                    if s <= j < e:
                        continue
                    ddx, ddy = q[j, 0] - q[s, 0], q[j, 1] - q[s, 1]
                    d2 = ddx * ddx + ddy * ddy
                    if 0 < d2 <= tol2:
                        for i in range(s, e):
                            near[i] = True
                        if first_a < 0:
                            first_a, first_b = order[s], order[j]
                        break
        s = e
    return int(near.sum()), first_a, first_b


def _boundary(found: _Found, p: NDArray, topo: _Topology, covers: bool) -> None:
    """Hanging nodes, crossing boundary edges and doubly covered area: one plane sweep
    (:mod:`qdrefine.sweep`)."""
    bedges, btris = topo.bedges, topo.btris
    check_needed(validation_needed(len(p), len(topo.t), len(bedges)),
                 f"validating {len(topo.t)} triangles ({len(bedges)} boundary edges)")
    n_hang, hits, crossing, n_cov, first_cov, n_near, near, firsts, _ = sweep(
        p, bedges, covers, found.stop, _CAP)
    ids = found.ids
    add = []  # (when found, how to report), reported in the sweep's order
    if n_hang:
        add.append((firsts[0], lambda: _hanging(found, hits, n_hang, bedges, btris)))
    if crossing[0]:
        add.append((firsts[2], lambda: _crossing(found, crossing, bedges, btris)))
    if n_cov:
        add.append((firsts[1], lambda: _covered(found, first_cov, n_cov, bedges, btris,
                                                topo.t)))
    for _, report in sorted(add, key=lambda x: x[0]):
        report()
    if n_near and not found.stop and not crossing[0] and not n_cov:
        v, r, d = int(near[0]), int(near[1]), float(near[2])
        tri = int(btris[r]) + found.base
        found.add("near-hanging-node", f"vertex {v + found.base} is off edge "
                  f"{tuple(ids(bedges[r]))} of triangle {tri} by only {d:.2g} times its length "
                  "(outside it: a crack; refinement decides it exactly)", n_near,
                  vertex=v + found.base, edge=ids(bedges[r]), triangle=tri, distance=d)


def _crossing(found: _Found, crossing: NDArray, bedges: NDArray, btris: NDArray) -> None:
    r, s = int(crossing[1]), int(crossing[2])
    ta, tb = int(btris[r]) + found.base, int(btris[s]) + found.base
    how = ("cross" if crossing[0] == CROSSING else
           "run along each other with both triangles on the same side")
    found.add("self-intersection", f"edge {tuple(found.ids(bedges[r]))} of triangle {ta} and "
              f"edge {tuple(found.ids(bedges[s]))} of triangle {tb} {how}: the mesh overlaps "
              "itself there", 1, triangles=[ta, tb],
              edges=[found.ids(bedges[r]), found.ids(bedges[s])])


def _covered(found: _Found, row: int, count: int, bedges: NDArray, btris: NDArray,
             t: NDArray) -> None:
    tri = int(btris[row]) + found.base
    found.add("overlap", f"triangle {tri} {tuple(found.ids(t[btris[row]]))} overlaps another "
              f"part of the mesh (the area along its edge {tuple(found.ids(bedges[row]))} is "
              "covered twice)", count, triangle=tri, edge=found.ids(bedges[row]))


def _hanging(found: _Found, hits: NDArray, count: int, bedges: NDArray, btris: NDArray
             ) -> None:
    v, row = (int(x) for x in hits[0])
    edge, tri = found.ids(bedges[row]), int(btris[row]) + found.base
    found.add("hanging-node", f"vertex {v + found.base} lies inside edge {tuple(edge)} of "
              f"triangle {tri} (a hanging node: the mesh is not conforming there)",
              count, vertex=v + found.base, edge=edge, triangle=tri)


def hanging_nodes(points: NDArray, bedges: NDArray) -> tuple[int, NDArray[np.int64]]:
    """Vertices of ``bedges (B, 2)`` lying strictly inside one of them (exact test).

    Returns the number of (vertex, edge) pairs and up to 64 of them as rows ``(vertex, edge
    row)``. A hanging node of a mesh whose triangles do not overlap is always a boundary
    vertex inside a boundary edge, so only those are tested, by the plane sweep of
    :mod:`qdrefine.sweep` (``O(B log B)``). Where two edges cross, the sweep stops there:
    the count covers the vertices before that crossing.
    """
    n_hang, hits = sweep(points, bedges, False, False, _CAP)[:2]
    return int(n_hang), hits



# tags -----------------------------------------------------------------------------------


def _integers(found: _Found, kind: str, value: ArrayLike, name: str) -> NDArray | None:
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:
        found.add(kind, f"{name} must hold integers ({exc})")
        return None
    if a.size and not np.issubdtype(a.dtype, np.integer):
        found.add(kind, f"{name} must hold integers, got dtype {a.dtype}")
        return None
    return a.astype(np.int64)


def _cell_tags(found: _Found, cell_tags: ArrayLike | None, m: int) -> NDArray | None:
    if cell_tags is None:
        return None
    ct = _integers(found, "cell-tags", cell_tags, "cell_tags")
    if ct is not None and ct.shape != (m,):
        found.add("cell-tags", f"cell_tags must have shape ({m},), got {ct.shape}")
        return None
    return ct


def _tagged_edges(found: _Found, edges, edge_tags, topo: _Topology, n: int,
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
        found.add("edge-tags", f"edge {i} {tuple(found.ids(e[i]))} has a vertex index outside "
                  f"{found.base}..{n - 1 + found.base}", np.count_nonzero(bad), edge_row=i)
        return None, None

    missing = edge_ids(topo.edges, e, n) < 0
    if missing.any():
        i = int(np.flatnonzero(missing)[0])
        found.add("edge-not-in-mesh", f"edge {i} {tuple(found.ids(e[i]))} is not an edge of "
                  "any triangle", np.count_nonzero(missing), edge_row=i, edge=found.ids(e[i]))
        return None, None
    return np.ascontiguousarray(e, dtype=dtype), et


# warnings -------------------------------------------------------------------------------


def _unused(found: _Found, used: NDArray) -> None:
    n = len(used)
    if not used.all():
        unused = np.flatnonzero(~used)
        found.add("unused-points", f"{len(unused)} of {n} points are used by no triangle "
                  f"(first: point {int(unused[0]) + found.base}); they are kept",
                  len(unused), point=int(unused[0]) + found.base)


def _pinched(found: _Found, bedges: NDArray) -> None:
    out = np.bincount(bedges[:, 0], minlength=1)
    pinched = np.flatnonzero(out > 1)
    if len(pinched):
        v = int(pinched[0])
        found.add("pinched-vertex", f"vertex {v + found.base} joins {int(out[v])} separate fans "
                  "of triangles (the mesh touches itself there)", len(pinched),
                  vertex=v + found.base)


def _small_angles(found: _Found, p: NDArray, t: NDArray, min_angle: float) -> None:
    angles = min_angles(p, t)
    small = angles < min_angle
    if small.any():
        i = int(np.argmin(angles))
        found.add("small-angle", f"{int(small.sum())} triangles have an angle below "
                  f"{min_angle:g} degrees (smallest: {angles[i]:.3g} degrees in triangle "
                  f"{i + found.base})", int(small.sum()), triangle=i + found.base,
                  angle=float(angles[i]))
