"""The paper's mapping diagram: coordinates, regions and their areas, recomputed.

Every triangle is mapped to the apex ``O = (x, y)`` of the similar triangle whose longest
edge is ``M = (0, 0)``, ``N = (1, 0)``, using the canonical labelling of
:mod:`qdrefine.kernels` (so ``x <= 1/2``: the *left half* of the diagram)::

    H = {0 <= x <= 1/2, y > 0, (x - 1)^2 + y^2 <= 1},   area(H) = pi/6 - sqrt(3)/8.

Regions (all subsets of ``H``; scheme decisions are those of :mod:`qdrefine.schemes`):

* ``I``, ``II``, ``III``: the three cases of 7T-QD (Definition 1, tie rules of
  ``docs/schemes.md``);
* ``shaded``: 7T-QD splits the pentagon A-D-C-B-O differently from 7T-D;
* ``C1 = shaded & {min LE > min QD}``, ``C2 = (shaded & {mean QD > mean D}) - C1``,
  ``C3 = shaded - C1 - C2``, where *min* and *mean* are the smallest angle and the mean of
  the smallest angles of the three pentagon triangles of a partition;
* ``le_min_above_qd``: ``H & {min LE > min QD}``.

Every scheme decision is the sign of a form ``a uu + b ww + c uw``; in the diagram
``uu = 1, ww = x^2 + y^2, uw = x``, so each decision boundary is a circle (or a vertical
line) and the regions ``I, II, III, shaded`` are bounded by circular arcs. Their areas are
computed *exactly* (:func:`arc_area`): the ``x`` axis is cut at every arc end and every
intersection of two arcs, and inside each slab the area between consecutive arcs is the
closed-form integral of ``sqrt(r^2 - (x - c)^2)``.

Regions bounded by angle-equality curves (``C1``, ``C2``, ``C3``, ``le_min_above_qd``) are
integrated numerically (:func:`quadrature_area`): for each ``x``, the ``y`` roots of every
boundary function (arcs: closed form; angle differences: sampled sign changes refined by
bisection to ~1e-15) cut the vertical line into pieces of constant membership, whose lengths
are summed; that length is integrated in ``x`` with an adaptive Gauss-Kronrod (7, 15) rule
whose summed ``|K15 - G7|`` is the reported error estimate.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from .kernels import canonical, decide
from .predicates import SCRATCH, factor_forms
from .schemes import SCHEMES
from .stencil import SEVEN, fan

__all__ = [
    "HALF_AREA",
    "REGIONS",
    "to_diagram",
    "stencil_points",
    "scheme_fans",
    "region_masks",
    "fan_angles",
    "partition_measure",
    "arc_area",
    "quadrature_area",
    "DiagramResult",
    "compute",
]

#: Area of the left half of the diagram, ``pi/6 - sqrt(3)/8``.
HALF_AREA = math.pi / 6 - math.sqrt(3) / 8
#: Area of the left half in the two-smallest-angles measure: the triangle
#: ``0 < beta <= alpha, 2 alpha + beta <= pi`` has area ``pi^2 / 12``.
HALF_ANGLE_AREA = math.pi**2 / 12
REGIONS = ("I", "II", "III", "shaded", "C1", "C2", "C3")
FANS = ("B", "D", "O", "A", "C")
_SCHEMES_7T = ("7t-qd", "7t-le", "7t-d")

# ----------------------------------------------------------------------------------------
# mapping triangles to the diagram


@njit(cache=True)
def _canonical_many(v):
    k = v.shape[0]
    out = np.empty((k, 3), dtype=np.int64)
    buf = np.empty(SCRATCH)
    for t in range(k):
        im, jn, ko = canonical(v[t, 0, 0], v[t, 0, 1], v[t, 1, 0], v[t, 1, 1],
                               v[t, 2, 0], v[t, 2, 1], buf)
        out[t, 0] = im
        out[t, 1] = jn
        out[t, 2] = ko
    return out


def to_diagram(vertices: ArrayLike) -> NDArray[np.float64]:
    """Diagram coordinates of triangles.

    Parameters
    ----------
    vertices : (K, 3, 2) float
        Triangles in any orientation and vertex order (one ``(3, 2)`` triangle is accepted).

    Returns
    -------
    (K, 2) float64
        The apex ``(x, y)`` of the similar triangle with longest edge ``(0,0)-(1,0)``, in the
        left half ``x <= 1/2`` (canonical labelling of :func:`qdrefine.kernels.canonical`,
        whose tie rules decide which longest edge and which endpoint is ``M``).

    Examples
    --------
    >>> to_diagram([[0, 0], [4, 0], [3, 1]]).round(4).tolist()
    [[0.25, 0.25]]
    """
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim == 2:
        v = v[None]
    if v.ndim != 3 or v.shape[1:] != (3, 2):
        raise ValueError(f"vertices must have shape (K, 3, 2), got {v.shape}")
    lab = _canonical_many(np.ascontiguousarray(v))
    rows = np.arange(v.shape[0])
    m, n, o = (v[rows, lab[:, i]] for i in range(3))
    u = n - m
    w = o - m
    uu = (u * u).sum(axis=1)
    x = (u * w).sum(axis=1) / uu
    y = np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]) / uu
    return np.stack([np.minimum(x, 1.0 - x), y], axis=1)


# ----------------------------------------------------------------------------------------
# scheme decisions and angles at diagram points


@njit(cache=True)
def _rows_exact(x, y, forms, lut):
    out = np.empty(x.shape[0], dtype=np.int64)
    buf = np.empty(SCRATCH)
    factors = factor_forms(forms)
    for i in range(x.shape[0]):
        out[i] = decide(0.0, 0.0, 1.0, 0.0, x[i], y[i], forms, factors, lut, buf)[3]
    return out


def _rows_float(x, y, scheme):
    """Table rows from float evaluation of the forms (used at points far from arcs)."""
    sch = SCHEMES[scheme]
    ww = x * x + y * y
    code = np.zeros(np.shape(x), dtype=np.int64)
    for f, (a, b, c) in enumerate(sch.forms):
        code += (np.sign(a + b * ww + c * x).astype(np.int64) + 1) * 3**f
    return sch.lut[code]


def scheme_fans(x: ArrayLike, y: ArrayLike, scheme: str, exact: bool = True) -> NDArray[np.str_]:
    """Apex letter (``"B", "D", "O", "A", "C"``) of the pentagon fan ``scheme`` uses.

    Parameters
    ----------
    x, y : (K,) float
        Diagram points, ``0 <= x <= 1/2``, ``y > 0``, inside the diagram.
    scheme : {"7t-qd", "7t-le", "7t-d"}
    exact : bool
        ``True``: the exact decision of the refinement kernels for the triangle
        ``(0,0), (1,0), (x, y)`` (:func:`qdrefine.kernels.decide`); ``False``: float
        evaluation of the forms (faster; only for points not on a decision arc).
    """
    if scheme not in _SCHEMES_7T:
        raise ValueError(f"unknown seven-triangle scheme {scheme!r}; choose one of: "
                         f"{', '.join(_SCHEMES_7T)}")
    xa = np.ascontiguousarray(np.atleast_1d(np.asarray(x, dtype=np.float64)))
    ya = np.ascontiguousarray(np.atleast_1d(np.asarray(y, dtype=np.float64)))
    sch = SCHEMES[scheme]
    rows = _rows_exact(xa, ya, sch.forms, sch.lut) if exact else _rows_float(xa, ya, scheme)
    letters = np.array([r[-1] for r in sch.rows])
    return letters[rows]


def inside_half(x: ArrayLike, y: ArrayLike) -> NDArray[np.bool_]:
    """``0 <= x <= 1/2``, ``y > 0`` and ``(x - 1)^2 + y^2 <= 1``."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    return (x >= 0) & (x <= 0.5) & (y > 0) & ((x - 1) ** 2 + y * y <= 1)


