"""One row of the study: every comparison on one batch of triangles.

:func:`qd_row` compares the float64 7T-QD with qdrefine and the exact reference;
:func:`delaunay_row` checks SciPy, Triangle and qdrefine's 7T-D on the nine points.
Counts are plain integers (JSON-ready); ``examples`` keep the first offending triangle.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

import qdrefine

from . import checks, delaunay, exact, local, naive


def _first(mask: NDArray[np.bool_], v: NDArray) -> list | None:
    i = np.flatnonzero(mask)
    return v[i[0]].tolist() if i.size else None


def _fraction_sample(k: int, n: int, seed: int) -> NDArray[np.int64]:
    return np.sort(np.random.default_rng(seed).choice(k, size=min(n, k), replace=False))


def qd_row(v: NDArray[np.float64], n_fraction: int, seed: int = 0) -> dict:
    """Float64 7T-QD versus qdrefine's exact decision on triangles ``v (K, 3, 2)``."""
    pts, tris = qdrefine.partition_many(v, "7t-qd", strict=False)
    nv = naive.naive_qd(v)
    ref = exact.qd_reference(v)
    key_q, key_n, key_r = (local.triangle_keys(t) for t in (tris, nv["triangles"],
                                                               ref["triangles"]))
    differs = (key_n != key_r).any(axis=1)
    label = (nv["m"] != ref["m"]) | (nv["n"] != ref["n"]) | (nv["o"] != ref["o"])
    tie = ref["label_tie"] | ref["case_tie"]
    ccw = exact.orient_sign(v[:, 0], v[:, 1], v[:, 2]) > 0
    boundary = checks.cycle_boundary(local.ninegon(ccw), 9)
    fq = checks.triangulation_flags(pts, tris, {"gon": boundary}, delaunay=False)
    fn = checks.triangulation_flags(pts, nv["triangles"], {"gon": boundary}, delaunay=False)
    bad_q = fq["not_tiling gon"]
    bad_n = fn["not_tiling gon"]
    children, ex = exact.triangles_area2(pts, tris)
    parent, ex0 = exact.polygon_area2(pts, np.tile([0, 1, 2], (len(v), 1)))
    assert (ex == ex0).all()
    parent = np.where(ccw, parent, -parent)
    area_exact = children == parent
    rel = max((abs(float((c - p) / p)) for c, p in zip(children, parent, strict=True)),
              default=0.0)
    sample = _fraction_sample(len(v), n_fraction, seed)
    fraction_ok = sum(exact.fraction_partition(v[i]) ==
                      frozenset(tuple(sorted(t)) for t in tris[i].tolist()) for i in sample)
    return {
        "triangles": len(v),
        "points_identical": bool(np.array_equal(pts, nv["points"])),
        "qdrefine_vs_exact": int((key_q != key_r).any(axis=1).sum()),
        "fraction_checked": len(sample), "fraction_agree": int(fraction_ok),
        "naive_differs": int(differs.sum()),
        "naive_differs_label": int((differs & label).sum()),
        "naive_differs_case": int((differs & ~label).sum()),
        "naive_differs_at_tie": int((differs & tie).sum()),
        "exact_ties": int(tie.sum()),
        "naive_invalid": int(bad_n.sum()),
        "naive_invalid_when_differs": int((bad_n & differs).sum()),
        "naive_invalid_not_qdrefine": int((bad_n & ~bad_q).sum()),
        "naive_zero_area": int(fn["zero_area"].sum()),
        "naive_inverted": int(fn["inverted"].sum()),
        "qdrefine_invalid": int(bad_q.sum()),
        "qdrefine_zero_area": int(fq["zero_area"].sum()),
        "qdrefine_inverted": int(fq["inverted"].sum()),
        "area_exact": int(area_exact.sum()),
        "max_relative_area_change": rel,
        "naive_order_dependent": int(naive.order_dependent(
            v, lambda w: naive.naive_qd(w)["triangles"]).sum()),
        "qdrefine_order_dependent": int(naive.order_dependent(
            v, lambda w: qdrefine.partition_many(w, "7t-qd", strict=False)[1]).sum()),
        "examples": {"naive_differs": _first(differs & ~tie, v),
                     "naive_invalid": _first(bad_n, v), "qdrefine_invalid": _first(bad_q, v)},
    }


def delaunay_row(v: NDArray[np.float64], methods: tuple[str, ...], n_fraction: int,
                 seed: int = 0) -> dict:
    """SciPy, Triangle and qdrefine's 7T-D on the nine points of triangles ``v (K, 3, 2)``.

    Sets whose nine float points are not distinct (trisection points rounded onto a vertex
    or onto each other) are counted and left out: no triangulation of them has 7 triangles.
    """
    pts = qdrefine.partition_many(v, "7t-d", strict=False)[0]
    ok = checks.distinct(pts)
    v, pts = v[ok], pts[ok]
    hull = checks.hull_boundary(pts)
    on_hull = hull.any(axis=2).sum(axis=1)
    ccw = exact.orient_sign(v[:, 0], v[:, 1], v[:, 2]) > 0
    gon = checks.cycle_boundary(local.ninegon(ccw), 9)
    off = np.zeros(len(v), dtype=bool)
    for a, b in ((0, 1), (0, 2), (1, 2)):
        for near in (local.NEAR[a, b], local.NEAR[b, a]):
            off |= exact.orient_sign(v[:, a], v[:, b], pts[:, near]) != 0
    out: dict = {"sets": int(len(v)), "not_distinct": int((~ok).sum()),
                 "off_line": int(off.sum()),
                 "hull_is_ninegon": int((hull == gon).all(axis=(1, 2)).sum()),
                 "methods": {}}
    for method in methods:
        tris, err = delaunay.run(method, v, pts)
        f = checks.triangulation_flags(pts, tris, {"hull": hull, "gon": gon})
        seven = f["n_triangles"] == 7
        wrong = (f["missing"] | f["not_tiling hull"] | f["not_delaunay"]) | err
        usable = seven & ~f["missing"] & ~f["not_tiling gon"]
        broken = err | f["zero_area"] | f["inverted"] | f["missing"]
        row = {
            "errors": int(err.sum()),
            "not_7": int((~seven).sum()),
            "expected_count": int((f["n_triangles"] == 16 - on_hull).sum()),
            "missing_point": int(f["missing"].sum()),
            "zero_area": int(f["zero_area"].sum()),
            "inverted": int(f["inverted"].sum()),
            "not_triangulation": int(f["not_tiling hull"].sum()),
            "not_delaunay": int(f["not_delaunay"].sum()),
            "wrong_delaunay": int(wrong.sum()),
            "broken": int(broken.sum()),
            "usable_7t": int(usable.sum()),
            "examples": {"wrong_delaunay": _first(wrong, v), "not_usable": _first(~usable, v)},
        }
        if method == "qdrefine 7t-d":
            sample = _fraction_sample(len(v), n_fraction, seed)
            row["fraction_checked"] = len(sample)
            row["fraction_delaunay"] = int(sum(exact.fraction_delaunay_ok(v[i], tris[i])
                                               for i in sample))
        out["methods"][method] = row
    return out
