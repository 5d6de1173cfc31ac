"""Mesh construction and validation: messages, and every check against an oracle."""

from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from oracle import exact, orient
from qdrefine import Mesh, check, examples
from qdrefine.predicates import orient_signs
from qdrefine.sweep import CROSSING, sweep

SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
TRIS = np.array([[0, 1, 2], [0, 2, 3]])


def test_valid_mesh_is_read_only_and_normalized():
    mesh = Mesh(SQUARE, TRIS, [1, 2], [[0, 1]], [7])
    assert mesh.triangles.dtype == np.int32 and mesh.points.dtype == np.float64
    with pytest.raises(ValueError):
        mesh.points[0, 0] = 5.0
    assert "4 points, 2 triangles" in repr(mesh)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"points": SQUARE[:, :1]}, r"points must have shape \(N, 2\)"),
        ({"points": np.where(SQUARE == 1, np.nan, SQUARE)}, "point 1 has a non-finite"),
        ({"points": SQUARE * 1e101}, "point 1 has a coordinate .* outside the supported range"),
        ({"triangles": TRIS[:, :2]}, r"triangles must have shape \(M, 3\)"),
        ({"triangles": TRIS * 1.0}, "triangles must hold integers"),
        ({"triangles": np.empty((0, 3), int)}, "no triangles"),
        ({"triangles": [[0, 1, 2], [0, 2, 4]]}, r"triangle 1 \(0, 2, 4\) has a vertex index"),
        ({"triangles": [[0, 1, 2], [0, 3, 2]]}, r"triangle 1 \(0, 3, 2\) is clockwise"),
        ({"triangles": [[0, 1, 2], [0, 2, 0]]}, "triangle 1 .* has zero area"),
        ({"cell_tags": [1]}, r"cell_tags must have shape \(2,\)"),
        ({"edges": [[0, 1]]}, "edges and edge_tags must be given together"),
        ({"edges": [[0, 1]], "edge_tags": [1, 2]}, r"edge_tags must have shape \(1,\)"),
        ({"edges": [[1, 3]], "edge_tags": [1]}, r"edge 0 \(1, 3\) is not an edge"),
        ({"edges": [[1, 9]], "edge_tags": [1]}, r"edge 0 \(1, 9\) has a vertex index"),
        # coerced before (review): a uint64 beyond int64 wrapped to -1, floats were
        # truncated, "21" and (2.7, 1.5) became the key (2, 1)
        ({"cell_tags": np.array([2**64 - 1, 1], np.uint64)}, "cell_tags holds "
                                                             "18446744073709551615, beyond int64"),
        ({"edges": np.array([[0, 2**64 - 1]], np.uint64), "edge_tags": [1]},
         "edges holds 18446744073709551615, beyond int64"),
        ({"origins": [[0.5, 1.7, 2.2], [0, 2, 3]]}, "origins must hold integers, got dtype "
                                                    "float64"),
        ({"physical_names": {"21": "a"}}, r"keys must be \(dimension, tag\) pairs of integers, "
                                          r"got '21'"),
        ({"physical_names": {(2.7, 1.5): "a"}}, r"pairs of integers, got \(2.7, 1.5\)"),
        # taken before (review): strings and booleans as coordinates, masks dropped
        ({"points": SQUARE.astype(str)}, "points must be numbers, got dtype <U32"),
        ({"points": SQUARE.astype(bool)}, "points must be numbers, got dtype bool"),
        ({"triangles": np.ma.array(TRIS, mask=[[0, 0, 0], [1, 1, 1]])},
         "triangles has masked entries"),
        ({"points": np.ma.array(SQUARE, mask=SQUARE == 1)}, "points has masked entries"),
        # an OverflowError before (review)
        ({"points": [[0, 0], [10**400, 0], [1, 1], [0, 1]]}, r"points must be numbers of shape "
                                                            r"\(N, 2\) \(int too large"),
    ],
)
def test_bad_input_names_the_problem(kwargs, message):
    args = {"points": SQUARE, "triangles": TRIS} | kwargs
    with pytest.raises(ValueError, match=message):
        Mesh(**args)


