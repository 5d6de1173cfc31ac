"""Adaptive finite elements with qdrefine: the loop a finite-element user writes, on the
singular Poisson problem of the L-shape, with scikit-fem P1 elements.

::

    mesh = examples.gmsh_mesh("l_shape")
    for cycle in range(12):
        basis, u = solve(mesh)                      # P1 Galerkin solution
        eta = estimate(basis, u)                    # residual a-posteriori indicator
        mesh = qdrefine.refine(mesh, "7t-qd", marked=mark_dorfler(eta, 0.5))

The problem: ``-Laplace u = 0`` in ``(-1, 1)^2`` minus ``(0, 1]^2`` with ``u`` equal to the
singular solution ``r^(2/3) sin(2 phi / 3)`` on the boundary (``phi`` measured from the
positive y-axis, counter-clockwise), whose gradient is unbounded at the re-entrant corner:
uniform refinement converges at ``DOFs^(-1/3)`` in the energy norm, adaptive refinement
recovers the optimal ``DOFs^(-1/2)``.

:func:`study` runs the loop for several refinement methods side by side (qdrefine's
schemes and scikit-fem's own ``MeshTri.refined(marked)``); ``qdrefine demo --afem`` runs it
and draws :func:`plot_error` and :func:`plot_min_angle`. Needs ``pip install
'qdrefine[fem]'`` (scikit-fem).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from .marking import mark_dorfler
from .mesh import Mesh
from .quality import min_angles
from .refine import refine

__all__ = ["exact_solution", "solve", "estimate", "energy_error", "Cycle", "run", "study",
           "plot_error", "plot_min_angle", "METHODS"]

#: Refinement methods of :func:`run`: qdrefine's schemes and scikit-fem's adaptive
#: refinement (red-green-blue) of ``MeshTri.refined(marked)``.
METHODS = ("7t-qd", "7t-le", "4t-le", "scikit-fem")


def _skfem():
    try:
        import skfem
    except ModuleNotFoundError:  # pragma: no cover - exercised without the extra
        raise ModuleNotFoundError("the AFEM example needs scikit-fem: pip install "
                                  "'qdrefine[fem]'", name="skfem") from None
    return skfem


def _polar(x: NDArray, y: NDArray) -> tuple[NDArray, NDArray]:
    r = np.hypot(x, y)
    phi = np.mod(np.arctan2(y, x) - np.pi / 2, 2 * np.pi)
    return r, phi


def exact_solution(x: NDArray, y: NDArray) -> NDArray[np.float64]:
    """``r^(2/3) sin(2 phi / 3)``, ``phi`` from the positive y-axis (zero on both edges of
    the re-entrant corner)."""
    r, phi = _polar(np.asarray(x, float), np.asarray(y, float))
    return r ** (2 / 3) * np.sin(2 * phi / 3)


def exact_gradient(x: NDArray, y: NDArray) -> tuple[NDArray, NDArray]:
    """Gradient ``(d/dx, d/dy)`` of :func:`exact_solution` (unbounded at the origin)."""
    r, phi = _polar(np.asarray(x, float), np.asarray(y, float))
    r = np.maximum(r, np.finfo(float).tiny)
    ur = (2 / 3) * r ** (-1 / 3) * np.sin(2 * phi / 3)
    up = (2 / 3) * r ** (-1 / 3) * np.cos(2 * phi / 3)
    theta = phi + np.pi / 2
    return (ur * np.cos(theta) - up * np.sin(theta), ur * np.sin(theta) + up * np.cos(theta))


def _skfem_mesh(mesh: Mesh):
    return _skfem().MeshTri(np.ascontiguousarray(mesh.points.T),
                            np.ascontiguousarray(mesh.triangles.T, dtype=np.int64))


def solve(mesh: Mesh | object):
    """P1 Galerkin solution of the L-shape problem on ``mesh`` (a :class:`Mesh` or a
    scikit-fem ``MeshTri``): returns ``(basis, u)``, ``u (N,)`` the nodal values."""
    skfem = _skfem()
    from skfem.models.poisson import laplace

    m = _skfem_mesh(mesh) if isinstance(mesh, Mesh) else mesh
    basis = skfem.Basis(m, skfem.ElementTriP1())
    stiffness = skfem.asm(laplace, basis)
    boundary = m.boundary_nodes()
    x = np.zeros(basis.N)
    x[boundary] = exact_solution(*m.p[:, boundary])
    return basis, skfem.solve(*skfem.condense(stiffness, x=x, D=boundary))


def estimate(basis, u: NDArray[np.float64]) -> NDArray[np.float64]:
    """Residual a-posteriori indicator ``eta_T^2 (M,)`` of P1 for a harmonic ``u``: half the
    sum over the interior edges ``E`` of ``T`` of ``h_E |[du/dn]|^2 |E|``."""
    skfem = _skfem()
    from skfem.helpers import grad

    m = basis.mesh
    sides = [skfem.InteriorFacetBasis(m, skfem.ElementTriP1(), side=i) for i in (0, 1)]
    values = {f"u{i + 1}": sides[i].interpolate(u) for i in (0, 1)}

    @skfem.Functional
    def jump(w):
        d1, d2 = grad(w["u1"]), grad(w["u2"])
        return w.h * ((d1[0] - d2[0]) * w.n[0] + (d1[1] - d2[1]) * w.n[1]) ** 2

    per_edge = np.zeros(m.facets.shape[1])
    np.add.at(per_edge, sides[0].find, jump.elemental(sides[0], **values))
    return 0.5 * per_edge[m.t2f].sum(axis=0)


def energy_error(basis, u: NDArray[np.float64], order: int = 8) -> float:
    """``|grad(u_exact - u_h)|`` in L2 over the mesh, by Gauss quadrature of ``order`` on
    each triangle (the same rule for every method compared)."""
    skfem = _skfem()
    from skfem.helpers import grad

    fine = skfem.Basis(basis.mesh, skfem.ElementTriP1(), intorder=order)

    @skfem.Functional
    def error(w):
        gx, gy = exact_gradient(*w.x)
        du = grad(w["uh"])
        return (gx - du[0]) ** 2 + (gy - du[1]) ** 2

    return float(np.sqrt(error.assemble(fine, uh=fine.interpolate(u))))


@dataclass(frozen=True)
class Cycle:
    """One cycle of :func:`run` (the quantities of the mesh the cycle solved on)."""

    method: str
    cycle: int
    dofs: int
    triangles: int
    error: float  # energy norm of the error
    min_angle: float  # degrees, smallest angle of the mesh
    min_angle_ratio: float  # ... over the initial mesh's
    marked: int
    added: int  # triangles the refinement of this cycle added
    refine_seconds: float


def run(mesh: Mesh, method: str = "7t-qd", cycles: int = 12, theta: float = 0.5
        ) -> list[Cycle]:
    """``cycles`` rounds of solve, estimate, mark (Doerfler, ``theta``), refine.

    ``method`` is one of :data:`METHODS`: a qdrefine scheme refines with
    ``mesh = qdrefine.refine(mesh, method, marked=...)`` (the history travels in the
    mesh), ``"scikit-fem"`` with ``MeshTri.refined(marked)``. Tags and edge tags of a
    :class:`Mesh` are kept by qdrefine's methods."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; choose one of: {', '.join(METHODS)}")
    a0 = float(min_angles(mesh).min())
    current = mesh if method != "scikit-fem" else _skfem_mesh(mesh)
    out = []
    for c in range(cycles):
        basis, u = solve(current)
        eta = estimate(basis, u)
        marked = mark_dorfler(eta, theta)
        points, tris = basis.mesh.p.T, basis.mesh.t.T
        angle = float(min_angles(np.ascontiguousarray(points), np.ascontiguousarray(tris)).min())
        t = time.perf_counter()
        if method == "scikit-fem":
            current = current.refined(np.flatnonzero(marked))
            n_after = current.t.shape[1]
        else:
            current = refine(current, method, marked=marked)
            n_after = current.n_triangles
        seconds = time.perf_counter() - t
        out.append(Cycle(method, c, int(basis.N), int(tris.shape[0]), energy_error(basis, u),
                         angle, angle / a0, int(marked.sum()), int(n_after - tris.shape[0]),
                         seconds))
    return out


