"""Reading a store's rows, each block checked for what an incomplete or damaged store holds:
the fill values of chunks never written (:data:`FILL`), indices outside the points,
coordinates that are not finite, tags beyond int64, chunks that cannot be decoded."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["FILL", "written", "read_rows"]

#: Fill values of unwritten chunks: never valid (tags: the smallest int64). The connectivity
#: fill -1 is UGRID's (and xugrid's) fill value; it is Zarr's ``fill_value``, not a
#: ``_FillValue`` attribute, which would make xarray decode the indices as float64.
FILL = {"points": float("nan"), "node_x": float("nan"), "node_y": float("nan"),
        "triangles": -1, "edges": -1,
        "cell_tags": int(np.iinfo(np.int64).min), "edge_tags": int(np.iinfo(np.int64).min)}


def written(path: str, n_points: int, name: str, start: int, block: NDArray
            ) -> NDArray:
    """``block`` (rows ``start ..`` of array ``name`` of the store at ``path``, which has
    ``n_points`` points), unless it holds the array's fill value
    (:data:`FILL`): a chunk that was never written (a store
    another tool marked complete, or damaged since), which must not pass for data; or,
    for the arrays a streamed file would carry into an unreadable one, a vertex index
    outside the points, a coordinate that is not finite or a tag beyond int64 (a damaged
    store)."""
    if name == "points":  # NaN, written so or a chunk never written, or infinite
        bad = ~np.isfinite(block)
        if bad.any():
            row = _first_bad(start, bad)
            raise ValueError(f"{path}: points row {row} {tuple(block[row - start].tolist())} "
                             "is not finite (NaN is also what a chunk never written reads "
                             "as): the store is incomplete or damaged")
        return block
    fill = FILL.get(name)
    hole = np.isnan(block) if fill is not None and np.isnan(fill) else block == fill
    if fill is not None and hole.any():
        raise ValueError(f"{path}: {name} row {_first_bad(start, hole)} holds the fill value of "
                         "a chunk that was never written: the store is incomplete or damaged")
    if name in ("triangles", "edges") and len(block):
        outside = (block < 0) | (block >= n_points)
        if outside.any():
            row = _first_bad(start, outside)
            raise ValueError(f"{path}: {name} row {row} {tuple(block[row - start].tolist())} "
                             f"has a vertex index outside 0..{n_points - 1}: the store is "
                             "damaged")
    if name in ("cell_tags", "edge_tags"):
        _unsigned_beyond_int64(path, name, start, block)
    return block


def _first_bad(start: int, bad: NDArray) -> int:
    """The store row of the first row of a block (starting at row ``start``) with a ``bad``
    entry."""
    return start + int(np.flatnonzero(bad.reshape(len(bad), -1).any(axis=1))[0])


def _unsigned_beyond_int64(path: str, name: str, start: int, block: NDArray) -> None:
    """Tags stored as unsigned integers beyond int64 (they would wrap to negative tags)."""
    if block.dtype.kind == "u" and len(block) and block.max() > np.iinfo(np.int64).max:
        row = _first_bad(start, block > np.iinfo(np.int64).max)
        raise ValueError(f"{path}: {name} row {row} holds {int(block[row - start])}, beyond "
                         "int64")


def read_rows(path: str, array, name: str, start: int, stop: int) -> NDArray:
    """Rows ``start .. stop - 1`` of the Zarr ``array`` called ``name`` of the store at
    ``path``; a chunk that cannot be decoded (a truncated or damaged file: the codec raises
    ``RuntimeError`` and the like) is a ``ValueError`` naming the store, the array and
    the rows."""
    try:
        return array[start:stop]
    except (RuntimeError, ValueError, TypeError, OSError) as exc:
        if isinstance(exc, OSError) and not isinstance(exc, FileNotFoundError):
            raise  # the system's reason (permissions, a lost connection) says it
        raise ValueError(f"{path}: array '{name}' rows {start}..{stop - 1} cannot be read "
                         f"({exc}): the store is damaged") from None
