"""The stencil's forms against direct rational geometry."""

from fractions import Fraction as F

import numpy as np
import pytest

from oracle import incircle, seven_points, sq
from qdrefine.stencil import SEVEN, incircle_form, sqdist_form

rng = np.random.default_rng(7)
SHAPES = [(F(float(x)), F(float(y))) for x, y in rng.uniform([-1, 0.05], [2, 2], size=(25, 2))]
NAMES = SEVEN.names


def frame(o):
    m, n = (F(0), F(0)), (F(1), F(0))
    uu, ww, uw = F(1), o[0] ** 2 + o[1] ** 2, o[0]
    return m, n, uu, ww, uw


@pytest.mark.parametrize("o", SHAPES)
def test_squared_distance_forms(o):
    m, n, uu, ww, uw = frame(o)
    s = seven_points(m, n, o)
    for p in NAMES:
        for q in NAMES:
            a, b, c = sqdist_form(SEVEN, p, q)
            assert a * uu + b * ww + c * uw == sq(s[p], s[q])


@pytest.mark.parametrize("o", SHAPES[:6])
def test_incircle_forms(o):
    m, n, uu, ww, uw = frame(o)
    s = seven_points(m, n, o)
    cross = o[1]  # (N - M) x (O - M)
    for quad in ("DCBO", "CBOA", "BOAD", "OADC", "ADCB", "MDPA", "CQBN", "MNOD"):
        a, b, c = incircle_form(SEVEN, *quad)
        expected = incircle(*(s[x] for x in quad))
        assert cross * (a * uu + b * ww + c * uw) == expected