def study(mesh: Mesh, methods: tuple[str, ...] = METHODS, cycles: int = 12,
          theta: float = 0.5) -> dict[str, list[dict]]:
    """:func:`run` for each method on the same mesh: ``{method: [cycle as dict, ...]}``."""
    return {m: [asdict(c) for c in run(mesh, m, cycles, theta)] for m in methods}


def rate(cycles: list[dict], last: int = 6) -> float:
    """Least-squares slope of ``log(error)`` against ``log(DOFs)`` over the last cycles."""
    d = np.log([c["dofs"] for c in cycles[-last:]])
    e = np.log([c["error"] for c in cycles[-last:]])
    return float(np.polyfit(d, e, 1)[0])


def error_at(cycles: list[dict], dofs: float) -> float:
    """The energy error at ``dofs`` degrees of freedom, interpolated in log-log."""
    d = np.log([c["dofs"] for c in cycles])
    e = np.log([c["error"] for c in cycles])
    return float(np.exp(np.interp(np.log(dofs), d, e)))


_STYLE = {"7t-qd": ("o", "-"), "7t-le": ("s", "--"), "4t-le": ("^", "-."),
          "scikit-fem": ("D", ":")}


def plot_error(results: dict[str, list[dict]], ax=None):
    """Energy error against DOFs (log-log) per method, with the optimal slope -1/2."""
    import matplotlib.pyplot as plt

    ax = ax or plt.figure(figsize=(6, 4.5)).add_subplot()
    for method, cycles in results.items():
        marker, line = _STYLE.get(method, ("x", "-"))
        fitted = f" (rate {rate(cycles):.2f})" if len(cycles) > 1 else ""  # a slope
        ax.loglog([c["dofs"] for c in cycles], [c["error"] for c in cycles], marker=marker,
                  linestyle=line, label=f"{method}{fitted}")
    first = next(iter(results.values()))
    d0, e0 = first[0]["dofs"], first[0]["error"]
    d = np.array([d0, max(c["dofs"] for cs in results.values() for c in cs)])
    ax.loglog(d, e0 * (d / d0) ** -0.5, color="gray", linewidth=0.8, label="slope -1/2")
    ax.set_xlabel("degrees of freedom")
    ax.set_ylabel("energy error |u - u_h|_1")
    ax.set_title("Adaptive P1 on the L-shape (Doerfler 0.5)")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    return ax


def plot_min_angle(results: dict[str, list[dict]], ax=None):
    """Smallest angle of the mesh over the initial one, per cycle and method."""
    import matplotlib.pyplot as plt

    ax = ax or plt.figure(figsize=(6, 4.5)).add_subplot()
    for method, cycles in results.items():
        marker, line = _STYLE.get(method, ("x", "-"))
        ax.plot([c["cycle"] for c in cycles], [c["min_angle_ratio"] for c in cycles],
                marker=marker, linestyle=line, label=method)
    ax.axhline(0.4, color="gray", linewidth=0.8, label="0.4 (acceptance)")
    ax.set_xlabel("cycle")
    ax.set_ylabel("smallest angle / initial smallest angle")
    ax.set_ylim(0, 1)
    ax.set_title("Mesh quality over the adaptive loop")
    ax.legend()
    ax.grid(True, alpha=0.3)
    return ax
