"""GPU refinement against the CPU, bit for bit: run by tests/test_gpu.py in a subprocess,
under numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``, small meshes) and on a real GPU
where there is one. Not collected directly (the name does not start with ``test_``): the
environment must be set before ``numba.cuda`` is first imported."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshes import crack, jittered_grid
from qdrefine import Mesh, examples, read, refine, scheme_names
from qdrefine.gpu import refine_device, refine_mesh
from qdrefine.gpu.numbering import exclusive_scan
from qdrefine.predicates import orient_signs
from shapes import triangles as triangle_strategy

SCHEMES = scheme_names()
FIELDS = ("points", "triangles", "cell_tags", "edges", "edge_tags")


def assert_identical(cpu: Mesh, gpu: Mesh) -> None:
    """Same arrays, dtypes and values (``array_equal`` on floats is bitwise for non-NaN)."""
    for name in FIELDS:
        a, b = getattr(cpu, name), getattr(gpu, name)
        assert (a is None) == (b is None), name
        if a is not None:
            assert a.dtype == b.dtype, (name, a.dtype, b.dtype)
            assert a.shape == b.shape, (name, a.shape, b.shape)
            assert np.array_equal(a.view(np.uint8), b.view(np.uint8)), name


def outcome(f):
    """The result of ``f()``, or the message of the ``ValueError`` it raised."""
    try:
        return f()
    except ValueError as exc:
        return str(exc)


def same_outcome(cpu, gpu) -> None:
    assert type(cpu) is type(gpu), (cpu, gpu)
    if isinstance(cpu, str):
        assert cpu == gpu
    else:
        assert_identical(cpu, gpu)


@settings(max_examples=10, deadline=None)
@given(n=st.integers(1, 4), seed=st.integers(0, 10**6), shear=st.sampled_from([0, 0.5, 40.0]),
       shuffle=st.booleans(), scheme=st.sampled_from(SCHEMES), levels=st.integers(1, 2))
def test_random_tagged_meshes(n, seed, shear, shuffle, scheme, levels):
    """Jittered grids (renumbered and reordered at random, sheared into needles), with cell
    and edge tags."""
    mesh = jittered_grid(n, seed, shear, shuffle)
    same_outcome(outcome(lambda: refine(mesh, scheme, levels)),
                 outcome(lambda: refine_mesh(mesh, scheme, levels)))


@settings(max_examples=25, deadline=None)
@given(tri=triangle_strategy(), scheme=st.sampled_from(SCHEMES), levels=st.integers(1, 2),
       strict=st.booleans())
def test_single_triangles_with_ties_and_near_ties(tri, scheme, levels, strict):
    """Exact ties, near-ties, tiny and huge triangles: every stage of the predicates, and the
    rounding check's refusals (same message)."""
    if orient_signs(tri, np.array([[0, 1, 2]]))[0] < 0:
        tri = tri[::-1].copy()
    mesh = Mesh(tri, [[0, 1, 2]])
    same_outcome(outcome(lambda: refine(mesh, scheme, levels, strict=strict)),
                 outcome(lambda: refine_mesh(mesh, scheme, levels, strict=strict)))


@pytest.mark.parametrize("scheme", SCHEMES)
def test_structured_and_unstructured_examples(scheme):
    """The right isosceles grid (every triangle an exact tie, decided by stage 2 at the
    first level; at the second, 7T-LE and 7T-D need the exact stage for some children) and
    the plate with a hole (tags, curved boundary)."""
    for mesh in (examples.square(2), examples.plate_with_hole(8, 2)):
        out = refine_device(mesh.points, mesh.triangles, scheme, 2, cell_tags=mesh.cell_tags,
                            edges=mesh.edges, edge_tags=mesh.edge_tags)
        if mesh.n_points == 9:  # the grid's differences are exact: stage 2 decides its ties
            assert out.exact_stage[0] == 0
        assert_identical(refine(mesh, scheme, 2), Mesh._trusted(
            *(None if a is None else a.copy_to_host() for a in
              (out.points, out.triangles, out.cell_tags, out.edges, out.edge_tags))))


def test_a_gmsh_made_mesh():
    """Gmsh's unstructured, near-equilateral triangles with two tagged regions and tagged
    boundary edges (read through meshio)."""
    mesh = read(Path(__file__).parent / "data" / "two_regions_22.msh")
    for scheme in SCHEMES:
        assert_identical(refine(mesh, scheme), refine_mesh(mesh, scheme))


