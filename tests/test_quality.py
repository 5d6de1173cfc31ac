"""Per-triangle quality measures against values derived by hand."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshes import jittered_grid
from qdrefine import Mesh, examples, quality, refine

SQRT3 = np.sqrt(3.0)
EQUILATERAL = (np.array([[0.0, 0.0], [2.0, 0.0], [1.0, SQRT3]]), np.array([[0, 1, 2]]))
# right isosceles with legs 1: r = (2 - sqrt2) / 2, R = sqrt2 / 2
RIGHT = (np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), np.array([[0, 1, 2]]))


def test_equilateral_is_perfect_on_every_measure():
    p, t = EQUILATERAL
    np.testing.assert_allclose(quality.angles(p, t), [[60, 60, 60]])
    np.testing.assert_allclose(quality.radius_ratios(p, t), [1.0])
    np.testing.assert_allclose(quality.aspect_ratios(p, t), [1.0])
    np.testing.assert_allclose(quality.areas(p, t), [SQRT3])
    np.testing.assert_allclose(quality.edge_lengths(p, t), [[2, 2, 2]])


def test_right_isosceles_values():
    p, t = RIGHT
    np.testing.assert_allclose(quality.angles(p, t), [[90, 45, 45]])
    r, big_r = (2 - np.sqrt(2)) / 2, np.sqrt(2) / 2
    np.testing.assert_allclose(quality.radius_ratios(p, t), [2 * r / big_r])
    # longest side sqrt2, smallest altitude sqrt2/2; equilateral ratio 2/sqrt3
    np.testing.assert_allclose(quality.aspect_ratios(p, t), [2 / (2 / SQRT3)])
    np.testing.assert_allclose(quality.max_angles(p, t), [90])
    np.testing.assert_allclose(quality.min_angles(p, t), [45])


def test_mesh_and_arrays_agree_and_misuse_is_refused():
    m = examples.plate_with_hole()
    np.testing.assert_array_equal(quality.min_angles(m), quality.min_angles(m.points,
                                                                            m.triangles))
    with pytest.raises(TypeError):
        quality.min_angles(m.points)
    with pytest.raises(TypeError):
        quality.min_angles(m, m.triangles)
    with pytest.raises(ValueError, match=r"\(M, 3\)"):
        quality.min_angles(m.points, m.triangles[:, :2])
    # a -1 measured another triangle (NumPy wraps it), an index too large was NumPy's
    # IndexError, floats were taken (review)
    points = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    for name in ("min_angles", "angles", "radius_ratios", "aspect_ratios", "areas"):
        with pytest.raises(ValueError, match=r"triangle 0 \(0, 1, -1\) has a vertex index "
                                             r"outside 0\.\.3"):
            getattr(quality, name)(points, [[0, 1, -1]])
    with pytest.raises(ValueError, match=r"triangle 1 \(1, 3, 4\) has a vertex index"):
        quality.min_angles(points, [[0, 1, 2], [1, 3, 4]])
    with pytest.raises(TypeError, match="integer vertex indices, got float64"):
        quality.min_angles(points, [[0.0, 1.0, 2.0]])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), shear=st.one_of(st.just(0.0), st.floats(0.01, 3.0)))
def test_invariants_on_random_meshes(seed, shear):
    m = jittered_grid(5, seed, shear=shear)
    a = quality.angles(m)
    np.testing.assert_allclose(a.sum(axis=1), 180.0)
    assert (quality.areas(m) > 0).all()
    rr, ar = quality.radius_ratios(m), quality.aspect_ratios(m)
    assert ((rr > 0) & (rr <= 1 + 1e-12)).all() and (ar >= 1 - 1e-12).all()
    # similarity invariance: rotate, scale, translate, reflect
    c, s = np.cos(0.7), np.sin(0.7)
    moved = 3.5 * m.points @ np.array([[c, -s], [s, c]]).T + [10.0, -4.0]
    mirror = moved * [-1.0, 1.0]
    for p, t in ((moved, m.triangles), (mirror, m.triangles[:, ::-1])):
        np.testing.assert_allclose(quality.radius_ratios(p, t), rr, rtol=1e-9)
        np.testing.assert_allclose(quality.aspect_ratios(p, t), ar, rtol=1e-9)
        np.testing.assert_allclose(np.sort(quality.angles(p, t), 1), np.sort(a, 1), atol=1e-9)
    # one value per triangle, in triangle order
    rolled = np.roll(m.triangles, 1, axis=1)
    np.testing.assert_allclose(quality.min_angles(m.points, rolled), quality.min_angles(m))


def test_similarity_classes():
    p = np.array([[0.0, 0.0], [1.0, 0.0], [0.2, 0.6],  # a triangle
                  [5.0, 5.0], [5.0, 7.0], [3.8, 5.4],  # the same, rotated and doubled
                  [0.0, 9.0], [-1.0, 9.0], [-0.2, 9.6],  # mirrored
                  [3.0, 0.0], [4.0, 0.0], [3.5, 1.0]])  # another shape
    t = np.array([[0, 1, 2], [3, 4, 5], [6, 8, 7], [9, 10, 11]])
    labels, shapes = quality.similarity_classes(p, t)
    assert labels[0] == labels[1] == labels[2] != labels[3]
    assert shapes.shape == (2, 3)
    np.testing.assert_allclose(shapes.sum(axis=1), 180.0)
    # red refinement keeps one shape: four children similar to the parent
    one = Mesh(p[:3], t[:1])
    assert quality.similarity_classes(refine(one, "4t-red", 3))[0].max() == 0
    # the tolerance matters: two shapes 1e-3 degrees apart merge at tolerance 1
    q = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, 0.5], [0.0, 2.0], [1.0, 2.0], [0.3, 2.50001]])
    tt = np.array([[0, 1, 2], [3, 4, 5]])
    assert quality.similarity_classes(q, tt)[0].tolist() == [0, 1]
    assert quality.similarity_classes(q, tt, tolerance=1.0)[0].tolist() == [0, 0]
    with pytest.raises(ValueError, match="tolerance"):
        quality.similarity_classes(q, tt, tolerance=0)


def test_min_angle_histogram_counts_every_triangle():
    m = refine(examples.plate_with_hole(), "7t-qd")
    counts, edges = quality.min_angle_histogram(m, bin_width=5)
    assert counts.sum() == m.n_triangles
    np.testing.assert_allclose(edges, np.arange(0, 61, 5))
    mins = quality.min_angles(m)
    assert counts[int(mins.min() // 5)] > 0
    p, t = EQUILATERAL  # 60 degrees (or a rounding above) lands in the last bin
    assert quality.min_angle_histogram(p, t)[0][-1] == 1
    with pytest.raises(ValueError, match="bin_width"):
        quality.min_angle_histogram(m, bin_width=0)
    for width in (1e-8, 1e-300, float("nan")):  # 1e-8 asked for 45 GiB (review)
        with pytest.raises(ValueError, match=r"bin_width must be in \[6e-05, 60\] degrees "
                                             r"\(at most 1000000 bins\)"):
            quality.min_angle_histogram(m, bin_width=width)
    assert len(quality.min_angle_histogram(m, bin_width=60 / quality.MAX_BINS)[0]) == \
        quality.MAX_BINS


def test_similarity_classes_are_not_split_by_rounding_noise():
    """Red refinement makes no new shape, wherever the mesh is: rounding each angle to the
    nearest multiple of the tolerance split classes whose angles sat near a multiple (the
    L-shape moved 1e5 counted more classes per level; numbers review, 2026-11-27).
    Touching cells keep them together, at the origin and far from it; at the origin for
    the smallest tolerance allowed too (moved 1e5, the points are rounded by about 1e-11,
    and the angles of these 0.1-sized triangles by about 1e-8 degrees: more than 1e-12)."""
    mesh = examples.gmsh_mesh("l_shape")
    for offset, tolerances in ((0.0, (1e-6, 1e-12)), (1e5, (1e-6,)), (5e5, (1e-6,))):
        moved = Mesh(mesh.points + offset, mesh.triangles)
        for tolerance in tolerances:
            counts = [quality.similarity_classes(refine(moved, "4t-red", k),
                                                 tolerance=tolerance)[0].max() + 1
                      for k in range(4)]
            assert counts == [counts[0]] * 4, (offset, tolerance, counts)


def test_touching_cells_form_one_class():
    """Cells of side ``tolerance`` that touch by a corner are one class; two apart are
    not (an oracle of the rule on hand-made angles)."""
    from qdrefine.quality import _touching_cells

    cells = np.array([[0, 0], [1, 1], [3, 1], [3, 2], [5, 5]], dtype=np.int64)
    assert _touching_cells(cells).tolist() == [0, 0, 1, 1, 2]


@pytest.mark.parametrize("scale", [1e-90, 1e-81, 1e-40, 1.0, 1e40, 1e90, 4e99])
def test_ratios_at_every_scale(scale):
    """2r/R was 0 for triangles of size 1e-81 (4 cross^2 underflowed) and NaN at 1e90 (the
    product of the lengths overflowed): it is scale-free, like the aspect ratio. An
    equilateral triangle has exactly 1 for both, never 1 + 1 ulp."""
    p = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, 0.8]]) * scale
    a, b, c = 1.0, np.hypot(0.7, 0.8), np.hypot(0.3, 0.8)
    area = 0.4
    expected = 16 * area**2 / ((a + b + c) * a * b * c)
    np.testing.assert_allclose(quality.radius_ratios(p, [[0, 1, 2]]), [expected], rtol=1e-13)
    np.testing.assert_allclose(quality.aspect_ratios(p, [[0, 1, 2]]),
                               [np.sqrt(3) * b**2 / (4 * area)], rtol=1e-13)
    s = np.sqrt(3.0) / 2
    equilateral = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, s]]) * scale
    assert quality.radius_ratios(equilateral, [[0, 1, 2]])[0] <= 1.0
    assert quality.aspect_ratios(equilateral, [[0, 1, 2]])[0] >= 1.0


def test_report_compare_takes_one_scheme_name_and_checks_levels():
    """``compare(mesh, "7t-qd", levels=0)`` gave rows for the schemes '7', 't', '-', ...;
    ``levels=1.5`` was a raw TypeError (review)."""
    from qdrefine import report

    mesh = examples.square(2)
    assert [r["scheme"] for r in report.compare(mesh, "7T-QD", levels=1)] == ["7t-qd"] * 2
    with pytest.raises(ValueError, match="levels must be an integer, got 1.5"):
        report.compare(mesh, levels=1.5)
    with pytest.raises(ValueError, match="unknown scheme '8t'"):
        report.compare(mesh, ["8t"], levels=0)


def test_similarity_classes_chain_past_the_tolerance():
    """Touching cells join, so finely spread shapes make one class wider than the
    tolerance (the guide says so; the reports said "equal within" the tolerance, review):
    400 separate triangles whose apex height steps by 1e-8."""
    k = np.arange(400)
    points = np.stack([np.c_[3.0 * k, 0 * k], np.c_[3.0 * k + 1, 0 * k],
                       np.c_[3.0 * k + 0.3, 0.8 + 1e-8 * k]], axis=1).reshape(-1, 2)
    mesh = Mesh(points, np.arange(3 * 400).reshape(-1, 3))
    labels, _ = quality.similarity_classes(mesh, tolerance=1e-6)
    smallest = np.sort(quality.angles(mesh), axis=1)[:, 0]
    assert np.unique(labels).size == 1
    assert np.ptp(smallest) > 100 * 1e-6  # 1.4e-4 degrees


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_figures_do_not_depend_on_the_numbering_or_the_first_vertex(seed):
    """The area, radius and aspect ratios of a triangle changed in their last bit with the
    vertex its row starts at, and the reports' sums and means with the triangle order
    (review: info's area, quality's mean radius ratio, compare's mean minimum angle)."""
    from qdrefine import report

    mesh = refine(examples.plate_with_hole(12, 3), "7t-qd")
    rng = np.random.default_rng(seed)
    points = rng.permutation(mesh.n_points)
    renumber = np.argsort(points)
    rows = rng.permutation(mesh.n_triangles)
    turns = rng.integers(0, 3, mesh.n_triangles)
    triangles = renumber[mesh.triangles[rows]]
    triangles = triangles[np.arange(len(rows))[:, None], (turns[:, None] + np.arange(3)) % 3]
    other = Mesh(mesh.points[points], triangles, cell_tags=mesh.cell_tags[rows],
                 edges=renumber[mesh.edges], edge_tags=mesh.edge_tags,
                 physical_names=mesh.physical_names)
    for measure in (quality.areas, quality.radius_ratios, quality.aspect_ratios):
        assert np.array_equal(measure(mesh)[rows], measure(other)), measure.__name__
    assert report.info(mesh) == report.info(other)
    assert report.quality(mesh) == report.quality(other)
    assert report.compare(mesh, ["7t-qd"], 1) == report.compare(other, ["7t-qd"], 1)
