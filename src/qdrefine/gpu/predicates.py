"""The exact predicates and the canonical labelling as CUDA device functions.

One concern, hence one module over 400 lines: it mirrors :mod:`qdrefine.predicates`
line by line (and must stay reviewable against it side by side).

Line-by-line ports of :mod:`qdrefine.predicates` and of the labelling of
:mod:`qdrefine.kernels` (same operations in the same order, same filter bound), in two
entry points:

* :func:`decide_fast`: stages 1 and 2 only (scalars, no work buffer), used by the emission
  kernel for every triangle; where the CPU would go on to stage 3 it returns row -1 and the
  triangle is listed;
* :func:`decide_exact`: all three stages, Shewchuk's expansions in a per-thread work buffer
  of :data:`qdrefine.predicates.SCRATCH` doubles, run by a second kernel on the listed
  triangles only (none on grids and on most meshes; a few percent of some levels, where
  children of curved meshes have near-ties with inexact coordinate differences).

Every sign is proved, so each triangle gets the CPU's labelling and table row, whichever
stage decided.

Stage 2 needs a fused multiply-add rounded once: ``cuda.fma`` on a device. The CUDA
simulator's ``cuda.fma`` computes ``a * b + c`` with two roundings, so under the simulator the
CPU's ``llvm.fma`` (through a small njit function) stands in for it.

**Contraction.** The CPU's code is compiled without contraction; numba-cuda's is not: NVVM
runs with its default ``-fma=1`` and fuses ``a * b + c`` into one FMA (in the filters and
:func:`suspect`: ``benchmarks/gpu_compile_check.py`` counts them per kernel), and ptxas may
still fuse any plain ``mul.f64`` whose result feeds an ``add.f64``. Hence:

* the filters (stage 1, :func:`suspect`) stay certified: a fused operation is the case
  "this product's rounding error is 0" of the error analysis behind each bound, which holds
  for every rounding error up to the unit roundoff (where the value uses a product fused
  and the bound the rounded one, the value's error only shrinks);
* the error-free transforms (stages 2 and 3) would not: ``x = a * b`` followed by
  ``two_sum(x, y)`` must add the *rounded* product. NVVM happened not to fuse them, but
  their PTX had the plain ``mul.f64`` into ``add.f64`` that ptxas may fuse, so their
  products are :func:`mul_rn` (libdevice's ``dmul_rn``, PTX ``mul.rn.f64``), which neither
  NVVM nor ptxas fuses, and their FMAs are explicit.
"""

from __future__ import annotations

from numba import cuda, njit
from numba.core import config

from ..kernels import _APEX, _STRICT
from ..predicates import (
    _EXPANSION,
    _FORM_I,
    _FORM_J,
    _LENGTH_C,
    _LENGTH_I,
    _ORIENT_C,
    _ORIENT_I,
    _ORIENT_J,
    FILTER,
    UNDECIDED,
)
from ..predicates import _fma as _llvm_fma

__all__ = ["UNDECIDED", "decide_exact", "decide_fast", "orient_filter", "orient_sign", "suspect"]

SIMULATOR = bool(config.ENABLE_CUDASIM)

if SIMULATOR:

    @njit(cache=True)
    def fma(a, b, c):
        """``a * b + c`` rounded once (the CPU's ``llvm.fma``; see the module docstring)."""
        return _llvm_fma(a, b, c)

    @cuda.jit(device=True, inline=True)
    def mul_rn(a, b):
        """``a * b`` rounded once (the simulator fuses nothing)."""
        return a * b

else:

    @cuda.jit(device=True, inline=True)
    def fma(a, b, c):
        """``a * b + c`` rounded once."""
        return cuda.fma(a, b, c)

    @cuda.jit(device=True, inline=True)
    def mul_rn(a, b):
        """``a * b`` rounded once and never fused into a later addition (``mul.rn.f64``)."""
        return cuda.libdevice.dmul_rn(a, b)


@cuda.jit(device=True, inline=True)
def _two_sum(a, b):
    x = a + b
    bv = x - a
    av = x - bv
    return x, (a - av) + (b - bv)