def test_near_ties_with_inexact_differences_go_to_the_exact_stage():
    """|OM| and |ON| nearly tie and the coordinate differences are not exact: neither the
    filter nor stage 2 proves the sign, the expansions on the device do, and the result is
    the CPU's."""
    mesh = Mesh(np.array([[0.1, 0.1], [0.7, 0.1], [0.4, 0.9]]), [[0, 1, 2]])
    for scheme in SCHEMES:
        out = refine_device(mesh.points, mesh.triangles, scheme, 2)
        assert out.exact_stage[0] == 1
        cpu = refine(mesh, scheme, 2)
        assert np.array_equal(out.points.copy_to_host(), cpu.points)
        assert np.array_equal(out.triangles.copy_to_host(), cpu.triangles)


def lattice_soup(n_triangles: int, seed: int) -> Mesh:
    """Triangles (a soup: no two share a vertex; they may overlap, which refinement does not
    mind) with corners on the lattice ``0.1 * {0, ..., 7}^2``: their side lengths and
    pentagon forms tie in real arithmetic (many isosceles and right triangles), but 0.1 is
    not a double and the corners differ by up to 7 times the smaller one, so the coordinate
    differences are inexact and neither the filter nor stage 2 decides the near-ties: on
    300 triangles 10-18% need the exact stage, per scheme."""
    rng = np.random.default_rng(seed)
    corners = (rng.integers(0, 5, (n_triangles, 3, 2))
               + rng.integers(0, 4, (n_triangles, 1, 2))).astype(float) * 0.1
    points = corners.reshape(-1, 2)
    triangles = np.arange(3 * n_triangles).reshape(-1, 3)
    signs = orient_signs(points, triangles)
    triangles = np.where((signs < 0)[:, None], triangles[:, ::-1], triangles)[signs != 0]
    used = np.unique(triangles)
    return Mesh._trusted(points[used], np.searchsorted(used, triangles))


def test_lattice_ties_in_bulk():
    """Many exact-in-reals ties with inexact float differences, in one launch: the filter,
    stage 2 and the device's expansions against the CPU, bit for bit, at least 5% of the
    triangles through the exact stage. On the simulator a few hundred triangles, on a GPU
    300,000 (where the arithmetic is the device's own: see the contraction note in
    :mod:`qdrefine.gpu.predicates`)."""
    from numba.core import config

    mesh = lattice_soup(300 if config.ENABLE_CUDASIM else 300_000, 5)
    for scheme in SCHEMES:
        for levels in (1, 2) if scheme == "7t-qd" else (1,):
            out = refine_device(mesh.points, mesh.triangles, scheme, levels, strict=False)
            assert out.exact_stage[0] >= mesh.n_triangles // 20, (scheme, out.exact_stage)
            assert_identical(refine(mesh, scheme, levels, strict=False), Mesh._trusted(
                out.points.copy_to_host(), out.triangles.copy_to_host()))


def test_high_degree_vertices():
    """A fan of 40 triangles: the centre's run of 40 half-edges is heap-sorted."""
    k = 40
    angles = 2 * np.pi * np.arange(k) / k
    points = np.concatenate([[[0.0, 0.0]], np.stack([np.cos(angles), np.sin(angles)], 1)])
    ring = np.arange(1, k + 1)
    triangles = np.stack([np.zeros(k, dtype=int), ring, np.roll(ring, -1)], 1)
    mesh = Mesh(points, triangles)
    for scheme in ("7t-qd", "4t-red"):
        assert_identical(refine(mesh, scheme), refine_mesh(mesh, scheme))


def test_device_arrays_in_device_arrays_out():
    from numba import cuda

    mesh = jittered_grid(3, 7, 0.5, True)
    out = refine_device(cuda.to_device(mesh.points), cuda.to_device(mesh.triangles), "7t-qd",
                        cell_tags=cuda.to_device(mesh.cell_tags),
                        edges=cuda.to_device(mesh.edges),
                        edge_tags=cuda.to_device(mesh.edge_tags))
    cpu = refine(mesh, "7t-qd")
    for name in FIELDS:
        a = getattr(out, name)
        assert hasattr(a, "copy_to_host")  # still on the device
        assert np.array_equal(a.copy_to_host(), getattr(cpu, name))
    assert_identical(cpu, refine(mesh, "7t-qd", device="cuda"))
    wide = refine_device(cuda.to_device(mesh.points),
                         cuda.to_device(mesh.triangles.astype(np.int64)), "7t-qd", 2)
    two = refine(mesh, "7t-qd", 2)
    assert wide.triangles.dtype == two.triangles.dtype  # int32: the points fit
    assert np.array_equal(wide.triangles.copy_to_host(), two.triangles)
    same = refine_device(mesh.points, mesh.triangles, "7t-qd", 0)
    assert np.array_equal(same.points.copy_to_host(), mesh.points)
    assert np.array_equal(same.triangles.copy_to_host(), mesh.triangles)


