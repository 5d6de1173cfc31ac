"""Seeded families of hard triangles, each in two placements.

Shapes are drawn in the paper's frame ``M = (0, 0)``, ``N = (1, 0)``, apex ``O = (x, y)``:

* ``needle``            one short edge: ``O = N + s (cos p, sin p)``, ``s = 10^U(-8, -1)``
                        (smallest angle down to about 1e-8 rad)
* ``cap``               one angle near pi: ``O = (U(0.02, 0.98), 10^U(-8, -1))``
* ``near-equilateral``  ``O`` within ``10^U(-16, -2)`` of ``(1/2, sqrt(3)/2)``
* ``near-right``        ``O`` on Thales' circle over ``MN``, radius off by ``10^U(-16, -2)``
* ``near-tie``          ``O`` on a curve where a decision ties (co-circular or equal-length
                        points: :data:`TIE_FORMS`), moved off it by ``10^U(-17, -3)`` or not
* ``exact-tie``         ``O`` *exactly* on such a curve at a rational point; integer
                        coordinates (times 81 = 3^4), so all points of 4 levels are exact
* ``exact-lattice``     integer triangles (times 81) with angles down to about 1e-8 rad

Placements: ``near`` (random rotation, size ``10^U(-12, 12)``, near the origin) and ``far``
(also translated by ``10^U(2, 9)`` sizes). The exact families use exact moves only
(dihedral and Pythagorean rotations, powers of two, lattice translations, keeping every
integer below 2^50), so their far translation is limited to what stays exact.
Triangles whose float coordinates are collinear after placement are dropped and counted.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction
from math import gcd, isqrt

import numpy as np
from numpy.typing import NDArray

from .exact import orient_sign

FAMILIES = ("needle", "cap", "near-equilateral", "near-right", "near-tie", "exact-tie",
            "exact-lattice")
PLACEMENTS = ("near", "far")
EXACT = {"exact-tie", "exact-lattice"}

#: Every tie of the decisions, as forms ``(kuu, kww, kuw)`` in ``(|MN|^2, |MO|^2, MN.MO)``:
#: the 7T-QD and 7T-D forms of qdrefine's registry and the labelling ties.
TIE_FORMS = {
    "7t-qd |AB|=|OD| (I/II)": (0, 3, -2),
    "7t-qd |BD|=|OC| (II/III)": (4, 5, -12),
    "7t-d shaded arc": (-2, -3, 6),
    "7t-d (x-2/3)^2+y^2=1/9": (1, 3, -4),
    "7t-d x^2+y^2=1/3": (-1, 3, 0),
    "x=1/2 (|OM|=|ON|, 7t-d, 7t-le)": (1, 0, -2),
    "|ON|=|MN|": (0, 1, -2),
}


@dataclass
class Batch:
    """Triangles ``vertices (K, 3, 2)`` of one family and placement."""

    family: str
    placement: str
    vertices: NDArray[np.float64]
    exact_points: bool
    generated: int
    dropped: int = 0
    curves: list[str] = field(default_factory=list)


def curve(form: tuple[int, int, int]) -> tuple[Fraction, Fraction | None]:
    """``kuu + kww (x^2 + y^2) + kuw x = 0`` as ``(centre, radius^2)`` of a circle centred
    on the x axis, or ``(x, None)`` for a vertical line."""
    kuu, kww, kuw = (Fraction(k) for k in form)
    if kww == 0:
        return -kuu / kuw, None
    c = -kuw / (2 * kww)
    return c, c * c - kuu / kww


def in_half(x: NDArray, y: NDArray) -> NDArray[np.bool_]:
    """The left half ``H`` of the mapping diagram: ``x <= 1/2, y > 0, (x-1)^2 + y^2 <= 1``."""
    return (x <= 0.5) & (y > 0) & ((x - 1) ** 2 + y**2 <= 1)


# ----------------------------------------------------------------------------------------
# float shapes


def _needle(rng, n):
    s, p = 10.0 ** rng.uniform(-8, -1, n), rng.uniform(0.4, np.pi - 0.4, n)
    return np.stack([1 + s * np.cos(p), s * np.sin(p)], axis=1)


def _cap(rng, n):
    return np.stack([rng.uniform(0.02, 0.98, n), 10.0 ** rng.uniform(-8, -1, n)], axis=1)


def _equilateral(rng, n):
    a = rng.uniform(0, 2 * np.pi, n)
    r = 10.0 ** rng.uniform(-16, -2, n)
    return np.stack([0.5 + r * np.cos(a), np.sqrt(3) / 2 + r * np.sin(a)], axis=1)


def _right(rng, n):
    t = rng.uniform(0.02, np.pi - 0.02, n)
    r = 0.5 * (1 + rng.choice([-1, 1], n) * 10.0 ** rng.uniform(-16, -2, n))
    return np.stack([0.5 + r * np.cos(t), r * np.sin(t)], axis=1)


def _near_tie(rng, n, names):
    out = np.empty((n, 2))
    which = rng.integers(0, len(names), n)
    for i, name in enumerate(names):
        sel = np.flatnonzero(which == i)
        out[sel] = _on_curve(rng, TIE_FORMS[name], len(sel))
    delta = rng.choice([-1, 1], n) * 10.0 ** rng.uniform(-17, -3, n)
    delta[rng.random(n) < 0.2] = 0.0
    centre = np.array([float(curve(TIE_FORMS[nm])[0]) for nm in names])[which]
    line = np.array([curve(TIE_FORMS[nm])[1] is None for nm in names])[which]
    normal = np.where(line[:, None], [1.0, 0.0], out - np.stack([centre, 0 * centre], axis=1))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    return out + delta[:, None] * normal


def _on_curve(rng, form, n):
    c, r2 = curve(form)
    pts = np.empty((0, 2))
    while len(pts) < n:
        if r2 is None:
            p = np.stack([np.full(4 * n, float(c)), rng.uniform(0, 1, 4 * n)], axis=1)
        else:
            a = rng.uniform(0, np.pi, 4 * n)
            r = np.sqrt(float(r2))
            p = np.stack([float(c) + r * np.cos(a), r * np.sin(a)], axis=1)
        pts = np.concatenate([pts, p[in_half(p[:, 0], p[:, 1])]])
    return pts[:n]


def tie_curves() -> list[str]:
    """Names of :data:`TIE_FORMS` whose curve meets the interior of ``H``."""
    out = []
    for name, form in TIE_FORMS.items():
        c, r2 = curve(form)
        if r2 is not None and r2 <= 0:
            continue
        a = np.linspace(0, np.pi, 2001)[1:-1]
        if r2 is None:
            x, y = np.full(a.size, float(c)), np.linspace(0, 1, a.size)
        else:
            x, y = float(c) + np.sqrt(float(r2)) * np.cos(a), np.sqrt(float(r2)) * np.sin(a)
        if in_half(x, y).any():
            out.append(name)
    return out


# ----------------------------------------------------------------------------------------
# exact (integer) shapes


def rational_curves() -> list[str]:
    """Tie curves of ``H`` with rational points: lines and circles of rational radius."""
    out = []
    for name in tie_curves():
        c, r2 = curve(TIE_FORMS[name])
        if r2 is None or (_is_square(r2.numerator) and _is_square(r2.denominator)):
            out.append(name)
    return out


def _is_square(k: int) -> bool:
    return k >= 0 and isqrt(k) ** 2 == k


def _rational_point(rng, form) -> tuple[Fraction, Fraction] | None:
    c, r2 = curve(form)
    for _ in range(200):
        p, q = (int(t) for t in rng.integers(1, 65, 2))
        if r2 is None:
            x, y = c, Fraction(p, q)
        else:
            r = Fraction(isqrt(r2.numerator), isqrt(r2.denominator))
            d = p * p + q * q
            x, y = c + r * Fraction(q * q - p * p, d), r * Fraction(2 * p * q, d)
        if x <= Fraction(1, 2) and y > 0 and (x - 1) ** 2 + y**2 <= 1:
            return x, y
    return None


def _exact_tie(rng, n, names) -> NDArray[np.int64]:
    out = []
    while len(out) < n:
        name = names[rng.integers(0, len(names))]
        pt = _rational_point(rng, TIE_FORMS[name])
        if pt is None:
            continue
        x, y = pt
        den = x.denominator * y.denominator // gcd(x.denominator, y.denominator)
        out.append([[0, 0], [den, 0], [int(x * den), int(y * den)]])
    return 81 * np.array(out, dtype=np.int64)


def _exact_lattice(rng, n) -> NDArray[np.int64]:
    big = np.round(2.0 ** rng.uniform(4, 27, n)).astype(np.int64)
    x = np.round(rng.uniform(-1, 2, n) * big).astype(np.int64)
    y = np.maximum(1, np.round(big * 10.0 ** rng.uniform(-8, 0.3, n))).astype(np.int64)
    tri = np.zeros((n, 3, 2), dtype=np.int64)
    tri[:, 1, 0] = big
    tri[:, 2, 0], tri[:, 2, 1] = x, y
    return 81 * tri


def _triples(limit: int = 1024) -> NDArray[np.int64]:
    out = []
    for m in range(2, isqrt(limit) + 1):
        for k in range(1, m):
            if (m - k) % 2 and gcd(m, k) == 1 and m * m + k * k <= limit:
                out.append((m * m - k * k, 2 * m * k, m * m + k * k))
    return np.array(out, dtype=np.int64)


_LIMIT = 2**50


def place_exact(rng, tri: NDArray[np.int64], placement: str) -> NDArray[np.float64]:
    """Exact moves of integer triangles ``(n, 3, 2)`` (multiples of 81): rotations by
    Pythagorean triples and by the dihedral group, a lattice translation (``far``: large),
    vertex order, and a power of two bringing the size to about ``10^U(-12, 12)``."""
    n = len(tri)
    t = tri - tri[:, :1]
    trip = _triples()[rng.integers(0, len(_triples()), n)]
    a, b = trip[:, 0, None], trip[:, 1, None]
    room = 2**44 if placement == "near" else 2**48 / 1000  # far: room for 10^2 sizes
    use = (rng.random(n) < 0.75) & (np.abs(t).max(axis=(1, 2)) * trip[:, 2] < room)
    x, y = t[..., 0], t[..., 1]
    t = np.where(use[:, None, None], np.stack([a * x - b * y, b * x + a * y], axis=-1), t)
    rot = rng.integers(0, 4, n)
    for _ in range(3):
        sel = rot > 0
        t[sel] = np.stack([-t[sel][..., 1], t[sel][..., 0]], axis=-1)
        rot -= 1
    flip = rng.random(n) < 0.5
    t[flip] = t[flip][:, :, ::-1]
    size = np.abs(t).max(axis=(1, 2))
    if placement == "far":
        hi = np.log10(_LIMIT / 4)
        lo = np.minimum(np.log10(np.maximum(size, 1)) + 2, hi)
        mag = 10.0 ** rng.uniform(lo, hi, n)
        ang = rng.uniform(0, 2 * np.pi, n)
    else:
        mag, ang = rng.uniform(0, 1, n) * size, rng.uniform(0, 2 * np.pi, n)
    shift = np.stack([np.round(mag * np.cos(ang) / 81), np.round(mag * np.sin(ang) / 81)], 1)
    t = t + 81 * shift.astype(np.int64)[:, None, :]
    assert (np.abs(t) < _LIMIT).all() and (t % 81 == 0).all()
    t = np.take_along_axis(t, np.argsort(rng.random((n, 3)), axis=1)[..., None], axis=1)
    target = rng.uniform(-12, 12, n) * np.log2(10) - np.log2(np.maximum(size, 1))
    return t.astype(np.float64) * 2.0 ** np.round(target)[:, None, None]


def place_float(rng, apex: NDArray[np.float64], placement: str) -> NDArray[np.float64]:
    """Triangles ``(0,0), (1,0), apex`` rotated, scaled by ``10^U(-12, 12)``, translated
    (``far``: by ``10^U(2, 9)`` sizes), vertices in random order."""
    n = len(apex)
    tri = np.zeros((n, 3, 2))
    tri[:, 1, 0] = 1.0
    tri[:, 2] = apex
    a = rng.uniform(0, 2 * np.pi, n)
    rot = np.stack([np.stack([np.cos(a), -np.sin(a)], 1), np.stack([np.sin(a), np.cos(a)], 1)],
                   axis=1)
    s = 10.0 ** rng.uniform(-12, 12, n)
    v = np.einsum("nij,nkj->nki", rot, tri) * s[:, None, None]
    if placement == "far":
        b = rng.uniform(0, 2 * np.pi, n)
        shift = (s * 10.0 ** rng.uniform(2, 9, n))[:, None] * np.stack([np.cos(b), np.sin(b)], 1)
    else:
        shift = s[:, None] * rng.normal(size=(n, 2))
    v = v + shift[:, None, :]
    return np.take_along_axis(v, np.argsort(rng.random((n, 3)), axis=1)[..., None], axis=1)


_SHAPES = {"needle": _needle, "cap": _cap, "near-equilateral": _equilateral,
           "near-right": _right}


def make(family: str, placement: str, n: int, seed: int = 0) -> Batch:
    """``n`` triangles of ``family`` in ``placement``, minus those collinear in float64."""
    if family not in FAMILIES or placement not in PLACEMENTS:
        raise ValueError(f"unknown family/placement {family!r}/{placement!r}; choose from "
                         f"{FAMILIES} and {PLACEMENTS}")
    rng = np.random.default_rng([seed, FAMILIES.index(family), PLACEMENTS.index(placement)])
    curves: list[str] = []
    if family == "exact-tie":
        curves = rational_curves()
        v = place_exact(rng, _exact_tie(rng, n, curves), placement)
    elif family == "exact-lattice":
        v = place_exact(rng, _exact_lattice(rng, n), placement)
    elif family == "near-tie":
        curves = tie_curves()
        v = place_float(rng, _near_tie(rng, n, curves), placement)
    else:
        v = place_float(rng, _SHAPES[family](rng, n), placement)
    keep = orient_sign(v[:, 0], v[:, 1], v[:, 2]) != 0
    return Batch(family, placement, v[keep], family in EXACT, n, int((~keep).sum()), curves)


def describe(v: NDArray[np.float64]) -> dict[str, float]:
    """Ranges actually covered by triangles ``v (K, 3, 2)``: longest edge, smallest angle
    (radians, float64 estimate) and distance from the origin in longest edges."""
    e = np.stack([np.linalg.norm(v[:, (i + 1) % 3] - v[:, (i + 2) % 3], axis=1)
                  for i in range(3)], axis=1)
    longest = e.max(axis=1)
    ang = []
    for i in range(3):
        p, q = v[:, (i + 1) % 3] - v[:, i], v[:, (i + 2) % 3] - v[:, i]
        ang.append(np.abs(np.arctan2(p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0],
                                     (p * q).sum(axis=1))))
    small = np.min(ang, axis=0)
    far = np.abs(v).max(axis=(1, 2)) / longest
    return {"longest_edge_min": float(longest.min()), "longest_edge_max": float(longest.max()),
            "smallest_angle_min": float(small.min()),
            "smallest_angle_median": float(np.median(small)),
            "offset_over_size_max": float(far.max()),
            "offset_over_size_median": float(np.median(far))}
