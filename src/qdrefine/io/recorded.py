"""The shape and dtype of each data field, recorded by the writers of formats that store
fields otherwise (MSH: float64 columns; VTU: booleans as bytes, float16 as float32) and
restored by their readers.

A record is trusted only where it fits the stored values: a shape of as many components
per row as stored, a numeric dtype, and a conversion that changes no value (a file whose
values were edited after writing, or a damaged record, would otherwise be read as other
numbers, e.g. ``0.5`` as ``0``). A record that does not fit is ignored with a warning
naming the file and the field, and the values are read as stored.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from numpy.typing import NDArray

__all__ = ["record", "record_of", "restored"]


def record(a: NDArray) -> dict:
    """The record of field ``a (N, ...)``: ``{"shape": [...], "dtype": "<f8"}`` (JSON)."""
    return {"shape": list(a.shape[1:]), "dtype": a.dtype.str}


def record_of(records: object, where: str, name: str) -> object:
    """The record of field ``name`` of ``where`` (``"point"``, ``"cell"``) in a file's
    ``{where: {name: record}}`` (None where the file's records are not such a mapping)."""
    fields = records.get(where) if isinstance(records, dict) else None
    return fields.get(name) if isinstance(fields, dict) else None


def restored(values: NDArray, spec: object, rows: int, where: str) -> NDArray | None:
    """``values`` (``rows`` rows, stored) in the shape and dtype of ``spec``
    (:func:`record`), or ``None`` when there is no record or it does not fit (then a
    warning names ``where``, e.g. ``"mesh.msh: point data 'u'"``)."""
    if spec is None:
        return None
    problem, out = _restore(np.asarray(values), spec, rows)
    if problem is not None:
        warnings.warn(f"{where}: its recorded shape and dtype are ignored ({problem}); "
                      "read as stored", stacklevel=3)
    return out


def _restore(values: NDArray, spec: object, rows: int) -> tuple[str | None, NDArray | None]:
    if not isinstance(spec, dict) or not isinstance(spec.get("shape"), list) \
            or not isinstance(spec.get("dtype"), str):
        return "not a record of a shape and a dtype", None
    shape = spec["shape"]
    if not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in shape):
        return f"shape {shape} is not a list of sizes", None
    try:
        dtype = np.dtype(spec["dtype"])
    except (TypeError, ValueError, SyntaxError):
        return f"{spec['dtype'][:20]!r} is not a dtype", None
    if dtype.kind not in "biuf":
        return f"dtype {dtype} is not numeric", None
    if values.size != rows * math.prod(shape):
        return f"shape {shape} does not fit the {values.size} stored values", None
    with np.errstate(invalid="ignore", over="ignore"):
        out = values.astype(dtype)
        same = np.array_equal(out.astype(values.dtype), values, equal_nan=dtype.kind == "f")
    if not same:
        return f"some stored values are not {dtype} values", None
    try:
        return None, out.reshape((rows, *shape))
    except ValueError:  # e.g. a size of 10**24 beside a 0
        return f"shape {shape} cannot be made", None