@pytest.mark.parametrize(("triangles", "message"), [
    ([[0, 2, 1], [0, 2, 0]], r"^triangle 0 \(0, 2, 1\) is clockwise"),
    ([[0, 2, 0], [0, 2, 1]], r"^triangle 0 \(0, 2, 0\) has zero area"),
])
def test_the_first_bad_row_is_named_whichever_its_kind(triangles, message):
    """A clockwise row before a zero-area one is named first, as the GPU and Dask paths
    name the first row of either kind (the zero-area one was named first before)."""
    with pytest.raises(ValueError, match=message):
        Mesh(SQUARE, triangles)
    found = check.find(SQUARE, triangles)
    assert [p.kind for p in found.problems if p.kind in ("clockwise", "zero-area")] == \
        (["clockwise", "zero-area"] if "clockwise" in message else ["zero-area", "clockwise"])


def test_points_as_python_numbers_of_any_kind():
    """Object arrays of numbers (Fractions, Python ints) are numbers (review of the check
    that refuses strings and booleans)."""
    from fractions import Fraction

    exact = np.array([[Fraction(v) for v in row] for row in SQUARE.tolist()], dtype=object)
    assert np.array_equal(Mesh(exact, TRIS).points, SQUARE)
    with pytest.raises(ValueError, match="points must be numbers, got dtype object"):
        Mesh(np.array([[0, 0], [1, 0], [1, "1"], [0, 1]], dtype=object), TRIS)


def test_data_must_be_a_mapping():
    with pytest.raises(TypeError, match="point_data must be a mapping of names to arrays, "
                                        "got list"):
        Mesh(SQUARE, TRIS, point_data=[("u", np.zeros(4))])


def test_examples_are_valid():
    mesh = examples.plate_with_hole()
    assert set(np.unique(mesh.edge_tags)) == {examples.OUTER, examples.HOLE}
    assert set(np.unique(mesh.cell_tags)) == {examples.LEFT, examples.RIGHT}
    assert examples.square(3).n_triangles == 18


def test_jittered_square_orders():
    """The three orders are one mesh renumbered: same triangles by coordinates, same tags."""
    def keyed(mesh):
        corners = np.sort(mesh.points[mesh.triangles].reshape(-1, 6), axis=1)
        order = np.lexsort(corners.T)
        return corners[order], mesh.cell_tags[order]

    meshes = [examples.jittered_square(6, seed=3, shuffle=s) for s in ("none", "points", "all")]
    assert not np.array_equal(meshes[0].triangles, meshes[1].triangles)
    for mesh in meshes[1:]:
        for got, expected in zip(keyed(mesh), keyed(meshes[0]), strict=True):
            np.testing.assert_array_equal(got, expected)
        assert sorted(np.bincount(mesh.edge_tags)) == sorted(np.bincount(meshes[0].edge_tags))
    with pytest.raises(ValueError, match="shuffle must be"):
        examples.jittered_square(2, shuffle="some")


# every check against a brute-force oracle in rational arithmetic ---------------------------

def oracle_counts(p: np.ndarray, t: np.ndarray) -> dict[str, int]:
    """Instances of each error kind, by definition (Fractions, dictionaries, all pairs);
    clockwise triangles are flipped first, as the readers do."""
    q = [exact(x) for x in p]
    signs = [orient(q[a], q[b], q[c]) for a, b, c in t]
    tris = [(a, c, b) if s < 0 else (a, b, c) for (a, b, c), s in zip(t.tolist(), signs,
                                                                       strict=True)]
    out = {"zero-area": sum(s == 0 for s in signs), "clockwise": sum(s < 0 for s in signs)}
    used = sorted({v for tri in tris for v in tri})
    out["duplicate-points"] = len(used) - len({q[v] for v in used})
    sides = [(tri[i], tri[(i + 1) % 3]) for tri in tris for i in range(3)]
    undirected = Counter(frozenset(s) for s in sides)
    out["overused-edge"] = sum(c > 2 for c in undirected.values())
    directed = Counter(sides)
    out["folded-edge"] = 0 if out["zero-area"] else sum(
        1 for e, c in undirected.items() if c == 2 and len(e) == 2
        and max(directed[tuple(sorted(e))], directed[tuple(sorted(e))[::-1]]) == 2)
    boundary = [s for s in sides if undirected[frozenset(s)] == 1]
    verts = {v for s in boundary for v in s}
    out["hanging-node"] = sum(
        1 for a, b in boundary for v in verts
        if v not in (a, b) and q[v] not in (q[a], q[b]) and orient(q[a], q[b], q[v]) == 0
        and min(q[a], q[b]) <= q[v] <= max(q[a], q[b]))
    return {k: v for k, v in out.items() if v}


