"""One refinement step: build the working mesh, run the rounds until nothing changes, emit;
then the follow-up step that partitions the children meeting marked transition children."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..mesh import Mesh
from ..schemes import Scheme
from .families import Families
from .output import emit_step
from .overlap import overlap_marks
from .rounds import close, conflicts, promote
from .working import start


def step(mesh: Mesh, marked: NDArray[np.bool_], fam_marked: NDArray[np.bool_], sch: Scheme,
         floor: float, fam: Families
         ) -> tuple[Mesh, NDArray[np.int64], Families, NDArray[np.bool_]]:
    """One refinement step, with the follow-up step that partitions the children meeting
    marked members; returns ``(mesh, parents, families, inside)``, ``inside`` flagging the
    output triangles that lie in marked input triangles (for ``levels``)."""
    out, parents, fam, inside, again = _one_step(mesh, marked, fam_marked, sch, floor, fam)
    if again.any():
        fam_again = np.zeros(fam.n_families, dtype=bool)
        fam_again[fam.member[again & (fam.member >= 0)]] = True
        out, step_parents, fam, inside2, _ = _one_step(out, again & (fam.member < 0),
                                                       fam_again, sch, floor, fam)
        parents, inside = parents[step_parents], inside[step_parents] | inside2
    return out, parents, fam, inside


def _one_step(mesh: Mesh, marked: NDArray[np.bool_], fam_marked: NDArray[np.bool_],
              sch: Scheme, floor: float, fam: Families
              ) -> tuple[Mesh, NDArray[np.int64], Families, NDArray[np.bool_],
                         NDArray[np.bool_]]:
    inp, tree, kids = start(mesh, marked, fam_marked, sch, fam)
    overlap_marks(inp, tree, kids)
    while True:
        cl = close(tree)
        if not (conflicts(inp, tree, cl) or promote(inp, tree, cl, floor)):
            return emit_step(inp, tree, cl)
