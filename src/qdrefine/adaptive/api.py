"""Public entry points of adaptive refinement: :func:`refine_marked`, :func:`refine_step`,
:func:`refine_cycles`, and the checks of their arguments."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..mesh import Mesh
from ..quality import angles
from ..refine import as_count, check_rounding
from ..schemes import Scheme, get_scheme
from .families import Families
from .step import step

#: Default quality floor of the transitions, as a fraction of the input's minimum angle.
KEEP = 0.5


def as_mask(marked: ArrayLike, n_triangles: int) -> NDArray[np.bool_]:
    """A boolean mask ``(M,)`` from a mask or an array of triangle indices."""
    a = np.asarray(marked)
    if a.dtype == bool:
        if a.shape != (n_triangles,):
            raise ValueError(f"a boolean marked mask must have shape ({n_triangles},), "
                             f"got {a.shape}")
        return a.copy()
    if a.size == 0:
        return np.zeros(n_triangles, dtype=bool)
    if not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"marked must be a boolean mask or triangle indices, got dtype "
                         f"{a.dtype}")
    if a.ndim != 1:
        raise ValueError(f"marked indices must be one-dimensional, got shape {a.shape}")
    bad = (a < 0) | (a >= n_triangles)
    if bad.any():
        raise ValueError(f"marked index {int(a[bad][0])} is outside 0..{n_triangles - 1}")
    mask = np.zeros(n_triangles, dtype=bool)
    mask[a] = True
    return mask


def refine_marked(mesh: Mesh, marked: ArrayLike, scheme: str | Scheme = "7t-qd",
                  levels: int = 1, min_angle: float | None = None
                  ) -> tuple[Mesh, NDArray[np.int64]]:
    """Conforming local refinement of the ``marked`` triangles; see :func:`qdrefine.refine`.

    Parameters
    ----------
    mesh : Mesh
    marked : (M,) bool or (K,) int
        Mask or indices of the triangles to partition with ``scheme``.
    scheme : {"7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"}
    levels : int, >= 0
        With ``levels > 1`` the children of the marked triangles are marked again,
        ``levels`` times in all (transitions made by one level are coarsened by the next
        one before it refines them, as in :func:`refine_step`).
    min_angle : float, optional
        Quality floor in degrees for the transition patterns of seven-triangle schemes: a
        triangle whose transition would create a child with a smaller minimum angle is
        fully partitioned instead (and the closure grows accordingly). Default:
        :data:`KEEP` times the smallest angle of ``mesh``. Over repeated cycles pass one
        fixed value (as :func:`refine_cycles` does), otherwise the floor can drift down.

    Returns
    -------
    mesh : Mesh
    parents : (M',) int64
        The input triangle of each output triangle (they are nested in it).
    """
    sch = get_scheme(scheme)
    levels = as_count(levels, "levels")
    mask = as_mask(marked, mesh.n_triangles)
    floor = _floor(mesh, min_angle)
    fam = Families.empty(mesh.n_triangles, sch.stencil.per_edge)
    fam_mask = np.zeros(0, dtype=bool)
    parents = np.arange(mesh.n_triangles, dtype=np.int64)
    out = mesh
    for _ in range(levels):
        if not (mask.any() or fam_mask.any()):
            break
        before = out
        out, level_parents, fam, inside = step(out, mask, fam_mask, sch, floor, fam)
        check_rounding(before.points, before.triangles, out.points, out.triangles,
                       sch.stencil.per_edge, level_parents, everywhere=True)
        parents = parents[level_parents]
        mask = inside & (fam.member < 0)
        fam_mask = np.zeros(fam.n_families, dtype=bool)
        fam_mask[fam.member[inside & (fam.member >= 0)]] = True
    return out, parents


def refine_step(mesh: Mesh, marked: ArrayLike, scheme: str | Scheme = "7t-qd",
                min_angle: float | None = None, families: Families | None = None
                ) -> tuple[Mesh, NDArray[np.int64], Families]:
    """One adaptive cycle that first coarsens the transitions it would otherwise refine.

    ``families`` (from the previous call) says which triangles are transition children.
    A family is *coarsened* back to its parent when a member is marked or would get a
    split edge; the parent is then refined as a whole: with a larger transition when the
    closure splits another of its edges, fully when it must. When a member was marked,
    the children of the parent's partition that meet it and are not smaller than it are
    partitioned again: every marked triangle is gone and every output triangle meeting it
    has at most its area. Transitions are thus only ever made of triangles that are not
    transition children, and repeated cycles do not compound them
    (``docs/adaptive.md``).

    Parameters
    ----------
    mesh : Mesh
    marked : (M,) bool or (K,) int
    scheme : str or Scheme
    min_angle : float, optional
        Quality floor of new transitions, as in :func:`refine_marked`.
    families : Families, optional
        Default: no triangle of ``mesh`` is a transition child (plain
        :func:`refine_marked`).

    Returns
    -------
    mesh : Mesh
    parents : (M',) int64
        Input triangle of each output triangle. Output triangles lie in it, except in a
        coarsened family: its new triangles lie in the union of the family (the parent)
        and map to the family's first member (every member has the same tags).
    families : Families
        The output's transition families, for the next call.
    """
    sch = get_scheme(scheme)
    mask = as_mask(marked, mesh.n_triangles)
    if families is None:
        families = Families.empty(mesh.n_triangles, sch.stencil.per_edge)
    if not mask.any():
        return mesh, np.arange(mesh.n_triangles, dtype=np.int64), families
    out, parents, fam, _ = step(mesh, mask, np.zeros(families.n_families, dtype=bool), sch,
                                _floor(mesh, min_angle), families)
    check_rounding(mesh.points, mesh.triangles, out.points, out.triangles,
                   sch.stencil.per_edge, parents, everywhere=True)
    return out, parents, fam


def _floor(mesh: Mesh, min_angle: float | None, keep: float = KEEP) -> float:
    """``min_angle``, or by default ``keep`` times the smallest angle of ``mesh``."""
    if min_angle is None:
        return keep * float(angles(mesh.points, mesh.triangles).min())
    return float(min_angle)


def refine_cycles(mesh: Mesh, mark: Callable[[Mesh], ArrayLike], cycles: int,
                  scheme: str | Scheme = "7t-qd", keep: float = KEEP, coarsen: bool = True
                  ) -> tuple[Mesh, NDArray[np.int64]]:
    """``cycles`` rounds of mark-then-refine with one fixed quality floor.

    Parameters
    ----------
    mesh : Mesh
    mark : callable
        ``mark(current_mesh)`` returns a mask ``(M,) bool`` or indices of the triangles to
        refine in this cycle (e.g. a :mod:`qdrefine.marking` helper with its arguments bound).
    cycles : int, >= 0
    scheme : str or Scheme
    keep : float
        The transitions' floor is ``keep`` times the minimum angle of the *input* mesh, the
        same in every cycle, so the minimum angle cannot drift down cycle after cycle
        through the transitions.
    coarsen : bool
        Keep the transition families from one cycle to the next and coarsen them before
        refining them (:func:`refine_step`, default). ``False``: each cycle is a plain
        :func:`refine_marked` (transitions of transitions are possible).

    Returns
    -------
    mesh : Mesh
    parents : (M',) int64
        The triangle of the input mesh each output triangle lies in.
    """
    cycles = as_count(cycles, "cycles")
    sch = get_scheme(scheme)
    floor = _floor(mesh, None, keep)
    parents = np.arange(mesh.n_triangles, dtype=np.int64)
    fam = Families.empty(mesh.n_triangles, sch.stencil.per_edge)
    out = mesh
    for _ in range(cycles):
        if coarsen:
            out, cycle_parents, fam = refine_step(out, mark(out), sch, floor, fam)
        else:
            out, cycle_parents = refine_marked(out, mark(out), sch, 1, min_angle=floor)
        parents = parents[cycle_parents]
    return out, parents
