"""The mapping diagram: classification against exact oracles and the partitions themselves,
exact arc areas against independent closed forms and quasi-Monte Carlo, convergence."""

import json
import math
from fractions import Fraction as F

import numpy as np
import pytest

from oracle import definition1_case, incircle, orient, seven_points
from qdrefine import diagram as dg
from qdrefine import partition, quality
from qdrefine.cli import main
from qdrefine.stencil import fan


def random_half_points(n, seed):
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        x, y = rng.uniform(0, 0.5), rng.uniform(1e-3, 0.87)
        if (x - 1) ** 2 + y * y < 1:
            out.append((x, y))
    return np.array(out)


def shaded_points(n, seed):
    rng = np.random.default_rng(seed)
    p = np.column_stack([rng.uniform(0.395, 0.5, 20 * n), rng.uniform(1e-3, 0.32, 20 * n)])
    keep = dg._pred("shaded")(p[:, 0], p[:, 1])
    return p[keep][:n]


def delaunay_fan(m, n, o):
    """First fan (B, D, O, A, C) whose two diagonals are locally Delaunay, exactly."""
    s = seven_points(m, n, o)
    for apex in "BDOAC":
        ok = True
        for tri in fan(apex):
            a, b, c = (s[k] for k in tri)
            sign = 1 if orient(a, b, c) > 0 else -1
            for other in "DCBOA":
                if other not in tri and incircle(a, b, c, s[other]) * sign > 0:
                    ok = False
        if ok:
            return apex
    raise AssertionError


def test_regions_match_exact_oracles():
    pts = np.concatenate([random_half_points(150, 1), shaded_points(50, 2)])
    masks = dg.region_masks(pts[:, 0], pts[:, 1])
    for i, (x, y) in enumerate(pts):
        m, n, o = (F(0), F(0)), (F(1), F(0)), (F(float(x)), F(float(y)))
        case = definition1_case(m, n, o)
        assert masks[case][i]
        qd_apex = {"I": "B", "II": "D", "III": "O"}[case]
        assert masks["shaded"][i] == (delaunay_fan(m, n, o) != qd_apex)


def test_regions_match_the_partitions():
    pts = np.concatenate([random_half_points(100, 3), shaded_points(40, 4)])
    masks = dg.region_masks(pts[:, 0], pts[:, 1])
    for i, (x, y) in enumerate(pts):
        v = np.array([[0.0, 0.0], [1.0, 0.0], [x, y]])
        tris = {s: {frozenset(t) for t in partition(v, s)[1].tolist()}
                for s in ("7t-qd", "7t-d", "7t-le")}
        assert masks["shaded"][i] == (tris["7t-qd"] != tris["7t-d"])
        assert masks["I"][i] == (tris["7t-qd"] == tris["7t-le"])
    # the min angle used by the regions is the one of the partition's pentagon triangles
    x, y = shaded_points(1, 5)[0]
    pts9, tris = partition(np.array([[0.0, 0.0], [1.0, 0.0], [x, y]]), "7t-qd")
    p = pts9[tris[4:]]
    ang = quality.corner_angles(p).min()
    assert ang == pytest.approx(dg.partition_measure([x], [y], "7t-qd")[0], abs=1e-9)


def test_to_diagram_is_invariant():
    rng = np.random.default_rng(6)
    xy = random_half_points(50, 7)
    base = np.stack([np.zeros((50, 2)), np.tile([1.0, 0.0], (50, 1)), xy], axis=1)
    th = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    moved = 3.7 * base @ rot.T + np.array([5.0, -2.0])
    moved = moved[:, [2, 0, 1]]
    mirrored = moved * np.array([-1.0, 1.0])
    for v in (base, moved, mirrored):
        assert np.allclose(dg.to_diagram(v), xy, atol=1e-12)


def g(r2, u, h):
    """Antiderivative of sqrt(r2 - u^2) at offset u, with h = sqrt(r2 - u^2) given exactly."""
    return 0.5 * (u * h + r2 * math.atan2(u, h))


def test_arc_areas_closed_forms():
    half = math.pi / 6 - math.sqrt(3) / 8
    assert dg.HALF_AREA == pytest.approx(half, abs=1e-15)
    # II + III: the half disc (x-1/3)^2 + y^2 < 1/9 left of x = 1/2
    not_i = math.pi / 27 + math.sqrt(3) / 72
    # III: under (x-6/5)^2+y^2=16/25 from its left end 2/5 to the intersection (6/13, 4/13),
    # then under (x-1/3)^2+y^2=1/9 to x = 1/2 (height sqrt(3)/6)
    iii = (g(16 / 25, -48 / 65, 4 / 13) - g(16 / 25, -4 / 5, 0.0)
           + g(1 / 9, 1 / 6, math.sqrt(3) / 6) - g(1 / 9, 5 / 39, 4 / 13))
    exact = {"I": half - not_i, "II": not_i - iii, "III": iii}
    for k, v in exact.items():
        assert dg.region_area(k).value == pytest.approx(v, abs=1e-14)
        q = dg.region_area(k, method="quadrature", tol=1e-11)
        assert abs(q.value - v) <= max(q.error, 1e-12)


