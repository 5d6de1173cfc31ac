"""Iterated refinement (not in the paper): what repeated uniform refinement does to shapes.

A triangle of the diagram point ``(x, y)`` is refined ``k = 1 .. levels`` times by a scheme.
Descendants are tracked by *similarity class* (diagram coordinates rounded to ``10^-digits``),
each with the share of the initial area it covers, so a level costs one partition per class
instead of ``7^k`` partitions. Per initial triangle and level this gives

* the **worst ratio**: the smallest minimum angle of any descendant at levels ``1 .. k`` over
  the initial minimum angle;
* the number of **classes** at level ``k`` and how many are new (never seen at a lower level);
* the **area-weighted quality**: the mean over the initial area of the descendants' minimum
  angle, over the initial minimum angle.

When a level brings no new class, the set of shapes is closed under the scheme: every later
level only repeats known classes, so the worst ratio found is a bound for *all* levels of that
triangle (a proof up to the rounding that identifies classes). :func:`counterexample_search`
looks for triangles whose ratio keeps falling: zooming around the worst sample and towards
the degenerate edge ``y -> 0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..diagram import inside_half, to_diagram
from ..partition import partition_many
from ..schemes import get_scheme

__all__ = ["Iterated", "diagram_grid", "iterate", "worst_ratio", "counterexample_search",
           "min_angle"]


def min_angle(x: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
    """Smallest angle (radians) of the triangles of diagram points (``x <= 1/2``): at ``N``."""
    return np.arctan2(np.asarray(y, dtype=np.float64), 1.0 - np.asarray(x, dtype=np.float64))


def diagram_grid(n: int) -> NDArray[np.float64]:
    """Cell centres of an ``n``-column square grid over the left half ``H``, ``(K, 2)``."""
    if n < 1:
        raise ValueError(f"n must be positive, got {n}")
    h = 0.5 / n
    xs = np.arange(h / 2, 0.5, h)
    ys = np.arange(h / 2, 0.8661, h)
    X, Y = (a.ravel() for a in np.meshgrid(xs, ys))
    keep = inside_half(X, Y)
    return np.column_stack([X[keep], Y[keep]])


@dataclass(frozen=True)
class Iterated:
    """Per-level results of :func:`iterate` for ``K`` initial triangles.

    Attributes
    ----------
    scheme : str
    points : (K, 2) float
        Diagram points of the initial triangles.
    worst : (L, K) float
        Worst descendant min-angle ratio over levels ``1 .. k`` (row ``k - 1``).
    classes : (L, K) int
        Similarity classes at level ``k``.
    new : (L, K) int
        Classes at level ``k`` never seen at a lower level (the initial shape counts as seen).
    quality : (L, K) float
        Area-weighted mean descendant min angle over the initial min angle.
    area : (L, K) float
        Total area share of the level's descendants (1 up to rounding: a check).
    shapes : (C, 2) float
        Diagram points of the classes of the last level; ``owner (C,)`` their triangle.
    digits : int
        Decimal digits to which diagram coordinates were rounded to tell classes apart.

    Notes
    -----
    A class stands for its shape in the canonical placement ``(0,0), (1,0), (x, y)``. A
    shape with a tie (``x = 1/2``: two equal longest-edge endpoints; an isosceles apex) is
    labelled in a mesh by its coordinates, so a mesh may partition a congruent copy as the
    mirror image, which for 7T-QD can give other children. A shape exactly on a 7T-QD
    decision arc (two pentagon splits of equal squared lengths, e.g. ``(0.24, 0.32)``) is
    split in a mesh by its rounded trisection points, which may pick the other split. A
    mesh may so hold a few more shapes than counted here, and another area-weighted quality
    (tests compare the worst ratio with brute-force meshes).
    """

    scheme: str
    points: NDArray[np.float64]
    worst: NDArray[np.float64]
    classes: NDArray[np.int64]
    new: NDArray[np.int64]
    quality: NDArray[np.float64]
    area: NDArray[np.float64]
    shapes: NDArray[np.float64]
    owner: NDArray[np.int64]
    digits: int = 9

    @property
    def levels(self) -> int:
        return self.worst.shape[0]

    @property
    def closed(self) -> NDArray[np.bool_]:
        """``(K,)``: the class set closed (a level without new classes) within the levels."""
        return (self.new == 0).any(axis=0)


def _children(x, y, scheme):
    """Diagram points ``(K, T, 2)`` and area shares ``(K, T)`` of the children of the
    triangles ``(0,0), (1,0), (x, y)``."""
    v = np.zeros((x.size, 3, 2))
    v[:, 1, 0] = 1.0
    v[:, 2, 0] = x
    v[:, 2, 1] = y
    pts, tris = partition_many(v, scheme, strict=False)
    k, t = tris.shape[:2]
    ch = pts[np.arange(k)[:, None, None], tris]  # (K, T, 3, 2)
    e1 = ch[:, :, 1] - ch[:, :, 0]
    e2 = ch[:, :, 2] - ch[:, :, 0]
    share = np.abs(e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]) / y[:, None]
    return to_diagram(ch.reshape(-1, 3, 2)).reshape(k, t, 2), share


def _keys(sid, x, y, scale):
    """One comparable key per (initial triangle, rounded shape): 16 raw bytes."""
    k = np.empty((sid.size, 2), dtype=np.int64)
    k[:, 0] = sid
    k[:, 1] = (np.round(x * scale).astype(np.int64) << 31) + np.round(y * scale).astype(
        np.int64)
    return np.ascontiguousarray(k).view(np.dtype((np.void, 16))).ravel()


def iterate(scheme: str, points: ArrayLike, levels: int = 6, digits: int = 9) -> Iterated:
    """Refine the triangles of diagram ``points`` ``levels`` times by ``scheme``.

    Parameters
    ----------
    scheme : str
        Any scheme of :mod:`qdrefine.schemes`.
    points : (K, 2) float
        Diagram points (``0 <= x <= 1/2``, ``y > 0``) of the initial triangles.
    levels : int
        Uniform refinements, ``>= 1``.
    digits : int
        Shapes whose diagram coordinates agree when rounded to ``10^-digits`` are one class.

    Returns
    -------
    Iterated
    """
    name = get_scheme(scheme).name
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if levels < 1:
        raise ValueError(f"levels must be positive, got {levels}")
    if not 0 <= digits <= 9:  # the key packs x and y in 31 bits each
        raise ValueError(f"digits must be in 0..9, got {digits}")
    n = p.shape[0]
    scale = 10.0**digits
    sid = np.arange(n)
    x, y = p[:, 0].copy(), p[:, 1].copy()
    weight = np.ones(n)
    alpha = min_angle(x, y)
    seen = _keys(sid, x, y, scale)
    worst = np.full((levels, n), np.inf)
    classes = np.zeros((levels, n), dtype=np.int64)
    new = np.zeros((levels, n), dtype=np.int64)
    quality = np.zeros((levels, n))
    area = np.zeros((levels, n))
    running = np.full(n, np.inf)
    for level in range(levels):
        cxy, share = _children(x, y, name)
        t = share.shape[1]
        csid = np.repeat(sid, t)
        cw = (weight[:, None] * share).ravel()
        cxy = cxy.reshape(-1, 2)
        key = _keys(csid, cxy[:, 0], cxy[:, 1], scale)
        uniq, first, inv = np.unique(key, return_index=True, return_inverse=True)
        weight = np.bincount(inv.ravel(), weights=cw)
        sid, x, y = csid[first], cxy[first, 0], cxy[first, 1]
        ratio = min_angle(x, y) / alpha[sid]
        np.minimum.at(running, sid, ratio)
        worst[level] = running
        classes[level] = np.bincount(sid, minlength=n)
        fresh = ~np.isin(uniq, seen)
        seen = np.concatenate([seen, uniq[fresh]])
        new[level] = np.bincount(sid[fresh], minlength=n)
        quality[level] = np.bincount(sid, weights=weight * ratio, minlength=n)
        area[level] = np.bincount(sid, weights=weight, minlength=n)
    return Iterated(name, p, worst, classes, new, quality, area, np.column_stack([x, y]), sid,
                    digits)


def worst_ratio(scheme: str = "7t-qd", levels: int = 6, samples: int | ArrayLike = 40
                ) -> float:
    """Worst min-angle ratio (descendant / initial) of ``levels`` uniform refinements.

    Parameters
    ----------
    scheme : str
    levels : int
        Descendants of levels ``1 .. levels`` are considered.
    samples : int or (K, 2) float
        An ``n``-column grid over the diagram (:func:`diagram_grid`) or the diagram points.

    Returns
    -------
    float
        The smallest ``min angle(descendant) / min angle(initial)`` over the samples.

    Examples
    --------
    >>> 0.4 < worst_ratio("7t-qd", levels=2, samples=8) < 1
    True
    """
    pts = diagram_grid(samples) if np.ndim(samples) == 0 else np.asarray(samples, float)
    return float(iterate(scheme, pts, levels).worst[-1].min())


def counterexample_search(scheme: str, levels: int = 6, start: int = 40, zooms: int = 4,
                          edge: tuple[float, ...] = (1e-3, 1e-4, 1e-5, 1e-6)) -> dict:
    """Search for triangles whose descendants' ratio keeps falling with the level.

    A grid (``start`` columns), then ``zooms`` rounds of a 21 x 21 grid around the worst
    point, each four times finer; then the degenerate edge: 101 points ``x`` in ``[0, 1/2]``
    at each height of ``edge``. Returns the worst ratio found, where, the ratio at each
    level there, and the worst ratio along the edge per height.
    """
    pts = diagram_grid(start)
    it = iterate(scheme, pts, levels)
    i = int(np.argmin(it.worst[-1]))
    best = (float(it.worst[-1, i]), pts[i], it.worst[:, i])
    h = 0.5 / start
    for _ in range(zooms):
        g = np.linspace(-h, h, 21)
        X, Y = np.meshgrid(best[1][0] + g, best[1][1] + g)
        cand = np.column_stack([X.ravel(), Y.ravel()])
        cand = cand[inside_half(cand[:, 0], cand[:, 1]) & (cand[:, 1] > 1e-9)]
        it = iterate(scheme, cand, levels)
        i = int(np.argmin(it.worst[-1]))
        if it.worst[-1, i] < best[0]:
            best = (float(it.worst[-1, i]), cand[i], it.worst[:, i])
        h /= 4
    along = {}
    xs = np.linspace(0.0, 0.5, 101)
    for e in edge:
        it = iterate(scheme, np.column_stack([xs, np.full_like(xs, e)]), levels)
        along[e] = float(it.worst[-1].min())
    return {"worst": best[0], "point": (float(best[1][0]), float(best[1][1])),
            "by_level": [float(v) for v in best[2]], "edge": along}
