"""The input triangle whose cell tag and cell data a triangle made from a group of input
triangles takes: the triangles made from a transition family's parent (by refinement, or
by coarsening, which chooses transitions again), a triangle restored by coarsening.
``parents`` keeps mapping them by row (a family's new triangles to its first member, a
restored triangle to its child with the lowest row: children stay contiguous and in
parent order); their data comes from here.

A triangle made again with the vertices of a member stands for that member
(:func:`same_rows`). Otherwise, the group's first row would make the output depend on the
triangle order whenever the members differ (cell data set per triangle after refinement,
marks read back through ``parents``); the rule here depends on the coordinates only: the
member whose vertices, sorted by ``(x, y)``, come first in lexicographic order
(:func:`first_in_coordinate_order`; distinct triangles never tie).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..mesh import Mesh
from .families import Families
from .output import blocks

__all__ = ["data_rows", "first_in_coordinate_order", "inherited", "same_rows"]


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
    corners = points[triangles[rows]]  # (R, 3, 2)
    x, y = corners[:, :, 0], corners[:, :, 1]
    row_of = np.repeat(np.arange(rows.size), 3)
    order = np.lexsort((y.ravel(), x.ravel(), row_of)).reshape(-1, 3)  # each row's vertices
    sx, sy = x.ravel()[order], y.ravel()[order]  # (R, 3), sorted by (x, y) within the row
    keys = [sy[:, 2], sx[:, 2], sy[:, 1], sx[:, 1], sy[:, 0], sx[:, 0], group]
    by = np.lexsort(keys)  # by group, then the coordinates (last key first)
    first = np.concatenate([[True], group[by][1:] != group[by][:-1]])
    return group[by][first], rows[by][first]


def same_rows(rows: NDArray, pool: NDArray) -> NDArray[np.int64]:
    """For each of ``rows (R, 3)``, the row of ``pool (P, 3)`` with the same three vertices
    (in any order), or -1."""
    if not len(rows) or not len(pool):
        return np.full(len(rows), -1, dtype=np.int64)
    keys = np.ascontiguousarray(np.sort(np.concatenate([pool, rows]), axis=1), dtype=np.int64)
    _, which = np.unique(keys.view([("", np.int64)] * 3).ravel(), return_inverse=True)
    first = np.full(which.max() + 1, -1, dtype=np.int64)
    first[which[:len(pool)][::-1]] = np.arange(len(pool) - 1, -1, -1)
    return first[which[len(pool):]]


def data_rows(before: Mesh, fam: Families, triangles: NDArray, parents: NDArray[np.int64]
              ) -> NDArray[np.int64]:
    """The ``before`` row whose cell tag and cell data each output triangle takes: its
    parent (``parents``, a step's), except for the triangles made from a transition
    family's parent, which the step lists under the family's first member: the member
    with the same vertices, else the member that comes first in coordinate order.
    Members copied as they are keep their own.

    ``fam``: ``before``'s families, members consecutive; ``triangles (M', 3)``: the
    output's. Returns ``parents`` itself (no pass over the output) for an input without
    families, or when no row changes.
    """
    if not fam.n_families:
        return parents
    member = fam.member[parents]
    cand = np.flatnonzero(member >= 0)
    if cand.size:  # not the members copied as they are
        copied = (triangles[cand] == before.triangles[parents[cand]]).all(axis=1)
        cand = cand[~copied]
    if not cand.size:
        return parents
    families = np.unique(member[cand])
    counts = fam.counts()[families]
    members = blocks(fam.first()[families], counts)
    found, chosen = first_in_coordinate_order(before.points, before.triangles, members,
                                              np.repeat(families, counts))
    by_family = np.full(fam.n_families, -1, dtype=np.int64)
    by_family[found] = chosen
    mapped = by_family[member[cand]]
    same = same_rows(triangles[cand], before.triangles[members])
    mapped[same >= 0] = members[same[same >= 0]]
    if (mapped == parents[cand]).all():
        return parents
    rows = parents.copy()
    rows[cand] = mapped
    return rows


def inherited(before: Mesh, after: Mesh, rows: NDArray[np.int64]) -> Mesh:
    """``after`` with the cell tags and cell data of ``before``'s ``rows`` (one per output
    triangle)."""
    tags = None if before.cell_tags is None else before.cell_tags[rows]
    cell_data = {name: values[rows] for name, values in before.cell_data.items()}
    return Mesh._trusted(after.points, after.triangles, tags, after.edges, after.edge_tags,
                         after.point_data, cell_data, after.physical_names)
