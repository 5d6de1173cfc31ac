"""Triangle families for tests: random, needles, caps, right, isosceles, near-equilateral."""

from __future__ import annotations

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st

from qdrefine.predicates import orient_signs

FAMILIES = ("random", "needle", "cap", "right", "isosceles", "equilateral", "grid")


def apex(family: str, rng: np.random.Generator) -> tuple[float, float]:
    """Apex (x, y) of a triangle with base (0,0)-(1,0) in the given family."""
    if family == "needle":
        return rng.uniform(-0.2, 1.2), 10.0 ** rng.uniform(-8, -2)
    if family == "cap":
        return rng.uniform(0.3, 0.7), 10.0 ** rng.uniform(-6, -1)
    if family == "right":
        t = rng.uniform(0.05, np.pi - 0.05)
        return 0.5 + 0.5 * np.cos(t), 0.5 * np.sin(t)
    if family == "isosceles":
        return 0.5, 10.0 ** rng.uniform(-3, 1)
    if family == "equilateral":
        return 0.5 + rng.normal(0, 1e-6), np.sqrt(3) / 2 + rng.normal(0, 1e-6)
    if family == "grid":
        return rng.integers(-3, 4) / 4, rng.integers(1, 5) / 4
    return rng.uniform(-1, 2), rng.uniform(1e-3, 2)


def family_triangles(n: int, seed: int = 0) -> np.ndarray:
    """``(n, 3, 2)`` triangles cycling through :data:`FAMILIES`, each moved by a random
    similarity (grid ones by an exact one), vertices in random order."""
    rng = np.random.default_rng(seed)
    out = np.empty((n, 3, 2))
    for i in range(n):
        fam = FAMILIES[i % len(FAMILIES)]
        x, y = apex(fam, rng)
        tri = np.array([[0.0, 0.0], [1.0, 0.0], [x, y]])
        if fam == "grid":
            tri = tri * 12 + rng.integers(-5, 5, size=2)
            tri = tri[:, ::-1] if rng.random() < 0.5 else tri
        else:
            a = rng.uniform(0, 2 * np.pi)
            rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
            tri = tri @ rot.T * 10.0 ** rng.uniform(-3, 3) + rng.normal(0, 10, size=2)
        out[i] = tri[rng.permutation(3)]
    keep = orient_signs(out.reshape(-1, 2), np.arange(3 * n).reshape(-1, 3)) != 0
    return out[keep]


coordinate = st.one_of(
    st.integers(-6, 6).map(float),
    st.floats(-100, 100, allow_nan=False, allow_infinity=False, width=64).filter(
        lambda x: x == 0 or abs(x) >= 1e-100),  # the documented exact range
    st.sampled_from([0.1, 0.2, 0.3, 1 / 3, 2 / 3, 0.5, np.sqrt(3) / 2, 1e-9, 1 - 1e-12]),
)


@st.composite
def triangles(draw) -> np.ndarray:
    """A non-degenerate triangle ``(3, 2)`` in either orientation, often with exact ties."""
    tri = np.array([[draw(coordinate), draw(coordinate)] for _ in range(3)])
    assume(orient_signs(tri, np.array([[0, 1, 2]]))[0] != 0)
    return tri


def triangle_set(points: np.ndarray, tris: np.ndarray) -> set[tuple]:
    """Triangles as coordinate tuples, rotated to start at their smallest vertex."""
    out = set()
    for t in tris:
        pts = [tuple(points[i].tolist()) for i in t]
        r = pts.index(min(pts))
        out.add(tuple(pts[r:] + pts[:r]))
    return out
