"""The stencils and connectivity tables shared by every partition scheme.

Everything is written in the *canonical labelling* of a triangle: ``MN`` is the longest
edge, ``O`` the apex, ``M`` the endpoint of ``MN`` nearer to ``O``; in the paper's mapping
diagram ``M = (0, 0)``, ``N = (1, 0)``, ``O = (x, y)`` with ``x <= 1/2`` and ``y > 0``, so
every table below is counter-clockwise in that frame.

Local point numbering (the same for every scheme with ``k`` points per edge)::

    0 M, 1 N, 2 O, then k points on M->N, k on N->O, k on O->M,
    each edge's points listed from its first endpoint.

Seven-triangle stencil (``k = 2``), as in the paper's Fig. 1::

    M N O D C Q B A P      D = (2M+N)/3, C = (M+2N)/3, Q = (2N+O)/3,
    0 1 2 3 4 5 6 7 8      B = (N+2O)/3, A = (2O+M)/3, P = (O+2M)/3

Four-triangle stencil (``k = 1``): ``m``, ``q``, ``p`` are the midpoints of MN, NO, OM.

Squared distances and incircle determinants of stencil points are *linear forms* in
``(uu, ww, uw) = (|N-M|^2, |O-M|^2, (N-M).(O-M))`` (the incircle up to the factor
``(N-M) x (O-M)``), derived here exactly with :class:`fractions.Fraction`. Every scheme
decision is the sign of such a form, evaluated exactly by :mod:`qdrefine.predicates`.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from functools import reduce
from math import gcd, lcm

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Stencil",
    "SEVEN",
    "FOUR",
    "FIXED_7T",
    "PENTAGON",
    "fan",
    "triangles_from_names",
    "sqdist_form",
    "incircle_form",
    "integer_form",
    "CENTROID",
    "with_centroid",
]


@dataclass(frozen=True)
class Stencil:
    """Points of a partition in barycentric weights over ``(M, N, O)``.

    Attributes
    ----------
    names : tuple of str, length P
        One-letter point names, local index = position.
    weights : (P, 3) tuple of Fractions
        Barycentric weights of each point over ``(M, N, O)``.
    per_edge : int
        Number of new points on each edge (2 for seven-triangle, 1 for four-triangle).
    """

    names: tuple[str, ...]
    weights: tuple[tuple[Fraction, Fraction, Fraction], ...]
    per_edge: int

    def index(self, name: str) -> int:
        return self.names.index(name)

    def coefficients(self, name: str) -> tuple[Fraction, Fraction]:
        """``(a, b)`` with ``point = M + a (N - M) + b (O - M)``."""
        w = self.weights[self.index(name)]
        return w[1], w[2]

    def coordinates(self, m: NDArray, n: NDArray, o: NDArray) -> NDArray[np.float64]:
        """Float coordinates ``(P, 2)`` of the stencil on the triangle ``(m, n, o)``."""
        w = np.array([[float(c) for c in row] for row in self.weights])
        return w @ np.array([m, n, o], dtype=np.float64)


def _bary(*w: int, denominator: int) -> tuple[Fraction, Fraction, Fraction]:
    return tuple(Fraction(x, denominator) for x in w)  # type: ignore[return-value]


SEVEN = Stencil(
    names=("M", "N", "O", "D", "C", "Q", "B", "A", "P"),
    weights=(
        _bary(3, 0, 0, denominator=3),
        _bary(0, 3, 0, denominator=3),
        _bary(0, 0, 3, denominator=3),
        _bary(2, 1, 0, denominator=3),  # D on M->N
        _bary(1, 2, 0, denominator=3),  # C
        _bary(0, 2, 1, denominator=3),  # Q on N->O
        _bary(0, 1, 2, denominator=3),  # B
        _bary(1, 0, 2, denominator=3),  # A on O->M
        _bary(2, 0, 1, denominator=3),  # P
    ),
    per_edge=2,
)

FOUR = Stencil(
    names=("M", "N", "O", "m", "q", "p"),
    weights=(
        _bary(2, 0, 0, denominator=2),
        _bary(0, 2, 0, denominator=2),
        _bary(0, 0, 2, denominator=2),
        _bary(1, 1, 0, denominator=2),  # m on M->N
        _bary(0, 1, 1, denominator=2),  # q on N->O
        _bary(1, 0, 1, denominator=2),  # p on O->M
    ),
    per_edge=1,
)

#: Name of the parent's centroid, the one interior point of transition patterns.
CENTROID = "X"


def with_centroid(stencil: Stencil) -> Stencil:
    """``stencil`` with the centroid ``(M + N + O) / 3`` appended as point :data:`CENTROID`
    (local index ``3 + 3k``): the point set of the transition patterns of local refinement."""
    third = Fraction(1, 3)
    return Stencil(stencil.names + (CENTROID,), stencil.weights + ((third, third, third),),
                   stencil.per_edge)


#: The four corner triangles every seven-triangle scheme shares (paper: MPD, ADP, BCQ, CNQ).
FIXED_7T: tuple[str, ...] = ("MDP", "PDA", "CQB", "CNQ")

#: The interior pentagon A-D-C-B-O, counter-clockwise from D.
PENTAGON: tuple[str, ...] = ("D", "C", "B", "O", "A")


def fan(apex: str) -> tuple[str, str, str]:
    """The triangulation of :data:`PENTAGON` by the two diagonals from ``apex``."""
    i = PENTAGON.index(apex)
    p = [PENTAGON[(i + j) % 5] for j in range(5)]
    return (p[0] + p[1] + p[2], p[0] + p[2] + p[3], p[0] + p[3] + p[4])


def triangles_from_names(stencil: Stencil, names: tuple[str, ...]) -> NDArray[np.int8]:
    """Local index table ``(T, 3)`` from three-letter triangle names."""
    return np.array([[stencil.index(c) for c in t] for t in names], dtype=np.int8)


Form = tuple[Fraction, Fraction, Fraction]


def _delta(stencil: Stencil, p: str, q: str) -> tuple[Fraction, Fraction]:
    (a1, b1), (a2, b2) = stencil.coefficients(p), stencil.coefficients(q)
    return a1 - a2, b1 - b2


def _sq(a: Fraction, b: Fraction) -> Form:
    return (a * a, b * b, 2 * a * b)


def sqdist_form(stencil: Stencil, p: str, q: str) -> Form:
    """``|p - q|^2`` as coefficients of ``(uu, ww, uw)``."""
    return _sq(*_delta(stencil, p, q))


def sqdist_difference(stencil: Stencil, long: str, short: str) -> Form:
    """``|long|^2 - |short|^2`` for two two-letter segment names, e.g. ``("OD", "AB")``."""
    f = sqdist_form(stencil, long[0], long[1])
    g = sqdist_form(stencil, short[0], short[1])
    return (f[0] - g[0], f[1] - g[1], f[2] - g[2])


def incircle_form(stencil: Stencil, a: str, b: str, c: str, d: str) -> Form:
    """``incircle(a, b, c, d) / ((N-M) x (O-M))`` as a form in ``(uu, ww, uw)``.

    Positive iff ``d`` lies strictly inside the circle through ``a, b, c`` when ``a, b, c``
    are counter-clockwise in the canonical frame (the sign convention of Shewchuk's
    ``incircle``). Derived from the cofactor expansion along the lifted column: with
    ``r_i = p_i - d = alpha_i u + beta_i w``, the determinant is
    ``sum_cyclic |r_a|^2 (alpha_b beta_c - alpha_c beta_b) (u x w)``.
    """
    r = [_delta(stencil, p, d) for p in (a, b, c)]
    total = [Fraction(0)] * 3
    for i in range(3):
        (al, be), (al_b, be_b), (al_c, be_c) = r[i], r[(i + 1) % 3], r[(i + 2) % 3]
        minor = al_b * be_c - al_c * be_b
        total = [t + minor * s for t, s in zip(total, _sq(al, be), strict=True)]
    return tuple(total)  # type: ignore[return-value]


def integer_form(form: Form) -> tuple[int, int, int]:
    """The primitive integer multiple (positive factor) of a rational form."""
    den = reduce(lcm, (f.denominator for f in form), 1)
    ints = [int(f * den) for f in form]
    g = reduce(gcd, (abs(i) for i in ints), 0) or 1
    return tuple(i // g for i in ints)  # type: ignore[return-value]
