"""Concrete nine-point sets on which SciPy's floating-point Delaunay fails, and a figure.

Two deterministic searches, each judged exactly (:mod:`.checks`), with the nine points of
:func:`qdrefine.paper.nine_points` (order M N O D C Q B A P, numbered 1-9 as in the paper):

* :func:`find_collinear`: the first triangle ``(0,0), (a,b), (c,d)``, ``0 <= a,b,c,d <= 9``
  in lexicographic order, on whose nine points SciPy returns a triangle with three exactly
  collinear vertices (the failure of the paper's Fig. 3);
* :func:`find_dropped`: the first right needle ``(0,0), (3 10^k, 0), (0, 3)`` (integer
  nine points, the trisection points exact) on which SciPy's output is not a
  triangulation of the nine points.

:func:`paper_example` re-judges the example found by :func:`qdrefine.paper.find_qhull_failure`
(the paper module's Fig. 3 search) with the exact checks.
"""

from __future__ import annotations

from itertools import product
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

import qdrefine
from qdrefine import paper

from .checks import hull_boundary, triangulation_flags
from .exact import incircle_sign, orient_sign


def judge(points: NDArray[np.float64], simplices: NDArray[np.int64]) -> dict:
    """Exact verdict on a triangulation ``simplices (T, 3)`` of ``points (P, 2)``: flags,
    and the offending triangles and points (0-based)."""
    f = triangulation_flags(points[None], simplices[None],
                            {"hull": hull_boundary(points[None])})
    p, s = points, simplices
    o = orient_sign(p[s[:, 0]], p[s[:, 1]], p[s[:, 2]])
    ins = incircle_sign(p[s[:, 0], None], p[s[:, 1], None], p[s[:, 2], None], p[None, :])
    own = (np.arange(len(p))[None, :] == s[:, :, None]).any(axis=1)
    bad = ((ins * o[:, None] > 0) & ~own & (o != 0)[:, None]).any(axis=1)
    return {"triangles": int(len(s)), "zero_area": bool(f["zero_area"][0]),
            "inverted": bool(f["inverted"][0]), "missing": bool(f["missing"][0]),
            "not_triangulation": bool(f["not_tiling hull"][0]),
            "not_delaunay": bool(f["not_delaunay"][0]),
            "zero_area_triangles": s[o == 0].tolist(), "inverted_triangles": s[o < 0].tolist(),
            "non_delaunay_triangles": s[bad].tolist(),
            "missing_points": sorted(set(range(len(p))) - set(s.ravel().tolist())),
            "valid": not (f["missing"][0] or f["not_tiling hull"][0] or f["not_delaunay"][0])}


def _scipy(points):
    from scipy.spatial import Delaunay

    return Delaunay(points).simplices.astype(np.int64)


def _case(v: NDArray[np.float64], tried: int) -> dict:
    p = paper.nine_points(v)
    s = _scipy(p)
    return {"vertices": v.tolist(), "points": p.tolist(), "simplices": s.tolist(),
            "tried": tried, "scipy": judge(p, s)}


def find_collinear(limit: int = 10) -> dict | None:
    """The first small-integer triangle on which SciPy returns a zero-area triangle."""
    tried = 0
    for a, b, c, d in product(range(limit), repeat=4):
        v = np.array([[0, 0], [a, b], [c, d]], dtype=np.float64)
        if orient_sign(v[0], v[1], v[2]) <= 0:
            continue
        tried += 1
        p = paper.nine_points(v)
        s = _scipy(p)
        if (orient_sign(p[s[:, 0]], p[s[:, 1]], p[s[:, 2]]) == 0).any():
            return _case(v, tried)
    return None


def find_dropped(max_power: int = 12) -> dict | None:
    """The first right needle ``(0,0), (3 10^k, 0), (0,3)`` SciPy does not triangulate."""
    for k in range(1, max_power + 1):
        v = np.array([[0, 0], [3 * 10**k, 0], [0, 3]], dtype=np.float64)
        p = paper.nine_points(v)
        if not judge(p, _scipy(p))["valid"]:
            out = _case(v, k)
            out["power"] = k
            return out
    return None


