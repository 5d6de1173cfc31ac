"""Adaptive (marked) refinement: conformity, closure, patterns, areas, tags, quality."""

from fractions import Fraction as F

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshes import crack, jittered_grid
from oracle import exact, orient
from qdrefine import (
    Mesh,
    coarsen,
    examples,
    marking,
    partition_many,
    refine,
    refine_with_parents,
    scheme_names,
)
from qdrefine.adaptive import (
    Families,
    HistoryMismatch,
    canonical_edges,
    canonical_labels,
    closure,
    refine_cycles,
    refine_marked,
)
from qdrefine.adaptive.history import families_of
from qdrefine.kernels import number_edges
from qdrefine.predicates import orient_signs
from qdrefine.quality import min_angles
from qdrefine.schemes import get_scheme
from qdrefine.topology import boundary_edges, conformity, euler_characteristic

SCHEMES = scheme_names()
mesh_params = st.tuples(st.integers(1, 6), st.integers(0, 10**6), st.sampled_from([0, 0.5, 4.0]))
marks = st.tuples(st.integers(0, 10**6), st.sampled_from([0.02, 0.1, 0.3, 0.7]))


def random_marks(mesh, seed, fraction):
    rng = np.random.default_rng(seed)
    mask = rng.random(mesh.n_triangles) < fraction
    mask[rng.integers(mesh.n_triangles)] = True  # at least one
    return mask


def triangle_keys(points, tris):
    """Sorted coordinate triples of each triangle, as a multiset of tuples."""
    p = points[tris]  # (T, 3, 2)
    return sorted(tuple(sorted(map(tuple, t.tolist()))) for t in p)


def split_edges_of(mesh, fine):
    """Input edges that carry a new point of ``fine`` (found from the output alone): an
    input edge is split iff it is not an edge of the output."""
    edges = number_edges(mesh.triangles, mesh.n_points)[0]
    out = number_edges(fine.triangles, fine.n_points)[0]
    key = set(map(tuple, out.tolist()))
    return np.array([tuple(e) not in key for e in edges.tolist()]), edges


@pytest.mark.parametrize("scheme", SCHEMES)
@settings(max_examples=20, deadline=None)
@given(params=mesh_params, mk=marks)
def test_marked_refinement_is_conforming_and_keeps_everything_else(scheme, params, mk):
    mesh = jittered_grid(*params)
    marked = random_marks(mesh, *mk)
    fine, parents = refine_with_parents(mesh, scheme, marked=marked)
    sch = get_scheme(scheme)
    # conforming, same topology, positively oriented
    assert conformity(fine).ok
    assert euler_characteristic(fine) == euler_characteristic(mesh)
    assert (orient_signs(fine.points, fine.triangles) > 0).all()
    np.testing.assert_array_equal(fine.points[: mesh.n_points], mesh.points)
    # children are contiguous per parent, parents in increasing order
    assert (np.diff(parents) >= 0).all()
    counts = np.bincount(parents, minlength=mesh.n_triangles)
    # every marked triangle is fully partitioned by the scheme, exactly as partition() does
    ids = np.flatnonzero(marked)
    assert (counts[ids] == sch.n_children).all()
    pts, tris = partition_many(mesh.points[mesh.triangles[ids]], scheme)
    for j, t in enumerate(ids):
        assert triangle_keys(fine.points, fine.triangles[parents == t]) == \
            triangle_keys(pts[j], tris[j])
    # nothing outside the closure changes: a triangle none of whose edges is split keeps its
    # row; a triangle with a split edge is refined
    split, edges = split_edges_of(mesh, fine)
    tri_edges = number_edges(mesh.triangles, mesh.n_points)[1]
    touched = split[tri_edges].any(axis=1)
    assert (counts[~touched] == 1).all()
    assert (counts[touched] > 1).all()
    np.testing.assert_array_equal(fine.triangles[np.isin(parents, np.flatnonzero(~touched))],
                                  mesh.triangles[~touched])
    # the closure rule holds: every touched triangle has its longest edge split
    ce = canonical_edges(canonical_labels(mesh.points, mesh.triangles), tri_edges)
    assert split[ce[touched, 0]].all()
    # each split edge has k new points, shared; the other new points are centroids of
    # transition triangles (seven-triangle schemes only), each used by its children alone
    k = sch.stencil.per_edge
    n_centroids = fine.n_points - mesh.n_points - k * int(split.sum())
    assert n_centroids >= 0 and (k == 2 or n_centroids == 0)
    if n_centroids:
        on_edges = set(map(tuple, fine.points[np.unique(fine.edges)].tolist()))
        transition = touched & ~marked
        rows = mesh.triangles[transition].astype(np.int64)
        mno = mesh.points[np.take_along_axis(
            rows, canonical_labels(mesh.points, rows).astype(np.int64), axis=1)]
        centroids = {tuple(c) for c in ((mno[:, 0] + mno[:, 1] + mno[:, 2]) / 3.0).tolist()}
        extra = [tuple(p) for p in fine.points[mesh.n_points:].tolist()]
        edge_pts = {tuple(p) for p in fine.points[mesh.n_points:].tolist()} - centroids
        assert sum(p in centroids for p in extra) == n_centroids
        assert not (on_edges & centroids)
        assert len(edge_pts) == k * int(split.sum())
    # tags: cells inherited; tagged edges cut into k + 1 pieces exactly where split
    np.testing.assert_array_equal(fine.cell_tags, mesh.cell_tags[parents])
    check_tagged_edges(mesh, fine, split, edges, k)


def check_tagged_edges(mesh, fine, split, edges, k):
    key = {tuple(e): g for g, e in enumerate(edges.tolist())}
    pieces = [k + 1 if split[key[tuple(sorted(e))]] else 1 for e in mesh.edges.tolist()]
    assert len(fine.edges) == sum(pieces)
    np.testing.assert_array_equal(fine.edge_tags, np.repeat(mesh.edge_tags, pieces))
    start = np.concatenate([[0], np.cumsum(pieces)])
    for i, (a, b) in enumerate(mesh.edges.tolist()):
        chain = fine.edges[start[i]: start[i + 1]]
        assert chain[0, 0] == a and chain[-1, 1] == b
        assert (chain[1:, 0] == chain[:-1, 1]).all()
    # every boundary edge of the refined mesh is tagged (the grid tags its whole boundary)
    b = {frozenset(e) for e in boundary_edges(fine).tolist()}
    assert b == {frozenset(e) for e in fine.edges.tolist()}


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("levels", [1, 2])
def test_all_marked_equals_uniform_refinement(scheme, levels):
    mesh = jittered_grid(5, seed=11, shear=0.5)
    uniform, up = refine_with_parents(mesh, scheme, levels)
    for marked in (np.ones(mesh.n_triangles, bool), np.arange(mesh.n_triangles)[::-1]):
        local, lp = refine_with_parents(mesh, scheme, levels, marked=marked)
        np.testing.assert_array_equal(local.points, uniform.points)
        np.testing.assert_array_equal(local.triangles, uniform.triangles)
        np.testing.assert_array_equal(local.cell_tags, uniform.cell_tags)
        np.testing.assert_array_equal(local.edges, uniform.edges)
        np.testing.assert_array_equal(local.edge_tags, uniform.edge_tags)
        np.testing.assert_array_equal(lp, up)


