"""The report model of :mod:`qdrefine.check`: every kind of problem with its severity
(:data:`KINDS`), one found problem (:class:`Problem`), what a check returns
(:class:`Checked`), and the collector the checks add to (:class:`Findings`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..numbering import EdgeBuckets

__all__ = ["KINDS", "MIN_ANGLE", "KEPT", "Problem", "Checked", "Findings", "Stop"]

#: Every kind of problem: its severity and what it means (the guide's table).
KINDS: dict[str, tuple[str, str]] = {
    "cell-types": ("error", "the file holds cells other than triangles, lines and vertices "
                            "(quads, tetrahedra, quadratic elements: refused)"),
    "not-flat": ("error", "3D points with some z != 0"),
    "points": ("error", "points are not an (N, 2) array of numbers"),
    "triangles": ("error", "triangles are not an (M, 3) array of integers"),
    "no-triangles": ("error", "the mesh has no triangles"),
    "non-finite": ("error", "a coordinate is NaN or infinite"),
    "coordinate-range": ("error", "a nonzero coordinate is outside [1e-100, 1e100] in "
                                  "magnitude (exact predicates)"),
    "index-range": ("error", "a triangle uses a vertex index that is not a point"),
    "zero-area": ("error", "a triangle has zero area (collinear or repeated corners)"),
    "clockwise": ("error", "a triangle is clockwise (readers flip it and warn instead)"),
    "duplicate-points": ("error", "two points used by triangles have identical coordinates"),
    "overused-edge": ("error", "an edge is shared by more than two triangles"),
    "folded-edge": ("error", "two triangles lie on the same side of their common edge "
                             "(they overlap)"),
    "hanging-node": ("error", "a vertex lies inside a boundary edge of another triangle "
                              "(non-conforming input)"),
    "self-intersection": ("error", "two boundary edges cross, or run along each other with "
                                   "their triangles on the same side (the mesh overlaps "
                                   "itself; the first one found is reported)"),
    "overlap": ("error", "part of the mesh lies on top of another part without any edges "
                         "crossing (e.g. a separate piece inside a triangle)"),
    "cell-tags": ("error", "cell_tags is not one integer per triangle"),
    "edge-tags": ("error", "tagged edges are not (K, 2) vertex indices with one integer tag "
                           "each"),
    "edge-not-in-mesh": ("error", "a tagged edge is not an edge of any triangle"),
    "data": ("error", "point or cell data, physical names or the refinement history do not "
                      "fit the mesh (reading refuses the file)"),
    "near-hanging-node": ("warning", "a boundary vertex off another triangle's boundary edge "
                                     "by less than 1e-12 times its length, outside it (a "
                                     "crack; inside it would be an overlap)"),
    "near-duplicate-points": ("warning", "two used points closer than 1e-12 times the "
                                         "mesh's extent (not identical: that is an error)"),
    "unused-points": ("warning", "points used by no triangle (kept, carried through "
                                 "refinement)"),
    "pinched-vertex": ("warning", "a vertex where separate fans of triangles touch"),
    "small-angle": ("warning", "triangles with a smallest angle below the threshold"),
    "too-thin": ("warning", "triangles so thin for their distance from the origin that their "
                            "new points, rounded to float64, would flatten a child: "
                            "refinement refuses them (`qdrefine check` only)"),
    "too-close": ("warning", "two parts of the mesh closer than float64 resolves at their "
                             "coordinates: the new boundary points, rounded, would make the "
                             "boundary cross itself, and refinement refuses the mesh "
                             "(`qdrefine check` only)"),
    "file": ("warning", "what the reader warns about the file (an entity in several physical "
                        "groups, elements given again with another tag, a field record "
                        "ignored): what reading keeps and what it drops (`qdrefine check` only)"),
    "skipped": ("note", "checks that could not run because of an earlier error"),
}


#: Default threshold (degrees) of the ``small-angle`` warning.
MIN_ANGLE = 5.0

#: Instances kept per kind by the compiled searches (all are counted).
KEPT = 64


@dataclass(frozen=True)
class Problem:
    """One kind of problem found in a mesh.

    ``message`` names the first instance (e.g. ``"points 3 and 17 are both at (0.5, 0.25)"``),
    ``count`` the number of instances, ``where`` the ids of the first instance (JSON-ready;
    numbered as in the message), ``severity`` is ``KINDS[kind][0]`` unless said otherwise.
    """

    kind: str
    message: str
    count: int = 1
    where: dict[str, Any] = field(default_factory=dict)
    severity: str = ""

    def __post_init__(self) -> None:
        if not self.severity:
            object.__setattr__(self, "severity", KINDS[self.kind][0])

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "severity": self.severity, "count": self.count,
                "message": self.message, "where": self.where}


@dataclass
class Checked:
    """What :func:`find` found, and the normalized arrays: ``points (N, 2) float64`` (a copy),
    ``triangles (M, 3)`` of :func:`index_dtype` (clockwise rows flipped when asked), tags as
    ``int64``; arrays are ``None`` where they could not be normalized."""

    problems: list[Problem]
    points: NDArray[np.float64] | None = None
    triangles: NDArray[np.integer] | None = None
    cell_tags: NDArray[np.int64] | None = None
    edges: NDArray[np.integer] | None = None
    edge_tags: NDArray[np.int64] | None = None
    summary: dict[str, Any] = field(default_factory=dict)
    buckets: EdgeBuckets | None = None  # the sorted edges of ``triangles``, for refinement

    @property
    def errors(self) -> list[Problem]:
        return [p for p in self.problems if p.severity == "error"]

    @property
    def ok(self) -> bool:
        """True when nothing makes the mesh unusable."""
        return not self.errors

    def raise_first(self, prefix: str = "") -> None:
        """Raise ``ValueError(prefix + message)`` of the first error, if any."""
        if self.errors:
            raise ValueError(prefix + self.errors[0].message)


class Stop(Exception):
    """Raised inside :func:`find` at the first error when ``stop_at_error``."""


class Findings:
    """The problems found so far; raises :class:`Stop` at the first error when ``stop``.
    Messages number points, triangles and tagged edges by ``point_numbers`` /
    ``triangle_numbers`` / ``edge_numbers`` (the file's own numbers, one per row) where
    given, else from ``base`` (edges: from 0)."""

    def __init__(self, stop: bool, base: int, point_numbers: NDArray | None = None,
                 triangle_numbers: NDArray | None = None,
                 edge_numbers: NDArray | None = None) -> None:
        self.problems: list[Problem] = []
        self.stop = stop
        self.base = base
        self.point_numbers, self.triangle_numbers = point_numbers, triangle_numbers
        self.edge_numbers = edge_numbers

    def add(self, kind: str, message: str, count: int = 1, severity: str = "",
            **where: Any) -> None:
        problem = Problem(kind, message, int(count), where, severity)
        self.problems.append(problem)
        if self.stop and problem.severity == "error":
            raise Stop

    def skip(self, what: str, because: str) -> None:
        self.add("skipped", f"{what} not checked: {because}", severity="note")

    def ids(self, values: ArrayLike) -> list[int]:
        """The numbers of points ``values`` in messages (the file's own, when known)."""
        return [self.point(v) for v in np.ravel(values)]

    def point(self, row: int) -> int:
        """The number of point ``row`` in messages: the file's node number when the reader
        gave them, else ``row + base``."""
        if self.point_numbers is not None:
            return int(self.point_numbers[row])
        return int(row) + self.base

    def triangle(self, row: int) -> int:
        """The number of triangle ``row`` in messages: the file's element number when the
        reader gave them, else ``row + base``."""
        if self.triangle_numbers is not None:
            return int(self.triangle_numbers[row])
        return int(row) + self.base

    def edge(self, row: int) -> int:
        """The number of tagged edge ``row`` in messages: the file's element number of the
        line when the reader gave them, else the row."""
        if self.edge_numbers is not None:
            return int(self.edge_numbers[row])
        return int(row)
