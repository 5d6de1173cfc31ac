"""Transition patterns: the candidate triangulations per split code and the choice among
them (largest minimum angle), in the canonical stencil of :mod:`qdrefine.stencil`."""

from __future__ import annotations

from functools import cache

import numpy as np
from numpy.typing import NDArray

from ..quality import angles
from .edgekeys import oriented
from .labels import MN, NO, OM

#: Split codes with a transition pattern (neither unsplit nor fully split).
PARTIAL = (MN, MN | NO, MN | OM)


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


def stencil_ids(t: NDArray, labels: NDArray[np.int8], ce: NDArray[np.int64],
                ep: NDArray[np.int64], k: int) -> NDArray[np.int64]:
    """Global point ids ``(G, 3 + 3k)`` of the local stencil (``-1`` on unsplit edges),
    from the edge points ``ep (E, k)`` listed from the lower id."""
    g = t.shape[0]
    verts = np.take_along_axis(t.astype(np.int64), labels.astype(np.int64), axis=1)
    ids = np.full((g, 3 + 3 * k), -1, dtype=np.int64)
    ids[:, :3] = verts
    for e in range(3):
        ids[:, 3 + k * e: 3 + k * (e + 1)] = oriented(ep[ce[:, e]], verts[:, e],
                                                        verts[:, (e + 1) % 3])
    return ids


def choose(points: NDArray[np.float64], ids: NDArray[np.int64], k: int, code: int
           ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Candidate index and its minimum angle (degrees) per triangle, ``ids`` from
    :func:`stencil_ids` (points must hold the split edges' points)."""
    tris, cand, _ = _tables(k, code)
    g = ids.shape[0]
    corners = ids[:, tris]  # (G, U, 3)
    ang = angles(points, corners.reshape(-1, 3)).min(axis=1).reshape(g, -1)
    score = ang[:, cand].min(axis=2)  # (G, C)
    choice = np.argmax(score, axis=1)  # first candidate on ties
    return choice, score[np.arange(g), choice]


def pattern(points: NDArray[np.float64], ids: NDArray[np.int64], labels: NDArray[np.int8],
            k: int, code: int) -> NDArray[np.int64]:
    """Children ``(G, T, 3)`` of triangles with split code ``code`` (not 0 or full)."""
    choice = choose(points, ids, k, code)[0]
    local = _tables(k, code)[2][choice].astype(np.int64)  # (G, T, 3)
    flip = (labels[:, 1].astype(np.int64) - labels[:, 0]) % 3 != 1
    local[flip] = local[flip][:, :, [0, 2, 1]]
    return np.take_along_axis(ids[:, None, :], local, axis=2)