def test_levels_refine_the_marked_children_again():
    mesh = jittered_grid(4, seed=2)
    marked = np.zeros(mesh.n_triangles, bool)
    marked[[3, 17]] = True
    fine, parents = refine_with_parents(mesh, "7t-qd", 2, marked=marked)
    counts = np.bincount(parents, minlength=mesh.n_triangles)
    assert (counts[marked] >= 49).all()
    assert conformity(fine).ok
    # nothing marked: the mesh itself
    same, p = refine_with_parents(mesh, marked=np.zeros(mesh.n_triangles, bool))
    assert same is mesh
    np.testing.assert_array_equal(p, np.arange(mesh.n_triangles))


@pytest.mark.parametrize("scheme", ["7t-qd", "4t-le"])
def test_levels_refine_a_marked_transition_child_again(scheme):
    """A marked transition child is refined through its family parent; with ``levels=2``
    its area is refined again. It was not when every child of the parent that meets it was
    smaller than it: levels 2 and 3 gave the level-1 mesh for 15 of the 51 transition
    children of this mesh (review)."""
    mesh = refine(examples.gmsh_mesh("l_shape"), scheme, marked=[10, 60])
    green = np.flatnonzero(mesh.transitions[:, 0] >= 0)
    assert green.size > 10

    def cross(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    def around(m: Mesh, point) -> float:
        """The largest area of a triangle of ``m`` that holds ``point``."""
        p = m.points[m.triangles]
        d = np.stack([cross(p[:, (i + 1) % 3] - p[:, i], point - p[:, i]) for i in range(3)])
        holds = (d >= 0).all(axis=0)
        assert holds.any()
        return float(cross(p[holds, 1] - p[holds, 0], p[holds, 2] - p[holds, 0]).max())

    for t in green:
        centre = np.array([0.41, 0.33, 0.26]) @ mesh.points[mesh.triangles[t]]
        one, two = (refine(mesh, scheme, levels, marked=[t]) for levels in (1, 2))
        assert around(two, centre) < around(one, centre) < around(mesh, centre), t


@pytest.mark.parametrize("scheme", ["7t-qd", "4t-le"])
def test_areas_are_conserved_exactly_on_an_exact_grid(scheme):
    """Coordinates that are multiples of 6 make every new point exact: equality holds."""
    mesh = jittered_grid(4, seed=5, shuffle=True)
    mesh = Mesh(np.round(mesh.points * 96) * 6, mesh.triangles)
    marked = random_marks(mesh, 1, 0.15)
    fine, parents = refine_with_parents(mesh, scheme, marked=marked)
    assert fine.n_triangles > mesh.n_triangles + 6 * marked.sum()  # closure did something
    pts = [exact(p) for p in fine.points]
    total = [F(0)] * mesh.n_triangles
    for (a, b, c), p in zip(fine.triangles.tolist(), parents.tolist(), strict=True):
        total[p] += orient(pts[a], pts[b], pts[c])
    old = pts[: mesh.n_points]
    assert total == [orient(old[a], old[b], old[c]) for a, b, c in mesh.triangles.tolist()]


def test_local_refinement_refuses_a_needle_it_would_flatten_and_only_that():
    """The rounding check of local refinement covers every triangle that changes, and only
    those: a needle far from the origin is refused when marked or reached by the closure,
    and a step that leaves it as it was refines."""
    points = np.array([[0, 0], [1, 0], [0.5, 1e-9], [3, 0], [3, 1], [4, 0], [0.5, -1],
                       [0.75, 0.5]]) + 1e7
    # the needle (0), a separate triangle (1), one across the needle's longest edge (2) and
    # one across a short edge (3)
    mesh = Mesh(points, [[0, 1, 2], [3, 5, 4], [0, 6, 1], [1, 7, 2]])
    for marked in ([0], [3]):  # marked, or given points on a short edge by a mark's closure
        with pytest.raises(ValueError, match="triangle 0 .* too thin for its distance"):
            refine(mesh, marked=marked)
    # points on its longest edge only: its transition's children have the needle's apex and
    # points on the edge opposite (exact), nothing flat
    assert refine(mesh, marked=[2]).n_triangles == 12
    fine = refine(mesh, marked=[1])  # untouched
    assert fine.n_triangles == 10
    np.testing.assert_array_equal(fine.triangles[:1], mesh.triangles[:1])


def test_areas_are_conserved_within_the_rounding_bound():
    """As in test_refine: with ``d`` the largest L1 displacement of a stored new point and
    ``L`` the parent's L1 perimeter, ``|sum(children) - parent| <= 3 L d + 3 d^2``."""
    mesh = jittered_grid(5, seed=8, shear=3.0)
    marked = random_marks(mesh, 4, 0.2)
    fine, parents = refine_with_parents(mesh, "7t-qd", marked=marked)
    split, edges = split_edges_of(mesh, fine)
    pts = [exact(p) for p in fine.points]
    old = pts[: mesh.n_points]
    d = F(0)
    for r, (a, b) in enumerate(edges[split].tolist()):
        for j in range(2):
            s = F(j + 1, 3)
            x = old[a][0] + s * (old[b][0] - old[a][0])
            y = old[a][1] + s * (old[b][1] - old[a][1])
            p = pts[mesh.n_points + 2 * r + j]
            d = max(d, abs(p[0] - x) + abs(p[1] - y))
    assert d > 0
    total = [F(0)] * mesh.n_triangles
    for (a, b, c), p in zip(fine.triangles.tolist(), parents.tolist(), strict=True):
        total[p] += orient(pts[a], pts[b], pts[c])
    for t, (a, b, c) in enumerate(mesh.triangles.tolist()):
        parent = orient(old[a], old[b], old[c])
        perimeter = sum(abs(old[i][0] - old[j][0]) + abs(old[i][1] - old[j][1])
                        for i, j in ((a, b), (b, c), (c, a)))
        assert abs(total[t] - parent) <= 3 * perimeter * d + 3 * d * d


@settings(max_examples=30, deadline=None)
@given(params=mesh_params, mk=marks)
def test_closure_is_the_smallest_closed_set(params, mk):
    mesh = jittered_grid(*params)
    marked = random_marks(mesh, *mk)
    edges, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    ce = canonical_edges(canonical_labels(mesh.points, mesh.triangles), tri_edges)
    split, rounds = closure(ce, marked, len(edges))
    assert rounds <= len(edges)
    touched = split[ce].any(axis=1)
    assert split[ce[touched, 0]].all()  # closed
    # smallest: each split edge is an edge of a marked triangle or the longest edge of a
    # triangle with another split edge ... checked by recomputing the fixed point naively
    naive = np.zeros(len(edges), bool)
    naive[ce[marked].ravel()] = True
    naive_rounds = 0
    while True:
        naive_rounds += 1  # one pass over all triangles, the last one changing nothing
        grow = naive.copy()
        grow[ce[naive[ce].any(axis=1), 0]] = True
        if (grow == naive).all():
            break
        naive = grow
    np.testing.assert_array_equal(split, naive)
    assert rounds == (naive_rounds if naive.any() else 0)


def test_longest_edge_of_canonical_labels_is_longest():
    mesh = jittered_grid(6, seed=9, shear=2.0)
    edges, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    ce = canonical_edges(canonical_labels(mesh.points, mesh.triangles), tri_edges)
    length = np.linalg.norm(mesh.points[edges[:, 0]] - mesh.points[edges[:, 1]], axis=1)
    assert (length[ce[:, 0]] >= length[ce].max(axis=1)).all()
    assert (length[ce[:, 0]] > length[ce[:, 1:]].min(axis=1)).all()


def test_repeated_cycles_keep_the_minimum_angle():
    """Random marks are the adversarial case (they hit transition children): the history
    in the mesh keeps the natural loop from compounding transitions."""
    mesh = jittered_grid(5, seed=3)
    rng = np.random.default_rng(7)

    def mark(m):
        return rng.random(m.n_triangles) < 0.04

    fine, parents = refine_cycles(mesh, mark, 7, "7t-qd")
    assert conformity(fine).ok
    assert fine.n_triangles > 10 * mesh.n_triangles
    np.testing.assert_array_equal(fine.cell_tags, mesh.cell_tags[parents])
    assert min_angles(fine).min() >= 0.4 * min_angles(mesh).min()


def test_bad_marks_raise():
    mesh = examples.square(2)
    for bad, what in (([8], "outside"), ([-1], "outside"), (np.ones(3, bool), "shape"),
                      ([0.5], "dtype"), ([[0, 1]], "one-dimensional"),
                      # its mask was dropped: the masked mark refined (review)
                      (np.ma.array([0, 1], mask=[0, 1]), "masked entries")):
        with pytest.raises(ValueError, match=what):
            refine(mesh, marked=bad)
    with pytest.raises(ValueError, match="masked entries"):
        coarsen(refine(mesh, marked=[0]), np.ma.array([0, 1], mask=[0, 1]))
    with pytest.raises(ValueError, match="levels"):
        refine(mesh, levels=-1, marked=[0])
    for flag in (True, np.True_):  # a bool is not a count (True was read as 1, review)
        with pytest.raises(ValueError, match="levels must be an integer, got (np.)?True"):
            refine(mesh, levels=flag, marked=[0])
        with pytest.raises(ValueError, match="levels must be an integer"):
            refine(mesh, levels=flag)
    with pytest.raises(ValueError, match="cycles"):
        refine_cycles(mesh, lambda m: [0], -1)


# ----------------------------------------------------------------------------------------
# repeated cycles: transition families are coarsened before they are refined

SCALE = 6**7  # room for seven trisections or bisections on integer coordinates


def exact_grid(n, seed):
    """A jittered grid on integer coordinates (multiples of 6^7): the points of up to seven
    levels of refinement are integers, so twice-areas and orientation tests below are exact
    in int64 (coordinates < 2^26, products < 2^53)."""
    g = jittered_grid(n, seed)
    return Mesh(np.round(g.points * 128) * SCALE, g.triangles, g.cell_tags, g.edges,
                g.edge_tags)


def ints(points):
    p = np.asarray(points)
    assert (p == np.round(p)).all(), "points are no longer integers: deeper than the scale"
    return np.round(p).astype(np.int64)


def twice_areas(p, tris):
    a, b, c = p[tris[..., 0]], p[tris[..., 1]], p[tris[..., 2]]
    return ((b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1])
            - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0]))


