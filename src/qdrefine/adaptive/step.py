"""One refinement step: build the working mesh, run the rounds until nothing changes, emit;
then the follow-up step that partitions the children meeting marked transition children
and not smaller than them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..memory import check_needed, local_memory_needed
from ..mesh import Mesh
from ..schemes import Scheme
from .families import Families
from .output import emit_step
from .overlap import overlap_marks
from .rounds import Upgrades, expansions, plan_splits
from .working import start


@dataclass(frozen=True)
class Step:
    """The result of one step.

    Attributes
    ----------
    mesh : Mesh
        Without tagged edges (cut them with ``split_keys`` and ``split_points``).
    parents : (M',) int64
        Input triangle of each output triangle.
    families : Families
        The output's transition families.
    inside : (M',) bool
        Output triangles inside marked input triangles (for ``levels``).
    centroids : (C,) int64
        Centroid points of the input's (and the follow-up's) transitions: those no output
        triangle uses any more belong to coarsened transitions and are to be removed.
    split_keys : (R,) int64 and split_points : (R, k) int64
        Every edge that has points (edge keys, sorted) and its points from the lower id.
    changed_rows : (C,) int64 or None
        The output triangles whose parent's output is not the parent itself, increasing,
        where known (a window's step); None: found from ``parents``.
    """

    mesh: Mesh
    parents: NDArray[np.int64]
    families: Families
    inside: NDArray[np.bool_]
    centroids: NDArray[np.int64]
    split_keys: NDArray[np.int64]
    split_points: NDArray[np.int64]
    changed_rows: NDArray[np.int64] | None = None


def step(mesh: Mesh, marked: NDArray[np.bool_], fam_marked: NDArray[np.bool_], sch: Scheme,
         fam: Families, verdicts: NDArray[np.int8] | None = None) -> Step:
    """One refinement step of ``mesh`` with transition families ``fam`` (``marked``
    triangles and ``fam_marked`` families partitioned), with the follow-up step that
    partitions the children meeting marked members. ``verdicts (M, 2)``: upgrade
    verdicts of ``mesh``'s triangles known already (:class:`~qdrefine.adaptive.rounds.
    Upgrades`), for a mesh without families."""
    out, parents, fam2, inside, again, (keys, pts) = _one_step(mesh, marked, fam_marked, sch,
                                                               fam, verdicts=verdicts)
    centroids = fam.centroids()
    if again.any():
        fam_again = np.zeros(fam2.n_families, dtype=bool)
        fam_again[fam2.member[again & (fam2.member >= 0)]] = True
        centroids = np.union1d(centroids, fam2.centroids())
        out, step_parents, fam2, inside2, _, (keys2, pts2) = _one_step(
            out, again & (fam2.member < 0), fam_again, sch, fam2, fam.registry()[0])
        parents, inside = parents[step_parents], inside[step_parents] | inside2
        keys, first = np.unique(np.concatenate([keys, keys2]), return_index=True)
        pts = np.concatenate([pts, pts2])[first]
    return Step(out, parents, fam2, inside, centroids, keys, pts)


def _one_step(mesh: Mesh, marked: NDArray[np.bool_], fam_marked: NDArray[np.bool_],
              sch: Scheme, fam: Families, earlier: NDArray[np.int64] | None = None,
              verdicts: NDArray[np.int8] | None = None):
    """One pass; ``earlier``: sorted keys of the edges that had points before the step
    (default: ``fam``'s, right for the first pass; the follow-up pass gets the step
    input's, so that it counts the first pass's points as this step's); ``verdicts
    (M, 2)``: upgrade verdicts of the mesh's triangles judged already (mesh without
    families)."""
    working = int((fam.member < 0).sum()) + fam.n_families
    check_needed(local_memory_needed(n_working=working),
                 f"local refinement: a pass over {working} working triangles")
    inp, tree, kids = start(mesh, marked, fam_marked, sch, fam, earlier)
    overlap_marks(inp, tree, kids)
    if verdicts is not None and fam.n_families:
        raise ValueError("internal error: known verdicts are for a mesh without families")
    upgrades = Upgrades(inp, tree, verdicts)  # the tree's first nodes: mesh's triangles
    cl = plan_splits(tree, upgrades)
    while (grown := expansions(inp, tree, cl)) is not None:
        cl = plan_splits(tree, upgrades, after=(cl, *grown))
    return emit_step(inp, tree, cl)

