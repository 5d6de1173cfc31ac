"""The input triangle whose cell tag and cell data a triangle made from a group of input
triangles takes: the triangles made from a transition family's parent (by refinement, or
by coarsening, which chooses transitions again), a triangle restored by coarsening.
``parents`` keeps mapping them by row (a family's new triangles to its first member, a
restored triangle to its child with the lowest row: children stay contiguous and in
parent order); their data comes from here.

A triangle made again with the vertices of a member stands for that member
(:func:`same_triangles`: by coordinates, since a transition made again numbers its
centroid anew). Otherwise, the group's first row would make the output depend on the
triangle order whenever the members differ (cell data set per triangle after refinement,
marks read back through ``parents``); the rule here depends on the coordinates only: the
member whose vertices, sorted by ``(x, y)``, come first in lexicographic order
(:func:`first_in_coordinate_order`; distinct triangles never tie).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

from ..mesh import Mesh
from .families import Families
from .output import blocks

__all__ = ["data_rows", "first_in_coordinate_order", "inherited", "same_triangles",
           "sorted_corners"]


def first_in_coordinate_order(points: NDArray[np.float64], triangles: NDArray[np.integer],
                              rows: NDArray[np.int64], group: NDArray[np.int64]
                              ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """For each group of triangles, the member that comes first in coordinate order.

    Parameters
    ----------
    points : (N, 2) float64
    triangles : (M, 3) int
    rows : (R,) int64
        Rows of ``triangles``, the members of the groups.
    group : (R,) int64
        The group of each row.

    Returns
    -------
    groups : (G,) int64
        The distinct groups, ascending.
    chosen : (G,) int64
        For each, its member row whose three vertices, sorted by ``x`` then ``y``, come
        first in lexicographic order of the six coordinates.
    """
    rows, group = np.asarray(rows, dtype=np.int64), np.asarray(group, dtype=np.int64)
    if not rows.size:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)
    corners = sorted_corners(points, triangles[rows])
    by = np.lexsort([*corners.T[::-1], group])  # by group, then the coordinates
    first = np.concatenate([[True], group[by][1:] != group[by][:-1]])
    return group[by][first], rows[by][first]


def sorted_corners(points: NDArray[np.float64], triangles: NDArray[np.integer]
                   ) -> NDArray[np.float64]:
    """``(R, 6)``: each triangle's corners ``x0, y0, x1, y1, x2, y2``, sorted by ``x``
    then ``y`` (a key of the triangle that neither the vertex ids nor the row's rotation
    change)."""
    corners = points[triangles]  # (R, 3, 2)
    x, y = corners[:, :, 0].ravel(), corners[:, :, 1].ravel()
    order = np.lexsort((y, x, np.repeat(np.arange(len(triangles)), 3)))
    return np.stack([x[order], y[order]], axis=1).reshape(-1, 6)


def same_triangles(points: NDArray[np.float64], rows: NDArray, pool_points: NDArray[np.float64],
                   pool: NDArray) -> NDArray[np.int64]:
    """For each of ``rows (R, 3)`` (into ``points``), the row of ``pool (P, 3)`` (into
    ``pool_points``) with the same three corners, or -1: by coordinates, bit for bit, so a
    point that a step numbered anew (the centroid of a transition made again) matches."""
    if not len(rows) or not len(pool):
        return np.full(len(rows), -1, dtype=np.int64)
    keys = np.ascontiguousarray(np.concatenate([sorted_corners(pool_points, pool),
                                                sorted_corners(points, rows)]))
    _, which = np.unique(keys.view(np.dtype((np.void, 48))).ravel(), return_inverse=True)
    which = which.ravel()
    first = np.full(which.max() + 1, -1, dtype=np.int64)
    first[which[:len(pool)][::-1]] = np.arange(len(pool) - 1, -1, -1)
    return first[which[len(pool):]]


def data_rows(before: Mesh, fam: Families, after: Mesh, parents: NDArray[np.int64]
              ) -> NDArray[np.int64]:
    """The ``before`` row whose cell tag and cell data each output triangle takes: its
    parent (``parents``, a step's), except for the triangles made from a transition
    family's parent, which the step lists under the family's first member: the member
    with the same vertices, else the member that comes first in coordinate order.
    Members copied as they are keep their own.

    ``fam``: ``before``'s families, members consecutive; ``after``: the step's output.
    Returns ``parents`` itself (no pass over the output) for an input without
    families, or when no row changes.
    """
    if not fam.n_families:
        return parents
    member = fam.member[parents]
    cand = np.flatnonzero(member >= 0)
    if cand.size:  # not the members copied as they are
        copied = (after.triangles[cand] == before.triangles[parents[cand]]).all(axis=1)
        cand = cand[~copied]
    if not cand.size:
        return parents
    families = np.unique(member[cand])
    counts = fam.counts()[families]
    members = blocks(fam.first()[families], counts)
    if before.cell_tags is not None:
        _warn_of_mixed_tags(before, members, counts)
    found, chosen = first_in_coordinate_order(before.points, before.triangles, members,
                                              np.repeat(families, counts))
    by_family = np.full(fam.n_families, -1, dtype=np.int64)
    by_family[found] = chosen
    mapped = by_family[member[cand]]
    same = same_triangles(after.points, after.triangles[cand], before.points,
                          before.triangles[members])
    mapped[same >= 0] = members[same[same >= 0]]
    if (mapped == parents[cand]).all():
        return parents
    rows = parents.copy()
    rows[cand] = mapped
    return rows


def _warn_of_mixed_tags(before: Mesh, members: NDArray[np.int64],
                        counts: NDArray[np.int64]) -> None:
    """Warn when a family made again holds members of different cell tags (a user re-tagged
    one): its new triangles take one member's, so the other tag loses area (it went
    silently; review). ``members``: the families' member rows, ``counts`` per family."""
    tags = before.cell_tags[members]
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    mixed = np.minimum.reduceat(tags, starts) != np.maximum.reduceat(tags, starts)
    if mixed.any():
        i = int(np.argmax(mixed))
        rows = members[starts[i]:starts[i] + counts[i]]
        warnings.warn(f"the transition family of triangles {tuple(rows.tolist())} holds cell "
                      f"tags {tuple(np.unique(before.cell_tags[rows]).tolist())} "
                      f"({int(mixed.sum())} such families): joined and made again, each "
                      "family's triangles take one member's tag and data", stacklevel=4)


def inherited(before: Mesh, after: Mesh, rows: NDArray[np.int64]) -> Mesh:
    """``after`` with the cell tags and cell data of ``before``'s ``rows`` (one per output
    triangle)."""
    tags = None if before.cell_tags is None else before.cell_tags[rows]
    cell_data = {name: values[rows] for name, values in before.cell_data.items()}
    return Mesh._trusted(after.points, after.triangles, tags, after.edges, after.edge_tags,
                         after.point_data, cell_data, after.physical_names)
