"""Uniform refinement of whole meshes: conformity, areas, tags, parents, invariance."""

from fractions import Fraction as F

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import qdrefine
from meshes import jittered_grid
from oracle import exact, orient
from qdrefine import Mesh, examples, partition, refine, refine_with_parents, scheme_names
from qdrefine.kernels import number_edges, rounding_suspects
from qdrefine.predicates import orient_signs
from qdrefine.schemes import get_scheme
from qdrefine.topology import boundary_edges, conformity, euler_characteristic
from shapes import triangle_set

SCHEMES = scheme_names()
mesh_params = st.tuples(st.integers(1, 7), st.integers(0, 10**6), st.sampled_from([0, 0.5, 40.0]))


def check_valid(mesh: Mesh, fine: Mesh) -> None:
    assert conformity(fine).ok
    assert euler_characteristic(fine) == euler_characteristic(mesh)
    assert (orient_signs(fine.points, fine.triangles) > 0).all()


@pytest.mark.parametrize("scheme", SCHEMES)
@settings(max_examples=25, deadline=None)
@given(params=mesh_params, levels=st.integers(1, 2))
def test_refined_mesh_is_conforming(scheme, params, levels):
    mesh = jittered_grid(*params)
    fine, parents = refine_with_parents(mesh, scheme, levels)
    check_valid(mesh, fine)
    t = get_scheme(scheme).n_children ** levels
    assert fine.n_triangles == mesh.n_triangles * t
    np.testing.assert_array_equal(parents, np.repeat(np.arange(mesh.n_triangles), t))
    np.testing.assert_array_equal(fine.cell_tags, mesh.cell_tags[parents])
    np.testing.assert_array_equal(fine.points[: mesh.n_points], mesh.points)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_children_areas_sum_to_parent_exactly_on_an_exact_grid(scheme):
    """Coordinates that are multiples of 6 make every new point exact: equality holds."""
    mesh = jittered_grid(4, seed=5, shuffle=True)
    mesh = Mesh(np.round(mesh.points * 96) * 6, mesh.triangles)
    fine, parents = refine_with_parents(mesh, scheme)
    pts = [exact(p) for p in fine.points]
    child = [orient(pts[a], pts[b], pts[c]) for a, b, c in fine.triangles]
    total = [F(0)] * mesh.n_triangles
    for c, p in zip(child, parents, strict=True):
        total[p] += c
    old = [exact(p) for p in mesh.points]
    assert total == [orient(old[a], old[b], old[c]) for a, b, c in mesh.triangles]


@pytest.mark.parametrize("scheme", SCHEMES)
def test_children_areas_sum_to_parent_within_the_rounding_bound(scheme):
    """Children tile the polygon through the stored (rounded) edge points exactly, so with
    ``d`` the largest L1 displacement of a stored new point from its exact position and ``L``
    the parent's L1 perimeter, ``|sum(children) - parent| <= 3 L d + 3 d^2`` (twice-areas,
    exact arithmetic; per edge a-p1-p2-b the change is cross(x1-a, d2) + cross(d1, x2-a) +
    cross(d1, d2) + cross(d2, b-a))."""
    mesh = jittered_grid(5, seed=8, shear=3.0)
    fine, parents = refine_with_parents(mesh, scheme)
    pts = [exact(p) for p in fine.points]
    old = pts[: mesh.n_points]
    k = get_scheme(scheme).stencil.per_edge
    edges = number_edges(mesh.triangles, mesh.n_points)[0]
    d = F(0)
    for g, (a, b) in enumerate(edges.tolist()):
        for j in range(k):
            s = F(j + 1, k + 1)
            x = old[a][0] + s * (old[b][0] - old[a][0])
            y = old[a][1] + s * (old[b][1] - old[a][1])
            p = pts[mesh.n_points + g * k + j]
            d = max(d, abs(p[0] - x) + abs(p[1] - y))
    assert d > 0  # the bound is exercised, not trivially zero
    total = [F(0)] * mesh.n_triangles
    for (a, b, c), p in zip(fine.triangles, parents, strict=True):
        total[p] += orient(pts[a], pts[b], pts[c])
    for t, (a, b, c) in enumerate(mesh.triangles):
        parent = orient(old[a], old[b], old[c])
        perimeter = sum(abs(old[i][0] - old[j][0]) + abs(old[i][1] - old[j][1])
                        for i, j in ((a, b), (b, c), (c, a)))
        assert abs(total[t] - parent) <= 3 * perimeter * d + 3 * d * d


