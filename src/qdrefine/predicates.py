"""Exact geometric predicates on float64 coordinates (compiled with numba).

One concern, hence one module over 400 lines: the three-stage signs below share their
error bounds, their exactness conditions and the expansion arithmetic of stage 3, and
are proved together.

Every decision of qdrefine is the sign of a polynomial of degree two in coordinate
differences: the orientation ``(b-a) x (c-a)``, the comparison of two squared lengths
``|b-a|^2 - |d-c|^2`` and linear forms ``k_uu |u|^2 + k_ww |w|^2 + k_uw u.w`` with
``u = b - a``, ``w = c - a`` and small integer ``k`` (squared-length comparisons and incircle
tests, see :mod:`qdrefine.stencil`).

Each sign is computed in up to three stages; each stage returns only a sign it has proved:

1. a floating-point *filter*: the value is evaluated in float64 together with a bound
   ``FILTER * S`` on its rounding error (``S`` is the sum of the absolute values of the
   terms, ``FILTER = 16 eps``; a first-order analysis gives ``7 eps``); the sign is
   returned when ``|value| > FILTER * S``;
2. an *error-free product comparison* for near-ties (every right isosceles triangle of a
   structured grid is an exact tie ``|OM| = |ON|`` that stage 1 cannot decide). When the
   coordinate differences are exact (``two_diff`` error 0, the common case: Sterbenz's
   lemma makes ``b - a`` exact whenever ``a/2 <= b <= 2a``), a squared-length difference
   is a sum of two products, ``|p|^2 - |q|^2 = A1 B1 + A2 B2`` with ``A1 = |px| - |qx|``,
   ``B1 = |px| + |qx| >= 0`` (and the same in y; the sign is immediate when ``A1`` and
   ``A2`` agree or one is 0), and a factorable form is ``sum_c L1(u_c, w_c) L2(u_c, w_c)``
   with integer linear forms ``L1, L2``. If these four factors are exact in float64 too
   (``two_sum``/``fma`` errors 0), the sign of ``a b - c d`` is decided by
   :func:`product_sign`: rounding to nearest is monotone, so
   ``fl(ab) > fl(cd)`` implies ``ab > cd`` (and ``<`` likewise); if ``fl(ab) = fl(cd) = x``
   then ``ab - cd = fma(a, b, -x) - fma(c, d, -x)`` exactly, because the error of a product
   is a double (see below) and ``fma`` rounds once. About 60 flops instead of hundreds;
3. otherwise an *exact* evaluation with Shewchuk's floating-point expansions: every
   difference is split exactly into two doubles (``two_diff``), every product into two
   (``two_product`` with ``fma``), and all terms are summed without error
   (``grow_expansion`` with zero elimination); the sign of an expansion is the sign of its
   largest component.

The result is the sign of the exact real value for the float64 inputs, so it never depends on
the order of the operands or on which stage decided. Stages 2 and 3 are exact as long as no
intermediate over- or underflows. That holds when every coordinate is zero or has a
magnitude in ``[1e-100, 1e100]`` (:data:`COORDINATE_RANGE`): such a coordinate is a multiple
of ``2^-385`` (its exponent is at least ``-333``), so are all exact sums and differences of
coordinates, every nonzero product of two of them is at least ``2^-770`` in magnitude, whose
rounding error is representable (``e_a + e_b >= -770 >= emin + p - 1 = -970``), and every
magnitude stays below ``1e205``. :class:`qdrefine.Mesh` and :func:`qdrefine.partition`
refuse other coordinates with a clear error (see :func:`check_coordinates`).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange, types
from numba.extending import intrinsic

from .jit import CHUNK, threads_for

__all__ = [
    "COORDINATE_RANGE",
    "below_range",
    "FILTER",
    "check_coordinates",
    "factor_forms",
    "factored_sign",
    "form_sign",
    "length_sign",
    "new_scratch",
    "orient_sign",
    "orient_signs",
    "orient_signs_of_rows",
    "product_sign",
]

#: Nonzero coordinate magnitudes for which every predicate is exact.
COORDINATE_RANGE = (1e-100, 1e100)

EPS = 2.0**-53
FILTER = 16.0 * EPS
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


def below_range(index: int | None, point, smallest: float | None) -> ValueError:
    """The error of a refinement whose new point ``index`` (None: not numbered yet) at
    ``point`` has a nonzero coordinate below :data:`COORDINATE_RANGE` (the input's
    smallest nonzero coordinate magnitude ``smallest``, where known, was close to the
    range's lower end)."""
    lo, hi = COORDINATE_RANGE
    which = "a new point" if index is None else f"new point {index}"
    also = "" if smallest is None else \
        f"; the mesh's smallest nonzero coordinate is {smallest:g}"
    return ValueError(f"refining this mesh makes {which} at "
                      f"{tuple(float(x) for x in point)}, below the supported range (nonzero "
                      f"coordinates of magnitude {lo:g} to {hi:g}, where the predicates are "
                      f"exact){also}: scale the mesh up")


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


@intrinsic
def _fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (LLVM ``llvm.fma.f64``; a libm call without hardware FMA)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


@njit(inline="always", cache=True)
def _two_product(a, b):
    """``(x, y)`` with ``x = fl(a b)`` and ``a b = x + y`` exactly."""
    x = a * b
    return x, _fma(a, b, -x)


@njit(cache=True)
def _exact_sign(ii, jj, cc, n_terms, buf):
    """Exact sign of ``sum_k cc[k] * d[ii[k]] * d[jj[k]]``, ``k < n_terms``.

    The four exact differences ``d`` are in ``buf[:8]``, each as a two-component expansion
    ``(buf[2 i], buf[2 i + 1])``; the expansion is accumulated in ``buf[16:]`` by Shewchuk's
    ``grow_expansion`` with zero elimination (written out here: a helper taking the array
    would pay two atomic reference-count updates per call).
    """
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
                s0, t0 = _two_product(c, x)
                s1, t1 = _two_product(c, y)
                for v in range(4):
                    g = s0 if v == 0 else (t0 if v == 1 else (s1 if v == 2 else t1))
                    if g == 0.0:
                        continue
                    h = 0
                    for i in range(n):
                        g, hh = _two_sum(g, buf[_EXPANSION + i])
                        if hh != 0.0:
                            buf[_EXPANSION + h] = hh
                            h += 1
                    if g != 0.0 or h == 0:
                        buf[_EXPANSION + h] = g
                        h += 1
                    n = h
    if n == 0:
        return 0
    top = buf[_EXPANSION + n - 1]
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


@njit(inline="always", cache=True)
def form_filter(ax, ay, bx, by, cx, cy, kuu, kww, kuw):
    """Stage 1 of :func:`form_sign`: its sign from float64 arithmetic with an error bound,
    or 0 when the filter cannot decide."""
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
    return int(value > bound) - int(value < -bound)


@njit(cache=True)
def form_sign(ax, ay, bx, by, cx, cy, kuu, kww, kuw, buf):
    """Exact sign of ``kuu |b-a|^2 + kww |c-a|^2 + kuw (b-a).(c-a)``.

    The coefficients are small integers given as floats; ``buf`` is a scratch array.
    """
    s = form_filter(ax, ay, bx, by, cx, cy, kuu, kww, kuw)
    if s != 0:
        return s
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


def orient_signs_of_rows(points, triangles, rows):
    """:func:`orient_signs` of the rows ``rows (R,)`` of ``triangles``, ``(R,) int8``, in
    parallel over blocks of rows (no copy of the rows)."""
    out = np.empty(rows.shape[0], dtype=np.int8)
    with threads_for(rows.shape[0]):
        _orient_rows(points, triangles, rows, CHUNK, out)
    return out


@njit(parallel=True, cache=True)
def _orient_rows(points, triangles, rows, chunk, out):
    n = rows.shape[0]
    for c in prange((n + chunk - 1) // chunk):
        buf = np.empty(SCRATCH)
        for i in range(c * chunk, min(n, (c + 1) * chunk)):
            t = rows[i]
            a, b, d = triangles[t, 0], triangles[t, 1], triangles[t, 2]
            out[i] = orient_sign(points[a, 0], points[a, 1], points[b, 0], points[b, 1],
                                 points[d, 0], points[d, 1], buf)


@njit(cache=True)
def orient_signs(points, triangles):
    """Exact orientation sign ``(M,) int8`` of every triangle of ``points (N,2)``."""
    m = triangles.shape[0]
    out = np.empty(m, dtype=np.int8)
    buf = np.empty(SCRATCH)
    for t in range(m):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        ax, ay = points[a, 0], points[a, 1]
        bx, by = points[b, 0], points[b, 1]
        cx, cy = points[c, 0], points[c, 1]
        p = (bx - ax) * (cy - ay)  # the filter of orient_sign, inline (no call per triangle)
        q = (by - ay) * (cx - ax)
        bound = FILTER * (abs(p) + abs(q))
        s = int(p - q > bound) - int(p - q < -bound)
        out[t] = s if s != 0 else orient_sign(ax, ay, bx, by, cx, cy, buf)
    return out


# ----------------------------------------------------------------------------------------
# stage 2: error-free product comparisons (see the module docstring for the proof)

UNDECIDED = 2  #: returned by stage-2 functions that cannot certify a sign


@njit(inline="always", cache=True)
def product_sign(a, b, c, d):
    """Exact sign of ``a b - c d`` for doubles whose product errors are representable.

    Rounding is monotone, so ``fl(ab) > fl(cd)`` proves ``ab > cd``; on equal roundings
    ``x`` the difference is ``fma(a, b, -x) - fma(c, d, -x)``, both terms exact.
    """
    x = a * b
    y = c * d
    if x > y:
        return 1
    if x < y:
        return -1
    ex = _fma(a, b, -x)
    ey = _fma(c, d, -y)
    return 1 if ex > ey else (-1 if ex < ey else 0)


@njit(inline="always", cache=True)
def _exact_diff(a, b):
    """``(a - b, True)`` when the float difference is exact, ``(a - b, False)`` otherwise."""
    x, e = _two_diff(a, b)
    return x, e == 0.0


@njit(inline="always", cache=True)
def _exact_sum(a, b):
    x, e = _two_sum(a, b)
    return x, e == 0.0


@njit(cache=True)
def _length_sign_stage2(px, py, qx, qy):
    """Sign of ``|p|^2 - |q|^2`` for exact doubles ``p, q``, or :data:`UNDECIDED`.

    ``|p|^2 - |q|^2 = A1 B1 + A2 B2`` with ``A1 = |px| - |qx|``, ``B1 = |px| + |qx| >= 0``
    (``B1 = 0`` only if ``A1 = 0``) and the same in y. With ``A1, A2`` exact the sign is
    theirs when they agree or one is 0; otherwise ``B1, B2`` must be exact too and
    :func:`product_sign` compares ``A1 B1`` with ``(-A2) B2``.
    """
    ax = abs(px)
    bx = abs(qx)
    ay = abs(py)
    by = abs(qy)
    a1, k1 = _exact_diff(ax, bx)
    a2, k2 = _exact_diff(ay, by)
    if not (k1 and k2):
        return UNDECIDED
    s1 = int(a1 > 0.0) - int(a1 < 0.0)
    s2 = int(a2 > 0.0) - int(a2 < 0.0)
    if s1 == s2 or s2 == 0:
        return s1
    if s1 == 0:
        return s2
    b1, k3 = _exact_sum(ax, bx)
    b2, k4 = _exact_sum(ay, by)
    if not (k3 and k4):
        return UNDECIDED
    if a1 == -a2 and b1 == b2:  # congruent legs, {|px|, |py|} = {|qx|, |qy|}: a grid's ties
        return 0
    return product_sign(a1, b1, -a2, b2)


_LENGTH_I = np.array([0, 1, 2, 3], dtype=np.int64)
_LENGTH_C = np.array([1.0, 1.0, -1.0, -1.0])


@njit(inline="always", cache=True)
def _sterbenz(a, b):
    """``a - b`` is exact in float64: by Sterbenz's lemma when ``b / 2 <= a <= 2 b`` (same
    sign), or trivially when either is 0."""
    return a == 0.0 or b == 0.0 or ((a > 0.0) == (b > 0.0) and abs(a) <= 2.0 * abs(b)
                                    and abs(b) <= 2.0 * abs(a))


@njit(inline="always", cache=True)
def congruent(ax, ay, bx, by, cx, cy, dx, dy):
    """``True`` proves ``|b - a| = |d - c|``: the coordinate differences are exact and equal
    up to order and sign (the ties of every structured grid, decided without a call to
    :func:`length_sign_slow`). ``False`` proves nothing."""
    if not (_sterbenz(bx, ax) and _sterbenz(by, ay) and _sterbenz(dx, cx)
            and _sterbenz(dy, cy)):
        return False
    px = abs(bx - ax)
    py = abs(by - ay)
    qx = abs(dx - cx)
    qy = abs(dy - cy)
    return (px == qx and py == qy) or (px == qy and py == qx)


@njit(cache=True)
def length_sign_slow(ax, ay, bx, by, cx, cy, dx, dy):
    """Stages 2 and 3 of :func:`length_sign` (for when the filter cannot decide).

    Scalars only: the rare stage 3 allocates its own work buffer.
    """
    px, k1 = _exact_diff(bx, ax)
    py, k2 = _exact_diff(by, ay)
    qx, k3 = _exact_diff(dx, cx)
    qy, k4 = _exact_diff(dy, cy)
    if k1 and k2 and k3 and k4:
        s = _length_sign_stage2(px, py, qx, qy)
        if s != UNDECIDED:
            return s
    return _length_sign_exact(ax, ay, bx, by, cx, cy, dx, dy, np.empty(SCRATCH))


@njit(cache=True)
def _length_sign_exact(ax, ay, bx, by, cx, cy, dx, dy, buf):
    buf[0], buf[1] = _two_diff(bx, ax)
    buf[2], buf[3] = _two_diff(by, ay)
    buf[4], buf[5] = _two_diff(dx, cx)
    buf[6], buf[7] = _two_diff(dy, cy)
    return _exact_sign(_LENGTH_I, _LENGTH_I, _LENGTH_C, 4, buf)


@njit(inline="always", cache=True)
def length_filter(px, py, qx, qy):
    """Stage 1 of :func:`length_sign` on float differences ``p, q``: ``sign(|p|^2 - |q|^2)``,
    or 0 when the filter cannot decide."""
    lp = px * px + py * py
    lq = qx * qx + qy * qy
    value = lp - lq
    bound = FILTER * (lp + lq)
    return int(value > bound) - int(value < -bound)


@njit(cache=True)
def length_sign(ax, ay, bx, by, cx, cy, dx, dy):
    """Exact sign of ``|b - a|^2 - |d - c|^2``."""
    s = length_filter(bx - ax, by - ay, dx - cx, dy - cy)
    if s != 0:
        return s
    return length_sign_slow(ax, ay, bx, by, cx, cy, dx, dy)


@njit(cache=True)
def _factor(kuu, kww, kuw):
    """``(ok, p1, q1, p2, q2)`` with ``kuu a^2 + kuw ab + kww b^2 = (p1 a + q1 b)(p2 a + q2 b)``."""
    if kuu == 0:
        return 1, 0, 1, kuw, kww
    if kww == 0:
        return 1, 1, 0, kuu, kuw
    for p1 in range(1, abs(kuu) + 1):  # Gauss: a rational factorization has an integer one
        if kuu % p1 != 0:
            continue
        for q1 in range(-abs(kww), abs(kww) + 1):
            if q1 != 0 and kww % q1 == 0 and p1 * (kww // q1) + (kuu // p1) * q1 == kuw:
                return 1, p1, q1, kuu // p1, kww // q1
    return 0, 0, 0, 0, 0


@njit(cache=True)
def factor_forms(forms):
    """Integer factorizations of binary quadratic forms, for :func:`factored_sign`.

    Row ``f`` of ``forms (F, 3)`` holds ``(k_uu, k_ww, k_uw)`` of
    ``q(a, b) = k_uu a^2 + k_uw a b + k_ww b^2``. Returns ``(F, 5) float64`` rows
    ``(1, p1, q1, p2, q2)`` with ``q(a, b) = (p1 a + q1 b)(p2 a + q2 b)``, or zeros where
    ``q`` does not factor over the integers (then only stages 1 and 3 decide). Every
    difference of two squared lengths factors (a difference of two squares).
    """
    out = np.zeros((forms.shape[0], 5))
    for f in range(forms.shape[0]):
        r = _factor(int(forms[f, 0]), int(forms[f, 1]), int(forms[f, 2]))
        for i in range(5):
            out[f, i] = r[i]
    return out


@njit(inline="always", cache=True)
def _linear(p, q, a, b):
    """``(p a + q b, exact)`` for small integers ``p, q`` given as floats."""
    s, es = _two_product(p, a)
    t, et = _two_product(q, b)
    x, ok = _exact_sum(s, t)
    return x, ok and es == 0.0 and et == 0.0


@njit(cache=True)
def factored_sign(ux, uy, wx, wy, p1, q1, p2, q2):
    """Sign of ``sum_c (p1 u_c + q1 w_c)(p2 u_c + q2 w_c)`` for exact doubles ``u, w``, or
    :data:`UNDECIDED` when a linear factor is not exact in float64."""
    l1x, k1 = _linear(p1, q1, ux, wx)
    l2x, k2 = _linear(p2, q2, ux, wx)
    l1y, k3 = _linear(p1, q1, uy, wy)
    l2y, k4 = _linear(p2, q2, uy, wy)
    if not (k1 and k2 and k3 and k4):
        return UNDECIDED
    return product_sign(l1x, l2x, -l1y, l2y)


@njit(cache=True)
def form_sign_slow(ax, ay, bx, by, cx, cy, kuu, kww, kuw, ok, p1, q1, p2, q2, buf):
    """Stages 2 and 3 of :func:`form_sign`; ``(ok, p1, q1, p2, q2)`` is the form's row of
    :func:`factor_forms` (stage 2 runs when ``ok == 1``)."""
    if ok == 1.0:
        ux, k1 = _exact_diff(bx, ax)
        uy, k2 = _exact_diff(by, ay)
        wx, k3 = _exact_diff(cx, ax)
        wy, k4 = _exact_diff(cy, ay)
        if k1 and k2 and k3 and k4:
            s = factored_sign(ux, uy, wx, wy, p1, q1, p2, q2)
            if s != UNDECIDED:
                return s
    return form_sign(ax, ay, bx, by, cx, cy, kuu, kww, kuw, buf)
