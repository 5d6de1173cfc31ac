"""The paper's regions as predicates on diagram points, and their areas."""

from __future__ import annotations

import numpy as np

from .arcs import Predicate, arc_area
from .mapping import _fan_measure, _fans_float, inside_half
from .quadrature import QuadResult, quadrature_area


def _pred(name: str) -> Predicate:
    def p(x, y):
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        f = _fans_float(x, y)
        h = inside_half(x, y)
        if name in ("I", "II", "III"):
            return h & (f["7t-qd"] == {"I": "B", "II": "D", "III": "O"}[name])
        shaded = h & (f["7t-qd"] != f["7t-d"])
        if name == "shaded":
            return shaded
        if name == "III-shaded":
            return h & (f["7t-qd"] == "O") & ~shaded
        le_above = _fan_measure(x, y, f["7t-le"], "min") > _fan_measure(x, y, f["7t-qd"], "min")
        if name == "le_min_above_qd":
            return h & le_above
        mean_above = (_fan_measure(x, y, f["7t-qd"], "mean")
                      > _fan_measure(x, y, f["7t-d"], "mean"))
        if name == "qd_mean_above_d":
            return shaded & mean_above
        if name == "C1":
            return shaded & le_above
        if name == "C2":
            return shaded & mean_above & ~le_above
        if name == "C3":
            return shaded & ~le_above & ~mean_above
        raise ValueError(f"unknown region {name!r}")

    return p


ARC_REGIONS = ("I", "II", "III", "shaded", "III-shaded")
ANGLE_REGIONS = ("C1", "C2", "C3", "le_min_above_qd", "qd_mean_above_d")
_LE_QD = ("7t-le", "7t-qd", "min")
_QD_D = ("7t-qd", "7t-d", "mean")
#: comparisons bounding each angle region, and the window in which they matter
_ANGLE_SETUP = {
    "C1": ([_LE_QD], "shaded"),
    "C2": ([_LE_QD, _QD_D], "shaded"),
    "C3": ([_LE_QD, _QD_D], "shaded"),
    "le_min_above_qd": ([_LE_QD], None),
    "qd_mean_above_d": ([_QD_D], "shaded"),
}


def region_area(name: str, method: str = "auto", tol: float = 1e-10, n_samples: int = 64,
                measure: str = "uniform") -> QuadResult:
    """Area of a region of ``H`` with an error estimate.

    ``method="exact"`` (arc-bounded regions, uniform measure) uses :func:`arc_area`, whose
    error is float rounding only (reported as ``1e-14``); ``"quadrature"`` uses
    :func:`quadrature_area`; ``"auto"`` picks exact when possible.
    """
    if method not in ("auto", "exact", "quadrature"):
        raise ValueError(f"unknown method {method!r}; choose one of: auto, exact, quadrature")
    arc_only = name in ARC_REGIONS
    if name not in ARC_REGIONS + ANGLE_REGIONS:
        raise ValueError(f"unknown region {name!r}; choose one of: "
                         f"{', '.join(ARC_REGIONS + ANGLE_REGIONS)}")
    if method == "exact" or (method == "auto" and arc_only and measure == "uniform"):
        if not arc_only or measure != "uniform":
            raise ValueError(f"region {name!r} in measure {measure!r} has no exact method")
        return QuadResult(arc_area(_pred(name)), 1e-14, 0, 0)
    if arc_only:
        return quadrature_area(_pred(name), tol=tol, n_samples=n_samples, measure=measure)
    comparisons, window = _ANGLE_SETUP[name]
    return quadrature_area(_pred(name), comparisons, _pred(window) if window else None,
                           tol=tol, n_samples=n_samples, measure=measure)