def oracle_overlap(p: np.ndarray, t: np.ndarray) -> bool:
    """Whether the interiors of two triangles intersect (Fractions, all pairs): convex
    triangles have disjoint interiors iff the line of some edge separates them."""
    q = [exact(x) for x in p]
    tris = [[q[v] for v in row] for row in t.tolist()]
    tris = [tri if orient(*tri) > 0 else tri[::-1] for tri in tris]

    def separated(s, u):
        return any(all(orient(s[i], s[(i + 1) % 3], c) <= 0 for c in u) for i in range(3))

    return any(not separated(a, b) and not separated(b, a)
               for i, a in enumerate(tris) for b in tris[i + 1:])


@st.composite
def lattice_meshes(draw):
    """Few points on a small lattice (many collinear and equal points), random triangles."""
    n = draw(st.integers(3, 9))
    p = np.array(draw(st.lists(st.tuples(st.integers(0, 3), st.integers(0, 3)), min_size=n,
                               max_size=n)), dtype=float) * draw(st.sampled_from([1.0, 0.1]))
    t = np.array(draw(st.lists(st.tuples(*[st.integers(0, n - 1)] * 3), min_size=1,
                               max_size=8)), dtype=np.int64)
    return p, t


@settings(max_examples=200, deadline=None)
@given(lattice_meshes())
def test_checks_agree_with_the_oracle(mesh):
    p, t = mesh
    found = check.find(p, t, flip_clockwise=True)
    got = {x.kind: x.count for x in found.problems if x.kind in (
        "zero-area", "clockwise", "duplicate-points", "overused-edge", "folded-edge",
        "hanging-node")}
    expected = oracle_counts(p, t)
    clean = not set(expected) - {"clockwise", "hanging-node"}
    overlapping = {"self-intersection", "overlap"} & {x.kind for x in found.problems}
    if clean and not overlapping:  # the sweep counts every hanging node before a crossing
        assert got == expected
    else:
        got.pop("hanging-node", None)
        expected.pop("hanging-node", None)
        assert got == expected
    if clean:  # the sweep finds an overlap exactly when two triangles overlap
        assert bool(overlapping) == oracle_overlap(p, t), found.problems
    refused = check.find(p, t, stop_at_error=True, warnings=False).errors
    try:
        Mesh(p, t)
    except ValueError as exc:
        assert str(exc) == refused[0].message
    else:
        assert not refused and not oracle_counts(p, t)