def paper_example(trials: int = 2000, seed: int = 0) -> dict:
    """The paper module's Fig. 3 search, its first example re-judged exactly."""
    found = paper.find_qhull_failure(trials=trials, seed=seed)
    ex = found.get("example")
    if not ex:
        return {"available": found.get("available", False), "example": None}
    p, s = np.array(ex["points"]), np.array(ex["simplices"], dtype=np.int64)
    return {"available": True, "trials": trials, "failures": found["failures"],
            "vertices": ex["vertices"], "simplices": ex["simplices"],
            "degenerate": ex["degenerate"], "scipy": judge(p, s)}


# ----------------------------------------------------------------------------------------
# figure


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _panel(ax, points, tris, title, verdict=None, stretch=(1.0, 1.0)):
    p = points * np.asarray(stretch)
    ax.triplot(p[:, 0], p[:, 1], tris, color="k", lw=1)
    if verdict:
        for t in verdict["zero_area_triangles"] + verdict["inverted_triangles"]:
            q = p[list(t) + [t[0]]]
            ax.plot(q[:, 0], q[:, 1], color="C3", lw=4, alpha=0.5)
        for t in verdict["non_delaunay_triangles"]:
            ax.fill(*p[t].T, color="C1", alpha=0.3)
        for i in verdict["missing_points"]:
            ax.plot(*p[i], "o", ms=12, mfc="none", mec="C3", mew=2)
    ax.plot(p[:, 0], p[:, 1], "o", color="C0", ms=4)
    if verdict is not None:
        for i, q in enumerate(p):
            ax.annotate(str(i + 1), q, textcoords="offset points", xytext=(5, 3), fontsize=9)
    ax.set_title(title, fontsize=10)
    ax.set_aspect("equal")
    ax.margins(0.1)
    ax.set_xticks([])
    ax.set_yticks([])


def _describe(v: dict) -> str:
    parts = []
    if v["zero_area_triangles"]:
        parts.append(f"{len(v['zero_area_triangles'])} with 3 collinear points (red)")
    if v["inverted_triangles"]:
        parts.append(f"{len(v['inverted_triangles'])} clockwise (red)")
    if v["missing_points"]:
        parts.append("points " + ", ".join(str(i + 1) for i in v["missing_points"])
                     + " left out (circled)")
    if v["non_delaunay_triangles"]:
        parts.append(f"{len(v['non_delaunay_triangles'])} not Delaunay (orange)")
    return "; ".join(parts)


def draw(collinear: dict, dropped: dict, path: Path) -> list[Path]:
    """Four panels (SciPy and qdrefine 7T-D on each exhibit) as PNG and SVG at ``path``
    (without suffix); returns the files written."""
    plt = _plt()
    fig, axs = plt.subplots(2, 2, figsize=(11, 9.5))
    for row, ex, stretch, note in ((0, collinear, (1.0, 1.0), ""),
                                   (1, dropped, (1.0 / dropped["vertices"][1][0], 1 / 3.0),
                                    "\n(drawn with x and y scaled to unit length)")):
        p = np.array(ex["points"])
        v = ex["scipy"]
        verts = ", ".join(f"({x:.12g}, {y:.12g})" for x, y in ex["vertices"])
        _panel(axs[row, 0], p, np.array(ex["simplices"]),
               f"SciPy/Qhull on the nine points of {verts}:\n{v['triangles']} triangles; "
               f"{_describe(v)}{note}", v, stretch)
        pts, tris = qdrefine.partition(np.array(ex["vertices"]), "7t-d")
        _panel(axs[row, 1], pts, tris, f"qdrefine 7T-D (exact decision): {len(tris)} "
               f"triangles{note}", None, stretch)
    fig.tight_layout()
    out = []
    for ext in ("png", "svg"):
        f = path.with_suffix(f".{ext}")
        fig.savefig(f, dpi=120, bbox_inches="tight")
        out.append(f)
    plt.close(fig)
    return out
