"""Lemmas 1 and 2 of the paper, checked symbolically (SymPy, optional)."""

from __future__ import annotations

import importlib.util

from ..stencil import FIXED_7T, SEVEN
from .claims import PAPER_CLAIMS

__all__ = ["lemma_checks", "has"]


def has(module: str) -> bool:
    """Whether an optional module is installed."""
    return importlib.util.find_spec(module) is not None


def lemma_checks() -> dict:
    """Check Lemmas 1 and 2 with SymPy over the closure of the left half ``H``.

    For each fixed triangle and each other stencil point ``X``, ``q(x, y) = incircle * orient
    / y^2`` is a polynomial ``a + b (x^2 + y^2) + c x`` (positive iff ``X`` is strictly inside
    the circumcircle). Its maximum over the closure of ``H`` is exact: ``H`` is convex and
    ``q`` has no interior critical point, so the maximum is on the boundary (``y = 0``:
    a quadratic; ``x = 1/2``: monotone in ``y^2``; the arc ``x^2 + y^2 = 2x``: linear in
    ``x``), evaluated at the corners and the critical point of the quadratic.
    Also compares the paper's circumcentres with the true ones.
    """
    if not has("sympy"):
        return {"available": False}
    import sympy as sp

    x, y = sp.symbols("x y", real=True)
    pts = {}
    for name, (wm, wn, wo) in zip(SEVEN.names, SEVEN.weights, strict=True):
        pts[name] = (sp.Rational(wn.numerator, wn.denominator) + sp.Rational(
            wo.numerator, wo.denominator) * x, sp.Rational(wo.numerator, wo.denominator) * y)
        del wm

    def orient(a, b, c):
        return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])

    def incircle(a, b, c, d):
        rows = [(p[0] - d[0], p[1] - d[1]) for p in (a, b, c)]
        return sp.Matrix([[u, v, u * u + v * v] for u, v in rows]).det()

    corners = [(0, 0), (sp.Rational(1, 2), 0), (sp.Rational(1, 2), sp.sqrt(3) / 2)]

    def max_on_h(q):
        cands = list(corners)
        qx = sp.Poly(sp.expand(q.subs(y, 0)), x)
        if qx.degree() == 2:
            xc = -qx.all_coeffs()[1] / (2 * qx.all_coeffs()[0])
            if 0 <= xc <= sp.Rational(1, 2):
                cands.append((xc, 0))
        vals = [(sp.nsimplify(sp.simplify(q.subs({x: a, y: b}))), (a, b)) for a, b in cands]
        return max(vals, key=lambda t: float(t[0]))

    # Lemma 1: the fixed corner triangles at M and N; Lemma 2: the other two
    lemma_1 = tuple(t for t in FIXED_7T if "M" in t or "N" in t)
    lemma_2 = tuple(t for t in FIXED_7T if t not in lemma_1)
    results = []
    for lemma, tris in (("Lemma 1", lemma_1), ("Lemma 2", lemma_2)):
        for tri in tris:
            a, b, c = (pts[n] for n in tri)
            o = orient(a, b, c)
            for other in SEVEN.names:
                if other in tri:
                    continue
                q = sp.factor(sp.expand(incircle(a, b, c, pts[other]) * o))
                q = sp.expand(sp.cancel(q / y**2))
                qmax, where = max_on_h(q)
                results.append({"lemma": lemma, "triangle": tri, "point": other,
                                "form": str(sp.factor(q)), "max_on_H": str(qmax),
                                "at": f"({where[0]}, {where[1]})",
                                "delaunay": bool(qmax <= 0)})
    # the paper's circumcentres
    def circumcentre(a, b, c):
        cx, cy = sp.symbols("cx cy")
        eqs = [sp.expand((a[0] - cx) ** 2 + (a[1] - cy) ** 2 - (p[0] - cx) ** 2
                         - (p[1] - cy) ** 2) for p in (b, c)]
        sol = sp.solve(eqs, [cx, cy], dict=True)[0]
        return sp.factor(sol[cx]), sp.factor(sol[cy])

    symbols = {"x": x, "y": y}
    paper_c0, paper_c1 = (tuple(sp.sympify(e, locals=symbols) for e in PAPER_CLAIMS[key])
                          for key in ("circumcentre_MPD", "circumcentre_ADP"))
    at_m = next(t for t in lemma_1 if "M" in t)  # the paper's MPD
    at_p = next(t for t in lemma_2 if "P" in t)  # the paper's ADP
    true_c0 = circumcentre(*(pts[n] for n in at_m))
    true_c1 = circumcentre(*(pts[n] for n in at_p))
    centres = []
    for lemma, tri, paper, true in (("Lemma 1", at_m, paper_c0, true_c0),
                                    ("Lemma 2", at_p, paper_c1, true_c1)):
        ok = [sp.simplify(p - t) == 0 for p, t in zip(paper, true, strict=True)]
        centres.append({"triangle": f"{tri} ({lemma})", "lemma": lemma,
                        "paper": f"({paper[0]}, {paper[1]})",
                        "true": f"({true[0]}, {true[1]})", "x_ok": ok[0], "y_ok": ok[1]})
    # the paper's intermediate inequalities of Lemma 1
    cc = true_c0
    def d2(p):
        return (p[0] - cc[0]) ** 2 + (p[1] - cc[1]) ** 2
    steps = [
        ("Lemma 1: |BC|^2 - |MC|^2 = (2/9)(x^2 + y^2 + 2x)",
         sp.simplify(d2(pts["B"]) - d2(pts["M"]) - sp.Rational(2, 9) * (x**2 + y**2 + 2 * x))
         == 0),
        ("Lemma 1: |QC|^2 - |MC|^2 = (2/9)(2x + 1), i.e. >= 0 iff x >= -1/2",
         sp.simplify(d2(pts["Q"]) - d2(pts["M"]) - sp.Rational(2, 9) * (2 * x + 1)) == 0),
    ]
    cc = true_c1
    ratio = sp.simplify((d2(pts["B"]) - d2(pts["A"])) / (1 - (x - 1) ** 2 - y**2))
    steps.append(("Lemma 2: |BC|^2 - |AC|^2 is a positive multiple of 1 - (x-1)^2 - y^2 "
                  f"(factor {ratio}), so >= 0 iff (x-1)^2 + y^2 <= 1",
                  bool(ratio.is_number and ratio > 0)))
    # does the paper's B step survive its wrong centre? (only if the centre's y cancels)
    def d2_at(p, c):
        return (p[0] - c[0]) ** 2 + (p[1] - c[1]) ** 2

    b_paper = sp.simplify(d2_at(pts["B"], paper_c1) - d2_at(pts["A"], paper_c1))
    b_true = sp.simplify(d2_at(pts["B"], true_c1) - d2_at(pts["A"], true_c1))
    b_step = {"same_y": sp.simplify(pts["A"][1] - pts["B"][1]) == 0,
              "unaffected": sp.simplify(b_paper - b_true) == 0}
    return {"available": True, "version": sp.__version__, "results": results,
            "centres": centres, "steps": steps, "b_step": b_step}
