"""Checks of the arguments that several entry points share."""

from __future__ import annotations

import operator

import numpy as np
from numpy.typing import NDArray

__all__ = ["as_count", "as_ids", "as_coordinates", "refuse_masked"]


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


def as_ids(value: object, n: int, what: str, rows: str) -> NDArray[np.int64]:
    """``value`` as int64 ids of ``n`` ``rows``, flattened; ``ValueError`` naming ``what``
    otherwise. Only integers in ``0 .. n - 1`` are ids: NumPy would read a boolean mask as
    the ids 0 and 1 and -1 as the last row."""
    ids = np.asarray(value)
    if ids.size and ids.dtype.kind not in "iu":
        hint = " (a boolean mask? pass np.flatnonzero(mask))" if ids.dtype.kind == "b" else ""
        raise ValueError(f"{what} must hold integers, got dtype {ids.dtype}{hint}")
    ids = ids.ravel()
    bad = (ids < 0) | (ids >= n)  # before int64: a uint64 of 2**63 or more would wrap
    if bad.any():
        raise ValueError(f"{what} has id {int(ids[bad][0])}, outside the {n} {rows}")
    return ids.astype(np.int64)


def refuse_masked(value: object, what: str, hint: str = "give a plain array") -> None:
    """``ValueError`` for a NumPy masked array with masked entries: ``np.asarray`` drops
    the mask, so the masked values would be used."""
    if isinstance(value, np.ma.MaskedArray) and bool(np.ma.getmaskarray(value).any()):
        raise ValueError(f"{what} has masked entries; {hint}")


def as_coordinates(value: object, what: str, shape: str = "(N, 2)") -> NDArray[np.float64]:
    """``value`` as a new float64 array of coordinates; ``ValueError`` naming ``what`` for
    a masked array, complex numbers (the cast would drop their imaginary parts), strings
    and booleans (``"1.5"`` and ``True`` were taken as coordinates), and anything float64
    cannot hold (``10**400``). The shape (``shape`` in the messages) is the caller's to
    check."""
    refuse_masked(value, what)
    try:
        given = np.asarray(value)
        if given.dtype.kind == "c":
            raise ValueError(f"{what} must be real numbers, got dtype {given.dtype}")
        if given.size and (given.dtype.kind in "bUSV" or (given.dtype.kind == "O" and any(
                isinstance(x, str | bytes | bool | np.bool_) for x in given.flat))):
            raise ValueError(f"{what} must be numbers, got dtype {given.dtype}")
        return np.array(given, dtype=np.float64, copy=True)
    except (TypeError, OverflowError) as exc:
        raise ValueError(f"{what} must be numbers of shape {shape} ({exc})") from None
    except ValueError as exc:
        if str(exc).startswith(what):
            raise
        raise ValueError(f"{what} must be numbers of shape {shape} ({exc})") from None