def test_too_little_device_memory_is_refused_before_any_work(monkeypatch):
    import qdrefine.gpu.refine as gpu_refine
    from qdrefine.memory import memory_needed

    mesh = examples.square(2)
    need = memory_needed(mesh.n_points, mesh.n_triangles, "7t-qd", 3)

    class Context:
        def get_memory_info(self):
            return need - 1, 2 * need

    monkeypatch.setattr(gpu_refine.cuda, "current_context", lambda: Context())
    with pytest.raises(MemoryError, match="on the GPU needs about .* GiB free on the device"):
        refine_device(mesh.points, mesh.triangles, "7t-qd", 3)
    monkeypatch.undo()
    assert refine_device(mesh.points, mesh.triangles, "4t-red", 1).triangles.shape[0] == 32


@pytest.mark.parametrize("size", [1, 5000, 40000])
def test_exclusive_scan(size):
    from numba import cuda

    values = np.random.default_rng(size).integers(0, 7, size).astype(np.int32)
    expect = np.concatenate([[0], np.cumsum(values)])
    assert np.array_equal(exclusive_scan(cuda.to_device(values)).copy_to_host(), expect)


def test_bad_input_is_refused_with_one_line():
    from numba import cuda

    mesh = examples.square(1)
    cases = [
        (lambda: refine_device(cuda.to_device(mesh.points.astype(np.float32)), mesh.triangles),
         "dtype"),
        (lambda: refine_device(mesh.points[:, :1], mesh.triangles), "shape"),
        (lambda: refine_device(mesh.points, mesh.triangles + 3), r"\[0, 4\)"),
        (lambda: refine_device(mesh.points, mesh.triangles, edges=np.array([[0, 9]]),
                               edge_tags=np.array([1])), r"edges: vertex indices .*\[0, 4\)"),
        (lambda: refine_device(mesh.points, mesh.triangles, levels=-1), "levels"),
        (lambda: refine_device(mesh.points, mesh.triangles, cell_tags=np.zeros(5, np.int64)),
         "cell_tags"),
        # host arrays of other dtypes: cast only where no value changes (GPU review)
        (lambda: refine_device(mesh.points, mesh.triangles + 0.5),
         "triangles must hold integers, got dtype float64"),
        (lambda: refine_device(mesh.points, mesh.triangles.astype(np.uint64) + 2**63),
         "triangles has values beyond int64"),
        (lambda: refine_device(mesh.points, mesh.triangles.astype(np.uint64) + 2**32),
         r"\[0, 4\), got \[4294967296"),  # it wrapped to 0..3
        (lambda: refine_device(mesh.points, mesh.triangles, cell_tags=[1.7, 2.2]),
         "cell_tags must hold integers"),
        (lambda: refine_device(mesh.points.astype(bool), mesh.triangles), "must be numbers"),
        # masks were dropped: the masked rows were refined (review)
        (lambda: refine_device(np.ma.masked_array(mesh.points, mask=mesh.points > 0.5),
                               mesh.triangles), "points has masked entries"),
        (lambda: refine_device(mesh.points, np.ma.masked_array(mesh.triangles,
                                                               mask=[[0, 0, 0], [1, 1, 1]])),
         "triangles has masked entries"),
        (lambda: refine(mesh, device="tpu"), "unknown device"),
        (lambda: refine(mesh, marked=[0], device="cuda"), "CPU only"),
    ]
    for call, match in cases:
        with pytest.raises(ValueError, match=match) as info:
            call()
        assert "\n" not in str(info.value)


