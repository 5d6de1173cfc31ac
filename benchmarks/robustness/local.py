"""The nine points of a seven-triangle partition in qdrefine's local numbering.

:func:`qdrefine.partition_many` lists ``v0, v1, v2`` and then two points on each of the edges
``v0-v1, v0-v2, v1-v2``, each edge's points from its first vertex. :data:`NEAR` gives the
local index of the point of edge ``{a, b}`` nearer ``a``. The 7T-QD triangles are written
with the paper's names (``M N O D C Q B A P``) and mapped to local indices here, so naive,
exact and qdrefine partitions can be compared as sets of local index triples.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: ``NEAR[a, b]``: local index of the trisection point of edge {a, b} nearer vertex ``a``.
NEAR = np.array([[-1, 3, 5], [4, -1, 7], [6, 8, -1]], dtype=np.int64)

FIXED = ("MDP", "PDA", "CQB", "CNQ")
#: 7T-QD Cases I, II, III: the pentagon D-C-B-O-A as a fan from B, D or O.
CASES = (("BOA", "BAD", "BDC"), ("DCB", "DBO", "DOA"), ("OAD", "ODC", "OCB"))


def name_indices(m: NDArray, n: NDArray, o: NDArray) -> dict[str, NDArray[np.int64]]:
    """Local index ``(K,)`` of every stencil name for labellings ``m, n, o (K,)``."""
    return {"M": m, "N": n, "O": o, "D": NEAR[m, n], "C": NEAR[n, m], "Q": NEAR[n, o],
            "B": NEAR[o, n], "A": NEAR[o, m], "P": NEAR[m, o]}


def qd_triangles(m: NDArray, n: NDArray, o: NDArray, case: NDArray) -> NDArray[np.int64]:
    """The 7T-QD triangles ``(K, 7, 3)`` (local indices, counter-clockwise when ``m, n, o``
    is) of labelling ``m, n, o (K,)`` and case ``(K,)`` in {0, 1, 2} (I, II, III)."""
    idx = name_indices(np.asarray(m), np.asarray(n), np.asarray(o))
    k = len(idx["M"])
    out = np.empty((k, 7, 3), dtype=np.int64)
    for t, name in enumerate(FIXED):
        out[:, t] = np.stack([idx[c] for c in name], axis=1)
    for c, names in enumerate(CASES):
        sel = np.asarray(case) == c
        for t, name in enumerate(names):
            out[sel, 4 + t] = np.stack([idx[ch][sel] for ch in name], axis=1)
    return out


def triangle_keys(tris: NDArray) -> NDArray[np.int64]:
    """Order-free key ``(K, T)`` of each row's triangle set (vertex order ignored)."""
    s = np.sort(tris, axis=2)
    return np.sort(s[..., 0] * 81 + s[..., 1] * 9 + s[..., 2], axis=1)


def ninegon(ccw: NDArray[np.bool_]) -> NDArray[np.int64]:
    """Boundary cycle ``(K, 9)`` of the nine points, counter-clockwise, given whether
    ``v0 v1 v2`` is counter-clockwise ``(K,)``."""
    cycle = np.array([0, 3, 4, 1, 7, 8, 2, 6, 5])
    out = np.tile(cycle, (len(ccw), 1))
    out[~np.asarray(ccw)] = cycle[::-1]
    return out
