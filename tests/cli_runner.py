"""The command line run as users run it: ``python -m qdrefine ARGS`` in a subprocess (for
the tests that need the real entry point: exit codes, signals, stderr of a fresh process;
the others call ``qdrefine.cli.main([...])`` in-process)."""

from __future__ import annotations

import os
import subprocess
import sys

__all__ = ["cli", "start", "finish", "without_compile_note"]

#: The line a run that compiles kernels prints first (``qdrefine.cli.COMPILING``).
_NOTE = "qdrefine: note: compiling the numerical kernels"


def without_compile_note(err: str) -> str:
    """``err`` without the compile note: which test first compiles a kernel depends on the
    order the tests run in (a fresh environment compiles in whichever comes first), so the
    tests of a command's own messages leave it out; the note is tested on its own."""
    return "".join(line for line in err.splitlines(keepends=True) if not line.startswith(_NOTE))


def start(*args, env: dict[str, str] | None = None, cwd=None) -> subprocess.Popen:
    """Start ``python -m qdrefine ARGS``; ``env`` adds to the environment."""
    return subprocess.Popen([sys.executable, "-m", "qdrefine", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=None if env is None else os.environ | env, cwd=cwd)


def finish(process: subprocess.Popen, timeout: float = 300) -> subprocess.CompletedProcess:
    """Wait for a :func:`start` ed process; its exit code, stdout and stderr."""
    out, err = process.communicate(timeout=timeout)
    return subprocess.CompletedProcess(process.args, process.returncode, out,
                                       without_compile_note(err))


def cli(*args, env: dict[str, str] | None = None, cwd=None,
        timeout: float = 300) -> subprocess.CompletedProcess:
    """Run ``python -m qdrefine ARGS`` to the end."""
    return finish(start(*args, env=env, cwd=cwd), timeout)