def inside(q, tri):
    """Points ``q (..., 2)`` in the closed counter-clockwise triangles ``tri (..., 3, 2)``
    (broadcast), exact on integers."""
    ok = np.ones(np.broadcast_shapes(q.shape[:-1], tri.shape[:-2]), dtype=bool)
    for i in range(3):
        a, b = tri[..., i, :], tri[..., (i + 1) % 3, :]
        ok &= ((b[..., 0] - a[..., 0]) * (q[..., 1] - a[..., 1])
               - (b[..., 1] - a[..., 1]) * (q[..., 0] - a[..., 0])) >= 0
    return ok


def contained(x, regions):
    """Whether each triangle ``x (X, 3, 2)`` lies in one of ``regions (R, 3, 2)``."""
    return inside(x[:, None, :, :], regions[None, :, None, :, :]).all(axis=2).any(axis=1)


def children_points(vertices, scheme, times):
    """The triangles ``(K, 3, 2)`` of ``times`` nested full partitions of ``vertices``."""
    v = vertices.reshape(-1, 3, 2).astype(float)
    for _ in range(times):
        pts, tris = partition_many(v, scheme)
        v = np.take_along_axis(pts[:, None, :, :], tris[..., None], axis=2).reshape(-1, 3, 2)
    return ints(v)


def check_step(mesh, fam, marked, fine, parents, new_fam, scheme):
    """Every invariant of one :func:`refine_marked` with history, from the output alone
    and oracles."""
    m = mesh.n_triangles
    member = fam.member
    p0, p1 = ints(mesh.points), ints(fine.points)
    # conforming, same topology, positively oriented, old points kept
    assert conformity(fine).ok
    assert euler_characteristic(fine) == euler_characteristic(mesh)
    assert (twice_areas(p1, fine.triangles) > 0).all()
    # old points kept in order, but for the centroids of coarsened transitions
    # (a re-used centroid comes back as a new point): align the two lists
    cent, keep, j = set(fam.centroids().tolist()), np.ones(mesh.n_points, dtype=bool), 0
    for i in range(mesh.n_points):
        if (fine.points[j] == mesh.points[i]).all():
            j += 1
        else:
            assert i in cent, f"old point {i} is gone but was no centroid"
            keep[i] = False
    np.testing.assert_array_equal(fine.points[: keep.sum()], mesh.points[keep])
    # from here on, the output in the input's point numbering (new points after the input's)
    old_id = np.concatenate([np.flatnonzero(keep),
                             mesh.n_points + np.arange(fine.n_points - keep.sum())])
    fine = Mesh._trusted(np.concatenate([mesh.points, fine.points[keep.sum():]]),
                         old_id[fine.triangles], fine.cell_tags, old_id[fine.edges],
                         fine.edge_tags)
    new_fam = Families(new_fam.member, old_id[new_fam.parent_triangles],
                       np.where(new_fam.stencil >= 0, old_id[new_fam.stencil], -1))
    p1 = ints(fine.points)
    # parents in order, cell tags inherited, tagged edges cut into chains
    assert (np.diff(parents) >= 0).all()
    np.testing.assert_array_equal(fine.cell_tags, mesh.cell_tags[parents])
    check_tag_chains(mesh, fine)
    # areas exact per input triangle, a coarsened family counting as one region
    group = np.where(member >= 0, m + member, np.arange(m))
    np.testing.assert_array_equal(
        np.bincount(group[parents], twice_areas(p1, fine.triangles), minlength=2 * m),
        np.bincount(group, twice_areas(p0, mesh.triangles), minlength=2 * m))
    # nested: every output triangle lies in its input triangle (its family's parent)
    region = p0[mesh.triangles]
    fm = np.flatnonzero(member >= 0)
    region[fm] = p0[fam.parent_triangles[member[fm]]]
    assert contained_each(p1[fine.triangles], region[parents]).all()
    check_marked_refined(mesh, fam, member, marked, fine, parents, scheme)
    check_rest_unchanged(mesh, member, marked, fine, parents)
    check_families(fine, new_fam, p1)
    check_no_transition_of_transition(mesh, member, fam, new_fam, scheme)


def check_no_transition_of_transition(mesh, member, fam, new_fam, scheme):
    """A new family's parent is never a transition child: if its row is an old member's,
    it is also a child of the full partition of that member's family parent."""
    old = {frozenset(r): g for g, r in enumerate(mesh.triangles.tolist()) if member[g] >= 0}
    p0 = ints(mesh.points)
    for r in new_fam.parent_triangles.tolist():
        g = old.get(frozenset(r))
        if g is not None:
            kids = children_points(p0[fam.parent_triangles[member[g]]], scheme, 1)
            key = sorted(map(tuple, p0[r].tolist()))
            assert key in [sorted(map(tuple, c.tolist())) for c in kids]


