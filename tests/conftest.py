"""Shared fixtures: the command line run in-process.

Tests that need the real entry point (exit codes of a fresh process, signals, the first-run
note, stderr of a process that imported nothing yet) use :mod:`cli_runner` instead."""

from __future__ import annotations

import contextlib
import subprocess
from pathlib import Path

import pytest

from cli_runner import without_compile_note
from qdrefine.cli import main


@pytest.fixture
def run(capsys):
    """``run(*args, cwd=None)``: ``qdrefine ARGS`` through ``qdrefine.cli.main`` in this
    process, as a ``CompletedProcess`` (``returncode``, ``stdout``, ``stderr``) like
    :func:`cli_runner.cli`; ``SystemExit`` (``--help``, argument errors) gives its code."""

    def run_(*args, cwd: Path | None = None) -> subprocess.CompletedProcess:
        capsys.readouterr()
        argv = [str(a) for a in args]
        with contextlib.chdir(cwd) if cwd is not None else contextlib.nullcontext():
            try:
                code = main(argv)
            except SystemExit as exc:
                code = exc.code if isinstance(exc.code, int) else 1
        out, err = capsys.readouterr()
        return subprocess.CompletedProcess(["qdrefine", *argv], code, out,
                                           without_compile_note(err))

    return run_
