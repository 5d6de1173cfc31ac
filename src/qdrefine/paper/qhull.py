"""Fig. 3 of the paper: floating-point Delaunay (SciPy/Qhull) on the nine points fails."""

from __future__ import annotations

import numpy as np

from ..partition import partition
from ..predicates import orient_signs
from .lemmas import has

__all__ = ["nine_points", "find_qhull_failure"]


def nine_points(v: np.ndarray) -> np.ndarray:
    """The nine points of triangle ``v (3, 2)`` as floats, in stencil order M N O D C Q B A P
    (the triangle's own vertex order is used as M, N, O)."""
    m, n, o = (np.asarray(p, dtype=np.float64) for p in v)
    return np.array([m, n, o, (2 * m + n) / 3, (m + 2 * n) / 3, (2 * n + o) / 3,
                     (n + 2 * o) / 3, (2 * o + m) / 3, (o + 2 * m) / 3])


_EDGE_SETS = ({0, 3, 4, 1}, {1, 5, 6, 2}, {2, 7, 8, 0})


def find_qhull_failure(trials: int = 2000, seed: int = 0) -> dict:
    """Search triangles with one-decimal coordinates for a nine-point set on which
    ``scipy.spatial.Delaunay`` returns a triangle with its three vertices on one edge of the
    input triangle (a degenerate, collinear triangle). Triangles of doubled area below 1
    are drawn again, not tested. Returns the first failure found, with the counts
    (``tested``: the triangles tested, of ``trials`` drawn)."""
    if not has("scipy"):
        return {"available": False}
    import scipy
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed)
    found = None
    failures = tested = 0
    for t in range(trials):
        v = np.round(rng.uniform(0, 10, (3, 2)), 1)
        e, f = v[1] - v[0], v[2] - v[0]
        if abs(e[0] * f[1] - e[1] * f[0]) < 1:
            continue
        tested += 1
        p = nine_points(v)
        tri = Delaunay(p).simplices
        bad = [s for s in tri if any(set(s.tolist()) <= e for e in _EDGE_SETS)]
        if bad or len(tri) != 7:
            failures += 1
            if found is None:
                signs = orient_signs(p, np.array(bad, dtype=np.int64)) if bad else []
                ours_p, ours_t = partition(v, "7t-d")
                ours_signs = orient_signs(ours_p, ours_t)
                found = {"trial": t, "vertices": v.tolist(), "points": p.tolist(),
                         "simplices": tri.tolist(), "degenerate": [b.tolist() for b in bad],
                         "exact_orientation": [int(s) for s in signs],
                         "ours_triangles": int(ours_t.shape[0]),
                         "ours_positive": bool((ours_signs > 0).all())}
    return {"available": True, "version": scipy.__version__, "trials": trials,
            "tested": tested, "failures": failures, "example": found}