def _meets(q, a, b, c, d) -> bool:
    """Segments ab and cd cross inside both, or overlap along a piece (Fractions)."""
    o1, o2 = orient(q[a], q[b], q[c]), orient(q[a], q[b], q[d])
    o3, o4 = orient(q[c], q[d], q[a]), orient(q[c], q[d], q[b])
    if o1 == o2 == 0:
        lo, hi = sorted((q[a], q[b])), sorted((q[c], q[d]))
        return max(lo[0], hi[0]) < min(lo[1], hi[1])
    return o1 * o2 < 0 and o3 * o4 < 0


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 40), st.integers(0, 2**32 - 1))
def test_hanging_node_sweep_matches_all_pairs(n, seed):
    """The plane sweep against all pairs, on non-crossing segments of a lattice (many
    collinear, many touching)."""
    rng = np.random.default_rng(seed)
    points = rng.integers(0, 6, size=(n, 2)).astype(float)
    points = np.unique(points, axis=0)
    k = len(points)
    q = [exact(x) for x in points]
    edges: list[tuple[int, int]] = []
    for a, b in rng.integers(0, k, size=(2 * k, 2)).tolist():
        if a != b and not any(_meets(q, a, b, c, d) for c, d in edges):
            edges.append((a, b))
    count, hits = check.hanging_nodes(points, np.array(edges, dtype=np.int64).reshape(-1, 2))
    verts = {v for e in edges for v in e}
    expected = {(v, r) for r, (a, b) in enumerate(edges) for v in verts
                if v not in (a, b) and orient(q[a], q[b], q[v]) == 0
                and min(q[a], q[b]) < q[v] < max(q[a], q[b])}
    assert count == len(expected)
    assert {tuple(h) for h in hits.tolist()} <= expected


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 30), st.integers(0, 2**32 - 1))
def test_sweep_finds_a_crossing_when_there_is_one(n, seed):
    rng = np.random.default_rng(seed)
    points = np.unique(rng.integers(0, 6, size=(n, 2)).astype(float), axis=0)
    q = [exact(x) for x in points]
    edges = [(a, b) for a, b in rng.integers(0, len(points), size=(n, 2)).tolist() if a != b]
    if not edges:
        return
    crossing = sweep(points, np.array(edges), False, False)[2]
    crossing_pairs = any(
        _meets(q, *edges[i], *edges[j]) and not (
            orient(q[edges[i][0]], q[edges[i][1]], q[edges[j][0]]) == 0
            == orient(q[edges[i][0]], q[edges[i][1]], q[edges[j][1]]))
        for i in range(len(edges)) for j in range(i))
    if crossing[0] == CROSSING:
        assert _meets(q, *edges[crossing[1]], *edges[crossing[2]])
    if crossing_pairs:  # collinear overlaps are ordered by direction, crossings are found
        assert crossing[0] != 0


def test_messages_name_where():
    sq = SQUARE.tolist()
    cases = [
        (sq + [[1.0, 1.0]], [[0, 1, 2], [0, 4, 3]], r"points 2 and 4 are both at \(1.0, 1.0\)"),
        (sq + [[2.0, 0.5]], [[0, 1, 2], [0, 2, 3], [0, 4, 2]],
         r"edge \(0, 2\) is shared by 3 triangles \(0, 1, 2\)"),
        (sq + [[2.0, 0.5]], [[0, 1, 2], [0, 4, 2]],
         r"triangles 0 and 1 lie on the same side of their common edge \(0, 2\)"),
        ([[0, 0], [2, 0], [1, 1], [1, 0], [1, -1]], [[0, 1, 2], [0, 4, 3], [3, 4, 1]],
         r"vertex 3 lies inside edge \(0, 1\) of triangle 0"),
    ]
    for points, tris, message in cases:
        with pytest.raises(ValueError, match=message):
            Mesh(points, tris)


def test_unused_points_are_allowed_and_kept():
    points = np.vstack([SQUARE, [[0.5, 0.5], [1.0, 1.0]]])  # an unused copy of point 2 too
    mesh = Mesh(points, TRIS)
    assert mesh.n_points == 6
    found = check.find(points, TRIS)
    assert found.ok and [p.kind for p in found.problems] == ["unused-points"]
    assert found.problems[0].count == 2


