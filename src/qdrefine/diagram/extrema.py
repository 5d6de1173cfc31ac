"""Certified extrema of the 7T-QD / 7T-D minimum-angle ratio over the shaded region.

One concern, hence one module over 400 lines: the region's boundary, the normalized
angles, their interval bounds and the branch and bound that certifies the extrema are one
argument, read top to bottom.

The closure of the shaded region (7T-QD's fan ``O`` where 7T-D uses fan ``D``) is bounded by
four curves that meet at four corners::

    base   y = 0                          from (2/5, 0)          to (1 - 1/sqrt3, 0)
    S      (x - 1)^2   + y^2 = 1/3        from (1 - 1/sqrt3, 0)  to (1/2, 1/sqrt12)
    I/III  (x - 1/3)^2 + y^2 = 1/9        from (1/2, 1/sqrt12)   to (6/13, 4/13)
    II/III (x - 6/5)^2 + y^2 = 16/25      from (6/13, 4/13)      to (2/5, 0)

(:data:`BOUNDARY`; the circles are decision forms of :mod:`qdrefine.schemes`, checked against
:func:`qdrefine.diagram.decision_arcs` by the tests). The ratio is that of the interior's fans
(7T-QD: ``O``, 7T-D: ``D``) extended continuously to the closure. Triangles on the boundary
have those fans only where the tie rules keep them (:data:`ATTAINED_ON`); elsewhere an
extremum on the boundary is an infimum (or supremum) that triangles approach but no triangle
reaches.

Angles are used *normalized*, ``theta / y``: every angle of a stencil triangle is
``atan2(|k| y, d(x, y))`` with a constant ``k`` and ``d = A + B x + C (x^2 + y^2)``, so
``theta / y = |k| g(|k| y, d)`` with ``g(c, d) = atan2(c, d) / c`` (``g(0, d) = 1/d``), which
is finite on the base ``y = 0`` (degenerate triangles: the ratio's limit) and decreasing in
both ``c`` and ``d``. Ratios of angles are ratios of normalized angles.

:func:`worst_ratio` returns, for one reading of the paper's "20% worse" (:data:`READINGS`):

* an **upper bound** ``U``: the smallest ratio found at points of the closure: every local
  minimum of a dense sampling of each boundary curve polished by golden-section search, the
  four corners, and the centres of the branch-and-bound boxes;
* a **lower bound** ``L``: interval branch and bound over the whole closure (interior
  included): on a box the range of ``c`` and of ``d`` is exact (``c`` is linear in ``y``,
  ``d`` separates into a quadratic in ``x`` plus ``C y^2``), ``g`` is monotone, so each
  normalized angle gets an enclosure, widened by a relative ``1e-12`` for rounding; the ratio
  is at least ``min(lower QD) / min(upper D)``. Boxes whose lower bound is at least
  ``U - delta`` are discarded; the rest are quartered.

The true minimum lies in ``[L, U]``; ``U - L`` is the stated error bound. The same search
on ``QD - D`` in degrees (exact angle enclosures: the polar angle of a rectangle of ``(d, c)``
is extreme at a corner) gives :func:`largest_gap`. One concern (certified extrema), hence
over 400 lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..stencil import FIXED_7T, SEVEN, fan

__all__ = ["READINGS", "BOUNDARY", "CORNERS", "ATTAINED_ON", "Extremum", "reading_triangles",
           "normalized_angles", "angles", "ratio", "gap", "in_closure", "worst_ratio",
           "worst_ratios", "largest_gap"]

_QD_FAN = fan("O")
_D_FAN = fan("D")
_SHARED = tuple(t for t in _QD_FAN if frozenset(t) in {frozenset(s) for s in _D_FAN})
_QD_TWO = tuple(t for t in _QD_FAN if t not in _SHARED)
_D_TWO = tuple(t for t in _D_FAN if frozenset(t) not in {frozenset(s) for s in _SHARED})

#: The readings of "the minimum angle of the other two triangles are, in the worst case, only
#: a 20% worse than the minimum angle of the Delaunay refinement" (Sec. 1):
#: name -> (description, 7T-QD triangles, 7T-D triangles).
READINGS: dict[str, tuple[str, tuple[str, ...], tuple[str, ...]]] = {
    "pentagon": ("the three pentagon triangles of each partition (the measure of Figs. 8-10)",
                 _QD_FAN, _D_FAN),
    "two": ("the two 7T-QD triangles that differ from 7T-D against the two 7T-D triangles "
            "they replace", _QD_TWO, _D_TWO),
    "seven": ("all seven triangles of each partition", FIXED_7T + _QD_FAN, FIXED_7T + _D_FAN),
    "two-vs-refinement": ("the two differing 7T-QD triangles against the whole 7T-D "
                          "refinement (the sentence of Sec. 1, word for word)",
                          _QD_TWO, FIXED_7T + _D_FAN),
}

_R3 = 1 / math.sqrt(3)
#: The corners of the closure of the shaded region.
CORNERS: dict[str, tuple[float, float]] = {
    "base / II-III": (0.4, 0.0),
    "base / S": (1 - _R3, 0.0),
    "S / I-III (x = 1/2)": (0.5, math.sqrt(1 / 12)),
    "I-III / II-III": (6 / 13, 4 / 13),
}


@dataclass(frozen=True)
class Curve:
    """A boundary curve: ``(cx + r cos t, r sin t)`` for ``t`` in ``[t0, t1]`` (``r = 0``:
    the base ``(t, 0)``)."""

    name: str
    cx: float
    r: float
    t0: float
    t1: float

    def point(self, t: NDArray) -> tuple[NDArray, NDArray]:
        t = np.asarray(t, dtype=np.float64)
        if self.r == 0:
            return t, np.zeros_like(t)
        return self.cx + self.r * np.cos(t), np.maximum(self.r * np.sin(t), 0.0)


#: The four boundary curves of the closure of the shaded region.
BOUNDARY: tuple[Curve, ...] = (
    Curve("base y = 0", 0.0, 0.0, 0.4, 1 - _R3),
    Curve("S: (x-1)^2 + y^2 = 1/3", 1.0, _R3, 5 * math.pi / 6, math.pi),
    Curve("I/III: (x-1/3)^2 + y^2 = 1/9", 1 / 3, 1 / 3, math.pi / 3, math.acos(5 / 13)),
    Curve("II/III: (x-6/5)^2 + y^2 = 16/25", 1.2, 0.8, math.pi - math.acos(12 / 13), math.pi),
)

#: Where on the closure the triangles have the interior's fans themselves, so that an
#: extremum there is attained, by the tie rules of ``docs/schemes.md``: the interior; the
#: ``S`` arc (7T-D's fans ``O`` and ``D`` are both Delaunay there and rule 6 takes ``D``);
#: the ``II/III`` arc (rule 4 keeps 7T-QD's Case III). Not on the base (degenerate
#: triangles) nor on the ``I/III`` arc and its corners (rule 3 gives 7T-QD's Case I, and
#: 7T-D's first Delaunay fan there is the same fan ``B``: ratio 1). ``tests/test_diagram.py``
#: checks the arcs with triangles of integer coordinates on them.
ATTAINED_ON: tuple[str, ...] = ("interior", BOUNDARY[1].name, BOUNDARY[3].name)


def reading_triangles(reading: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """``(7T-QD triangles, 7T-D triangles)`` compared by a reading."""
    if reading not in READINGS:
        raise ValueError(f"unknown reading {reading!r}; choose one of: {', '.join(READINGS)}")
    return READINGS[reading][1], READINGS[reading][2]


def _angle_coefficients(names: tuple[str, ...]) -> NDArray[np.float64]:
    """``(3 T, 4)`` rows ``(k, A, B, C)``: the angle at each vertex of each triangle is
    ``atan2(|k| y, A + B x + C (x^2 + y^2))``."""
    rows = []
    for tri in names:
        for i in range(3):
            p0, p1, p2 = (SEVEN.coefficients(tri[(i + j) % 3]) for j in range(3))
            un, uo = float(p1[0] - p0[0]), float(p1[1] - p0[1])
            vn, vo = float(p2[0] - p0[0]), float(p2[1] - p0[1])
            rows.append((un * vo - vn * uo, un * vn, un * vo + uo * vn, uo * vo))
    return np.array(rows)


def _g(c: NDArray, d: NDArray) -> NDArray:
    """``atan2(c, d) / c`` for ``c >= 0`` (``1/d`` at ``c = 0``, ``inf`` if also ``d <= 0``)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        small = c <= 1e-8 * np.abs(d)
        t = c / np.where(d == 0, 1.0, d)
        series = (1 - t * t / 3) / np.where(d == 0, np.nan, d)  # atan(t)/t to O(t^4)
        series = np.where(d > 0, series, np.inf)
        return np.where(small, series, np.arctan2(c, d) / np.where(c > 0, c, 1.0))


