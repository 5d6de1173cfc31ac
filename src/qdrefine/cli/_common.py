"""Helpers shared by the subcommands (not a subcommand itself)."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import sys
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..io import FORMATS, GMSH_VERSIONS, atomic_path, write
from ..report import counted  # noqa: F401  (the commands count with it)
from ..schemes import get_scheme
from ..store.locations import location

if TYPE_CHECKING:
    from ..adaptive import HistoryMismatch

#: Extension of a chunked Zarr mesh store (:mod:`qdrefine.store`).
STORE = ".zarr"

#: Picture formats the commands can save (matplotlib's names).
PICTURES = {".png": "png", ".svg": "svg", ".pdf": "pdf"}


class UsageError(ValueError):
    """Options that do not go together (``--cycles`` without a mark, ``--compress`` for a
    ``.msh`` output): said as argparse says its errors, with the command's ``--help``, exit
    code 2 (they ended with exit 1 and no hint; review)."""


def setup(parser: argparse.ArgumentParser, quiet: bool = True, quiet_also: str = "") -> None:
    """One-line argument errors (``qdrefine: error: ...``, exit 2) and ``--quiet`` (whose
    help adds ``quiet_also``, what it still prints)."""
    prog = parser.prog

    def error(message: str) -> None:
        print(f"qdrefine: error: {message} (see '{prog} --help')", file=sys.stderr)
        sys.exit(2)

    parser.error = error  # type: ignore[method-assign]
    if quiet:
        parser.add_argument("-q", "--quiet", action="store_true",
                            help=f"print nothing but errors and warnings{quiet_also}; no "
                                 "progress bar")


def add_mesh_in_out(parser: argparse.ArgumentParser, options: Callable[[], None]) -> None:
    """``IN`` and ``OUT`` mesh files, then ``options()`` (the command's own), then how OUT
    is written: ``--binary``, ``--format-version``, ``--compress``."""
    parser.add_argument("input", metavar="IN", help="mesh file to read (never modified)")
    parser.add_argument("output", metavar="OUT",
                        help="mesh file to write (written atomically; .msh is Gmsh 4.1 unless "
                             "--format-version 2.2)")
    options()
    parser.add_argument("--binary", action="store_true",
                        help="write .msh or .stl as binary (text by default; much faster "
                             "for large meshes); .vtk, .vtu and .ply are written binary "
                             "anyway")
    add_format_version(parser)
    add_compress(parser)


def check_mesh_output(args: argparse.Namespace) -> None:
    """The checks of :func:`add_mesh_in_out`'s OUT and options, before IN is read."""
    check_output(args.output, (args.input,), binary=args.binary)
    check_format_version(args.output, args.format_version)
    check_compress(args.output, args.compress)


def write_mesh(args: argparse.Namespace, mesh: Any) -> None:
    """Write ``mesh`` to OUT as :func:`add_mesh_in_out`'s options say."""
    write(args.output, mesh, binary=args.binary or None, format_version=args.format_version,
          compress=args.compress)


def add_format_version(parser: argparse.ArgumentParser) -> None:
    """``--format-version``: the Gmsh MSH version of a ``.msh`` output."""
    parser.add_argument("--format-version", choices=GMSH_VERSIONS, default=None,
                        metavar="V", help=f"Gmsh .msh version to write: "
                        f"{' or '.join(GMSH_VERSIONS)} (default {GMSH_VERSIONS[0]})")


def note_written(path: str | Path, what: str, args: argparse.Namespace) -> None:
    """Say that ``path`` was written (``"PATH: WHAT written"``): on stdout after a text
    report, on stderr when stdout is JSON; nothing with ``--quiet``."""
    if not getattr(args, "quiet", False):
        print(f"{path}: {what} written", file=sys.stderr if getattr(args, "json", False)
              else sys.stdout)


def add_compress(parser: argparse.ArgumentParser) -> None:
    """``--compress``: compressed data in a ``.vtu`` or ``.xdmf`` output."""
    parser.add_argument("--compress", action="store_true",
                        help="compress the data of a .vtu (zlib) or .xdmf/.xmf (gzip HDF5) "
                        "output: smaller, slower")


def check_compress(path: str, compress: bool) -> None:
    """``--compress`` applies to the outputs :func:`qdrefine.write` compresses (``.vtu``,
    ``.xdmf`` and ``.xmf``; ``.xmf`` was refused here, not by the API)."""
    from ..io import COMPRESSIBLE, FORMATS

    if compress and FORMATS.get(Path(path).suffix.lower()) not in COMPRESSIBLE:
        raise UsageError(f"{path}: --compress applies to .vtu and .xdmf (.xmf) output only")


def check_format_version(path: str, version: str | None) -> None:
    """``--format-version`` applies to a ``.msh`` output only."""
    if version is not None and Path(path).suffix.lower() != ".msh":
        raise UsageError(f"{path}: --format-version applies to Gmsh .msh output only")


def history_mismatch(path: str, scheme: str, exc: HistoryMismatch) -> ValueError:
    """One line for a file whose refinement history does not fit ``scheme``
    (:class:`qdrefine.adaptive.HistoryMismatch` ``exc``), in the command line's terms."""
    return ValueError(f"{path}: its refinement history (cell data qdrefine:transitions) does "
                      f"not fit scheme {scheme}: {exc.detail} (rows and points counted from 0); "
                      "refine and coarsen it with the scheme it was refined with, or, if its "
                      "points or triangles were changed since (a text format that rounds "
                      "them), refine it uniformly (--levels), which does not use the history")


def scheme_name(text: str) -> str:
    """argparse type: a scheme's name (any case), as :func:`qdrefine.get_scheme` spells it."""
    try:
        return get_scheme(text).name
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def scheme_names_list(text: str) -> list[str]:
    """argparse type: one scheme name or several separated by commas (spaces around them
    allowed); at least one."""
    names = [scheme_name(name.strip()) for name in text.split(",") if name.strip()]
    if not names:
        raise argparse.ArgumentTypeError(f"expected scheme names, got {text!r}")
    return names


def _at_least(text: str, least: int) -> int:
    """An integer ``>= least`` for argparse, or its error naming that bound."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"expected a number >= {least}, got {value}")
    return value


def non_negative(text: str) -> int:
    """argparse type: an integer >= 0."""
    return _at_least(text, 0)


def positive(text: str) -> int:
    """argparse type: an integer >= 1."""
    return _at_least(text, 1)


def similarity_tolerance(parser: argparse.ArgumentParser, what: str) -> None:
    """The ``--tolerance DEG`` option of the similarity classes (``quality``, ``compare``),
    ``what`` starting its help."""
    from ..quality import SIMILARITY_TOLERANCE, TOLERANCE_RANGE

    lo, hi = TOLERANCE_RANGE
    parser.add_argument("--tolerance", type=float_between(
                            lo, hi, "the angles are computed to about 1e-13 degrees"),
                        default=SIMILARITY_TOLERANCE, metavar="DEG",
                        help=f"{what}, {lo:g} to {hi:g} degrees "
                             f"(default {SIMILARITY_TOLERANCE:g})")


def float_between(lo: float, hi: float, why: str = "") -> Callable[[str], float]:
    """argparse type: a number from ``lo`` to ``hi`` (``why``: the reason for the range,
    said when a value is refused)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"expected a number from {lo:g} to {hi:g}, got "
                                             f"{text}{f' ({why})' if why else ''}")
        return value
    return parse