@cuda.jit(device=True, inline=True)
def _two_diff(a, b):
    x = a - b
    bv = a - x
    av = x + bv
    return x, (a - av) + (bv - b)


@cuda.jit(device=True, inline=True)
def _two_product(a, b):
    x = mul_rn(a, b)
    return x, fma(a, b, -x)


@cuda.jit(device=True, inline=True)
def product_sign(a, b, c, d):
    """:func:`qdrefine.predicates.product_sign`."""
    x = mul_rn(a, b)
    y = mul_rn(c, d)
    if x > y:
        return 1
    if x < y:
        return -1
    ex = fma(a, b, -x)
    ey = fma(c, d, -y)
    return 1 if ex > ey else (-1 if ex < ey else 0)


@cuda.jit(device=True, inline=True)
def _exact_diff(a, b):
    x, e = _two_diff(a, b)
    return x, e == 0.0


@cuda.jit(device=True, inline=True)
def _exact_sum(a, b):
    x, e = _two_sum(a, b)
    return x, e == 0.0


@cuda.jit(device=True)
def _length_sign_stage2(px, py, qx, qy):
    """:func:`qdrefine.predicates._length_sign_stage2`."""
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
    if a1 == -a2 and b1 == b2:
        return 0
    return product_sign(a1, b1, -a2, b2)


@cuda.jit(device=True, inline=True)
def _sterbenz(a, b):
    return a == 0.0 or b == 0.0 or ((a > 0.0) == (b > 0.0) and abs(a) <= 2.0 * abs(b)
                                    and abs(b) <= 2.0 * abs(a))


@cuda.jit(device=True)
def congruent(ax, ay, bx, by, cx, cy, dx, dy):
    """:func:`qdrefine.predicates.congruent`."""
    if not (_sterbenz(bx, ax) and _sterbenz(by, ay) and _sterbenz(dx, cx)
            and _sterbenz(dy, cy)):
        return False
    px = abs(bx - ax)
    py = abs(by - ay)
    qx = abs(dx - cx)
    qy = abs(dy - cy)
    return (px == qx and py == qy) or (px == qy and py == qx)


@cuda.jit(device=True)
def length_sign_stage2(ax, ay, bx, by, cx, cy, dx, dy):
    """Stage 2 of :func:`qdrefine.predicates.length_sign_slow`; :data:`UNDECIDED` where the
    CPU goes on to stage 3."""
    px, k1 = _exact_diff(bx, ax)
    py, k2 = _exact_diff(by, ay)
    qx, k3 = _exact_diff(dx, cx)
    qy, k4 = _exact_diff(dy, cy)
    if k1 and k2 and k3 and k4:
        return _length_sign_stage2(px, py, qx, qy)
    return UNDECIDED


@cuda.jit(device=True, inline=True)
def length_filter(px, py, qx, qy):
    """:func:`qdrefine.predicates.length_filter`."""
    lp = px * px + py * py
    lq = qx * qx + qy * qy
    value = lp - lq
    bound = FILTER * (lp + lq)
    return int(value > bound) - int(value < -bound)


@cuda.jit(device=True, inline=True)
def form_filter(ax, ay, bx, by, cx, cy, kuu, kww, kuw):
    """:func:`qdrefine.predicates.form_filter`."""
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


@cuda.jit(device=True, inline=True)
def _linear(p, q, a, b):
    s, es = _two_product(p, a)
    t, et = _two_product(q, b)
    x, ok = _exact_sum(s, t)
    return x, ok and es == 0.0 and et == 0.0


