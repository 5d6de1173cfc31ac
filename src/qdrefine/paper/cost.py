"""The paper's cost claims, measured: the time of one scheme decision per triangle.

Every seven-triangle scheme decides a triangle by the exact signs of a few forms
``a uu + b ww + c uw`` (:mod:`qdrefine.schemes`); the cost of a scheme is the number of forms
and the time :func:`qdrefine.kernels.decide` takes per triangle (canonical labelling plus
the exact signs), measured here on the same random triangles for every scheme.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from ..kernels import decide
from ..predicates import SCRATCH, factor_forms
from ..schemes import SCHEMES

__all__ = ["DecisionCost", "decision_costs"]


@dataclass(frozen=True)
class DecisionCost:
    """Measured decision cost of one scheme.

    Attributes
    ----------
    scheme : str
    forms : int
        Exact form signs the scheme needs (all are evaluated for every triangle).
    ns_per_triangle : float
        Fastest of ``repeats`` runs, nanoseconds per triangle (one thread): the least
        disturbed run on a shared machine.
    spread : float
        ``(second fastest - fastest) / fastest``: how far the estimate may be off.
    """

    scheme: str
    forms: int
    ns_per_triangle: float
    spread: float


@njit(cache=True)
def _decide_all(v, forms, factors, lut):
    buf = np.empty(SCRATCH)
    acc = 0
    for t in range(v.shape[0]):
        acc += decide(v[t, 0, 0], v[t, 0, 1], v[t, 1, 0], v[t, 1, 1], v[t, 2, 0], v[t, 2, 1],
                      forms, factors, lut, buf)[3]
    return acc


def decision_costs(n: int = 100_000, repeats: int = 11, seed: int = 0,
                   schemes: tuple[str, ...] = ("7t-le", "7t-qd", "7t-d")) -> list[DecisionCost]:
    """Time :func:`qdrefine.kernels.decide` on ``n`` random triangles per scheme.

    The same triangles (uniform vertices in the unit square) are decided by every scheme,
    interleaved over ``repeats`` rounds so that a load change on the machine affects all
    schemes alike.
    """
    rng = np.random.default_rng(seed)
    v = rng.uniform(0.0, 1.0, (n, 3, 2))
    setups = {}
    for s in schemes:
        sch = SCHEMES[s]
        setups[s] = (np.ascontiguousarray(sch.forms), factor_forms(sch.forms), sch.lut)
        _decide_all(v[:10], *setups[s])  # compile outside the timing
    times: dict[str, list[float]] = {s: [] for s in schemes}
    for _ in range(repeats):
        for s in schemes:
            t0 = time.perf_counter()
            _decide_all(v, *setups[s])
            times[s].append((time.perf_counter() - t0) / n * 1e9)
    out = []
    for s in schemes:
        t = np.sort(np.array(times[s]))
        out.append(DecisionCost(s, int(SCHEMES[s].forms.shape[0]), float(t[0]),
                                float((t[1] - t[0]) / t[0]) if t.size > 1 else float("nan")))
    return out
