"""Refinement kernels and the error-free predicate stage, against independent oracles:
rational arithmetic (fractions.Fraction) for every sign, ``np.unique`` for edge numbering,
and a per-triangle Python transcription of the emission rule."""

import os
from fractions import Fraction as F

import numba
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from meshes import jittered_grid
from oracle import canonical as canonical_oracle
from oracle import exact, sq
from qdrefine import Mesh, examples, refine, scheme_names
from qdrefine.kernels import canonical, classify, edge_points, emit, number_edges
from qdrefine.numbering import bucket_points, sort_edges
from qdrefine.predicates import (
    UNDECIDED,
    _length_sign_stage2,
    factor_forms,
    factored_sign,
    form_sign_slow,
    length_sign,
    length_sign_slow,
    new_scratch,
    product_sign,
)
from qdrefine.schemes import get_scheme
from shapes import coordinate

SCHEMES = scheme_names()


def sign(x) -> int:
    return (x > 0) - (x < 0)


# ----------------------------------------------------------------------------------------
# adversarial near-ties: small integer vectors times an awkward step, from an awkward origin,
# optionally nudged by a few units in the last place

steps = st.sampled_from([1.0, 0.1, 1 / 3, 2.0**-30, 1e-7 / 3, 7.0, 1 / 1024, 0.3])
origins = st.sampled_from([0.0, 0.5, 0.1, 1 / 3, -2.7, 1e5 / 7, 123456.789, 1e-9])
small = st.integers(-4, 4)


@st.composite
def grid_point(draw, origin, step):
    x = origin + draw(small) * step
    y = origin * 0.7 + draw(small) * step
    for _ in range(draw(st.integers(0, 2))):  # a few ulps off the grid
        if draw(st.booleans()):
            x = float(np.nextafter(x, draw(st.sampled_from([-np.inf, np.inf]))))
        else:
            y = float(np.nextafter(y, draw(st.sampled_from([-np.inf, np.inf]))))
    assume(all(v == 0 or abs(v) >= 1e-100 for v in (x, y)))  # the documented exact range
    return x, y


@st.composite
def near_tie_points(draw, k):
    origin, step = draw(origins), draw(steps)
    return [draw(grid_point(origin, step)) for _ in range(k)]


def nudge(draw, v: float) -> float:
    for _ in range(draw(st.integers(0, 2))):
        v = float(np.nextafter(v, draw(st.sampled_from([-np.inf, np.inf]))))
    assume(v == 0 or abs(v) >= 1e-100)
    return v


@st.composite
def congruent_segments(draw):
    """Segments ``ab`` and ``cd`` whose integer step vectors are equally long (a rotation
    or reflection of each other), from awkward origins and steps, a few ulps off: exact
    ties and near-ties of ``|b - a| = |d - c|`` that the filter cannot decide."""
    origin, step = draw(origins), draw(steps)
    i, j, k, m = (draw(small) for _ in range(4))
    di, dj = draw(st.sampled_from([(i, j), (j, i), (-j, i), (i, -j), (-i, -j)]))
    a = (origin + i * step, origin * 0.7 + j * step)
    b = (origin + (i + di) * step, origin * 0.7 + (j + dj) * step)
    c = (origin + k * step, origin * 0.7 + m * step)
    ei, ej = draw(st.sampled_from([(di, dj), (dj, di), (-dj, di), (di, -dj)]))
    d = (origin + (k + ei) * step, origin * 0.7 + (m + ej) * step)
    return [tuple(nudge(draw, v) for v in p) for p in (a, b, c, d)]


def length_oracle(a, b, c, d) -> int:
    a, b, c, d = (exact(p) for p in (a, b, c, d))
    return sign(sq(a, b) - sq(c, d))


@settings(max_examples=1500, deadline=None)
@given(st.one_of(near_tie_points(4), congruent_segments()))
def test_length_sign_is_exact_on_near_ties(p):
    a, b, c, d = p
    expected = length_oracle(a, b, c, d)
    assert length_sign(*a, *b, *c, *d) == expected
    assert length_sign_slow(*a, *b, *c, *d) == expected


@settings(max_examples=800, deadline=None)
@given(st.tuples(*[coordinate] * 8))
def test_length_sign_is_exact_on_random_coordinates(v):
    a, b, c, d = v[0:2], v[2:4], v[4:6], v[6:8]
    assert length_sign_slow(*a, *b, *c, *d) == length_oracle(a, b, c, d)


