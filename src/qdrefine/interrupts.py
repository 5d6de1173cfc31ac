"""Signals as exceptions, so that every entry point cleans up the same way: SIGTERM (what
``kill``, SLURM and Kubernetes send) becomes ``KeyboardInterrupt`` like Ctrl-C, and the
writers' ``except BaseException`` removes their temporary files."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any

__all__ = ["sigterm_as_interrupt", "TERMINATED"]

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
