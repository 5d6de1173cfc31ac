"""Marking helpers."""

from fractions import Fraction as F

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from meshes import jittered_grid
from qdrefine import Mesh, examples, marking
from qdrefine.marking import (
    mark_box,
    mark_dorfler,
    mark_ids,
    mark_mask,
    mark_maximum,
    mark_region,
    mark_tag,
)


def test_ids_mask_and_tag():
    mesh = examples.plate_with_hole(8, 2)
    m = mark_ids(mesh, [0, 5, 5])
    assert m.dtype == bool and m.shape == (mesh.n_triangles,)
    assert np.flatnonzero(m).tolist() == [0, 5]
    assert not mark_ids(mesh, []).any()
    with pytest.raises(ValueError, match="outside"):
        mark_ids(mesh, [mesh.n_triangles])
    with pytest.raises(ValueError, match="mark_mask"):
        mark_ids(mesh, np.ones(mesh.n_triangles, bool))
    mask = np.arange(mesh.n_triangles) % 3 == 0
    np.testing.assert_array_equal(mark_mask(mesh, mask), mask)
    with pytest.raises(ValueError, match="boolean"):
        mark_mask(mesh, mask.astype(int))
    left = mark_tag(mesh, examples.LEFT)
    np.testing.assert_array_equal(left, mesh.cell_tags == examples.LEFT)
    assert mark_tag(mesh, [examples.LEFT, examples.RIGHT]).all()
    with pytest.raises(ValueError, match="no cell tags"):
        mark_tag(examples.square(2), 1)


def test_region_on_centroids():
    mesh = examples.square(4)
    m = mark_region(mesh, lambda c: c[:, 0] + c[:, 1] < 0.5)
    c = mesh.points[mesh.triangles].mean(axis=1)
    np.testing.assert_array_equal(m, c.sum(axis=1) < 0.5)
    with pytest.raises(ValueError, match="boolean"):
        mark_region(mesh, lambda c: c[:, 0])


def _box_hits_by_sampling(p, box):
    """Brute force: dense barycentric samples of the triangle inside the box, or a box
    corner inside the triangle."""
    x0, y0, x1, y1 = box
    w = np.array([(i, j, 60 - i - j) for i in range(61) for j in range(61 - i)]) / 60
    s = w @ p
    if ((s[:, 0] >= x0) & (s[:, 0] <= x1) & (s[:, 1] >= y0) & (s[:, 1] <= y1)).any():
        return True
    q = [(F(float(a)), F(float(b))) for a, b in p]  # exact: a corner may be a hair outside
    for cx, cy in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)):
        cx, cy = F(cx), F(cy)
        d = [(q[(i + 1) % 3][0] - q[i][0]) * (cy - q[i][1])
             - (q[(i + 1) % 3][1] - q[i][1]) * (cx - q[i][0]) for i in range(3)]
        if min(d) >= 0:
            return True
    return None  # undecided by sampling: an edge barely crossing a corner


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10**6), x=st.floats(-0.2, 1.0), y=st.floats(-0.2, 1.0),
       w=st.floats(0.0, 0.5), h=st.floats(0.0, 0.5))
@example(seed=0, x=-1.1754943508222875e-38, y=0.0, w=0.0, h=0.0)  # a hair left of a vertex
def test_box_marks_the_triangles_it_meets(seed, x, y, w, h):
    mesh = jittered_grid(4, seed)
    box = (x, y, x + w, y + h)
    try:
        m = mark_box(mesh, box)
    except ValueError as exc:  # a coordinate within the mesh of magnitude below 1e-100
        assert "outside the supported range" in str(exc)
        assert any(0 < abs(v) < 1e-100 for v in box)
        return
    for t in range(mesh.n_triangles):
        truth = _box_hits_by_sampling(mesh.points[mesh.triangles[t]], box)
        if truth:
            assert m[t]


