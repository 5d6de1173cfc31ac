"""The working mesh of one step: the input with every family replaced by its parent, as a
tree whose *expanded* nodes are replaced by the children of their full partition."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..kernels import edge_points, emit
from ..mesh import Mesh
from ..schemes import Scheme
from .edgekeys import KEY, edge_keys, lookup, register
from .families import Families
from .labels import canonical_labels


@dataclass
class StepInput:
    """What one step starts from (fixed during the step)."""

    mesh: Mesh
    sch: Scheme
    fam: Families
    pairs: NDArray[np.int64]  # (P, 2) marked member, its family
    first: NDArray[np.int64]  # (F,) first member of each family
    counts: NDArray[np.int64]
    codes: NDArray[np.int64]

    @property
    def k(self) -> int:
        return self.sch.stencil.per_edge


@dataclass
class Tree:
    """Nodes of the working mesh: the input triangles that are not transition children and
    the family parents (roots), and the children of *expanded* nodes. The leaves, in order
    of ``key`` then creation, are the working mesh. Arrays only grow during a step."""

    triangles: NDArray[np.int64]  # (Nn, 3) vertex rows, counter-clockwise
    key: NDArray[np.int64]  # input triangle the node's output maps to
    fam: NDArray[np.int64]  # family of a root parent node, -1 otherwise
    mark: NDArray[np.bool_]  # fully partitioned (marked or promoted)
    user: NDArray[np.bool_]  # inside a marked input triangle
    again: NDArray[np.bool_]  # meets a marked member: partitioned by a follow-up step
    expanded: NDArray[np.bool_]
    labels: NDArray[np.int8]  # (Nn, 3) canonical labelling of each node
    points: NDArray[np.float64]  # input points, then the points of expanded nodes' edges
    reg_keys: NDArray[np.int64]  # sorted keys of the edges whose points exist
    reg_pts: NDArray[np.int64]  # (R, k) their points, from the lower id
    earlier_keys: NDArray[np.int64]  # sorted keys of the edges with points at the start

    def leaves(self) -> NDArray[np.int64]:
        idx = np.flatnonzero(~self.expanded)
        return idx[np.argsort(self.key[idx], kind="stable")]


def start(mesh: Mesh, marked: NDArray[np.bool_], fam_marked: NDArray[np.bool_],
          sch: Scheme, fam: Families, earlier: NDArray[np.int64] | None = None
          ) -> tuple[StepInput, Tree, NDArray[np.int64]]:
    """The step's input and its working mesh: input triangles that are not transition
    children, then one root per family (``fam_marked`` marks roots), the parents of marked
    members expanded; also returns the expanded parents' children ``(X, T)``. ``earlier``:
    sorted keys of the edges that had points before the step (default: ``fam``'s)."""
    member = fam.member
    if member.shape != (mesh.n_triangles,) or fam.per_edge != sch.stencil.per_edge:
        raise ValueError(f"families do not fit: {member.shape[0]} members for "
                         f"{mesh.n_triangles} triangles, {fam.per_edge} points per edge for "
                         f"{sch.name}")
    rows, owner = working_rows(mesh, fam)
    t0 = owner[:rows.shape[0] - fam.n_families]
    g = np.flatnonzero(marked & (member >= 0))
    inp = StepInput(mesh, sch, fam, np.stack([g, member[g]], axis=1), owner[t0.size:],
                    fam.counts(), fam.codes())
    f1 = np.arange(fam.n_families)
    own = np.concatenate([marked[t0], fam_marked])
    keys, pts = fam.registry()
    tree = Tree(rows, owner, np.concatenate([-1 + 0 * t0, f1]),
                own, own.copy(), np.zeros(own.size, bool), np.zeros(own.size, bool),
                canonical_labels(mesh.points, rows), mesh.points, keys, pts,
                keys if earlier is None else earlier)
    parents_of_marked = t0.size + np.unique(inp.pairs[:, 1])
    return inp, tree, expand(tree, parents_of_marked, sch)


def working_rows(mesh: Mesh, fam: Families) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The working triangles: the triangles that are not transition children, then one
    parent per transition family ``(W, 3)``; and the mesh triangle of each (the family's
    first member)."""
    plain = np.flatnonzero(fam.member < 0)
    rows = np.concatenate([mesh.triangles[plain].astype(np.int64), fam.parent_triangles])
    return rows, np.concatenate([plain, fam.first()])


def expand(tree: Tree, nodes: NDArray[np.int64], sch: Scheme) -> NDArray[np.int64]:
    """Replace ``nodes`` by the children of their full partitions (new points on the edges
    that have none yet); returns the children's node ids ``(X, T)``."""
    k, t = sch.stencil.per_edge, sch.n_children
    rows = tree.triangles[nodes]
    ek = edge_keys(rows, np.roll(rows, -1, axis=1))
    new = np.unique(ek[lookup(tree.reg_keys, ek) < 0])
    points, ids = with_edge_points(tree.points, np.stack([new // KEY, new % KEY], axis=1), k)
    tree.points = points
    tree.reg_keys, tree.reg_pts = register(tree.reg_keys, tree.reg_pts, new, ids)
    kids = emit_full(points, rows, tree.reg_pts[lookup(tree.reg_keys, ek)], sch)
    first = tree.triangles.shape[0]
    size = nodes.size * t
    tree.triangles = np.concatenate([tree.triangles, kids.reshape(-1, 3)])
    tree.labels = np.concatenate([tree.labels, canonical_labels(points, kids.reshape(-1, 3))])
    tree.key = np.concatenate([tree.key, np.repeat(tree.key[nodes], t)])
    tree.fam = np.concatenate([tree.fam, np.full(size, -1, dtype=np.int64)])
    tree.user = np.concatenate([tree.user, np.repeat(tree.user[nodes], t)])
    for name in ("mark", "again", "expanded"):
        setattr(tree, name, np.concatenate([getattr(tree, name), np.zeros(size, bool)]))
    tree.expanded[nodes] = True
    return first + np.arange(size).reshape(-1, t)


def with_edge_points(points: NDArray[np.float64], edges: NDArray, k: int
                     ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """``points`` followed by the ``k`` points of each edge ``(a, b)``, ``a < b`` (the
    kernel's formula, so both neighbours of an edge get the same values), in one compiled
    pass; and the new points' ids ``(E, k)``, from ``a``."""
    edges = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
    out = np.empty((points.shape[0] + k * edges.shape[0], 2))
    # one pass: the old points copied, the new ones computed from their edge's ends
    edge_points(np.ascontiguousarray(points, dtype=np.float64), edges, k, out)
    ids = points.shape[0] + k * np.arange(edges.shape[0])[:, None] + np.arange(k)
    return out, ids


def emit_full(points: NDArray[np.float64], rows: NDArray[np.int64],
              edge_pts: NDArray[np.int64], sch: Scheme) -> NDArray[np.int64]:
    """The scheme's partition ``(G, T, 3)`` of ``rows (G, 3)`` whose edge ``(v_i, v_i+1)``
    has the points ``edge_pts[:, i] (G, 3, k)`` (listed from the lower id)."""
    g, n, k = rows.shape[0], points.shape[0], sch.stencil.per_edge
    out = np.empty((g * sch.n_children, 3), dtype=np.int64)
    if g:
        virtual = np.arange(3 * g, dtype=np.int64).reshape(g, 3)
        emit(points, np.ascontiguousarray(rows, dtype=np.int64), virtual, k, sch.forms,
             sch.lut, sch.tables, out)
        new = out >= n
        out[new] = edge_pts.reshape(-1)[out[new] - n]
    return out.reshape(g, sch.n_children, 3)
