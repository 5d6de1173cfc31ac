"""The rounds of one step on the working mesh: closure (with the upgrade of poor
transitions), expansion of conflicts (two levels of points on one edge), until nothing
changes."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ..partition import partition_many
from ..predicates import COORDINATE_RANGE, below_range
from ..schemes import Scheme
from .edgekeys import edge_keys, lookup, lookup_sorted
from .families import Families
from .labels import MN, NO, OM, canonical_labels
from .longest_edge import closure, touching
from .patterns import canonical_corners, min_angles, quality, stencil_coordinates
from .plan import SplitPlan, advanced, working_edges
from .working import StepInput, Tree, expand, with_edge_points


def plan_splits(tree: Tree, upgrades: Callable[[NDArray[np.int64], NDArray[np.int64]],
                                               NDArray[np.bool_]] | None = None,
                after: tuple[SplitPlan, NDArray[np.bool_], NDArray[np.int64]] | None = None
                ) -> SplitPlan:
    """Edges of the working mesh and the closure of its marks (pre-split edges included),
    with ``upgrades(nodes, codes)`` (e.g. :class:`Upgrades`) saying which triangles get
    ``NO`` split too. ``after``: the previous round's plan, its expanded working triangles
    and their children (:func:`expansions`), to advance the numbering from
    (:func:`~qdrefine.adaptive.plan.advanced`) instead of numbering again."""
    cl = working_edges(tree) if after is None else advanced(tree, *after)
    leaves = cl.leaves
    cl.split, _ = closure(cl.ce, tree.mark[leaves], cl.edges.shape[0], presplit=cl.pre,
                          earlier=lookup_sorted(tree.earlier_keys, cl.keys) >= 0,
                          upgrade=None if upgrades is None else
                          lambda t, code: upgrades(leaves[t], code), layers=UPGRADE_LAYERS,
                          around=cl.around)
    return cl


def one_sided_pieces(tree: Tree, cl: SplitPlan) -> tuple[NDArray[np.int64],
                                                         NDArray[np.int64]]:
    """The working edges that have points and one working triangle ``(C,)`` (the coarse
    side of finer triangles, or the mesh's boundary), and the keys of their pieces
    ``(C, k + 1)`` between their points."""
    cand = np.flatnonzero(cl.pre & (cl.counts == 1))
    chain = np.column_stack([cl.edges[cand, 0], tree.reg_pts[cl.pos[cand]],
                             cl.edges[cand, 1]]).astype(np.int64)
    return cand, edge_keys(chain[:, :-1], chain[:, 1:])


def conflicts(inp: StepInput, tree: Tree, cl: SplitPlan) -> bool:
    """Expand the coarse side of every pre-split edge one of whose pieces gets points too
    (two levels of points on one working edge); whether there was any."""
    return expansions(inp, tree, cl) is not None


def expansions(inp: StepInput, tree: Tree, cl: SplitPlan
               ) -> tuple[NDArray[np.bool_], NDArray[np.int64]] | None:
    """:func:`conflicts`, returning the expanded working triangles ``(W,) bool`` and their
    children's tree nodes ``(X, T)``, or None if there was no conflict."""
    cand, sub = one_sided_pieces(tree, cl)
    if not cand.size:
        return None
    at = lookup(cl.keys, sub)
    hit = np.where(at >= 0, cl.split[at], False) | (lookup(tree.reg_keys, sub) >= 0)
    bad = np.zeros(cl.edges.shape[0], dtype=bool)
    bad[cand[hit.any(axis=1)]] = True
    own = touching(bad, cl.tri_edges)
    if not own.any():
        return None
    return own, expand(tree, cl.leaves[own], inp.sch)


#: A transition that leaves ``NO`` unsplit is upgraded (``NO`` split too) when that
#: multiplies the smallest angle of its best pattern by at least this factor. It trades
#: quality for spread: on the L-shape AFEM loop 1.7 keeps 0.423 of the initial angle with a
#: median of 9.7 triangles added per marked one, 1.6 kept 0.437 with 10.15
#: (docs/adaptive.md, "Upgrades").
UPGRADE = 1.7

#: Upgrades may bring new triangles into a step this many layers beyond the closure of the
#: marks (:func:`~qdrefine.adaptive.longest_edge.closure`); 2 is the least that keeps the
#: upgrades' gain on the Gmsh examples (docs/adaptive.md, "Upgrades").
UPGRADE_LAYERS = 2


#: No upgrades for triangles with a smallest angle (degrees) under this: thin triangles are
#: thin by design (boundary layers), and upgrading them refines across the layers.
UPGRADE_MIN_ANGLE = 20.0


def upgraded(plain: NDArray[np.float64], better: NDArray[np.float64],
             own: NDArray[np.float64]) -> NDArray[np.bool_]:
    """The upgrade rule: whether a triangle whose smallest angle is ``own`` takes the
    pattern whose smallest angle is ``better`` (with ``NO`` split) instead of the one whose
    smallest angle is ``plain`` (degrees, arrays of one shape)."""
    return (own >= UPGRADE_MIN_ANGLE) & (better >= UPGRADE * plain)


class Upgrades:
    """The upgrade rule of a step, a property of each working triangle's shape alone.

    A transition that leaves ``NO`` unsplit (codes ``MN`` and ``MN, OM``) of a
    seven-triangle scheme keeps, at worst, about half of its triangle's minimum angle; on
    right-angled triangles splitting ``NO`` too keeps much more (all of it on a 30-60-90
    triangle). A triangle gets ``NO`` split when its ``MN`` is split and the best pattern
    with ``NO`` split is at least :data:`UPGRADE` times better than the best without
    (``MN, NO`` against ``MN``), or, once its ``OM`` is split too, when the full partition is
    that much better than the best ``MN, OM`` pattern. No mesh-wide floor: the comparison is
    on the triangle's own shape. An upgrade splits an edge of the triangle across ``NO``
    too, which may want an upgrade of its own: so that this cannot cascade (it did, through
    the thin right triangles of a boundary layer, where nearly every transition wants one),
    upgrades may bring new triangles in only :data:`UPGRADE_LAYERS` layers beyond the
    closure of the marks; further out a triangle is upgraded only where the triangle across
    its ``NO`` is refined already. The verdicts are computed once per tree node, on first
    need.
    """

    def __init__(self, inp: StepInput, tree: Tree, known: NDArray[np.int8] | None = None
                 ) -> None:
        """``known (N, 2) int8``, optional: verdicts of the first ``N`` tree nodes judged
        already (:func:`upgrade_verdicts` by ``MN``, by ``OM``; -1 where not judged), e.g.
        by the window's estimate (:mod:`~qdrefine.adaptive.reach`)."""
        self.inp, self.tree = inp, tree
        # (nodes, [by MN, by OM]): 1 upgraded, 0 not, -1 not judged yet
        self.verdicts = np.full((0, 2), -1, dtype=np.int8)
        if known is not None:
            known = np.asarray(known)
            if known.ndim != 2 or known.shape[1] != 2 \
                    or known.shape[0] > tree.triangles.shape[0]:
                raise ValueError(f"internal error: known verdicts of shape {known.shape} for "
                                 f"{tree.triangles.shape[0]} tree nodes")
            self.verdicts = known.astype(np.int8)

    def __call__(self, nodes: NDArray[np.int64], code: NDArray[np.int64]) -> NDArray[np.bool_]:
        if self.inp.k != 2:
            return np.zeros(nodes.shape, dtype=bool)
        size = self.tree.triangles.shape[0]
        if self.verdicts.shape[0] < size:  # the tree grew
            grow = np.full((size - self.verdicts.shape[0], 2), -1, dtype=np.int8)
            self.verdicts = np.concatenate([self.verdicts, grow])
        with_om = (code & OM) != 0
        for col, need in ((0, np.ones(nodes.shape, dtype=bool)), (1, with_om)):
            todo = np.unique(nodes[need & (self.verdicts[nodes, col] < 0)])
            if todo.size:
                self.verdicts[todo, col] = self._judge(todo, col)
        return (self.verdicts[nodes, 0] == 1) | (with_om & (self.verdicts[nodes, 1] == 1))

    def _judge(self, nodes: NDArray[np.int64], col: int) -> NDArray[np.int8]:
        tree = self.tree
        return upgrade_verdicts(tree.points, tree.triangles[nodes], tree.labels[nodes], col,
                                self.inp.sch)


def upgrade_verdicts(points: NDArray[np.float64], rows: NDArray, labels: NDArray,
                     col: int, sch: Scheme) -> NDArray[np.int8]:
    """The upgrade rule's verdicts ``(G,)`` (1: ``NO`` split too, 0: not) for the triangles
    ``rows (G, 3)`` with canonical labels ``labels (G, 3)``: by ``MN`` (``col = 0``: the
    best ``MN, NO`` pattern against the best ``MN`` one) or by ``OM`` (``col = 1``: the
    full partition against the best ``MN, OM`` pattern); a seven-triangle scheme."""
    k = sch.stencil.per_edge
    corners = canonical_corners(points, rows, labels)
    coords = stencil_coordinates(corners, k)
    own = min_angles(corners)
    if col == 0:
        verdict = upgraded(quality(coords, k, MN), quality(coords, k, MN | NO), own)
    else:
        verdict = upgraded(quality(coords, k, MN | OM), full_quality(corners, sch), own)
    return verdict.astype(np.int8)


def waiting_upgrades(points: NDArray[np.float64], fam: Families, families: NDArray[np.int64],
                     keys: NDArray[np.int64], sch: Scheme) -> NDArray[np.bool_]:
    """``(G,) bool``: which of the transitions ``families (G,)`` a step upgrades as soon as
    the triangle across their parent's edge with key ``keys (G,)`` gets a split edge: that
    edge is the parent's unsplit ``NO`` and the upgrade rule (:class:`Upgrades`) says so.

    An earlier step left such a transition waiting: its upgrade was judged outside the
    closure of that step's marks, where it may not bring a new triangle in, and the
    triangle across ``NO`` had no split edge. Once that triangle changes, in any later step
    and however far from the marks, every triangle around ``NO`` has a split edge and the
    upgrade is made."""
    out = np.zeros(families.shape[0], dtype=bool)
    if sch.stencil.per_edge != 2 or not families.size:
        return out
    rows = fam.parent_triangles[families]
    labels = canonical_labels(points, rows)
    g = np.arange(rows.shape[0])
    code = fam.codes(families)
    no_key = edge_keys(rows[g, labels[:, 1]], rows[g, labels[:, 2]])
    idx = np.flatnonzero((no_key == keys) & (code & NO == 0))
    if not idx.size:
        return out
    up = upgrade_verdicts(points, rows[idx], labels[idx], 0, sch) == 1
    om = np.flatnonzero(~up & (code[idx] & OM != 0))
    if om.size:
        up[om] = upgrade_verdicts(points, rows[idx[om]], labels[idx[om]], 1, sch) == 1
    out[idx[up]] = True
    return out


def full_quality(corners: NDArray[np.float64], sch: Scheme) -> NDArray[np.float64]:
    """Smallest angle (degrees) of the scheme's partition of triangles ``(G, 3, 2)``
    (children of this step: a corner below the coordinate range is the refinement's new
    point, said as uniform refinement says it)."""
    a = np.abs(corners.reshape(-1, 2))
    low = ((a < COORDINATE_RANGE[0]) & (a != 0)).any(axis=1)
    if low.any():
        raise below_range(None, corners.reshape(-1, 2)[np.flatnonzero(low)[0]], None)
    points, tris = partition_many(corners, sch, strict=False)
    return min_angles(points[np.arange(tris.shape[0])[:, None, None], tris]).min(axis=1)


def unchanged(inp: StepInput, tree: Tree, cl: SplitPlan, code: NDArray[np.int64]
              ) -> NDArray[np.bool_]:
    """Family parents whose transition stays the same (their members are copied)."""
    f = tree.fam[cl.leaves]
    out = f >= 0
    out[out] = code[out] == inp.codes[f[out]]
    return out


def new_points(tree: Tree, cl: SplitPlan, k: int
               ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """All points and the point ids ``(E, k)`` of every split edge (from the lower id),
    ``-1`` on unsplit edges: existing ones from the registry, the others numbered by rank."""
    new = cl.split & ~cl.pre
    points, ids = with_edge_points(tree.points, cl.edges[new], k)
    ep = np.full((cl.edges.shape[0], k), -1, dtype=np.int64)
    ep[cl.pre] = tree.reg_pts[cl.pos[cl.pre]]
    ep[new] = ids
    return points, ep
