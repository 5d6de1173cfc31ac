"""Self-checks of the geometry robustness study's instruments (docs/robustness.md).

The study is a benchmark, not part of the product: the product's tests (``tests/``) never
import it. Its instruments are checked here, by ``python -m pytest benchmarks/robustness``,
which ``python benchmarks/robustness/study.py`` runs before it measures anything.

Exact signs against fractions.Fraction, the exact 7T-QD reference against the independent
oracle of tests/oracle.py, the float decision on easy and hard shapes, the triangulation
checks on hand-made cases, the exhibited SciPy failures, and refinement checks that must
catch a known bad case.
"""

import sys
from fractions import Fraction as F
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[2]
sys.path[:0] = [str(ROOT / "benchmarks"), str(ROOT / "tests")]  # the study; the oracles

from oracle import canonical as oracle_canonical  # noqa: E402
from oracle import exact as exact_point  # noqa: E402
from oracle import incircle, orient, qd_triangles, seven_points  # noqa: E402
from qdrefine import partition, partition_many  # noqa: E402
from robustness import (  # noqa: E402
    bad_input,
    checks,
    exact,
    exhibit,
    families,
    local,
    naive,
    refinement,
    report,
    rows,
)
from shapes import family_triangles, triangles  # noqa: E402

finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False, width=64)


def _frac(p):
    return (F(float(p[0])), F(float(p[1])))


def _sign(x):
    return (x > 0) - (x < 0)


# ----------------------------------------------------------------------------------------
# exact arithmetic


@given(st.lists(st.tuples(finite, finite), min_size=3, max_size=3))
@settings(max_examples=100, deadline=None)
def test_as_integers_is_exact(pts):
    x = np.array(pts)[None]
    ints, ex = exact.as_integers(x)
    for (a, b), (ia, ib) in zip(x[0], ints[0], strict=True):
        assert F(ia) * F(2) ** int(ex[0]) == F(a)
        assert F(ib) * F(2) ** int(ex[0]) == F(b)


@st.composite
def near_collinear(draw):
    """Three points on a line, the last rounded and nudged by a few ulps."""
    a = np.array([draw(finite), draw(finite)])
    b = np.array([draw(finite), draw(finite)])
    t = draw(st.floats(-2, 3))
    c = a + t * (b - a)
    c = c + draw(st.integers(-3, 3)) * np.spacing(c)
    return a, b, c


@given(near_collinear())
@settings(max_examples=300, deadline=None)
def test_orient_sign_matches_fractions(abc):
    a, b, c = abc
    assert exact.orient_sign(a, b, c) == _sign(orient(_frac(a), _frac(b), _frac(c)))


@st.composite
def near_cocircular(draw):
    """Four points on a circle (rounded), the last nudged by a few ulps."""
    cx, cy = draw(finite), draw(finite)
    r = draw(st.floats(1e-3, 1e3))
    ang = [draw(st.floats(0, 2 * np.pi)) for _ in range(4)]
    p = [np.array([cx + r * np.cos(t), cy + r * np.sin(t)]) for t in ang]
    p[3] = p[3] + draw(st.integers(-3, 3)) * np.spacing(p[3])
    return p


@given(near_cocircular())
@settings(max_examples=300, deadline=None)
def test_incircle_sign_matches_fractions(p):
    want = _sign(incircle(*(_frac(q) for q in p)))
    assert exact.incircle_sign(*p) == want


def test_incircle_sign_exact_ties():
    # integer points on the circle x^2 + y^2 = 25
    a, b, c, d = (np.array(q, float) for q in ((5, 0), (3, 4), (-4, 3), (0, -5)))
    assert exact.incircle_sign(a, b, c, d) == 0
    assert exact.incircle_sign(a, b, c, np.array([0.0, -5 + 2**-50])) == 1
    assert exact.orient_sign(np.zeros(2), np.array([3.0, 3]), np.array([1e15, 1e15])) == 0


def _oracle_set(v):
    """tests/oracle.py's 7T-QD as a set of sorted local index triples (partition order)."""
    pts = [exact_point(p) for p in v]
    m, n, o = oracle_canonical(pts)
    named = seven_points(m, n, o)
    local_pts = exact.fraction_points(np.asarray(v))
    index = {q: i for i, q in enumerate(local_pts)}
    return frozenset(tuple(sorted(index[named[c]] for c in t)) for t in qd_triangles(m, n, o))


def _key_sets(tris):
    return [frozenset(tuple(sorted(t)) for t in row.tolist()) for row in tris]


def test_exact_reference_matches_oracle_on_families():
    v = family_triangles(400, seed=5)
    ref = _key_sets(exact.qd_reference(v)["triangles"])
    for i in range(len(v)):
        assert ref[i] == _oracle_set(v[i])
        if i % 7 == 0:
            assert exact.fraction_partition(v[i]) == ref[i]


