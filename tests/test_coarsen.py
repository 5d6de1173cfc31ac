"""Coarsening (``qdrefine.coarsen``): the inverse of local refinement, on Gmsh-made meshes
and on grids (where a group of children straddling two parents is a partition too)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import qdrefine
from qdrefine import Mesh, coarsen, examples, marking, refine
from qdrefine.adaptive import coarsen_marked
from qdrefine.adaptive import red_families as red_module
from qdrefine.adaptive.families import smallest_first
from qdrefine.adaptive.history import families_of
from qdrefine.topology import conformity, euler_characteristic

SCHEMES = ["7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"]


def _rows(mesh):
    """Triangle rows, each rotated to start at its smallest id."""
    t = mesh.triangles.astype(np.int64)
    shift = np.argmin(t, axis=1)[:, None]
    return np.take_along_axis(t, (shift + np.arange(3)) % 3, axis=1)


def _twice_areas(mesh):
    p = mesh.points[mesh.triangles]
    return ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
            - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))


def _with_data(mesh):
    """``mesh`` with a linear point field and a cell field."""
    x, y = mesh.points.T
    return mesh.replace(point_data={"u": 2.0 * x - 3.0 * y + 1.0},
                        cell_data={"id": np.arange(mesh.n_triangles) % 5})


def _all_the_way_back(mesh, scheme):
    """Coarsen everything until nothing changes."""
    for _ in range(20):
        out = coarsen(mesh, np.ones(mesh.n_triangles, dtype=bool), scheme)
        if out.n_triangles == mesh.n_triangles:
            return out
        mesh = out
    raise AssertionError("coarsening did not stop")


def _assert_same(a, b):
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.triangles, b.triangles)  # rows as given, rotation too
    for name in ("cell_tags", "edges", "edge_tags"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert dict(a.physical_names) == dict(b.physical_names)
    for name in b.point_data:
        np.testing.assert_array_equal(a.point_data[name], b.point_data[name])
    for name in b.cell_data:
        np.testing.assert_array_equal(a.cell_data[name], b.cell_data[name])


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("name", ["l_shape", "plate_with_hole", "boundary_layer", "grid"])
def test_coarsening_everything_gives_the_input_back(name, scheme):
    """Three cycles of local refinement (random marks, marks on transition children
    among them), then coarsening of every triangle, again and again: the input comes
    back, bit for bit: points, triangles in their order, tags, tagged edges (joined
    again), physical names, point and cell data; with no transitions left."""
    base = examples.square(4) if name == "grid" else examples.gmsh_mesh(name)
    base = _with_data(base)
    mesh = base
    for cycle in range(3):
        mesh = refine(mesh, scheme, marked=marking.mark_random(mesh, 0.15, seed=cycle))
    assert mesh.origins is not None and mesh.transitions is not None
    back = _all_the_way_back(mesh, scheme)
    _assert_same(back, base)
    assert back.transitions is None
    np.testing.assert_array_equal(back.origins, base.triangles)


def _valid(mesh, before):
    """Conforming, oriented, the same region and topology, every triangle in its origin,
    and a history the next refinement reads."""
    assert conformity(mesh).ok
    assert (_twice_areas(mesh) > 0).all()
    assert euler_characteristic(mesh) == euler_characteristic(before)
    assert np.isclose(_twice_areas(mesh).sum(), _twice_areas(before).sum(), rtol=1e-12)
    Mesh(mesh.points, mesh.triangles, mesh.cell_tags, mesh.edges, mesh.edge_tags)
    origin = mesh.points[mesh.origins]  # (M, 3, 2)
    centre = mesh.points[mesh.triangles].mean(axis=1)
    for i in range(3):
        a, b = origin[:, i], origin[:, (i + 1) % 3]
        assert ((b[:, 0] - a[:, 0]) * (centre[:, 1] - a[:, 1])
                - (b[:, 1] - a[:, 1]) * (centre[:, 0] - a[:, 0]) > 0).all()
    families_of(mesh, 2)


@settings(max_examples=12, deadline=None)
@given(ops=st.lists(st.tuples(st.booleans(), st.floats(0.05, 0.6), st.integers(0, 10**6)),
                    min_size=2, max_size=7),
       name=st.sampled_from(["l_shape", "plate_with_hole", "step"]))
def test_refining_and_coarsening_in_any_order_keeps_a_valid_mesh(ops, name):
    """Any sequence of local refinements and coarsenings with random marks (7T-QD): the
    mesh stays conforming, covers the same region, each triangle lies in its origin,
    and coarsening everything afterwards gives the input back."""
    base = examples.gmsh_mesh(name)
    mesh = base
    for refine_step, fraction, seed in ops:
        if refine_step:  # at most about 10,000 marks: seven steps of 60% grew to millions
            fraction = min(fraction, 10_000 / mesh.n_triangles)
        marked = marking.mark_random(mesh, fraction, seed=seed)
        out = refine(mesh, "7t-qd", marked=marked) if refine_step else \
            coarsen(mesh, marked) if mesh.origins is not None else mesh
        if out is not mesh:
            _valid(out, mesh)
        mesh = out
    if mesh.origins is not None:
        _assert_same(_all_the_way_back(mesh, "7t-qd"), base)


def test_coarsening_is_local():
    """Coarsening a box of the plate changes nothing more than two vertex rings away from
    it (it undoes what the refinement's closure did there, which reaches that far on
    this mesh; along a boundary layer's long edges it reaches much further)."""
    mesh = examples.gmsh_mesh("plate_with_hole")
    for cycle in range(3):
        mesh = refine(mesh, marked=marking.mark_random(mesh, 0.3, seed=cycle))
    box = marking.mark_box(mesh, (-1, -1, -0.3, -0.3))
    out, parents = coarsen_marked(mesh, box)
    assert out.n_triangles < mesh.n_triangles
    near = box.copy()
    for _ in range(2):
        touched = np.zeros(mesh.n_points, dtype=bool)
        touched[mesh.triangles[near].reshape(-1)] = True
        near = touched[mesh.triangles].any(axis=1)
    # the triangles far from the box are in the output, as they were
    far = np.flatnonzero(~near)
    kept = {tuple(r) for r in out.points[out.triangles].reshape(-1, 6).tolist()}
    assert all(tuple(r) in kept for r in mesh.points[mesh.triangles[far]].reshape(-1, 6).tolist())
    assert set(parents.tolist()) >= set(far.tolist())


@pytest.mark.parametrize("scheme, base", [("4t-le", examples.square(3)),
                                          ("7t-qd", examples.plate_with_hole())])
def test_a_lattice_partition_that_is_no_parent_is_not_restored(scheme, base, monkeypatch):
    """On uniformly refined meshes, groups of children straddling two parents are exact
    partitions too (with 4T-LE on a grid, two levels down: 44 of 116; with 7T-QD on the
    plate, three levels down: 12 of 18,828): they are found, and refused, because no
    descent from their origin meets them. Taking them anyway gives another mesh, or none;
    refusing them, everything comes back."""
    levels = 2 if scheme == "4t-le" else 3
    mesh = base
    for _ in range(levels):
        mesh = refine(mesh, scheme, marked=np.ones(mesh.n_triangles, dtype=bool))
    everything = np.ones(mesh.n_triangles, dtype=bool)
    accepted = []
    check = red_module.in_hierarchy
    monkeypatch.setattr(red_module, "in_hierarchy",
                        lambda *a: accepted.append(check(*a)) or accepted[-1])
    right = coarsen(mesh, everything, scheme)
    assert (~np.concatenate(accepted)).any()  # lattice partitions were found and refused
    monkeypatch.setattr(red_module, "in_hierarchy", lambda *a: np.ones(a[2].shape[0], bool))
    try:
        wrong = coarsen(mesh, everything, scheme)
    except (ValueError, RuntimeError):
        wrong = None
    assert wrong is None or wrong.n_triangles != right.n_triangles \
        or not np.array_equal(_rows(wrong), _rows(right))
    monkeypatch.undo()
    _assert_same(_all_the_way_back(right, scheme), base)


@settings(max_examples=20, deadline=None)
@given(st.sampled_from(["l_shape", "plate_with_hole", "boundary_layer"]),
       st.integers(0, 2**32 - 1))
def test_vertex_neighbours_list_each_vertexs_neighbours_once_in_coordinate_order(name, seed):
    """The corner search reads each vertex's neighbours from one packed run: the other
    vertices of its triangles, each once, in the order of their coordinates (then ids),
    so that a place is found by bisection, with their coordinates; on any subset of
    triangles in any order and rotation, and around vertices of every degree (a fan
    joined in tests the runs longer than the insertion limit)."""
    from qdrefine.numbering import incidence

    mesh = examples.gmsh_mesh(name)
    rng = np.random.default_rng(seed)
    n = mesh.n_triangles
    rows = mesh.triangles.astype(np.int64)[rng.permutation(n)[:rng.integers(1, n + 1)]]
    # a fan of 40 triangles around a new centre: its runs are long
    centre, ring = mesh.n_points, rng.choice(mesh.n_points, 41, replace=False)
    fan = np.c_[np.full(40, centre), ring[:-1], ring[1:]]
    points = np.vstack([mesh.points, mesh.points[ring[0]]])  # the centre repeats a point
    rows = np.vstack([rows, fan])[rng.permutation(rows.shape[0] + 40)]
    shift = rng.integers(0, 3, rows.shape[0])[:, None]
    rows = np.take_along_axis(rows, (shift + np.arange(3)) % 3, axis=1)
    start, tris = incidence(rows, points.shape[0])
    first, ids, xy = red_module.vertex_neighbours(points, rows, start, tris)
    assert (np.diff(first) > red_module._FEW).any()
    for v in range(points.shape[0]):
        others = {int(u) for t in tris[start[v]:start[v + 1]] for u in rows[t] if u != v}
        expected = sorted(others, key=lambda u: (points[u, 0], points[u, 1], u))
        assert ids[first[v]:first[v + 1]].tolist() == expected
    np.testing.assert_array_equal(xy, points[ids])


def test_without_history_nothing_changes():
    mesh = refine(examples.square(2), levels=1)  # uniform: no origins
    assert mesh.origins is None
    assert coarsen(mesh, np.ones(mesh.n_triangles, dtype=bool)) is mesh


def test_history_travels_through_uniform_refinement_and_files(tmp_path):
    """Uniform refinement carries the origins to the children; files that hold cell data
    keep them (``qdrefine:origins``), so a mesh read back coarsens as in memory."""
    mesh = refine(examples.gmsh_mesh("l_shape"), marked=np.arange(0, 126, 4))
    fine = refine(mesh, levels=1)
    np.testing.assert_array_equal(fine.origins, np.repeat(mesh.origins, 7, axis=0))
    for suffix in (".msh", ".vtu"):
        path = tmp_path / f"m{suffix}"
        qdrefine.write(path, mesh)
        again = qdrefine.read(path)
        np.testing.assert_array_equal(again.origins, mesh.origins)
        everything = np.ones(mesh.n_triangles, dtype=bool)
        _assert_same(coarsen(again, everything), coarsen(mesh, everything))


def test_a_tagged_piece_alone_is_refused():
    """A tagged edge that refinement did not cut (a piece tagged on its own) ends at a
    point coarsening removes: one clear error, not a silently dropped tag."""
    mesh = refine(examples.gmsh_mesh("l_shape"), marked=[0])
    inner = mesh.triangles[0, :2]  # an edge of a child, not on a tagged edge
    tagged = mesh.replace(edges=np.concatenate([mesh.edges, [inner]]),
                          edge_tags=np.concatenate([mesh.edge_tags, [7]]))
    with pytest.raises(ValueError, match="cannot coarsen: tagged edge"):
        coarsen(tagged, np.ones(mesh.n_triangles, dtype=bool))


def _corner_sets(mesh, rows=None):
    """Each triangle as its three corners' coordinates, sorted (any rotation alike)."""
    p = mesh.points[mesh.triangles if rows is None else mesh.triangles[rows]]
    order = np.lexsort((p[..., 1], p[..., 0]), axis=-1)
    return {tuple(r) for r in
            np.take_along_axis(p, order[..., None], axis=-2).reshape(-1, 6).tolist()}


def test_a_moving_front_leaves_nothing_behind():
    """Refine a band around a moving line twice per step, coarsen what it left until
    nothing changes: a few input triangles behind the band the mesh is the input again
    (nearer, a restored triangle whose neighbour is still two levels finer keeps its
    children), and the quality never falls under the computed bound."""
    from qdrefine.adaptive.bounds import quality_bound
    from qdrefine.quality import min_angles

    base = examples.gmsh_mesh("l_shape")  # edges of about 0.25
    bound = quality_bound(base, "7t-qd", levels=6)
    original = _corner_sets(base)
    mesh = base
    for step in range(8):
        x = -0.9 + 0.2 * step
        for _ in range(2):
            mesh = refine(mesh, marked=np.abs(marking.centroids(mesh)[:, 0] - x) < 0.08)
        for _ in range(20):
            before = mesh
            mesh = coarsen(mesh, marking.centroids(mesh)[:, 0] < x - 0.2)
            if mesh.n_triangles == before.n_triangles:
                break
        assert min_angles(mesh).min() >= bound.ratio * bound.initial - 1e-9
        behind = np.flatnonzero(marking.centroids(mesh)[:, 0] < x - 0.8)
        assert _corner_sets(mesh, behind) <= original


def test_an_edge_in_two_groups_is_joined_in_both():
    """A boundary edge in two physical groups (two tagged copies, as Gmsh writes them):
    refinement cuts both, coarsening joins both again."""
    base = examples.gmsh_mesh("l_shape")
    base = base.replace(edges=np.concatenate([base.edges, base.edges[:5]]),
                        edge_tags=np.concatenate([base.edge_tags, [7] * 5]))
    fine = refine(base, marked=np.ones(base.n_triangles, dtype=bool))
    _assert_same(coarsen(fine, np.ones(fine.n_triangles, dtype=bool)), base)


def test_coarsening_does_not_depend_on_the_triangle_order():
    """A restored triangle took the cell data of its child with the lowest row, and the
    new transitions of a family that of its first row: the same mesh with its rows
    shuffled came back with other data where children differ (review, 2026-11-27)."""
    base = examples.gmsh_mesh("l_shape")
    mesh = refine(base, marked=marking.mark_box(base, (-1, -1, 0, 0)))
    mesh = refine(mesh, marked=marking.mark_box(mesh, (-0.5, -0.5, 0, 0)))
    rng = np.random.default_rng(1)
    mesh = mesh.replace(cell_data={"err": rng.random(mesh.n_triangles)})
    order = np.random.default_rng(3).permutation(mesh.n_triangles)
    shuffled = Mesh(mesh.points, mesh.triangles[order], mesh.cell_tags[order], mesh.edges,
                    mesh.edge_tags, cell_data={"err": mesh.cell_data["err"][order]},
                    transitions=mesh.transitions[order], origins=mesh.origins[order])

    def data(m):
        return {tuple(sorted(map(tuple, m.points[t].tolist()))): float(e)
                for t, e in zip(m.triangles, m.cell_data["err"], strict=True)}

    for marked in (np.ones(mesh.n_triangles, dtype=bool),
                   marking.mark_box(mesh, (-1, -1, -0.2, 1))):
        assert data(coarsen(mesh, marked)) == data(coarsen(shuffled, marked[order]))


def test_coarsen_mark_file_cycles_do_not_depend_on_the_triangle_order(tmp_path, monkeypatch):
    """``qdrefine coarsen --mark-file F --cycles 3`` marked later cycles through
    ``parents``, which map a family's new triangles to its first row: the same mesh with
    its rows shuffled (and F renumbered) coarsened to another mesh (review, 2026-11-27).
    The marks are now carried as cell data."""
    from qdrefine.cli import main

    monkeypatch.chdir(tmp_path)
    base = examples.gmsh_mesh("l_shape")
    mesh = base
    for _ in range(3):
        mesh = refine(mesh, marked=marking.mark_box(mesh, (-1, -1, 0.2, 0.2)))
    order = np.random.default_rng(2).permutation(mesh.n_triangles)
    qdrefine.write("a.msh", mesh)
    qdrefine.write("b.msh", Mesh(mesh.points, mesh.triangles[order], mesh.cell_tags[order],
                                 mesh.edges, mesh.edge_tags, transitions=mesh.transitions[order],
                                 origins=mesh.origins[order]))
    keep = np.random.default_rng(0).random(mesh.n_triangles) < 0.99
    np.savetxt("a.txt", np.flatnonzero(keep), fmt="%d")
    np.savetxt("b.txt", np.flatnonzero(keep[order]), fmt="%d")
    for x in "ab":
        assert main(["coarsen", f"{x}.msh", f"{x}_out.msh", "--mark-file", f"{x}.txt",
                     "--cycles", "3", "-q"]) == 0
    a, b = qdrefine.read("a_out.msh"), qdrefine.read("b_out.msh")
    assert a.n_triangles < mesh.n_triangles
    assert _keys(a) == _keys(b)
    assert not a.cell_data  # the carried marks are not written


def _keys(mesh):
    return sorted(tuple(sorted(map(tuple, mesh.points[t].tolist()))) for t in mesh.triangles)


def test_tagged_pieces_in_any_order_are_joined():
    """The pieces of a cut edge listed in any order (a file sorted by tag, a user's
    permutation) are joined all the same; each joined edge keeps its tag."""
    base = examples.gmsh_mesh("l_shape")
    fine = refine(base, marked=np.ones(base.n_triangles, dtype=bool))
    perm = np.random.default_rng(0).permutation(len(fine.edges))
    shuffled = fine.replace(edges=fine.edges[perm], edge_tags=fine.edge_tags[perm])
    back = coarsen(shuffled, np.ones(fine.n_triangles, dtype=bool))
    got = sorted(zip(map(tuple, back.edges.tolist()), back.edge_tags.tolist(), strict=True))
    want = sorted(zip(map(tuple, base.edges.tolist()), base.edge_tags.tolist(), strict=True))
    assert got == want


@settings(max_examples=15, deadline=None)
@given(st.sampled_from(["l_shape", "plate_with_hole"]), st.sampled_from(SCHEMES),
       st.integers(0, 2**32 - 1), st.floats(0.05, 1.0))
def test_tagged_pieces_turned_around_are_joined(name, scheme, seed, share):
    """Pieces listed the other way round (``(80, 0)`` for ``(0, 80)``; a tool that sorts
    each edge as ``(min, max)``) made coarsening refuse the mesh when a chain mixed both
    directions (review). They are joined as the pieces as refined are, each joined edge
    in the direction of the piece in its row."""
    base = examples.gmsh_mesh(name)
    fine = refine(base, scheme, marked=np.ones(base.n_triangles, dtype=bool))
    rng = np.random.default_rng(seed)
    turn = rng.random(len(fine.edges)) < share
    edges = np.where(turn[:, None], fine.edges[:, ::-1], fine.edges)
    every = np.ones(fine.n_triangles, dtype=bool)
    back = coarsen(fine.replace(edges=edges), every, scheme)
    want = coarsen(fine, every, scheme)
    assert len(want.edges) == len(base.edges)
    np.testing.assert_array_equal(back.points, want.points)
    np.testing.assert_array_equal(back.triangles, want.triangles)
    np.testing.assert_array_equal(back.edge_tags, want.edge_tags)
    same = (back.edges == want.edges).all(axis=1)
    assert (same | (back.edges == want.edges[:, ::-1]).all(axis=1)).all()
    # each joined edge runs as the piece in its row (the first piece as refined)
    first = np.flatnonzero(~np.isin(fine.edges[:, 0], np.arange(base.n_points, fine.n_points)))
    np.testing.assert_array_equal(same, ~turn[first])


def test_history_rows_of_a_mirrored_mesh(tmp_path):
    """History rows are counter-clockwise like triangles: a Mesh built with clockwise ones
    is refused with one line; a mirrored file (its triangles flipped on reading, with a
    warning) has them flipped too, so coarsening it gives counter-clockwise triangles (its
    restored triangles take their origin's row only as a rotation, never a reflection)."""
    import warnings

    import meshio

    from qdrefine import read, write

    base = examples.gmsh_mesh("plate_with_hole")
    fine = refine(base, "7t-qd", marked=marking.mark_random(base, 0.2, seed=1))
    with pytest.raises(ValueError, match=r"origins: row 0 \(.*\) is clockwise or flat"):
        Mesh(fine.points, fine.triangles, origins=fine.origins[:, ::-1])
    write(tmp_path / "fine.vtu", fine)
    mirrored = meshio.read(tmp_path / "fine.vtu")
    mirrored.points[:, 0] *= -1
    meshio.write(tmp_path / "mirrored.vtu", mirrored)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the flipped triangles are reported
        back = read(tmp_path / "mirrored.vtu")
    assert back.transitions is not None and back.origins is not None
    out = _all_the_way_back(back, "7t-qd")
    assert (_twice_areas(out) > 0).all()
    assert out.n_triangles == base.n_triangles
    expected = base.points * [-1.0, 1.0]
    assert sorted(map(tuple, np.sort(expected[base.triangles], axis=1).reshape(-1, 6).tolist())) \
        == sorted(map(tuple, np.sort(out.points[out.triangles], axis=1).reshape(-1, 6).tolist()))


@pytest.mark.parametrize("name", ["l_shape", "plate_with_hole", "grid"])
def test_triangles_that_stay_keep_their_own_cell_data(name):
    """A restored triangle with a neighbour two levels finer is expanded again: its children
    are the input's, and each keeps its own cell data (they took the family's first
    child's; data review, 2026-11-27)."""
    base = examples.square(4) if name == "grid" else examples.gmsh_mesh(name)
    mesh = refine(base, marked=np.arange(0, base.n_triangles, 3))
    mesh = refine(mesh, marked=np.arange(0, mesh.n_triangles, 5))
    mesh = mesh.replace(cell_data={"centroid": mesh.points[mesh.triangles].mean(axis=1)})
    out = coarsen(mesh, np.ones(mesh.n_triangles, dtype=bool))

    def rows(m):
        return {tuple(sorted(map(tuple, t.tolist()))): i
                for i, t in enumerate(m.points[m.triangles])}

    before = rows(mesh)
    stayed = [(j, before[key]) for key, j in rows(out).items() if key in before]
    assert stayed
    for j, i in stayed:
        np.testing.assert_array_equal(out.cell_data["centroid"][j],
                                      mesh.cell_data["centroid"][i])


def test_a_family_given_back_as_its_parent_takes_a_members_data():
    """A restored triangle that keeps its children gave a child that was a transition family
    (it comes back as the family's parent) the cell data and parent of a triangle beside it,
    and which one depended on the triangle order (review: 44 of 4,296 triangles on the
    L-shape after a moving front; 15 differed between two orders on `graded`). Now a
    member's, the first in coordinate order, in any order."""
    def key(corners):
        return tuple(sorted(map(tuple, corners.tolist())))

    mesh = examples.gmsh_mesh("l_shape")
    lo, hi = mesh.points.min(0), mesh.points.max(0)
    width = hi[0] - lo[0]
    for cycle in range(3):  # a front moving right, refined, then coarsened behind it
        x = lo[0] + width * (cycle + 1) / 8
        near = np.abs(marking.centroids(mesh)[:, 0] - x) < width / 20
        mesh = refine(mesh, "7t-qd", marked=near | marking.mark_random(mesh, 0.03, cycle))
    mesh = mesh.replace(cell_data={"id": np.arange(mesh.n_triangles, dtype=float)})
    behind = marking.centroids(mesh)[:, 0] < x - width / 6
    out, parents = coarsen_marked(mesh, behind)
    families: dict[tuple, list[int]] = {}
    for row in np.flatnonzero(mesh.transitions[:, 0] >= 0):
        families.setdefault(key(mesh.points[mesh.transitions[row]]), []).append(int(row))
    given_back = [(o, families[key(out.points[t])]) for o, t in enumerate(out.triangles)
                  if key(out.points[t]) in families]
    assert len(given_back) > 10  # the case arises here
    for o, members in given_back:
        assert int(out.cell_data["id"][o]) in members and parents[o] in members
    order = np.random.default_rng(1).permutation(mesh.n_triangles)
    shuffled = Mesh(mesh.points, mesh.triangles[order], cell_tags=mesh.cell_tags[order],
                    edges=mesh.edges, edge_tags=mesh.edge_tags,
                    cell_data={"id": mesh.cell_data["id"][order]},
                    transitions=mesh.transitions[order], origins=mesh.origins[order])
    again = coarsen(shuffled, behind[order])
    def data(m: Mesh) -> dict:
        return {key(m.points[t]): v for t, v in zip(m.triangles, m.cell_data["id"], strict=True)}

    assert data(out) == data(again)


def test_origins_given_from_another_corner_still_coarsen():
    """``origins`` rows listing the same triangle from another corner (``Mesh`` takes them)
    made every family look mixed: nothing was restored, silently (review)."""
    base = examples.gmsh_mesh("l_shape")
    fine = refine(base, "7t-qd", marked=marking.mark_random(base, 0.3, 0))
    turns = np.random.default_rng(0).integers(0, 3, fine.n_triangles)[:, None]
    turned = fine.replace(origins=np.take_along_axis(fine.origins, (turns + np.arange(3)) % 3,
                                                     axis=1))  # each row from its own corner
    everything = np.ones(fine.n_triangles, dtype=bool)
    expected = coarsen(fine, everything)
    assert expected.n_triangles == base.n_triangles
    again = coarsen(turned, everything)
    assert np.array_equal(again.points, expected.points)  # the triangles, as their origins
    assert np.array_equal(smallest_first(again.triangles), smallest_first(expected.triangles))
