"""Uniform refinement of a mesh store on a Dask cluster, for meshes larger than memory.

:func:`refine_store` reads a :mod:`qdrefine.store`, refines it ``levels`` times and writes
a new store. Every array is cut into the source's triangle chunks (``C`` rows); a level
runs three stages, and no stage holds more than about one chunk per task on a worker:

1. **corners** (first level only): the rows ``(h = 3t + i, v_i)`` of every triangle chunk
   are merged with the points on ``v`` (``dask.dataframe``) and shuffled back by ``h``
   into triangle chunks (``set_index`` with the chunk boundaries as divisions): the
   coordinates ``(C, 3, 2)`` of every corner, one ``.npy`` file per chunk in a scratch
   directory. Later levels get these files from the previous level's emission.
2. **edge ids**: every half-edge ``h`` (edge ``v_i v_{i+1}`` of triangle ``t``) becomes a
   row ``(key = lo * N + hi, h, coordinates of lo and hi)``, every tagged edge ``e`` a row
   with ``h = 3 M + e``; the rows are hash-shuffled on ``key``. Each edge partition ``p``
   numbers its distinct keys ``0 .. u_p - 1`` and computes their new points with the
   in-memory kernel :func:`qdrefine.kernels.edge_points` (the symmetric formula, from
   ``lo`` to ``hi``). The global edge id is ``offset_p + local id`` (``offset``: prefix sums
   of the ``u_p``, the only numbers gathered on the client); the new points of edge ``g``
   are rows ``N + g k .. N + g k + k - 1``.
3. **emission**: the ``(h, edge id)`` rows are shuffled back into triangle chunks (and
   tagged edge chunks); each triangle chunk runs the in-memory kernel
   :func:`qdrefine.kernels.emit` on its own vertices (renumbered by rank, which keeps the
   kernel's ``a < b`` comparisons) and writes its ``T`` children per triangle, rows
   ``t T .. t T + T - 1``, with the inherited cell tags; each tagged edge chunk is split by
   :func:`qdrefine.refine.split_tagged_edges`. The points (old points, then the new points
   of the edge partitions in order) are rechunked and written chunk by chunk.

The result equals :func:`qdrefine.refine` in memory: the same triangles, row by row, with
bit-identical coordinates (the same compiled kernels on the same float64 inputs), the same
cell tags and tagged edge pieces, and no duplicated point. Only the numbering of the new
points differs (edge ids follow the hash partitions, not the sorted edge order of the
in-memory refinement). See ``docs/scale-out.md``.

Dask and Zarr are imported only when these functions are called.
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import os
import re
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from . import store as mesh_store
from .kernels import edge_points, emit
from .mesh import index_dtype
from .predicates import check_coordinates, orient_signs
from .refine import as_count, split_tagged_edges
from .schemes import Scheme, get_scheme

if TYPE_CHECKING:
    import pandas as pd
    from distributed import Client

__all__ = ["refine_store", "RefineSummary", "local_client", "MAX_POINTS"]

PathLike = str | os.PathLike
Progress = Callable[[str, int, int], Any]

#: Edge keys ``lo * N + hi`` are int64: at most this many points per level.
MAX_POINTS = 3_037_000_499


@dataclass(frozen=True)
class RefineSummary:
    """What :func:`refine_store` did.

    Attributes
    ----------
    target : Path
        The store written.
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

    target: Path
    scheme: str
    levels: int
    n_points: int
    n_triangles: int
    n_edges: int
    seconds: float
    level_seconds: tuple[float, ...]
    n_workers: int
    dashboard: str | None