def contained_each(x, regions):
    """Whether ``x[i]`` lies in ``regions[i]`` (both ``(X, 3, 2)``)."""
    return inside(x, regions[:, None, :, :]).all(axis=1)


def check_marked_refined(mesh, fam, member, marked, fine, parents, scheme):
    """Every marked triangle is gone. One that is no transition child: the output
    triangles in it lie in the children of its partition. A marked transition child: the
    output triangles meeting its interior lie in the children of its family parent's
    partition and none is larger than it."""
    p0, p1 = ints(mesh.points), ints(fine.points)
    rows = {frozenset(r) for r in fine.triangles.tolist()}
    gone = [frozenset(r) not in rows for r in mesh.triangles[marked].tolist()]
    assert all(gone)
    t = get_scheme(scheme).n_children
    ts = np.flatnonzero(marked & (member < 0))
    kids = children_points(p0[mesh.triangles[ts]], scheme, 1).reshape(ts.size, t, 3, 2)
    sel = np.flatnonzero(np.isin(parents, ts))
    x = p1[fine.triangles[sel]]
    assert inside(x[:, None], kids[np.searchsorted(ts, parents[sel])][:, :, None]
                  ).all(axis=2).any(axis=1).all()
    gs = np.flatnonzero(marked & (member >= 0))
    if not gs.size:
        return
    fs = np.unique(member[gs])
    kids = children_points(p0[fam.parent_triangles[fs]], scheme, 1).reshape(fs.size, t, 3, 2)
    out_family = np.where(member[parents] >= 0, member[parents], -1)
    for g in gs:
        x = p1[fine.triangles[out_family == member[g]]]
        tri = p0[mesh.triangles[g]]
        meets = np.array([overlap_area(xi, tri) > 0 for xi in x])
        assert meets.sum() > 1
        own = np.arange(3 * meets.sum()).reshape(-1, 3)
        assert (twice_areas(x[meets].reshape(-1, 2), own) <= twice_areas(tri, np.arange(3))).all()
        assert contained(x[meets], kids[np.searchsorted(fs, member[g])]).all()


def overlap_area(a, b):
    """Exact area of the intersection of two counter-clockwise triangles (integer
    coordinates): ``a`` clipped by the three half-planes of ``b`` (Sutherland-Hodgman)."""
    poly = [(F(int(x)), F(int(y))) for x, y in a]
    for i in range(3):
        (px, py), (qx, qy) = b[i].tolist(), b[(i + 1) % 3].tolist()

        def side(v, px=px, py=py, qx=qx, qy=qy):
            return (qx - px) * (v[1] - py) - (qy - py) * (v[0] - px)

        out = []
        for j, v in enumerate(poly):
            w = poly[(j + 1) % len(poly)]
            sv, sw = side(v), side(w)
            if sv >= 0:
                out.append(v)
            if sv * sw < 0:
                s = sv / (sv - sw)
                out.append((v[0] + s * (w[0] - v[0]), v[1] + s * (w[1] - v[1])))
        poly = out
        if len(poly) < 3:
            return F(0)
    return sum(poly[j][0] * poly[(j + 1) % len(poly)][1]
               - poly[(j + 1) % len(poly)][0] * poly[j][1] for j in range(len(poly))) / 2


def check_rest_unchanged(mesh, member, marked, fine, parents):
    """Input triangles that are not marked, have no split edge and are not in a family
    with a marked member or a split edge keep their row; marked or split ones change."""
    edges, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    out = {tuple(e) for e in number_edges(fine.triangles, fine.n_points)[0].tolist()}
    split = np.array([tuple(e) not in out for e in edges.tolist()])
    hit = marked | split[tri_edges].any(axis=1)
    touched = np.zeros(member.max() + 2, dtype=bool)
    touched[member[hit & (member >= 0)]] = True
    affected = hit | ((member >= 0) & touched[member])
    counts = np.bincount(parents, minlength=mesh.n_triangles)
    assert (counts[~affected] == 1).all()
    np.testing.assert_array_equal(fine.triangles[np.isin(parents, np.flatnonzero(~affected))],
                                  mesh.triangles[~affected])
    assert (counts[hit & (member < 0)] > 1).all()


def check_families(fine, fam, p):
    """Each family's members lie in its parent and fill it."""
    assert fam.member.shape == (fine.n_triangles,)
    idx = np.flatnonzero(fam.member >= 0)
    assert contained_each(p[fine.triangles[idx]], p[fam.parent_triangles[fam.member[idx]]]).all()
    total = np.bincount(fam.member[idx], twice_areas(p, fine.triangles[idx]),
                        minlength=fam.n_families)
    np.testing.assert_array_equal(total, twice_areas(p, fam.parent_triangles))
    np.testing.assert_array_equal(fam.stencil[:, :3].min(axis=1), fam.parent_triangles.min(axis=1))


def check_tag_chains(mesh, fine):
    """Each tagged input edge a -> b became a chain a -> ... -> b of output tagged edges
    with its tag, on the segment; every boundary edge of the output is tagged."""
    p0, p1 = ints(mesh.points), ints(fine.points)
    e, tags = fine.edges.astype(np.int64), fine.edge_tags
    i = 0
    for (a, b), tag in zip(mesh.edges.tolist(), mesh.edge_tags.tolist(), strict=True):
        assert e[i, 0] == a
        while e[i, 1] != b:
            assert tags[i] == tag and e[i + 1, 0] == e[i, 1]
            d = p1[e[i, 1]] - p0[a]
            assert d[0] * (p0[b] - p0[a])[1] == d[1] * (p0[b] - p0[a])[0]  # on the segment
            i += 1
        assert tags[i] == tag
        i += 1
    assert i == len(e)
    b = {frozenset(x) for x in boundary_edges(fine).tolist()}
    assert b == {frozenset(x) for x in fine.edges.tolist()}


@pytest.mark.parametrize("scheme", SCHEMES)
@settings(max_examples=6, deadline=None)
@given(n=st.integers(2, 4), seed=st.integers(0, 10**6),
       fraction=st.sampled_from([0.05, 0.2, 0.5]))
def test_cycles_coarsen_transitions_and_keep_every_invariant(scheme, n, seed, fraction):
    mesh = exact_grid(n, seed)
    rng = np.random.default_rng(seed)
    k = get_scheme(scheme).stencil.per_edge
    for _ in range(3):
        fam = families_of(mesh, k)[1]
        marked = rng.random(mesh.n_triangles) < fraction
        if (fam.member >= 0).any():  # always mark a transition child
            marked[rng.choice(np.flatnonzero(fam.member >= 0))] = True
        marked[rng.integers(mesh.n_triangles)] = True
        fine, parents = refine_marked(mesh, marked, scheme)
        new_fam = families_of(fine, k)[1]
        check_step(mesh, fam, marked, fine, parents, new_fam, scheme)
        mesh = fine


@pytest.mark.parametrize("scheme", ["7t-qd", "4t-red"])
def test_refine_cycles_parents_are_nested_in_the_input(scheme):
    mesh = exact_grid(3, 4)
    rng = np.random.default_rng(1)
    fine, parents = refine_cycles(mesh, lambda m: rng.random(m.n_triangles) < 0.2, 3, scheme)
    p0, p1 = ints(mesh.points), ints(fine.points)
    assert conformity(fine).ok
    assert contained_each(p1[fine.triangles], p0[mesh.triangles[parents]]).all()
    np.testing.assert_array_equal(np.bincount(parents, twice_areas(p1, fine.triangles)),
                                  twice_areas(p0, mesh.triangles))
    np.testing.assert_array_equal(fine.cell_tags, mesh.cell_tags[parents])


