"""Fast text numbers for the ASCII formats: whole sections parsed at once, rows formatted at
once, and the place (line) of the first bad number when parsing fails.

Floats are written in a form that reads back bit for bit: pyarrow's shortest exact
representation where pyarrow is installed, else 17 significant digits (``%.17g``); integers
by a compiled formatter (about 10 ns each, against 80 ns for Python's ``%d``). Text is parsed
by pandas' C reader (CPython's correctly rounded conversion) where pandas is installed.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["format_floats", "format_ints", "int_lines", "parse", "parse_table", "BadNumber"]

#: Rows formatted per batch by :func:`format_floats` (bounds the memory of the Python objects).
BATCH = 1 << 16


class BadNumber(ValueError):
    """A token that is not a number of the wanted kind: ``line`` counts from the start of the
    parsed text (1-based), ``token`` is the word."""

    def __init__(self, line: int, token: str, what: str) -> None:
        super().__init__(f"line {line}: expected {what}, got {token[:40]!r}")
        self.line, self.token, self.what = line, token, what


def parse(text: bytes, dtype: type, what: str = "a number") -> NDArray:
    """Every whitespace-separated number of ``text`` as a flat array of ``dtype`` (int64 or
    float64); :class:`BadNumber` naming the line of the first bad word otherwise."""
    if not text.strip():
        return np.empty(0, dtype=dtype)
    convert = int if np.dtype(dtype).kind == "i" else float
    try:
        values = np.fromstring(text, dtype=dtype, sep=" ")
    except ValueError:
        values = None
    if values is not None and not (convert is int and values.size and _at_limit(values)):
        return values
    for number, line in enumerate(text.split(b"\n"), start=1):
        for word in line.split():
            try:
                if b"_" in word:  # Python reads 1_0 as 10; the files' C readers do not
                    raise ValueError(word)
                value = convert(word)
            except ValueError:
                raise BadNumber(number, word.decode("utf-8", "replace"),
                                "an integer" if convert is int else what) from None
            if convert is int and not -(2**63) <= value < 2**63:
                raise BadNumber(number, word.decode(), "a 64-bit integer")
    if values is not None:  # the limits themselves were written
        return values
    raise BadNumber(1, text[:40].decode("utf-8", "replace"), what)  # not reached in practice


def _at_limit(values: NDArray[np.int64]) -> bool:
    """Whether ``values`` reach int64's limits, where ``np.fromstring`` puts integers it
    cannot hold (it saturates without a word: 10**20 reads as 2**63 - 1)."""
    limits = np.iinfo(values.dtype)
    return bool(values.max() == limits.max or values.min() == limits.min)


def parse_table(text: bytes, columns: int, what: str = "a number", dtype: type = np.float64
                ) -> NDArray:
    """The lines of ``text``, each ``columns`` whitespace-separated numbers, as a
    ``(lines, columns) float64`` array, correctly rounded. pandas' C reader does it (about
    7x ``np.fromstring``) with CPython's own string-to-double; without pandas, or when a
    line does not fit, :func:`parse` does (and names the line of a bad number)."""
    if len(text) > 1 << 16:
        table = _pandas_table(text, columns, dtype)
        if table is not None:
            return table
    values = parse(text, dtype, what)
    if len(values) % columns:
        raise BadNumber(text.count(b"\n") + 1, "", f"{columns} numbers per line")
    return values.reshape(-1, columns)


def _pandas_table(text: bytes, columns: int, dtype: type) -> NDArray | None:
    try:
        import pandas as pd
    except ImportError:
        return None
    import io
    import warnings

    options = {"sep": r"\s+", "header": None, "dtype": dtype, "engine": "c",
               "na_filter": False}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:  # CPython's correctly rounded conversion
                frame = pd.read_csv(io.BytesIO(text), float_precision="round_trip", **options)
            except TypeError:  # a pandas without the option: its default is exact
                frame = pd.read_csv(io.BytesIO(text), **options)
    except (ValueError, OverflowError, pd.errors.ParserError, pd.errors.EmptyDataError):
        return None
    table = frame.to_numpy(dtype=dtype)
    if table.ndim != 2 or table.shape[1] != columns:
        return None
    return table


@njit(cache=True)
def _format_ints(a: NDArray[np.int64]) -> NDArray[np.uint8]:
    """One pass: each value's digits into a small buffer, then copied in order."""
    n, k = a.shape
    out = np.empty(n * k * 21, dtype=np.uint8)  # at most 20 characters and a separator
    digits = np.empty(20, dtype=np.uint8)
    ten, nothing, zero = np.uint64(10), np.uint64(0), np.uint8(48)
    pos = 0
    for i in range(n):
        for j in range(k):
            v = a[i, j]
            if v < 0:
                out[pos] = 45  # '-'
                pos += 1
                u = np.uint64(-(v + 1)) + np.uint64(1)  # also for -2**63
            else:
                u = np.uint64(v)
            t = 0
            while True:  # uint64 throughout (mixing with int64 would go through float64)
                q10 = u // ten
                digits[t] = np.uint8(u - q10 * ten) + zero
                u = q10
                t += 1
                if u == nothing:
                    break
            for q in range(t):
                out[pos + q] = digits[t - 1 - q]
            pos += t
            out[pos] = 32 if j < k - 1 else 10
            pos += 1
    return out[:pos]