def _exactly_in_closed_triangle(corners, q) -> bool:
    """Whether the point ``q`` lies in the closed counter-clockwise triangle, in rationals."""
    q = [F(v) for v in q]
    for i in range(3):
        a, c = ([F(v) for v in corners[j]] for j in (i, (i + 1) % 3))
        if (c[0] - a[0]) * (q[1] - a[1]) - (c[1] - a[1]) * (q[0] - a[0]) < 0:
            return False
    return True


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), t=st.integers(0, 31), edge=st.integers(0, 2),
       s=st.floats(0.0, 1.0), nudge=st.integers(-2, 2))
@example(seed=0, t=0, edge=0, s=0.0, nudge=0).via("a point box at a vertex")
@example(seed=0, t=1, edge=0, s=0.0, nudge=1).via("5e-324 above a vertex at y = 0")
def test_a_point_box_marks_exactly_the_triangles_that_hold_the_point(seed, t, edge, s, nudge):
    """A point box on (or a few ulps off) a triangle's edge marks exactly the triangles
    that hold the point, by a rational oracle: the float side test missed a triangle
    holding a point 1.6e-17 (exactly) inside it, and marked no triangle at all (review)."""
    mesh = jittered_grid(4, seed)  # 32 triangles
    a, c = mesh.points[mesh.triangles[t, edge]], mesh.points[mesh.triangles[t, (edge + 1) % 3]]
    q = a + s * (c - a)
    q = np.array([q[0], np.nextafter(q[1], np.sign(nudge) * np.inf) if nudge else q[1]])
    if ((0 < np.abs(q)) & (np.abs(q) < 1e-100)).any():  # e.g. 5e-324 beside 0: refused
        with pytest.raises(ValueError, match="box corner 0 has a coordinate .* outside the "
                                             "supported range"):
            mark_box(mesh, (q[0], q[1], q[0], q[1]))
        return
    marks = mark_box(mesh, (q[0], q[1], q[0], q[1]))
    truth = [_exactly_in_closed_triangle(mesh.points[mesh.triangles[k]], q)
             for k in range(mesh.n_triangles)]
    np.testing.assert_array_equal(marks, truth)


def test_a_box_reaching_the_float_limit_is_decided_exactly():
    """Box corners near 1e308 overflowed the exact predicates (a triangle beyond the box's
    corner was marked; review): the box is taken within the mesh's extent."""
    mesh = Mesh([[0.0, 0], [4, 0], [0, 4]], [[0, 1, 2]])
    big = np.finfo(float).max
    assert not mark_box(mesh, (3, 3, 1e308, 1e308))[0]  # beyond the hypotenuse
    assert mark_box(mesh, (2, 2, big, big))[0]  # touches it at (2, 2)
    assert mark_box(mesh, (-big, -big, big, big))[0]


def test_a_point_box_inside_a_thin_triangle_marks_it():
    o, a, c = (0.6666666666666666, 0.0), (1.0, 0.0), (1.757722778427078, 0.3333333333333333)
    q = (0.8134855524694892, 0.04485528111104853)  # exactly inside, by 1.6e-17
    assert _exactly_in_closed_triangle([o, a, c], q)
    assert mark_box(Mesh(np.array([o, a, c]), np.array([[0, 1, 2]])), (*q, *q))[0]


def test_box_rejects_a_triangle_whose_bounding_box_overlaps():
    mesh = Mesh([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], [[0, 1, 2]])
    assert not mark_box(mesh, (0.8, 0.8, 1.0, 1.0))[0]  # beyond the hypotenuse
    assert mark_box(mesh, (0.5, 0.5, 1.0, 1.0))[0]  # touches it at (0.5, 0.5)
    assert mark_box(mesh, (0.1, 0.1, 0.2, 0.2))[0]  # inside
    assert mark_box(mesh, (-1, -1, 2, 2))[0]  # around
    assert not mark_box(mesh, (1.1, 0.0, 2.0, 1.0))[0]
    with pytest.raises(ValueError, match="box"):
        mark_box(mesh, (1, 0, 0, 1))


@settings(max_examples=50, deadline=None)
@given(eta=st.lists(st.floats(0, 100), min_size=1, max_size=40),
       theta=st.floats(0.01, 1.0))
