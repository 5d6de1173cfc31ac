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


def test_stencil_labels_are_spelled_only_in_the_stencil_modules():
    """Every stencil fact lives in ``stencil.py``/``schemes.py``: no other source module
    spells a triangle or a point list of the seven-triangle stencil (three or more distinct
    point names as one string literal, e.g. ``"MDP"``); they take them from there."""
    import ast
    from pathlib import Path

    import qdrefine

    names = set(SEVEN.names)
    root = Path(qdrefine.__file__).parent
    found = []
    for path in sorted(root.rglob("*.py")):
        if path.name in ("stencil.py", "schemes.py"):
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            value = getattr(node, "value", None) if isinstance(node, ast.Constant) else None
            if (isinstance(value, str) and len(value) >= 3 and set(value) <= names
                    and len(set(value)) == len(value)):
                found.append(f"{path.relative_to(root)}:{node.lineno} {value!r}")
    assert found == []