def stencil_points(x: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
    """The nine points ``M N O D C Q B A P`` of the triangle with apex ``(x, y)``, ``(K, 9, 2)``."""
    x = np.atleast_1d(np.asarray(x, dtype=np.float64))
    y = np.atleast_1d(np.asarray(y, dtype=np.float64))
    w = np.array([[float(c) for c in row] for row in SEVEN.weights])  # (9, 3) over M, N, O
    px = w[:, 1][None, :] + w[:, 2][None, :] * x[:, None]
    py = w[:, 2][None, :] * y[:, None]
    return np.stack([px, py], axis=-1)


def _tri_angles(p: NDArray) -> NDArray:
    """Angles (degrees) ``(..., 3)`` of triangles ``(..., 3, 2)``."""
    a = np.roll(p, -1, axis=-2) - p
    b = np.roll(p, 1, axis=-2) - p
    cross = np.abs(a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0])
    dot = (a * b).sum(axis=-1)
    return np.degrees(np.arctan2(cross, dot))


def _names_index(names):
    return np.array([[SEVEN.index(c) for c in t] for t in names])


_FIXED_IDX = _names_index(("MDP", "PDA", "CQB", "CNQ"))
_FAN_IDX = {a: _names_index(fan(a)) for a in FANS}


def fan_angles(x: ArrayLike, y: ArrayLike, apex: str) -> NDArray[np.float64]:
    """Smallest angle (degrees) of each of the three triangles of a pentagon fan, ``(K, 3)``."""
    p = stencil_points(x, y)
    return _tri_angles(p[:, _FAN_IDX[apex]]).min(axis=-1)


