"""Uniform refinement of a mesh store on a Dask cluster, for meshes larger than memory.

:func:`refine_store` reads a :mod:`qdrefine.store` (a local path or any URL Zarr accepts:
``s3://``, ``gs://``, ``memory://`` ...), refines it ``levels`` times and writes a new
store, **equal bit for bit** to :func:`qdrefine.refine` of the same mesh (same points in the
same order, same triangles, tags and tagged edge pieces), whatever the chunk size or the
number of workers. :mod:`.cluster` connects to the cluster, checks the workers and watches
the stages; :mod:`.level` runs one level (stages, numbering and why it equals the in-memory
one: its docstring and ``docs/scale-out.md``).

Dask and Zarr are imported only when these functions are called.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .. import store as mesh_store
from ..arguments import as_count
from ..interrupts import sigterm_as_interrupt
from ..io import WRITE_ERRNOS, cannot_write
from ..schemes import Scheme, get_scheme
from ..store.locations import overlap
from .cluster import (
    PAUSE_TIMEOUT,
    STALL_TIMEOUT,
    ClusterError,
    Reporter,
    check_workers,
    connect,
    local_client,
    min_worker_memory,
    quiet_shuffle_logs,
)
from .level import MAX_POINTS, Level, copy_store

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["refine_store", "RefineSummary", "local_client", "min_worker_memory",
           "ClusterError", "MAX_POINTS"]

Progress = Callable[[str, int, int], Any]

#: Name of the folder of intermediate data inside the run's temporary store.
WORK = "_work"


@dataclass(frozen=True)
class RefineSummary:
    """What :func:`refine_store` did.

    Attributes
    ----------
    target : str
        The store written (URL, or absolute local path).
    scheme : str
    levels : int
    n_points, n_triangles, n_edges : int
        Sizes of the result (``n_edges``: tagged edges).
    seconds : float
        Wall time, cluster start-up included.
    level_seconds : tuple of float
        Wall time of each level.
    n_workers : int
    dashboard : str or None
        The Dask dashboard's address; None when the scheduler serves none (bokeh missing).
    """

    target: str
    scheme: str
    levels: int
    n_points: int
    n_triangles: int
    n_edges: int
    seconds: float
    level_seconds: tuple[float, ...]
    n_workers: int
    dashboard: str | None


def refine_store(source: mesh_store.PathLike, target: mesh_store.PathLike,
                 scheme: str | Scheme = "7t-qd", levels: int = 1, *,
                 client: Client | None = None, address: str | None = None,
                 progress: Progress | None = None, pause_timeout: float = PAUSE_TIMEOUT,
                 stall_timeout: float = STALL_TIMEOUT) -> RefineSummary:
    """Refine the store ``source`` ``levels`` times on Dask into the new store ``target``.

    Parameters
    ----------
    source, target : str or os.PathLike
        Mesh stores (:mod:`qdrefine.store`): local paths (made absolute here; on a
        filesystem every worker sees at the same path) or URLs Zarr accepts. ``target`` is
        complete or absent: it is written as a temporary store next to it, which replaces
        an existing store only when complete (any other existing file is refused); its
        chunks have the source's chunk sizes.
    scheme : {"7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"}
    levels : int, >= 0
    client : distributed.Client, optional
        Use this client; it is left open.
    address : str, optional
        Connect to the scheduler at this address (``tcp://host:8786``) instead.
        With neither: a local cluster sized to the machine (:func:`local_client`), closed
        at the end; its workers are threads of this process when a store is at a
        ``memory://`` URL (which other processes cannot see).
    progress : callable, optional
        Called as ``progress(text, done, total)`` when a stage starts (``done`` stages of
        ``total`` finished), and once at the end with ``done == total``. The first call
        names the dashboard when there is one.
    pause_timeout, stall_timeout : float
        Seconds a worker may stay paused for lack of memory, and seconds without any task
        progress, before the run stops with :class:`ClusterError`.

    Returns
    -------
    RefineSummary

    Raises
    ------
    ValueError
        Bad scheme or levels, both ``client`` and ``address``, an invalid source (the
        message names the store and the first bad point, triangle or edge found).
    FileNotFoundError
        No source store, or a path the workers cannot see.
    FileExistsError
        ``target`` exists and is not a mesh store.
    MemoryError
        A worker's memory limit is below :func:`min_worker_memory` of the chunk size.
    ClusterError
        A worker died (``KilledWorker``) or stayed paused, or a stage stalled.
    KeyboardInterrupt
        Ctrl-C or SIGTERM. On every error the target is left as it was and the run's
        temporary store is removed.
    """
    start = time.perf_counter()
    sch = get_scheme(scheme)
    levels = as_count(levels, "levels")
    src = mesh_store.open(source)
    url = mesh_store.location(target)
    clash = overlap(url, src.path, ("target", "source"))
    if clash:
        raise ValueError(f"{url}: {clash}; choose another path")
    if src.n_points > MAX_POINTS:
        raise ValueError(f"{src.path}: {src.n_points} points; distributed refinement "
                         f"handles at most {MAX_POINTS} (int64 edge keys)")
    timeouts = {"pause_timeout": float(pause_timeout), "stall_timeout": float(stall_timeout)}
    report = Reporter(progress, 1 + (3 + 2 * (levels - 1) if levels else 1))
    in_process = any(u.startswith("memory://") for u in (src.path, url))
    try:
        with sigterm_as_interrupt(), connect(client, address, in_process) as (cl, dashboard), \
                quiet_shuffle_logs(), mesh_store.writing(url) as out:
            report.message(f"dask dashboard: {dashboard}" if dashboard else "dask cluster ready")
            n_workers = check_workers(cl, src.path, url, src.chunk_size,
                                      _stored_chunk_rows(src))
            work = f"{out}/{WORK}"
            current, times, below = src, [], None
            for level in range(1, levels + 1):
                t0 = time.perf_counter()
                last = level == levels
                path = out if last else f"{work}/level-{level}.zarr"
                meta = _metadata(src, sch, levels) if last else {}
                run = Level(cl, current, sch, path, f"{work}/coords-{level}",
                            None if last else f"{work}/coords-{level + 1}", level, meta,
                            report.prefixed(f"level {level}/{levels}: "), timeouts, src)
                run.run()
                below = below or run.below_range  # the first level's: the smallest row
                if current is not src:
                    mesh_store.remove(current.path)
                mesh_store.remove(f"{work}/coords-{level}")
                if not last:
                    mesh_store.finish(path)
                    current = mesh_store.open(path)
                times.append(time.perf_counter() - t0)
            if below is not None:  # no output: the writing is abandoned, as on any error
                raise below
            if levels == 0:
                report.stage("copying the source")
                copy_store(cl, src, out, _metadata(src, sch, 0), timeouts)
            mesh_store.remove(work)
    except OSError as exc:  # a full disk, a file size limit ... in a worker: name the store
        if exc.errno not in WRITE_ERRNOS or str(exc).startswith((url, src.path)):
            raise
        raise cannot_write(url, exc.strerror or str(exc), exc.errno) from None
    result = mesh_store.open(url)
    report.done(f"wrote {url}")
    return RefineSummary(url, sch.name, levels, result.n_points, result.n_triangles,
                         result.n_edges, time.perf_counter() - start, tuple(times), n_workers,
                         dashboard)


def _stored_chunk_rows(src: mesh_store.MeshStore) -> int:
    """The rows of the source's largest Zarr chunk, which the tasks read and the output's
    chunks copy (:attr:`MeshStore.chunk_size` is clipped to the array: a store of 384
    triangles in chunks of 10**8 rows took 6.7 GB past the worker memory check)."""
    import zarr

    group = zarr.open_group(src.path, mode="r")
    return max(int(group[name].chunks[0]) for name in mesh_store.ARRAYS if name in group)


def _metadata(src: mesh_store.MeshStore, sch: Scheme, levels: int) -> dict[str, Any]:
    meta = dict(src.metadata)
    history = meta.get("refinements", [])  # a user's own value of another kind is kept too
    history = list(history) if isinstance(history, list) else [history]
    meta["refinements"] = history + [{"scheme": sch.name, "levels": levels}]
    return meta
