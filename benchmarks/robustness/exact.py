"""Exact signs and areas on float64 input, independent of qdrefine's predicates.

Every float64 is ``m 2^e`` with an integer ``m``; scaling a row of floats by ``2^-e_min`` turns
it into Python integers, on which orientation, incircle and areas are exact
(:func:`as_integers`, numpy object arrays). The filtered signs :func:`orient_sign` and
:func:`incircle_sign` evaluate in float64 first and accept the sign when the value exceeds
``FILTER * permanent``; ``FILTER`` is 30 to 90 times Shewchuk's proven first-stage bounds
(``3.3e-16`` and ``1.1e-15``), and the rest goes to the integer path.

:func:`qd_reference` is the 7T-QD decision (documented labelling, Definition 1, tie rules)
on exact integers; :func:`fraction_partition` and :func:`fraction_delaunay_ok` redo the
same with :class:`fractions.Fraction` for the subsample check.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from numpy.typing import NDArray

from .local import qd_triangles

FILTER_ORIENT = 1e-14
FILTER_INCIRCLE = 1e-13
TINY = 1e-250  # below this permanent the filter is not trusted (subnormal products)


def as_integers(x: NDArray[np.float64]) -> tuple[NDArray[np.object_], NDArray[np.int64]]:
    """Exact integers ``(K, ...)`` (object) and exponents ``(K,)`` with
    ``x[k] = ints[k] * 2**exp[k]`` for every row ``k`` of ``x (K, ...)``."""
    x = np.asarray(x, dtype=np.float64)
    flat = x.reshape(x.shape[0], -1)
    if not np.isfinite(flat).all():
        raise ValueError("as_integers needs finite values")
    mant, ex = np.frexp(flat)
    mant = (mant * 2.0**53).astype(np.int64)
    ex = ex.astype(np.int64) - 53
    nonzero = mant != 0
    low = np.where(nonzero, ex, np.iinfo(np.int64).max).min(axis=1)
    low = np.where(nonzero.any(axis=1), low, 0)
    shift = np.where(nonzero, ex - low[:, None], 0)
    ints = mant.astype(object) << shift.astype(object)
    return ints.reshape(x.shape), low


def sign(v: NDArray) -> NDArray[np.int8]:
    """Sign ``{-1, 0, 1}`` of an object (or numeric) array."""
    return (v > 0).astype(np.int8) - (v < 0).astype(np.int8)


def cross(ax, ay, bx, by, cx, cy):
    """``(b - a) x (c - a)`` (exact on integer object arrays)."""
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def incircle(ax, ay, bx, by, cx, cy, dx, dy):
    """Shewchuk's incircle determinant: > 0 iff ``d`` is inside the circle through ``a, b,
    c`` when they are counter-clockwise (exact on integer object arrays)."""
    adx, ady, bdx, bdy, cdx, cdy = ax - dx, ay - dy, bx - dx, by - dy, cx - dx, cy - dy
    alift = adx * adx + ady * ady
    blift = bdx * bdx + bdy * bdy
    clift = cdx * cdx + cdy * cdy
    return (alift * (bdx * cdy - cdx * bdy) + blift * (cdx * ady - adx * cdy)
            + clift * (adx * bdy - bdx * ady))


def _exact_rows(fn, pts: list[NDArray]) -> NDArray[np.int8]:
    """``sign(fn(...))`` on the exact integers of the points ``pts`` (each ``(n, 2)``)."""
    if len(pts[0]) == 0:
        return np.zeros(0, dtype=np.int8)
    ints, _ = as_integers(np.stack(pts, axis=1))
    args = [ints[:, i, j] for i in range(len(pts)) for j in range(2)]
    return sign(fn(*args))


def orient_sign(a: NDArray, b: NDArray, c: NDArray) -> NDArray[np.int8]:
    """Exact sign of ``(b - a) x (c - a)`` for points ``(..., 2)``: +1 counter-clockwise."""
    a, b, c = np.broadcast_arrays(*(np.asarray(p, dtype=np.float64) for p in (a, b, c)))
    shape = a.shape[:-1]
    a, b, c = (p.reshape(-1, 2) for p in (a, b, c))
    with np.errstate(all="ignore"):
        p = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1])
        q = (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
        det = p - q
        perm = np.abs(p) + np.abs(q)
        sure = np.isfinite(perm) & (perm > TINY) & (np.abs(det) > FILTER_ORIENT * perm)
    out = np.where(sure, np.sign(det), 0).astype(np.int8)
    todo = ~sure
    out[todo] = _exact_rows(cross, [a[todo], b[todo], c[todo]])
    return out.reshape(shape)


def incircle_sign(a: NDArray, b: NDArray, c: NDArray, d: NDArray) -> NDArray[np.int8]:
    """Exact sign of :func:`incircle` for points ``(..., 2)``."""
    arrays = np.broadcast_arrays(*(np.asarray(p, dtype=np.float64) for p in (a, b, c, d)))
    shape = arrays[0].shape[:-1]
    a, b, c, d = (p.reshape(-1, 2) for p in arrays)
    with np.errstate(all="ignore"):
        adx, ady = a[:, 0] - d[:, 0], a[:, 1] - d[:, 1]
        bdx, bdy = b[:, 0] - d[:, 0], b[:, 1] - d[:, 1]
        cdx, cdy = c[:, 0] - d[:, 0], c[:, 1] - d[:, 1]
        bc, cb = bdx * cdy, cdx * bdy
        ca, ac = cdx * ady, adx * cdy
        ab, ba = adx * bdy, bdx * ady
        alift, blift, clift = adx**2 + ady**2, bdx**2 + bdy**2, cdx**2 + cdy**2
        det = alift * (bc - cb) + blift * (ca - ac) + clift * (ab - ba)
        perm = ((np.abs(bc) + np.abs(cb)) * alift + (np.abs(ca) + np.abs(ac)) * blift
                + (np.abs(ab) + np.abs(ba)) * clift)
        sure = np.isfinite(perm) & (perm > TINY) & (np.abs(det) > FILTER_INCIRCLE * perm)
    out = np.where(sure, np.sign(det), 0).astype(np.int8)
    todo = ~sure
    out[todo] = _exact_rows(incircle, [a[todo], b[todo], c[todo], d[todo]])
    return out.reshape(shape)


def polygon_area2(points: NDArray, cycles: NDArray) -> tuple[NDArray, NDArray[np.int64]]:
    """Exact twice-areas of polygons: ``points (K, P, 2)``, ``cycles (K, L)`` local indices.

    Returns object integers ``(K,)`` and exponents ``(K,)``: area2 = ints * 2**(2 exp).
    """
    ints, ex = as_integers(points)
    rows = np.arange(len(points))[:, None]
    x = ints[rows, cycles, 0]
    y = ints[rows, cycles, 1]
    xn, yn = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    return (x * yn - xn * y).sum(axis=1), ex


def triangles_area2(points: NDArray, tris: NDArray) -> tuple[NDArray, NDArray[np.int64]]:
    """Exact sums of the twice-areas of ``tris (K, T, 3)`` over ``points (K, P, 2)``,
    as :func:`polygon_area2` (same exponents, so the two compare directly)."""
    ints, ex = as_integers(points)
    rows = np.arange(len(points))[:, None]
    a, b, c = (ints[rows, tris[..., i]] for i in range(3))
    return cross(a[..., 0], a[..., 1], b[..., 0], b[..., 1], c[..., 0], c[..., 1]).sum(axis=1), ex


# ----------------------------------------------------------------------------------------
# the 7T-QD decision on exact integers


def labelling(v: NDArray, e: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray[np.bool_]]:
    """Documented canonical labelling from squared edge lengths ``e (K, 3)`` (``e[:, i]``
    opposite vertex ``i``) of triangles ``v (K, 3, 2)``: ``MN`` longest (tie: opposite vertex
    lexicographically smaller), ``M`` nearer ``O`` (tie: lexicographically smaller).

    Works on exact integers or floats alike. Returns ``m, n, o (K,)`` and whether a tie rule
    was used ``(K,)``.
    """
    k = len(v)
    is_max = np.stack([(e[:, i] >= e[:, (i + 1) % 3]) & (e[:, i] >= e[:, (i + 2) % 3])
                       for i in range(3)], axis=1)
    o = np.full(k, -1)
    for i in range(3):
        better = is_max[:, i] & ((o < 0) | _lex_less_rows(v, i, o))
        o = np.where(better, i, o)
    tie = is_max.sum(axis=1) > 1
    j, kk = (o + 1) % 3, (o + 2) % 3
    rows = np.arange(k)
    ej, ek = e[rows, j], e[rows, kk]  # |O v_j|^2 = e_k, |O v_k|^2 = e_j
    vj_first = (ek < ej) | ((ek == ej) & _lex_less_pairs(v, j, kk))
    tie |= ek == ej
    m = np.where(vj_first, j, kk)
    n = np.where(vj_first, kk, j)
    return m, n, o, tie


def _lex_less_rows(v, i: int, o: NDArray) -> NDArray[np.bool_]:
    rows = np.arange(len(v))
    oo = np.where(o < 0, 0, o)
    a, b = v[:, i], v[rows, oo]
    return (a[:, 0] < b[:, 0]) | ((a[:, 0] == b[:, 0]) & (a[:, 1] < b[:, 1]))


def _lex_less_pairs(v, j: NDArray, k: NDArray) -> NDArray[np.bool_]:
    rows = np.arange(len(v))
    a, b = v[rows, j], v[rows, k]
    return (a[:, 0] < b[:, 0]) | ((a[:, 0] == b[:, 0]) & (a[:, 1] < b[:, 1]))


def edge_lengths2(v: NDArray) -> NDArray:
    """Squared lengths ``(K, 3)`` of the edges opposite each vertex of ``v (K, 3, 2)``."""
    out = []
    for i in range(3):
        p, q = v[:, (i + 1) % 3], v[:, (i + 2) % 3]
        out.append((p[:, 0] - q[:, 0]) ** 2 + (p[:, 1] - q[:, 1]) ** 2)
    return np.stack(out, axis=1)


def qd_case(m: NDArray, n: NDArray, o: NDArray) -> tuple[NDArray, NDArray[np.bool_]]:
    """Definition 1 with the documented ties on exact integer vertices ``(K, 2)`` (object):
    the nine points are taken times 3 (``3M``, ``2M + N``, ...) so they stay integers.
    Returns the case ``(K,)`` in {0, 1, 2} and whether ``|AB| = |OD|`` or ``|BD| = |OC|``
    held exactly."""

    def d2(p, q):
        return (p[:, 0] - q[:, 0]) ** 2 + (p[:, 1] - q[:, 1]) ** 2

    o3, d3, c3 = 3 * o, 2 * m + n, m + 2 * n
    b3, a3 = n + 2 * o, 2 * o + m
    ab, od, bd, oc = d2(a3, b3), d2(o3, d3), d2(b3, d3), d2(o3, c3)
    case = np.where(ab <= od, 0, np.where(bd < oc, 1, 2)).astype(np.int64)
    return case, (ab == od) | (bd == oc)


def qd_reference(v: NDArray[np.float64]) -> dict[str, NDArray]:
    """The exact 7T-QD decision for triangles ``v (K, 3, 2)``: labelling, case, ties and the
    triangles ``(K, 7, 3)`` in local indices (counter-clockwise if ``v`` is)."""
    ints, _ = as_integers(v)
    m, n, o, label_tie = labelling(ints, edge_lengths2(ints))
    rows = np.arange(len(v))
    case, case_tie = qd_case(ints[rows, m], ints[rows, n], ints[rows, o])
    return {"m": m, "n": n, "o": o, "case": case, "label_tie": label_tie,
            "case_tie": case_tie, "triangles": qd_triangles(m, n, o, case)}


# ----------------------------------------------------------------------------------------
# Fraction oracles (subsample)


def fraction_points(v: NDArray[np.float64]) -> list[tuple[Fraction, Fraction]]:
    """The nine exact points of triangle ``v (3, 2)`` in local order (trisection exact)."""
    p = [(Fraction(float(x)), Fraction(float(y))) for x, y in v]
    out = list(p)
    for i, j in ((0, 1), (0, 2), (1, 2)):
        for s in (1, 2):
            t = Fraction(s, 3)
            out.append((p[i][0] + t * (p[j][0] - p[i][0]), p[i][1] + t * (p[j][1] - p[i][1])))
    return out


def _fsq(p, q) -> Fraction:
    return (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2


def fraction_partition(v: NDArray[np.float64]) -> frozenset[tuple[int, ...]]:
    """7T-QD of one triangle in Fractions: the documented labelling, Definition 1 with the
    documented ties; a set of sorted local index triples."""
    p = fraction_points(v)[:3]
    e = [_fsq(p[(i + 1) % 3], p[(i + 2) % 3]) for i in range(3)]
    top = max(e)
    o = min((i for i in range(3) if e[i] == top), key=lambda i: p[i])
    j, k = (o + 1) % 3, (o + 2) % 3
    oj, ok = _fsq(p[o], p[j]), _fsq(p[o], p[k])
    m, n = (j, k) if (oj < ok or (oj == ok and p[j] < p[k])) else (k, j)
    s = {"M": p[m], "N": p[n], "O": p[o]}

    def at(a, b):
        return tuple(s[a][i] + (s[b][i] - s[a][i]) / 3 for i in range(2))

    s.update(D=at("M", "N"), C=at("N", "M"), B=at("O", "N"), A=at("O", "M"))
    if _fsq(s["A"], s["B"]) <= _fsq(s["O"], s["D"]):
        case = 0
    elif _fsq(s["B"], s["D"]) < _fsq(s["O"], s["C"]):
        case = 1
    else:
        case = 2
    tris = qd_triangles(np.array([m]), np.array([n]), np.array([o]), np.array([case]))[0]
    return frozenset(tuple(sorted(int(i) for i in t)) for t in tris)


def fraction_delaunay_ok(v: NDArray[np.float64], tris: NDArray) -> bool:
    """Whether no exact nine point of ``v (3, 2)`` lies strictly inside the circumcircle of
    a triangle of ``tris (T, 3)`` and every triangle has positive exact area (either
    orientation accepted for the incircle test)."""
    p = fraction_points(v)
    for t in tris:
        a, b, c = (p[i] for i in t)
        s = cross(*a, *b, *c)
        if s == 0:
            return False
        for j, d in enumerate(p):
            if j in t:
                continue
            if incircle(*a, *b, *c, *d) * (1 if s > 0 else -1) > 0:
                return False
    return True
