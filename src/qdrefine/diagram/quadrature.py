"""Areas of regions bounded by angle-equality curves: roots along vertical lines, adaptive
Gauss-Kronrod (7, 15) along ``x``.

The rule is our own vectorized adaptive GK(7,15): each round evaluates the integrand (a vector
of vertical-line root searches) at every pending interval's 15 nodes at once, which
``scipy.integrate.quad`` (one scalar call per node) does not allow. Measured on C3
(24 Nov 2026, shared 2-core machine, load average 9.6): ours 2.0 s (1290 nodes, estimate
5e-11), ``scipy.integrate.quad`` per slab at ``epsabs = epsrel = 1e-12`` 22.3 s (2100 scalar
calls); the two areas agree to 2e-12.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .arcs import Predicate, _critical_x, decision_arcs
from .mapping import _fans_float, fan_angles, inside_half

#: The smallest quadrature tolerance: the summed error estimates of the diagram's areas stop
#: falling at about 3e-14 (float64 rounding of the roots and sums), so a smaller target only
#: bisects on: at 1e-16 one run took 43 s and 5 GB before running out of memory, at 1e-300
#: it filled the machine's (a review, 2026-11-27).
SMALLEST_TOL = 1e-14

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


#: Width below which a sign change of a comparison is located (the bisection stops).
ROOT_TOLERANCE = 2e-16


def _bisect(g, x, lo, hi, slo, iterations=60):
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        same = (g(x, mid) > 0) == slo
        lo = np.where(same, mid, lo)
        hi = np.where(same, hi, mid)
        if np.all(hi - lo <= ROOT_TOLERANCE):
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
    if not tol >= SMALLEST_TOL:
        raise ValueError(f"tol must be at least {SMALLEST_TOL:g} (float64 rounding bounds "
                         f"the error estimates at about 3e-14), got {tol!r}")
    arcs, lines = decision_arcs()
    breaks = _critical_x(arcs, lines, 0.0, 0.5)
    win = window or inside_half

    def f(x):
        return _line_measure(x, predicate, win, list(comparisons), arcs, n_samples, measure)

    return gauss_kronrod(f, breaks, tol)