def _soup(kind: str, m: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """``m`` separate triangles: stacked parallel slivers (valid, every bounding box overlaps
    every other), random slivers or small scattered triangles (overlapping), or a fan of
    slivers sharing one vertex (valid)."""
    if kind == "stacked":
        y = rng.permutation(m) * 1e-5
        tri = np.stack([np.stack([np.zeros(m), y], 1), np.stack([np.ones(m), y + 1], 1),
                        np.stack([np.full(m, 0.5), y + 0.5 + 1e-6], 1)], 1)
    elif kind == "slivers":
        a, b = rng.random((m, 2)), rng.random((m, 2))
        tri = np.stack([a, b, (a + b) / 2 + rng.normal(size=(m, 2)) * 1e-7], 1)
    elif kind == "scattered":
        tri = rng.random((m, 1, 2)) + rng.random((m, 3, 2)) * 1e-2
    else:  # thin wedges around the origin, separated by gaps
        angle = np.linspace(0, 2 * np.pi, 2 * m + 1)[:-1].reshape(m, 2)
        far = np.stack([np.cos(angle), np.sin(angle)], 2) * (1 + rng.random((m, 1, 1)))
        tri = np.concatenate([np.zeros((m, 1, 2)) + 1e-3 * np.stack(
            [np.cos(angle[:, :1]), np.sin(angle[:, :1])], 2), far], 1)
    p = tri.reshape(-1, 2)
    t = np.arange(3 * m).reshape(m, 3)
    s = orient_signs(p, t)
    t[s < 0] = t[s < 0][:, ::-1]
    return p, t[s != 0]


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(["stacked", "slivers", "scattered", "fan"]), st.integers(1, 3000),
       st.integers(0, 2**32 - 1))