def refine_store(source: PathLike, target: PathLike, scheme: str | Scheme = "7t-qd",
                 levels: int = 1, *, client: Client | None = None, address: str | None = None,
                 progress: Progress | None = None) -> RefineSummary:
    """Refine the store ``source`` ``levels`` times on Dask into the new store ``target``.

    Parameters
    ----------
    source, target : str or os.PathLike
        Mesh stores (:mod:`qdrefine.store`); both on a filesystem every worker sees at the
        same path. ``target`` is written atomically (an existing store is replaced, any
        other existing file is refused); its chunks have the source's chunk sizes.
    scheme : {"7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"}
    levels : int, >= 0
    client : distributed.Client, optional
        Use this client; it is left open.
    address : str, optional
        Connect to the scheduler at this address (``tcp://host:8786``) instead.
        With neither: a local cluster sized to the machine (:func:`local_client`), closed
        at the end.
    progress : callable, optional
        Called as ``progress(text, done, total)`` when a stage starts (``done`` stages of
        ``total`` finished), and once at the end with ``done == total``. The first call
        names the dashboard when there is one.

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
    """
    start = time.perf_counter()
    sch = get_scheme(scheme)
    levels = as_count(levels, "levels")
    src = mesh_store.open(source)
    target = Path(target)
    if target.resolve() == src.path.resolve():
        raise ValueError(f"{target}: the target would overwrite the source; choose another "
                         "path")
    if src.n_points > MAX_POINTS:
        raise ValueError(f"{src.path}: {src.n_points} points; distributed refinement "
                         f"handles at most {MAX_POINTS} (int64 edge keys)")
    report = _Reporter(progress, 1 + (3 + 2 * (levels - 1) if levels else 1))
    with _connect(client, address) as (cl, dashboard), _quiet_shuffle_logs(), \
            mesh_store.writing(target) as out, _work_dir(target) as work:
        report.message(f"dask dashboard: {dashboard}" if dashboard else "dask cluster ready")
        _check_visible(cl, [src.path, out, work])
        n_workers = len(cl.scheduler_info()["workers"])
        current, times = src, []
        for level in range(1, levels + 1):
            t0 = time.perf_counter()
            last = level == levels
            path = out if last else work / f"level-{level}.zarr"
            meta = _metadata(src, sch, levels) if last else {}
            refined = _Level(cl, current, sch, path, work / f"scratch-{level}",
                             None if last else work / f"scratch-{level + 1}", level > 1, meta,
                             report.prefixed(f"level {level}/{levels}: ")).run()
            if current is not src:
                shutil.rmtree(current.path, ignore_errors=True)
            current = refined
            times.append(time.perf_counter() - t0)
        if levels == 0:
            report.stage("copying the source")
            _copy(cl, src, out, _metadata(src, sch, 0))
    result = mesh_store.open(target)
    report.done(f"wrote {target}")
    return RefineSummary(target, sch.name, levels, result.n_points, result.n_triangles,
                         result.n_edges, time.perf_counter() - start, tuple(times), n_workers,
                         dashboard)


def _metadata(src: mesh_store.MeshStore, sch: Scheme, levels: int) -> dict[str, Any]:
    meta = dict(src.metadata)
    history = list(meta.get("refinements", []))
    meta["refinements"] = history + [{"scheme": sch.name, "levels": levels}]
    return meta


# --------------------------------------------------------------------------------------------
# cluster


def local_client(n_workers: int | None = None, memory_limit: str | float = "auto",
                 processes: bool = True, **cluster_kwargs: Any) -> Client:
    """A client of a new local cluster: ``n_workers`` (default: one per core) workers of
    one thread each, sharing the machine's memory (``"auto"``).

    Closing the client also closes the cluster. The dashboard is served when bokeh is
    installed (``client.dashboard_link``).
    """
    from dask.system import CPU_COUNT
    from distributed import Client

    if not _has_dashboard():
        cluster_kwargs.setdefault("dashboard_address", None)
    # a client given cluster arguments starts its own LocalCluster and closes it on close()
    return Client(n_workers=n_workers or CPU_COUNT, threads_per_worker=1, processes=processes,
                  memory_limit=memory_limit, **cluster_kwargs)


def _has_dashboard() -> bool:
    return importlib.util.find_spec("bokeh") is not None


