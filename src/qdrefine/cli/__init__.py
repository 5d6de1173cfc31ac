"""The ``qdrefine`` command line: one module per subcommand.

Each subcommand module defines ``HELP`` (one line), ``add_args(parser)`` and
``run(args) -> int``. A run that compiles a kernel (a first run, or a new numba) says so
on stderr when the compiling starts (:func:`qdrefine.jit.compile_note`).

Errors that users can cause (bad arguments, bad files, bad meshes, a mesh too large for
the memory) are raised as ``ValueError``, ``OSError`` or
``MemoryError`` and printed as one line ``qdrefine: error: ...`` with exit code 1; no
traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib
import os
import sys
from typing import Any, TextIO

try:
    from ..interrupts import TERMINATED, sigterm_as_interrupt
    from ..jit import compile_note
    from . import _common
except KeyboardInterrupt:  # Ctrl-C while a command starts: one line, as main says it
    print("qdrefine: interrupted", file=sys.stderr)
    raise SystemExit(130) from None

__all__ = ["main", "COMMANDS"]

#: Subcommands in the order ``--help`` lists them (module ``qdrefine.cli.<name>``).
COMMANDS: tuple[str, ...] = (
    "refine", "coarsen", "check", "info", "quality", "plot", "compare", "convert", "clean", "demo",
    "diagram", "paper",
)


#: Top-level packages of optional extras, and the extra that installs each.
OPTIONAL = {"dask": "dask", "distributed": "dask", "zarr": "dask", "fsspec": "dask",
            "scipy": "paper", "sympy": "paper", "skfem": "fem"}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="qdrefine",
        description="Refine 2D triangle meshes with seven-triangle partitions (7T-QD).",
    )
    _common.setup(parser, quiet=False)  # one-line errors here too (an unknown command)
    parser.add_argument("--version", action="version", version=f"qdrefine {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        module = importlib.import_module(f"{__name__}.{name.replace('-', '_')}")
        cmd = sub.add_parser(name, help=module.HELP, description=module.HELP)
        cmd.set_defaults(parser=cmd)
        module.add_args(cmd)
        cmd.set_defaults(handler=module.run)
    return parser


#: Said once when a run compiles a kernel (:func:`qdrefine.jit.compile_note`).
COMPILING = ("qdrefine: note: compiling the numerical kernels for this machine (once, about a "
             "minute; later runs use the cache)")


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code."""
    if sys.stderr is None:  # '2>&-': messages have nowhere to go (print would use stdout)
        sys.stderr = open(os.devnull, "w")  # noqa: SIM115 (for the rest of the process)
    try:
        parser = _parser()  # imports every command: Ctrl-C here is one line too
    except KeyboardInterrupt:
        print("qdrefine: interrupted", file=sys.stderr)
        return 130
    try:
        args, extra = _parsed(parser, sys.argv[1:] if argv is None else argv)
    except BrokenPipeError:  # 'qdrefine --help | head -1'
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # '--help > /dev/full', '--version >&-': the text was lost
        print(f"qdrefine: error: {_one_line(exc)}", file=sys.stderr)
        return 1
    if extra:  # said by the command's parser: one line, with its --help
        (getattr(args, "parser", None) or parser).error(
            f"unrecognized arguments: {' '.join(extra)}")
    if getattr(args, "handler", None) is None:
        parser.print_help()
        return 2
    _refuse_empty_values(args)
    try:
        # '>&-': a report fails as '> /dev/full' does, naming standard output (it was lost,
        # exit 0); a command that prints nothing (-q) runs as usual
        named = contextlib.redirect_stdout(_standard_output())
        with sigterm_as_interrupt(), compile_note(COMPILING), named:
            code = int(args.handler(args))  # a kill cleans up as Ctrl-C
            sys.stdout.flush()  # a full disk behind '>' is said here, not at exit
            return code
    except BrokenPipeError:  # e.g. `qdrefine info x.msh | head`: not an error of ours
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except _common.UsageError as exc:  # as argparse says its own
        print(f"qdrefine: error: {_one_line(exc)} (see '{args.parser.prog} --help')",
              file=sys.stderr)
        return 2
    except (ValueError, OSError, MemoryError) as exc:
        print(f"qdrefine: error: {_one_line(exc)}", file=sys.stderr)
        return 1
    except ModuleNotFoundError as exc:  # an optional extra that is not installed
        if exc.name is None or exc.name.split(".")[0] not in OPTIONAL:
            raise
        top = exc.name.split(".")[0]
        print(f"qdrefine: error: this needs the optional package '{top}': "
              f"pip install 'qdrefine[{OPTIONAL[top]}]'", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        terminated = str(exc) == TERMINATED
        print(f"qdrefine: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
        return 143 if terminated else 130


def _parsed(parser: argparse.ArgumentParser,
            argv: list[str]) -> tuple[argparse.Namespace, list[str]]:
    """``parser.parse_known_args(argv)``; the text of ``--help`` and ``--version`` that
    could not be written raises :class:`OSError` naming standard output (argparse ignores
    write errors, so it was lost with exit 0)."""
    stream = _standard_output()
    try:
        with contextlib.redirect_stdout(stream):
            return parser.parse_known_args(_joined_negative_values(argv))
    except SystemExit as exit_:
        if exit_.code == 0:  # after --help or --version: was the text written?
            stream.flush()
            if stream.failed is not None:
                raise stream.failed from None
        raise


def _refuse_empty_values(args: argparse.Namespace) -> None:
    """An empty argument (``qdrefine info ""``) is an argument error: as a path it was
    taken as ``.``, the current directory (``demo ""`` wrote its files there)."""
    command = args.parser
    for action in command._actions:
        if "" in (action.const, action.default):  # '--dask' alone: const ""
            continue
        value = getattr(args, action.dest, None)
        values = value if isinstance(value, list) else [value]
        if any(v == "" for v in values):
            name = "/".join(action.option_strings) or action.metavar or action.dest
            command.error(f"argument {name}: expected a value, got an empty string")


def _version() -> str:
    from .. import __version__
    return __version__


def _standard_output() -> _NamedStream:
    """Standard output, its write errors named; a closed one (``>&-``) fails each write."""
    return _NamedStream(_Closed() if sys.stdout is None else sys.stdout, "standard output")


class _Closed:
    """Standard output closed by the shell (``>&-``): every write fails as ``write(2)``
    on a closed descriptor does."""

    def write(self, text: str) -> int:
        if not text:
            return 0
        raise OSError(errno.EBADF, os.strerror(errno.EBADF))

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False


class _NamedStream:
    """A text stream whose write errors name it (``> /dev/full``: "No space left on device:
    'standard output'", where the bare error named nothing)."""

    def __init__(self, stream: TextIO, name: str) -> None:
        self._stream, self._name = stream, name
        #: The first write error, kept for callers that swallow it (argparse's help).
        self.failed: OSError | None = None

    def write(self, text: str) -> int:
        try:
            return self._stream.write(text)
        except OSError as exc:
            raise self._named(exc) from None

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as exc:
            raise self._named(exc) from None

    def _named(self, exc: OSError) -> OSError:
        if exc.filename is None and not isinstance(exc, BrokenPipeError):
            exc.filename = self._name
        if self.failed is None:
            self.failed = exc
        return exc

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


def _joined_negative_values(argv: list[str]) -> list[str]:
    """``--mark-box -1,0,0,1`` as ``--mark-box=-1,0,0,1``: argparse takes a value starting
    with ``-`` for an option unless it is a single number."""
    out, i = [], 0
    while i < len(argv):
        # the option as given, or abbreviated as argparse allows (--mark-b: review)
        if len(argv[i]) >= len("--mark-b") and "--mark-box".startswith(argv[i]) \
                and i + 1 < len(argv) and argv[i + 1].startswith("-") and "," in argv[i + 1]:
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text or type(exc).__name__
