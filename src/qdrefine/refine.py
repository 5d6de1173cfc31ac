"""The public front of refinement: :func:`refine` and :func:`refine_with_parents` send a
mesh to uniform refinement (:mod:`qdrefine.uniform`), local refinement
(:mod:`qdrefine.adaptive`) or the GPU (:mod:`qdrefine.gpu`, imported on first use: it needs
the optional CUDA packages)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .adaptive import refine_marked
from .arguments import as_count
from .mesh import Mesh
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
    if device != "cpu":
        if device != "cuda":
            raise ValueError(f"unknown device {device!r}; choose 'cpu' or 'cuda'")
        if marked is not None:
            raise ValueError("local refinement (marked) runs on the CPU only")
        from .gpu import refine_mesh

        return refine_mesh(mesh, scheme, levels, strict)
    if marked is not None:
        return refine_with_parents(mesh, scheme, levels, marked)[0]
    return refine_uniform(mesh, get_scheme(scheme), as_count(levels, "levels"), strict)


def refine_with_parents(
    mesh: Mesh, scheme: str | Scheme = "7t-qd", levels: int = 1,
    marked: ArrayLike | None = None, *, strict: bool = True,
) -> tuple[Mesh, NDArray[np.int64]]:
    """:func:`refine`, also returning ``parents (M',) int64``: the input triangle of each child."""
    if marked is not None:
        return refine_marked(mesh, marked, scheme, levels)
    sch = get_scheme(scheme)
    levels = as_count(levels, "levels")
    out = refine_uniform(mesh, sch, levels, strict)
    return out, np.arange(out.n_triangles, dtype=np.int64) // sch.n_children**levels