def test_sweep_work_is_at_most_b_log_b(kind, m, seed):
    """Issue 17: validation is O(N log N) on any input. The edge sort and every other pass
    are linear; the plane sweep makes at most a few orientation tests per edge and tree
    level (a treap with fixed pseudo-random priorities: its depth is O(log B) whatever the
    input's order). Counted, not timed."""
    p, t = _soup(kind, m, np.random.default_rng(seed))
    bedges = t[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    b = len(bedges)
    work = sweep(p, bedges, True, False)[-1]
    assert work <= 6 * b * max(1.0, np.log2(b)) + 10 * b
    found = check.find(p, t)
    if kind in ("stacked", "fan"):  # separate, non-overlapping: valid
        assert found.ok, found.errors


def _near_duplicates_match_all_pairs(q, tol):
    count, a, b = check.near_duplicates(q, tol)
    d = np.hypot(*(q[:, None, :] - q[None, :, :]).transpose(2, 0, 1))
    close = (d > 0) & (d <= tol)
    assert count == int(close.any(axis=1).sum())
    if count:
        assert close[a, b]


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 60), st.integers(0, 2**32 - 1))
def test_near_duplicates_match_all_pairs(n, seed):
    """Clusters of points a few tolerances apart, against all pairs."""
    rng = np.random.default_rng(seed)
    tol = 1e-3
    centres = rng.random((max(1, n // 4), 2))
    q = centres[rng.integers(0, len(centres), n)] + rng.integers(-3, 4, (n, 2)) * tol / 2.5
    q[rng.random(n) < 0.2] = q[0]  # exact copies are not near duplicates
    _near_duplicates_match_all_pairs(q, tol)


@settings(max_examples=20, deadline=None)
@given(st.integers(40, 300), st.integers(0, 2**32 - 1), st.floats(0.5, 3.0))
def test_near_duplicates_on_crowded_columns(n, seed, spacing):
    """Many points in a few columns of cells (points on vertical lines: the search bisects
    instead of walking), against all pairs."""
    rng = np.random.default_rng(seed)
    tol = 1e-3
    x = rng.choice([0.25, 0.25 + tol / 3, 0.75], n)
    y = np.round(rng.random(n) * n) * spacing * tol
    q = np.column_stack([x, y])
    _near_duplicates_match_all_pairs(q, tol)


@pytest.mark.parametrize("scheme", ["7t-qd", "4t-red"])
def test_first_refinement_reuses_the_validation_edges(scheme):
    """Issue 16: one edge numbering per mesh. The sorted edges of the validation serve the
    first uniform refinement (then they are released), with a result bit for bit equal to
    sorting them again; pickling leaves them out."""
    import pickle

    from qdrefine import refine
    from qdrefine.numbering import sort_edges

    base = examples.jittered_square(12, seed=3)
    p, t = np.array(base.points), np.array(base.triangles)
    mesh = Mesh(p, t)
    kept = mesh.__dict__["_buckets"]
    again = sort_edges(mesh.triangles, mesh.n_points)
    for name in ("starts", "first", "local"):
        assert np.array_equal(getattr(kept, name), getattr(again, name))
    copy = pickle.loads(pickle.dumps(mesh))
    assert "_buckets" not in copy.__dict__
    fine = refine(mesh, scheme)
    assert "_buckets" not in mesh.__dict__
    for other in (refine(mesh, scheme), refine(copy, scheme)):
        assert np.array_equal(other.points, fine.points)
        assert np.array_equal(other.triangles, fine.triangles)
    two = refine(Mesh(p, t), scheme, 2)
    twice = refine(refine(copy, scheme), scheme)
    assert np.array_equal(two.points, twice.points)
    assert np.array_equal(two.triangles, twice.triangles)


@settings(max_examples=5, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([300, 3000, 100_000]))
def test_bucket_scan_equals_the_edge_scan(seed, n_points):
    """40,000 random triangles (edges used once, twice either way and more often): the scan
    of the sorted buckets gives the counts, first edges and boundary of the scan of global
    edge ids."""
    from qdrefine.kernels import number_edges
    from qdrefine.numbering import sort_edges

    rng = np.random.default_rng(seed)
    t = rng.integers(0, n_points, size=(40_000, 3)).astype(np.int32)
    t = t[(t[:, 0] != t[:, 1]) & (t[:, 1] != t[:, 2]) & (t[:, 0] != t[:, 2])]
    e, tri_edges, counts = number_edges(t, n_points)
    serial = check.edge_scan(t, tri_edges, counts)
    b = sort_edges(t, n_points)
    scan = check.bucket_scan(t, b.local, b.starts, b.first, b.shift, b.mult)
    assert serial[:4] == scan[:4]
    assert np.array_equal(serial[4], scan[4]) and np.array_equal(serial[5], scan[5])


def test_physical_names_must_be_a_mapping():
    with pytest.raises(TypeError, match="physical_names must be a mapping"):
        Mesh([[0, 0], [1, 0], [0, 1]], [[0, 1, 2]], physical_names=[(2, 1)])


def test_a_pickled_or_copied_mesh_stays_read_only():
    """After pickle or deepcopy the arrays of point_data and cell_data came back writeable
    (review): a mesh's data could be changed under it."""
    import copy
    import pickle

    mesh = examples.square(2)
    mesh = mesh.replace(point_data={"u": np.arange(mesh.n_points, dtype=float)},
                        cell_data={"c": np.arange(mesh.n_triangles)},
                        physical_names={(2, 1): "plate"})
    for other in (pickle.loads(pickle.dumps(mesh)), copy.deepcopy(mesh)):
        for data in (other.point_data, other.cell_data):
            for value in data.values():
                with pytest.raises(ValueError, match="read-only"):
                    value[0] = 99
        assert dict(other.physical_names) == {(2, 1): "plate"}
        assert not other.points.flags.writeable and not other.triangles.flags.writeable


def test_an_edge_used_twice_by_one_triangle_is_counted_right():
    """A triangle with a repeated vertex ``(0, 1, 1)`` uses edge (0, 1) twice: "shared by 3
    triangles (0, 4)" named two (review)."""
    p = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]])
    t = np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4], [3, 0, 4], [0, 1, 1]])
    messages = [x.message for x in check.find(p, t).problems if x.kind == "overused-edge"]
    assert messages == ["edge (0, 1) is used 3 times, by triangles (0, 4) (a triangle with a "
                        "repeated vertex uses it twice); at most two triangles may share an "
                        "edge"]
    q = np.vstack([p, [[0.5, -0.5]]])  # three triangles on (0, 1): named as before
    three = np.vstack([t[:4], [[1, 0, 5], [0, 1, 2]]])
    messages = [x.message for x in check.find(q, three).problems if x.kind == "overused-edge"]
    assert messages == ["edge (0, 1) is shared by 3 triangles (0, 4, 5); at most two may "
                        "share an edge"]
