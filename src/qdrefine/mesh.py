"""The mesh data model: one small immutable dataclass of NumPy arrays."""

from __future__ import annotations

import operator
from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .check import find, index_dtype, not_int64
from .numbering import EdgeBuckets, edge_ids
from .predicates import orient_signs

__all__ = ["Mesh", "edge_ids", "index_dtype"]


def _readonly(a: Any) -> Any:
    if isinstance(a, np.ndarray):
        a.flags.writeable = False
    return a


def _frozen_map(data: Mapping[str, NDArray] | None) -> Mapping[str, NDArray]:
    """A read-only mapping of read-only arrays (empty for ``None``)."""
    return MappingProxyType({str(k): _readonly(np.asarray(v)) for k, v in (data or {}).items()})


#: The cell-data names under which files hold :attr:`Mesh.transitions` and
#: :attr:`Mesh.origins` (``qdrefine.io``): reserved, a mesh's own cell data cannot use them.
HISTORY_CELL_DATA = ("qdrefine:transitions", "qdrefine:origins")


def _data(data: Mapping[str, ArrayLike] | None, size: int, what: str, rows: str,
          reserved: tuple[str, ...] = ()) -> Mapping[str, NDArray]:
    """Copies of the arrays of ``data``, each with ``size`` rows, in a read-only mapping;
    the names ``reserved`` are refused."""
    if data is not None and not isinstance(data, Mapping):
        raise TypeError(f"{what} must be a mapping of names to arrays, got "
                        f"{type(data).__name__}")
    out = {}
    for key, value in (data or {}).items():
        a = np.array(value)
        if not isinstance(key, str):
            raise ValueError(f"{what}: keys must be strings, got {key!r}")
        if key in reserved:
            raise ValueError(f"{what}[{key!r}]: this name is reserved for the refinement "
                             f"history, which files store under it (pass it as "
                             f"{key.split(':')[1]}=..., or rename the field)")
        if a.ndim == 0 or a.shape[0] != size:
            raise ValueError(f"{what}[{key!r}] must have one row per {rows[:-1]} "
                             f"({size} {rows}), got shape {a.shape}")
        if a.dtype.kind not in "biuf":
            raise ValueError(f"{what}[{key!r}] must be numeric, got dtype {a.dtype}")
        out[key] = a
    return _frozen_map(out)


def _names(names: Mapping[tuple[int, int], str] | None) -> Mapping[tuple[int, int], str]:
    if names is not None and not isinstance(names, Mapping):
        raise TypeError("physical_names must be a mapping of (dimension, tag) pairs to names, "
                        f"got {type(names).__name__}")
    out = {}
    for key, name in (names or {}).items():
        try:  # integers only: "21" or (2.7, 1.5) became (2, 1)
            if isinstance(key, str | bytes):  # bytes iterate as integers
                raise TypeError
            dim, tag = (operator.index(x) for x in key)
        except (TypeError, ValueError):
            raise ValueError(f"physical_names: keys must be (dimension, tag) pairs of "
                             f"integers, got {key!r}") from None
        if dim not in (0, 1, 2):
            raise ValueError(f"physical_names: dimension must be 0, 1 or 2, got {dim}")
        out[(dim, tag)] = str(name)
    return MappingProxyType(out)


def _transitions(rows: ArrayLike | None, triangles: NDArray, n_points: int
                 ) -> NDArray[np.int64] | None:
    """The history rows ``(M, 3)``: ``-1`` rows or vertex rows of existing points."""
    a = _rows_of(rows, triangles, "transitions")
    if a is not None and a.size and (
            a.min() < -1 or a.max() >= n_points
            or ((a == -1).any(axis=1) & (a != -1).any(axis=1)).any()):
        raise ValueError("transitions: each row is a vertex row or all -1")
    return a


def _origins(rows: ArrayLike | None, triangles: NDArray, n_points: int
             ) -> NDArray[np.int64] | None:
    """The origin rows ``(M, 3)``: vertex rows of existing points."""
    a = _rows_of(rows, triangles, "origins")
    if a is not None and a.size and (a.min() < 0 or a.max() >= n_points):
        raise ValueError(f"origins: vertex ids must be in 0..{n_points - 1}")
    return a


def history_rows(points: NDArray[np.float64], triangles: NDArray,
                 transitions: ArrayLike | None, origins: ArrayLike | None, flip: bool = False
                 ) -> tuple[NDArray[np.int64] | None, NDArray[np.int64] | None]:
    """``transitions`` and ``origins`` checked (:func:`_transitions`, :func:`_origins`) and
    counter-clockwise (:func:`_counter_clockwise`; ``flip``: clockwise rows of a mirrored
    file flipped, else refused)."""
    n = points.shape[0]
    return (_counter_clockwise(points, _transitions(transitions, triangles, n), "transitions",
                               flip),
            _counter_clockwise(points, _origins(origins, triangles, n), "origins", flip))


