"""Independent exact oracles in rational arithmetic (fractions.Fraction), written from the
paper's definitions, not from qdrefine's forms or tables."""

from __future__ import annotations

from fractions import Fraction as F

Point = tuple[F, F]


def exact(p) -> Point:
    return (F(float(p[0])), F(float(p[1])))


def sq(p: Point, q: Point) -> F:
    return (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2


def orient(a: Point, b: Point, c: Point) -> F:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def incircle(a: Point, b: Point, c: Point, d: Point) -> F:
    """> 0 iff d is inside the circle through a, b, c, for a, b, c counter-clockwise."""
    rows = [(p[0] - d[0], p[1] - d[1]) for p in (a, b, c)]
    rows = [(x, y, x * x + y * y) for x, y in rows]
    (a1, a2, a3), (b1, b2, b3), (c1, c2, c3) = rows
    return a1 * (b2 * c3 - b3 * c2) - a2 * (b1 * c3 - b3 * c1) + a3 * (b1 * c2 - b2 * c1)


def strictly_inside_circumcircle(tri: tuple[Point, Point, Point], d: Point) -> bool:
    a, b, c = tri
    s = orient(a, b, c)
    return incircle(a, b, c, d) * (1 if s > 0 else -1) > 0


def lerp(a: Point, b: Point, t: F) -> Point:
    return (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))


def lex_less(a: Point, b: Point) -> bool:
    return a < b


def canonical(v: list[Point]) -> tuple[Point, Point, Point]:
    """(M, N, O) by the documented rules: MN longest (tie: lexicographically smaller apex),
    M nearer O (tie: lexicographically smaller)."""
    length = [sq(v[(i + 1) % 3], v[(i + 2) % 3]) for i in range(3)]  # opposite vertex i
    top = max(length)
    o = min((i for i in range(3) if length[i] == top), key=lambda i: v[i])
    j, k = (o + 1) % 3, (o + 2) % 3
    dj, dk = sq(v[o], v[j]), sq(v[o], v[k])
    if dj < dk or (dj == dk and v[j] < v[k]):
        m, n = j, k
    else:
        m, n = k, j
    return v[m], v[n], v[o]


def seven_points(m: Point, n: Point, o: Point) -> dict[str, Point]:
    third, two = F(1, 3), F(2, 3)
    return {
        "M": m, "N": n, "O": o,
        "D": lerp(m, n, third), "C": lerp(m, n, two),
        "Q": lerp(n, o, third), "B": lerp(n, o, two),
        "A": lerp(o, m, third), "P": lerp(o, m, two),
    }


FIXED = ["MDP", "PDA", "CQB", "CNQ"]


def definition1_case(m: Point, n: Point, o: Point) -> str:
    """The paper's Definition 1, with the tie |AB| = |OD| sent to Case I (documented)."""
    s = seven_points(m, n, o)
    ab, od = sq(s["A"], s["B"]), sq(s["O"], s["D"])
    bd, oc = sq(s["B"], s["D"]), sq(s["O"], s["C"])
    if ab <= od:
        return "I"
    if bd < oc:
        return "II"
    return "III"


CASE_TRIANGLES = {
    "I": ["BOA", "BAD", "BDC"],  # 7T-LE: corner at O, then A-D-C-B split by BD
    "II": ["DCB", "DBO", "DOA"],  # D joined to B and O
    "III": ["OAD", "ODC", "OCB"],  # O joined to D and C
}


def qd_triangles(m: Point, n: Point, o: Point) -> list[str]:
    return FIXED + CASE_TRIANGLES[definition1_case(m, n, o)]
