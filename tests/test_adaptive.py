"""Adaptive (marked) refinement: conformity, closure, patterns, areas, tags, quality."""

from fractions import Fraction as F

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshes import jittered_grid
from oracle import exact, orient
from qdrefine import Mesh, examples, partition_many, refine, refine_with_parents, scheme_names
from qdrefine.adaptive import (
    canonical_edges,
    canonical_labels,
    closure,
    refine_cycles,
    refine_marked,
)
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
    # each split edge has k new points, shared: the point count matches
    k = sch.stencil.per_edge
    assert fine.n_points == mesh.n_points + k * int(split.sum())
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
    while True:
        grow = naive.copy()
        grow[ce[naive[ce].any(axis=1), 0]] = True
        if (grow == naive).all():
            break
        naive = grow
    np.testing.assert_array_equal(split, naive)


def test_longest_edge_of_canonical_labels_is_longest():
    mesh = jittered_grid(6, seed=9, shear=2.0)
    edges, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    ce = canonical_edges(canonical_labels(mesh.points, mesh.triangles), tri_edges)
    length = np.linalg.norm(mesh.points[edges[:, 0]] - mesh.points[edges[:, 1]], axis=1)
    assert (length[ce[:, 0]] >= length[ce].max(axis=1)).all()
    assert (length[ce[:, 0]] > length[ce[:, 1:]].min(axis=1)).all()


@settings(max_examples=15, deadline=None)
@given(params=mesh_params, mk=marks, keep=st.sampled_from([0.3, 0.5, 0.7]))
def test_transition_children_respect_the_quality_floor(params, mk, keep):
    mesh = jittered_grid(*params)
    marked = random_marks(mesh, *mk)
    floor = keep * min_angles(mesh).min()
    fine, parents = refine_marked(mesh, marked, "7t-qd", min_angle=floor)
    assert conformity(fine).ok
    counts = np.bincount(parents, minlength=mesh.n_triangles)
    transition = np.isin(parents, np.flatnonzero((counts > 1) & (counts < 7)))
    assert (min_angles(fine)[transition] >= floor).all()


def test_repeated_cycles_keep_half_the_initial_minimum_angle():
    """Random marks are the adversarial case (they hit transition children): without a
    fixed floor the minimum angle falls cycle after cycle."""
    mesh = jittered_grid(5, seed=3)
    rng = np.random.default_rng(7)

    def mark(m):
        return rng.random(m.n_triangles) < 0.04

    fine, parents = refine_cycles(mesh, mark, 7, "7t-qd", keep=0.5)
    assert conformity(fine).ok
    assert fine.n_triangles > 20 * mesh.n_triangles
    np.testing.assert_array_equal(fine.cell_tags, mesh.cell_tags[parents])
    assert min_angles(fine).min() >= 0.45 * min_angles(mesh).min()


def test_bad_marks_raise():
    mesh = examples.square(2)
    for bad, what in (([8], "outside"), ([-1], "outside"), (np.ones(3, bool), "shape"),
                      ([0.5], "dtype"), ([[0, 1]], "one-dimensional")):
        with pytest.raises(ValueError, match=what):
            refine(mesh, marked=bad)
    with pytest.raises(ValueError, match="levels"):
        refine(mesh, levels=-1, marked=[0])
    with pytest.raises(ValueError, match="cycles"):
        refine_cycles(mesh, lambda m: [0], -1)