@given(st.lists(triangles(), min_size=20, max_size=20))
@settings(max_examples=10, deadline=None)
def test_exact_reference_and_qdrefine_match_oracle(vs):
    """Exact ties are frequent here (small integers, repeated coordinates)."""
    v = np.array(vs)
    ref = _key_sets(exact.qd_reference(v)["triangles"])
    got = _key_sets(partition_many(v, "7t-qd", strict=False)[1])
    for i in range(len(v)):
        assert ref[i] == got[i] == _oracle_set(v[i])


def test_exact_reference_on_tie_curve_sends_tie_to_case_one():
    # O = (2/15, 4/15) lies on |AB| = |OD|, the circle (x - 1/3)^2 + y^2 = 1/9
    v = np.array([[0, 0], [15 * 81, 0], [2 * 81, 4 * 81]], dtype=float)
    ref = exact.qd_reference(v[None])
    assert ref["case_tie"][0] and ref["case"][0] == 0
    assert exact.qd_reference((v - [[0, 0], [0, 0], [0, 1]])[None])["case"][0] != 0  # inside


# ----------------------------------------------------------------------------------------
# the float decision


def test_naive_points_are_qdrefine_points():
    v = family_triangles(500, seed=2)
    assert np.array_equal(naive.naive_qd(v)["points"], partition_many(v, "7t-qd", strict=False)[0])