@contextlib.contextmanager
def _connect(client: Client | None, address: str | None) -> Iterator[tuple[Client, str | None]]:
    if client is not None and address is not None:
        raise ValueError("give a client or a scheduler address, not both")
    if client is not None:
        yield client, _dashboard(client)
        return
    if address is not None:
        from distributed import Client

        try:
            own = Client(address, timeout="30s")
        except OSError as exc:
            raise OSError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
    else:
        own = local_client()
    try:
        yield own, _dashboard(own)
    finally:
        own.close()


def _dashboard(client: Client) -> str | None:
    """The dashboard's address, if the scheduler serves one (it needs bokeh)."""
    services = client.scheduler_info().get("services", {})
    if "dashboard" not in services or not client.run_on_scheduler(_has_dashboard):
        return None
    return client.dashboard_link


@contextlib.contextmanager
def _quiet_shuffle_logs() -> Iterator[None]:
    """Dask logs every shuffle's start and end as a warning; keep only errors."""
    logger = logging.getLogger("distributed.shuffle._scheduler_plugin")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


@contextlib.contextmanager
def _work_dir(target: Path) -> Iterator[Path]:
    work = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".work", dir=target.parent))
    try:
        yield work
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _missing(paths: list[str]) -> list[str]:
    return [p for p in paths if not os.path.exists(p)]


def _check_visible(client: Client, paths: Sequence[Path]) -> None:
    missing = client.run(_missing, [str(p) for p in paths])
    for worker, gone in missing.items():
        if gone:
            raise FileNotFoundError(f"{gone[0]}: not visible from the Dask worker {worker}; "
                                    "the source and target must be on a filesystem shared "
                                    "by the client and every worker, at the same path")


class _Reporter:
    """Counts stages and forwards them to the user's ``progress`` callable."""

    def __init__(self, progress: Progress | None, total: int, prefix: str = "",
                 state: list[int] | None = None) -> None:
        self.progress, self.total, self.prefix = progress, total, prefix
        self.state = state if state is not None else [0]

    def prefixed(self, prefix: str) -> _Reporter:
        return _Reporter(self.progress, self.total, prefix, self.state)

    def message(self, text: str) -> None:
        if self.progress is not None:
            self.progress(self.prefix + text, self.state[0], self.total)

    def stage(self, text: str) -> None:
        self.message(text)
        self.state[0] += 1

    def done(self, text: str) -> None:
        self.state[0] = self.total
        self.message(text)


# --------------------------------------------------------------------------------------------
# one level


def _bounds(n: int, chunk: int) -> list[tuple[int, int]]:
    """Row ranges ``[(start, stop)]`` of ``n`` rows in chunks of ``chunk``."""
    return [(a, min(n, a + chunk)) for a in range(0, n, chunk)]


def _divisions(ranges: Sequence[tuple[int, int]], per_row: int) -> tuple[int, ...]:
    """Dask divisions putting the values ``per_row * [start, stop)`` in one partition each."""
    return tuple(per_row * a for a, _ in ranges) + (per_row * ranges[-1][1] - 1,)


class _Job:
    """What the tasks of one level share: the source's and the output's Zarr arrays, the
    scratch directories, the scheme and the sizes. Plain (not a dataclass) so that Dask
    passes it as an opaque argument; its token is random (one per level)."""

    def __init__(self, src: mesh_store.MeshStore, sch: Scheme, scratch: Path,
                 next_scratch: Path | None) -> None:
        import zarr

        group = zarr.open_group(str(src.path), mode="r")
        self.src = {name: group[name] for name in group.array_keys()}
        self.out: dict[str, Any] = {}
        self.path, self.scheme = str(src.path), sch.name
        self.scratch = str(scratch)
        self.next_scratch = None if next_scratch is None else str(next_scratch)
        self.n, self.m, self.n_out = src.n_points, src.n_triangles, 0
        self.k, self.children = sch.stencil.per_edge, sch.n_children
        self.chunk = int(self.src["triangles"].chunks[0])
        self.token = os.urandom(16).hex()

    def __dask_tokenize__(self) -> str:
        return self.token

    def file(self, kind: str, i: int, scratch: str | None = None) -> str:
        return os.path.join(scratch or self.scratch, f"{kind}-{i}.npy")


