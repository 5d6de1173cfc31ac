"""The Dask side of :func:`qdrefine.distributed.refine_store`: connecting, checking the
workers (memory, what they can see) before any work, running a stage with a watchdog, and
turning every way a cluster can fail into one clear error.

Dask is imported only when these functions are called.
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import multiprocessing
import os
import signal
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

from .. import store as mesh_store
from ..interrupts import signals_held

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["local_client", "min_worker_memory", "ClusterError", "Reporter", "connect",
           "compute", "check_workers", "quiet_shuffle_logs"]

Progress = Callable[[str, int, int], Any]

#: What every worker holds besides its tasks' data (Python, pandas, Zarr, the kernels), bytes.
BASE_MEMORY = 400 * 2**20
#: Bytes a task holds per row of a chunk, at most (measured about 1.2 KB: the emission of a
#: 7T level with coordinates; an edge partition of 4 chunks, about 1 KB; docs/scale-out.md).
BYTES_PER_ROW = 2048
#: Bytes a worker holds per row of the Zarr chunks the store is stored in (Zarr reads and
#: writes whole chunks, whatever the array's length: a 384-triangle store in chunks of 10**7
#: rows took 585 MiB more to refine on one worker, 3 * 10**7 rows 1444 MiB: 50-61 bytes).
STORED_BYTES_PER_ROW = 64

#: Default seconds a worker may stay paused (memory) before the run stops.
PAUSE_TIMEOUT = 60.0
#: Default seconds without any task transition on the scheduler before the run stops.
STALL_TIMEOUT = 600.0


class ClusterError(OSError):
    """The cluster failed: a worker died (``KilledWorker``), stayed paused for lack of
    memory, or a stage made no progress for too long. The message is one line."""


def min_worker_memory(chunk_size: int, stored_rows: int = 0) -> int:
    """The memory limit a worker needs for chunks of ``chunk_size`` rows stored in Zarr
    chunks of ``stored_rows`` rows (the same rows, or more for an array shorter than its
    chunk), in bytes: ``BASE_MEMORY + BYTES_PER_ROW * chunk_size + STORED_BYTES_PER_ROW *
    stored_rows`` (docs/scale-out.md)."""
    return BASE_MEMORY + BYTES_PER_ROW * int(chunk_size) + STORED_BYTES_PER_ROW * int(stored_rows)


#: A Dask preload (the text of a script: nothing to import) run in every worker process
#: of a local cluster: a terminal's Ctrl-C reaches the whole process group, and the client
#: stops the run, removes its temporary store and closes the cluster; the workers ignore
#: it instead of each printing its own traceback.
WORKER_SETUP = """import signal, threading
if threading.current_thread() is threading.main_thread():
    signal.signal(signal.SIGINT, signal.SIG_IGN)