@cuda.jit(device=True)
def form_sign_stage2(ax, ay, bx, by, cx, cy, ok, p1, q1, p2, q2):
    """Stage 2 of :func:`qdrefine.predicates.form_sign_slow` (``factored_sign``);
    :data:`UNDECIDED` where the CPU goes on to stage 3."""
    if ok == 1.0:
        ux, k1 = _exact_diff(bx, ax)
        uy, k2 = _exact_diff(by, ay)
        wx, k3 = _exact_diff(cx, ax)
        wy, k4 = _exact_diff(cy, ay)
        if k1 and k2 and k3 and k4:
            l1x, j1 = _linear(p1, q1, ux, wx)
            l2x, j2 = _linear(p2, q2, ux, wx)
            l1y, j3 = _linear(p1, q1, uy, wy)
            l2y, j4 = _linear(p2, q2, uy, wy)
            if j1 and j2 and j3 and j4:
                return product_sign(l1x, l2x, -l1y, l2y)
    return UNDECIDED


# ----------------------------------------------------------------------------------------
# canonical labelling (qdrefine.kernels._canonical)


@cuda.jit(device=True, inline=True)
def _lex_less(ax, ay, bx, by):
    return ax < bx or (ax == bx and ay < by)


@cuda.jit(device=True, inline=True)
def _cmp(i, j, s01, s02, s12):
    if i == j:
        return 0
    lo = min(i, j)
    hi = max(i, j)
    s = s01 if (lo == 0 and hi == 1) else (s02 if lo == 0 else s12)
    return s if i < j else -s


@cuda.jit(device=True, inline=True)
def _pick(i, a, b, c):
    return a if i == 0 else (b if i == 1 else c)


@cuda.jit(device=True)
def _tied_labels(x0, y0, x1, y1, x2, y2, s01, s02, s12):
    """:func:`qdrefine.kernels._tied_labels`."""
    o = -1
    for i in range(3):
        if _cmp(i, (i + 1) % 3, s01, s02, s12) >= 0 and _cmp(i, (i + 2) % 3, s01, s02, s12) >= 0:
            if o < 0 or _lex_less(_pick(i, x0, x1, x2), _pick(i, y0, y1, y2),
                                  _pick(o, x0, x1, x2), _pick(o, y0, y1, y2)):
                o = i
    j = (o + 1) % 3
    k = (o + 2) % 3
    c = _cmp(k, j, s01, s02, s12)
    if c < 0 or (c == 0 and _lex_less(_pick(j, x0, x1, x2), _pick(j, y0, y1, y2),
                                      _pick(k, x0, x1, x2), _pick(k, y0, y1, y2))):
        return j, k, o
    return k, j, o


@cuda.jit(device=True)
def canonical(x0, y0, x1, y1, x2, y2):
    """:func:`qdrefine.kernels._canonical`: ``(iM, iN, iO)``, or ``iM = -1`` when a length
    comparison needs stage 3."""
    s01 = length_filter(x2 - x1, y2 - y1, x0 - x2, y0 - y2)
    s02 = length_filter(x2 - x1, y2 - y1, x1 - x0, y1 - y0)
    s12 = length_filter(x0 - x2, y0 - y2, x1 - x0, y1 - y0)
    if s01 == 0 and not congruent(x1, y1, x2, y2, x2, y2, x0, y0):
        s01 = length_sign_stage2(x1, y1, x2, y2, x2, y2, x0, y0)
    if s02 == 0 and not congruent(x1, y1, x2, y2, x0, y0, x1, y1):
        s02 = length_sign_stage2(x1, y1, x2, y2, x0, y0, x1, y1)
    if s12 == 0 and not congruent(x2, y2, x0, y0, x0, y0, x1, y1):
        s12 = length_sign_stage2(x2, y2, x0, y0, x0, y0, x1, y1)
    if s01 == UNDECIDED or s02 == UNDECIDED or s12 == UNDECIDED:
        return -1, -1, -1
    return _labels(x0, y0, x1, y1, x2, y2, s01, s02, s12)