def test_areas_against_quasi_monte_carlo():
    # independent oracle: a scrambled-free Halton sequence over the bounding box, membership
    # by the region masks; standard error ~ sqrt(p(1-p)/n) * box area; 5 sigma
    n = 40000
    i = np.arange(1, n + 1)

    def halton(b):
        out = np.zeros(n)
        f = 1.0
        k = i.copy()
        while (k > 0).any():
            f /= b
            out += f * (k % b)
            k //= b
        return out

    x, y = 0.5 * halton(2), 0.87 * halton(3)
    masks = dg.region_masks(x, y, exact=False)
    box = 0.5 * 0.87
    for k in ("I", "II", "III", "shaded", "C1", "C2", "C3"):
        est = masks[k].mean() * box
        p = masks[k].mean()
        tol = 5 * math.sqrt(p * (1 - p) / n) * box + 1e-4
        assert dg.region_area(k, tol=1e-8).value == pytest.approx(est, abs=tol)


def test_quadrature_converges():
    prev = None
    for tol in (1e-7, 1e-9, 1e-11):
        r = dg.region_area("C2", tol=tol)
        assert r.error <= tol
        if prev is not None:
            assert abs(r.value - prev.value) <= prev.error + r.error + 1e-12
        prev = r
    fine = {k: dg.region_area(k, tol=1e-10, n_samples=128).value for k in ("C1", "C2", "C3")}
    coarse = {k: dg.region_area(k, tol=1e-10, n_samples=32).value for k in ("C1", "C2", "C3")}
    for k in fine:
        assert fine[k] == pytest.approx(coarse[k], abs=1e-9)
    assert sum(fine.values()) == pytest.approx(dg.region_area("shaded").value, abs=1e-9)


def test_angle_measure_total():
    total = sum(dg.region_area(k, method="quadrature", tol=1e-9, measure="angles").value
                for k in ("I", "II", "III"))
    assert total == pytest.approx(dg.HALF_ANGLE_AREA, abs=5e-9)