@pytest.mark.parametrize("scheme", SCHEMES)
def test_triangle_and_vertex_order_do_not_matter(scheme):
    mesh = jittered_grid(6, seed=3, shear=0.7, shuffle=False)
    ref = triangle_set(*_arrays(refine(mesh, scheme, 2)))
    rng = np.random.default_rng(0)
    for _ in range(3):
        perm = rng.permutation(mesh.n_points)
        inv = np.argsort(perm)
        tris = inv[mesh.triangles][rng.permutation(mesh.n_triangles)]
        tris = np.roll(tris, rng.integers(3), axis=1)  # rotate each triangle's vertex list
        shuffled = Mesh(mesh.points[perm], tris)
        assert triangle_set(*_arrays(refine(shuffled, scheme, 2))) == ref


def _arrays(mesh):
    return mesh.points, mesh.triangles


@pytest.mark.parametrize("scheme", SCHEMES)
def test_tagged_edges_follow_the_boundary(scheme):
    mesh = examples.plate_with_hole(16, 3)
    fine = refine(mesh, scheme, 2)
    pieces = (get_scheme(scheme).stencil.per_edge + 1) ** 2
    assert len(fine.edges) == len(mesh.edges) * pieces
    np.testing.assert_array_equal(fine.edge_tags, np.repeat(mesh.edge_tags, pieces))
    # every boundary edge of the refined mesh is tagged, with its parent's tag
    b = {frozenset(e) for e in boundary_edges(fine).tolist()}
    assert b == {frozenset(e) for e in fine.edges.tolist()}
    # pieces chain from the parent edge's first to its last vertex
    chains = fine.edges.reshape(len(mesh.edges), pieces, 2)
    np.testing.assert_array_equal(chains[:, 0, 0], mesh.edges[:, 0])
    np.testing.assert_array_equal(chains[:, -1, 1], mesh.edges[:, 1])
    np.testing.assert_array_equal(chains[:, 1:, 0], chains[:, :-1, 1])


def test_zero_levels_and_bad_levels():
    mesh = examples.square(2)
    assert refine(mesh, levels=0) is mesh
    for bad in (-1, 1.5, "2"):
        with pytest.raises(ValueError, match="levels"):
            refine(mesh, levels=bad)
    with pytest.raises(ValueError, match="unknown scheme"):
        refine(mesh, "7T-QD ")


def test_right_isosceles_grid_with_exact_ties():
    mesh = examples.square(8)
    for scheme in SCHEMES:
        fine = refine(mesh, scheme, 2)
        check_valid(mesh, fine)


def test_output_is_bit_identical_for_any_thread_count():
    import numba

    mesh = jittered_grid(40, seed=2, shear=0.3)
    results = []
    for threads in sorted({1, numba.config.NUMBA_NUM_THREADS}):
        numba.set_num_threads(threads)
        fine = refine(mesh, "7t-qd", 2)
        results.append((fine.points.tobytes(), fine.triangles.tobytes()))
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    assert all(r == results[0] for r in results)


# --- rounding of the new points ---------------------------------------------------------

NEEDLE_FAR = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1e-9]]) + 1e7


