"""The rounds of one step on the working mesh: closure, expansion of conflicts (two levels
of points on one edge) and the quality guard, until nothing changes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..kernels import number_edges
from .edgekeys import edge_keys, lookup
from .labels import FULL, canonical_edges, split_codes
from .longest_edge import closure
from .patterns import PARTIAL, choose, stencil_ids
from .working import StepInput, Tree, expand, with_edge_points


@dataclass
class Closure:
    """The working mesh's edges and the closure of its marks."""

    leaves: NDArray[np.int64]  # tree node of each working triangle
    rows: NDArray[np.int64]
    edges: NDArray
    tri_edges: NDArray[np.int64]
    counts: NDArray[np.int64]
    keys: NDArray[np.int64]
    pos: NDArray[np.int64]  # registry position of each edge, -1 if it has no points yet
    labels: NDArray[np.int8]
    ce: NDArray[np.int64]
    split: NDArray[np.bool_]

    @property
    def pre(self) -> NDArray[np.bool_]:
        return self.pos >= 0

    def codes(self) -> NDArray[np.int64]:
        """Split code of each working triangle."""
        return split_codes(self.split[self.ce])


def close(tree: Tree) -> Closure:
    """Edges of the working mesh and the closure of its marks (pre-split edges included)."""
    leaves = tree.leaves()
    rows = tree.rows[leaves]
    edges, tri_edges, counts = number_edges(rows, tree.points.shape[0])
    keys = edge_keys(edges[:, 0], edges[:, 1])
    pos = lookup(tree.reg_keys, keys)
    labels = tree.labels[leaves]
    ce = canonical_edges(labels, tri_edges)
    split, _ = closure(ce, tree.mark[leaves], edges.shape[0], presplit=pos >= 0)
    return Closure(leaves, rows, edges, tri_edges, counts, keys, pos, labels, ce, split)


def conflicts(inp: StepInput, tree: Tree, cl: Closure) -> bool:
    """Expand the coarse side of every pre-split edge one of whose pieces gets points too
    (two levels of points on one working edge)."""
    cand = np.flatnonzero(cl.pre & (cl.counts == 1))
    if not cand.size:
        return False
    chain = np.column_stack([cl.edges[cand, 0], tree.reg_pts[cl.pos[cand]],
                             cl.edges[cand, 1]]).astype(np.int64)
    sub = edge_keys(chain[:, :-1], chain[:, 1:])
    at = lookup(cl.keys, sub)
    hit = np.where(at >= 0, cl.split[at], False) | (lookup(tree.reg_keys, sub) >= 0)
    bad = np.zeros(cl.edges.shape[0], dtype=bool)
    bad[cand[hit.any(axis=1)]] = True
    own = bad[cl.tri_edges].any(axis=1)
    if not own.any():
        return False
    expand(tree, cl.leaves[own], inp.sch)
    return True


def promote(inp: StepInput, tree: Tree, cl: Closure, floor: float) -> bool:
    """Quality guard: mark the working triangles whose new transition has a child with
    minimum angle below ``floor``; seven-triangle schemes only."""
    if inp.k != 2 or floor <= 0:
        return False
    code = cl.codes()
    partial = (code != 0) & (code != FULL) & ~unchanged(inp, tree, cl, code)
    if not partial.any():
        return False
    points, ep = new_points(tree, cl, inp.k)
    bad = np.zeros(code.shape[0], dtype=bool)
    for c in PARTIAL:
        sel = np.flatnonzero(partial & (code == c))
        if sel.size:
            ids = stencil_ids(cl.rows[sel], cl.labels[sel], cl.ce[sel], ep, inp.k)
            bad[sel] = choose(points, ids, inp.k, c)[1] < floor
    tree.mark[cl.leaves[bad]] = True
    return bool(bad.any())


def unchanged(inp: StepInput, tree: Tree, cl: Closure, code: NDArray[np.int64]
              ) -> NDArray[np.bool_]:
    """Family parents whose transition stays the same (their members are copied)."""
    f = tree.fam[cl.leaves]
    out = f >= 0
    out[out] = code[out] == inp.codes[f[out]]
    return out


def new_points(tree: Tree, cl: Closure, k: int
               ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """All points and the point ids ``(E, k)`` of every split edge (from the lower id),
    ``-1`` on unsplit edges: existing ones from the registry, the others numbered by rank."""
    new = cl.split & ~cl.pre
    points, ids = with_edge_points(tree.points, cl.edges[new], k)
    ep = np.full((cl.edges.shape[0], k), -1, dtype=np.int64)
    ep[cl.pre] = tree.reg_pts[cl.pos[cl.pre]]
    ep[new] = ids
    return points, ep
