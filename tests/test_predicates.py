"""The exact predicates against rational arithmetic."""

from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from oracle import exact, orient
from qdrefine.predicates import congruent, form_sign, new_scratch, orient_sign, orient_signs
from shapes import coordinate

points = st.tuples(coordinate, coordinate)
small = st.integers(-20, 20)


def sign(x) -> int:
    return (x > 0) - (x < 0)


@settings(max_examples=600, deadline=None)
@given(points, points, points)
def test_orient_sign_is_exact(a, b, c):
    expected = sign(orient(exact(a), exact(b), exact(c)))
    assert orient_sign(*a, *b, *c, new_scratch()) == expected


@settings(max_examples=600, deadline=None)
@given(points, points, points, small, small, small)
def test_form_sign_is_exact(a, b, c, kuu, kww, kuw):
    ea, eb, ec = exact(a), exact(b), exact(c)
    u = (eb[0] - ea[0], eb[1] - ea[1])
    w = (ec[0] - ea[0], ec[1] - ea[1])
    value = kuu * (u[0] ** 2 + u[1] ** 2) + kww * (w[0] ** 2 + w[1] ** 2) \
        + kuw * (u[0] * w[0] + u[1] * w[1])
    assert form_sign(*a, *b, *c, float(kuu), float(kww), float(kuw), new_scratch()) == sign(value)


def test_collinear_points_off_the_float_grid():
    # points on the line y = x / 3 rounded to floats: the float filter cannot decide these
    buf = new_scratch()
    rng = np.random.default_rng(1)
    for _ in range(2000):
        x = rng.uniform(-1e3, 1e3, size=3)
        pts = [(xi, xi / 3) for xi in x]
        expected = sign(orient(*(exact(p) for p in pts)))
        assert orient_sign(*pts[0], *pts[1], *pts[2], buf) == expected


def test_exact_tie_of_squared_lengths():
    buf = new_scratch()
    # |b - a| = |c - a| exactly, with non-representable-looking coordinates
    a, b, c = (0.1, 0.2), (0.1 + 0.3, 0.2), (0.1, 0.2 + 0.3)
    ea, eb, ec = exact(a), exact(b), exact(c)
    expected = sign((eb[0] - ea[0]) ** 2 + (eb[1] - ea[1]) ** 2
                    - (ec[0] - ea[0]) ** 2 - (ec[1] - ea[1]) ** 2)
    assert form_sign(*a, *b, *c, 1.0, -1.0, 0.0, buf) == expected
    assert form_sign(0.0, 0.0, 3.0, 4.0, 5.0, 0.0, 1.0, -1.0, 0.0, buf) == 0
    assert Fraction(0) == 0


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(points, points, points), min_size=1, max_size=20))
def test_orient_signs_matches_orient_sign(tris):
    """The vectorized orientation (inline filter) agrees with the exact oracle, collinear
    triples included."""
    pts = np.array([p for t in tris for p in t], dtype=np.float64)
    idx = np.arange(len(pts)).reshape(-1, 3)
    expected = [sign(orient(exact(a), exact(b), exact(c))) for a, b, c in tris]
    assert orient_signs(pts, idx).tolist() == expected
    line = np.array([[x, x / 3] for t in tris for x in (t[0][0], t[1][0], t[2][0])])
    expected = [sign(orient(*(exact(p) for p in line[i]))) for i in idx]
    assert orient_signs(line, idx).tolist() == expected


lattice = st.builds(lambda i, e: i * 2.0**e, st.integers(-8, 8), st.integers(-60, 60))
anywhere = st.one_of(points, st.tuples(lattice, lattice))


@settings(max_examples=600, deadline=None)
@given(anywhere, anywhere, anywhere, anywhere, st.booleans())
def test_congruent_proves_equal_lengths(a, b, c, d, mirror):
    """``congruent`` never claims a tie that is not one; it finds a lattice's mirrored legs."""
    if mirror:  # d - c = (b - a) with the coordinates swapped and a sign flipped, exactly
        d = (c[0] + (a[1] - b[1]), c[1] + (b[0] - a[0]))
    ea, eb, ec, ed = exact(a), exact(b), exact(c), exact(d)
    tie = (eb[0] - ea[0]) ** 2 + (eb[1] - ea[1]) ** 2 == (ed[0] - ec[0]) ** 2 + (ed[1] - ec[1]) ** 2
    if congruent(*a, *b, *c, *d):
        assert tie


def test_congruent_finds_the_ties_of_a_grid():
    h = 0.1
    for i in range(1, 30):  # the legs of the right isosceles triangles of a structured grid
        x, y = i * h, (i + 1) * h
        assert congruent(x, x, y, x, x, x, x, y)
        assert congruent(y, y, x, y, y, x, y, y)