def test_input_the_mesh_would_refuse_is_refused_on_the_device_with_its_message():
    """Clockwise and zero-area triangles (exact orientation: a near-collinear triangle that
    only the exact stage decides) and bad coordinates, in device arrays."""
    from numba import cuda

    points = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [0.5, 1.0],
                       [1.5, 1.0]])
    cases = [
        ([[0, 1, 3], [0, 2, 1]], points),  # triangle 1 clockwise
        ([[0, 1, 3], [2, 4, 3]], points),  # triangle 1: zero area
        ([[0, 1, 2]], np.array([[0.0, 0.0], [1.0, 0.0], [0.0, np.inf]])),
        ([[0, 1, 2]], np.array([[0.0, 0.0], [1.0, 0.0], [1e-200, 1.0]])),
        # a point out of range before a non-finite one: Mesh names the non-finite one
        ([[0, 1, 2]], np.array([[0.0, 1e-200], [1.0, np.nan], [0.0, 1.0]])),
    ]
    for tris, pts in cases:
        tris = np.array(tris)
        with pytest.raises(ValueError) as host:
            Mesh(pts, tris)
        for levels in (0, 2):  # levels=0 skipped every check
            with pytest.raises(ValueError) as device:
                refine_device(cuda.to_device(pts), cuda.to_device(tris), levels=levels)
            assert str(device.value) == str(host.value)
    edges, edge_tags = np.array([[0, 1], [0, 2], [1, 3]]), np.array([1, 2, 3])
    with pytest.raises(ValueError) as host:
        Mesh(points, [[0, 1, 3]], edges=edges, edge_tags=edge_tags)
    with pytest.raises(ValueError) as device:
        refine_device(points, [[0, 1, 3]], edges=edges, edge_tags=edge_tags, levels=2)
    assert str(device.value) == str(host.value)
    # nearly collinear: the float filter cannot tell, the exact stage can
    thin = np.array([[0.1, 0.1], [0.7, 0.7], [0.3, 0.30000000000000004]])
    for tris in ([[0, 1, 2]], [[0, 2, 1]]):
        host = outcome(lambda t=tris: refine(Mesh(thin, t), "4t-red"))
        device = outcome(lambda t=tris: refine_mesh(Mesh._trusted(thin, np.array(t)), "4t-red"))
        if isinstance(host, str):
            assert host == device
        else:
            assert_identical(host, device)
    assert refine_device(thin, [[0, 1, 2]], "4t-red", strict=False).exact_stage == (1,)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_data_comes_through_as_on_the_cpu(scheme):
    """Point data (interpolated on the host from each level's device edges), cell data,
    physical names and the history: the CPU's, bit for bit (the GPU path dropped all of
    them; data review, 2026-11-27)."""
    mesh = jittered_grid(3, 7, 0.5, True)
    x, y = mesh.points.T
    mesh = mesh.replace(
        point_data={"u": 3 * x - y, "v": np.column_stack([x, y]).astype(np.float32),
                    "k": np.arange(mesh.n_points)},
        cell_data={"mat": np.arange(mesh.n_triangles) % 3,
                   "w": np.ones((mesh.n_triangles, 2, 2))},
        physical_names={(2, 1): "plate", (1, 1): "wall"})
    for levels in (1, 2):
        cpu, gpu = refine(mesh, scheme, levels), refine_mesh(mesh, scheme, levels)
        assert_identical(cpu, gpu)
        for data in ("point_data", "cell_data"):
            a, b = getattr(cpu, data), getattr(gpu, data)
            assert sorted(a) == sorted(b)
            for name in a:
                assert a[name].dtype == b[name].dtype and a[name].shape == b[name].shape
                assert np.array_equal(a[name].view(np.uint8), b[name].view(np.uint8)), name
        assert dict(gpu.physical_names) == dict(cpu.physical_names)


def test_no_level_returns_the_mesh_itself_as_on_the_cpu():
    """``levels=0`` gave a copy without the history on the GPU (the CPU returns the mesh),
    so the next ``marked`` step behaved differently."""
    mesh = refine(examples.square(2), "7t-qd", marked=[0])
    assert mesh.transitions is not None
    assert refine(mesh, "7t-qd", 0, device="cuda") is refine(mesh, "7t-qd", 0) is mesh


def test_a_rounded_boundary_that_crosses_itself_is_refused_as_on_the_cpu():
    """Two parts a float step apart: the CPU refuses the mesh whose rounded new boundary
    points cross the other part; the GPU returned it (review). Both levels, both kinds (a
    point across an edge, a point onto a vertex), and a mesh that refines on both."""
    cracked = Mesh(*crack(1, 0.375, 1e3, 1e-3))
    onto = Mesh(np.array([(0.0, 0.0), (1.5, -1.0), (3.0, 3.012e-16), (1.0, 1.004e-16),
                          (0.5, 1.0), (1.5, 1.0)]), [[0, 1, 2], [3, 5, 4]])
    for mesh in (cracked, onto):
        for levels in (1, 2):
            cpu = outcome(lambda m=mesh, lv=levels: refine(m, "7t-qd", lv))
            gpu = outcome(lambda m=mesh, lv=levels: refine_mesh(m, "7t-qd", lv))
            assert isinstance(cpu, str) and "closer to another part" in cpu
            assert gpu == cpu
    apart = Mesh(cracked.points + np.array([[0, 0]] * 3 + [[0, -1e-4]] * 3), cracked.triangles)
    cpu, gpu = refine(apart, "7t-qd", 2), refine_mesh(apart, "7t-qd", 2)
    assert_identical(cpu, gpu)
    # the output keeps its boundary, as on the CPU (no sort of its edges on the next call)
    from qdrefine.boundaries import boundary_edges
    from qdrefine.topology import unique_edges

    kept = sorted(map(tuple, gpu.__dict__["_boundary"].tolist()))
    _, tri_edges, counts = unique_edges(gpu)
    t, i = np.nonzero(counts[tri_edges] == 1)
    assert kept == sorted(zip(gpu.triangles[t, i].tolist(),
                              gpu.triangles[t, (i + 1) % 3].tolist(), strict=True))
    assert boundary_edges(gpu) is gpu.__dict__["_boundary"]
