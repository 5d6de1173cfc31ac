"""The public front of refinement: :func:`refine` and :func:`refine_with_parents` send a
mesh to uniform refinement (:mod:`qdrefine.uniform`), local refinement
(:mod:`qdrefine.adaptive`) or the GPU (:mod:`qdrefine.gpu`, imported on first use: it needs
the optional CUDA packages)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .adaptive import refine_marked
from .arguments import as_count
from .mesh import Mesh, need_mesh
from .predicates import COORDINATE_RANGE, below_range
from .schemes import Scheme, get_scheme
from .uniform import RefusedTriangle, refine_uniform

__all__ = ["refine", "refine_with_parents", "RefusedTriangle"]


def refine(mesh: Mesh, scheme: str | Scheme = "7t-qd", levels: int = 1,
           marked: ArrayLike | None = None, *, strict: bool = True, device: str = "cpu"
           ) -> Mesh:
    """Refine every triangle of ``mesh`` ``levels`` times with ``scheme``.

    Parameters
    ----------
    mesh : Mesh
    scheme : {"7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"}
    levels : int, >= 0
    marked : (M,) bool or (K,) int, optional
        Refine locally: only these triangles are partitioned by ``scheme``, and a
        longest-edge closure with transition patterns keeps the mesh conforming (see
        :mod:`qdrefine.adaptive` and ``docs/adaptive.md``). With ``levels > 1`` the
        children of the marked triangles are marked again. Everything said below about
        points, parents and tags holds, with only the split edges getting new points
        (numbered by their rank among split edges) and tagged edges cut only where split.
        Indices must be integers, a mask booleans: ``M`` integers all 0 or 1 (a mask
        stored as integers) are refused rather than read as the indices 0 and 1.
    strict : bool
        Uniform refinement only: ``False`` returns children that rounding the new points to
        float64 flattened or inverted instead of raising (for studies of that effect,
        ``docs/robustness.md``); local refinement always checks.
    device : {"cpu", "cuda"}
        ``"cuda"``: uniform refinement on the GPU, the same mesh bit for bit
        (:mod:`qdrefine.gpu`, ``pip install 'qdrefine[gpu]'``; copies both ways included).

    Raises
    ------
    MemoryError
        Before allocating anything, when the output and work arrays would need more memory
        than is available (:func:`qdrefine.memory.check_memory`).
    ValueError
        When a triangle is too thin for its distance from the origin: its new points,
        rounded to float64, would give a child with zero area or clockwise orientation
        (:func:`qdrefine.uniform.check_rounding`, :class:`RefusedTriangle`).

    Returns
    -------
    Mesh
        Old points keep their indices; each edge's new points are shared by its two
        triangles; the ``T`` children of triangle ``t`` are rows ``t*T .. t*T+T-1``;
        cell tags are inherited and every tagged edge becomes ``T``-scheme's edge pieces
        (three for 7T schemes, two for 4T) with the same tag and direction. Point data is
        interpolated linearly to the new points, by the formula of their coordinates (a
        linear field stays exact up to rounding; integer fields become float64), cell
        data is inherited by the children, physical names are kept
        (:mod:`qdrefine.fields`).

    Examples
    --------
    >>> from qdrefine import examples, refine
    >>> fine = refine(examples.plate_with_hole(), "7t-qd", levels=2)
    >>> fine.n_triangles == examples.plate_with_hole().n_triangles * 49
    True
    """
    need_mesh(mesh, "refine")
    if device != "cpu":
        if device != "cuda":
            raise ValueError(f"unknown device {device!r}; choose 'cpu' or 'cuda'")
        if marked is not None:
            raise ValueError("local refinement (marked) runs on the CPU only")
        from .gpu import refine_mesh

        return _in_range(mesh, refine_mesh(mesh, scheme, levels, strict), levels)
    if marked is not None:
        return refine_with_parents(mesh, scheme, levels, marked)[0]
    levels = as_count(levels, "levels")
    return _in_range(mesh, refine_uniform(mesh, get_scheme(scheme), levels, strict), levels)


def refine_with_parents(
    mesh: Mesh, scheme: str | Scheme = "7t-qd", levels: int = 1,
    marked: ArrayLike | None = None, *, strict: bool = True,
) -> tuple[Mesh, NDArray[np.int64]]:
    """:func:`refine`, also returning ``parents (M',) int64``: the input triangle of each child."""
    need_mesh(mesh, "refine_with_parents")
    if marked is not None:
        out, parents = refine_marked(mesh, marked, scheme, levels)
        return _in_range(mesh, out, as_count(levels, "levels")), parents
    sch = get_scheme(scheme)
    levels = as_count(levels, "levels")
    out = _in_range(mesh, refine_uniform(mesh, sch, levels, strict), levels)
    return out, np.arange(out.n_triangles, dtype=np.int64) // sch.n_children**levels


def _in_range(mesh: Mesh, out: Mesh, levels: int) -> Mesh:
    """``out``, unless a new point of it has a nonzero coordinate below
    :data:`~qdrefine.predicates.COORDINATE_RANGE` (the range of exact predicates, which
    ``Mesh`` refuses on input): ``ValueError`` then.

    A new point is ``(2a + b) / 3``, ``(a + b) / 2`` or ``(a + b + c) / 3`` of coordinates
    that are 0 or at least ``m`` in magnitude; every sum of them is a multiple of
    ``ulp(m) >= m 2^-53``, so a nonzero new coordinate is at least ``m 2^-55``. Only
    meshes whose smallest nonzero coordinate ``m`` is within ``2^(55 levels)`` of the
    range's lower end (about 1e-84 for one level) can leave it, and only then are the
    output's points checked (all of them: a coarsened transition's centroid is removed and
    the later points move up). ``m`` is kept on the mesh (a pass over its points, 4 ms per million),
    and the bound ``m 2^(-55 levels)`` on ``out``, for the next call."""
    lo = COORDINATE_RANGE[0]
    smallest = _smallest_coordinate(mesh)
    bound = smallest * 2.0 ** (-55 * min(levels, 20))
    if out.n_points and bound < lo:  # every point: coarsening may have renumbered some
        a = np.abs(out.points)
        bad = ((a < lo) & (a != 0)).any(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            a = np.abs(mesh.points)  # the real smallest, not a bound an earlier call kept
            raise below_range(i, out.points[i], float(np.min(a, where=a > 0, initial=np.inf)))
        bound = float(np.min(a, where=a > 0, initial=np.inf))
    object.__setattr__(out, "_smallest", bound)
    return out


def _smallest_coordinate(mesh: Mesh) -> float:
    """The smallest nonzero coordinate magnitude of ``mesh`` (or a lower bound of it that
    an earlier refinement left), ``inf`` if none."""
    known = mesh.__dict__.get("_smallest")
    if known is None:
        a = np.abs(mesh.points)
        known = float(np.min(a, where=a > 0, initial=np.inf))
        object.__setattr__(mesh, "_smallest", known)
    return known
