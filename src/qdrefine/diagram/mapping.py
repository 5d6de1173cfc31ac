"""Diagram coordinates of triangles and the schemes' decisions and angles at diagram points.

See :mod:`qdrefine.diagram` for the diagram ``H`` and its regions.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

from ..kernels import canonical, decide
from ..predicates import SCRATCH, factor_forms
from ..quality import corner_angles
from ..schemes import SCHEMES
from ..stencil import FIXED_7T, SEVEN, fan

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


def _names_index(names):
    return np.array([[SEVEN.index(c) for c in t] for t in names])


_FIXED_IDX = _names_index(FIXED_7T)
_FAN_IDX = {a: _names_index(fan(a)) for a in FANS}


def fan_angles(x: ArrayLike, y: ArrayLike, apex: str) -> NDArray[np.float64]:
    """Smallest angle (degrees) of each of the three triangles of a pentagon fan, ``(K, 3)``."""
    p = stencil_points(x, y)
    return corner_angles(p[:, _FAN_IDX[apex]]).min(axis=-1)


def fixed_angles(x: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
    """Smallest angle of each of the four fixed corner triangles, ``(K, 4)``."""
    p = stencil_points(x, y)
    return corner_angles(p[:, _FIXED_IDX]).min(axis=-1)


MEASURES = ("min", "mean")
OVER = ("pentagon", "all")


def partition_measure(x: ArrayLike, y: ArrayLike, scheme: str, measure: str = "min",
                      over: str = "pentagon", exact: bool = True) -> NDArray[np.float64]:
    """Min angle or mean min angle (degrees) of a scheme's partition at diagram points.

    Parameters
    ----------
    x, y : (K,) float
        Diagram points, in the half ``H`` (:func:`inside_half`; :func:`to_diagram` maps a
        triangle there): the fan is decided on the canonical triangle, so elsewhere the
        stencil measured would not be the one decided on, and such points are refused.
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
    outside = ~inside_half(np.atleast_1d(x), np.atleast_1d(y))
    if outside.any():  # measured wrong before, without a word (review)
        i = int(np.flatnonzero(outside)[0])
        raise ValueError(f"point {i} ({np.atleast_1d(x)[i]!r}, {np.atleast_1d(y)[i]!r}) is "
                         "outside the diagram's half H (0 <= x <= 1/2, y > 0, "
                         "(x-1)^2 + y^2 <= 1); map a triangle there with to_diagram")
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



def _fans_float(x, y):
    return {s: np.array([r[-1] for r in SCHEMES[s].rows])[_rows_float(x, y, s)]
            for s in _SCHEMES_7T}


def _fan_measure(x, y, fans, measure):
    per = np.empty(x.shape + (3,))
    for a in np.unique(fans):
        sel = fans == a
        per[sel] = fan_angles(x[sel], y[sel], a)
    return per.min(axis=1) if measure == "min" else per.mean(axis=1)

