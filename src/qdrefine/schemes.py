"""The partition schemes: a registry of table choices driven by exact signs.

A scheme is data: a stencil, a table of candidate partitions ``(R, T, 3)`` (local point
indices, counter-clockwise in the canonical frame), a few linear forms in
``(uu, ww, uw)`` whose signs decide, and a lookup table from the sign pattern to a table
row. The lookup table is built once, here, by running the scheme's *rule* (plain Python on
signs) over every sign pattern; the compiled kernels only evaluate signs and index it.

Tie rules (all depend on the geometry only, never on the order of the vertices):

* canonical labelling (:mod:`qdrefine.kernels`): of two equally long longest edges, the
  one whose opposite vertex is lexicographically smaller (x, then y) is ``MN``; when
  ``|OM| = |ON|``, ``M`` is the lexicographically smaller endpoint;
* ``7t-qd``: Case I when ``|AB| <= |OD|`` (the paper's Definition 1 sends the tie to Case
  III, which is not Delaunay on the I/II arc where A, B, O, D are co-circular; both I and II
  are Delaunay there and Case I is also the cheaper, 7T-LE, split); Case II when
  ``|AB| > |OD|`` and ``|BD| < |OC|`` (strict, as in the paper); Case III otherwise;
* ``7t-le``: the quadrilateral A-D-C-B is split by BD when ``|BD| <= |AC|``, else by AC
  (in the canonical frame ``|BD| <= |AC|`` always holds, since ``|BD| = 2|OM|/3``);
* ``7t-d``: the first Delaunay fan of the pentagon in the priority order B, D, O, A, C
  (B is 7T-LE and Case I, D is Case II, O is Case III), decided by exact incircle signs
  on the exact trisection points of the float64 input triangle.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from .stencil import (
    FIXED_7T,
    FOUR,
    PENTAGON,
    SEVEN,
    Form,
    Stencil,
    fan,
    incircle_form,
    integer_form,
    sqdist_difference,
    triangles_from_names,
)

__all__ = ["Scheme", "SCHEMES", "get_scheme", "scheme_names"]

Rule = Callable[[tuple[int, ...]], int]


@dataclass(frozen=True, eq=False)
class Scheme:
    """One partition scheme.

    Attributes
    ----------
    name : str
        Registry name, e.g. ``"7t-qd"``.
    stencil : Stencil
    rows : tuple of str
        A name for each candidate partition (row of ``tables``).
    tables : (R, T, 3) int8
        Local point indices of the ``T`` triangles of each candidate.
    forms : (F, 3) float64
        Integer coefficients of the deciding forms in ``(uu, ww, uw)``.
    lut : (3**F,) int8
        Table row for each sign pattern ``sum_f (sign_f + 1) 3**f``.
    description : str
    """

    name: str
    stencil: Stencil
    rows: tuple[str, ...]
    tables: NDArray[np.int8]
    forms: NDArray[np.float64]
    lut: NDArray[np.int8]
    description: str = field(default="")

    @property
    def n_children(self) -> int:
        return int(self.tables.shape[1])

    def row(self, name: str) -> int:
        return self.rows.index(name)


def _build(
    name: str,
    stencil: Stencil,
    rows: dict[str, tuple[str, ...]],
    conditions: list[Form],
    rule: Rule,
    description: str,
) -> Scheme:
    """Deduplicate the condition forms up to sign and tabulate ``rule`` over all signs."""
    base: list[tuple[int, int, int]] = []
    where: list[tuple[int, int]] = []  # (base index, sign factor) per condition
    for cond in conditions:
        f = integer_form(cond)
        neg = tuple(-c for c in f)
        if f in base:
            where.append((base.index(f), 1))
        elif neg in base:
            where.append((base.index(neg), -1))
        else:
            base.append(f)
            where.append((len(base) - 1, 1))
    names = tuple(rows)
    lut = np.empty(3 ** len(base), dtype=np.int8)
    for signs in itertools.product((-1, 0, 1), repeat=len(base)):
        code = sum((s + 1) * 3**f for f, s in enumerate(signs))
        lut[code] = rule(tuple(signs[i] * factor for i, factor in where))
    tables = np.stack([triangles_from_names(stencil, rows[r]) for r in names])
    forms = np.array(base, dtype=np.float64).reshape(-1, 3)
    return Scheme(name, stencil, names, tables, forms, lut, description)


def _seven_rows(*apexes: str) -> dict[str, tuple[str, ...]]:
    return {f"fan-{a}": FIXED_7T + fan(a) for a in apexes}


def _qd() -> Scheme:
    conditions = [
        sqdist_difference(SEVEN, "OD", "AB"),  # >= 0: Case I
        sqdist_difference(SEVEN, "OC", "BD"),  # > 0: Case II (when not I)
    ]

    def rule(s: tuple[int, ...]) -> int:
        if s[0] >= 0:
            return 0  # Case I
        return 1 if s[1] > 0 else 2

    return _build(
        "7t-qd", SEVEN, _seven_rows("B", "D", "O"), conditions, rule,
        "Seven Triangle Quasi-Delaunay (paper, Definition 1; extended to all triangles)",
    )


def _le() -> Scheme:
    conditions = [sqdist_difference(SEVEN, "AC", "BD")]  # >= 0: split by BD

    def rule(s: tuple[int, ...]) -> int:
        return 0 if s[0] >= 0 else 1

    return _build(
        "7t-le", SEVEN, _seven_rows("B", "A"), conditions, rule,
        "Seven Triangle Longest-Edge: corners at M, N, O; A-D-C-B split by its shorter diagonal",
    )


def _delaunay_conditions() -> tuple[list[Form], list[list[tuple[int, int]]]]:
    """Per fan, its two diagonals as (condition index, required sign side).

    Diagonal ``p_i p_{i+2}`` of fan ``i`` is legal iff ``incircle(p_i, p_{i+1}, p_{i+2},
    p_{i+3}) <= 0``; diagonal ``p_i p_{i+3}`` iff ``incircle(p_{i+2}, p_{i+3}, p_{i+4}, p_i)
    >= 0`` (the fourth point is the opposite vertex of the quadrilateral).
    """
    conditions: list[Form] = []
    fans: list[list[tuple[int, int]]] = []
    p = PENTAGON
    for i in range(5):
        q = [p[(i + j) % 5] for j in range(5)]
        conditions.append(incircle_form(SEVEN, q[0], q[1], q[2], q[3]))
        conditions.append(incircle_form(SEVEN, q[2], q[3], q[4], q[0]))
        fans.append([(2 * i, -1), (2 * i + 1, 1)])
    return conditions, fans


def _delaunay() -> Scheme:
    conditions, fans = _delaunay_conditions()
    priority = ("B", "D", "O", "A", "C")

    def rule(s: tuple[int, ...]) -> int:
        for r, apex in enumerate(priority):
            legal = all(s[c] * side >= 0 for c, side in fans[PENTAGON.index(apex)])
            if legal:
                return r
        return 0  # sign pattern no triangle realizes

    return _build(
        "7t-d", SEVEN, _seven_rows(*priority), conditions, rule,
        "Seven Triangle Delaunay: exact Delaunay triangulation of the nine points",
    )


def _four(name: str, triangles: tuple[str, ...], description: str) -> Scheme:
    return _build(name, FOUR, {name: triangles}, [], lambda s: 0, description)


SCHEMES: dict[str, Scheme] = {
    s.name: s
    for s in (
        _qd(),
        _le(),
        _delaunay(),
        _four("4t-le", ("Mmp", "mOp", "mqO", "mNq"),
              "Four Triangle Longest-Edge: longest-edge midpoint joined to all midpoints and O"),
        _four("4t-red", ("Mmp", "mNq", "pqO", "mqp"),
              "Four Triangle regular (red) refinement: the three midpoints joined"),
    )
}


def scheme_names() -> tuple[str, ...]:
    return tuple(SCHEMES)


def get_scheme(scheme: str | Scheme) -> Scheme:
    """The registered scheme called ``scheme`` (any case: ``"7T-QD"`` is ``"7t-qd"``); an
    unknown name raises ``ValueError``."""
    if isinstance(scheme, Scheme):
        return scheme
    try:
        return SCHEMES[scheme.lower()]
    except (KeyError, TypeError, AttributeError):
        raise ValueError(
            f"unknown scheme {scheme!r}; choose one of: {', '.join(SCHEMES)}"
        ) from None
