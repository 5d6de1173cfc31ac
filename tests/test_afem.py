"""The AFEM example (qdrefine.afem) against scikit-fem, and 'qdrefine demo --afem'."""

import json

import numpy as np

from qdrefine import afem, examples
from qdrefine.cli import main


def test_exact_solution_is_harmonic_and_vanishes_on_the_corner_edges():
    x = np.array([0.0, 0.0, 0.3, 0.7])
    y = np.array([0.5, 0.9, 0.0, 0.0])
    np.testing.assert_allclose(afem.exact_solution(x, y), 0.0, atol=1e-15)
    # gradient against central differences away from the corner
    p = np.array([-0.4, -0.3])
    h = 1e-6
    gx, gy = afem.exact_gradient(*p)
    fd = [(afem.exact_solution(p[0] + h, p[1]) - afem.exact_solution(p[0] - h, p[1])) / (2 * h),
          (afem.exact_solution(p[0], p[1] + h) - afem.exact_solution(p[0], p[1] - h)) / (2 * h)]
    np.testing.assert_allclose([gx, gy], fd, rtol=1e-6)


def test_adaptive_loop_converges_and_keeps_tags():
    mesh = examples.gmsh_mesh("l_shape")
    rows = afem.run(mesh, "7t-qd", cycles=5)
    errors = [r.error for r in rows]
    assert all(b < a for a, b in zip(errors, errors[1:], strict=False))
    assert all(r.min_angle_ratio >= 0.4 for r in rows)
    # the same loop by hand keeps cell and edge tags every cycle
    m = mesh
    for _ in range(3):
        basis, u = afem.solve(m)
        m = afem.refine(m, "7t-qd", marked=afem.mark_dorfler(afem.estimate(basis, u), 0.5))
        assert set(np.unique(m.cell_tags)) == set(np.unique(mesh.cell_tags))
        assert set(np.unique(m.edge_tags)) == set(np.unique(mesh.edge_tags))
        assert m.transitions is not None


def test_scikit_fem_reference_runs_the_same_loop():
    mesh = examples.gmsh_mesh("l_shape")
    ours = afem.study(mesh, ("7t-qd", "scikit-fem"), cycles=4)
    assert ours["7t-qd"][0]["error"] == ours["scikit-fem"][0]["error"]  # same first mesh
    assert ours["scikit-fem"][-1]["dofs"] > ours["scikit-fem"][0]["dofs"]


def test_demo_afem_writes_its_figure_and_numbers(tmp_path, capsys):
    assert main(["demo", str(tmp_path), "--afem", "--cycles", "2", "--quiet"]) == 0
    data = json.loads((tmp_path / "afem.json").read_text())
    assert set(data) == set(afem.METHODS)
    assert (tmp_path / "afem.png").stat().st_size > 10_000
