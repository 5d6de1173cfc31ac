"""Signals as exceptions, so that every entry point cleans up the same way: SIGTERM (what
``kill``, SLURM and Kubernetes send) becomes ``KeyboardInterrupt`` like Ctrl-C, and the
writers' ``except BaseException`` removes their temporary files."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any

__all__ = ["sigterm_as_interrupt", "signals_held", "TERMINATED"]

#: The message of the ``KeyboardInterrupt`` that SIGTERM raises.
TERMINATED = "terminated (SIGTERM)"


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM (what SLURM and Kubernetes send) raises ``KeyboardInterrupt`` like Ctrl-C,
    so the run cleans up the same way (main thread only; elsewhere nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: Any) -> None:  # noqa: ARG001
        raise KeyboardInterrupt(TERMINATED)

    before = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


@contextlib.contextmanager
def signals_held(held: list[int]) -> Iterator[None]:
    """SIGINT and SIGTERM are held back (appended to ``held``) instead of acting, while code
    that cannot be interrupted cleanly runs (main thread only; elsewhere nothing changes);
    the handlers before are restored after. The caller acts on ``held`` once it can clean
    up (``signal.raise_signal(held[0])``).

    A Dask cluster interrupted while it starts leaves Dask's own error messages and exit
    hooks with tracebacks (a ``NameError`` in ``distributed.utils.sync``, an
    ``AssertionError`` in ``close_clusters``)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def hold(signum: int, frame: Any) -> None:  # noqa: ARG001
        held.append(signum)

    before = {s: signal.signal(s, hold) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in before.items():
            signal.signal(s, handler)