def test_dorfler_is_a_smallest_bulk_of_the_largest(eta, theta):
    eta = np.array(eta)
    m = mark_dorfler(eta, theta)
    total = eta.sum()
    if total == 0:
        assert not m.any()
        return
    assert eta[m].sum() >= theta * total * (1 - 1e-12)
    # largest first: every marked value >= every unmarked one
    if m.any() and (~m).any():
        assert eta[m].min() >= eta[~m].max()
    # smallest: a zero adds nothing (theta = 1 of [0.1] * 10 + [0] took it: the target was
    # eta.sum(), rounded otherwise than the cumulative sum; review)
    assert (eta[m] > 0).all()
    # smallest: dropping the smallest marked value (all of its ties) falls short
    kept = m & (eta > eta[m].min())
    if kept.any():  # (theta * 5e-324 underflows to 0)
        assert eta[kept].sum() < theta * total * (1 + 1e-12)
    # every tie of the smallest marked value is marked, in any triangle order
    assert (m == (eta >= eta[m].min())).all()
    order = np.random.default_rng(len(eta)).permutation(len(eta))
    assert (mark_dorfler(eta[order], theta) == m[order]).all()


def test_dorfler_of_equal_values_and_a_zero():
    assert mark_dorfler([0.1] * 10 + [0.0], 1.0).tolist() == [True] * 10 + [False]


def test_dorfler_marks_do_not_depend_on_the_triangle_order():
    """Ties were broken by triangle index, so renumbering a mesh marked (and refined)
    other triangles (review): every value tied with the last one taken is marked."""
    assert mark_dorfler([1.0, 2.0, 2.0, 1.0], 0.4).tolist() == [False, True, True, False]
    assert mark_dorfler([2.0, 1.0, 1.0, 1.0, 1.0], 0.5).tolist() == [True] * 5
    mesh = examples.square(2)
    flipped = Mesh(mesh.points, mesh.triangles[::-1])
    eta = np.ones(mesh.n_triangles)
    a = marking.centroids(mesh)[mark_dorfler(eta, 0.5)]
    b = marking.centroids(flipped)[mark_dorfler(eta[::-1], 0.5)]
    assert sorted(map(tuple, a)) == sorted(map(tuple, b))


def test_geometric_marks_refuse_bad_arguments():
    """A 3-D point was NumPy's broadcasting error; a fraction of 2, a negative or NaN radius
    were taken (review)."""
    from qdrefine.marking import mark_circle, mark_point, mark_random

    mesh = examples.square(2)
    for call, message in [(lambda: mark_point(mesh, (0, 0, 0)), "point must be two finite"),
                          (lambda: mark_point(mesh, (0, 0), np.nan), "radius must be finite"),
                          (lambda: mark_circle(mesh, (0, 0), -1.0), "radius must be finite"),
                          (lambda: mark_circle(mesh, (0, 0), 1.0, -2), "size must be finite"),
                          (lambda: mark_random(mesh, 2.0), r"fraction must be in \[0, 1\]")]:
        with pytest.raises(ValueError, match=message):
            call()


def test_maximum_strategy_and_bad_indicators():
    eta = np.array([0.0, 1.0, 4.0, 3.0, 2.0])
    assert mark_maximum(eta, 0.5).tolist() == [False, False, True, True, True]
    assert not mark_maximum(np.zeros(3), 0.5).any()
    for bad in ([-1.0, 2.0], [np.nan], [[1.0]]):
        with pytest.raises(ValueError):
            mark_dorfler(bad, 0.5)
    with pytest.raises(ValueError, match="theta"):
        mark_dorfler([1.0], 0.0)
    with pytest.raises(ValueError, match="theta"):
        mark_maximum([1.0], 1.5)


def test_mark_tag_of_a_missing_tag_lists_the_tags_present():
    mesh = examples.plate_with_hole()
    with pytest.raises(ValueError, match=r"no triangle has cell tag 7 \(cell tags: 1, 2\)"):
        mark_tag(mesh, [1, 7])


