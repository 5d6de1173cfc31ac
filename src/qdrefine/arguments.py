"""Checks of the arguments that several entry points share."""

from __future__ import annotations

import operator

import numpy as np

__all__ = ["as_count"]


def as_count(value: object, name: str) -> int:
    """``value`` as a non-negative integer; ``ValueError`` naming ``name`` otherwise."""
    try:
        if isinstance(value, bool | np.bool_):  # True is an int to Python, not a count
            raise TypeError
        count = operator.index(value)
    except TypeError:
        raise ValueError(f"{name} must be an integer, got {value!r}") from None
    if count < 0:
        raise ValueError(f"{name} must be >= 0, got {count}")
    return count
