"""Every check a triangle mesh can fail, on raw arrays: one place for :class:`~qdrefine.Mesh`,
the readers of :mod:`qdrefine.io` and ``qdrefine check``.

:func:`find` returns *all* problems of ``points (N, 2)`` and ``triangles (M, 3)`` (with the
optional tags), each a :class:`Problem` naming its kind, how many instances there are and
where the first one is. ``Mesh`` calls it with ``stop_at_error=True`` and raises the first
error as ``ValueError``; ``qdrefine check`` prints the whole list. :data:`KINDS` lists every
kind with its severity: an ``"error"`` makes the mesh unusable (``Mesh`` refuses it), a
``"warning"`` does not, a ``"note"`` says that a check was skipped.

Examples
--------
>>> from qdrefine import check
>>> found = check.find([[0, 0], [1, 0], [0, 1], [0, 1]], [[0, 1, 2], [1, 3, 2]])
>>> [p.kind for p in found.errors]
['zero-area', 'duplicate-points']
>>> found.errors[1].message
'points 2 and 3 are both at (0.0, 1.0)'
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..memory import check_needed, validation_needed
from ..numbering import index_dtype, sort_edges
from ..sweep import vertices_of
from . import boundary as boundary_checks
from . import cells as cell_checks
from . import edges as edge_checks
from . import points as point_checks
from .boundary import hanging_nodes
from .cells import not_int64
from .edges import Topology, bucket_scan, edge_scan
from .points import NEAR_DUPLICATE, duplicate_pairs, near_duplicates
from .report import KINDS, MIN_ANGLE, Checked, Findings, Problem, Stop

__all__ = ["KINDS", "MIN_ANGLE", "NEAR_DUPLICATE", "Checked", "Problem", "bucket_scan",
           "duplicate_pairs", "edge_scan", "find", "hanging_nodes", "index_dtype",
           "near_duplicates", "not_int64"]


def find(points: ArrayLike, triangles: ArrayLike, cell_tags: ArrayLike | None = None,
         edges: ArrayLike | None = None, edge_tags: ArrayLike | None = None, *,
         flip_clockwise: bool = False, stop_at_error: bool = False, warnings: bool = True,
         min_angle: float = MIN_ANGLE, geometry: bool = True, base: int = 0,
         point_numbers: ArrayLike | None = None, triangle_numbers: ArrayLike | None = None,
         edge_numbers: ArrayLike | None = None) -> Checked:
    """All problems of a mesh given as arrays.

    Parameters
    ----------
    points : (N, 2) float
    triangles : (M, 3) int
    cell_tags : (M,) int, optional
    edges : (K, 2) int, optional
        Tagged edges, given together with ``edge_tags (K,) int``.
    flip_clockwise : bool
        Flip clockwise triangles (a warning) instead of refusing them (an error); the
        readers do this.
    stop_at_error : bool
        Return at the first error (what :class:`~qdrefine.Mesh` needs).
    warnings : bool
        Also look for warnings (unused points, pinched vertices, small angles).
    min_angle : float
        Threshold of the ``small-angle`` warning, degrees.
    geometry : bool
        False skips every check that uses coordinates (e.g. for non-flat input).
    base : int
        Number of the first point and triangle in messages (files numbered from 1).
    point_numbers : (N,) int, optional
        The file's own number of every point (e.g. Gmsh node tags), used in messages and
        ``where`` instead of ``row + base``.
    triangle_numbers : (M,) int, optional
        The file's own number of every triangle (e.g. Gmsh element tags), likewise.
    edge_numbers : (K,) int, optional
        The file's own number of every tagged edge (Gmsh line element tags), likewise.

    Returns
    -------
    Checked
        Problems in the order checked (shape, coordinates, indices, orientation, topology,
        tags, warnings) and the normalized arrays.
    """
    found = Findings(stop_at_error, base, _numbers(point_numbers), _numbers(triangle_numbers),
                     _numbers(edge_numbers))
    out = Checked(found.problems)
    try:
        _run(found, out, points, triangles, cell_tags, edges, edge_tags, flip_clockwise,
             warnings, min_angle, geometry)
    except Stop:
        pass
    return out


def _numbers(values: ArrayLike | None) -> NDArray[np.int64] | None:
    return None if values is None else np.asarray(values, dtype=np.int64).reshape(-1)


def _run(found: Findings, out: Checked, points, triangles, cell_tags, edges, edge_tags,
         flip: bool, warnings: bool, min_angle: float, geometry: bool) -> None:
    p = cell_checks.points(found, points)
    t = cell_checks.triangles(found, triangles)
    if p is None or t is None:
        return
    out.points = p
    n = len(p)
    for what, numbers, rows in (("point_numbers", found.point_numbers, n),
                                ("triangle_numbers", found.triangle_numbers, len(t))):
        if numbers is not None and len(numbers) != rows:
            raise ValueError(f"{what} must give one number per row ({rows}), got "
                             f"{len(numbers)}")
    if not cell_checks.in_range(found, t, n):
        return found.skip("orientation, topology and tags", "vertex indices out of range")
    t = out.triangles = np.array(t, dtype=index_dtype(n), order="C")
    geometry = geometry and cell_checks.coordinates(found, p)
    if not geometry:
        found.skip("orientation, duplicate points, overlaps, hanging nodes and angles",
                   "no valid flat coordinates")
    check_needed(validation_needed(n, len(t), 0), f"validating {len(t)} triangles")
    oriented = flat = False
    if geometry:
        oriented, flat = cell_checks.orientation(found, p, t, flip)
    topo = Topology(t, n, sort_edges(t, n))
    used = None
    if not found.stop:
        used = edge_checks.used(t, n)
        out.summary = edge_checks.summary(t, used, topo) | {
            "numbered_from": found.base,
            "numbered_by": "file" if found.point_numbers is not None else "row"}
    manifold = edge_checks.overused(found, topo)
    if oriented:
        oriented = edge_checks.folded(found, topo) and manifold
    if geometry:
        # validation: duplicates among boundary vertices; one at an inner vertex is always
        # an overlap too, which the sweep finds
        point_checks.duplicates(found, p, vertices_of(topo.bedges, n) if used is None else
                                np.flatnonzero(used))
        if flat:
            boundary_checks.boundary(found, p, topo, oriented)
        else:
            found.skip("overlaps and hanging nodes", "triangles with zero area")
    if found.edge_numbers is not None and np.ndim(edges) == 2 \
            and len(found.edge_numbers) != len(edges):
        raise ValueError(f"edge_numbers must give one number per tagged edge ({len(edges)}), "
                         f"got {len(found.edge_numbers)}")
    out.cell_tags = cell_checks.cell_tags(found, cell_tags, len(t))
    out.edges, out.edge_tags = cell_checks.tagged_edges(found, edges, edge_tags, topo, n,
                                                        t.dtype)
    if warnings:
        used = edge_checks.used(t, n) if used is None else used
        edge_checks.unused(found, used)
        if geometry:
            point_checks.near_duplicate_points(found, p, np.flatnonzero(used))
        if oriented:
            edge_checks.pinched(found, topo.bedges)
        if geometry:
            cell_checks.small_angles(found, p, t, min_angle)
    out.buckets = topo.buckets
