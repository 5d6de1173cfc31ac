"""Marking helpers: which triangles to refine. Each returns a boolean mask ``(M,)``.

Pass the mask as ``marked`` to :func:`qdrefine.refine`.

Examples
--------
>>> from qdrefine import examples, refine
>>> from qdrefine.marking import mark_box
>>> mesh = examples.square(4)
>>> fine = refine(mesh, marked=mark_box(mesh, (0.0, 0.0, 0.2, 0.2)))
>>> fine.n_triangles > mesh.n_triangles
True
"""

from __future__ import annotations

import re
from collections.abc import Callable
from os import PathLike
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .adaptive import as_mask
from .adaptive.api import is_integer_mask
from .mesh import Mesh
from .predicates import check_coordinates, orient_signs

__all__ = ["mark_ids", "mark_mask", "mark_tag", "mark_region", "mark_box", "mark_point",
           "mark_circle", "mark_random", "mark_dorfler", "mark_maximum", "mark_file"]


def mark_ids(mesh: Mesh, ids: ArrayLike) -> NDArray[np.bool_]:
    """Mask of the triangles with indices ``ids (K,) int`` (checked to be in range)."""
    a = np.asarray(ids)
    if a.size and a.dtype == bool:
        raise ValueError("ids must be integers; use mark_mask for a boolean mask")
    return as_mask(a.astype(np.int64) if a.size == 0 else a, mesh.n_triangles)


def mark_mask(mesh: Mesh, mask: ArrayLike) -> NDArray[np.bool_]:
    """A checked copy of a boolean mask ``(M,)``."""
    a = np.asarray(mask)
    if a.dtype != bool:
        raise ValueError(f"mask must be boolean, got dtype {a.dtype}")
    return as_mask(a, mesh.n_triangles)


def mark_tag(mesh: Mesh, tags: int | ArrayLike) -> NDArray[np.bool_]:
    """Triangles whose cell tag is ``tags`` (one tag or several); a tag no triangle has is an
    error that lists the tags present."""
    if mesh.cell_tags is None:
        raise ValueError("the mesh has no cell tags")
    given = np.atleast_1d(np.asarray(tags))
    if given.size and given.dtype.kind not in "iu":  # 1.7 marked tag 1
        raise ValueError(f"cell tags are integers, got {tags!r}")
    if given.size and given.dtype.kind == "u" and int(given.max()) > np.iinfo(np.int64).max:
        raise ValueError(f"no triangle has cell tag {int(given.max())} (cell tags are "
                         "64-bit signed integers)")  # the cast named it -1
    wanted = given.astype(np.int64)
    present = np.unique(mesh.cell_tags)
    missing = np.setdiff1d(wanted, present)
    if missing.size:
        raise ValueError(f"no triangle has cell tag {int(missing[0])} (cell tags: "
                         f"{', '.join(str(int(t)) for t in present)})")
    return np.isin(mesh.cell_tags, wanted)


#: A triangle id in a mark file: ASCII digits, an optional sign.
_ID = re.compile(r"[+-]?[0-9]+")