@cuda.jit(device=True)
def _labels(x0, y0, x1, y1, x2, y2, s01, s02, s12):
    """``(iM, iN, iO)`` from the three exact signs of the length comparisons."""
    code = (s01 + 1) + 3 * (s02 + 1) + 9 * (s12 + 1)
    packed = _STRICT[code]
    if packed >= 0:
        return packed % 3, (packed // 3) % 3, packed // 9
    o = _APEX[code]
    if o >= 0:
        j = (o + 1) % 3
        k = (o + 2) % 3
        if _lex_less(_pick(j, x0, x1, x2), _pick(j, y0, y1, y2),
                     _pick(k, x0, x1, x2), _pick(k, y0, y1, y2)):
            return j, k, o
        return k, j, o
    return _tied_labels(x0, y0, x1, y1, x2, y2, s01, s02, s12)


@cuda.jit(device=True)
def decide_fast(x0, y0, x1, y1, x2, y2, forms, factors, lut):
    """:func:`qdrefine.kernels.decide` with stages 1 and 2 only: ``(iM, iN, iO, row)``, or
    ``row = -1`` when some sign needs stage 3 (the caller hands the triangle to the CPU)."""
    im, jn, ko = canonical(x0, y0, x1, y1, x2, y2)
    if im < 0:
        return -1, -1, -1, -1
    mx, my = _pick(im, x0, x1, x2), _pick(im, y0, y1, y2)
    nx, ny = _pick(jn, x0, x1, x2), _pick(jn, y0, y1, y2)
    ox, oy = _pick(ko, x0, x1, x2), _pick(ko, y0, y1, y2)
    code = 0
    power = 1
    for f in range(forms.shape[0]):
        s = form_filter(mx, my, nx, ny, ox, oy, forms[f, 0], forms[f, 1], forms[f, 2])
        if s == 0:
            s = form_sign_stage2(mx, my, nx, ny, ox, oy, factors[f, 0], factors[f, 1],
                                 factors[f, 2], factors[f, 3], factors[f, 4])
            if s == UNDECIDED:
                return im, jn, ko, -1
        code += (s + 1) * power
        power *= 3
    return im, jn, ko, lut[code]


@cuda.jit(device=True)
def suspect(ax, ay, bx, by, cx, cy, lattice):
    """:func:`qdrefine.kernels._suspect` (a certified bound: it only selects the triangles
    whose children the CPU then checks exactly)."""
    eps = 2.220446049250313e-16
    big = max(max(abs(ax), abs(ay)), max(max(abs(bx), abs(by)), max(abs(cx), abs(cy))))
    ux, uy, wx, wy = bx - ax, by - ay, cx - ax, cy - ay
    vx, vy = cx - bx, cy - by
    area = abs(ux * wy - uy * wx)
    longest = max(abs(ux) + abs(uy), max(abs(wx) + abs(wy), abs(vx) + abs(vy)))
    d = 4.0 * eps * big
    change = 3.0 * 1.4142135623730951 * longest * d + 6.0 * d * d
    return area <= 8.0 * lattice * lattice * change + 4.0 * longest * d


# ----------------------------------------------------------------------------------------
# stage 3 (qdrefine.predicates._exact_sign and its callers) and the full decision


@cuda.jit(device=True)
def _exact_sign(ii, jj, cc, n_terms, buf):
    """:func:`qdrefine.predicates._exact_sign`."""
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


@cuda.jit(device=True)
def _length_sign_exact(ax, ay, bx, by, cx, cy, dx, dy, buf):
    buf[0], buf[1] = _two_diff(bx, ax)
    buf[2], buf[3] = _two_diff(by, ay)
    buf[4], buf[5] = _two_diff(dx, cx)
    buf[6], buf[7] = _two_diff(dy, cy)
    return _exact_sign(_LENGTH_I, _LENGTH_I, _LENGTH_C, 4, buf)


@cuda.jit(device=True)
def _length_sign(ax, ay, bx, by, cx, cy, dx, dy, buf):
    """Stages 2 and 3 of a squared-length comparison
    (:func:`qdrefine.predicates.length_sign_slow`)."""
    s = length_sign_stage2(ax, ay, bx, by, cx, cy, dx, dy)
    if s != UNDECIDED:
        return s
    return _length_sign_exact(ax, ay, bx, by, cx, cy, dx, dy, buf)


@cuda.jit(device=True)
def _form_sign_exact(ax, ay, bx, by, cx, cy, kuu, kww, kuw, buf, cc):
    """Stage 3 of :func:`qdrefine.predicates.form_sign` (``cc``: 6 doubles of scratch)."""
    buf[0], buf[1] = _two_diff(bx, ax)
    buf[2], buf[3] = _two_diff(by, ay)
    buf[4], buf[5] = _two_diff(cx, ax)
    buf[6], buf[7] = _two_diff(cy, ay)
    cc[0] = kuu
    cc[1] = kuu
    cc[2] = kww
    cc[3] = kww
    cc[4] = kuw
    cc[5] = kuw
    return _exact_sign(_FORM_I, _FORM_J, cc, 6, buf)


@cuda.jit(device=True)
def decide_exact(x0, y0, x1, y1, x2, y2, forms, factors, lut, buf, cc):
    """:func:`qdrefine.kernels.decide`, all three stages: ``(iM, iN, iO, row)``."""
    s01 = length_filter(x2 - x1, y2 - y1, x0 - x2, y0 - y2)
    s02 = length_filter(x2 - x1, y2 - y1, x1 - x0, y1 - y0)
    s12 = length_filter(x0 - x2, y0 - y2, x1 - x0, y1 - y0)
    if s01 == 0 and not congruent(x1, y1, x2, y2, x2, y2, x0, y0):
        s01 = _length_sign(x1, y1, x2, y2, x2, y2, x0, y0, buf)
    if s02 == 0 and not congruent(x1, y1, x2, y2, x0, y0, x1, y1):
        s02 = _length_sign(x1, y1, x2, y2, x0, y0, x1, y1, buf)
    if s12 == 0 and not congruent(x2, y2, x0, y0, x0, y0, x1, y1):
        s12 = _length_sign(x2, y2, x0, y0, x0, y0, x1, y1, buf)
    im, jn, ko = _labels(x0, y0, x1, y1, x2, y2, s01, s02, s12)
    mx, my = _pick(im, x0, x1, x2), _pick(im, y0, y1, y2)
    nx, ny = _pick(jn, x0, x1, x2), _pick(jn, y0, y1, y2)
    ox, oy = _pick(ko, x0, x1, x2), _pick(ko, y0, y1, y2)
    code = 0
    power = 1
    for f in range(forms.shape[0]):
        s = form_filter(mx, my, nx, ny, ox, oy, forms[f, 0], forms[f, 1], forms[f, 2])
        if s == 0:
            s = form_sign_stage2(mx, my, nx, ny, ox, oy, factors[f, 0], factors[f, 1],
                                 factors[f, 2], factors[f, 3], factors[f, 4])
            if s == UNDECIDED:
                s = _form_sign_exact(mx, my, nx, ny, ox, oy, forms[f, 0], forms[f, 1],
                                     forms[f, 2], buf, cc)
        code += (s + 1) * power
        power *= 3
    return im, jn, ko, lut[code]


@cuda.jit(device=True, inline=True)
def orient_filter(ax, ay, bx, by, cx, cy):
    """Stage 1 of :func:`qdrefine.predicates.orient_sign`: +1 or -1 when proved, else 0."""
    p = (bx - ax) * (cy - ay)
    q = (by - ay) * (cx - ax)
    bound = FILTER * (abs(p) + abs(q))
    return int(p - q > bound) - int(p - q < -bound)


@cuda.jit(device=True)
def orient_sign(ax, ay, bx, by, cx, cy, buf):
    """:func:`qdrefine.predicates.orient_sign`: the exact sign of ``(b-a) x (c-a)``."""
    s = orient_filter(ax, ay, bx, by, cx, cy)
    if s != 0:
        return s
    buf[0], buf[1] = _two_diff(bx, ax)
    buf[2], buf[3] = _two_diff(by, ay)
    buf[4], buf[5] = _two_diff(cx, ax)
    buf[6], buf[7] = _two_diff(cy, ay)
    return _exact_sign(_ORIENT_I, _ORIENT_J, _ORIENT_C, 2, buf)