def test_untouched_families_are_copied_and_a_marked_one_is_coarsened():
    mesh = jittered_grid(6, seed=21)
    fine, _ = refine_marked(mesh, [0])
    fam = families_of(fine, 2)[1]
    assert fam.n_families > 0
    # far away from everything: the families and their rows stay
    far = np.argmax(np.linalg.norm(fine.points[fine.triangles].mean(axis=1)
                                   - fine.points[fine.triangles[0]].mean(axis=0), axis=1))
    again, parents = refine_marked(fine, [far])
    kept = np.isin(parents, np.flatnonzero(fam.member >= 0))
    assert kept.sum() >= 0.5 * (fam.member >= 0).sum()
    np.testing.assert_array_equal(again.triangles[kept], fine.triangles[parents[kept]])
    # marking a member: its family's parent is partitioned, no transition of it remains
    g = int(np.flatnonzero(fam.member >= 0)[0])
    out, parents = refine_marked(fine, [g])
    fam3 = families_of(out, 2)[1]
    assert conformity(out).ok
    rows = {frozenset(r) for r in out.triangles.tolist()}
    assert frozenset(fine.triangles[g].tolist()) not in rows
    assert frozenset(fam.parent_triangles[fam.member[g]].tolist()) not in \
        {frozenset(r) for r in fam3.parent_triangles.tolist()}


def test_repeated_cycles_do_not_compound_transitions():
    """The random-mark experiment of docs/adaptive.md: with the history the minimum angle
    stays above what the same loop reaches when the history is dropped every cycle."""
    mesh = jittered_grid(5, seed=3)
    a0 = min_angles(mesh).min()
    worst = {}
    for keep_history in (True, False):
        rng = np.random.default_rng(7)
        fine = mesh
        for _ in range(7):
            fine = refine(fine, "7t-qd", marked=rng.random(fine.n_triangles) < 0.04)
            if not keep_history:
                fine = fine.replace(transitions=None)
        worst[keep_history] = min_angles(fine).min() / a0
    assert worst[True] >= 0.4
    assert worst[True] > worst[False]


def test_history_is_validated_and_can_be_dropped():
    mesh = examples.square(2)
    fine = refine(mesh, marked=[0])
    assert fine.transitions is not None and (fine.transitions[:, 0] >= 0).any()
    moved = fine.points.copy()
    g = int(np.flatnonzero(fine.transitions[:, 0] >= 0)[0])
    inner = np.setdiff1d(fine.triangles[g], fine.transitions[g])
    moved[inner] += 1e-3
    bad = fine.replace(points=moved)
    with pytest.raises(ValueError, match="transitions"):
        refine(bad, marked=[0])
    plain = refine(bad.replace(transitions=None), marked=[0])
    assert conformity(plain).ok
    with pytest.raises(ValueError, match="consecutive"):
        Families(np.r_[0, -1, 0], np.zeros((1, 3)), -np.ones((1, 10)))
    with pytest.raises(ValueError, match="stencil"):
        Families(np.r_[0, 0], np.zeros((1, 3)), -np.ones((1, 7)))
    for member in (np.r_[0, 0, 1], np.r_[0, 0, -2]):  # ids outside -1..F-1
        with pytest.raises(ValueError, match="member ids"):
            Families(member, np.zeros((1, 3)), -np.ones((1, 10)))
        assert member.flags.writeable  # a refused array is left as it was
    with pytest.raises(ValueError, match="family 1 does not"):  # one member only
        Families(np.r_[0, 0, 1], np.zeros((2, 3)), -np.ones((2, 10)))
    fam = Families(np.r_[-1, 1, 1, 0, 0, 0], np.zeros((2, 3)), -np.ones((2, 10)))
    assert fam.first().tolist() == [3, 1]


def test_history_survives_reordering_the_triangles():
    """A mesh whose transition children are not consecutive (e.g. read back from a file
    written in another order) refines like the original, up to the triangle order."""
    mesh = jittered_grid(4, seed=5)
    fine = refine(mesh, marked=[3, 7])
    order = np.random.default_rng(0).permutation(fine.n_triangles)
    shuffled = Mesh(fine.points, fine.triangles[order], fine.cell_tags[order], fine.edges,
                    fine.edge_tags, transitions=fine.transitions[order])
    g = int(np.flatnonzero(fine.transitions[:, 0] >= 0)[0])
    a, pa = refine_with_parents(fine, marked=[g])
    b, pb = refine_with_parents(shuffled, marked=[int(np.flatnonzero(order == g)[0])])
    assert triangle_keys(a.points, a.triangles) == triangle_keys(b.points, b.triangles)

    def pairs(out, parents, src):  # (child's corners, its parent's region), as a multiset
        region = np.where(src.transitions[:, :1] >= 0, src.transitions, src.triangles)
        return sorted((tuple(sorted(map(tuple, out.points[c].tolist()))),
                       tuple(sorted(map(tuple, src.points[region[p]].tolist()))))
                      for c, p in zip(out.triangles, parents, strict=True))

    assert pairs(a, pa, fine) == pairs(b, pb, shuffled)


def _shuffled(mesh, order):
    """``mesh`` with its triangles (tags, data, history) in ``order``."""
    return Mesh(mesh.points, mesh.triangles[order], mesh.cell_tags[order], mesh.edges,
                mesh.edge_tags, cell_data={k: v[order] for k, v in mesh.cell_data.items()},
                transitions=mesh.transitions[order], origins=mesh.origins[order])


def _data_by_triangle(mesh):
    """``{sorted corner coordinates: (tag, cell data values)}``."""
    return {tuple(sorted(map(tuple, mesh.points[t].tolist()))):
            (int(mesh.cell_tags[i]), *(float(v[i]) for v in mesh.cell_data.values()))
            for i, t in enumerate(mesh.triangles)}


@pytest.mark.parametrize("scheme", ["7t-qd", "7t-le", "4t-le"])
def test_what_a_familys_new_triangles_inherit_does_not_depend_on_the_triangle_order(scheme):
    """Members of a transition family with different cell data (set after refinement):
    the new triangles made from the family's parent took the data of its first row, so
    the same mesh with its rows shuffled gave other data (review, 2026-11-27). Now: the
    member with the same vertices, else the member first in coordinate order; ``parents``
    keeps mapping them to the first member (children stay in parent order)."""
    base = examples.gmsh_mesh("l_shape")
    mesh = refine(base, scheme, marked=marking.mark_box(base, (-1, -1, 0, 0)))
    mesh = refine(mesh, scheme, marked=marking.mark_box(mesh, (-0.5, -0.5, 0, 0)))
    rng = np.random.default_rng(1)
    mesh = mesh.replace(cell_tags=rng.integers(1, 4, mesh.n_triangles),
                        cell_data={"err": rng.random(mesh.n_triangles)})
    order = np.random.default_rng(3).permutation(mesh.n_triangles)
    marked = marking.mark_box(mesh, (-0.3, -0.3, 0.1, 0.1))
    with pytest.warns(UserWarning, match="holds cell tags .* take one member's tag"):
        a, pa = refine_with_parents(mesh, scheme, marked=marked)  # tags mixed on purpose
    with pytest.warns(UserWarning, match="holds cell tags .* take one member's tag"):
        b = refine(_shuffled(mesh, order), scheme, marked=marked[order])
    assert _data_by_triangle(a) == _data_by_triangle(b)
    assert (np.diff(pa) >= 0).all()  # parents: in order, as documented