def normalized_angles(x: ArrayLike, y: ArrayLike, names: tuple[str, ...]) -> NDArray:
    """``theta / y`` of every angle of the named stencil triangles, ``(K, 3 T)``.

    ``x, y : (K,) float`` with ``y >= 0``; at ``y = 0`` the limit (degenerate triangle).
    """
    x = np.atleast_1d(np.asarray(x, dtype=np.float64))[:, None]
    y = np.atleast_1d(np.asarray(y, dtype=np.float64))[:, None]
    k, a, b, c = _angle_coefficients(names).T
    ak = np.abs(k)
    return ak * _g(ak * y, a + b * x + c * (x * x + y * y))


def ratio(x: ArrayLike, y: ArrayLike, reading: str = "pentagon") -> NDArray[np.float64]:
    """7T-QD / 7T-D minimum-angle ratio of a reading at diagram points ``(K,)`` (fans O and
    D, i.e. the shaded region's; the limit on ``y = 0``)."""
    q, d = reading_triangles(reading)
    return normalized_angles(x, y, q).min(axis=1) / normalized_angles(x, y, d).min(axis=1)


def in_closure(x: ArrayLike, y: ArrayLike, slack: float = 0.0) -> NDArray[np.bool_]:
    """Membership in the closure of the shaded region (``slack`` widens every constraint)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    return ((y >= -slack) & (x <= 0.5 + slack) & ((x - 1) ** 2 + y * y >= 1 / 3 - slack)
            & ((x - 1.2) ** 2 + y * y <= 0.64 + slack)
            & ((x - 1 / 3) ** 2 + y * y <= 1 / 9 + slack))


# ---------------------------------------------------------------------------------------
# enclosures on boxes


def _sq_range(lo, hi, centre):
    """Range of ``(t - centre)^2`` for ``t`` in ``[lo, hi]``."""
    a, b = (lo - centre) ** 2, (hi - centre) ** 2
    inside = (lo <= centre) & (centre <= hi)
    return np.where(inside, 0.0, np.minimum(a, b)), np.maximum(a, b)


def _box_in_closure(x0, x1, y0, y1):
    """Boxes that may meet the closure (conservative)."""
    ok = (x0 <= 0.5) & (y1 >= 0)
    for cx, r2, side in ((1.0, 1 / 3, ">="), (1.2, 0.64, "<="), (1 / 3, 1 / 9, "<=")):
        lo, hi = _sq_range(x0, x1, cx)
        ylo, yhi = _sq_range(y0, y1, 0.0)
        if side == ">=":
            ok &= hi + yhi >= r2 * (1 - 1e-12)
        else:
            ok &= lo + ylo <= r2 * (1 + 1e-12)
    return ok


def _box_angles(coef, x0, x1, y0, y1):
    """Lower and upper bounds ``(K, 3 T)`` of every normalized angle over boxes."""
    k, a, b, c = (v[None, :] for v in coef.T)
    x0, x1, y0, y1 = (v[:, None] for v in (x0, x1, y0, y1))
    ak = np.abs(k)
    # d = A + B x + C x^2 + C y^2: a quadratic in x plus C y^2, ranges exact
    qa = a + b * x0 + c * x0 * x0
    qb = a + b * x1 + c * x1 * x1
    qlo, qhi = np.minimum(qa, qb), np.maximum(qa, qb)
    with np.errstate(divide="ignore", invalid="ignore"):
        xv = np.where(c != 0, -b / (2 * np.where(c != 0, c, 1.0)), np.nan)
    inside = (x0 < xv) & (xv < x1)
    qv = a + b * xv + c * xv * xv
    qlo = np.where(inside, np.minimum(qlo, qv), qlo)
    qhi = np.where(inside, np.maximum(qhi, qv), qhi)
    ylo, yhi = y0 * y0, y1 * y1
    dlo = qlo + np.minimum(c * ylo, c * yhi)
    dhi = qhi + np.maximum(c * ylo, c * yhi)
    pad = 1e-13 * (np.abs(a) + np.abs(b) + np.abs(c) + 1)
    lower = ak * _g(ak * y1, dhi + pad)
    upper = ak * _g(ak * y0, dlo - pad)
    return lower * (1 - 1e-12), upper * (1 + 1e-12)


def _box_ratio_lower(coef_q, coef_d, x0, x1, y0, y1):
    lq = _box_angles(coef_q, x0, x1, y0, y1)[0].min(axis=1)
    ud = _box_angles(coef_d, x0, x1, y0, y1)[1].min(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(ud), lq / ud, 0.0)


# ---------------------------------------------------------------------------------------
# the search


@dataclass(frozen=True)
class Extremum:
    """A certified extremum over the closed shaded region: the true value lies in
    ``[lower, upper]``.

    Attributes
    ----------
    reading : str
    quantity : str
        ``"ratio"`` (7T-QD / 7T-D min angle) or ``"gap"`` (7T-D - 7T-QD min angle, degrees).
    sense : {"min", "max"}
    value : float
        The extremum found at a point of the closure (the value there of the interior's
        fans, continued to the boundary: attained by a triangle only when :attr:`attained`).
    certified : float
        The other end from interval branch and bound (below ``value`` for a minimum, above
        for a maximum).
    point : (float, float)
        Where ``value`` is found.
    where : str
        The boundary curve or corner of ``point`` ("interior" if none).
    boxes : int
        Boxes examined by the branch and bound.
    """

    reading: str
    quantity: str
    sense: str
    value: float
    certified: float
    point: tuple[float, float]
    where: str
    boxes: int

    @property
    def lower(self) -> float:
        return self.certified if self.sense == "min" else self.value

    @property
    def upper(self) -> float:
        return self.value if self.sense == "min" else self.certified

    @property
    def attained(self) -> bool:
        """Whether a triangle at :attr:`point` has the partitions compared
        (:data:`ATTAINED_ON`); if not, :attr:`value` is an infimum (a supremum for a gap)
        that triangles approach without reaching it."""
        return self.where in ATTAINED_ON

    @property
    def bound(self) -> float:
        """``upper - lower`` plus float rounding of ``value`` (``1e-14``)."""
        return self.upper - self.lower + 1e-14


def _golden(f, a, b, tol=1e-15, iterations=200):
    g = (math.sqrt(5) - 1) / 2
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iterations):
        if b - a <= tol * max(1.0, abs(a)):
            break
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return (c, fc) if fc < fd else (d, fd)


def _boundary_minimum(func, samples: int, polish: int = 4
                      ) -> tuple[float, tuple[float, float], str]:
    """Smallest value of ``func(x, y)`` on the corners and curves of the closure: the
    ``polish`` smallest sampled local minima of every curve, refined by golden-section search
    on their bracket."""
    best = (math.inf, (math.nan, math.nan), "")
    for name, (x, y) in CORNERS.items():
        v = float(func(np.array([x]), np.array([y]))[0])
        if v < best[0]:
            best = (v, (x, y), f"corner {name}")
    for curve in BOUNDARY:
        t = np.linspace(curve.t0, curve.t1, samples)
        v = func(*curve.point(t))
        # every sampled local minimum (including the ends), polished on its bracket
        left = np.concatenate([[np.inf], v[:-1]])
        right = np.concatenate([v[1:], [np.inf]])
        minima = np.flatnonzero((v <= left) & (v <= right))
        for i in minima[np.argsort(v[minima], kind="stable")[:polish]]:
            lo, hi = t[max(i - 1, 0)], t[min(i + 1, samples - 1)]

            def f(s, curve=curve):
                return float(func(*curve.point(np.array([s])))[0])

            s, fs = _golden(f, lo, hi)
            if fs < best[0]:
                xs, ys = curve.point(np.array([s]))
                best = (fs, (float(xs[0]), float(ys[0])), curve.name)
    for name, (x, y) in CORNERS.items():
        if math.hypot(best[1][0] - x, best[1][1] - y) < 1e-7:
            best = (best[0], best[1], f"corner {name}")
    return best


def _certified_minimum(func, box_lower, delta: float, samples: int, max_rounds: int,
                       max_boxes: int = 200_000
                       ) -> tuple[float, tuple[float, float], str, float, int]:
    """Minimum of ``func`` over the closure: ``(value, point, where, lower, boxes)``."""
    value, point, where = _boundary_minimum(func, samples)
    n = 32
    ex = np.linspace(0.4, 0.5, n + 1)
    ey = np.linspace(0.0, 4 / 13 + 1e-9, n + 1)
    X0, Y0 = (a.ravel() for a in np.meshgrid(ex[:-1], ey[:-1]))
    X1, Y1 = (a.ravel() for a in np.meshgrid(ex[1:], ey[1:]))
    lower = math.inf
    examined = 0
    for _ in range(max_rounds):
        keep = _box_in_closure(X0, X1, Y0, Y1)
        X0, X1, Y0, Y1 = X0[keep], X1[keep], Y0[keep], Y1[keep]
        if X0.size == 0:
            break
        examined += X0.size
        xc, yc = 0.5 * (X0 + X1), 0.5 * (Y0 + Y1)
        feasible = in_closure(xc, yc)
        if feasible.any():
            rc = func(xc[feasible], yc[feasible])
            j = int(np.argmin(rc))
            if rc[j] < value:
                value, point, where = float(rc[j]), (float(xc[feasible][j]),
                                                     float(yc[feasible][j])), "interior"
        lb = box_lower(X0, X1, Y0, Y1)
        done = lb >= value - delta
        if done.any():
            lower = min(lower, float(lb[done].min()))
        X0, X1, Y0, Y1 = X0[~done], X1[~done], Y0[~done], Y1[~done]
        if X0.size == 0:
            break
        if X0.size > max_boxes or (X1 - X0).max() < 1e-13:
            # float boxes cannot shrink further: the rest bounds the minimum as it is
            lower = min(lower, float(lb[~done].min()))
            break
        xm, ym = 0.5 * (X0 + X1), 0.5 * (Y0 + Y1)
        X0, X1, Y0, Y1 = (np.concatenate(v) for v in (
            (X0, xm, X0, xm), (xm, X1, xm, X1), (Y0, Y0, ym, ym), (ym, ym, Y1, Y1)))
    else:
        lower = min(lower, float(box_lower(X0, X1, Y0, Y1).min()))
    return value, point, where, min(lower, value), examined


def worst_ratio(reading: str = "pentagon", delta: float = 1e-10, samples: int = 2001,
                max_rounds: int = 60) -> Extremum:
    """Certified minimum of the 7T-QD / 7T-D min-angle ratio over the closed shaded region.

    Parameters
    ----------
    reading : str
        One of :data:`READINGS`.
    delta : float
        Boxes whose lower bound reaches ``value - delta`` are discarded: the returned
        ``lower`` is at least ``value - delta`` unless ``max_rounds`` ran out.
    samples : int
        Samples per boundary curve before golden-section polishing.

    Returns
    -------
    Extremum
        ``lower <= min <= value``.
    """
    q, d = reading_triangles(reading)
    cq, cd = _angle_coefficients(q), _angle_coefficients(d)
    value, point, where, lower, boxes = _certified_minimum(
        lambda x, y: ratio(x, y, reading),
        lambda x0, x1, y0, y1: _box_ratio_lower(cq, cd, x0, x1, y0, y1),
        delta, samples, max_rounds)
    return Extremum(reading, "ratio", "min", value, lower, point, where, boxes)


def angles(x: ArrayLike, y: ArrayLike, names: tuple[str, ...]) -> NDArray[np.float64]:
    """Every angle (radians) of the named stencil triangles at diagram points, ``(K, 3 T)``."""
    x = np.atleast_1d(np.asarray(x, dtype=np.float64))[:, None]
    y = np.atleast_1d(np.asarray(y, dtype=np.float64))[:, None]
    k, a, b, c = _angle_coefficients(names).T
    return np.arctan2(np.abs(k) * y, a + b * x + c * (x * x + y * y))


def gap(x: ArrayLike, y: ArrayLike, reading: str = "pentagon") -> NDArray[np.float64]:
    """7T-D minus 7T-QD minimum angle of a reading, degrees, ``(K,)``."""
    q, d = reading_triangles(reading)
    return np.degrees(angles(x, y, d).min(axis=1) - angles(x, y, q).min(axis=1))


def _box_true_angles(coef, x0, x1, y0, y1):
    """Lower and upper bounds of every angle (radians) over boxes: the polar angle of
    ``(d, c)`` on the rectangle of their ranges is extreme at a corner (``[0, pi]`` when the
    rectangle holds the origin)."""
    k, a, b, c = (v[None, :] for v in coef.T)
    ak = np.abs(k)
    X0, X1, Y0, Y1 = (v[:, None] for v in (x0, x1, y0, y1))
    qa = a + b * X0 + c * X0 * X0
    qb = a + b * X1 + c * X1 * X1
    qlo, qhi = np.minimum(qa, qb), np.maximum(qa, qb)
    with np.errstate(divide="ignore", invalid="ignore"):
        xv = np.where(c != 0, -b / (2 * np.where(c != 0, c, 1.0)), np.nan)
    inside = (X0 < xv) & (xv < X1)
    qv = a + b * xv + c * xv * xv
    qlo = np.where(inside, np.minimum(qlo, qv), qlo)
    qhi = np.where(inside, np.maximum(qhi, qv), qhi)
    pad = 1e-13 * (np.abs(a) + np.abs(b) + np.abs(c) + 1)
    dlo = qlo + np.minimum(c * Y0 * Y0, c * Y1 * Y1) - pad
    dhi = qhi + np.maximum(c * Y0 * Y0, c * Y1 * Y1) + pad
    clo, chi = ak * Y0, ak * Y1
    corners = np.stack([np.arctan2(clo, dlo), np.arctan2(clo, dhi), np.arctan2(chi, dlo),
                        np.arctan2(chi, dhi)])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    origin = (clo <= 0) & (dlo <= 0) & (dhi >= 0)
    lo = np.where(origin, 0.0, lo)
    hi = np.where(origin, np.pi, hi)
    return lo - 1e-15, hi + 1e-15


def largest_gap(reading: str = "pentagon", delta: float = 1e-10, samples: int = 2001,
                max_rounds: int = 60) -> Extremum:
    """Certified maximum of the 7T-D minus 7T-QD minimum angle (degrees) over the closed
    shaded region (same method as :func:`worst_ratio`, on ``QD - D``)."""
    q, d = reading_triangles(reading)
    cq, cd = _angle_coefficients(q), _angle_coefficients(d)

    def box_lower(x0, x1, y0, y1):
        lq = _box_true_angles(cq, x0, x1, y0, y1)[0].min(axis=1)
        ud = _box_true_angles(cd, x0, x1, y0, y1)[1].min(axis=1)
        return np.degrees(lq - ud)

    value, point, where, lower, boxes = _certified_minimum(
        lambda x, y: -gap(x, y, reading), box_lower, delta, samples, max_rounds)
    return Extremum(reading, "gap", "max", -value, -lower, point, where, boxes)


def worst_ratios(delta: float = 1e-10) -> dict[str, Extremum]:
    """:func:`worst_ratio` for every reading."""
    return {r: worst_ratio(r, delta) for r in READINGS}