def test_diagram_json(capsys):
    assert main(["diagram", "--json", "--no-angle-measure"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert {"diagram_area", "fractions", "areas", "le_min_above_qd",
            "worst_qd_over_d_min_angle", "error_bound"} <= set(obj)
    keys = {"I", "II", "III", "shaded", "C1", "C2", "C3"}
    assert set(obj["fractions"]) == keys and set(obj["areas"]) == keys
    fr = obj["fractions"]
    assert fr["I"] + fr["II"] + fr["III"] == pytest.approx(1, abs=1e-12)
    assert fr["C1"] + fr["C2"] + fr["C3"] == pytest.approx(fr["shaded"], abs=1e-8)
    assert obj["error_bound"] <= 1e-6
    assert 0 < obj["worst_qd_over_d_min_angle"] < 1
    assert 0 < obj["worst_qd_over_d_min_angle_bound"] < 1e-9
    by = obj["worst_qd_over_d_by_reading"]
    assert set(by) == set(dg.READINGS)
    for e in by.values():
        assert e["lower"] <= e["value"] and e["bound"] >= e["value"] - e["lower"]
    assert by["pentagon"]["value"] == obj["worst_qd_over_d_min_angle"]
    assert "paper_claims" in obj


def test_bad_options():
    with pytest.raises(ValueError, match="choose one of"):
        dg.region_area("IV")
    with pytest.raises(ValueError, match="choose one of"):
        dg.partition_measure([0.3], [0.3], "7t-qd", measure="max")


# ---------------------------------------------------------------------------------------
# certified extrema against an independent 30-digit search


def _mp_ratio_factory(mp):
    """The 7T-QD / 7T-D ratio of each reading in mpmath, from the paper's coordinates
    (Lemma 1: B, Q; Lemma 2: A, D, P; Definition 1: the fans), not from qdrefine."""
    def points(x, y):
        return {"M": (0, 0), "N": (1, 0), "O": (x, y), "D": (mp.mpf(1) / 3, 0),
                "C": (mp.mpf(2) / 3, 0), "Q": ((2 + x) / 3, y / 3),
                "B": ((1 + 2 * x) / 3, 2 * y / 3), "A": (2 * x / 3, 2 * y / 3),
                "P": (x / 3, y / 3)}

    def min_angle(p, tri):
        out = []
        for i in range(3):
            a, b, c = p[tri[i]], p[tri[(i + 1) % 3]], p[tri[(i + 2) % 3]]
            u = (b[0] - a[0], b[1] - a[1])
            v = (c[0] - a[0], c[1] - a[1])
            out.append(mp.atan2(abs(u[0] * v[1] - u[1] * v[0]), u[0] * v[0] + u[1] * v[1]))
        return min(out)

    fixed = ["MPD", "ADP", "BCQ", "CNQ"]
    case3 = ["ADO", "CDO", "BCO"]       # Definition 1 (c): 7T-QD in the shaded region
    case2 = ["ADO", "BDO", "BCD"]       # Definition 1 (b): 7T-D there
    readings = {"pentagon": (case3, case2), "two": (case3[1:], case2[1:]),
                "seven": (fixed + case3, fixed + case2),
                "two-vs-refinement": (case3[1:], fixed + case2)}

    def ratio(reading, x, y):
        p = points(x, y)
        q, d = readings[reading]
        return min(min_angle(p, t) for t in q) / min(min_angle(p, t) for t in d)

    def neg_gap(reading, x, y):  # QD - D in degrees: its minimum is minus the largest gap
        p = points(x, y)
        q, d = readings[reading]
        return mp.degrees(min(min_angle(p, t) for t in q) - min(min_angle(p, t) for t in d))

    ratio.neg_gap = neg_gap
    return ratio


def _mp_search(mp, ratio, reading):
    r3 = 1 / mp.sqrt(3)
    tiny = mp.mpf("1e-25")  # the base y = 0: the ratio's limit, to O(y^2)
    curves = [  # (x(t), y(t), t0, t1): the boundary of {III, outside (x-1)^2+y^2=1/3}
        (lambda t: t, lambda t: tiny, mp.mpf(2) / 5, 1 - r3),
        (lambda t: 1 + r3 * mp.cos(t), lambda t: r3 * mp.sin(t), 5 * mp.pi / 6, mp.pi),
        (lambda t: (1 + mp.cos(t)) / 3, lambda t: mp.sin(t) / 3, mp.pi / 3,
         mp.acos(mp.mpf(5) / 13)),
        (lambda t: mp.mpf(6) / 5 + 4 * mp.cos(t) / 5, lambda t: 4 * mp.sin(t) / 5,
         mp.pi - mp.acos(mp.mpf(12) / 13), mp.pi),
    ]
    best = min(ratio(reading, x, y) for x, y in (
        (mp.mpf(2) / 5, tiny), (1 - r3, tiny), (mp.mpf(1) / 2, mp.sqrt(mp.mpf(1) / 12)),
        (mp.mpf(6) / 13, mp.mpf(4) / 13)))
    g = (mp.sqrt(5) - 1) / 2
    for fx, fy, t0, t1 in curves:
        def f(t, fx=fx, fy=fy):
            return ratio(reading, fx(t), max(fy(t), tiny))
        n = 40
        ts = [t0 + (t1 - t0) * i / n for i in range(n + 1)]
        vs = [f(t) for t in ts]
        for i in sorted(range(n + 1), key=lambda i: vs[i])[:3]:
            a, b = ts[max(i - 1, 0)], ts[min(i + 1, n)]
            c, d = b - g * (b - a), a + g * (b - a)
            fc, fd = f(c), f(d)
            while b - a > mp.mpf("1e-22"):
                if fc < fd:
                    b, d, fd = d, c, fc
                    c = b - g * (b - a)
                    fc = f(c)
                else:
                    a, c, fc = c, d, fd
                    d = a + g * (b - a)
                    fd = f(d)
            best = min(best, fc, fd, vs[i])
    return best


def test_worst_ratio_agrees_with_a_30_digit_search_of_every_arc_and_corner():
    import mpmath  # shipped with sympy, a test dependency

    mp = mpmath.mp
    ratio = _mp_ratio_factory(mp)
    with mpmath.workdps(30):
        _check_worst_ratios(mp, ratio)


def _check_worst_ratios(mp, ratio):
    for reading in dg.READINGS:
        ours = dg.worst_ratio(reading)
        ref = _mp_search(mp, ratio, reading)
        assert abs(ours.value - float(ref)) < 1e-9, reading
        # the certified interval contains the independent value
        assert ours.lower - 1e-12 <= float(ref) <= ours.value + 1e-12, reading
        assert ours.bound < 1e-9
        big = dg.largest_gap(reading)
        ref_gap = -_mp_search(mp, ratio.neg_gap, reading)
        assert abs(big.value - float(ref_gap)) < 1e-9, reading
        assert big.lower - 1e-12 <= float(ref_gap) <= big.upper + 1e-12
        # and the value is attained where it says
        x, y = ours.point
        assert float(ratio(reading, mp.mpf(x), mp.mpf(max(y, 1e-25)))) == pytest.approx(
            ours.value, abs=1e-12)


def test_closure_and_boundary_of_the_shaded_region():
    from qdrefine.diagram import extrema as ex

    rng = np.random.default_rng(11)
    x, y = rng.uniform(0.39, 0.51, 50000), rng.uniform(1e-6, 0.33, 50000)
    assert np.array_equal(ex.in_closure(x, y), dg._pred("shaded")(x, y))
    arcs, _ = dg.decision_arcs()
    for curve in ex.BOUNDARY[1:]:
        assert any(abs(a.cx - curve.cx) < 1e-12 and abs(a.r2 - curve.r**2) < 1e-12
                   for a in arcs)
    for cx, cy in ex.CORNERS.values():  # every corner is on two of the curves
        on = [c for c in ex.BOUNDARY
              if (c.r == 0 and cy == 0) or abs(math.hypot(cx - c.cx, cy) - c.r) < 1e-12]
        assert len(on) == 2
    # the ratio away from the boundary is above the certified minimum (no interior dip)
    for reading in dg.READINGS:
        e = dg.worst_ratio(reading)
        inside = ex.in_closure(x, y)
        assert ex.ratio(x[inside], y[inside], reading).min() >= e.lower


@pytest.mark.parametrize("triangle, curve, attained", [
    ([(0, 0), (185, 0), (82, 48)], 3, True),  # on the II/III arc: rule 4 keeps Case III
    ([(0, 0), (51, 0), (25, 15)], 2, False),  # on the I/III arc: rule 3 gives Case I
    ([(0, 0), (13, 0), (6, 4)], None, False),  # the corner I-III / II-III
])
def test_extrema_are_attained_only_where_the_tie_rules_keep_the_compared_fans(
        triangle, curve, attained):
    """The worst ratios were called attained at the corner I-III / II-III, where 7T-QD and
    7T-D split alike (ratio 1; review). Triangles of integer coordinates exactly on the arcs
    and the corner, refined by the real schemes, against the closure's continued ratio."""
    from qdrefine.diagram import extrema as ex

    p = np.array(triangle, dtype=float)
    x, y = p[2] / p[1, 0]
    ours = {s: partition(p, s) for s in ("7t-qd", "7t-d")}
    real = (quality.min_angles(*ours["7t-qd"]).min() / quality.min_angles(*ours["7t-d"]).min())
    closure = float(ex.ratio(np.array([x]), np.array([y]), "seven")[0])
    assert closure < 0.999  # the fans compared differ there
    assert (abs(real - closure) < 1e-12) == attained and (real == 1.0) != attained
    where = ex.BOUNDARY[curve].name if curve is not None else "corner I-III / II-III"
    assert (where in ex.ATTAINED_ON) == attained
    assert (ex.Extremum("seven", "ratio", "min", closure, 0.0, (x, y), where, 0).attained
            == attained)


def test_interval_enclosures_contain_the_point_values():
    from qdrefine.diagram import extrema as ex

    rng = np.random.default_rng(12)
    x0 = rng.uniform(0.4, 0.5, 300)
    y0 = rng.uniform(0, 0.3, 300)
    w = rng.uniform(0, 0.02, 300)
    names = ex.READINGS["seven"][1]
    lo, hi = ex._box_angles(ex._angle_coefficients(names), x0, x0 + w, y0, y0 + w)
    for s, t in rng.uniform(0, 1, (20, 2)):
        v = ex.normalized_angles(x0 + s * w, y0 + t * w, names)
        assert np.all(lo <= v) and np.all(v <= hi)


@pytest.mark.parametrize("tol", [1e-15, 1e-300, 0.0, float("nan")])
def test_a_tolerance_below_the_rounding_floor_is_refused(tol):
    """``tol=1e-300`` bisected until the machine's memory was full (review): the summed error
    estimates stop falling at about 3e-14."""
    with pytest.raises(ValueError, match="tol must be at least 1e-14"):
        dg.region_area("C2", method="quadrature", tol=tol)


@pytest.mark.parametrize("x, y", [(0.7, 0.3), (0.2, 0.99), (0.3, 0.0), (-0.1, 0.5)])
def test_partition_measure_refuses_points_outside_the_half(x, y):
    """Outside H the fan was decided on the canonical triangle but measured on the stencil
    as given: (0.7, 0.3) gave 16.09 degrees where its partition has 23.20 (review)."""
    with pytest.raises(ValueError, match=r"point 0 .* is outside the diagram's half H"):
        dg.partition_measure([x], [y], "7t-qd", "min", over="all")
    p = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, 0.5]])
    (u, v), = dg.to_diagram(p)
    assert dg.partition_measure([u], [v], "7t-qd", "min", over="all")[0] == pytest.approx(
        quality.min_angles(*partition(p, "7t-qd")).min(), abs=1e-9)