@pytest.mark.parametrize("scheme", ["7t-qd", "7t-le", "7t-d"])
def test_a_triangle_made_again_keeps_its_own_cell_data(scheme):
    """A family's triangle that the step makes again (the same corners) keeps its own cell
    data, also one at the family's centroid, which the step numbers anew (review: it took
    another member's; the match was by vertex ids). Refinement and coarsening."""
    base = examples.gmsh_mesh("l_shape")

    def with_ids(mesh):
        return mesh.replace(cell_data={"id": np.arange(mesh.n_triangles, dtype=float)})

    def made_again(before, after):  # (output row, input row) with the same corners
        rows = {tuple(sorted(map(tuple, before.points[t].tolist()))): i
                for i, t in enumerate(before.triangles)}
        return [(i, rows[k]) for i, t in enumerate(after.triangles)
                if (k := tuple(sorted(map(tuple, after.points[t].tolist())))) in rows]

    cases = []
    mesh = with_ids(refine(base, scheme, marked=[0]))
    cases.append((mesh, refine(mesh, scheme, marked=[15])))
    mesh = with_ids(refine(refine(base, scheme, marked=[7]), scheme, marked=[36]))
    cases.append((mesh, coarsen(mesh, np.ones(mesh.n_triangles, dtype=bool), scheme)))
    for before, after in cases:
        pairs = made_again(before, after)
        renumbered = [i for i, j in pairs  # a point numbered anew: the review's case
                      if set(after.triangles[i]) != set(before.triangles[j])]
        assert renumbered
        for i, j in pairs:
            assert after.cell_data["id"][i] == j


@pytest.mark.parametrize("scheme, marks", [("7t-qd", "scattered"), ("7t-qd", "circle"),
                                           ("7t-le", "children"), ("4t-le", "scattered")])
def test_a_step_on_a_window_is_the_step_on_the_whole_mesh(scheme, marks, monkeypatch):
    """From 20,000 triangles on, a step runs on a window around the marks (grown where its
    rim gets split) and is stitched into the rest: over four cycles with history on a
    27,440-triangle Gmsh-made mesh, every array equals the whole-mesh step's, bit for bit,
    and windows were really used (and regrown, with scattered marks). (A transition far
    from every mark used to be upgraded by the whole-mesh step, not by the window's.)"""
    from qdrefine.adaptive import window

    base = refine(examples.gmsh_mesh("plate_with_hole"), "7t-qd", 2)
    assert base.n_triangles >= window.WHOLE_BELOW
    if marks == "scattered":
        def mark(mesh, cycle):
            return marking.mark_random(mesh, 0.003, seed=cycle)
    elif marks == "circle":
        def mark(mesh, cycle):
            return marking.mark_circle(mesh, (0.3, 0.2), 0.1 + 0.05 * cycle)
    else:  # transition children (their families are coarsened first), and a few others
        def mark(mesh, cycle):
            out = marking.mark_random(mesh, 0.002, seed=cycle)
            if mesh.transitions is not None:
                out[np.flatnonzero(mesh.transitions[:, 0] >= 0)[::5]] = True
            return out

    calls = []
    sub_step = window._sub_step
    monkeypatch.setattr(window, "_sub_step", lambda *a: calls.append(1) or sub_step(*a))
    windowed = base
    for cycle in range(4):
        marked = mark(windowed, cycle)
        monkeypatch.setattr(window, "WHOLE_BELOW", 20_000)
        a, pa = refine_with_parents(windowed, scheme, marked=marked)
        monkeypatch.setattr(window, "WHOLE_BELOW", 10**9)
        b, pb = refine_with_parents(windowed, scheme, marked=marked)
        for name in ("points", "triangles", "cell_tags", "edges", "edge_tags", "transitions"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        np.testing.assert_array_equal(pa, pb)
        windowed = a
    assert calls  # windows were used (a window over 30% of the mesh is given up)
    if marks == "scattered" and scheme == "7t-qd":
        assert len(calls) > 4  # and a window regrown where its rim was split


def test_a_waiting_upgrade_across_the_rim_grows_the_window(monkeypatch):
    """A transition left waiting for an upgrade (judged outside the closure of its step's
    marks, with no split edge across its ``NO``) is upgraded by the first later step that
    changes the triangle across ``NO``, however far that step's marks are. A window that
    holds that triangle but not the transition must grow (the window's step does not see
    the transition and leaves that rim edge unsplit): the result equals the whole-mesh
    step's, with the transition upgraded. The window is forced to be everything but the
    transition: any window must give the whole step's result."""
    from qdrefine.adaptive import window
    from qdrefine.adaptive.edgekeys import KEY, edge_keys
    from qdrefine.adaptive.labels import canonical_labels
    from qdrefine.adaptive.rounds import waiting_upgrades

    mesh = refine(examples.gmsh_mesh("boundary_layer"), "7t-qd", 1)
    for cycle in range(3):
        mesh = refine(mesh, "7t-qd", marked=marking.mark_random(mesh, 0.05, seed=30 + cycle))
    fam = families_of(mesh, 2)[1]
    rows = fam.parent_triangles
    g = np.arange(rows.shape[0])
    labels = canonical_labels(mesh.points, rows)
    no = edge_keys(rows[g, labels[:, 1]], rows[g, labels[:, 2]])
    waiting = np.flatnonzero(waiting_upgrades(mesh.points, fam, g, no, get_scheme("7t-qd")))
    assert waiting.size
    t = mesh.triangles
    f = int(waiting[0])
    a, b = divmod(int(no[f]), int(KEY))
    members = np.flatnonzero(fam.member == f)
    across = [u for u in np.flatnonzero((t == a).any(1) & (t == b).any(1))
              if fam.member[u] != f]
    assert len(across) == 1 and fam.member[across[0]] < 0  # U: plain, no split edge
    u = across[0]
    # X: a neighbour of U across another edge; marking it changes U, not by splitting NO
    x = next(v for j in range(3) if {t[u, j], t[u, (j + 1) % 3]} != {a, b}
             for v in np.flatnonzero((t == t[u, j]).any(1) & (t == t[u, (j + 1) % 3]).any(1))
             if v != u)
    marked = np.zeros(mesh.n_triangles, dtype=bool)
    marked[x] = True
    monkeypatch.setattr(window, "WHOLE_BELOW", 10**9)
    whole, p_whole = refine_with_parents(mesh, "7t-qd", marked=marked)
    upgraded = np.isin(p_whole, members)
    assert not np.array_equal(whole.triangles[upgraded], t[members])  # the upgrade is made

    monkeypatch.setattr(window, "WHOLE_BELOW", 0)
    monkeypatch.setattr(window, "WHOLE_ABOVE", 1.01)
    grown = window._grown
    first = []

    def everything_but_the_transition(triangles, n_points, seed, rings):
        if first:
            return grown(triangles, n_points, seed, rings)
        first.append(1)
        out = np.ones(triangles.shape[0], dtype=bool)
        out[members] = False
        return out

    monkeypatch.setattr(window, "_grown", everything_but_the_transition)
    calls = []
    sub_step = window._sub_step
    monkeypatch.setattr(window, "_sub_step", lambda *a: calls.append(1) or sub_step(*a))
    windowed, p_windowed = refine_with_parents(mesh, "7t-qd", marked=marked)
    assert first and len(calls) >= 2  # the forced window was used, then grown
    for name in ("points", "triangles", "transitions"):
        np.testing.assert_array_equal(getattr(windowed, name), getattr(whole, name),
                                      err_msg=name)
    np.testing.assert_array_equal(p_windowed, p_whole)


@pytest.mark.parametrize("name, scheme, fraction", [
    ("plate_with_hole", "7t-qd", 0.01), ("boundary_layer", "7t-qd", 0.02),
    ("step", "7t-le", 0.01), ("l_shape", "4t-le", 0.03), ("graded", "7t-d", 0.01)])
def test_scattered_marks_start_from_the_reached_triangles(name, scheme, fraction,
                                                          monkeypatch):
    """Scattered marks on a mesh without history: two rings around every mark would cover
    much of the mesh, so the window starts from the estimate of what the step reaches
    (``adaptive/reach.py``); the step equals the whole-mesh step bit for bit, the window
    is much smaller than the rings, and on meshes without thin triangles the estimate
    holds every triangle the step changes (one window, not regrown)."""
    from qdrefine.adaptive import reach, window

    base = refine(examples.gmsh_mesh(name), scheme, 2)
    marked = marking.mark_random(base, fraction, seed=3)
    sizes, estimates = [], []
    sub_step, estimate = window._sub_step, reach.reached_triangles
    monkeypatch.setattr(window, "_sub_step",
                        lambda mesh, w, *a: sizes.append(int(w.sum())) or sub_step(mesh, w, *a))
    monkeypatch.setattr(window, "reached_triangles",
                        lambda *a: estimates.append(estimate(*a)) or estimates[-1])
    monkeypatch.setattr(window, "WHOLE_BELOW", 0)
    a, pa = refine_with_parents(base, scheme, marked=marked)
    # over the marks, under the estimate: the whole mesh, with the estimate's verdicts
    monkeypatch.setattr(window, "WHOLE_ABOVE", 1.5 * marked.mean())
    c, pc = refine_with_parents(base, scheme, marked=marked)
    monkeypatch.setattr(window, "WHOLE_BELOW", 10**9)  # the whole mesh, no estimate
    b, pb = refine_with_parents(base, scheme, marked=marked)
    for field in ("points", "triangles", "cell_tags", "edges", "edge_tags", "transitions"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
        np.testing.assert_array_equal(getattr(c, field), getattr(b, field), err_msg=field)
    np.testing.assert_array_equal(pa, pb)
    np.testing.assert_array_equal(pc, pb)
    assert len(estimates) == 2 and len(sizes) >= 1
    assert estimates[1][0].mean() > 1.5 * marked.mean()  # so it was given up
    rings = window._grown(base.triangles, base.n_points, marked, 2)
    assert sizes[0] < 0.6 * rings.sum()
    reached, verdicts = estimates[0]
    changed = np.bincount(pb, minlength=base.n_triangles) != 1
    assert not (changed & ~reached).any() or name == "boundary_layer"
    if name != "boundary_layer":
        assert len(sizes) == 1
    if scheme.startswith("7t"):  # upgrades judged on the way
        assert (verdicts[reached & ~marked, 0] >= 0).any()


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 300), max_size=60), st.lists(st.integers(0, 320), max_size=60))
def test_lookup_sorted_is_lookup_for_increasing_queries(keys, query):
    from qdrefine.adaptive.edgekeys import lookup, lookup_sorted

    k = np.unique(np.array(keys, dtype=np.int64))
    q = np.unique(np.array(query, dtype=np.int64))
    np.testing.assert_array_equal(lookup_sorted(k, q), lookup(k, q))
    if q.size > 1:
        with pytest.raises(ValueError, match="not increasing"):
            lookup_sorted(k, q[::-1].copy())


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.tuples(st.integers(0, 5), st.integers(0, 5), st.integers(0, 5)),
                          st.integers(1, 4)), min_size=1, max_size=20), st.booleans())