def fixed_angles(x: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
    """Smallest angle of each of the four fixed corner triangles, ``(K, 4)``."""
    p = stencil_points(x, y)
    return _tri_angles(p[:, _FIXED_IDX]).min(axis=-1)


MEASURES = ("min", "mean")
OVER = ("pentagon", "all")


def partition_measure(x: ArrayLike, y: ArrayLike, scheme: str, measure: str = "min",
                      over: str = "pentagon", exact: bool = True) -> NDArray[np.float64]:
    """Min angle or mean min angle (degrees) of a scheme's partition at diagram points.

    Parameters
    ----------
    x, y : (K,) float
    scheme : {"7t-qd", "7t-le", "7t-d"}
    measure : {"min", "mean"}
        Smallest angle of the triangles, or the mean of their smallest angles.
    over : {"pentagon", "all"}
        The three triangles inside the pentagon A-D-C-B-O (the paper's measure), or all seven.
    """
    if measure not in MEASURES:
        raise ValueError(f"unknown measure {measure!r}; choose one of: {', '.join(MEASURES)}")
    if over not in OVER:
        raise ValueError(f"unknown over {over!r}; choose one of: {', '.join(OVER)}")
    fans = scheme_fans(x, y, scheme, exact=exact)
    x = np.atleast_1d(np.asarray(x, dtype=np.float64))
    y = np.atleast_1d(np.asarray(y, dtype=np.float64))
    per = np.empty((x.shape[0], 3))
    for a in np.unique(fans):
        sel = fans == a
        per[sel] = fan_angles(x[sel], y[sel], a)
    if over == "all":
        per = np.concatenate([fixed_angles(x, y), per], axis=1)
    return per.min(axis=1) if measure == "min" else per.mean(axis=1)


def region_masks(x: ArrayLike, y: ArrayLike, exact: bool = True) -> dict[str, NDArray[np.bool_]]:
    """Membership of diagram points in every region (points outside ``H`` are in none).

    Returns a dict with keys ``I, II, III, shaded, C1, C2, C3, le_min_above_qd``, each
    ``(K,) bool``. Scheme decisions are exact when ``exact``; angles are float64.
    """
    x = np.atleast_1d(np.asarray(x, dtype=np.float64))
    y = np.atleast_1d(np.asarray(y, dtype=np.float64))
    h = inside_half(x, y)
    qd = np.full(x.shape, "-", dtype="<U1")
    d = qd.copy()
    qd[h] = scheme_fans(x[h], y[h], "7t-qd", exact)
    d[h] = scheme_fans(x[h], y[h], "7t-d", exact)
    out = {"I": h & (qd == "B"), "II": h & (qd == "D"), "III": h & (qd == "O")}
    shaded = h & (qd != d)
    le_above = np.zeros(x.shape, dtype=bool)
    qd_mean_above = np.zeros(x.shape, dtype=bool)
    if h.any():
        xs, ys = x[h], y[h]
        le = partition_measure(xs, ys, "7t-le", "min", exact=exact)
        q = partition_measure(xs, ys, "7t-qd", "min", exact=exact)
        le_above[h] = le > q
        qm = partition_measure(xs, ys, "7t-qd", "mean", exact=exact)
        dm = partition_measure(xs, ys, "7t-d", "mean", exact=exact)
        qd_mean_above[h] = qm > dm
    out["shaded"] = shaded
    out["C1"] = shaded & le_above
    out["C2"] = shaded & qd_mean_above & ~le_above
    out["C3"] = shaded & ~out["C1"] & ~out["C2"]
    out["le_min_above_qd"] = h & le_above
    return out


# ----------------------------------------------------------------------------------------
# arcs: every decision form as a circle in the diagram


@dataclass(frozen=True)
class Arc:
    """The zero set of ``a + b (x^2 + y^2) + c x`` (``b != 0``): circle ``(cx, r)``."""

    a: float
    b: float
    c: float

    @property
    def cx(self) -> float:
        return -self.c / (2 * self.b)

    @property
    def r2(self) -> float:
        return self.cx**2 - self.a / self.b

    def y(self, x: NDArray) -> NDArray:
        """Upper ordinate ``sqrt(r^2 - (x - cx)^2)``, NaN where the circle does not reach."""
        with np.errstate(invalid="ignore"):
            return np.sqrt(self.r2 - (x - self.cx) ** 2)

    def integral(self, x0: float, x1: float) -> float:
        """``int_{x0}^{x1} sqrt(r^2 - (x - cx)^2) dx`` in closed form."""
        r2 = self.r2
        r = math.sqrt(r2)

        def g(t: float) -> float:
            t = min(max(t, -r), r)
            h = math.sqrt(max((r - t) * (r + t), 0.0))  # accurate near t = +-r
            return 0.5 * (t * h + r2 * math.atan2(t, h))

        return g(x1 - self.cx) - g(x0 - self.cx)


#: The boundary of the diagram, ``(x - 1)^2 + y^2 = 1``.
DOMAIN_ARC = Arc(0.0, 1.0, -2.0)


def decision_arcs() -> tuple[list[Arc], list[float]]:
    """Circles and vertical lines ``x = const`` of every 7T scheme form (deduplicated)."""
    arcs: list[Arc] = [DOMAIN_ARC]
    lines: list[float] = []
    seen = {(DOMAIN_ARC.cx, DOMAIN_ARC.r2)}
    for name in _SCHEMES_7T:
        for a, b, c in SCHEMES[name].forms:
            if b == 0:
                if c != 0:
                    lines.append(-a / c)
                continue
            arc = Arc(float(a), float(b), float(c))
            key = (round(arc.cx, 14), round(arc.r2, 14))
            if key not in seen and arc.r2 > 0:
                seen.add(key)
                arcs.append(arc)
    return arcs, lines


def _critical_x(arcs: list[Arc], lines: list[float], lo: float, hi: float) -> list[float]:
    xs = {lo, hi}
    for arc in arcs:
        r = math.sqrt(arc.r2)
        xs.update((arc.cx - r, arc.cx + r))
    for i, p in enumerate(arcs):
        for q in arcs[i + 1:]:
            # x^2 + y^2 + (c/b) x + a/b = 0 for both: subtract
            k = p.c / p.b - q.c / q.b
            if k != 0:
                xi = -(p.a / p.b - q.a / q.b) / k
                if p.r2 - (xi - p.cx) ** 2 >= 0:
                    xs.add(xi)
    xs.update(lines)
    out: list[float] = []
    for v in sorted(v for v in xs if lo <= v <= hi):
        if out and v - out[-1] < 1e-12:
            out[-1] = hi if v == hi else out[-1]
            continue
        out.append(v)
    return out


Predicate = Callable[[NDArray, NDArray], NDArray]


def arc_area(predicate: Predicate, arcs: list[Arc] | None = None,
             lines: list[float] | None = None) -> float:
    """Exact area of ``{(x, y) in H: predicate}`` for a region bounded by ``arcs``.

    ``predicate(x, y)`` must be constant between consecutive arcs of every vertical line;
    it is evaluated once per piece, at the piece's midpoint. The area of a piece is the
    closed-form integral of its upper arc minus that of its lower arc (or the axis).
    """
    if arcs is None:
        arcs, lines = decision_arcs()
    lines = lines or []
    xs = _critical_x(arcs, lines, 0.0, 0.5)
    total = 0.0
    for x0, x1 in zip(xs[:-1], xs[1:], strict=True):
        if x1 - x0 <= 0:
            continue
        xm = 0.5 * (x0 + x1)
        ys = [(arc.y(np.array(xm)).item(), k) for k, arc in enumerate(arcs)]
        ys = sorted((v, k) for v, k in ys if v == v and v > 0)
        bounds = [(0.0, -1)] + ys
        mids_y = np.array([0.5 * (lo[0] + hi[0]) for lo, hi in zip(bounds[:-1], bounds[1:],
                                                                   strict=True)])
        keep = predicate(np.full(mids_y.shape, xm), mids_y) & inside_half(
            np.full(mids_y.shape, xm), mids_y)
        for (lo, hi), on in zip(zip(bounds[:-1], bounds[1:], strict=True), keep, strict=True):
            if on:
                total += arcs[hi[1]].integral(x0, x1)
                if lo[1] >= 0:
                    total -= arcs[lo[1]].integral(x0, x1)
    return total


# ----------------------------------------------------------------------------------------
# numerical areas: roots along y, adaptive Gauss-Kronrod along x

# full-precision nodes (QUADPACK qk15)
_NODES = np.array([
    -0.991455371120812639206854697526329, -0.949107912342758524526189684047851,
    -0.864864423359769072789712788640926, -0.741531185599394439863864773280788,
    -0.586087235467691130294144845693013, -0.405845151377397166906606412076961,
    -0.207784955007898467600689403773245, 0.0,
    0.207784955007898467600689403773245, 0.405845151377397166906606412076961,
    0.586087235467691130294144845693013, 0.741531185599394439863864773280788,
    0.864864423359769072789712788640926, 0.949107912342758524526189684047851,
    0.991455371120812639206854697526329])
_WK15 = np.array([
    0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
    0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
    0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
    0.204432940075298892414161999234649, 0.209482141084727828012999174891714,
    0.204432940075298892414161999234649, 0.190350578064785409913256402421014,
    0.169004726639267902826583426598550, 0.140653259715525918745189590510238,
    0.104790010322250183839876322541518, 0.063092092629978553290700663189204,
    0.022935322010529224963732008058970])
_WG7 = np.zeros(15)
_WG7[[1, 3, 5, 7, 9, 11, 13]] = [
    0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
    0.381830050505118944950369775488975, 0.417959183673469387755102040816327,
    0.381830050505118944950369775488975, 0.279705391489276667901467771423780,
    0.129484966168869693270611432679082]


@dataclass
class QuadResult:
    """An integral, its error estimate and the work done."""

    value: float
    error: float
    intervals: int
    evaluations: int


def gauss_kronrod(f: Callable[[NDArray], NDArray], breaks: list[float], tol: float,
                  max_intervals: int = 20000) -> QuadResult:
    """Adaptive GK(7,15) of a vectorized ``f`` over ``[breaks[0], breaks[-1]]``.

    Intervals are bisected, worst first (all those above their share of ``tol`` in one
    vectorized round), until the summed estimate ``sum |K15 - G7|`` is below ``tol``.
    """
    ivs = [(a, b) for a, b in zip(breaks[:-1], breaks[1:], strict=True) if b > a]
    done_val = 0.0
    done_err = 0.0
    evals = 0
    n_done = 0
    pending = ivs
    span = breaks[-1] - breaks[0]
    while pending:
        a = np.array([p[0] for p in pending])
        b = np.array([p[1] for p in pending])
        h = 0.5 * (b - a)
        xs = (0.5 * (a + b))[:, None] + h[:, None] * _NODES[None, :]
        fx = f(xs.ravel()).reshape(xs.shape)
        evals += fx.size
        k = (fx * _WK15).sum(axis=1) * h
        g = (fx * _WG7).sum(axis=1) * h
        err = np.abs(k - g)
        total_err = done_err + err.sum()
        if total_err <= tol or n_done + len(pending) >= max_intervals:
            done_val += k.sum()
            done_err += err.sum()
            n_done += len(pending)
            break
        # accept intervals whose error is below their share; bisect the rest
        share = tol * (2 * h) / span * 0.5
        ok = err <= share
        done_val += k[ok].sum()
        done_err += err[ok].sum()
        n_done += int(ok.sum())
        pending = []
        for ai, bi in zip(a[~ok], b[~ok], strict=True):
            mid = 0.5 * (ai + bi)
            pending += [(ai, mid), (mid, bi)]
    return QuadResult(float(done_val), float(done_err), n_done, evals)


def _ytop(x):
    return np.sqrt(np.maximum(1.0 - (x - 1.0) ** 2, 0.0))


def _sample_fractions(n: int) -> NDArray:
    """Fractions of a piece at which comparison functions are sampled: ``n`` uniform points
    plus a geometric grading (down to ``1e-13``) towards both ends, so that a sliver between
    an arc and a nearby root of the comparison is still bracketed."""
    uni = (np.arange(n) + 0.5) / n
    geo = np.geomspace(1e-13, 0.5 / n, 20, endpoint=False)
    return np.sort(np.concatenate([geo, uni, 1.0 - geo]))


def _measure_uniform(x, y):
    return y


def _measure_angles(x, y):
    """Antiderivative in ``y`` of the density ``y / ((x^2+y^2)((1-x)^2+y^2))`` of the
    two-smallest-angles measure (the Jacobian of ``(x, y) -> (angle M, angle N)``)."""
    d = 1.0 - 2.0 * x
    s = y * y + (1.0 - x) ** 2
    t = y * y + x * x
    with np.errstate(divide="ignore", invalid="ignore"):
        # log(t / s): log1p where t/s is near 1 (x near 1/2), a log difference elsewhere
        log_ratio = np.where(t < 0.5 * s, np.log(t) - np.log(s), np.log1p(-d / s))
        small = np.abs(d) < 1e-6  # limit d -> 0 of log1p(-d/s) / (2d), to O(d^2)
        return np.where(small, -1.0 / (2.0 * s) - d / (4.0 * s * s), log_ratio / (2.0 * d))


_MEASURE_FUNCS = {"uniform": _measure_uniform, "angles": _measure_angles}

#: A comparison ``(scheme_a, scheme_b, measure)``: the sign of ``measure(a) - measure(b)``.
Comparison = tuple[str, str, str]


def _fan_difference(a: str, b: str, measure: str) -> Callable[[NDArray, NDArray], NDArray]:
    """``measure(fan a) - measure(fan b)`` (pentagon triangles), a continuous function."""
    def g(x, y):
        fa = fan_angles(x, y, a)
        fb = fan_angles(x, y, b)
        if measure == "min":
            return fa.min(axis=1) - fb.min(axis=1)
        return fa.mean(axis=1) - fb.mean(axis=1)

    return g


def _bisect(g, x, lo, hi, slo, iterations=60):
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        same = (g(x, mid) > 0) == slo
        lo = np.where(same, mid, lo)
        hi = np.where(same, hi, mid)
        if np.all(hi - lo <= 2e-16):
            break
    return 0.5 * (lo + hi)


def _comparison_roots(x, lo, hi, fans, comparisons, samples):
    """Roots of every comparison inside every piece ``[lo, hi]`` (arrays ``(n,)``).

    Inside a piece (bounded by consecutive decision arcs) every scheme's fan is constant, so
    a comparison of two schemes is the continuous fixed-fan difference; its sign changes on
    the sampled fractions are bisected. Returns ``(piece index, root)`` flat arrays.
    """
    idx_out, root_out = [], []
    for sa, sb, meas in comparisons:
        fa, fb = fans[sa], fans[sb]
        for pair in set(zip(fa.tolist(), fb.tolist(), strict=True)):
            if pair[0] == pair[1]:
                continue  # the same partition: the difference is identically zero
            sel = np.flatnonzero((fa == pair[0]) & (fb == pair[1]))
            g = _fan_difference(pair[0], pair[1], meas)
            ys = lo[sel, None] + (hi - lo)[sel, None] * samples[None, :]
            xs = np.broadcast_to(x[sel, None], ys.shape)
            s = (g(xs.ravel(), ys.ravel()) > 0).reshape(ys.shape)
            i, j = np.nonzero(s[:, 1:] != s[:, :-1])
            if i.size:
                r = _bisect(g, x[sel][i], ys[i, j].copy(), ys[i, j + 1].copy(), s[i, j])
                idx_out.append(sel[i])
                root_out.append(r)
    if not idx_out:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    return np.concatenate(idx_out), np.concatenate(root_out)


def _line_measure(x, predicate, window, comparisons, arcs, n_samples, measure):
    """Measure of ``{y: (x, y) in H and predicate}`` for each ``x`` of a vector."""
    x = np.asarray(x, dtype=np.float64)
    k = x.shape[0]
    top = _ytop(x)
    cuts = [np.zeros((k, 1)), top[:, None]]
    for arc in arcs:
        yy = arc.y(x)
        cuts.append(np.where((yy > 0) & (yy < top), yy, top)[:, None])
    cuts = np.sort(np.concatenate(cuts, axis=1), axis=1)
    if comparisons:
        lo, hi = cuts[:, :-1].ravel(), cuts[:, 1:].ravel()
        owner = np.repeat(np.arange(k), cuts.shape[1] - 1)
        live = hi > lo
        mid = 0.5 * (lo + hi)
        live[live] = window(x[owner[live]], mid[live])
        live = np.flatnonzero(live)
        fans = _fans_float(x[owner[live]], mid[live])
        piece, roots = _comparison_roots(x[owner[live]], lo[live], hi[live], fans,
                                         comparisons, _sample_fractions(n_samples))
        rows = owner[live][piece]
        if rows.size:
            count = np.bincount(rows, minlength=k)
            extra = np.repeat(top[:, None], count.max(), axis=1)
            order = np.argsort(rows, kind="stable")
            rows, roots = rows[order], roots[order]
            first = np.concatenate([[0], np.cumsum(count)[:-1]])
            extra[rows, np.arange(rows.size) - first[rows]] = roots
            cuts = np.sort(np.concatenate([cuts, extra], axis=1), axis=1)
    lo, hi = cuts[:, :-1], cuts[:, 1:]
    mid = 0.5 * (lo + hi)
    xs = np.broadcast_to(x[:, None], mid.shape)
    on = hi > lo
    on[on] = predicate(xs[on], mid[on])
    phi = _MEASURE_FUNCS[measure]
    seg = np.zeros(mid.shape)
    seg[on] = phi(xs[on], hi[on]) - phi(xs[on], lo[on])
    return seg.sum(axis=1)


def quadrature_area(predicate: Predicate, comparisons: list[Comparison] = (),
                    window: Predicate | None = None, tol: float = 1e-10, n_samples: int = 64,
                    measure: str = "uniform") -> QuadResult:
    """Area of ``{(x, y) in H: predicate}`` by root finding in ``y`` and quadrature in ``x``.

    Parameters
    ----------
    predicate : callable ``(x, y) -> bool array``
        Membership; must be constant between consecutive cuts of each vertical line.
    comparisons : list of ``(scheme_a, scheme_b, measure)``
        Angle comparisons whose sign changes (besides the decision arcs, cut in closed form)
        bound the region. On each piece of a vertical line between two arcs where
        ``window`` holds, the fixed-fan difference is sampled at ``n_samples`` uniform and
        40 graded points and its sign changes are bisected to ``~2e-16``.
    tol : float
        Target for the summed Gauss-Kronrod error estimate.
    measure : {"uniform", "angles"}
        Lebesgue measure on the diagram, or the uniform measure in the two smallest angles
        (density ``y / ((x^2+y^2)((1-x)^2+y^2))``, total ``pi^2/12`` over ``H``).
    """
    if measure not in _MEASURE_FUNCS:
        raise ValueError(f"unknown measure {measure!r}; choose one of: "
                         f"{', '.join(_MEASURE_FUNCS)}")
    arcs, lines = decision_arcs()
    breaks = _critical_x(arcs, lines, 0.0, 0.5)
    win = window or inside_half

    def f(x):
        return _line_measure(x, predicate, win, list(comparisons), arcs, n_samples, measure)

    return gauss_kronrod(f, breaks, tol)


# ----------------------------------------------------------------------------------------
# the regions as predicates (float decisions: they are only evaluated away from the arcs)


def _fans_float(x, y):
    return {s: np.array([r[-1] for r in SCHEMES[s].rows])[_rows_float(x, y, s)]
            for s in _SCHEMES_7T}


def _fan_measure(x, y, fans, measure):
    per = np.empty(x.shape + (3,))
    for a in np.unique(fans):
        sel = fans == a
        per[sel] = fan_angles(x[sel], y[sel], a)
    return per.min(axis=1) if measure == "min" else per.mean(axis=1)


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


# ----------------------------------------------------------------------------------------
# extremes over the shaded region


def worst_ratio(measure: str = "min", over: str = "pentagon", grid: int = 400
                ) -> tuple[float, tuple[float, float]]:
    """Smallest ``QD / D`` ratio of ``measure`` over the closure of the shaded region.

    A ``grid x grid`` scan of the shaded region's bounding box, then a compass search from
    the best points, restricted to the shaded region (closed: points on its arcs count,
    evaluated with the fans of its interior: QD fan O, D fan D, checked at the grid).
    Returns ``(ratio, (x, y))``.
    """
    pred = _pred("shaded")
    xs = np.linspace(0.39, 0.5, grid)
    ys = np.linspace(1e-6, 0.45, grid)
    X, Y = (a.ravel() for a in np.meshgrid(xs, ys))
    sel = pred(X, Y)
    X, Y = X[sel], Y[sel]
    fq = _fans_float(X, Y)
    assert set(np.unique(fq["7t-qd"])) == {"O"} and set(np.unique(fq["7t-d"])) == {"D"}

    def ratio(x, y):
        q = fan_angles(x, y, "O")
        d = fan_angles(x, y, "D")
        if over == "all":
            fx = fixed_angles(x, y)
            q = np.concatenate([fx, q], axis=1)
            d = np.concatenate([fx, d], axis=1)
        if measure == "min":
            return q.min(axis=1) / d.min(axis=1)
        return q.mean(axis=1) / d.mean(axis=1)

    def closed(x, y, eps=1e-13):
        # closure of shaded: III (closed) and (x-1)^2 + y^2 >= 1/3, inside H
        ww = x * x + y * y
        return ((9 * ww - 6 * x <= eps) & (4 + 5 * ww - 12 * x <= eps)
                & ((x - 1) ** 2 + y * y >= 1 / 3 - eps) & (x <= 0.5) & (y > 0)
                & ((x - 1) ** 2 + y * y <= 1))

    r = ratio(X, Y)
    order = np.argsort(r)[:8]
    best = (float(r[order[0]]), (float(X[order[0]]), float(Y[order[0]])))
    steps = np.array([[1, 0], [-1, 0], [0, 1], [0, -1], [1, 1], [1, -1], [-1, 1], [-1, -1]],
                     dtype=float)
    for i in order:
        p = np.array([X[i], Y[i]])
        v = float(r[i])
        h = (xs[1] - xs[0]) * 2
        while h > 1e-14:
            cand = p[None, :] + h * steps
            ok = closed(cand[:, 0], cand[:, 1])
            if ok.any():
                rv = ratio(cand[ok, 0], cand[ok, 1])
                j = int(np.argmin(rv))
                if rv[j] < v:
                    p, v = cand[ok][j], float(rv[j])
                    continue
            h *= 0.5
        if v < best[0]:
            best = (v, (float(p[0]), float(p[1])))
    return best


# ----------------------------------------------------------------------------------------
# the whole computation


@dataclass
class DiagramResult:
    """Areas and fractions of the regions, with error estimates."""

    diagram_area: float
    areas: dict[str, float]
    errors: dict[str, float]
    methods: dict[str, str]
    le_min_above_qd: float
    le_min_above_qd_error: float
    worst_qd_over_d_min_angle: float
    worst_point: tuple[float, float]
    angle_measure_fractions: dict[str, float] = field(default_factory=dict)
    angle_measure_errors: dict[str, float] = field(default_factory=dict)
    extra_areas: dict[str, float] = field(default_factory=dict)
    tol: float = 1e-10
    n_samples: int = 64

    @property
    def fractions(self) -> dict[str, float]:
        return {k: v / self.diagram_area for k, v in self.areas.items()}

    @property
    def error_bound(self) -> float:
        errs = [e / self.diagram_area for e in self.errors.values()]
        errs.append(self.le_min_above_qd_error / self.diagram_area)
        return max(errs)

    def to_json(self) -> dict:
        keys = list(REGIONS)
        return {
            "diagram_area": self.diagram_area,
            "fractions": {k: self.fractions[k] for k in keys},
            "areas": {k: self.areas[k] for k in keys},
            "le_min_above_qd": self.le_min_above_qd / self.diagram_area,
            "worst_qd_over_d_min_angle": self.worst_qd_over_d_min_angle,
            "error_bound": self.error_bound,
            "errors": {k: self.errors[k] / self.diagram_area for k in keys},
            "extra": {
                "III_minus_shaded": self.fractions["III-shaded"],
                "le_min_above_qd_area": self.le_min_above_qd,
                "worst_qd_over_d_point": list(self.worst_point),
                "angle_measure_fractions": self.angle_measure_fractions,
                "angle_measure_errors": self.angle_measure_errors,
            },
            "method": {
                "measure": "uniform (Lebesgue) on the left half of the diagram "
                           "H = {0 <= x <= 1/2, y > 0, (x-1)^2 + y^2 <= 1}; fractions are "
                           "areas divided by area(H) = pi/6 - sqrt(3)/8",
                "regions": self.methods,
                "quadrature": f"adaptive Gauss-Kronrod (7,15) in x, tol {self.tol:g} on "
                              f"the area; comparison roots in y bracketed on "
                              f"{self.n_samples} uniform + 40 graded samples per piece "
                              "between decision arcs, bisected to ~2e-16",
                "error_bound": "largest error estimate of any fraction (exact arc regions: "
                               "float rounding, 1e-14; others: summed |K15 - G7|)",
                "worst_ratio": "grid scan of the shaded region then compass search on its "
                               "closure; min angles of the pentagon triangles",
                "angle_measure": "the same fractions under the uniform measure in the two "
                                 "smallest angles (angle at N, angle at M); total pi^2/12",
            },
        }


def compute(tol: float = 1e-10, n_samples: int = 64, angle_measure: bool = True
            ) -> DiagramResult:
    """Compute every region's area (see the module docstring)."""
    areas: dict[str, float] = {}
    errors: dict[str, float] = {}
    methods: dict[str, str] = {}
    for name in REGIONS + ("III-shaded",):
        r = region_area(name, tol=tol, n_samples=n_samples)
        areas[name], errors[name] = r.value, r.error
        methods[name] = ("exact circular-arc geometry" if name in ARC_REGIONS
                         else f"root finding + adaptive quadrature ({r.intervals} intervals)")
    le = region_area("le_min_above_qd", tol=tol, n_samples=n_samples)
    worst, point = worst_ratio()
    am: dict[str, float] = {}
    ae: dict[str, float] = {}
    if angle_measure:
        for name in REGIONS + ("le_min_above_qd",):
            r = region_area(name, method="quadrature", tol=tol * 10, n_samples=n_samples,
                            measure="angles")
            am[name] = r.value / HALF_ANGLE_AREA
            ae[name] = r.error / HALF_ANGLE_AREA
    return DiagramResult(HALF_AREA, areas, errors, methods, le.value, le.error, worst, point,
                         angle_measure_fractions=am, angle_measure_errors=ae, tol=tol,
                         n_samples=n_samples)