class _Level:
    """One level of refinement of ``src`` into a new store at ``out``.

    ``scratch`` receives this level's intermediate files; its corner coordinates are
    already there when ``coords_ready`` (written by the previous level's emission). With
    ``next_scratch``, the emission writes the children's corner coordinates there.
    """

    def __init__(self, client: Client, src: mesh_store.MeshStore, sch: Scheme, out: Path,
                 scratch: Path, next_scratch: Path | None, coords_ready: bool,
                 metadata: dict[str, Any], report: _Reporter) -> None:
        self.client, self.src, self.sch, self.out = client, src, sch, out
        self.coords_ready, self.metadata, self.report = coords_ready, metadata, report
        scratch.mkdir(exist_ok=True)
        if next_scratch is not None:
            next_scratch.mkdir()
        if src.n_points > MAX_POINTS:
            raise ValueError(f"{report.prefix}{src.n_points} points; distributed refinement "
                             f"handles at most {MAX_POINTS} per level (int64 edge keys)")
        self.job = _Job(src, sch, scratch, next_scratch)
        self.tri_ranges = _bounds(src.n_triangles, self.job.chunk)
        e = self.job.src.get("edges")
        self.edge_ranges = _bounds(src.n_edges, int(e.chunks[0])) if src.n_edges else []

    def run(self) -> mesh_store.MeshStore:
        import dask

        with dask.config.set({"dataframe.convert-string": False}):
            if not self.coords_ready:
                self.report.stage("corner coordinates (merge and shuffle)")
                self._corners()
            self.report.stage("global edge ids and new points (shuffle on edges)")
            counts = self._edges()
            self.report.stage("emission of the children, written chunk by chunk")
            self._emit(counts)
        shutil.rmtree(self.job.scratch, ignore_errors=True)
        return mesh_store.open(self.out)

    def _compute(self, tasks: list) -> list:
        return _compute(self.client, tasks)

    def _corners(self) -> None:
        """Stage 1: ``coords-j.npy (M_j, 3, 2)`` for every triangle chunk ``j``."""
        import dask.dataframe as dd
        from dask import delayed

        job = self.job
        p_ranges = _bounds(self.src.n_points, int(job.src["points"].chunks[0]))
        points = dd.from_map(_points_frame, p_ranges, job=job, meta=_meta("x", "y"),
                             divisions=_divisions(p_ranges, 1))
        corners = dd.from_map(_corners_frame, self.tri_ranges, job=job,
                              meta=_meta("h", "v", ints=2))
        joined = corners.merge(points, left_on="v", right_index=True, how="inner")
        by_tri = joined[["h", "x", "y"]].set_index("h", divisions=_divisions(self.tri_ranges, 3))
        write = delayed(_write_coords, pure=False)
        self._compute([write(part, job, j, a, b) for j, (part, (a, b))
                       in enumerate(zip(by_tri.to_delayed(), self.tri_ranges, strict=True))])

    def _edges(self) -> NDArray[np.int64]:
        """Stage 2: number the edges per hash partition; returns the edges per partition."""
        import dask.dataframe as dd
        from dask import delayed

        job, meta = self.job, _meta("key", "h", "xlo", "ylo", "xhi", "yhi", ints=2)
        rows = dd.from_map(_edge_frame, list(enumerate(self.tri_ranges)), job=job, meta=meta)
        if self.edge_ranges:
            tagged = dd.from_map(_tagged_frame, self.edge_ranges, job=job, meta=meta)
            rows = dd.concat([rows, tagged])
        parts = rows.shuffle(on="key", npartitions=len(self.tri_ranges)).to_delayed()
        number = delayed(_number_edges, pure=False)
        return np.array(self._compute([number(part, job, p) for p, part in enumerate(parts)]),
                        dtype=np.int64)

    def _emit(self, counts: NDArray[np.int64]) -> None:
        """Stage 3: triangles, cell tags, tagged edges and points of the output store."""
        import dask.array as da
        import dask.dataframe as dd
        from dask import delayed

        job = self.job
        job.n_out = job.n + job.k * int(counts.sum())
        group = mesh_store.new_group(self.out, self._specs(job.n_out), self._chunks(),
                                     self.metadata)
        job.out = {name: group[name] for name in group.array_keys()}
        offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]).tolist()
        gids = dd.from_map(_gid_frame, list(enumerate(offsets)), job=job,
                           meta=_meta("h", "gid", ints=2))
        # one shuffle back: half-edge h to triangle chunks, tagged edge 3M + e to edge chunks
        m3 = 3 * self.src.n_triangles
        divisions = (_divisions(self.tri_ranges, 3)[:-1]
                     + tuple(m3 + a for a, _ in self.edge_ranges)
                     + (m3 + self.src.n_edges - 1 if self.edge_ranges else m3 - 1,))
        parts = gids.set_index("h", divisions=divisions).to_delayed()
        emit_chunk = delayed(_emit_chunk, pure=False)
        tasks = [emit_chunk(part, job, j, a, b) for j, (part, (a, b))
                 in enumerate(zip(parts, self.tri_ranges, strict=False))]
        split = delayed(_split_chunk, pure=False)
        tasks += [split(part, job, a, b) for part, (a, b)
                  in zip(parts[len(self.tri_ranges):], self.edge_ranges, strict=True)]
        load = delayed(np.load, pure=False)
        new = [da.from_delayed(load(job.file("points", p)), shape=(int(c) * job.k, 2),
                               dtype=np.float64) for p, c in enumerate(counts) if c]
        points = da.concatenate([da.from_zarr(job.src["points"])] + new)
        points = points.rechunk((job.out["points"].chunks[0], 2))
        tasks.append(da.store(points, job.out["points"], lock=False, compute=False))
        self._compute(tasks)

    def _specs(self, n_out: int) -> dict[str, tuple[tuple[int, ...], Any] | None]:
        src, t, k = self.src, self.sch.n_children, self.job.k
        specs: dict[str, tuple[tuple[int, ...], Any] | None] = {
            "points": ((n_out, 2), np.float64),
            "triangles": ((src.n_triangles * t, 3), index_dtype(n_out)),
            "cell_tags": None if src.cell_tags is None else ((src.n_triangles * t,), np.int64),
            "edges": None, "edge_tags": None,
        }
        if src.edges is not None:
            specs["edges"] = ((src.n_edges * (k + 1), 2), index_dtype(n_out))
            specs["edge_tags"] = ((src.n_edges * (k + 1),), np.int64)
        return specs

    def _chunks(self) -> dict[str, int]:
        """The source's chunk sizes (the triangles' also for the cell tags)."""
        z = self.job.src
        tri = self.job.chunk
        edges = int(z["edges"].chunks[0]) if "edges" in z else 1
        return {"points": int(z["points"].chunks[0]), "triangles": tri, "cell_tags": tri,
                "edges": edges, "edge_tags": edges}


