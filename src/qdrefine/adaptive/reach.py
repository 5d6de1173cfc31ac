"""Where a step will reach, estimated cheaply: the window a step starts from on a mesh
without transitions (:mod:`qdrefine.adaptive.window`).

Two vertex rings around every mark cover much of a mesh once the marks are scattered (1%
of a Gmsh mesh's triangles picked at random: about 40%), while the step itself changes
about 7 triangles per mark. This module follows the step's rules on the input triangles,
in time proportional to what they reach: the longest-edge closure of the marks (a
worklist over the vertex-to-triangle table, the exact canonical labels of the visited
triangles only), then the upgrades of :class:`~qdrefine.adaptive.rounds.Upgrades`, judged
on the triangles whose split edges changed, bringing new triangles in for
:data:`~qdrefine.adaptive.rounds.UPGRADE_LAYERS` layers. The set is an estimate, not the
step (the layers are counted more loosely): the window grows wherever its rim gets a split
edge, so the result does not depend on it, only the time does. The verdicts judged on the
way are passed to the step, which uses them as its own: they come from the step's function
(:func:`~qdrefine.adaptive.rounds.upgrade_verdicts`) on the same coordinates.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from ..kernels import canonical
from ..mesh import Mesh
from ..predicates import SCRATCH
from ..schemes import Scheme
from .labels import canonical_edges, canonical_labels, local_edge
from .rounds import UPGRADE_LAYERS, upgrade_verdicts

#: Upgrade rounds after the last layer (upgrades that bring no new triangle in).
INNER_ROUNDS = 8


def reached_triangles(mesh: Mesh, marked: NDArray[np.bool_], sch: Scheme,
                      start: NDArray[np.int64], tris_of: NDArray[np.int64]
                      ) -> tuple[NDArray[np.bool_], NDArray[np.int8]]:
    """The triangles that the step of ``marked`` with scheme ``sch`` is estimated to
    change, and those across an upgrade that is not made, for a mesh without transition
    families, given its vertex-to-triangle table ``tris_of[start[v]:start[v + 1]]``.

    Returns
    -------
    window : (M,) bool
    verdicts : (M, 2) int8
        The upgrade rule's verdicts judged on the way, as
        :class:`~qdrefine.adaptive.rounds.Upgrades` keeps them (by ``MN``, by ``OM``; 1
        upgraded, 0 not, -1 not judged): the step can start from them.
    """
    m = mesh.n_triangles
    points = np.ascontiguousarray(mesh.points, dtype=np.float64)
    triangles = mesh.triangles
    state = np.zeros((m, 3), dtype=np.bool_)  # reached, all edges split, MN split
    split = np.zeros((m, 3), dtype=np.bool_)  # local edge (v_j, v_j+1) split
    dirty = np.zeros(m, dtype=np.bool_)  # split edges changed since the last verdict
    across = np.zeros(m, dtype=np.bool_)  # across an upgrade's NO edge, not reached
    verdicts = np.full((m, 2), -1, dtype=np.int8)
    seeds = np.flatnonzero(marked)
    whole = np.ones(seeds.size, dtype=np.bool_)
    for r in range(UPGRADE_LAYERS + 1 + INNER_ROUNDS):
        _close(points, triangles, start, tris_of, seeds, whole, state, split, dirty)
        if sch.stencil.per_edge != 2:  # upgrades are a seven-triangle rule
            break
        todo = np.flatnonzero(dirty & state[:, 0] & ~state[:, 1])
        dirty[:] = False
        if not todo.size:
            break
        up, no_edge = _upgrades(points, triangles, todo, split[todo], sch, verdicts)
        seeds = _split_no(triangles, start, tris_of, todo[up], no_edge[up], state, split,
                          dirty, across, r < UPGRADE_LAYERS)
        whole = np.zeros(seeds.size, dtype=np.bool_)
        if not (seeds.size or dirty.any()):
            break
    return state[:, 0] | across, verdicts


def _upgrades(points: NDArray[np.float64], triangles: NDArray, todo: NDArray[np.int64],
              split: NDArray[np.bool_], sch: Scheme, verdicts: NDArray[np.int8]
              ) -> tuple[NDArray[np.bool_], NDArray[np.int64]]:
    """Which of the triangles ``todo (G,)`` with local split edges ``split (G, 3)`` the
    upgrade rule gives ``NO`` split, and the local index of their ``NO`` edge; the
    verdicts not judged yet are judged (by the step's own
    :func:`~qdrefine.adaptive.rounds.upgrade_verdicts`) and kept in ``verdicts (M, 2)``."""
    rows = triangles[todo].astype(np.int64)
    labels = canonical_labels(points, rows)
    g = np.arange(rows.shape[0])
    # local indices of the canonical edges MN, NO, OM: those of the edges (0, 1, 2)
    local = canonical_edges(labels, np.broadcast_to(np.arange(3), rows.shape))
    s_mn, s_no, s_om = (split[g, local[:, e]] for e in range(3))
    cand = s_mn & ~s_no
    for col, need in ((0, cand), (1, cand & s_om)):
        idx = np.flatnonzero(need & (verdicts[todo, col] < 0))
        if idx.size:
            verdicts[todo[idx], col] = upgrade_verdicts(points, rows[idx], labels[idx], col,
                                                        sch)
    up = cand & ((verdicts[todo, 0] == 1) | (s_om & (verdicts[todo, 1] == 1)))
    return up, local[:, 1]


@njit(cache=True)
def _across(triangles, start, tris_of, t, a, b):
    """The triangle other than ``t`` with the edge ``(a, b)``, or -1."""
    for i in range(start[a], start[a + 1]):
        u = tris_of[i]
        if u != t:
            for j in range(3):
                if triangles[u, j] == b:
                    return u
    return -1


@njit(cache=True)
def _split_edge(triangles, start, tris_of, t, j, split, dirty):
    """Split local edge ``j`` of ``t`` on both sides; returns the triangle across, or -1."""
    split[t, j] = True
    dirty[t] = True
    a, b = triangles[t, j], triangles[t, (j + 1) % 3]
    u = _across(triangles, start, tris_of, t, a, b)
    if u >= 0:
        for i in range(3):
            if triangles[u, i] == b and triangles[u, (i + 1) % 3] == a:
                split[u, i] = True
                dirty[u] = True
    return u


@njit(cache=True)
def _split_no(triangles, start, tris_of, tris, local, state, split, dirty, across,
              may_bring):
    """Split the ``NO`` edges (local index ``local``) of the upgraded triangles ``tris``;
    returns the triangles across them not reached yet. Where upgrades may not bring new
    triangles in, an upgrade towards an unreached triangle is not made, but that triangle
    is flagged in ``across``: the window needs it, since on a window's rim the step sees
    no triangle across, as on the mesh's boundary, where the upgrade is made."""
    out = np.empty(tris.shape[0], dtype=np.int64)
    n = 0
    for i in range(tris.shape[0]):
        t, j = tris[i], local[i]
        u = _across(triangles, start, tris_of, t, triangles[t, j], triangles[t, (j + 1) % 3])
        if u >= 0 and not state[u, 0]:
            if not may_bring:
                across[u] = True
                continue
            out[n] = u
            n += 1
        _split_edge(triangles, start, tris_of, t, j, split, dirty)
    return out[:n]


