"""Marked transition children: which children of the parent's partition overlap them
(exact integer geometry on the parent's stencil)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .edgekeys import edge_keys, lookup, oriented
from .patterns import pattern_stencil
from .working import StepInput, Tree


def overlap_marks(inp: StepInput, tree: Tree, kids: NDArray[np.int64]) -> None:
    """Flag the children ``kids (X, T)`` of the expanded parents of marked members (in
    family order) whose interior meets a marked member: those not smaller than it
    (``again``) for the follow-up pass, the smaller ones as inside the marks (``user``),
    so that ``levels > 1`` refines the marked member's area again (it stopped after one
    level when every such child was smaller; review)."""
    if not inp.pairs.size:
        return
    k = inp.k
    f = inp.pairs[:, 1]
    nodes = kids[np.searchsorted(np.unique(f), f)]  # (P, T)
    sten = inp.fam.stencil[f].copy()
    for e in range(3):  # fill the edges the transition left unsplit
        a, b = sten[:, e], sten[:, (e + 1) % 3]
        p = tree.reg_pts[lookup(tree.reg_keys, edge_keys(a, b))]
        sten[:, 3 + k * e: 3 + k * (e + 1)] = oriented(p, a, b)
    ref = _reference(k)
    child = ref[_local(tree.triangles[nodes], sten)]  # (P, T, 3, 2)
    marked = ref[_local(inp.mesh.triangles[inp.pairs[:, 0]][:, None, :], sten)]  # (P, 1, 3, 2)
    meet = _interiors_meet(child, np.broadcast_to(marked, child.shape))
    again = meet & (_twice_area(child) >= _twice_area(marked))  # smaller: refine it already
    tree.again[nodes[again]] = True
    tree.user[nodes[meet & ~again]] = True


def _reference(k: int) -> NDArray[np.int64]:
    """Integer coordinates ``(S, 2)`` of :func:`~qdrefine.adaptive.patterns.pattern_stencil`
    in the triangle (0,0), (s,0), (0,s) with ``s = 3 (k+1)`` (then every stencil point,
    the centroid included, has integer coordinates): barycentric positions are affine
    invariants, so overlaps decided here are the overlaps in every triangle."""
    w = np.array([[int(c * 3 * (k + 1)) for c in row] for row in pattern_stencil(k).weights])
    return w[:, 1:].astype(np.int64)


def _local(ids: NDArray, sten: NDArray[np.int64]) -> NDArray[np.int64]:
    """Stencil positions ``(P, ..., 3)`` of point ids ``(P, ..., 3)`` in ``sten (P, S)``."""
    eq = ids[..., None] == sten.reshape(sten.shape[0], *(1,) * (ids.ndim - 1), -1)
    if not eq.any(axis=-1).all():
        raise RuntimeError("internal error: a family member is not on its parent's stencil")
    return eq.argmax(axis=-1)


def _interiors_meet(a: NDArray[np.int64], b: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Whether triangles ``a`` and ``b`` (``(..., 3, 2)`` integers) share interior points:
    exact separating-axis test (no edge line of either has the other on or beyond it)."""
    a, b = _ccw(a), _ccw(b)
    return ~(_separated(a, b) | _separated(b, a))


def signed_twice_areas(t: NDArray) -> NDArray:
    """Signed twice area ``(...)`` of triangles ``t (..., 3, 2)`` (integer or float;
    positive for counter-clockwise)."""
    d = t[..., 1, :] - t[..., 0, :], t[..., 2, :] - t[..., 0, :]
    return d[0][..., 0] * d[1][..., 1] - d[0][..., 1] * d[1][..., 0]


def _twice_area(t: NDArray[np.int64]) -> NDArray[np.int64]:
    return np.abs(signed_twice_areas(t))


def _ccw(t: NDArray[np.int64]) -> NDArray[np.int64]:
    return np.where((signed_twice_areas(t) < 0)[..., None, None], t[..., [0, 2, 1], :], t)


def _separated(a: NDArray[np.int64], b: NDArray[np.int64]) -> NDArray[np.bool_]:
    out = np.zeros(a.shape[:-2], dtype=bool)
    for i in range(3):
        p, q = a[..., i, :], a[..., (i + 1) % 3, :]
        d = ((q - p)[..., None, 0] * (b[..., 1] - p[..., None, 1])
             - (q - p)[..., None, 1] * (b[..., 0] - p[..., None, 0]))
        out |= (d <= 0).all(axis=-1)
    return out