_WRITERS = ("_write_coords", "_number_edges", "_emit_chunk", "_split_chunk", "store-map")


def _compute(client: Client, tasks: list) -> list:
    """Run ``tasks`` and gather their results. On failure (a bad chunk, an interrupt) the
    other tasks are cancelled and the workers given time to finish the writes they are in,
    so that no write lands after the temporary directories are removed."""
    futures = client.compute(tasks)
    try:
        return client.gather(futures)
    except BaseException:
        client.cancel(futures)
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and any(client.run(_writing).values()):
            time.sleep(0.05)
        raise


def _writing(dask_worker: Any) -> int:
    """How many of qdrefine's writing tasks this worker is executing."""
    keys = [str(ts.key) for ts in dask_worker.state.executing]
    return sum(any(name in key for name in _WRITERS) for key in keys)


def _copy(client: Client, src: mesh_store.MeshStore, out: Path,
          metadata: dict[str, Any]) -> None:
    """``levels = 0``: the source's arrays into ``out``, chunk by chunk."""
    import dask.array as da
    import zarr

    group = zarr.open_group(str(src.path), mode="r")
    names = list(group.array_keys())
    specs = {n: (group[n].shape, group[n].dtype) for n in names}
    target = mesh_store.new_group(out, specs, {n: int(group[n].chunks[0]) for n in names},
                                  metadata)
    sources = [da.from_zarr(group[n]) for n in names]
    _compute(client, [da.store(sources, [target[n] for n in names], lock=False,
                               compute=False)])


