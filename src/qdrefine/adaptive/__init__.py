"""Adaptive conforming local refinement: marked triangles, a longest-edge closure and
transition patterns; across cycles, transition families that are coarsened before they are
refined. The rules, why the loops end, and the quality study: ``docs/adaptive.md``.

Modules: :mod:`.api` (entry points), :mod:`.step` (one step), :mod:`.working` (the working
mesh), :mod:`.rounds` (closure, conflicts, quality guard), :mod:`.output` (children,
families, tagged edges), :mod:`.overlap` (marked transition children), :mod:`.families`,
:mod:`.patterns`, :mod:`.longest_edge`, :mod:`.labels`, :mod:`.edgekeys`.
"""

from .api import KEEP, as_mask, refine_cycles, refine_marked, refine_step
from .families import Families
from .labels import canonical_edges, canonical_labels
from .longest_edge import closure
from .patterns import TRANSITIONS

__all__ = [
    "refine_marked",
    "refine_step",
    "refine_cycles",
    "Families",
    "KEEP",
    "closure",
    "canonical_labels",
    "canonical_edges",
    "as_mask",
    "TRANSITIONS",
]