def mark_file(mesh: Mesh, path: str | PathLike[str]) -> NDArray[np.bool_]:
    """Triangles listed in a file: a text file of triangle ids (0-based, whitespace or
    line separated, ``#`` starts a comment), or a ``.npy`` file of ids ``(K,) int`` or of a
    boolean mask ``(M,)``. Errors name the file and the line (or entry).

    Examples
    --------
    >>> import tempfile, os
    >>> from qdrefine import examples
    >>> with tempfile.TemporaryDirectory() as d:
    ...     f = os.path.join(d, "ids.txt")
    ...     _ = open(f, "w").write("0 3 5  # a comment")
    ...     mark_file(examples.square(2), f).nonzero()[0].tolist()
    [0, 3, 5]
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.is_dir():
        raise IsADirectoryError(f"{path}: is a directory, not a file of triangle ids")
    if not path.is_file():  # reading a FIFO or device could wait forever
        raise OSError(f"{path}: not a regular file (a file of triangle ids is read whole)")
    if path.suffix.lower() == ".npy":
        return _npy_marks(path, mesh.n_triangles)
    n = mesh.n_triangles
    ids = []
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark (Notepad) too
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file of triangle ids (or a .npy file)") from None
    for line, content in enumerate(text.splitlines(), start=1):
        for word in content.split("#", 1)[0].split():
            if not _ID.fullmatch(word):  # int() also takes 3_0 and ١٢
                raise ValueError(f"{path}, line {line}: {word!r} is not a triangle id")
            t = int(word)
            if not 0 <= t < n:
                raise ValueError(f"{path}, line {line}: triangle id {t} is outside 0..{n - 1}")
            ids.append(t)
    ids = np.array(ids, dtype=np.int64)
    _not_a_mask(path, ids, n)
    mask = np.zeros(n, dtype=bool)
    mask[ids] = True
    return mask


def _npy_marks(path: Path, n: int) -> NDArray[np.bool_]:
    with open(path, "rb") as f:
        if f.read(6) != b"\x93NUMPY":  # NumPy would say "pickled data"
            raise ValueError(f"{path}: not a .npy file (no NumPy header); a text file of "
                             "triangle ids needs another extension")
    try:
        a = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise ValueError(f"{path}: not a readable .npy file ({exc})") from None
    if a.dtype == bool:
        if a.shape != (n,):
            raise ValueError(f"{path}: a boolean mask needs shape ({n},) (one entry per "
                             f"triangle), got {a.shape}")
        return a.copy()
    if not np.issubdtype(a.dtype, np.integer) or a.ndim != 1:
        raise ValueError(f"{path}: expected triangle ids (K,) int or a mask ({n},) bool, got "
                         f"{a.dtype} {a.shape}")
    bad = np.flatnonzero((a < 0) | (a >= n))
    if bad.size:
        raise ValueError(f"{path}, entry {int(bad[0])}: triangle id {int(a[bad[0]])} is "
                         f"outside 0..{n - 1}")
    _not_a_mask(path, a, n)
    return as_mask(a, n)


def _not_a_mask(path: Path, ids: NDArray[np.integer], n: int) -> None:
    if is_integer_mask(ids, n):
        raise ValueError(f"{path}: {n} integers, all 0 or 1, one per triangle: a mask? Save "
                         "it as booleans (mask.astype(bool)) or as triangle ids")


def centroids(mesh: Mesh) -> NDArray[np.float64]:
    """Centroids ``(M, 2)``, the same bits in whatever order a triangle lists its vertices
    (each coordinate's three values are summed in increasing order: the rounding of a sum
    depends on its order, and a mark at a threshold did too)."""
    return np.sort(mesh.points[mesh.triangles], axis=1).mean(axis=1)


def mark_region(mesh: Mesh, inside: Callable[[NDArray[np.float64]], ArrayLike]
                ) -> NDArray[np.bool_]:
    """Triangles whose centroid is in a region: ``inside(centroids (M, 2)) -> (M,) bool``.

    Examples
    --------
    >>> from qdrefine import examples
    >>> m = mark_region(examples.square(4), lambda c: c[:, 0] < 0.25)
    >>> int(m.sum())
    8
    """
    out = np.asarray(inside(centroids(mesh)))
    if out.shape != (mesh.n_triangles,) or out.dtype != bool:
        raise ValueError(f"inside(centroids) must return a boolean array of shape "
                         f"({mesh.n_triangles},), got {out.dtype} {out.shape}")
    return out.copy()


def mark_box(mesh: Mesh, box: ArrayLike) -> NDArray[np.bool_]:
    """Triangles that intersect (touch or overlap) the closed box ``(x0, y0, x1, y1)``,
    decided exactly on the float coordinates.

    Separating-axis test: the box's two axes (float comparisons, exact) and the three edge
    lines of each triangle, where the box is apart iff its four corners lie strictly
    outside one edge, by the exact orientation predicate (a float test of that side
    missed triangles that hold a point box a few ulps inside them). The box is taken
    within the mesh's extent; a coordinate left of magnitude below 1e-100 (other than 0)
    is refused, as mesh coordinates are (:data:`qdrefine.predicates.COORDINATE_RANGE`).
    """
    b = np.asarray(box, dtype=np.float64)
    if b.shape != (4,) or not np.isfinite(b).all() or b[0] > b[2] or b[1] > b[3]:
        raise ValueError(f"box must be (x0, y0, x1, y1) with x0 <= x1 and y0 <= y1, got {box}")
    p = mesh.points[mesh.triangles]  # (M, 3, 2)
    hit = ((p[..., 0].max(1) >= b[0]) & (p[..., 0].min(1) <= b[2])
           & (p[..., 1].max(1) >= b[1]) & (p[..., 1].min(1) <= b[3]))
    rows = np.flatnonzero(hit)
    if rows.size:  # the box within the mesh's extent meets the same triangles, and its
        # corners stay in the exact predicates' range (1e308 overflowed them)
        extent = p.reshape(-1, 2)
        b = np.concatenate([np.maximum(b[:2], extent.min(0)), np.minimum(b[2:], extent.max(0))])
    corners = np.array([[b[0], b[1]], [b[2], b[1]], [b[2], b[3]], [b[0], b[3]]])
    check_coordinates(corners, "box corner")  # 5e-324 underflowed the exact side tests
    n = mesh.n_points
    points = np.concatenate([mesh.points, corners])
    t = mesh.triangles[rows].astype(np.int64)  # the box's corners are points n..n+3
    for i in range(3):  # edge (a, c) of each counter-clockwise triangle: inside is left
        a, c = t[:, i], t[:, (i + 1) % 3]
        outside = np.ones(rows.size, dtype=np.bool_)
        for k in range(4):
            corner = np.full(rows.size, n + k, dtype=np.int64)
            sides = orient_signs(points, np.stack([a, c, corner], axis=1))
            outside &= sides < 0
        hit[rows[outside]] = False
    return hit


def mark_point(mesh: Mesh, point: ArrayLike, radius: float = 0.0) -> NDArray[np.bool_]:
    """Triangles with a vertex within ``radius`` of ``point`` (a corner singularity: with
    ``radius = 0`` the triangles around the vertex at ``point``)."""
    d = np.linalg.norm(mesh.points - _point(point, "point"), axis=1)
    return (d[mesh.triangles] <= _length(radius, "radius")).any(axis=1)


def mark_circle(mesh: Mesh, center: ArrayLike, radius: float, size: float = 0.0
                ) -> NDArray[np.bool_]:
    """Triangles crossing the circle (vertices on both sides of it, or on it) whose
    longest edge is longer than ``size``: a front refined to a target size."""
    center, radius, size = _point(center, "center"), _length(radius, "radius"), \
        _length(size, "size")
    p = mesh.points[mesh.triangles]
    d = np.linalg.norm(p - center, axis=2)
    cross = (d.min(axis=1) <= radius) & (d.max(axis=1) >= radius)
    longest = np.linalg.norm(p - np.roll(p, -1, axis=1), axis=2).max(axis=1)
    return cross & (longest > size)


def mark_random(mesh: Mesh, fraction: float, seed: int = 0) -> NDArray[np.bool_]:
    """About ``fraction`` of the triangles, picked by a hash of their centroid and
    ``seed``: deterministic for a given mesh, independent of the triangle order, and as
    likely to hit a transition child as any other triangle (the adversarial case for
    local refinement)."""
    if not 0.0 <= fraction <= 1.0:
        raise ValueError(f"fraction must be in [0, 1], got {fraction}")
    c = centroids(mesh)
    u = np.sin(c @ np.array([12.9898, 78.233]) + 3.7 * seed) * 43758.5453
    return u - np.floor(u) < fraction


def mark_dorfler(indicator: ArrayLike, theta: float) -> NDArray[np.bool_]:
    """Dörfler (bulk) marking: a smallest set of triangles holding a ``theta`` share of the
    total of a non-negative ``indicator (M,)`` (e.g. squared local error estimates).

    The largest values are taken first, until their sum reaches ``theta *
    sum(indicator)``; ``0 < theta <= 1``. Every triangle whose value equals the last one
    taken is marked too, so that the marks do not depend on the triangle order (a
    symmetric mesh has equal values in mirrored triangles); the set is then the smallest
    that holds the share and all of each value it takes.

    Examples
    --------
    >>> mark_dorfler([1.0, 5.0, 3.0, 1.0], 0.5).tolist()
    [False, True, False, False]
    """
    eta = _indicator(indicator)
    if not 0.0 < theta <= 1.0:
        raise ValueError(f"theta must be in (0, 1], got {theta}")
    order = np.argsort(-eta, kind="stable")
    mask = np.zeros(eta.shape[0], dtype=bool)
    if not eta.size or eta.max() == 0:
        return mask
    if theta == 1.0:  # all of the sum: every nonzero one (the rounded cumulative sum
        return eta > 0  # reached its total early: [1, 1e-20] marked only the first)
    # scaled by a power of two so that the largest is below 1: the sums cannot overflow
    # (values near 1e308 made the total inf), and every sum rounds as it did unscaled
    eta = np.ldexp(eta, -int(np.frexp(eta.max())[1]))
    csum = np.cumsum(eta[order])
    # against the cumulative sum's own total: eta.sum() rounds otherwise, and theta = 1
    # took a zero too (review)
    count = int(np.searchsorted(csum, theta * csum[-1], side="left")) + 1
    last = eta[order[min(count, eta.shape[0]) - 1]]  # the smallest value taken
    return eta >= last  # its ties too (scaling by a power of two kept every equality)


def mark_maximum(indicator: ArrayLike, theta: float) -> NDArray[np.bool_]:
    """Maximum strategy: triangles with ``indicator >= theta * max(indicator)``, ``0 < theta
    <= 1`` (nothing when the indicator is zero everywhere)."""
    eta = _indicator(indicator)
    if not 0.0 < theta <= 1.0:
        raise ValueError(f"theta must be in (0, 1], got {theta}")
    top = eta.max() if eta.size else 0.0
    return (eta >= theta * top) & (eta > 0)


def _point(point: ArrayLike, name: str) -> NDArray[np.float64]:
    p = np.asarray(point, dtype=np.float64)
    if p.shape != (2,) or not np.isfinite(p).all():
        raise ValueError(f"{name} must be two finite coordinates (x, y), got {point!r}")
    return p


def _length(value: float, name: str) -> float:
    if not (np.isfinite(value) and value >= 0):
        raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
    return float(value)


def _indicator(indicator: ArrayLike) -> NDArray[np.float64]:
    eta = np.asarray(indicator, dtype=np.float64)
    if eta.ndim != 1:
        raise ValueError(f"indicator must be one-dimensional, got shape {eta.shape}")
    if not np.isfinite(eta).all() or (eta < 0).any():
        raise ValueError("indicator must be finite and non-negative")
    return eta
