"""Every decision form of the seven-triangle schemes as a circle of the diagram, and exact
areas of regions bounded by such circles (closed-form segment integrals between the abscissae
of arc ends and intersections)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..schemes import SCHEMES
from .mapping import _SCHEMES_7T, inside_half

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