def test_stage_2_decides_the_ties_of_structured_grids():
    """Every |OM| = |ON| tie of a linspace grid is decided by the product stage (no
    expansions): the case that made the exact stage run for every triangle."""
    x = np.linspace(0.0, 1.0, 301)
    rng = np.random.default_rng(4)
    decided = 0
    for _ in range(2000):
        i, j = rng.integers(1, 299, size=2)
        a = (x[i], x[j])
        legs = [(x[i + 1], x[j]), (x[i], x[j + 1]), (x[i - 1], x[j]), (x[i], x[j - 1])]
        b, c = (legs[k] for k in rng.choice(4, size=2, replace=False))
        p = (b[0] - a[0], b[1] - a[1])
        q = (c[0] - a[0], c[1] - a[1])
        s = _length_sign_stage2(*p, *q)
        assert s == UNDECIDED or s == length_oracle(a, b, a, c)
        decided += s != UNDECIDED
    assert decided == 2000


finite = st.floats(-1e100, 1e100, allow_nan=False).filter(lambda v: v == 0 or abs(v) >= 1e-100)


@settings(max_examples=1500, deadline=None)
@given(finite, finite, finite, finite, st.sampled_from(["free", "swap", "scale", "nudge"]))
def test_product_sign_is_exact(a, b, c, d, kind):
    if kind == "swap":  # a b = b a exactly
        c, d = b, a
    elif kind == "scale":  # a b = (2a)(b/2) exactly when no bits are lost
        c, d = 2.0 * a, b / 2.0
    elif kind == "nudge":  # products one ulp apart
        c, d = float(np.nextafter(a, np.inf)), b
    assume(all(v == 0 or abs(v) >= 1e-100 for v in (c, d)))
    expected = sign(F(a) * F(b) - F(c) * F(d))
    assert product_sign(a, b, c, d) == expected


def test_forms_factor_as_documented():
    """Each factorization reproduces its form's coefficients; a form is left unfactored
    exactly when its discriminant is not a perfect square."""
    for name in SCHEMES:
        forms = get_scheme(name).forms
        for (kuu, kww, kuw), (ok, p1, q1, p2, q2) in zip(forms, factor_forms(forms), strict=True):
            disc = int(kuw * kuw - 4 * kuu * kww)
            square = disc >= 0 and int(np.sqrt(disc)) ** 2 == disc
            assert bool(ok) == square
            if ok:
                assert (p1 * p2, q1 * q2, p1 * q2 + q1 * p2) == (kuu, kww, kuw)


def form_oracle(m, n, o, kuu, kww, kuw) -> int:
    m, n, o = (exact(p) for p in (m, n, o))
    u = (n[0] - m[0], n[1] - m[1])
    w = (o[0] - m[0], o[1] - m[1])
    uu, ww, uw = u[0] ** 2 + u[1] ** 2, w[0] ** 2 + w[1] ** 2, u[0] * w[0] + u[1] * w[1]
    return sign(F(int(kuu)) * uu + F(int(kww)) * ww + F(int(kuw)) * uw)


@pytest.mark.parametrize("name", ["7t-qd", "7t-le", "7t-d"])
@settings(max_examples=500, deadline=None)
@given(p=near_tie_points(3))
def test_form_stages_are_exact_on_near_ties(name, p):
    m, n, o = p
    forms = get_scheme(name).forms
    buf = new_scratch()
    for form, factor in zip(forms, factor_forms(forms), strict=True):
        expected = form_oracle(m, n, o, *form)
        assert form_sign_slow(*m, *n, *o, *form, *factor, buf) == expected
        if factor[0]:
            u = (n[0] - m[0], n[1] - m[1])
            w = (o[0] - m[0], o[1] - m[1])
            if all(exact((b, 0))[0] - exact((a, 0))[0] == F(d) for a, b, d in
                   ((m[0], n[0], u[0]), (m[1], n[1], u[1]), (m[0], o[0], w[0]),
                    (m[1], o[1], w[1]))):
                s = factored_sign(*u, *w, *factor[1:])
                assert s == UNDECIDED or s == expected


def test_factored_stage_decides_the_7t_le_ties_of_a_grid():
    """On the right isosceles triangles of a grid, |AC| = |BD| exactly; stage 2 decides."""
    forms = get_scheme("7t-le").forms
    (ok, p1, q1, p2, q2), = factor_forms(forms)
    x = np.linspace(0.0, 1.0, 101)
    for i in range(1, 99):
        m, n, o = (x[i], x[i]), (x[i + 1], x[i + 1]), (x[i + 1], x[i])
        u = (n[0] - m[0], n[1] - m[1])
        w = (o[0] - m[0], o[1] - m[1])
        s = factored_sign(*u, *w, p1, q1, p2, q2)
        assert s == form_oracle(m, n, o, *forms[0]) == 0


