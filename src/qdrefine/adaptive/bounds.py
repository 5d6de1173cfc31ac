"""The quality of local refinement, computed: the worst ratio (child minimum angle over
parent minimum angle) of every transition pattern over the mapping diagram, and a lower
bound on the smallest angle that any number of adaptive cycles can reach on a given mesh.

Why cycles cannot compound (``docs/adaptive.md``): a transition is always coarsened
before any part of it is refined, and a partition is only ever applied to a triangle that
is no transition child. So every triangle of an adaptive mesh, after any number of cycles,
is either *red*, a triangle of the uniform refinements of an input triangle, or a
transition child of a red triangle. Its smallest angle is thus at least the smallest angle
over the red triangles' shapes and over the transitions of those shapes, which
:func:`quality_bound` computes shape class by shape class.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..mesh import Mesh
from ..partition import partition_many
from ..quality import min_angles as mesh_min_angles
from ..schemes import Scheme, get_scheme
from .labels import MN, NO, OM, canonical_labels
from .patterns import PARTIAL, min_angles, quality, stencil_coordinates
from .rounds import full_quality, upgraded

#: Apexes (in the normalised frame of the mapping diagram) equal to this many significant
#: bits per coordinate are one shape class (about 9 significant digits).
SHAPE_BITS = 30

#: The bound is lowered by this fraction: a class's angles are within about
#: ``2 ** -SHAPE_BITS`` (1e-9) of those of the triangles it stands for, relative to
#: themselves, and refinement carries such differences to the children.
ROUNDING_MARGIN = 1e-6


def canonical_shapes(corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """The apex ``(x, y)`` of each triangle ``(K, 3, 2)`` in the mapping diagram (canonical
    labelling, ``M = (0, 0)``, ``N = (1, 0)``, ``y > 0``)."""
    k = corners.shape[0]
    labels = canonical_labels(corners.reshape(-1, 2), np.arange(3 * k).reshape(k, 3))
    v = np.take_along_axis(corners, labels.astype(np.int64)[:, :, None], axis=1)
    d, r = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
    length2 = (d * d).sum(axis=1)
    return np.stack([(r * d).sum(axis=1) / length2,
                     np.abs(r[:, 0] * d[:, 1] - r[:, 1] * d[:, 0]) / length2], axis=1)


def shape_triangles(xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """Triangles ``(K, 3, 2)``: ``(0, 0), (1, 0)`` and the apexes ``xy (K, 2)``."""
    t = np.zeros((xy.shape[0], 3, 2))
    t[:, 1, 0] = 1.0
    t[:, 2] = xy
    return t


def transition_angles(xy: NDArray[np.float64], sch: Scheme) -> dict[str, NDArray[np.float64]]:
    """Smallest angle (degrees) of each shape and of what local refinement makes of it:
    ``"triangle"``, ``"full"`` (the scheme's partition), and per split code the transition
    chosen, with the upgrade rule (``"MN"``, ``"MN,NO"``, ``"MN,OM"``) and without it
    (``"MN plain"``, ``"MN,OM plain"``)."""
    corners = shape_triangles(xy)
    k = sch.stencil.per_edge
    coords = stencil_coordinates(corners, k)
    full = full_quality(corners, sch)
    own = min_angles(corners)
    out = {"triangle": own, "full": full}
    q = {code: quality(coords, k, code) for code in PARTIAL}
    if k == 2:
        by_mn = upgraded(q[MN], q[MN | NO], own)
        by_om = upgraded(q[MN | OM], full, own)
    else:
        by_mn = by_om = np.zeros(xy.shape[0], dtype=bool)
    out["MN plain"], out["MN,OM plain"] = q[MN], q[MN | OM]
    out["MN"] = np.where(by_mn, q[MN | NO], q[MN])
    out["MN,NO"] = q[MN | NO]
    out["MN,OM"] = np.where(by_mn | by_om, full, q[MN | OM])
    return out


def diagram_samples(n: int = 200) -> NDArray[np.float64]:
    """Apexes ``(K, 2)`` on a grid over the left half of the mapping diagram (``x`` in
    ``(0, 1/2]``, inside the unit circle around ``N``)."""
    x = (np.arange(n) + 0.5) / (2 * n)
    y = (np.arange(2 * n) + 0.5) / (2 * n) * np.sqrt(3) / 2
    xx, yy = np.meshgrid(x, y)
    keep = (xx - 1) ** 2 + yy**2 <= 1
    return np.stack([xx[keep], yy[keep]], axis=1)


def pattern_ratios(scheme: str | Scheme = "7t-qd", n: int = 200) -> dict[str, dict]:
    """Per transition (and the full partition), the worst and median ratio of the smallest
    angle of the children to the triangle's, over :func:`diagram_samples`, with the apex
    where the worst is reached."""
    xy = diagram_samples(n)
    ang = transition_angles(xy, get_scheme(scheme))
    out = {}
    for name, a in ang.items():
        if name == "triangle":
            continue
        r = a / ang["triangle"]
        i = int(np.argmin(r))
        out[name] = {"worst": float(r[i]), "median": float(np.median(r)),
                     "at": [float(xy[i, 0]), float(xy[i, 1])], "samples": int(xy.shape[0])}
    return out


@dataclass(frozen=True)
class QualityBound:
    """What :func:`quality_bound` found.

    Attributes
    ----------
    initial : float
        Smallest angle of the mesh (degrees).
    red : float
        Smallest angle over the shapes of its uniform refinements up to ``levels``.
    transition : float
        Smallest angle over the transitions of those shapes, each with or without its
        upgrade (an upgrade is not always allowed: :data:`~qdrefine.adaptive.rounds.
        UPGRADE_LAYERS`).
    ratio : float
        ``min(red, transition) / initial``, lowered by :data:`ROUNDING_MARGIN`: the bound,
        as a fraction of the initial angle.
    upgraded : float
        ``min(red, transition) / initial`` where every transition the upgrade rule asks for
        is made, lowered by :data:`ROUNDING_MARGIN` too: what the loops on our examples
        reach (docs/adaptive.md); not guaranteed.
    classes : list of int
        Number of shape classes after each level (the growth tells how close the list is to
        all shapes that refinement ever makes).
    """

    initial: float
    red: float
    transition: float
    ratio: float
    upgraded: float
    classes: list[int]


def quality_bound(mesh: Mesh, scheme: str | Scheme = "7t-qd", levels: int = 10
                  ) -> QualityBound:
    """A lower bound on the smallest angle of any adaptive refinement of ``mesh``, with
    transitions ``levels`` deep at most: the red shapes are the similarity classes of the
    uniform refinements of its triangles (shapes equal to :data:`SHAPE_BITS` bits in
    the normalised frame are one class), and each class's transitions are evaluated with
    the upgrade rule. Exact within the classes enumerated; beyond ``levels`` the new
    classes are few (``classes`` shows it) and have not lowered the minimum in our
    meshes."""
    sch = get_scheme(scheme)
    xy = _classes(canonical_shapes(mesh.points[mesh.triangles]))
    seen, counts = xy, []
    for _ in range(levels):
        pts, tris = partition_many(shape_triangles(xy), sch, strict=False)
        kids = np.take_along_axis(pts[:, None], tris[..., None], axis=2).reshape(-1, 3, 2)
        kids_xy = _classes(canonical_shapes(kids))
        new = kids_xy[~_member(kids_xy, seen)]
        seen = np.concatenate([seen, new])
        counts.append(int(seen.shape[0]))
        xy = new
        if not new.size:
            break
    ang = transition_angles(seen, sch)
    initial = float(mesh_min_angles(mesh).min())
    red = float(ang["triangle"].min())
    # an upgrade is not always allowed (rounds.Upgrades): the worst case is without it
    trans = float(min(ang["MN plain"].min(), ang["MN,NO"].min(), ang["MN,OM plain"].min()))
    ruled = float(min(ang["MN"].min(), ang["MN,NO"].min(), ang["MN,OM"].min()))
    keep = 1.0 - ROUNDING_MARGIN
    return QualityBound(initial, red, trans, keep * min(red, trans) / initial,
                        keep * min(red, ruled) / initial, counts)


def _classes(xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """The distinct apexes ``xy (K, 2)`` rounded to :data:`SHAPE_BITS` significant bits per
    coordinate: relative, so that every angle of a class's representative is within about
    ``2 ** -SHAPE_BITS`` of its members' relative to itself, however thin the shape (a
    rounding to a fixed number of decimals moved the angles of thin shapes by 1e-4 of
    themselves)."""
    mantissa, exponent = np.frexp(xy)
    return np.unique(np.ldexp(np.round(np.ldexp(mantissa, SHAPE_BITS)), exponent - SHAPE_BITS),
                     axis=0)


def _member(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Rows of ``a (K, 2)`` that are rows of ``b``."""
    view = np.dtype([("x", np.float64), ("y", np.float64)])
    return np.isin(np.ascontiguousarray(a).view(view).ravel(),
                   np.ascontiguousarray(b).view(view).ravel())