def positive_float(text: str) -> float:
    """argparse type: a float > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text}")
    return value


@contextlib.contextmanager
def session() -> Iterator[None]:
    """Show Python warnings as one line ``qdrefine: warning: ...`` on stderr; use the Agg
    backend of matplotlib."""
    def show(message, category, filename, lineno, file=None, line=None):  # noqa: ARG001
        print(f"qdrefine: warning: {message}", file=sys.stderr)

    os.environ.setdefault("MPLBACKEND", "Agg")
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        # unclosed sockets and files of libraries (Dask's, at exit): nothing the user can act on
        warnings.simplefilter("ignore", ResourceWarning)
        warnings.showwarning = show
        yield


def _files(path: str | Path, read: bool = True) -> set[Path]:
    """The files that the mesh file ``path`` is made of, as identities: Triangle files by
    their common base name, an XDMF file with its HDF5 file (``name.h5``, shared by
    ``name.xdmf`` and ``name.xmf``: what qdrefine writes) and, when ``read``, every other
    HDF5 file it refers to."""
    p = Path(location(path)).resolve()  # file:// URLs as their paths
    if p.suffix.lower() in (".node", ".ele", ".poly"):
        return {p.with_suffix(".triangle")}
    if p.suffix.lower() in (".xdmf", ".xmf"):
        from ..io.xdmf import heavy_data_files

        referred = {h.resolve() for h in heavy_data_files(p)} if read else set()
        return {p, p.with_suffix(".h5")} | referred
    return {p}


def check_output(path: str, inputs: tuple[str, ...] = (), kinds: str = "mesh",
                 binary: bool = False) -> Path:
    """Fail early (before any long work) when ``path`` cannot be written.

    ``kinds``: ``"mesh"`` (a mesh file), ``"store"`` (a ``.zarr`` mesh store), ``"any"``
    (either) or ``"picture"``.
    """
    out = Path(path)
    if str(path).endswith(("/", os.sep)) and out.suffix.lower() != STORE:  # Path() drops it
        raise ValueError(f"{path}: a file name cannot end in '/' (it names a directory)")
    if kinds in ("store", "any") and out.suffix.lower() == STORE:
        if binary:
            raise UsageError(f"{out}: --binary applies to mesh files, not to Zarr stores")
    elif kinds == "store":
        raise ValueError(f"{out}: expected a Zarr mesh store (a name ending in {STORE})")
    elif kinds in ("mesh", "any"):
        if out.suffix.lower() == STORE:  # a store where this command writes files
            raise ValueError(f"{out}: a Zarr mesh store, which this command does not write "
                             "('refine --dask' refines into one; 'qdrefine convert FILE "
                             f"{out.name}' makes one of a file)")
        if out.suffix.lower() not in FORMATS:
            what = f"extension '{out.suffix}'" if out.suffix else "no extension"
            raise ValueError(f"{out}: unknown file format ({what}); known extensions: "
                             f"{', '.join(FORMATS)}")
        if binary and FORMATS[out.suffix.lower()].binary is None:
            raise ValueError(f"{out}: {FORMATS[out.suffix.lower()].name} files have no binary "
                             "variant")
    elif out.suffix.lower() not in PICTURES:
        raise ValueError(f"{out}: pictures are saved as {', '.join(PICTURES)}; got "
                         f"'{out.suffix}'")
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{out}: directory {out.parent} does not exist")
    check_url_output(str(out), inputs)  # a store inside the output, or the output inside one
    for i in inputs:
        shared = _files(i) & _files(path, read=False)
        if shared:
            h5 = [p for p in shared if p.suffix == ".h5"]
            also = "" if out.resolve() in shared or not h5 else \
                f" ({i} and {out} share the heavy-data file {h5[0].name})"
            raise ValueError(f"{out}: the output would overwrite the input{also}; choose "
                             "another name")
    return out


def check_url_output(path: str, inputs: tuple[str, ...] = ()) -> None:
    """For an output given as a URL (``file://`` included), what :func:`check_output` checks
    of a path that a URL can say: it is not one of the inputs, however spelled (links,
    ``file://``, ``memory:///b`` against ``memory://b``), not inside one (a store), and
    holds none (a store is replaced as a whole: an input inside it would be deleted)."""
    from ..store.locations import overlap

    for i in inputs:
        clash = overlap(location(path), i)
        if clash:
            raise ValueError(f"{path}: {clash}; choose another name")


def save_figure(fig: Any, path: str | Path, dpi: int = 150) -> None:
    """Save a matplotlib figure atomically, then close it."""
    import matplotlib.pyplot as plt

    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=PICTURES[path.suffix.lower()], dpi=dpi)
    finally:
        plt.close(fig)


def write_text(path: str | Path, text: str) -> None:
    """Write a text file atomically."""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")


def plain(data: Any) -> Any:
    """``data`` with NumPy scalars and arrays as Python numbers and lists, tuples as lists
    and NaN or infinite floats as ``None`` (JSON's ``null``): what :func:`dumps` writes."""
    if isinstance(data, dict):
        return {str(k): plain(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [plain(v) for v in data]
    if hasattr(data, "tolist"):  # NumPy scalars and arrays
        return plain(data.tolist())
    if isinstance(data, float) and not math.isfinite(data):
        return None
    return data


def dumps(data: Any) -> str:
    """Valid JSON always (``null`` for undefined values such as the angles of an empty
    selection)."""
    return json.dumps(plain(data), indent=2, allow_nan=False)


class Progress:
    """A rich progress bar on stderr, shown only when stderr is a terminal and not quiet.

    ``step(text)`` finishes the previous step and starts the next one.
    """

    def __init__(self, total: int, quiet: bool = False) -> None:
        self.total = total
        self.enabled = not quiet and sys.stderr.isatty()
        self._bar = None
        self._task = None
        self._started = False

    def __enter__(self) -> Progress:
        if self.enabled:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                SpinnerColumn,
                TextColumn,
                TimeElapsedColumn,
            )
            from rich.progress import Progress as Bar

            self._bar = Bar(SpinnerColumn(), TextColumn("{task.description:<28}"), BarColumn(),
                            MofNCompleteColumn(), TimeElapsedColumn(),
                            console=Console(stderr=True), transient=True)
            self._bar.__enter__()
            self._task = self._bar.add_task("starting", total=self.total)
        return self

    def step(self, text: str, total: int | None = None) -> None:
        """Start step ``text``; ``total`` corrects the number of steps when known late."""
        if self._bar is not None:
            if self._started:
                self._bar.advance(self._task)
            self._started = True
            self._bar.update(self._task, description=text,
                             **({} if total is None else {"total": total}))

    def __exit__(self, *exc: Any) -> None:
        if self._bar is not None:
            self._bar.__exit__(*exc)
