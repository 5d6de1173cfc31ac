"""The longest-edge closure of a set of split edges, in rounds over whole arrays."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def closure(cedges: NDArray[np.int64], marked: NDArray[np.bool_], n_edges: int,
            presplit: NDArray[np.bool_] | None = None) -> tuple[NDArray[np.bool_], int]:
    """Split edges: all edges of marked triangles, closed under the longest-edge rule.

    Parameters
    ----------
    cedges : (M, 3) int64
        Canonical edge ids (``MN, NO, OM``) per triangle, see
        :func:`~qdrefine.adaptive.canonical_edges`.
    marked : (M,) bool
    n_edges : int
    presplit : (E,) bool, optional
        Edges that are split already (their points exist); they seed the closure too.

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
        new = np.unique(new[~split[new]])
        if new.size == 0:
            break
        split[new] = True
        touched = np.zeros(n_edges, dtype=bool)
        touched[new] = True
        active = np.flatnonzero(touched[cedges].any(axis=1))
    return split, rounds