def _meta(*names: str, ints: int = 0) -> pd.DataFrame:
    """An empty frame with columns ``names``, the first ``ints`` of them int64, the rest
    float64 (the rows of each stage, for Dask)."""
    import pandas as pd

    return pd.DataFrame({name: np.array([], dtype=np.int64 if i < ints else np.float64)
                         for i, name in enumerate(names)})


# --------------------------------------------------------------------------------------------
# tasks (run on the workers)


def _points_frame(rows: tuple[int, int], job: _Job) -> pd.DataFrame:
    import pandas as pd

    a, b = rows
    p = job.src["points"][a:b]
    try:
        check_coordinates(p)
    except ValueError as exc:  # the message names the row within the chunk: shift it
        row = re.match(r"point (\d+) (.*)", str(exc), re.DOTALL)
        where = f"point {a + int(row[1])} {row[2]}" if row else f"points {a}..{b - 1}: {exc}"
        raise ValueError(f"{job.path}: {where}") from None
    return pd.DataFrame({"x": p[:, 0], "y": p[:, 1]}, index=pd.RangeIndex(a, b))


def _triangles(job: _Job, a: int, b: int) -> NDArray[np.int64]:
    """Triangles ``a .. b - 1`` of the source, indices checked."""
    return _vertex_rows(job, "triangles", "triangle", a, b)


def _vertex_rows(job: _Job, name: str, what: str, a: int, b: int) -> NDArray[np.int64]:
    """Rows ``a .. b - 1`` of the source's ``name`` array as ``int64``; ``ValueError`` naming
    the first row (a ``what``) with a vertex index outside ``0 .. n - 1``."""
    rows = job.src[name][a:b].astype(np.int64)
    bad = ((rows < 0) | (rows >= job.n)).any(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{job.path}: {what} {a + i} {tuple(rows[i].tolist())} has a vertex "
                         f"index outside 0..{job.n - 1}")
    return rows


def _corners_frame(rows: tuple[int, int], job: _Job) -> pd.DataFrame:
    import pandas as pd

    a, b = rows
    t = _triangles(job, a, b)
    return pd.DataFrame({"h": np.arange(3 * a, 3 * b, dtype=np.int64), "v": t.ravel()})


def _in_order(part: pd.DataFrame, start: int, stop: int, what: str) -> None:
    """The shuffle put exactly the rows ``start .. stop - 1`` here, sorted (or it is a bug)."""
    index = part.index.to_numpy()
    if len(index) != stop - start or (len(index) and (index[0] != start or index[-1] != stop - 1)):
        raise RuntimeError(f"qdrefine internal error: {what} rows {start}..{stop - 1} arrived "
                           f"as {len(index)} rows")


def _write_coords(part: pd.DataFrame, job: _Job, j: int, a: int, b: int) -> None:
    _in_order(part, 3 * a, 3 * b, "corner")
    np.save(job.file("coords", j), part[["x", "y"]].to_numpy(np.float64).reshape(-1, 3, 2))


def _edge_frame(item: tuple[int, tuple[int, int]], job: _Job) -> pd.DataFrame:
    """Half-edge ``h = 3t + i`` (from corner ``i`` to corner ``i + 1``) with its key and the
    coordinates of its smaller and larger vertex."""
    import pandas as pd

    j, (a, b) = item
    t = _triangles(job, a, b)
    xy = np.load(job.file("coords", j))
    t2, xy2 = np.roll(t, -1, axis=1), np.roll(xy, -1, axis=1)
    swap = (t > t2)[..., None]
    lo_xy, hi_xy = np.where(swap, xy2, xy), np.where(swap, xy, xy2)
    key = np.minimum(t, t2) * job.n + np.maximum(t, t2)
    return pd.DataFrame({"key": key.ravel(), "h": np.arange(3 * a, 3 * b, dtype=np.int64),
                         "xlo": lo_xy[..., 0].ravel(), "ylo": lo_xy[..., 1].ravel(),
                         "xhi": hi_xy[..., 0].ravel(), "yhi": hi_xy[..., 1].ravel()})


