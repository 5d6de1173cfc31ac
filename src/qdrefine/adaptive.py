"""Adaptive conforming local refinement: marked triangles, a longest-edge closure, transitions.

Every marked triangle is partitioned by the scheme. To keep the mesh conforming, a set of
*split edges* is closed under one rule, applied in rounds over whole arrays:

    a triangle with any split edge has its longest edge split.

Each triangle then has no split edge (copied unchanged), its longest edge ``MN`` only,
``MN`` and one other edge, or all three edges split (the scheme's full partition). The
transition patterns (canonical labelling, stencil ``M N O D C Q B A P`` of
:mod:`qdrefine.stencil`):

=================  ===========================================================
split edges        children
=================  ===========================================================
``MN``             ``MDO, DCO, CNO`` (7T; the only triangulation) -- ``MmO, mNO`` (4T)
``MN, NO``         7T: max-min-angle triangulation of the heptagon ``M D C N Q B O``
                   4T: ``MmO, mqO, mNq`` (longest-edge bisection)
``MN, OM``         7T: max-min-angle triangulation of the heptagon ``M D C N O A P``
                   4T: ``Mmp, mOp, mNO``
all three          the scheme's partition (identical to uniform refinement)
=================  ===========================================================

Quality guard (seven-triangle schemes): a triangle whose transition would create a child
with a minimum angle below ``min_angle`` is treated as marked and the closure runs again.
See ``docs/adaptive.md`` for the closure's termination and the quality study.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike, NDArray

from .kernels import CHUNK, canonical, edge_points, emit, number_edges
from .mesh import Mesh, index_dtype
from .predicates import SCRATCH
from .quality import angles
from .refine import as_count, split_tagged_edges
from .schemes import Scheme, get_scheme

__all__ = [
    "refine_marked",
    "refine_cycles",
    "KEEP",
    "closure",
    "canonical_labels",
    "canonical_edges",
    "as_mask",
    "TRANSITIONS",
]

#: Default quality floor of the transitions, as a fraction of the input's minimum angle.
KEEP = 0.5

# bit of each canonical edge in a triangle's split code
MN, NO, OM = 1, 2, 4
FULL = MN | NO | OM


@njit(parallel=True, cache=True)
def _labels(points, triangles, out):
    m = triangles.shape[0]
    n_chunks = (m + CHUNK - 1) // CHUNK
    for ch in prange(n_chunks):
        buf = np.empty(SCRATCH)
        for t in range(ch * CHUNK, min(m, (ch + 1) * CHUNK)):
            v0 = triangles[t, 0]
            v1 = triangles[t, 1]
            v2 = triangles[t, 2]
            im, jn, ko = canonical(points[v0, 0], points[v0, 1], points[v1, 0], points[v1, 1],
                                   points[v2, 0], points[v2, 1], buf)
            out[t, 0] = im
            out[t, 1] = jn
            out[t, 2] = ko


def canonical_labels(points: NDArray[np.float64], triangles: NDArray[np.integer]
                     ) -> NDArray[np.int8]:
    """Local indices ``(M, 3) int8`` of ``(M, N, O)`` for every triangle (exact, tie rules
    of :mod:`qdrefine.schemes`), the same labelling uniform refinement uses."""
    out = np.empty((triangles.shape[0], 3), dtype=np.int8)
    if triangles.shape[0]:
        _labels(points, triangles, out)
    return out


def canonical_edges(labels: NDArray[np.int8], tri_edges: NDArray[np.int64]
                    ) -> NDArray[np.int64]:
    """Edge ids ``(M, 3)`` of the canonical edges ``MN, NO, OM`` of each triangle.

    ``tri_edges[:, i]`` is the edge ``(v_i, v_{i+1})``, so the edge between local vertices
    ``a`` and ``b`` is column ``a`` when ``b == a + 1 (mod 3)`` and column ``b`` otherwise.
    """
    a = labels.astype(np.int64)
    b = np.roll(a, -1, axis=1)
    col = np.where(b == (a + 1) % 3, a, b)
    return np.take_along_axis(tri_edges, col, axis=1)


def closure(cedges: NDArray[np.int64], marked: NDArray[np.bool_], n_edges: int
            ) -> tuple[NDArray[np.bool_], int]:
    """Split edges: all edges of marked triangles, closed under the longest-edge rule.

    Parameters
    ----------
    cedges : (M, 3) int64
        Canonical edge ids (``MN, NO, OM``) per triangle, see :func:`canonical_edges`.
    marked : (M,) bool
    n_edges : int

    Returns
    -------
    split : (E,) bool
    rounds : int
        Number of propagation rounds (each one pass over the arrays).

    The set only grows and is bounded by the edge set, so the loop ends after at most
    ``E`` rounds; in practice the rounds follow longest-edge propagation paths, whose length
    is bounded by the number of times the edge length can grow along a path.
    """
    split = np.zeros(n_edges, dtype=bool)
    split[cedges[marked].ravel()] = True
    longest = cedges[:, 0]
    rounds = 0
    # only triangles touching a newly split edge can change: follow a frontier
    active = np.flatnonzero(split[cedges].any(axis=1))
    while active.size:
        rounds += 1
        new = longest[active]
        new = np.unique(new[~split[new]])
        if new.size == 0:
            break
        split[new] = True
        touched = np.zeros(n_edges, dtype=bool)
        touched[new] = True
        active = np.flatnonzero(touched[cedges].any(axis=1))
    return split, rounds


# ----------------------------------------------------------------------------------------
# transition tables


def _triangulations(poly: tuple[int, ...]) -> list[list[tuple[int, int, int]]]:
    """All triangulations of a convex polygon (vertex ids in counter-clockwise order)."""
    if len(poly) < 3:
        return [[]]
    if len(poly) == 3:
        return [[poly]]
    a, b = poly[0], poly[-1]
    out = []
    for i in range(1, len(poly) - 1):
        for left in _triangulations(poly[: i + 1]):
            for right in _triangulations(poly[i:]):
                out.append(left + [(a, poly[i], b)] + right)
    return out


def _seven_candidates(poly: tuple[str, ...]) -> list[tuple[str, ...]]:
    """Non-degenerate triangulations of a heptagon of seven-point stencil names, the ones
    holding most of the scheme's corner triangles first (so exact ties prefer them)."""
    lines = ({"M", "D", "C", "N"}, {"N", "Q", "B", "O"}, {"O", "A", "P", "M"})
    fixed = {frozenset(t) for t in ("MDP", "PDA", "CQB", "CNQ")}
    cands = []
    for tri in _triangulations(poly):
        names = tuple("".join(t) for t in tri)
        if any(set(t) <= line for t in names for line in lines):
            continue
        cands.append(names)
    cands.sort(key=lambda c: -sum(frozenset(t) in fixed for t in c))
    return cands