def test_unique_rows_is_numpy_unique(runs, shuffle):
    """Rows in runs (a family's members), a row possibly in two runs, or shuffled."""
    from qdrefine.adaptive.history import _unique_rows

    rows = np.array([r for r, n in runs for _ in range(n)], dtype=np.int64)
    if shuffle:
        rows = rows[np.random.default_rng(len(rows)).permutation(len(rows))]
    uniq, inverse = np.unique(rows, axis=0, return_inverse=True)
    got_uniq, got_inverse = _unique_rows(rows)
    np.testing.assert_array_equal(got_uniq, uniq)
    np.testing.assert_array_equal(got_inverse, inverse.reshape(-1))


@pytest.mark.parametrize("k", [1, 2])
def test_pattern_writes_the_same_children_into_given_rows(k):
    """``pattern(..., out, rows)`` writes exactly the children it returns, mirrored
    triangles (clockwise labels) included, and nothing else."""
    from qdrefine.adaptive.patterns import PARTIAL, pattern, tables

    rng = np.random.default_rng(k)
    perms = np.array([[0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 2, 1], [2, 1, 0], [1, 0, 2]],
                     dtype=np.int8)
    for code in PARTIAL:
        tris, cand, count = tables(k, code)
        g = 30
        ids = rng.integers(0, 10**6, size=(g, int(tris.max()) + 1)).astype(np.int64)
        labels = perms[rng.integers(0, 6, g)]
        choice = rng.integers(0, cand.shape[0], g)
        kids = pattern(ids, labels, k, code, choice)
        n = count[choice]
        assert kids.shape == (n.sum(), 3)
        for i in range(g):  # each child is a candidate triangle of the stencil, oriented
            local = tris[cand[choice[i], :n[i]]]
            if (labels[i, 1] - labels[i, 0]) % 3 != 1:
                local = local[:, [0, 2, 1]]
            np.testing.assert_array_equal(kids[n[:i].sum():n[:i + 1].sum()], ids[i][local])
        out = np.full((n.sum() + 7, 3), -9, dtype=np.int64)
        rows = 3 + np.cumsum(n) - n
        pattern(ids, labels, k, code, choice, out, rows)
        np.testing.assert_array_equal(out[3:3 + n.sum()], kids)
        assert (out[:3] == -9).all() and (out[3 + n.sum():] == -9).all()


@pytest.mark.parametrize("name, scheme", [("l_shape", "7t-qd"), ("boundary_layer", "7t-qd"),
                                          ("plate_with_hole", "7t-le"), ("step", "4t-le")])
def test_an_advanced_round_numbers_the_working_mesh_as_from_scratch(name, scheme,
                                                                    monkeypatch):
    """After an expansion the next round advances the previous numbering
    (``plan.advanced``) instead of numbering the working mesh again: on cycles with
    history (random marks, their transitions' families coarsened and refined again) every
    array, the edges' incidence included, equals ``plan.working_edges`` of the same tree,
    and advanced rounds really ran."""
    from qdrefine.adaptive import plan, rounds

    checked = []
    advanced = plan.advanced

    def checking(tree, cl, own, kids):
        got, expected = advanced(tree, cl, own, kids), plan.working_edges(tree)
        for field in ("leaves", "triangles", "edges", "tri_edges", "counts", "keys", "pos",
                      "labels", "ce", "split"):
            a, b = getattr(got, field), getattr(expected, field)
            assert a.dtype == b.dtype, field
            np.testing.assert_array_equal(a, b, err_msg=field)
        for a, b in zip(got.around, expected.around, strict=True):
            np.testing.assert_array_equal(a, b)
        checked.append(int(own.sum()))
        return got

    monkeypatch.setattr(rounds, "advanced", checking)
    mesh = examples.gmsh_mesh(name)
    for cycle in range(4):
        mesh = refine(mesh, scheme, marked=marking.mark_random(mesh, 0.15, seed=cycle))
    assert len(checked) >= 3 and sum(checked) > 0


