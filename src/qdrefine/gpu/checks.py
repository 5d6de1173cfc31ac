"""Checks of the GPU refinement's inputs and outputs: coordinates in the range of exact
predicates (:data:`qdrefine.predicates.COORDINATE_RANGE`), vertex indices in range (each a
kernel pass that finds the first bad row, the message built on the host); the rounded
boundary of each level (cut on the device, swept on the host over its points only,
:mod:`qdrefine.boundaries`); on the host, the dtypes of host arrays and, where no level
runs, the orientation."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import cuda
from numpy.typing import NDArray

from ..boundaries import first_bad_edge
from ..check.cells import misoriented
from ..predicates import COORDINATE_RANGE, below_range, check_coordinates, orient_signs
from . import kernels as k
from .numbering import THREADS, blocks

__all__ = ["BoundaryCrossed", "cast_host", "check_boundary", "check_indices", "check_new_points",
           "check_orientation", "check_points", "split_boundary"]


def check_points(points) -> None:
    """:func:`qdrefine.predicates.check_coordinates` on the device: ``ValueError`` naming
    the first bad point."""
    n = points.shape[0]
    if n == 0:
        return
    first_bad = cuda.to_device(np.array([n], dtype=np.int64))
    lo, hi = COORDINATE_RANGE
    k.check_points[blocks(n), THREADS](points, lo, hi, first_bad)
    if int(first_bad.copy_to_host()[0]) < n:  # rare: the host names the point Mesh names
        check_coordinates(points.copy_to_host())  # (a non-finite one before one out of range)


def check_new_points(points, n: int, smallest: Callable[[], float]) -> None:
    """The new points (rows ``n ..`` of ``points``) in the range of exact predicates, as
    :func:`qdrefine.refine` checks them on the CPU (same message): a device pass;
    ``smallest()``: the input's smallest nonzero coordinate, for the message."""
    new = points[n:]
    if new.shape[0] == 0:
        return
    first_bad = cuda.to_device(np.array([new.shape[0]], dtype=np.int64))
    lo, hi = COORDINATE_RANGE
    k.check_points[blocks(new.shape[0]), THREADS](new, lo, hi, first_bad)
    i = int(first_bad.copy_to_host()[0])
    if i < new.shape[0]:
        raise below_range(n + i, new[i:i + 1].copy_to_host()[0], smallest())


def check_indices(index, n: int, name: str) -> None:
    """``ValueError`` when a device index array has an entry outside ``[0, n)``."""
    if index.shape[0] == 0:
        return
    first_bad = cuda.to_device(np.array([index.shape[0]], dtype=np.int64))
    _first_out_of_range[blocks(index.shape[0]), THREADS](index, n, first_bad)
    if int(first_bad.copy_to_host()[0]) == index.shape[0]:
        return
    # rare: the range for the message (atomics on one address serialise: only now)
    bounds = cuda.to_device(np.array([np.iinfo(np.int64).max, -1], dtype=np.int64))
    _index_range[blocks(index.shape[0]), THREADS](index, bounds)
    lo, hi = (int(b) for b in bounds.copy_to_host())
    raise ValueError(f"{name}: vertex indices must be in [0, {n}), got [{lo}, {hi}]")


@cuda.jit
def _first_out_of_range(index, n, first_bad):
    """``first_bad[0]``: the least row of ``index`` with an entry outside ``[0, n)``
    (unchanged when there is none; an atomic only where an entry is bad)."""
    r = cuda.grid(1)
    if r < index.shape[0]:
        for i in range(index.shape[1]):
            v = index[r, i]
            if v < 0 or v >= n:
                cuda.atomic.min(first_bad, 0, r)


@cuda.jit
def _index_range(index, bounds):
    r = cuda.grid(1)
    if r < index.shape[0]:
        for i in range(index.shape[1]):
            cuda.atomic.min(bounds, 0, index[r, i])
            cuda.atomic.max(bounds, 1, index[r, i])


def cast_host(host: NDArray, name: str, real: bool) -> NDArray:
    """A host array of another dtype as ``float64`` (``real``: coordinates) or ``int64``
    (indices, tags), refused as :class:`qdrefine.Mesh` refuses it where that would change a
    value (a fraction, a wrapped integer) or is not a number."""
    kind = host.dtype.kind
    if real:
        if kind not in "iuf":
            raise ValueError(f"{name} must be numbers, got dtype {host.dtype}")
        return host.astype(np.float64)
    if kind not in "iu":
        raise ValueError(f"{name} must hold integers, got dtype {host.dtype}")
    if kind == "u" and host.max() > np.iinfo(np.int64).max:
        raise ValueError(f"{name} has values beyond int64 (up to {host.max()})")
    return host.astype(np.int64)


def check_orientation(points: NDArray, triangles: NDArray) -> None:
    """``ValueError`` naming the first zero-area or clockwise triangle (exact, the wording
    of :class:`qdrefine.Mesh`)."""
    signs = orient_signs(points, triangles.astype(np.int64))
    bad = np.flatnonzero(signs <= 0)
    if bad.size:
        t = int(bad[0])
        raise ValueError(misoriented(t, triangles[t], signs[t] == 0))


class BoundaryCrossed(Exception):
    """The rounded boundary of a level crosses itself (:mod:`qdrefine.boundaries`): the
    caller refuses the mesh with the CPU's words."""


def split_boundary(pieces, ed, n: int, per: int):
    """The boundary ``pieces (B, 2)`` (device) cut at the level's new points."""
    out = cuda.device_array((pieces.shape[0] * (per + 1), 2), dtype=np.int64)
    if pieces.shape[0]:
        first_bad = cuda.to_device(np.array([pieces.shape[0]], dtype=np.int64))
        k.split_edges[blocks(pieces.shape[0]), THREADS](pieces, n, ed.starts, ed.first, ed.hi,
                                                        per, out, first_bad)
    return out


def check_boundary(points, pieces) -> None:
    """:class:`BoundaryCrossed` where the boundary ``pieces`` cross (the sweep on the host,
    on their points only, gathered on the device)."""
    host = pieces.copy_to_host()
    if not host.size:
        return
    used, local = np.unique(host, return_inverse=True)
    ids = cuda.to_device(used)
    gathered = cuda.device_array((used.size, 2), dtype=np.float64)
    k.gather_rows[blocks(used.size), THREADS](points, ids, gathered)
    if first_bad_edge(gathered.copy_to_host(), local.reshape(-1, 2), used.size) is not None:
        raise BoundaryCrossed