"""


#: What a worker process prints when it finds that importing the script starts a cluster.
MAIN_GUARD = ("qdrefine: the script starts a local Dask cluster when it is imported, and "
              "Dask's worker processes import it again (each would start a cluster of its "
              "own): put the script's code under 'if __name__ == \"__main__\":' "
              "(docs/scale-out.md)")


def local_client(n_workers: int | None = None, memory_limit: str | float = "auto",
                 processes: bool = True, profile: bool = False, **cluster_kwargs: Any) -> Client:
    """A client of a new local cluster: ``n_workers`` (default: one per core) workers of
    one thread each, sharing the machine's memory (``"auto"``).

    Closing the client also closes the cluster. The dashboard is served when bokeh is
    installed (``client.dashboard_link``). The workers' statistical profiler (the
    dashboard's "Profile" page) runs only with ``profile=True``: sampling every 10 ms, it
    took about 10% of the workers' CPU time of a refinement (docs/scale-out.md).
    """
    from dask.system import CPU_COUNT
    from distributed import Client

    if processes and getattr(multiprocessing.current_process(), "_inheriting", False):
        # a worker process importing the script again (how processes start: "spawn"),
        # whose top-level code starts a cluster: it would wait for its own workers forever.
        # SystemExit: the worker process prints this one line, not a traceback of
        # multiprocessing's start-up; the script's own process reports the failed start.
        raise SystemExit(MAIN_GUARD)
    # any free port (the link is printed), so that two runs side by side do not fight over
    # Dask's default 8787; without bokeh the HTTP server still serves health checks
    cluster_kwargs.setdefault("dashboard_address", ":0")
    if processes:  # worker processes ignore a terminal's Ctrl-C: the client handles it
        cluster_kwargs.setdefault("preload", [WORKER_SETUP])
    # a client given cluster arguments starts its own LocalCluster and closes it on close();
    # Ctrl-C or SIGTERM while it starts acts once it has started (and is closed again)
    held: list[int] = []
    try:
        with signals_held(held):
            client = Client(n_workers=n_workers or CPU_COUNT, threads_per_worker=1,
                            processes=processes, memory_limit=memory_limit, **cluster_kwargs)
    except Exception as exc:
        if held:  # worker processes still importing Dask died of the Ctrl-C: it stops us too
            signal.raise_signal(held[0])
        if processes and "Nanny failed to start" in str(exc):  # each worker printed why
            raise RuntimeError("the local Dask cluster's worker processes failed to start "
                               "(their messages are above)") from None
        raise
    if held:
        client.close()
        signal.raise_signal(held[0])
    if not profile:  # a plugin: it also reaches workers restarted after a kill
        from .plugins import NoProfiler

        client.register_plugin(NoProfiler())
    return client


def _has_dashboard() -> bool:
    return importlib.util.find_spec("bokeh") is not None


@contextlib.contextmanager
def connect(client: Client | None, address: str | None, in_process: bool = False
            ) -> Iterator[tuple[Client, str | None]]:
    """``(client, dashboard address)``: ``client``, a new client of the scheduler at
    ``address``, or of a new local cluster (closed at the end), of threads in this process
    when ``in_process`` (for ``memory://`` stores, which only this process sees)."""
    if client is not None and address is not None:
        raise ValueError("give a client or a scheduler address, not both")
    if client is not None:
        yield client, _dashboard(client)
        return
    _ignore_dask_cancel_error()
    if address is not None:
        from distributed import Client

        try:
            own = Client(address, timeout="30s")
        except OSError as exc:
            raise OSError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
    else:
        own = local_client(processes=not in_process)
        if not in_process:  # our own worker processes: a failed task is one line of ours
            own.run(_quiet_worker_logs)
    try:
        yield own, _dashboard(own)
    finally:
        with contextlib.suppress(Exception):
            own.close()


class _DaskCancelError(logging.Filter):
    """Drops one record: the ``NameError`` that ``distributed.utils.sync``'s ``cancel``
    callback raises (and tornado logs with its traceback) when Ctrl-C or SIGTERM arrives
    before the awaited call has started (its ``future`` is not assigned yet; distributed
    2026.7). Nothing was left to cancel; the interrupt itself goes on as usual."""

    def filter(self, record: logging.LogRecord) -> bool:
        kind = record.exc_info[0] if record.exc_info else None
        return not (kind is NameError and "sync.<locals>.cancel" in record.getMessage())


def _ignore_dask_cancel_error() -> None:
    logger = logging.getLogger("tornado.application")
    if not any(isinstance(f, _DaskCancelError) for f in logger.filters):
        logger.addFilter(_DaskCancelError())


def _quiet_worker_logs() -> None:
    """Run on the workers of a local cluster: they do not log a failed task ("Compute
    Failed" with its traceback); :func:`refine_store` turns the failure into one line."""
    logging.getLogger("distributed.worker").setLevel(logging.CRITICAL)


def _dashboard(client: Client) -> str | None:
    """The dashboard's address, if the scheduler serves one (it needs bokeh)."""
    services = client.scheduler_info().get("services", {})
    if "dashboard" not in services or not client.run_on_scheduler(_has_dashboard):
        return None
    return client.dashboard_link


@contextlib.contextmanager
def quiet_shuffle_logs() -> Iterator[None]:
    """Dask logs every shuffle's start and end as a warning; keep only errors."""
    logger = logging.getLogger("distributed.shuffle._scheduler_plugin")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def check_workers(client: Client, source: str, target: str, chunk_size: int,
                  stored_rows: int = 0) -> int:
    """Before any work: every worker sees the source and the target's parent, and has the
    memory limit that chunks of ``chunk_size`` rows stored in Zarr chunks of
    ``stored_rows`` rows need (:func:`min_worker_memory`). Returns the number of workers."""
    # Asked of the scheduler itself: Client.scheduler_info() returns a cached copy that its
    # periodic refresh may overwrite with one that lists no workers (distributed 2026.7).
    workers = client.run_on_scheduler(_memory_limits)
    if not workers:
        raise ClusterError("the Dask cluster has no workers")
    need = min_worker_memory(chunk_size, stored_rows)
    stored = f" (stored in Zarr chunks of {stored_rows} rows)" if stored_rows > chunk_size else ""
    for address, limit in workers.items():
        if limit and limit < need:
            raise MemoryError(
                f"Dask worker {address} has a memory limit of {limit / 2**20:.0f} MiB; chunks "
                f"of {chunk_size} rows{stored} need at least {need / 2**20:.0f} MiB per worker "
                "(docs/scale-out.md): give the workers more memory or make the store with a "
                "smaller --chunk-size")
    problems = client.run(_visible, source, target)
    for worker, problem in problems.items():
        if problem:
            raise FileNotFoundError(f"{problem}: not visible from the Dask worker {worker}; "
                                    "the source and target must be URLs (s3://, gs://, ...) "
                                    "or paths on a filesystem every worker sees at the same "
                                    "path")
    return len(workers)


def _memory_limits(dask_scheduler: Any) -> dict[str, int]:
    """On the scheduler: each worker's address and memory limit in bytes (0: none)."""
    return {address: int(ws.memory_limit or 0)
            for address, ws in dask_scheduler.workers.items()}


def _visible(source: str, target: str) -> str | None:
    """On a worker: the first of ``source`` (a store) and ``target``'s parent (a local
    directory) it cannot see, or None."""
    if not mesh_store.is_store(source):
        return source
    if mesh_store.is_local(target) and not os.path.isdir(os.path.dirname(target)):
        return os.path.dirname(target)
    return None


class Reporter:
    """Counts stages and forwards them to the user's ``progress`` callable."""

    def __init__(self, progress: Progress | None, total: int, prefix: str = "",
                 state: list[int] | None = None) -> None:
        self.progress, self.total, self.prefix = progress, total, prefix
        self.state = state if state is not None else [0]

    def prefixed(self, prefix: str) -> Reporter:
        return Reporter(self.progress, self.total, prefix, self.state)

    def message(self, text: str) -> None:
        if self.progress is not None:
            self.progress(self.prefix + text, self.state[0], self.total)

    def stage(self, text: str) -> None:
        self.message(text)
        self.state[0] += 1

    def done(self, text: str) -> None:
        self.state[0] = self.total
        self.message(text)


#: Names of qdrefine's writing tasks (waited for after a failure).
WRITERS = ("_write_coords", "_emit_chunk", "_split_chunk", "_write_points", "store-map")


def compute(client: Client, tasks: list, *, pause_timeout: float = PAUSE_TIMEOUT,
            stall_timeout: float = STALL_TIMEOUT, keep: bool = False) -> list:
    """Run ``tasks`` and gather their results (``keep``: return the futures instead, once
    they are all done).

    A worker paused (memory) for ``pause_timeout`` seconds, or a scheduler without any
    task transition for ``stall_timeout`` seconds, stops the run with :class:`ClusterError`;
    so does a worker dying (``KilledWorker``). On any failure (a bad chunk, an interrupt)
    the other tasks are cancelled and the workers given time to finish the writes they are
    in, so that no write lands after the temporary store is removed.
    """
    futures = client.compute(tasks)
    try:
        pending, last, since, checked, paused = set(futures), -1, time.monotonic(), 0.0, {}
        nap = 0.01
        while pending:
            # poll (distributed.wait would use the default client, maybe another's loop)
            time.sleep(nap)
            nap = min(2 * nap, 0.2)
            done = {f for f in pending if f.done()}
            if any(f.status != "finished" for f in done):
                break
            pending -= done
            now = time.monotonic()
            if not pending or now - checked < 1.0:
                continue
            checked = now
            count, states = client.run_on_scheduler(_scheduler_state)
            if count != last:
                last, since = count, now
            elif now - since > stall_timeout:
                raise ClusterError(f"no Dask task made progress for {stall_timeout:.0f} s "
                                   "(stalled stage); stopped")
            for worker, status in states.items():
                if status == "paused":
                    start = paused.setdefault(worker, now)
                    if now - start > pause_timeout:
                        raise ClusterError(
                            f"Dask worker {worker} stayed paused for {pause_timeout:.0f} s: "
                            "its memory is full (docs/scale-out.md: give the workers more "
                            "memory or make the store with a smaller --chunk-size)")
                else:
                    paused.pop(worker, None)
        if keep:
            for f in futures:
                if f.status != "finished":
                    f.result()
            return futures
        return client.gather(futures)
    except BaseException as exc:
        cancel(client, futures)
        if _is_cluster_failure(exc):
            raise _one_line(exc) from None
        raise


def _scheduler_state(dask_scheduler: Any) -> tuple[int, dict[str, str]]:
    return (int(dask_scheduler.transition_counter),
            {w: ws.status.name for w, ws in dask_scheduler.workers.items()})


def _is_cluster_failure(exc: BaseException) -> bool:
    import asyncio
    import concurrent.futures

    from distributed import KilledWorker
    from distributed.comm.core import CommClosedError

    return isinstance(exc, KilledWorker | CommClosedError | asyncio.CancelledError
                      | concurrent.futures.CancelledError | TimeoutError)


def _one_line(exc: BaseException) -> BaseException:
    from distributed import KilledWorker

    if isinstance(exc, KilledWorker):
        task = getattr(exc, "task", None) or (exc.args[0] if exc.args else "a task")
        return ClusterError(f"a Dask worker died while running {task} (killed, or out of "
                            "memory); the run was stopped and its temporaries removed")
    name = type(exc).__name__
    return ClusterError(f"the Dask cluster failed ({name}: {exc}); the run was stopped and "
                        "its temporaries removed")


def cancel(client: Client, futures: list) -> None:
    """Cancel ``futures`` and wait (60 s at most) until no worker runs a writing task."""
    with contextlib.suppress(Exception):
        client.cancel(futures)
    deadline = time.monotonic() + 60.0
    with contextlib.suppress(Exception):
        while time.monotonic() < deadline and any(client.run(_writing).values()):
            time.sleep(0.05)


def _writing(dask_worker: Any) -> int:
    """How many of qdrefine's writing tasks this worker is executing."""
    keys = [str(ts.key) for ts in dask_worker.state.executing]
    return sum(any(name in key for name in WRITERS) for key in keys)
