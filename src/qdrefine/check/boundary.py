"""Checks along the boundary, by one plane sweep (:mod:`qdrefine.sweep`): hanging nodes,
crossing boundary edges, doubly covered area and vertices nearly on another edge."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..memory import check_needed, validation_needed
from ..sweep import CROSSING, sweep
from .edges import Topology
from .report import KEPT, Findings

__all__ = ["boundary", "hanging_nodes"]


def boundary(found: Findings, p: NDArray, topo: Topology, covers: bool) -> None:
    """Hanging nodes, crossing boundary edges and doubly covered area: one plane sweep
    (:mod:`qdrefine.sweep`)."""
    bedges, btris = topo.bedges, topo.btris
    check_needed(validation_needed(len(p), len(topo.t), len(bedges)),
                 f"validating {len(topo.t)} triangles ({len(bedges)} boundary edges)")
    n_hang, hits, crossing, n_cov, first_cov, n_near, near, firsts, _ = sweep(
        p, bedges, covers, found.stop, KEPT)
    ids = found.ids
    add = []  # (when found, how to report), reported in the sweep's order
    if n_hang:
        add.append((firsts[0], lambda: _hanging(found, hits, n_hang, bedges, btris)))
    if crossing[0]:
        add.append((firsts[2], lambda: _crossing(found, crossing, bedges, btris)))
    if n_cov:
        add.append((firsts[1], lambda: _covered(found, first_cov, n_cov, bedges, btris,
                                                topo.t)))
    for _, report in sorted(add, key=lambda x: x[0]):
        report()
    if n_near and not found.stop and not crossing[0] and not n_cov:
        v, r, d = int(near[0]), int(near[1]), float(near[2])
        tri = found.triangle(btris[r])
        found.add("near-hanging-node", f"vertex {found.point(v)} is off edge "
                  f"{tuple(ids(bedges[r]))} of triangle {tri} by only {d:.2g} times its length "
                  "(outside it: a crack; refinement decides it exactly)", n_near,
                  vertex=found.point(v), edge=ids(bedges[r]), triangle=tri, distance=d)


def _crossing(found: Findings, crossing: NDArray, bedges: NDArray, btris: NDArray) -> None:
    r, s = int(crossing[1]), int(crossing[2])
    ta, tb = found.triangle(btris[r]), found.triangle(btris[s])
    how = ("cross" if crossing[0] == CROSSING else
           "run along each other with both triangles on the same side")
    found.add("self-intersection", f"edge {tuple(found.ids(bedges[r]))} of triangle {ta} and "
              f"edge {tuple(found.ids(bedges[s]))} of triangle {tb} {how}: the mesh overlaps "
              "itself there", 1, triangles=[ta, tb],
              edges=[found.ids(bedges[r]), found.ids(bedges[s])])


def _covered(found: Findings, row: int, count: int, bedges: NDArray, btris: NDArray,
             t: NDArray) -> None:
    tri = found.triangle(btris[row])
    found.add("overlap", f"triangle {tri} {tuple(found.ids(t[btris[row]]))} overlaps another "
              f"part of the mesh (the area along its edge {tuple(found.ids(bedges[row]))} is "
              "covered twice)", count, triangle=tri, edge=found.ids(bedges[row]))


def _hanging(found: Findings, hits: NDArray, count: int, bedges: NDArray, btris: NDArray
             ) -> None:
    v, row = (int(x) for x in hits[0])
    edge, tri = found.ids(bedges[row]), found.triangle(btris[row])
    found.add("hanging-node", f"vertex {found.point(v)} lies inside edge {tuple(edge)} of "
              f"triangle {tri} (a hanging node: the mesh is not conforming there)",
              count, vertex=found.point(v), edge=edge, triangle=tri)


def hanging_nodes(points: NDArray, bedges: NDArray) -> tuple[int, NDArray[np.int64]]:
    """Vertices of ``bedges (B, 2)`` lying strictly inside one of them (exact test).

    Returns the number of (vertex, edge) pairs and up to 64 of them as rows ``(vertex, edge
    row)``. A hanging node of a mesh whose triangles do not overlap is always a boundary
    vertex inside a boundary edge, so only those are tested, by the plane sweep of
    :mod:`qdrefine.sweep` (``O(B log B)``). Where two edges cross, the sweep stops there:
    the count covers the vertices before that crossing.
    """
    n_hang, hits = sweep(points, bedges, False, False, KEPT)[:2]
    return int(n_hang), hits