@pytest.mark.parametrize("scheme", ["7t-qd", "7t-d", "4t-le"])
def test_a_needle_far_from_the_origin_is_refused_not_returned_broken(scheme):
    mesh = Mesh(NEEDLE_FAR, [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"triangle 0 \(0, 1, 2\) is too thin for its "
                                         r"distance from the origin"):
        refine(mesh, scheme)
    with pytest.raises(ValueError, match="too thin"):
        qdrefine.partition(NEEDLE_FAR, scheme)
    with pytest.raises(ValueError, match="too thin"):
        refine(mesh, scheme, marked=[0])
    raw = refine(mesh, scheme, strict=False)  # what the check refuses: a degenerate child
    assert (orient_signs(raw.points, raw.triangles) <= 0).any()
    # the same needle near the origin is fine
    near = refine(Mesh(NEEDLE_FAR - 1e7, [[0, 1, 2]]), scheme)
    assert (orient_signs(near.points, near.triangles) > 0).all()


@settings(max_examples=300, deadline=None)
@given(st.floats(-30, 30), st.floats(-30, 30), st.floats(-12, 0), st.floats(0.001, 1),
       st.integers(0, 1))
def test_triangles_not_flagged_never_get_a_bad_child(log_offset_x, log_offset_y, log_height,
                                                     apex, turn):
    """The float screen of :func:`kernels.rounding_suspects` is certified: whenever it lets
    a triangle through, every child is counter-clockwise (checked exactly)."""
    base = np.array([[0.0, 0.0], [1.0, 0.0], [apex, 10.0**log_height]])
    if turn % 2:
        base = base[:, ::-1].copy()  # needles along y as well as along x
    pts = base + [np.sign(log_offset_x) * 10 ** abs(log_offset_x) / 1e10,
                  np.sign(log_offset_y) * 10 ** abs(log_offset_y) / 1e10]
    t = np.array([[0, 1, 2]])
    if orient_signs(pts, t)[0] <= 0:
        t = t[:, ::-1].copy()
    if orient_signs(pts, t)[0] <= 0:
        return  # the rounded apex fell on the base: not a triangle
    mesh = Mesh(pts, t)
    for scheme in ("7t-qd", "4t-red"):
        k = get_scheme(scheme).stencil.per_edge
        fine = refine(mesh, scheme, strict=False)
        flagged = rounding_suspects(mesh.points, mesh.triangles, k + 1)[0]
        if not flagged:
            assert (orient_signs(fine.points, fine.triangles) > 0).all()


def test_refinement_stays_in_the_range_of_exact_predicates():
    """A mesh at the lower end of the coordinate range (review): its new points would fall
    below 1e-100, which Mesh and partition refuse (exactness); refine says so instead of
    returning a mesh it cannot take back. One level of a mesh whose smallest coordinate is
    1e-83 provably stays in range (no check); complex coordinates are refused, not cast."""
    tiny = Mesh(np.array([[0.0, 0.0], [1.2e-100, 0.0], [0.0, 1.2e-100]]), [[0, 1, 2]])
    for call in (lambda: refine(tiny), lambda: refine_with_parents(tiny, "4t-le"),
                 lambda: refine(tiny, marked=[0])):
        with pytest.raises(ValueError, match=r"refining this mesh makes new point 3 at "
                                             r"\([46]e-101, 0\.0\), below the supported range"):
            call()
    # a second local level reached it inside the step, where the message named a "vertex 0"
    # that is no vertex of the input (review)
    wide = Mesh([[0, 0], [1e100, 0], [0, 1e-100], [1e100, 1e100]], [[0, 1, 2], [1, 3, 2]])
    with pytest.raises(ValueError, match=r"^refining this mesh makes a new point at \(.*\), "
                                         r"below the supported range"):
        refine(wide, marked=[0], levels=2)
    # a mesh refined before keeps a lower bound of its smallest coordinate: the message
    # gave the bound (2.28597e-100) as the mesh's smallest coordinate (GPU review)
    a, b = 2.0**-276, -(2.0**-276 - 2.0**-328)
    once = refine(Mesh([[a, 0], [0, 1], [b, 0]], [[0, 1, 2]]), "4t-red")
    with pytest.raises(ValueError, match="the mesh's smallest nonzero coordinate is 9.1439e-100"):
        refine(once, "4t-red", 4)
    small = Mesh(tiny.points * 1e17, tiny.triangles)
    fine = refine(small)
    assert Mesh(fine.points, fine.triangles).n_triangles == 7  # valid input again
    with pytest.raises(ValueError, match="points must be real numbers, got dtype complex128"):
        Mesh(np.array([[0, 0], [1, 0], [0, 1j]]), [[0, 1, 2]])
    with pytest.raises(ValueError, match="vertices must be real numbers"):
        partition([[0, 0], [1, 0], [0.3, 0.5 + 2j]])
