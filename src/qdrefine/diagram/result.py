"""The whole diagram computation: every region's area and the certified extrema."""

from __future__ import annotations

from dataclasses import dataclass, field

from .extrema import READINGS, Extremum, largest_gap, worst_ratios
from .mapping import HALF_ANGLE_AREA, HALF_AREA, REGIONS
from .regions import ARC_REGIONS, region_area

# ----------------------------------------------------------------------------------------
# the whole computation


@dataclass
class DiagramResult:
    """Areas and fractions of the regions, with error estimates."""

    diagram_area: float
    areas: dict[str, float]
    errors: dict[str, float]
    methods: dict[str, str]
    le_min_above_qd: float
    le_min_above_qd_error: float
    worst: dict[str, Extremum]
    gaps: dict[str, Extremum] = field(default_factory=dict)
    angle_measure_fractions: dict[str, float] = field(default_factory=dict)
    angle_measure_errors: dict[str, float] = field(default_factory=dict)
    extra_areas: dict[str, float] = field(default_factory=dict)
    tol: float = 1e-10
    n_samples: int = 64

    @property
    def worst_qd_over_d_min_angle(self) -> float:
        """The certified worst ratio of the pentagon reading (the measure of Figs. 8-10)."""
        return self.worst["pentagon"].value

    @property
    def worst_point(self) -> tuple[float, float]:
        return self.worst["pentagon"].point

    @property
    def fractions(self) -> dict[str, float]:
        return {k: v / self.diagram_area for k, v in self.areas.items()}

    @property
    def error_bound(self) -> float:
        errs = [e / self.diagram_area for e in self.errors.values()]
        errs.append(self.le_min_above_qd_error / self.diagram_area)
        return max(errs)

    def to_json(self) -> dict:
        keys = list(REGIONS)
        return {
            "diagram_area": self.diagram_area,
            "fractions": {k: self.fractions[k] for k in keys},
            "areas": {k: self.areas[k] for k in keys},
            "le_min_above_qd": self.le_min_above_qd / self.diagram_area,
            "worst_qd_over_d_min_angle": self.worst_qd_over_d_min_angle,
            "worst_qd_over_d_min_angle_bound": self.worst["pentagon"].bound,
            "worst_qd_over_d_by_reading": {
                r: {"value": e.value, "lower": e.lower, "bound": e.bound,
                    "point": list(e.point), "where": e.where, "attained": e.attained,
                    "reading": READINGS[r][0]}
                for r, e in self.worst.items()},
            "largest_d_minus_qd_min_angle_deg": {
                r: {"value": e.value, "upper": e.upper, "bound": e.bound,
                    "point": list(e.point), "where": e.where, "attained": e.attained}
                for r, e in self.gaps.items()},
            "error_bound": self.error_bound,
            "errors": {k: self.errors[k] / self.diagram_area for k in keys},
            "extra": {
                "III_minus_shaded": self.fractions["III-shaded"],
                "le_min_above_qd_area": self.le_min_above_qd,
                "worst_qd_over_d_point": list(self.worst_point),
                "angle_measure_fractions": self.angle_measure_fractions,
                "angle_measure_errors": self.angle_measure_errors,
            },
            "method": {
                "measure": "uniform (Lebesgue) on the left half of the diagram "
                           "H = {0 <= x <= 1/2, y > 0, (x-1)^2 + y^2 <= 1}; fractions are "
                           "areas divided by area(H) = pi/6 - sqrt(3)/8",
                "regions": self.methods,
                "quadrature": f"adaptive Gauss-Kronrod (7,15) in x, tol {self.tol:g} on "
                              f"the area; comparison roots in y bracketed on "
                              f"{self.n_samples} uniform + 40 graded samples per piece "
                              "between decision arcs, bisected to ~2e-16",
                "error_bound": "largest error estimate of any fraction (exact arc regions: "
                               "float rounding, 1e-14; others: summed |K15 - G7|)",
                "worst_ratio": "certified: every boundary curve and corner of the closed "
                               "shaded region sampled and polished by golden section (a "
                               "value of the closure, upper bound; 'attained' says whether "
                               "a triangle there has the partitions compared), interval "
                               "branch and bound over the whole closure (lower bound); "
                               "bound = upper - lower",
                "angle_measure": "the same fractions under the uniform measure in the two "
                                 "smallest angles (angle at N, angle at M); total pi^2/12",
            },
        }


def compute(tol: float = 1e-10, n_samples: int = 64, angle_measure: bool = True
            ) -> DiagramResult:
    """Compute every region's area (see the module docstring)."""
    areas: dict[str, float] = {}
    errors: dict[str, float] = {}
    methods: dict[str, str] = {}
    for name in REGIONS + ("III-shaded",):
        r = region_area(name, tol=tol, n_samples=n_samples)
        areas[name], errors[name] = r.value, r.error
        methods[name] = ("exact circular-arc geometry" if name in ARC_REGIONS
                         else f"root finding + adaptive quadrature ({r.intervals} intervals)")
    le = region_area("le_min_above_qd", tol=tol, n_samples=n_samples)
    worst = worst_ratios()
    gaps = {r: largest_gap(r) for r in READINGS}
    am: dict[str, float] = {}
    ae: dict[str, float] = {}
    if angle_measure:
        for name in REGIONS + ("le_min_above_qd",):
            r = region_area(name, method="quadrature", tol=tol * 10, n_samples=n_samples,
                            measure="angles")
            am[name] = r.value / HALF_ANGLE_AREA
            ae[name] = r.error / HALF_ANGLE_AREA
    return DiagramResult(HALF_AREA, areas, errors, methods, le.value, le.error, worst,
                         gaps=gaps, angle_measure_fractions=am, angle_measure_errors=ae, tol=tol,
                         n_samples=n_samples)
