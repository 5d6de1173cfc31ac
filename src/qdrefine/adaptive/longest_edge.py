"""The longest-edge closure of a set of split edges, in rounds over whole arrays."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray


def closure(cedges: NDArray[np.int64], marked: NDArray[np.bool_], n_edges: int,
            presplit: NDArray[np.bool_] | None = None,
            upgrade: Callable[[NDArray[np.int64], NDArray[np.int64]], NDArray[np.bool_]]
            | None = None) -> tuple[NDArray[np.bool_], int]:
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
    longest = cedges[:, 0]
    rounds = 0
    # only triangles touching a newly split edge can change: follow a frontier
    active = np.flatnonzero(split[cedges].any(axis=1))
    while active.size:
        rounds += 1
        new = longest[active]
        if upgrade is not None:
            s = split[cedges[active]]
            code = s @ np.array([1, 2, 4]) | 1  # MN is split by this round anyway
            cand = (code & 2) == 0
            if cand.any():
                up = active[cand][upgrade(active[cand], code[cand])]
                new = np.concatenate([new, cedges[up, 1]])
        new = np.unique(new[~split[new]])
        if new.size == 0:
            break
        split[new] = True
        touched = np.zeros(n_edges, dtype=bool)
        touched[new] = True
        active = np.flatnonzero(touched[cedges].any(axis=1))
    return split, rounds