def int_lines(rows: NDArray) -> Iterator[NDArray[np.uint8]]:
    """:func:`format_ints` in pieces of :data:`ARROW_BATCH` rows (bounded memory)."""
    for start in range(0, max(len(rows), 1), ARROW_BATCH):
        yield format_ints(rows[start:start + ARROW_BATCH])


def format_ints(rows: NDArray) -> NDArray[np.uint8]:
    """``rows (n, k)`` integers as text, one line per row, numbers separated by spaces (a
    buffer to pass to ``file.write``)."""
    a = np.ascontiguousarray(rows, dtype=np.int64)
    if a.ndim == 1:
        a = a[:, None]
    if a.size == 0:
        return np.empty(0, dtype=np.uint8)
    return _format_ints(a)


def format_floats(rows: NDArray, suffix: str = "", first: str = "%.17g") -> Iterator[bytes]:
    """``rows (n, k)`` floats as text that reads back bit for bit, one line per row,
    ``suffix`` appended to each line (e.g. ``" 0"`` for a z coordinate); ``first="%d"``
    writes the first column as integers (an id). Yields the text in pieces of
    :data:`BATCH` rows.

    With pyarrow, numbers are written in their shortest exact form by its compiled
    formatter (about 5x Python's); otherwise Python writes them with 17 significant digits.
    """
    a = np.asarray(rows, dtype=np.float64)
    if a.ndim == 1:
        a = a[:, None]
    n, k = a.shape
    arrow = _arrow()
    step = ARROW_BATCH if arrow is not None else BATCH
    for start in range(0, n, step):
        block = a[start:start + step]
        if arrow is not None:
            yield _arrow_lines(arrow, block, suffix, first)
        else:
            line = " ".join([first] + ["%.17g"] * (k - 1)) + suffix + "\n"
            yield ((line * len(block)) % tuple(block.ravel().tolist())).encode()


#: Rows per piece of the pyarrow formatter.
ARROW_BATCH = 1 << 20


def _arrow():
    try:
        import pyarrow
        import pyarrow.compute
    except ImportError:
        return None
    return pyarrow


def _arrow_lines(pa, block: NDArray[np.float64], suffix: str, first: str) -> memoryview:
    pc = pa.compute
    columns = []
    for j in range(block.shape[1]):
        values = block[:, j]
        if j == 0 and first == "%d":
            values = values.astype(np.int64)
        columns.append(pc.cast(pa.array(values), pa.string()))
    columns[-1] = pc.binary_join_element_wise(columns[-1], pa.scalar(suffix + "\n"), "")
    lines = columns[0] if len(columns) == 1 else \
        pc.binary_join_element_wise(*columns, " ")
    offsets = np.frombuffer(lines.buffers()[1], np.int32)[lines.offset:
                                                           lines.offset + len(lines) + 1]
    return memoryview(lines.buffers()[2])[offsets[0]:offsets[-1]]