#: Transition patterns by split code (bits MN=1, NO=2, OM=4) and points per edge: a list
#: of candidate triangulations (three-letter names, counter-clockwise in the canonical
#: frame); the candidate with the largest minimum angle is used, the first on ties.
TRANSITIONS: dict[int, dict[int, list[tuple[str, ...]]]] = {
    2: {
        MN: [("MDO", "DCO", "CNO")],
        MN | NO: _seven_candidates(("M", "D", "C", "N", "Q", "B", "O")),
        MN | OM: _seven_candidates(("M", "D", "C", "N", "O", "A", "P")),
    },
    1: {
        MN: [("MmO", "mNO")],
        MN | NO: [("MmO", "mqO", "mNq")],
        MN | OM: [("Mmp", "mOp", "mNO")],
    },
}


@cache
def _tables(k: int, code: int) -> tuple[NDArray[np.int8], NDArray[np.int64], NDArray[np.int8]]:
    """``(tris (U,3), cand (C,T) indices into tris, table (C,T,3))`` of local indices."""
    names = "MNODCQBAP" if k == 2 else "MNOmqp"
    cands = TRANSITIONS[k][code]
    uniq = sorted({t for c in cands for t in c})
    tris = np.array([[names.index(ch) for ch in t] for t in uniq], dtype=np.int8)
    cand = np.array([[uniq.index(t) for t in c] for c in cands], dtype=np.int64)
    return tris, cand, tris[cand]