@given(st.lists(st.tuples(st.floats(-10, 10), st.floats(-10, 10)), min_size=3, max_size=3))
@settings(max_examples=150, deadline=None)
def test_naive_agrees_with_exact_away_from_ties(pts):
    v = np.array(pts)
    fv = [_frac(p) for p in v]
    area = abs(orient(*fv))
    scale = max(max(abs(c) for c in p) for p in fv) + 1
    assume(area > F(1, 100) * scale**2)
    m, n, o = oracle_canonical(fv)
    s = seven_points(m, n, o)

    def d2(p, q):
        return (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2

    lengths = sorted(d2(fv[i], fv[j]) for i, j in ((0, 1), (0, 2), (1, 2)))
    margins = [abs(d2(s["O"], s["D"]) - d2(s["A"], s["B"])),
               abs(d2(s["O"], s["C"]) - d2(s["B"], s["D"])),
               lengths[2] - lengths[1], lengths[1] - lengths[0]]
    assume(min(margins) > F(1, 10**6) * scale**2)
    got = _key_sets(naive.naive_qd(v[None])["triangles"])[0]
    assert got == _key_sets(exact.qd_reference(v[None])["triangles"])[0]


def test_naive_differs_near_ties_but_stays_valid():
    b = families.make("near-tie", "far", 1500, seed=0)
    q = rows.qd_row(b.vertices, n_fraction=5)
    assert q["naive_differs"] > 0  # the float decision does err here
    assert q["naive_invalid_not_qdrefine"] == 0
    assert q["qdrefine_vs_exact"] == 0 and q["fraction_agree"] == q["fraction_checked"]


def test_order_dependence_detects_a_dependent_rule():
    v = family_triangles(200, seed=3)

    def first_vertex_fan(w):  # not symmetric: depends on which vertex is listed first
        return local.qd_triangles(np.zeros(len(w), int), np.ones(len(w), int),
                                  np.full(len(w), 2), np.zeros(len(w), int))

    assert naive.order_dependent(v, first_vertex_fan).all()
    assert not naive.order_dependent(v, lambda w: partition_many(w, "7t-qd", strict=False)[1]).any()


# ----------------------------------------------------------------------------------------
# triangulation checks


def _square():
    pts = np.array([[0, 0], [2, 0], [2, 2], [0, 2], [1, 0]], float)[None]
    hull = checks.hull_boundary(pts)
    return pts, hull


def test_hull_boundary_keeps_collinear_points():
    pts, hull = _square()
    edges = {tuple(e) for e in np.argwhere(hull[0]).tolist()}
    assert edges == {(0, 4), (4, 1), (1, 2), (2, 3), (3, 0)}


@pytest.mark.parametrize("tris, flag", [
    ([[0, 4, 3], [4, 1, 2], [4, 2, 3]], None),
    ([[0, 4, 3], [4, 1, 2]], "not_tiling hull"),  # a gap
    ([[0, 4, 3], [4, 1, 2], [4, 2, 3], [4, 2, 3]], "not_tiling hull"),  # overlap
    ([[0, 1, 3], [1, 2, 3]], "missing"),  # point 4 left out (a T-junction)
    ([[0, 3, 4], [4, 1, 2], [4, 2, 3]], "inverted"),
    ([[0, 4, 1], [0, 1, 2], [0, 2, 3]], "zero_area"),
])
def test_triangulation_flags(tris, flag):
    pts, hull = _square()
    f = checks.triangulation_flags(pts, np.array([tris]), {"hull": hull})
    raised = {k for k, v in f.items() if k != "n_triangles" and v[0]}
    if flag is None:
        assert not raised
    else:
        assert flag in raised
    if flag == "missing":
        assert "not_tiling hull" in raised


def test_not_delaunay_flag():
    pts = np.array([[0, 0], [4, 0], [4, 1], [0, 1.5]], float)[None]
    hull = checks.hull_boundary(pts)
    good = checks.triangulation_flags(pts, np.array([[[0, 1, 2], [0, 2, 3]]]), {"h": hull})
    bad = checks.triangulation_flags(pts, np.array([[[0, 1, 3], [1, 2, 3]]]), {"h": hull})
    assert bool(good["not_delaunay"][0]) != bool(bad["not_delaunay"][0])


def test_seven_triangles_for_nine_boundary_points():
    """A triangulation of n points with h on the hull boundary has 2n - h - 2 triangles;
    the nine exact stencil points all lie on the boundary, so 7."""
    b = families.make("exact-lattice", "near", 200, seed=1)
    pts, tris = partition_many(b.vertices, "7t-d")
    hull = checks.hull_boundary(pts)
    assert (hull.any(axis=2).sum(axis=1) == 9).all()
    assert 2 * 9 - 9 - 2 == 7 == tris.shape[1]
    ccw = exact.orient_sign(b.vertices[:, 0], b.vertices[:, 1], b.vertices[:, 2]) > 0
    gon = checks.cycle_boundary(local.ninegon(ccw), 9)
    assert (hull == gon).all()
    f = checks.triangulation_flags(pts, tris, {"hull": hull})
    assert not (f["not_tiling hull"] | f["not_delaunay"] | f["missing"]).any()


def test_exact_families_have_exact_points_and_are_seeded():
    for fam in families.EXACT:
        a = families.make(fam, "far", 300, seed=4)
        b = families.make(fam, "far", 300, seed=4)
        assert np.array_equal(a.vertices, b.vertices)
        v = a.vertices
        pts = naive.nine_points(v)
        for i, j in ((0, 1), (0, 2), (1, 2)):
            for k in (local.NEAR[i, j], local.NEAR[j, i]):
                assert (exact.orient_sign(v[:, i], v[:, j], pts[:, k]) == 0).all()
        for t in range(0, 300, 30):  # the stored points are the exact trisection points
            assert [_frac(q) for q in pts[t]] == exact.fraction_points(v[t])


# ----------------------------------------------------------------------------------------
# the exhibits and refinement


def test_exhibited_scipy_failures_are_real():
    from scipy.spatial import Delaunay

    c = exhibit.find_collinear()
    p = np.array(c["points"])
    s = Delaunay(p).simplices
    flat = [t for t in s if orient(*(_frac(p[i]) for i in t)) == 0]
    assert flat, "SciPy no longer returns a collinear triangle on this set"
    d = exhibit.find_dropped()
    p = np.array(d["points"])
    assert (p == np.round(p)).all()  # integer points: every collinear triple is exact
    assert len(set(Delaunay(p).simplices.ravel().tolist())) < 9
    assert len(partition(np.array(d["vertices"]), "7t-d")[1]) == 7


def test_refinement_checks_catch_rounded_collapse():
    bad = np.array([[[0, 0], [1, 0], [0.5, 1e-9]]]) + 1e7
    out = refinement.study(bad, "7t-qd", levels=1)
    assert out["levels"][0]["zero_area"] == 1
    good = families.make("exact-lattice", "far", 3, seed=2).vertices
    out = refinement.study(good, "7t-qd", levels=2)
    for lv in out["levels"]:
        assert lv["non_conforming"] == lv["zero_area"] == lv["inverted"] == 0
        assert lv["area_changed"] == 0


def test_page_is_generated_from_the_committed_results():
    """docs/robustness.md is exactly what the report code makes of results.json (regenerate
    both with ``python benchmarks/robustness/study.py``), bad_input.json and the latest
    fuzzing run, and its figure exists."""
    import json

    root = ROOT
    results = json.loads((root / "benchmarks/robustness/results.json").read_text())
    page = report.markdown(results, root / "docs/robustness.md", root / "docs/img/robustness",
                           root / "benchmarks/robustness/results.json")
    hostile = json.loads((root / "benchmarks/robustness/bad_input.json").read_text())
    # section 4 (python benchmarks/robustness/bad_input.py) from its own results
    page = bad_input.splice(page, bad_input.section(hostile))
    # section 5 (python benchmarks/fuzz_run.py) from the latest fuzzing run
    import fuzz_run

    latest = sorted((root / "benchmarks/results").glob("fuzz-*.json"))[-1]
    page = bad_input.splice(page, fuzz_run.section(json.loads(latest.read_text()), latest.name),
                            fuzz_run.START, fuzz_run.END)
    assert page == (root / "docs/robustness.md").read_text()
    assert (root / "docs/img/robustness/scipy_failures.png").stat().st_size > 10_000


def test_wilson_interval():
    lo, hi = report.wilson(0, 1000)
    assert lo == 0 and 0.003 < hi < 0.004
    lo, hi = report.wilson(50, 100)
    assert lo < 0.5 < hi and abs((lo + hi) / 2 - 0.5) < 1e-12
