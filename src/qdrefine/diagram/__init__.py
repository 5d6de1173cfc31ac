"""The paper's mapping diagram: coordinates, regions, their areas and extrema, recomputed.

Modules, one concern each: :mod:`.mapping` (diagram coordinates, scheme decisions and
angles at points), :mod:`.arcs` (decision forms as circles, exact arc areas),
:mod:`.quadrature` (areas bounded by angle-equality curves), :mod:`.regions` (the paper's
regions as predicates, their areas), :mod:`.extrema` (certified worst ratios),
:mod:`.result` (the whole computation).

Every triangle is mapped to the apex ``O = (x, y)`` of the similar triangle whose longest
edge is ``M = (0, 0)``, ``N = (1, 0)``, using the canonical labelling of
:mod:`qdrefine.kernels` (so ``x <= 1/2``: the *left half* of the diagram)::

    H = {0 <= x <= 1/2, y > 0, (x - 1)^2 + y^2 <= 1},   area(H) = pi/6 - sqrt(3)/8.

Regions (all subsets of ``H``; scheme decisions are those of :mod:`qdrefine.schemes`):

* ``I``, ``II``, ``III``: the three cases of 7T-QD (Definition 1, tie rules of
  ``docs/schemes.md``);
* ``shaded``: 7T-QD splits the pentagon A-D-C-B-O differently from 7T-D;
* ``C1 = shaded & {min LE > min QD}``, ``C2 = (shaded & {mean QD > mean D}) - C1``,
  ``C3 = shaded - C1 - C2``, where *min* and *mean* are the smallest angle and the mean of
  the smallest angles of the three pentagon triangles of a partition;
* ``le_min_above_qd``: ``H & {min LE > min QD}``.

Every scheme decision is the sign of a form ``a uu + b ww + c uw``; in the diagram
``uu = 1, ww = x^2 + y^2, uw = x``, so each decision boundary is a circle (or a vertical
line) and the regions ``I, II, III, shaded`` are bounded by circular arcs. Their areas are
computed *exactly* (:func:`arc_area`): the ``x`` axis is cut at every arc end and every
intersection of two arcs, and inside each slab the area between consecutive arcs is the
closed-form integral of ``sqrt(r^2 - (x - c)^2)``.

Regions bounded by angle-equality curves (``C1``, ``C2``, ``C3``, ``le_min_above_qd``) are
integrated numerically (:func:`quadrature_area`): for each ``x``, the ``y`` roots of every
boundary function (arcs: closed form; angle differences: sampled sign changes refined by
bisection to ~1e-15) cut the vertical line into pieces of constant membership, whose lengths
are summed; that length is integrated in ``x`` with an adaptive Gauss-Kronrod (7, 15) rule
whose summed ``|K15 - G7|`` is the reported error estimate.
"""


from .arcs import DOMAIN_ARC, Arc, Predicate, arc_area, decision_arcs
from .extrema import (
    READINGS,
    Extremum,
    gap,
    in_closure,
    largest_gap,
    ratio,
    worst_ratio,
    worst_ratios,
)
from .mapping import (
    _SCHEMES_7T as _SCHEMES_7T,
)
from .mapping import (
    FANS,
    HALF_ANGLE_AREA,
    HALF_AREA,
    MEASURES,
    OVER,
    REGIONS,
    fan_angles,
    fixed_angles,
    inside_half,
    partition_measure,
    region_masks,
    scheme_fans,
    stencil_points,
    to_diagram,
)
from .mapping import (
    _fan_measure as _fan_measure,
)
from .mapping import (
    _fans_float as _fans_float,
)
from .mapping import (
    _rows_float as _rows_float,
)
from .quadrature import QuadResult, gauss_kronrod, quadrature_area
from .regions import ANGLE_REGIONS, ARC_REGIONS, region_area
from .regions import _pred as _pred
from .result import DiagramResult, compute

__all__ = [
    "HALF_AREA",
    "HALF_ANGLE_AREA",
    "REGIONS",
    "FANS",
    "MEASURES",
    "OVER",
    "READINGS",
    "ARC_REGIONS",
    "ANGLE_REGIONS",
    "to_diagram",
    "stencil_points",
    "scheme_fans",
    "inside_half",
    "region_masks",
    "fan_angles",
    "fixed_angles",
    "partition_measure",
    "Arc",
    "DOMAIN_ARC",
    "Predicate",
    "decision_arcs",
    "arc_area",
    "QuadResult",
    "gauss_kronrod",
    "quadrature_area",
    "region_area",
    "Extremum",
    "ratio",
    "in_closure",
    "worst_ratio",
    "worst_ratios",
    "gap",
    "largest_gap",
    "DiagramResult",
    "compute",
]
