"""Adaptive conforming local refinement (red-green): marked triangles get the scheme's
partition, a longest-edge closure with transition patterns keeps the mesh conforming, and
the output mesh carries its transitions (``Mesh.transitions``) so that the next call
coarsens them before refining them. The rules, the quality bound and the studies:
``docs/adaptive.md``.

Modules: :mod:`.api` (entry points), :mod:`.history` (``Mesh.transitions`` as families and
back), :mod:`.step` (one step), :mod:`.working` (the working mesh), :mod:`.rounds`
(closure, conflicts, transition upgrades), :mod:`.output` (children, families, tagged edges,
point data), :mod:`.overlap` (marked transition children), :mod:`.families`,
:mod:`.patterns`, :mod:`.longest_edge`, :mod:`.labels`, :mod:`.edgekeys`.
"""

from .api import as_mask, refine_cycles, refine_marked
from .coarsen import coarsen, coarsen_marked
from .families import Families
from .history import HistoryMismatch
from .labels import canonical_edges, canonical_labels
from .longest_edge import closure
from .patterns import TRANSITIONS

__all__ = [
    "refine_marked",
    "coarsen",
    "coarsen_marked",
    "refine_cycles",
    "Families",
    "HistoryMismatch",
    "closure",
    "canonical_labels",
    "canonical_edges",
    "as_mask",
    "TRANSITIONS",
]