def _tagged_frame(rows: tuple[int, int], job: _Job) -> pd.DataFrame:
    """Tagged edge ``e`` as a row ``h = 3 M + e`` (no coordinates)."""
    import pandas as pd

    a, b = rows
    e = _vertex_rows(job, "edges", "edge", a, b)
    key = e.min(axis=1) * job.n + e.max(axis=1)
    nan = np.full(b - a, np.nan)
    m3 = 3 * job.m
    return pd.DataFrame({"key": key, "h": m3 + np.arange(a, b, dtype=np.int64),
                         "xlo": nan, "ylo": nan, "xhi": nan, "yhi": nan})


def _number_edges(part: pd.DataFrame, job: _Job, p: int) -> int:
    """Number the distinct keys of edge partition ``p`` and compute their new points; save
    ``h``, local ids and points in the scratch directory; return the number of edges."""
    key = part["key"].to_numpy(dtype=np.int64)
    h = part["h"].to_numpy(dtype=np.int64)
    order = np.lexsort((h, key))  # by key; a triangle's row (h < 3 M) first
    first_of_key = np.ones(len(key), dtype=bool)
    first_of_key[1:] = key[order][1:] != key[order][:-1]
    first = order[first_of_key]
    tagged_only = h[first] >= 3 * job.m
    if tagged_only.any():
        i = first[int(np.flatnonzero(tagged_only)[0])]
        lo, hi = divmod(int(key[i]), job.n)
        raise ValueError(f"{job.path}: edge {int(h[i]) - 3 * job.m} ({lo}, {hi}) is not an edge of "
                         "any triangle")
    lid = np.empty(len(key), dtype=np.int64)
    lid[order] = np.cumsum(first_of_key) - 1
    ends = part[["xlo", "ylo", "xhi", "yhi"]].to_numpy(dtype=np.float64)[first]
    np.save(job.file("h", p), h)
    np.save(job.file("lid", p), lid)
    np.save(job.file("points", p), _new_points(ends, job.k))
    return len(first)


def _new_points(ends: NDArray[np.float64], k: int) -> NDArray[np.float64]:
    """The ``k`` new points of each edge ``(xlo, ylo, xhi, yhi)`` by the in-memory kernel:
    ``(E * k, 2)``, each edge's points listed from its smaller vertex."""
    u = len(ends)
    local = np.ascontiguousarray(np.concatenate([ends[:, :2], ends[:, 2:]]))
    edges = np.stack([np.arange(u), np.arange(u, 2 * u)], axis=1).astype(index_dtype(2 * u))
    out = np.empty((2 * u + k * u, 2), dtype=np.float64)
    with _one_numba_thread():
        edge_points(local, edges, k, out)
    return out[2 * u:]


def _gid_frame(item: tuple[int, int], job: _Job) -> pd.DataFrame:
    import pandas as pd

    p, offset = item
    return pd.DataFrame({"h": np.load(job.file("h", p)),
                         "gid": offset + np.load(job.file("lid", p))})