# ----------------------------------------------------------------------------------------
# refinement


def as_mask(marked: ArrayLike, n_triangles: int) -> NDArray[np.bool_]:
    """A boolean mask ``(M,)`` from a mask or an array of triangle indices."""
    a = np.asarray(marked)
    if a.dtype == bool:
        if a.shape != (n_triangles,):
            raise ValueError(f"a boolean marked mask must have shape ({n_triangles},), "
                             f"got {a.shape}")
        return a.copy()
    if a.size == 0:
        return np.zeros(n_triangles, dtype=bool)
    if not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"marked must be a boolean mask or triangle indices, got dtype "
                         f"{a.dtype}")
    if a.ndim != 1:
        raise ValueError(f"marked indices must be one-dimensional, got shape {a.shape}")
    bad = (a < 0) | (a >= n_triangles)
    if bad.any():
        raise ValueError(f"marked index {int(a[bad][0])} is outside 0..{n_triangles - 1}")
    mask = np.zeros(n_triangles, dtype=bool)
    mask[a] = True
    return mask


def refine_marked(mesh: Mesh, marked: ArrayLike, scheme: str | Scheme = "7t-qd",
                  levels: int = 1, min_angle: float | None = None
                  ) -> tuple[Mesh, NDArray[np.int64]]:
    """Conforming local refinement of the ``marked`` triangles; see :func:`qdrefine.refine`.

    Parameters
    ----------
    mesh : Mesh
    marked : (M,) bool or (K,) int
        Mask or indices of the triangles to partition with ``scheme``.
    scheme : {"7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"}
    levels : int, >= 0
        With ``levels > 1`` the children of the marked triangles' full partitions are
        marked again, ``levels`` times in all.
    min_angle : float, optional
        Quality floor in degrees for the transition patterns of seven-triangle schemes: a
        triangle whose transition would create a child with a smaller minimum angle is
        fully partitioned instead (and the closure grows accordingly). Default:
        :data:`KEEP` times the smallest angle of ``mesh``. Over repeated cycles pass one
        fixed value (as :func:`refine_cycles` does), otherwise the floor can drift down.

    Returns
    -------
    mesh : Mesh
    parents : (M',) int64
        The input triangle of each output triangle.
    """
    sch = get_scheme(scheme)
    levels = as_count(levels, "levels")
    mask = as_mask(marked, mesh.n_triangles)
    if min_angle is None:
        min_angle = KEEP * float(angles(mesh.points, mesh.triangles).min())
    min_angle = float(min_angle)
    parents = np.arange(mesh.n_triangles, dtype=np.int64)
    out = mesh
    for _ in range(levels):
        if not mask.any():
            break
        out, step, full = _refine_marked_once(out, mask, sch, min_angle)
        parents = parents[step]
        mask = full & mask[step]
    return out, parents