@pytest.mark.parametrize("scheme", ["7t-qd", "7t-le", "4t-le"])
@pytest.mark.parametrize("name", ["plate_with_hole", "boundary_layer"])
def test_kept_families_are_the_ones_the_history_rebuilds(name, scheme):
    """The families a refinement keeps on its output for the next call (so that call does
    not rebuild them from ``transitions``) are exactly what ``families_of`` rebuilds from
    the rows, cycle after cycle and after coarsening; never pickled; not used once an array
    of the mesh is made writeable again."""
    import pickle

    from qdrefine import coarsen, examples
    from qdrefine.marking import mark_random

    k = get_scheme(scheme).stencil.per_edge
    mesh = examples.gmsh_mesh(name)
    kept_seen = 0
    for cycle in range(5):
        if cycle == 3:
            mesh = coarsen(mesh, mark_random(mesh, 0.5, seed=cycle), scheme)
        else:
            mesh = refine(mesh, scheme, marked=mark_random(mesh, 0.05, seed=cycle))
        kept = mesh.__dict__.get("_families")
        plain = Mesh._trusted(mesh.points, mesh.triangles, transitions=mesh.transitions)
        _, rebuilt, order = families_of(plain, k)
        if kept is None:  # no transition child left
            assert rebuilt.n_families == 0
            continue
        kept_seen += 1
        assert order is None
        for field in ("member", "parent_triangles", "stencil"):
            assert np.array_equal(getattr(kept, field), getattr(rebuilt, field)), field
        assert families_of(mesh, k)[1] is kept
        assert "_families" not in pickle.loads(pickle.dumps(mesh)).__dict__
    assert kept_seen >= 3
    mesh.transitions.flags.writeable = True  # a user who breaks immutability on purpose
    assert families_of(mesh, k)[1] is not mesh.__dict__["_families"]


def test_origins_naming_a_removed_centroid_are_refused():
    """Origins set by hand to rows that name a transition's centroid (which the next
    refinement removes when it coarsens that transition) give one clear error, not origin
    rows with -1 (or, before, another point's id) in the output."""
    from qdrefine.marking import mark_random

    base = examples.gmsh_mesh("plate_with_hole")
    fine = refine(base, "7t-qd", marked=mark_random(base, 0.1, seed=3))
    anew = fine.replace(origins=fine.triangles)
    green = np.flatnonzero(anew.transitions[:, 0] >= 0)
    with pytest.raises(ValueError, match="names the centroid of a transition"):
        refine(anew, "7t-qd", marked=green[::5])
    again = refine(fine, "7t-qd", marked=green[::5])  # the history as refinement left it
    assert again.origins.min() >= 0


@pytest.mark.parametrize("scheme", ["7t-qd", "4t-le"])
def test_a_family_missing_a_member_is_refused(scheme):
    """A submesh cut out of a refined mesh, one transition child left out with its history
    kept: the family no longer covers its parent, and refining or coarsening it would put
    the removed triangle back (the area grew from 2.9965 to 3.0 before this was checked).
    The message names a remaining member, by its row in the mesh as given, shuffled too."""
    mesh = examples.gmsh_mesh("l_shape")
    fine = refine(mesh, scheme, marked=marking.mark_point(mesh, (0, 0), 0.3))
    green = np.flatnonzero(fine.transitions[:, 0] >= 0)
    for gone in green[[0, len(green) // 2, -1]]:
        keep = np.flatnonzero(np.arange(fine.n_triangles) != gone)
        order = keep[np.random.default_rng(int(gone)).permutation(keep.size)]
        sub = Mesh(fine.points, fine.triangles[order], fine.cell_tags[order],
                   transitions=fine.transitions[order], origins=fine.origins[order])
        for call in (lambda s=sub: refine(s, scheme, marked=[0]),
                     lambda s=sub: coarsen(s, np.ones(s.n_triangles, dtype=bool), scheme)):
            with pytest.raises(HistoryMismatch, match="does not cover") as info:
                call()
            named = info.value.triangle
            assert (sub.transitions[named] == fine.transitions[gone]).all()
            assert f"triangle {named} " in str(info.value)
    # the whole family removed is a valid history (its parent's region is a hole now)
    family = np.flatnonzero((fine.transitions == fine.transitions[green[0]]).all(axis=1))
    keep = np.setdiff1d(np.arange(fine.n_triangles), family)
    sub = Mesh(fine.points, fine.triangles[keep], fine.cell_tags[keep],
               transitions=fine.transitions[keep], origins=fine.origins[keep])
    assert conformity(refine(sub, scheme, marked=[0])).ok


def test_the_history_names_are_reserved_for_cell_data():
    """A cell field named like the history's file fields would be overwritten by it in
    every file written: refused when the mesh is made."""
    mesh = examples.square(2)
    for name in ("qdrefine:transitions", "qdrefine:origins"):
        with pytest.raises(ValueError, match=rf"cell_data\['{name}'\]: this name is reserved"):
            mesh.replace(cell_data={name: np.zeros((mesh.n_triangles, 3), np.int64)})


@pytest.mark.parametrize("name", ["l_shape", "plate_with_hole"])
def test_the_boundary_kept_through_refinement_is_the_boundary(name):
    """Local refinement cuts the input's boundary as it cuts tagged edges and keeps it on
    its output, to check that rounding did not make it cross itself: after cycles of
    scattered marks (transitions coarsened and refined again), two levels, uniform levels
    and a coarsening, it is the boundary found from the triangles (an independent count
    of each edge's triangles)."""
    from qdrefine.boundaries import boundary_edges as kept
    from qdrefine.topology import unique_edges

    def oracle(mesh):
        _, tri_edges, counts = unique_edges(mesh)
        t, i = np.nonzero(counts[tri_edges] == 1)
        rows = mesh.triangles
        return sorted(zip(rows[t, i].tolist(), rows[t, (i + 1) % 3].tolist(), strict=True))

    mesh = examples.gmsh_mesh(name)
    for cycle in range(5):
        marks = marking.mark_random(mesh, 0.1, seed=cycle)
        mesh = refine(mesh, "7t-qd", marked=marks, levels=2 if cycle == 3 else 1)
        assert "_boundary" in mesh.__dict__
        assert sorted(map(tuple, kept(mesh).tolist())) == oracle(mesh), cycle
    mesh = coarsen(mesh, marking.mark_random(mesh, 0.5))
    assert sorted(map(tuple, kept(mesh).tolist())) == oracle(mesh)
    mesh = refine(refine(mesh, "7t-qd"), "7t-qd", marked=[0, 5])
    assert sorted(map(tuple, kept(mesh).tolist())) == oracle(mesh)
    plain = examples.gmsh_mesh(name)  # the midpoints of 4T
    for cycle in range(3):
        plain = refine(plain, "4t-le", marked=marking.mark_random(plain, 0.1, seed=cycle))
        assert sorted(map(tuple, kept(plain).tolist())) == oracle(plain), cycle


def test_local_refinement_refuses_what_rounding_makes_cross():
    """Two parts a float step apart: the local step returned a mesh that crossed itself
    (review), as uniform refinement did."""
    from qdrefine.uniform import RefusedTriangle

    mesh = Mesh(*crack(1, 0.375, 1e3, 1e-3))
    with pytest.raises(RefusedTriangle, match=r"^triangle 0 \(0, 1, 2\) is closer to another "
                                              "part of the mesh than float64"):
        refine(mesh, "7t-qd", marked=[0])
    assert refine(mesh, "7t-qd", marked=[1]).n_triangles == 8  # its edges stay whole
