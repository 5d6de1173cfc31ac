"""Exact geometric predicates on float64 coordinates (compiled with numba).

Every decision of qdrefine is the sign of a polynomial of degree two in coordinate
differences: the orientation ``(b-a) x (c-a)`` and linear forms
``k_uu |u|^2 + k_ww |w|^2 + k_uw u.w`` with ``u = b - a``, ``w = c - a`` and small integer
``k`` (squared-length comparisons and incircle tests, see :mod:`qdrefine.stencil`).

Each sign is computed in two stages:

1. a floating-point *filter*: the value is evaluated in float64 together with a bound
   ``FILTER * S`` on its rounding error (``S`` is the sum of the absolute values of the
   terms, ``FILTER = 16 eps``; a first-order analysis gives ``7 eps``); the sign is
   returned when ``|value| > FILTER * S``;
2. otherwise an *exact* evaluation with Shewchuk's floating-point expansions: every
   difference is split exactly into two doubles (``two_diff``), every product into two
   (``two_product``), and all terms are summed without error (``grow_expansion`` with zero
   elimination); the sign of an expansion is the sign of its largest component.

The result is the sign of the exact real value for the float64 inputs, so it never depends on
the order of the operands. Stage 2 is exact as long as no intermediate over- or underflows,
which holds when every coordinate is zero or has a magnitude in ``[1e-100, 1e100]``
(:data:`COORDINATE_RANGE`); :class:`qdrefine.Mesh` and :func:`qdrefine.partition` refuse
other coordinates with a clear error (see :func:`check_coordinates`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "COORDINATE_RANGE",
    "FILTER",
    "check_coordinates",
    "form_sign",
    "new_scratch",
    "orient_sign",
    "orient_signs",
]

#: Nonzero coordinate magnitudes for which every predicate is exact.
COORDINATE_RANGE = (1e-100, 1e100)

EPS = 2.0**-53
FILTER = 16.0 * EPS
_SPLITTER = 134217729.0  # 2**27 + 1
SCRATCH = 160  # work buffer: 8 differences, 6 coefficients, then an expansion of <= 97 terms
_EXPANSION = 16  # offset of the expansion in the work buffer


def check_coordinates(points: np.ndarray, what: str = "point") -> None:
    """Raise ``ValueError`` naming the first row of ``points (N, 2)`` that is not finite or
    has a nonzero coordinate outside :data:`COORDINATE_RANGE`."""
    p = np.asarray(points)
    bad = ~np.isfinite(p).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{what} {i} has a non-finite coordinate {tuple(p[i].tolist())}")
    lo, hi = COORDINATE_RANGE
    a = np.abs(p)
    bad = ((a > hi) | ((a < lo) & (a != 0))).any(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(
            f"{what} {i} has a coordinate {tuple(p[i].tolist())} outside the supported range: "
            f"each coordinate must be 0 or between {lo:g} and {hi:g} in magnitude "
            "(exact predicates; rescale the mesh or round tiny values to 0)"
        )


def new_scratch() -> np.ndarray:
    """A work buffer for the exact stage; one per thread."""
    return np.empty(SCRATCH, dtype=np.float64)


@njit(inline="always", cache=True)
def _two_sum(a, b):
    x = a + b
    bv = x - a
    av = x - bv
    return x, (a - av) + (b - bv)


@njit(inline="always", cache=True)
def _two_diff(a, b):
    x = a - b
    bv = a - x
    av = x + bv
    return x, (a - av) + (bv - b)


@njit(inline="always", cache=True)
def _split(a):
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


@njit(inline="always", cache=True)
def _two_product(a, b):
    x = a * b
    ah, al = _split(a)
    bh, bl = _split(b)
    err = ((x - ah * bh) - al * bh) - ah * bl
    return x, al * bl - err


@njit(inline="always", cache=True)
def _grow(e, n, b):
    """Add ``b`` to the expansion ``e[:n]`` in place; return the new length."""
    q = b
    h = 0
    for i in range(n):
        q, hh = _two_sum(q, e[i])
        if hh != 0.0:
            e[h] = hh
            h += 1
    if q != 0.0 or h == 0:
        e[h] = q
        h += 1
    return h


@njit(cache=True)
def _exact_sign(ii, jj, cc, n_terms, buf):
    """Exact sign of ``sum_k cc[k] * d[ii[k]] * d[jj[k]]``, ``k < n_terms``.

    The four exact differences ``d`` are in ``buf[:8]``, each as a two-component expansion
    ``(buf[2 i], buf[2 i + 1])``; the expansion is accumulated in ``buf[16:]``.
    """
    e = buf[_EXPANSION:]
    n = 0
    for k in range(n_terms):
        c = cc[k]
        if c == 0.0:
            continue
        for p in range(2):
            a = buf[2 * ii[k] + p]
            if a == 0.0:
                continue
            for q in range(2):
                b = buf[2 * jj[k] + q]
                if b == 0.0:
                    continue
                x, y = _two_product(a, b)
                s, t = _two_product(c, x)
                n = _grow(e, n, s)
                if t != 0.0:
                    n = _grow(e, n, t)
                if y != 0.0:
                    s, t = _two_product(c, y)
                    n = _grow(e, n, s)
                    if t != 0.0:
                        n = _grow(e, n, t)
    if n == 0:
        return 0
    top = e[n - 1]
    return 1 if top > 0.0 else (-1 if top < 0.0 else 0)


# products (ux ux), (uy uy), (wx wx), (wy wy), (ux wx), (uy wy) over d = (ux, uy, wx, wy)
_FORM_I = np.array([0, 1, 2, 3, 0, 1], dtype=np.int64)
_FORM_J = np.array([0, 1, 2, 3, 2, 3], dtype=np.int64)
# orientation ux wy - uy wx
_ORIENT_I = np.array([0, 1], dtype=np.int64)
_ORIENT_J = np.array([3, 2], dtype=np.int64)
_ORIENT_C = np.array([1.0, -1.0])


@njit(inline="always", cache=True)
def _differences(ax, ay, bx, by, cx, cy, buf):
    """Exact ``(ux, uy, wx, wy)`` as two-component expansions into ``buf[:8]``."""
    buf[0], buf[1] = _two_diff(bx, ax)
    buf[2], buf[3] = _two_diff(by, ay)
    buf[4], buf[5] = _two_diff(cx, ax)
    buf[6], buf[7] = _two_diff(cy, ay)


@njit(cache=True)
def form_sign(ax, ay, bx, by, cx, cy, kuu, kww, kuw, buf):
    """Exact sign of ``kuu |b-a|^2 + kww |c-a|^2 + kuw (b-a).(c-a)``.

    The coefficients are small integers given as floats; ``buf`` is a scratch array.
    """
    ux = bx - ax
    uy = by - ay
    wx = cx - ax
    wy = cy - ay
    p0 = ux * wx
    p1 = uy * wy
    uu = ux * ux + uy * uy
    ww = wx * wx + wy * wy
    value = kuu * uu + kww * ww + kuw * (p0 + p1)
    bound = FILTER * (abs(kuu) * uu + abs(kww) * ww + abs(kuw) * (abs(p0) + abs(p1)))
    if value > bound:
        return 1
    if value < -bound:
        return -1
    _differences(ax, ay, bx, by, cx, cy, buf)
    cc = buf[8:14]
    cc[0] = kuu
    cc[1] = kuu
    cc[2] = kww
    cc[3] = kww
    cc[4] = kuw
    cc[5] = kuw
    return _exact_sign(_FORM_I, _FORM_J, cc, 6, buf)


@njit(cache=True)
def orient_sign(ax, ay, bx, by, cx, cy, buf):
    """Exact sign of ``(b-a) x (c-a)``: +1 counter-clockwise, -1 clockwise, 0 collinear."""
    p = (bx - ax) * (cy - ay)
    q = (by - ay) * (cx - ax)
    value = p - q
    bound = FILTER * (abs(p) + abs(q))
    if value > bound:
        return 1
    if value < -bound:
        return -1
    _differences(ax, ay, bx, by, cx, cy, buf)
    return _exact_sign(_ORIENT_I, _ORIENT_J, _ORIENT_C, 2, buf)


@njit(cache=True)
def orient_signs(points, triangles):
    """Exact orientation sign ``(M,) int8`` of every triangle of ``points (N,2)``."""
    m = triangles.shape[0]
    out = np.empty(m, dtype=np.int8)
    buf = np.empty(SCRATCH)
    for t in range(m):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        out[t] = orient_sign(
            points[a, 0], points[a, 1], points[b, 0], points[b, 1], points[c, 0], points[c, 1], buf
        )
    return out