def test_an_integer_mask_is_not_taken_for_indices(tmp_path):
    """One 0/1 integer per triangle (a mask saved as integers) is refused, not read as the
    indices 0 and 1 (which would silently mark two triangles): by ``refine``, ``coarsen``
    and ``--mark-file``'s ``.npy``; a genuine index list is still indices."""
    import qdrefine
    from qdrefine.marking import mark_file

    mesh = examples.plate_with_hole()
    mask = np.zeros(mesh.n_triangles, dtype=np.uint8)
    mask[::3] = 1
    for call in (lambda: qdrefine.refine(mesh, marked=mask),
                 lambda: qdrefine.coarsen(mesh, mask.astype(int))):
        with pytest.raises(ValueError, match="all 0 or 1, one per triangle"):
            call()
    np.save(tmp_path / "m.npy", mask)
    with pytest.raises(ValueError, match=r"m\.npy: .* all 0 or 1, one per triangle"):
        mark_file(mesh, tmp_path / "m.npy")
    (tmp_path / "m.txt").write_text("\n".join(map(str, mask)) + "\n")
    with pytest.raises(ValueError, match=r"m\.txt: .* all 0 or 1, one per triangle"):
        mark_file(mesh, tmp_path / "m.txt")
    fine = qdrefine.refine(mesh, marked=mask.astype(bool))
    assert fine.n_triangles > mesh.n_triangles + 300
    assert np.array_equal(qdrefine.refine(mesh, marked=[0, 1]).triangles,
                          qdrefine.refine(mesh, marked=np.arange(mesh.n_triangles) < 2).triangles)


def test_mark_tag_takes_integer_tags_only():
    """``mark_tag(mesh, 1.7)`` marked the triangles of tag 1 (review)."""
    mesh = examples.plate_with_hole()
    with pytest.raises(ValueError, match="cell tags are integers, got 1.7"):
        marking.mark_tag(mesh, 1.7)
    assert marking.mark_tag(mesh, np.int32(1)).sum() == (mesh.cell_tags == 1).sum()


def test_dorfler_with_theta_one_marks_every_nonzero_indicator():
    """The rounded cumulative sum reached its total at the first entry: [1, 1e-20] marked
    only the first, short of the whole sum (review)."""
    assert mark_dorfler([1.0, 1e-20], 1.0).tolist() == [True, True]
    assert mark_dorfler([1.0, 0.0, 3.0], 1.0).tolist() == [True, False, True]


def test_centroids_do_not_depend_on_the_vertex_order():
    """A triangle's centroid was rounded differently when its vertices were listed in
    another order, so mark_random and mark_region could mark differently at a threshold
    (review: 23,094 of 192,000 centroids differed)."""
    mesh = jittered_grid(40, 40, 0.45, True)
    rotated = Mesh(mesh.points, np.roll(mesh.triangles, 1, axis=1))
    a, b = marking.centroids(mesh), marking.centroids(rotated)
    assert np.array_equal(a.view(np.uint64), b.view(np.uint64))
    u = np.sin(a @ np.array([12.9898, 78.233])) * 43758.5453
    fraction = float(np.sort(u - np.floor(u))[len(u) // 2])  # a threshold on a triangle
    assert np.array_equal(marking.mark_random(mesh, fraction),
                          marking.mark_random(rotated, fraction))


def test_a_mark_file_with_a_byte_order_mark_and_a_tag_beyond_int64(tmp_path):
    """A mark file saved with a UTF-8 byte-order mark (Windows Notepad) was refused as
    "'\\ufeff1' is not a triangle id"; the tag 2**64 - 1 was named -1 (review)."""
    path = tmp_path / "ids.txt"
    path.write_text("1 2\n", encoding="utf-8-sig")
    assert marking.mark_file(examples.square(2), path).nonzero()[0].tolist() == [1, 2]
    with pytest.raises(ValueError, match="no triangle has cell tag 18446744073709551615"):
        mark_tag(examples.plate_with_hole(8, 2), np.uint64(2**64 - 1))
