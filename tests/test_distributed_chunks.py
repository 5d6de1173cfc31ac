"""The per-chunk passes of the distributed level against NumPy and the in-memory kernels
(the level's own tests compare whole refinements with ``qdrefine.refine``)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qdrefine import examples
from qdrefine.distributed.chunks import (
    child_coordinates,
    distinct,
    edge_ends,
    global_children,
    merge_sorted,
    new_points,
)
from qdrefine.kernels import edge_points, emit, number_edges
from qdrefine.schemes import get_scheme

values = st.lists(st.integers(-50, 50), max_size=200).map(lambda v: np.array(v, np.int64))


@settings(max_examples=200, deadline=None)
@given(values)
def test_distinct_is_unique_up_to_which_occurrence(v):
    keys, one, inverse = distinct(v)
    expected, back = np.unique(v, return_inverse=True)
    assert np.array_equal(keys, expected) and np.array_equal(inverse, back)
    assert np.array_equal(v[one], keys)
    assert distinct(v, inverse=False)[2] is None


@settings(max_examples=200, deadline=None)
@given(st.lists(st.lists(st.integers(0, 40), max_size=30, unique=True), max_size=12))
def test_merge_sorted_runs(runs):
    runs = [np.sort(np.array(r, np.int64)) for r in runs]
    keys = np.concatenate(runs) if runs else np.empty(0, np.int64)
    starts = np.concatenate([[0], np.cumsum([len(r) for r in runs])]).astype(np.int64)
    first, inverse = merge_sorted(keys, starts)
    expected, back = np.unique(keys, return_inverse=True)
    assert np.array_equal(keys[first], expected)
    assert np.array_equal(inverse, back)


@pytest.mark.parametrize("k", [1, 2])
def test_new_points_and_edge_ends_are_the_kernels_bits(k):
    mesh = examples.jittered_square(6, seed=3, shuffle="points")
    t = mesh.triangles.astype(np.int64)
    edges, _, _ = number_edges(mesh.triangles, mesh.n_points)
    expected = np.empty((mesh.n_points + k * len(edges), 2))
    edge_points(mesh.points, edges, k, expected)
    # the half-edges of the first occurrence of every edge, in edge order
    lo, hi = np.minimum(t, np.roll(t, -1, axis=1)), np.maximum(t, np.roll(t, -1, axis=1))
    key = (lo * mesh.n_points + hi).ravel()
    _, first = np.unique(key, return_index=True)
    ends = edge_ends(t, mesh.points[t], first)
    assert np.array_equal(ends, np.hstack([mesh.points[edges[:, 0]], mesh.points[edges[:, 1]]]))
    assert np.array_equal(new_points(ends, k), expected[mesh.n_points:])
    # at given places, an edge twice: the same bits
    at = np.concatenate([np.arange(len(edges))[::-1], [0]])
    out = np.full((len(edges) * k, 2), np.nan)
    new_points(np.vstack([ends[::-1], ends[:1]]), k, at, out)
    assert np.array_equal(out, expected[mesh.n_points:])


@pytest.mark.parametrize("scheme", ["7t-qd", "4t-red"])
def test_children_rows_and_coordinates(scheme):
    sch = get_scheme(scheme)
    k = sch.stencil.per_edge
    mesh = examples.jittered_square(5, seed=4, shuffle="points")
    t = mesh.triangles.astype(np.int64)
    edges, tri_edges, _ = number_edges(mesh.triangles, mesh.n_points)
    # half-edge (v_i, v_i+1) ids, as the level computes them
    lo, hi = np.minimum(t, np.roll(t, -1, axis=1)), np.maximum(t, np.roll(t, -1, axis=1))
    key = lo * mesh.n_points + hi
    gid = np.searchsorted(edges[:, 0].astype(np.int64) * mesh.n_points + edges[:, 1], key)
    children = np.empty((len(t) * sch.n_children, 3), dtype=np.int64)
    emit(mesh.points, t, gid, k, sch.forms, sch.lut, sch.tables, children)
    # the chunk's vertices as ranks of global rows 3 i + 1 of a mesh of 1000 points
    rows = np.empty(children.shape, dtype=np.int32)
    global_children(children, 3 * np.arange(mesh.n_points) + 1, 1000, rows)
    u = mesh.n_points
    assert np.array_equal(rows, np.where(children < u, 3 * children + 1, 1000 + children - u))
    all_points = np.empty((mesh.n_points + k * len(edges), 2))
    edge_points(mesh.points, edges, k, all_points)
    xy = child_coordinates(mesh.points, t, gid, children, k)
    assert np.array_equal(xy, all_points[children])