def _refine_marked_once(mesh: Mesh, marked: NDArray[np.bool_], sch: Scheme, min_angle: float
                        ) -> tuple[Mesh, NDArray[np.int64], NDArray[np.bool_]]:
    """One step: ``(mesh, parents, from_full)``, ``from_full`` flags children of full
    partitions."""
    k = sch.stencil.per_edge
    t = mesh.triangles
    n = mesh.n_points
    m = t.shape[0]
    edges, tri_edges, _ = number_edges(t, n)
    labels = canonical_labels(mesh.points, t)
    ce = canonical_edges(labels, tri_edges)
    split, _ = closure(ce, marked, edges.shape[0])
    if k == 2:
        split = _guarded(mesh, edges, labels, ce, marked, split, min_angle)

    # new points: k per split edge, numbered by the split edge's rank among split edges
    rank = np.cumsum(split) - 1
    n_new = n + k * int(split.sum())
    points = np.empty((n_new, 2), dtype=np.float64)
    edge_points(mesh.points, np.ascontiguousarray(edges[split]), k, points)
    dtype = index_dtype(n_new)

    code = (split[ce] * np.array([MN, NO, OM])).sum(axis=1)
    n_children = np.ones(m, dtype=np.int64)
    n_children[code == FULL] = sch.n_children
    for c in (MN, MN | NO, MN | OM):
        n_children[code == c] = len(TRANSITIONS[k][c][0])
    first = np.concatenate([[0], np.cumsum(n_children)])
    triangles = np.empty((int(first[-1]), 3), dtype=dtype)
    parents = np.repeat(np.arange(m, dtype=np.int64), n_children)

    same = np.flatnonzero(code == 0)
    triangles[first[same]] = t[same]

    full = np.flatnonzero(code == FULL)
    if full.size:
        kids = np.empty((full.size * sch.n_children, 3), dtype=dtype)
        full_edges = np.ascontiguousarray(rank[tri_edges[full]])  # ranks: all split
        emit(mesh.points, np.ascontiguousarray(t[full]), full_edges, k, sch.forms, sch.lut,
             sch.tables, kids)
        rows = (first[full][:, None] + np.arange(sch.n_children)).ravel()
        triangles[rows] = kids

    for c in (MN, MN | NO, MN | OM):
        sel = np.flatnonzero(code == c)
        if sel.size:
            kids = _transition(points, t[sel], labels[sel], ce[sel], rank, n, k, c)
            rows = (first[sel][:, None] + np.arange(kids.shape[1])).ravel()
            triangles[rows] = kids.reshape(-1, 3)

    cell_tags = None if mesh.cell_tags is None else mesh.cell_tags[parents]
    new_edges, edge_tags = None, None
    if mesh.edges is not None:
        new_edges, edge_tags = split_tagged_edges(mesh.edges, mesh.edge_tags, edges, n, k,
                                                  split, rank)
        new_edges = new_edges.astype(dtype)
    from_full = np.repeat(code == FULL, n_children)
    out = Mesh._trusted(points, triangles, cell_tags, new_edges, edge_tags)
    return out, parents, from_full


def _guarded(mesh: Mesh, edges: NDArray, labels: NDArray[np.int8], ce: NDArray[np.int64],
             marked: NDArray[np.bool_], split: NDArray[np.bool_], min_angle: float
             ) -> NDArray[np.bool_]:
    """The quality guard: a triangle whose best transition pattern has a child with minimum
    angle below ``min_angle`` is *promoted* (treated as marked: full partition) and the
    closure is run again, until no transition falls below ``min_angle``. Promotions only
    grow, so this ends (at worst with every triangle promoted)."""
    k = 2
    n = mesh.n_points
    allpts = np.empty((n + k * edges.shape[0], 2))
    edge_points(mesh.points, edges, k, allpts)  # the same values the output will hold
    ident = np.arange(edges.shape[0], dtype=np.int64)
    promoted = marked.copy()
    while True:
        code = (split[ce] * np.array([MN, NO, OM])).sum(axis=1)
        bad = np.zeros(len(code), dtype=bool)
        for c in (MN, MN | NO, MN | OM):
            sel = np.flatnonzero(code == c)
            if sel.size:
                ids = _stencil_ids(mesh.triangles[sel], labels[sel], ce[sel], ident, n, k)
                bad[sel] = _choose(allpts, ids, k, c)[1] < min_angle
        if not bad.any():
            return split
        promoted |= bad
        split, _ = closure(ce, promoted, edges.shape[0])