# ----------------------------------------------------------------------------------------
# canonical labelling


@settings(max_examples=1500, deadline=None)
@given(near_tie_points(3))
def test_canonical_labelling_matches_the_rational_oracle(p):
    v = [exact(q) for q in p]
    area = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1]) - (v[1][1] - v[0][1]) * (v[2][0] - v[0][0])
    assume(area != 0)
    im, jn, ko = canonical(*p[0], *p[1], *p[2], new_scratch())
    assert (v[im], v[jn], v[ko]) == canonical_oracle(v)


# ----------------------------------------------------------------------------------------
# edge numbering


def edges_oracle(tri):
    half = np.stack([tri, np.roll(tri, -1, axis=1)], axis=-1).reshape(-1, 2)
    keys = np.sort(half, axis=1)
    edges, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    return edges, inverse.reshape(-1, 3), counts


def triangle_soup(rng, n_points, m, fan=0):
    """Random triangles with distinct vertices, plus a fan of ``fan`` triangles at vertex 0
    (long runs: the sort and binary-search paths) and repeated triangles (counts > 2)."""
    tri = np.array([rng.choice(n_points, 3, replace=False) for _ in range(m)])
    if fan:
        ring = rng.choice(np.arange(1, n_points), fan + 1, replace=False)
        tri = np.concatenate([tri, np.stack([np.zeros(fan, int), ring[:-1], ring[1:]], 1)])
    return np.concatenate([tri, tri[: m // 10]])


@settings(max_examples=60, deadline=None)
@given(n_points=st.integers(3, 5000), m=st.integers(1, 400), fan=st.sampled_from([0, 5, 40]),
       seed=st.integers(0, 2**32 - 1), n_chunks=st.integers(1, 7), shift=st.integers(0, 18),
       dtype=st.sampled_from([np.int32, np.int64]))
def test_number_edges_matches_np_unique(n_points, m, fan, seed, n_chunks, shift, dtype):
    rng = np.random.default_rng(seed)
    tri = triangle_soup(rng, n_points, m, fan if n_points > fan + 2 else 0).astype(dtype)
    expected = edges_oracle(tri)
    buckets = sort_edges(tri, n_points, n_chunks, shift, with_rows=True)
    edges, counts = buckets.edges()
    got = (edges, buckets.global_ids(tri), counts)
    for g, e in zip(got, expected, strict=True):
        np.testing.assert_array_equal(g, e)
    assert got[0].dtype == dtype and got[1].dtype == np.int64 and got[2].dtype == np.int64
    assert buckets.local.dtype == np.int32
    # the triangles around each edge, read off the sort: a stable argsort of the global
    # ids (the oracle) lists them edge by edge, in increasing order around each edge
    np.testing.assert_array_equal(buckets.rows,
                                  np.argsort(expected[1].reshape(-1), kind="stable") // 3)


def test_number_edges_around_is_number_edges_and_incidence():
    """:func:`number_edges_around` equals :func:`number_edges` plus :func:`incidence` of
    the edge ids, on a shuffled mesh large enough for the parallel paths; without
    ``with_rows`` the buckets hold no rows."""
    from qdrefine.jit import PARALLEL_MIN
    from qdrefine.numbering import incidence, number_edges_around

    mesh = jittered_grid(int((PARALLEL_MIN / 2) ** 0.5) + 20, seed=5)
    rng = np.random.default_rng(5)
    tri = mesh.triangles[rng.permutation(mesh.n_triangles)]
    edges, tri_edges, counts, (start, rows) = number_edges_around(tri, mesh.n_points)
    for g, e in zip((edges, tri_edges, counts), number_edges(tri, mesh.n_points), strict=True):
        np.testing.assert_array_equal(g, e)
    s, r = incidence(tri_edges, edges.shape[0])
    np.testing.assert_array_equal(start, s)
    np.testing.assert_array_equal(rows, r)
    assert sort_edges(tri, mesh.n_points).rows is None


@pytest.mark.parametrize("scheme", ["7t-qd", "4t-red"])
def test_bucket_pipeline_matches_global_ids(scheme):
    """refine's path (bucket-local ids, points per bucket) equals the public kernels' (global
    ids, points per edge), with several buckets and chunks."""
    mesh = jittered_grid(40, seed=3)
    sch = get_scheme(scheme)
    k = sch.stencil.per_edge
    buckets = sort_edges(mesh.triangles, mesh.n_points, n_chunks=3, shift=6)
    edges, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    n_new = mesh.n_points + k * len(edges)
    expected_points, points = np.empty((n_new, 2)), np.full((n_new, 2), np.nan)
    edge_points(mesh.points, edges, k, expected_points)
    bucket_points(mesh.points, buckets, k, points)
    np.testing.assert_array_equal(points, expected_points)
    shape = (mesh.n_triangles * sch.n_children, 3)
    expected, got = np.empty(shape, dtype=np.int64), np.empty(shape, dtype=np.int64)
    emit(mesh.points, mesh.triangles, tri_edges, k, sch.forms, sch.lut, sch.tables, expected)
    emit(mesh.points, mesh.triangles, buckets.local, k, sch.forms, sch.lut, sch.tables, got,
         buckets)
    np.testing.assert_array_equal(got, expected)


def test_number_edges_public_entry_on_a_mesh():
    mesh = jittered_grid(60, seed=1)
    expected = edges_oracle(mesh.triangles)
    for g, e in zip(number_edges(mesh.triangles, mesh.n_points), expected, strict=True):
        np.testing.assert_array_equal(g, e)


# ----------------------------------------------------------------------------------------
# emission against a per-triangle transcription of the rule


def emit_reference(points, tri, tri_edges, sch):
    """Children of every triangle: classify(), then the scheme's table row in the canonical
    frame, each edge's points taken from the edge's numbering, reflections flipped."""
    k = sch.stencil.per_edge
    n = points.shape[0]
    buf = new_scratch()
    out = []
    for t, v in enumerate(tri):
        im, jn, ko, row = classify(*points[v].ravel(), sch.forms, sch.lut, buf)
        lab = (im, jn, ko)
        loc = [v[im], v[jn], v[ko]]
        for e in range(3):
            a, b = lab[e], lab[(e + 1) % 3]
            own = a if b == (a + 1) % 3 else b  # the input edge (v_own, v_own+1) is {a, b}
            base = n + tri_edges[t, own] * k
            loc += [base + (j if v[a] < v[b] else k - 1 - j) for j in range(k)]
        flip = (jn - im) % 3 != 1
        for i0, i1, i2 in sch.tables[row]:
            out.append([loc[i0], loc[i2], loc[i1]] if flip else [loc[i0], loc[i1], loc[i2]])
    return np.array(out)


def tie_mesh():
    """Right isosceles grid (every triangle a tie) with shuffled vertices and rotated rows."""
    mesh = examples.square(12)
    rng = np.random.default_rng(7)
    perm = rng.permutation(mesh.n_points)
    tri = np.argsort(perm)[mesh.triangles]
    tri = np.roll(tri, 1, axis=1)[rng.permutation(len(tri))]
    return Mesh(mesh.points[perm], tri)


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("which", ["ties", "jittered", "sheared"])
def test_emit_matches_the_reference(scheme, which):
    mesh = {"ties": tie_mesh, "jittered": lambda: jittered_grid(9, seed=2),
            "sheared": lambda: jittered_grid(7, seed=5, shear=40.0)}[which]()
    sch = get_scheme(scheme)
    edges, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    out = np.empty((mesh.n_triangles * sch.n_children, 3), dtype=np.int64)
    emit(mesh.points, mesh.triangles, tri_edges, sch.stencil.per_edge, sch.forms, sch.lut,
         sch.tables, out)
    np.testing.assert_array_equal(out, emit_reference(mesh.points, mesh.triangles, tri_edges,
                                                      sch))


def test_edge_points_are_symmetric_thirds_and_halves():
    mesh = jittered_grid(5, seed=3)
    edges, _, _ = number_edges(mesh.triangles, mesh.n_points)
    p = mesh.points
    for k in (1, 2):
        out = np.empty((mesh.n_points + k * len(edges), 2))
        edge_points(p, edges, k, out)
        a, b = p[edges[:, 0]], p[edges[:, 1]]
        new = out[mesh.n_points:].reshape(len(edges), k, 2)
        np.testing.assert_array_equal(out[: mesh.n_points], p)
        if k == 1:
            np.testing.assert_array_equal(new[:, 0], (a + b) * 0.5)
        else:
            np.testing.assert_array_equal(new[:, 0], (2.0 * a + b) / 3.0)
            np.testing.assert_array_equal(new[:, 1], (a + 2.0 * b) / 3.0)


# ----------------------------------------------------------------------------------------
# thread count


def test_kernels_are_bit_identical_for_1_and_2_threads():
    """A mesh big enough for several chunks of triangles and of edge buckets. Where numba
    has one thread (``NUMBA_NUM_THREADS=1``, one core) the test runs itself in a process
    given two (it failed there; newcomer review)."""
    if numba.config.NUMBA_NUM_THREADS < 2:
        import subprocess
        import sys

        env = {**os.environ, "NUMBA_NUM_THREADS": "2"}
        test = f"{__file__}::test_kernels_are_bit_identical_for_1_and_2_threads"
        done = subprocess.run([sys.executable, "-m", "pytest", test, "-q", "-o", "addopts=",
                               "-p", "no:cacheprovider", "-n", "0"], env=env,
                              capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
        assert "1 passed" in done.stdout
        return
    mesh = jittered_grid(280, seed=9, shear=0.2)  # 156800 triangles: 2 chunks, 39 for emit
    results = []
    for threads in (1, 2):
        numba.set_num_threads(threads)
        try:
            row = [*number_edges(mesh.triangles, mesh.n_points)]
            for scheme in SCHEMES:
                fine = refine(mesh, scheme)
                row += [fine.points, fine.triangles]
        finally:
            numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
        results.append([r.tobytes() for r in row])
    assert results[0] == results[1]


def test_number_edges_refuses_indices_out_of_range():
    for bad in ([[0, 1, -1]], [[0, 1, 3]]):
        with pytest.raises(ValueError, match=r"vertex indices must be in \[0, 3\)"):
            number_edges(np.array(bad), 3)


def test_emit_refuses_a_table_with_missing_rows():
    mesh = examples.square(2)
    sch = get_scheme("7t-qd")
    _, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    lut = sch.lut.copy()
    lut[0] = -1
    out = np.empty((mesh.n_triangles * sch.n_children, 3), dtype=np.int64)
    with pytest.raises(ValueError, match="without a row"):
        emit(mesh.points, mesh.triangles, tri_edges, 2, sch.forms, lut, sch.tables, out)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 3000), m=st.integers(0, 2000), chunks=st.integers(1, 7),
       seed=st.integers(0, 2**32 - 1))
def test_incidence_blocks_match_a_stable_argsort(n, m, chunks, seed):
    """The parallel counting sort by blocks of rows gives each id's rows in increasing
    order, exactly as a stable argsort of the flattened table (the oracle), for any
    number of blocks (more blocks than rows included)."""
    from qdrefine.numbering import _incidence_blocks, incidence

    table = np.random.default_rng(seed).integers(0, n, size=(m, 3)).astype(np.int32)
    flat = table.reshape(-1).astype(np.int64)
    expected_rows = np.argsort(flat, kind="stable") // 3
    expected_start = np.concatenate([[0], np.cumsum(np.bincount(flat, minlength=n))])
    start = np.zeros(n + 1, dtype=np.int64)
    rows = np.empty(3 * m, dtype=np.int64)
    bounds = np.linspace(0, m, chunks + 1).astype(np.int64)
    _incidence_blocks(table, bounds, start, np.zeros((chunks, n), dtype=np.int64), rows)
    assert np.array_equal(start, expected_start)
    assert np.array_equal(rows, expected_rows)
    s, r = incidence(table, n)  # the sequential pass below PARALLEL_MIN rows
    assert np.array_equal(s, expected_start) and np.array_equal(r, expected_rows)


@pytest.mark.parametrize("n", [100, 60_000, 500_000])
def test_incidence_of_a_large_table_matches_a_stable_argsort(n):
    """:func:`incidence` itself above ``PARALLEL_MIN`` rows: blocks as many as the threads
    allow (few ids), or as ``3M / n`` allows (about one id per entry), or one (more ids
    than entries); the same table each time."""
    from qdrefine.jit import PARALLEL_MIN
    from qdrefine.numbering import incidence

    m = PARALLEL_MIN + 7_000
    table = np.random.default_rng(n).integers(0, n, size=(m, 3))
    flat = table.reshape(-1)
    start, rows = incidence(table, n)
    assert np.array_equal(rows, np.argsort(flat, kind="stable") // 3)
    assert np.array_equal(start, np.concatenate([[0], np.cumsum(np.bincount(flat, minlength=n))]))