@njit(cache=True)
def _push(stack, top, value):
    if top >= stack.shape[0]:
        stack = np.concatenate((stack, np.empty(stack.shape[0], dtype=np.int64)))
    stack[top] = value
    return stack, top + 1


@njit(cache=True)
def _close(points, triangles, start, tris_of, seeds, whole, state, split, dirty):
    """Longest-edge closure from ``seeds`` (``whole``: every edge split, else reached
    across an edge), in place on ``state (M, 3)`` (reached, all edges split, ``MN``
    split), ``split`` and ``dirty``."""
    buf = np.empty(SCRATCH)
    stack = np.empty(max(64, 2 * seeds.shape[0]), dtype=np.int64)
    top = 0
    for i in range(seeds.shape[0]):
        stack, top = _push(stack, top, 2 * seeds[i] + (1 if whole[i] else 0))
    while top > 0:
        top -= 1
        t = stack[top] >> 1
        if not state[t, 0]:
            state[t, 0] = True
            dirty[t] = True
        if stack[top] & 1:
            if state[t, 1]:
                continue
            state[t, 1] = True
            state[t, 2] = True
            for j in range(3):
                u = _split_edge(triangles, start, tris_of, t, j, split, dirty)
                if u >= 0 and not state[u, 2]:
                    stack, top = _push(stack, top, 2 * u)
        elif not state[t, 2]:
            state[t, 2] = True
            v0, v1, v2 = triangles[t, 0], triangles[t, 1], triangles[t, 2]
            im, jn, _ = canonical(points[v0, 0], points[v0, 1], points[v1, 0],
                                  points[v1, 1], points[v2, 0], points[v2, 1], buf)
            j = local_edge(im, jn)
            u = _split_edge(triangles, start, tris_of, t, j, split, dirty)
            if u >= 0 and not state[u, 2]:
                stack, top = _push(stack, top, 2 * u)
