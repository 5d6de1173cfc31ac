"""7T-QD decided in plain float64, the way a user would implement the paper.

Squared lengths are computed in float64 from float64 points and compared with ``<=``/``<``.
Only the arithmetic is naive: the tie rules are qdrefine's documented ones (applied to the
float values), and the nine points are ``(2a + b) / 3`` as qdrefine stores them, so every
difference from :func:`qdrefine.partition` comes from rounding alone.
"""

from __future__ import annotations

from itertools import permutations

import numpy as np
from numpy.typing import NDArray

from .exact import edge_lengths2, labelling
from .local import NEAR, qd_triangles, triangle_keys


def nine_points(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """The nine float points ``(K, 9, 2)`` of triangles ``v (K, 3, 2)`` in local order."""
    out = np.empty((len(v), 9, 2))
    out[:, :3] = v
    for a in range(3):
        for b in range(3):
            if a != b:
                out[:, NEAR[a, b]] = (2.0 * v[:, a] + v[:, b]) / 3.0
    return out


def _d2(p: NDArray, q: NDArray) -> NDArray:
    d = p - q
    return d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]


def naive_qd(v: NDArray[np.float64]) -> dict[str, NDArray]:
    """Float64 7T-QD of triangles ``v (K, 3, 2)``.

    Returns ``m, n, o, case (K,)``, ``points (K, 9, 2)`` and ``triangles (K, 7, 3)``
    (local indices, flipped to counter-clockwise by the float orientation of ``M N O``).
    """
    v = np.asarray(v, dtype=np.float64)
    m, n, o, _ = labelling(v, edge_lengths2(v))
    pts = nine_points(v)
    rows = np.arange(len(v))

    def p(a, b=None):
        return pts[rows, a if b is None else NEAR[a, b]]

    pm, pn, po = p(m), p(n), p(o)
    pd, pc, pb, pa = p(m, n), p(n, m), p(o, n), p(o, m)
    case = np.where(_d2(pa, pb) <= _d2(po, pd), 0, np.where(_d2(pb, pd) < _d2(po, pc), 1, 2))
    tris = qd_triangles(m, n, o, case)
    u, w = pn - pm, po - pm
    cw = u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0] < 0
    tris[cw] = tris[cw][:, :, ::-1]
    return {"m": m, "n": n, "o": o, "case": case, "points": pts, "triangles": tris}


def local_map(perm: tuple[int, int, int]) -> NDArray[np.int64]:
    """Local index in the original numbering ``(9,)`` of each local index of the triangle
    whose vertex ``i`` is original vertex ``perm[i]``."""
    out = np.empty(9, dtype=np.int64)
    out[:3] = perm
    for a in range(3):
        for b in range(3):
            if a != b:
                out[NEAR[a, b]] = NEAR[perm[a], perm[b]]
    return out


def order_dependent(v: NDArray[np.float64], partition_fn) -> NDArray[np.bool_]:
    """Whether the triangle set of ``partition_fn(v) -> (K, T, 3)`` changes ``(K,)`` when the
    three vertices of ``v (K, 3, 2)`` are listed in any of the other five orders."""
    base = triangle_keys(partition_fn(v))
    out = np.zeros(len(v), dtype=bool)
    for perm in list(permutations(range(3)))[1:]:
        tris = local_map(perm)[partition_fn(v[:, list(perm)])]
        out |= (triangle_keys(tris) != base).any(axis=1)
    return out