def _counter_clockwise(points: NDArray[np.float64], rows: NDArray[np.int64] | None,
                       name: str, flip: bool = False) -> NDArray[np.int64] | None:
    """History rows ``(M, 3)`` (``transitions`` or ``origins``; ``-1`` rows skipped) checked
    counter-clockwise by the exact predicate: clockwise ones flipped where ``flip`` (a
    mirrored file, whose triangles are flipped too), else a ``ValueError`` naming the first
    (triangles that refinement restores from these rows would be clockwise)."""
    if rows is None or not rows.size:
        return rows
    used = np.flatnonzero(rows[:, 0] >= 0)
    sign = orient_signs(np.ascontiguousarray(points, dtype=np.float64), rows[used])
    bad = used[sign <= 0]
    if not bad.size:
        return rows
    if flip and (sign < 0).sum() == bad.size:
        rows = rows.copy()
        rows[bad] = rows[bad][:, [0, 2, 1]]
        return rows
    r = int(bad[0])
    raise ValueError(f"{name}: row {r} {tuple(int(v) for v in rows[r])} is clockwise or flat; "
                     "history rows are counter-clockwise vertex rows")


def _rows_of(rows: ArrayLike | None, triangles: NDArray, name: str
             ) -> NDArray[np.int64] | None:
    """``rows`` as an int64 copy with the shape of ``triangles``, or None."""
    if rows is None:
        return None
    given = np.asarray(rows)
    problem = not_int64(given, name)
    if problem is not None:
        raise ValueError(problem)
    a = np.array(given, dtype=np.int64)
    if a.shape != triangles.shape:
        raise ValueError(f"{name} must have shape {triangles.shape}, got {a.shape}")
    return a


