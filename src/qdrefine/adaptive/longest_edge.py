"""The longest-edge closure of a set of split edges, in rounds over whole arrays."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from .labels import split_codes


def closure(cedges: NDArray[np.int64], marked: NDArray[np.bool_], n_edges: int,
            presplit: NDArray[np.bool_] | None = None,
            upgrade: Callable[[NDArray[np.int64], NDArray[np.int64]], NDArray[np.bool_]]
            | None = None, layers: int = 1) -> tuple[NDArray[np.bool_], int]:
    """Split edges: all edges of marked triangles, closed under the longest-edge rule
    (and the upgrade rule, if given).

    Parameters
    ----------
    cedges : (M, 3) int64
        Canonical edge ids (``MN, NO, OM``) per triangle, see
        :func:`~qdrefine.adaptive.canonical_edges`.
    marked : (M,) bool
    n_edges : int
    presplit : (E,) bool, optional
        Edges that are split already (their points exist); they seed the closure too.
    upgrade : callable, optional
        ``upgrade(triangles, codes)`` says which of these triangles, whose split code
        (bits ``MN=1, NO=2, OM=4``) has ``MN`` but not ``NO``, get ``NO`` split as well.
    layers : int
        How far upgrades may bring new triangles into the refinement: the upgrades of the
        triangles of the closure of the marks may (layer 1), then those of the triangles
        they brought in (layer 2), up to ``layers``; any later upgrade only where the
        triangle across ``NO`` is refined already (or there is none). So upgrades cannot
        cascade through a mesh (a boundary layer of thin right triangles, where every
        transition wants one).

    Returns
    -------
    split : (E,) bool
    rounds : int
        Number of propagation rounds (each one pass over the arrays).

    The set only grows and is bounded by the edge set, so the loop ends after at most
    ``E`` rounds; in practice the rounds follow longest-edge propagation paths, whose length
    is bounded by the number of times the edge length can grow along a path.
    """
    split = np.zeros(n_edges, dtype=bool) if presplit is None else presplit.copy()
    split[cedges[marked].ravel()] = True
    rounds = _propagate(split, cedges, np.flatnonzero(split[cedges].any(axis=1)))
    if upgrade is None:
        return split, rounds
    reached = split[cedges].any(axis=1)  # the closure of the marks
    incident = np.bincount(cedges.ravel(), minlength=n_edges)
    while True:
        s = split[cedges]
        active = s.any(axis=1)
        cand = np.flatnonzero(active & ~s[:, 1])
        if not cand.size:
            break
        up = cand[upgrade(cand, split_codes(s[cand]))]
        # an upgrade outside the closure of the marks brings no new triangle in: the
        # triangles across its NO edge are refined already (or there are none)
        touched = np.bincount(cedges[active].ravel(), minlength=n_edges)
        no = cedges[up, 1]
        no = no[reached[up] | (touched[no] == incident[no])]
        no = np.unique(no[~split[no]])
        if not no.size:
            break
        split[no] = True
        rounds += 1 + _propagate(split, cedges, np.flatnonzero(split[cedges[:, 1:]].any(axis=1)
                                                               & ~split[cedges[:, 0]]))
        layers -= 1
        if layers > 0:
            reached = split[cedges].any(axis=1)
    return split, rounds


def _propagate(split: NDArray[np.bool_], cedges: NDArray[np.int64],
               active: NDArray[np.int64]) -> int:
    """Close ``split`` in place under the longest-edge rule (a triangle with a split edge
    has its longest edge ``MN`` split), starting from the triangles ``active``; the number
    of rounds."""
    longest = cedges[:, 0]
    rounds = 0
    while active.size:
        rounds += 1
        new = longest[active]
        new = np.unique(new[~split[new]])
        if new.size == 0:
            break
        split[new] = True
        touched = np.zeros(split.shape[0], dtype=bool)
        touched[new] = True
        active = np.flatnonzero(touched[cedges].any(axis=1))
    return rounds