def _stencil_ids(t: NDArray, labels: NDArray[np.int8], ce: NDArray[np.int64],
                 rank: NDArray[np.int64], n: int, k: int) -> NDArray[np.int64]:
    """Global point ids ``(G, 3 + 3k)`` of the local stencil (``-1`` on unsplit edges)."""
    g = t.shape[0]
    lab = labels.astype(np.int64)
    verts = np.take_along_axis(t.astype(np.int64), lab, axis=1)  # M, N, O
    ids = np.full((g, 3 + 3 * k), -1, dtype=np.int64)
    ids[:, :3] = verts
    for e in range(3):
        a = verts[:, e]
        b = verts[:, (e + 1) % 3]
        r = rank[ce[:, e]]
        ok = r >= 0
        from_a = a < b
        for j in range(k):
            jj = np.where(from_a, j, k - 1 - j)
            ids[:, 3 + k * e + j] = np.where(ok, n + r * k + jj, -1)
    return ids


def _choose(points: NDArray[np.float64], ids: NDArray[np.int64], k: int, code: int
            ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Candidate index and its minimum angle (degrees) per triangle, ``ids`` from
    :func:`_stencil_ids` (points must hold the split edges' points)."""
    tris, cand, _ = _tables(k, code)
    g = ids.shape[0]
    corners = ids[:, tris]  # (G, U, 3)
    ang = angles(points, corners.reshape(-1, 3)).min(axis=1).reshape(g, -1)
    score = ang[:, cand].min(axis=2)  # (G, C)
    choice = np.argmax(score, axis=1)  # first candidate on ties
    return choice, score[np.arange(g), choice]


def _transition(points: NDArray[np.float64], t: NDArray, labels: NDArray[np.int8],
                ce: NDArray[np.int64], rank: NDArray[np.int64], n: int, k: int, code: int
                ) -> NDArray[np.int64]:
    """Children ``(G, T, 3)`` of triangles with split code ``code`` (not 0 or full)."""
    ids = _stencil_ids(t, labels, ce, rank, n, k)
    choice = _choose(points, ids, k, code)[0]
    table = _tables(k, code)[2]
    local = table[choice].astype(np.int64)  # (G, T, 3)
    flip = (labels[:, 1].astype(np.int64) - labels[:, 0]) % 3 != 1
    local[flip] = local[flip][:, :, [0, 2, 1]]
    return np.take_along_axis(ids[:, None, :], local, axis=2)


def refine_cycles(mesh: Mesh, mark: Callable[[Mesh], ArrayLike], cycles: int,
                  scheme: str | Scheme = "7t-qd", keep: float = KEEP
                  ) -> tuple[Mesh, NDArray[np.int64]]:
    """``cycles`` rounds of mark-then-refine with one fixed quality floor.

    Parameters
    ----------
    mesh : Mesh
    mark : callable
        ``mark(current_mesh)`` returns a mask ``(M,) bool`` or indices of the triangles to
        refine in this cycle (e.g. a :mod:`qdrefine.marking` helper with its arguments bound).
    cycles : int, >= 0
    scheme : str or Scheme
    keep : float
        The transitions' floor is ``keep`` times the minimum angle of the *input* mesh, the
        same in every cycle, so the minimum angle cannot drift down cycle after cycle
        through the transitions.

    Returns
    -------
    mesh : Mesh
    parents : (M',) int64
        The triangle of the input mesh each output triangle lies in.
    """
    cycles = as_count(cycles, "cycles")
    floor = keep * float(angles(mesh.points, mesh.triangles).min())
    parents = np.arange(mesh.n_triangles, dtype=np.int64)
    out = mesh
    for _ in range(cycles):
        out, step = refine_marked(out, mark(out), scheme, 1, min_angle=floor)
        parents = parents[step]
    return out, parents