@dataclass(frozen=True, eq=False)
class Mesh:
    """A 2D triangle mesh.

    Parameters
    ----------
    points : (N, 2) float64
        Vertex coordinates: each 0 or of magnitude in ``[1e-100, 1e100]`` (the range in
        which every predicate is exact).
    triangles : (M, 3) int
        Vertex indices, counter-clockwise, positive area (checked exactly). Stored as
        ``int32`` while ``N`` fits, ``int64`` beyond.
    cell_tags : (M,) int64, optional
        One tag per triangle (e.g. a Gmsh physical group).
    edges : (K, 2) int, optional
        Tagged boundary or interface edges; each must be an edge of some triangle.
    edge_tags : (K,) int64, optional
        One tag per row of ``edges``; given together with ``edges``.
    point_data : mapping of str to (N, ...) array, optional
        Per-point fields (a solution, a size field). Refinement interpolates them linearly
        to the new points.
    cell_data : mapping of str to (M, ...) array, optional
        Per-triangle fields (a material id, an indicator). Children inherit their parent's
        values.
    physical_names : mapping of (int, int) to str, optional
        Names of tags, keyed by ``(dimension, tag)`` as Gmsh's ``$PhysicalNames``: dimension
        2 for ``cell_tags``, 1 for ``edge_tags``.
    transitions : (M, 3) int, optional
        Refinement history for local refinement: for each triangle that is a child of a
        transition ("green") pattern, the counter-clockwise vertex row of the triangle the
        pattern replaced; ``-1`` rows for every other triangle. Set by
        :func:`qdrefine.refine` with ``marked``, read by the next such call, which coarsens
        those patterns before refining them (``docs/adaptive.md``). ``None``: no triangle is
        a transition child.
    origins : (M, 3) int, optional
        Refinement history for coarsening: for each triangle, the vertex row of the
        triangle of the mesh that local refinement started from (its *origin*) that it
        lies in. Set by :func:`qdrefine.refine` with ``marked`` (the input's triangles
        where the input has none), carried by every refinement, read by
        :func:`qdrefine.coarsen`, which restores only triangles of an origin's uniform
        refinements (not checked against the points: they only choose among exact
        partitions, so a coarsened mesh stays valid either way). ``None``: no history
        (the mesh cannot be coarsened).

    Construction validates everything once with :func:`qdrefine.check.find` and raises
    ``ValueError`` naming the first problem and where (triangle, vertex or edge ids): shapes,
    non-finite or out-of-range coordinates, indices, zero-area or clockwise triangles, two
    used points at the same coordinates, an edge shared by more than two triangles, two
    triangles folded onto one side of their edge, hanging nodes, tags. Unused points are
    allowed (kept). The arrays are copied and made read-only. Functions of qdrefine return
    new meshes and never change one.
    """

    points: NDArray[np.float64]
    triangles: NDArray[np.integer]
    cell_tags: NDArray[np.int64] | None = None
    edges: NDArray[np.integer] | None = None
    edge_tags: NDArray[np.int64] | None = None
    point_data: Mapping[str, NDArray] | None = None
    cell_data: Mapping[str, NDArray] | None = None
    physical_names: Mapping[tuple[int, int], str] | None = None
    transitions: NDArray[np.int64] | None = None
    origins: NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        fields, buckets = _validated(self.points, self.triangles, self.cell_tags, self.edges,
                                     self.edge_tags)
        object.__setattr__(self, "_buckets", buckets)
        n, m = fields["points"].shape[0], fields["triangles"].shape[0]
        fields["point_data"] = _data(self.point_data, n, "point_data", "points")
        fields["cell_data"] = _data(self.cell_data, m, "cell_data", "triangles",
                                    HISTORY_CELL_DATA)
        fields["physical_names"] = _names(self.physical_names)
        fields["transitions"], fields["origins"] = history_rows(
            fields["points"], fields["triangles"], self.transitions, self.origins)
        for name, value in fields.items():
            object.__setattr__(self, name, _readonly(value))

    @classmethod
    def _trusted(cls, points: NDArray, triangles: NDArray, cell_tags: NDArray | None = None,
                 edges: NDArray | None = None, edge_tags: NDArray | None = None,
                 point_data: Mapping[str, NDArray] | None = None,
                 cell_data: Mapping[str, NDArray] | None = None,
                 physical_names: Mapping[tuple[int, int], str] | None = None,
                 transitions: NDArray | None = None, buckets: EdgeBuckets | None = None,
                 origins: NDArray | None = None) -> Mesh:
        """A mesh from arrays already known to be valid (output of qdrefine's kernels or of
        :func:`qdrefine.check.find`, whose ``buckets`` the first refinement then reuses)."""
        mesh = object.__new__(cls)
        if buckets is not None:
            object.__setattr__(mesh, "_buckets", buckets)
        for name, value in (("points", points), ("triangles", triangles),
                            ("cell_tags", cell_tags), ("edges", edges),
                            ("edge_tags", edge_tags),
                            ("point_data", _frozen_map(point_data)),
                            ("cell_data", _frozen_map(cell_data)),
                            ("physical_names", MappingProxyType(dict(physical_names or {}))),
                            ("transitions", transitions), ("origins", origins)):
            object.__setattr__(mesh, name, _readonly(value))
        return mesh

    def _take_buckets(self) -> EdgeBuckets | None:
        """The sorted edges that validation built (:func:`qdrefine.numbering.sort_edges` of
        ``triangles``), handed once to the first uniform refinement, which then numbers no
        edges itself; ``None`` afterwards and for meshes built by qdrefine's kernels. Until
        then they hold about 30 bytes per triangle."""
        return self.__dict__.pop("_buckets", None)

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without what is kept for the next call (the sorted edges, transition
        families: private attributes); read-only mappings as plain dicts."""
        return {k: dict(v) if isinstance(v, MappingProxyType) else v
                for k, v in self.__dict__.items() if not k.startswith("_")}

    def __setstate__(self, state: dict[str, Any]) -> None:
        for k, v in state.items():
            if k in ("point_data", "cell_data"):  # their arrays come back writeable
                value = _frozen_map(v)
            else:
                value = MappingProxyType(v) if isinstance(v, dict) else _readonly(v)
            object.__setattr__(self, k, value)

    @property
    def n_points(self) -> int:
        return int(self.points.shape[0])

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    def replace(self, **changes: Any) -> Mesh:
        """A validated copy with some fields replaced (``dataclasses.replace``)."""
        return replace(self, **changes)

    def __repr__(self) -> str:
        tags = "" if self.cell_tags is None else f", {len(np.unique(self.cell_tags))} cell tags"
        edges = "" if self.edges is None else f", {len(self.edges)} tagged edges"
        return f"Mesh({self.n_points} points, {self.n_triangles} triangles{tags}{edges})"


def need_mesh(mesh: object, function: str) -> None:
    """``TypeError`` saying that ``function`` needs a :class:`Mesh`, unless ``mesh`` is one
    (instead of an ``AttributeError`` deep inside)."""
    if not isinstance(mesh, Mesh):
        raise TypeError(f"{function}() needs a Mesh, got {type(mesh).__name__}")


def _validated(points: ArrayLike, triangles: ArrayLike, cell_tags: ArrayLike | None,
               edges: ArrayLike | None, edge_tags: ArrayLike | None
               ) -> tuple[dict[str, NDArray | None], EdgeBuckets | None]:
    found = find(points, triangles, cell_tags, edges, edge_tags, stop_at_error=True,
                 warnings=False)
    found.raise_first()
    return ({"points": found.points, "triangles": found.triangles,
             "cell_tags": found.cell_tags, "edges": found.edges, "edge_tags": found.edge_tags},
            found.buckets)