def _emit_chunk(part: pd.DataFrame, job: _Job, j: int, a: int, b: int) -> None:
    """Children of triangles ``a .. b - 1`` (rows ``a T .. b T - 1``), their cell tags and,
    with a next level, their corner coordinates."""
    sch = get_scheme(job.scheme)
    k, tc = job.k, job.children
    _in_order(part, 3 * a, 3 * b, "half-edge")
    t = _triangles(job, a, b)
    xy = np.load(job.file("coords", j)).reshape(-1, 2)
    gid = part["gid"].to_numpy(dtype=np.int64).reshape(-1, 3)
    # renumber the chunk's vertices by rank: the kernel compares indices (a < b) only
    vertices, first, local = np.unique(t, return_index=True, return_inverse=True)
    local = local.reshape(-1, 3).astype(np.int32)
    points = np.ascontiguousarray(xy[first])
    _check_orientation(points, local, t, a, job.path)
    u = len(vertices)
    children = np.empty((len(t) * tc, 3), dtype=index_dtype(u + k * (job.n_out - job.n)))
    with _one_numba_thread():
        emit(points, local, gid, k, sch.forms, sch.lut, sch.tables, children)
    old = children < u
    glob = np.where(old, vertices[np.where(old, children, 0)], job.n + (children - u))
    job.out["triangles"][a * tc:b * tc] = glob.astype(job.out["triangles"].dtype)
    if "cell_tags" in job.out:
        job.out["cell_tags"][a * tc:b * tc] = np.repeat(job.src["cell_tags"][a:b], tc)
    if job.next_scratch is not None:
        _save_child_coordinates(job, j, points, local, gid, children)


def _save_child_coordinates(job: _Job, j: int, points: NDArray, local: NDArray,
                            gid: NDArray, children: NDArray) -> None:
    """The children's corner coordinates, one ``(C, 3, 2)`` file per chunk of the next
    level. The new points are computed here again, from the same endpoints by the same
    kernel as in the edge partitions, so they are the stored points bit for bit."""
    k, u = job.k, len(points)
    nxt = np.roll(local, -1, axis=1)
    lo, hi = np.minimum(local, nxt).ravel(), np.maximum(local, nxt).ravel()
    edge_ids, first = np.unique(gid.ravel(), return_index=True)
    ends = np.concatenate([points[lo[first]], points[hi[first]]], axis=1)
    new = _new_points(ends, k).reshape(-1, k, 2)
    for i, c in enumerate(range(0, len(children), job.chunk)):
        block = children[c:c + job.chunk].astype(np.int64)
        old = block < u
        rel = np.where(old, 0, block - u)
        pos = np.minimum(np.searchsorted(edge_ids, rel // k), len(new) - 1)
        coords = np.where(old[..., None], points[np.where(old, block, 0)], new[pos, rel % k])
        np.save(job.file("coords", j * job.children + i, job.next_scratch), coords)


def _check_orientation(points: NDArray, local: NDArray, t: NDArray, a: int, path: str) -> None:
    signs = orient_signs(points, local)
    if (signs <= 0).any():
        i = int(np.flatnonzero(signs <= 0)[0])
        what = "has zero area" if signs[i] == 0 else "is clockwise"
        raise ValueError(f"{path}: triangle {a + i} {tuple(t[i].tolist())} {what}; triangles "
                         "must be counter-clockwise with positive area")


def _split_chunk(part: pd.DataFrame, job: _Job, a: int, b: int) -> None:
    """Tagged edges ``a .. b - 1`` as ``k + 1`` pieces each (rows ``a (k+1) ..``)."""
    _in_order(part, 3 * job.m + a, 3 * job.m + b, "tagged edge")
    k = job.k
    tagged = job.src["edges"][a:b].astype(np.int64)
    gid = part["gid"].to_numpy(dtype=np.int64)
    # split_tagged_edges looks each edge up in a sorted edge list: give it these edges
    lo, hi = tagged.min(axis=1), tagged.max(axis=1)
    order = np.lexsort((hi, lo))
    pieces, tags = split_tagged_edges(tagged, job.src["edge_tags"][a:b],
                                      np.stack([lo, hi], axis=1)[order], job.n, k,
                                      rank=gid[order])
    job.out["edges"][a * (k + 1):b * (k + 1)] = pieces
    job.out["edge_tags"][a * (k + 1):b * (k + 1)] = tags


@contextlib.contextmanager
def _one_numba_thread() -> Iterator[None]:
    """Run the kernels on one thread: Dask's tasks are the parallelism (thread-local)."""
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(before)
