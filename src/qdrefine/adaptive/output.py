"""The output of one step: the children of every working triangle in input order, the
output's families, and the tagged edges cut where they were split."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..mesh import Mesh, index_dtype
from .edgekeys import edge_keys, lookup, oriented, register
from .families import Families
from .labels import FULL
from .patterns import PARTIAL, TRANSITIONS, pattern, stencil_ids
from .rounds import Closure, new_points, unchanged
from .working import StepInput, Tree, emit_full


def emit_step(inp: StepInput, tree: Tree, cl: Closure
              ) -> tuple[Mesh, NDArray[np.int64], Families, NDArray[np.bool_],
                         NDArray[np.bool_]]:
    """Children of every working triangle, in input order; unchanged families are copied.
    Returns ``(mesh, parents, families, inside, again)`` (see ``step.step``)."""
    k, mesh = inp.k, inp.mesh
    points, ep = new_points(tree, cl, k)
    code = cl.codes()
    keep = unchanged(inp, tree, cl, code)
    nk = np.ones(code.shape[0], dtype=np.int64)
    nk[code == FULL] = inp.sch.n_children
    for c in PARTIAL:
        nk[code == c] = len(TRANSITIONS[k][c][0])
    kept = np.flatnonzero(keep)
    kept_fam = tree.fam[cl.leaves[kept]]
    nk[kept] = inp.counts[kept_fam]
    start = np.concatenate([[0], np.cumsum(nk)])
    tris = np.empty((int(start[-1]), 3), dtype=np.int64)
    parents = np.repeat(tree.key[cl.leaves], nk)

    same = np.flatnonzero(code == 0)
    tris[start[same]] = cl.rows[same]
    full = np.flatnonzero(code == FULL)
    if full.size:
        kids = emit_full(points, cl.rows[full], ep[cl.tri_edges[full]], inp.sch)
        tris[blocks(start[full], nk[full])] = kids.reshape(-1, 3)
    new_fam = []  # (working triangles, stencils)
    for c in PARTIAL:
        sel = np.flatnonzero((code == c) & ~keep)
        if sel.size:
            ids = stencil_ids(cl.rows[sel], cl.labels[sel], cl.ce[sel], ep, k)
            tris[blocks(start[sel], nk[sel])] = pattern(points, ids, cl.labels[sel], k,
                                                        c).reshape(-1, 3)
            new_fam.append((sel, ids))
    rows = blocks(start[kept], nk[kept])
    olds = blocks(inp.first[kept_fam], nk[kept])
    tris[rows] = mesh.triangles[olds]
    parents[rows] = olds
    families = _families(cl.rows, start, nk, new_fam, kept, kept_fam, inp.fam)

    dtype = index_dtype(points.shape[0])
    cell_tags = None if mesh.cell_tags is None else mesh.cell_tags[parents]
    edges, edge_tags = None, None
    if mesh.edges is not None:
        new = cl.split & ~cl.pre
        keys, pts = register(tree.reg_keys, tree.reg_pts, cl.keys[new], ep[new])
        edges, edge_tags = _split_tagged(mesh.edges, mesh.edge_tags, keys, pts)
        edges = edges.astype(dtype)
    out = Mesh._trusted(points, tris.astype(dtype), cell_tags, edges, edge_tags)
    inside = np.repeat(tree.user[cl.leaves] & ~keep, nk)
    again = np.repeat(tree.again[cl.leaves] & (code != FULL), nk)  # done when partitioned
    return out, parents, families, inside, again


def blocks(start: NDArray[np.int64], size: NDArray[np.int64]) -> NDArray[np.int64]:
    """Concatenated ranges ``start[i] .. start[i] + size[i] - 1``."""
    total = int(size.sum())
    offset = np.arange(total) - np.repeat(np.cumsum(size) - size, size)
    return np.repeat(start, size) + offset


def _families(rows: NDArray[np.int64], start: NDArray[np.int64], nk: NDArray[np.int64],
              new: list[tuple[NDArray[np.int64], NDArray[np.int64]]], kept: NDArray[np.int64],
              kept_fam: NDArray[np.int64], old: Families) -> Families:
    """The output's families: the new transitions and the copied ones, by position."""
    items = np.concatenate([s for s, _ in new] + [kept]).astype(np.int64)
    parent = np.concatenate([rows[s] for s, _ in new] + [old.rows[kept_fam]])
    sten = np.concatenate([ids for _, ids in new] + [old.stencil[kept_fam]])
    order = np.argsort(items)
    items, parent, sten = items[order], parent[order], sten[order]
    member = np.full(int(start[-1]), -1, dtype=np.int64)
    member[blocks(start[items], nk[items])] = np.repeat(np.arange(items.size), nk[items])
    return Families(member, parent.reshape(-1, 3), sten.reshape(-1, old.stencil.shape[1]))


def _split_tagged(edges: NDArray, tags: NDArray, keys: NDArray[np.int64],
                  pts: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Cut every tagged edge ``a -> b`` that has points (``keys``, ``pts`` from the lower
    id) into pieces with its tag and direction, again until no piece has points."""
    e, t = edges.astype(np.int64), np.asarray(tags)
    k = pts.shape[1] if pts.ndim == 2 else 1
    while e.size:
        pos = lookup(keys, edge_keys(e[:, 0], e[:, 1]))
        hit = pos >= 0
        if not hit.any():
            break
        a, b = e[hit, 0], e[hit, 1]
        chain = np.column_stack([a, oriented(pts[pos[hit]], a, b), b])
        size = np.where(hit, k + 1, 1)
        start = np.cumsum(size) - size
        out = np.empty((int(size.sum()), 2), dtype=np.int64)
        out[start[~hit]] = e[~hit]
        out[blocks(start[hit], size[hit])] = np.stack([chain[:, :-1], chain[:, 1:]],
                                                      axis=2).reshape(-1, 2)
        e, t = out, np.repeat(t, size)
    return e, t
