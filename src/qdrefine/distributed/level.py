"""One level of uniform refinement of a mesh store on Dask, numbered as in memory.

One concern, hence one module over 400 lines: the driver (:class:`Level`) and the tasks
it sends to the workers (below it) are the four stages described here, which share the
run's job description and chunk boundaries; the cluster lives in
:mod:`qdrefine.distributed.cluster`.

Every array is cut into the source's triangle chunks (``C`` rows); no task holds more than
about one chunk. Intermediate data stays in Dask (shuffles, results held by the workers)
or in Zarr arrays under the run's temporary store, never in local files. The stages:

1. **corners** (first level only): the rows ``(h = 3t + i, v_i)`` of every triangle chunk
   are merged with the points on ``v`` (``dask.dataframe``) and shuffled back by ``h``
   (``set_index`` with the chunk boundaries as divisions) into a Zarr array
   ``coords (M, 3, 2)`` of corner coordinates. Later levels get it from the previous
   level's emission.
2. **edge ids**: in memory, edge ``(lo, hi)`` (``lo < hi``) gets its rank in the sorted
   list of distinct edges (:mod:`qdrefine.numbering`). Here every triangle chunk lists its
   *distinct* edges as rows ``(key = lo * N + hi, chunk, coordinates of lo and hi)``: an
   edge inside a chunk is sent once, not once per half-edge. The rows are
   **range-partitioned** on ``key`` (``set_index`` with divisions at vertex boundaries,
   chosen from a histogram of ``lo`` so that partitions are about the same size), so
   partition ``p`` holds a contiguous range of the sorted keys. It numbers its distinct keys
   ``0 .. u_p - 1`` in order and computes their new points by the in-memory formula
   (``edge_point`` of :func:`qdrefine.kernels.edge_points`); with ``offset_p`` the prefix
   sums of the ``u_p`` (the only numbers gathered on the client), ``offset_p + local id``
   is the edge's rank among all keys: exactly the in-memory id, whatever the chunk size or
   worker count.
3. **emission**: the ``(chunk, key, p, local id)`` rows are shuffled back to their chunks;
   each triangle chunk looks its half-edges up, runs the in-memory kernel
   :func:`qdrefine.kernels.emit` on its own vertices (renumbered by rank, which keeps the
   kernel's ``a < b`` comparisons) and writes its ``T`` children per triangle, rows
   ``t T .. t T + T - 1``, with the inherited cell tags (and, for a next level, their corner
   coordinates); each tagged edge chunk is split by
   :func:`qdrefine.refine.split_tagged_edges`. The points (old points, then the new points
   of the partitions in key order) are written by one task per points chunk.
4. **boundary check**: stage 2 also sends each distinct edge's *lone code* (the chunk's
   only half-edge of it, or how many it holds), so each partition knows its edges of one
   half-edge in the mesh, and those of more than two or of two walking them the same way
   (refused: :func:`_misused`); the client sweeps the boundary, as in memory
   (:meth:`Level._check_boundary`).

Up to :data:`DIRECT_PIECES` pieces, the pieces go from task to task as NumPy arrays instead
of through a shuffle, with one edge partition per :data:`EDGE_GROUP` triangle chunks (one
per chunk with a shuffle). The per-chunk passes of both paths are in
:mod:`qdrefine.distributed.chunks`.

Every write covers whole Zarr chunks, so no two tasks write the same chunk.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .. import store as mesh_store
from ..boundaries import first_bad_edge
from ..check.cells import misoriented
from ..jit import one_thread
from ..kernels import emit
from ..mesh import index_dtype
from ..predicates import COORDINATE_RANGE, below_range, check_coordinates, orient_signs
from ..schemes import Scheme, get_scheme
from ..uniform import edge_pieces, split_tagged_edges, too_close_reason
from . import cluster
from .chunks import (
    child_coordinates,
    distinct,
    distinct_counted,
    edge_ends,
    global_children,
    merge_sorted,
    new_points,
)

if TYPE_CHECKING:
    import pandas as pd
    from distributed import Client

__all__ = ["Level", "MAX_POINTS", "copy_store"]

#: Edge keys ``lo * N + hi`` are int64: at most this many points per level.
MAX_POINTS = 3_037_000_499

#: Bins of the histogram of smaller vertices that places the edge partitions' boundaries.
_BINS = 4096

#: Exchanges of at most this many pieces (sources x destinations) go directly from task to
#: task (NumPy arrays, one small task per piece); larger ones through Dask's P2P shuffle.
DIRECT_PIECES = 5_000


#: Without a shuffle, one edge partition per this many triangle chunks: each partition
#: holds about as many edges as this many chunks have (about 1 KB per chunk row, within
#: :func:`~qdrefine.distributed.cluster.min_worker_memory`'s 2 KiB); the pieces
#: exchanged, one small task each, are this many times fewer than with a partition per
#: chunk, which on two workers cut a 2-level run by about a third (``docs/scale-out.md``).
EDGE_GROUP = 4


def _release(futures: Sequence) -> None:
    for future in futures:
        future.release()


def _bounds(n: int, chunk: int) -> list[tuple[int, int]]:
    """Row ranges ``[(start, stop)]`` of ``n`` rows in chunks of ``chunk``."""
    return [(a, min(n, a + chunk)) for a in range(0, n, chunk)]


def _divisions(ranges: Sequence[tuple[int, int]], per_row: int) -> tuple[int, ...]:
    """Dask divisions putting the values ``per_row * [start, stop)`` in one partition each."""
    return tuple(per_row * a for a, _ in ranges) + (per_row * ranges[-1][1] - 1,)


class _Job:
    """What the tasks of one level share: the source's, coordinates' and output's Zarr
    arrays, the scheme and the sizes. Plain (not a dataclass) so that Dask passes it as an
    opaque argument; its token is random (one per level)."""

    def __init__(self, src: mesh_store.MeshStore, sch: Scheme, coords: str,
                 next_coords: str | None) -> None:
        import os

        import zarr

        group = zarr.open_group(src.path, mode="r")
        self.src = {name: group[name] for name in mesh_store.ARRAYS if name in group}
        self.out: dict[str, Any] = {}
        self.path, self.scheme = src.path, sch.name
        self.n, self.m, self.n_out = src.n_points, src.n_triangles, 0
        self.k, self.children = sch.stencil.per_edge, sch.n_children
        self.chunk = int(self.src["triangles"].chunks[0])
        self.n_chunks = -(-self.m // self.chunk)
        self.coords_url, self.next_coords_url = coords, next_coords
        self.coords: Any = None
        self.next_coords: Any = None
        self.level = 1
        self.origin = src.path
        self.token = os.urandom(16).hex()

    def __dask_tokenize__(self) -> str:
        return self.token


def _coords_array(url: str, m: int, chunk: int, create: bool):
    import zarr

    if create:
        return zarr.create_array(url, shape=(m, 3, 2), chunks=(chunk, 3, 2), dtype=np.float64,
                                 fill_value=np.nan, compressors=None)
    return zarr.open_array(url, mode="r")


class _Direct(list):
    """The edge partitions' futures when their results go back directly (not shuffled);
    ``inverses``: for every triangle chunk, the future of the index of each of its
    half-edges among its sorted distinct edges (:func:`_edge_pieces`), kept for its
    emission."""

    inverses: list | tuple = ()


class Level:
    """One level of refinement of ``src`` into a new (incomplete) store at ``out``; the
    run's first source is ``origin`` (``src`` at ``level`` 1), which refusals name.

    ``coords`` is the URL of the Zarr array of corner coordinates; from ``level`` 2 on it
    is already written (by the previous level's emission). With ``next_coords``, the
    emission writes the children's corner coordinates there.
    """

    def __init__(self, client: Client, src: mesh_store.MeshStore, sch: Scheme, out: str,
                 coords: str, next_coords: str | None, level: int,
                 metadata: dict[str, Any], report: cluster.Reporter,
                 timeouts: dict[str, float], origin: mesh_store.MeshStore) -> None:
        coords_ready = level > 1
        self.client, self.src, self.sch, self.out = client, src, sch, out
        self.coords_ready, self.metadata, self.report = coords_ready, metadata, report
        self.timeouts = timeouts
        if src.n_points > MAX_POINTS:
            raise ValueError(f"{report.prefix}{src.n_points} points; distributed refinement "
                             f"handles at most {MAX_POINTS} per level (int64 edge keys)")
        job = self.job = _Job(src, sch, coords, next_coords)
        job.level, job.origin = level, origin.path
        #: The refusal of a point below the coordinate range, raised by the run once every
        #: level is done (in memory: after the last level), None if there is none.
        self.below_range: ValueError | None = None
        #: The refusal of an edge of more than two triangles, or of two on one side of it
        #: (:func:`_misused`), raised after the emission's clockwise triangles, as in memory.
        self.misused: ValueError | None = None
        job.coords = _coords_array(coords, job.m, job.chunk, not coords_ready)
        if next_coords is not None:
            job.next_coords = _coords_array(next_coords, job.m * job.children, job.chunk, True)
        self.tri_ranges = _bounds(src.n_triangles, job.chunk)
        e = job.src.get("edges")
        self.edge_ranges = _bounds(src.n_edges, int(e.chunks[0])) if src.n_edges else []

    def run(self) -> None:
        import dask

        with dask.config.set({"dataframe.convert-string": False,
                              "dataframe.shuffle.method": "p2p"}):
            if not self.coords_ready:
                self.report.stage("corner coordinates")
                self._corners()
            self.report.stage("edge ids in sorted order and new points")
            numbered, counts = self._edges()
            self.direct_back = isinstance(numbered, _Direct)
            self.report.stage("emission of the children, written chunk by chunk")
            try:
                self._emit(numbered, counts)
                self._check_boundary(numbered, counts)
            finally:  # the partitions' results are no longer needed (nor recomputed)
                _release([*numbered, *getattr(numbered, "inverses", [])])

    def _compute(self, tasks: list, keep: bool = False) -> list:
        return cluster.compute(self.client, tasks, keep=keep, **self.timeouts)

    def _corners(self) -> None:
        """Stage 1: the Zarr array ``coords (M, 3, 2)``."""
        import dask.dataframe as dd
        from dask import delayed

        job = self.job
        p_ranges = _bounds(self.src.n_points, int(job.src["points"].chunks[0]))
        if len(p_ranges) * len(self.tri_ranges) <= DIRECT_PIECES:
            self._corners_direct(p_ranges)
            return
        points = dd.from_map(_points_frame, p_ranges, job=job, meta=_meta("x", "y"),
                             divisions=_divisions(p_ranges, 1))
        corners = dd.from_map(_corners_frame, self.tri_ranges, job=job,
                              meta=_meta("h", "v", ints=2))
        joined = corners.merge(points, left_on="v", right_index=True, how="inner")
        by_tri = joined[["h", "x", "y"]].set_index("h", divisions=_divisions(self.tri_ranges, 3))
        write = delayed(_write_coords, pure=False)
        self._compute([write(part, job, a, b) for part, (a, b)
                       in zip(by_tri.to_delayed(), self.tri_ranges, strict=True)])

    def _corners_direct(self, p_ranges: list[tuple[int, int]]) -> None:
        """Stage 1 without a shuffle: each triangle chunk asks each points chunk for the
        coordinates of its vertices there, and writes its corners."""
        from dask import delayed

        job = self.job
        starts = np.array([a for a, _ in p_ranges[1:]], dtype=np.int64)
        ask = delayed(_vertex_requests, pure=False, nout=len(p_ranges))
        asks = [ask(r, job, starts) for r in self.tri_ranges]
        answer = delayed(_answer_points, pure=False, nout=len(self.tri_ranges))
        answers = [answer([q[i] for q in asks], job, a, b) for i, (a, b) in enumerate(p_ranges)]
        write = delayed(_write_coords_direct, pure=False)
        self._compute([write([r[j] for r in answers], job, a, b)
                       for j, (a, b) in enumerate(self.tri_ranges)])

    def _splitters(self, n_parts: int) -> tuple[int, ...]:
        """Divisions of the edge keys: vertex boundaries ``V_i`` (as keys ``V_i N``) that
        give every partition about the same number of half-edges."""
        from dask import delayed

        job = self.job
        hist = delayed(_lo_histogram, pure=False)
        parts = [hist(r, job) for r in self.tri_ranges]
        while len(parts) > 1:  # a tree sum: the client receives one histogram
            parts = [delayed(np.add)(*parts[i:i + 2]) if i + 1 < len(parts) else parts[i]
                     for i in range(0, len(parts), 2)]
        counts = self._compute(parts)[0]
        bins = len(counts)
        cum = np.cumsum(counts)
        cuts = np.searchsorted(cum, cum[-1] * np.arange(1, n_parts) / n_parts, side="right")
        vertices = -(-(cuts.astype(np.int64) * job.n) // bins)  # first vertex of bin `cut`
        vertices = np.unique(vertices[(vertices > 0) & (vertices < job.n)])
        return (0, *(int(v) * job.n for v in vertices), job.n * job.n - 1)

    def _edges(self) -> tuple[list, NDArray[np.int64]]:
        """Stage 2: number the edges per key range; returns the partitions' results (held
        by the workers: count, new points, rows back) and the edges per partition."""
        import dask.dataframe as dd
        from dask import delayed

        job = self.job
        # direct: one partition per EDGE_GROUP chunks (fewer pieces, one task each); the
        # shuffle's cost does not grow with the pieces: one partition per chunk (less memory)
        grouped = -(-len(self.tri_ranges) // EDGE_GROUP) or 1
        if (job.n_chunks + len(self.edge_ranges)) * grouped <= DIRECT_PIECES:
            return self._edges_direct(self._splitters(grouped))
        divisions = self._splitters(max(1, len(self.tri_ranges)))
        meta = _meta("key", "j", "lone", "xlo", "ylo", "xhi", "yhi", ints=3)
        rows = dd.from_map(_edge_frame, list(enumerate(self.tri_ranges)), job=job, meta=meta)
        if self.edge_ranges:
            items = [(job.n_chunks + i, r) for i, r in enumerate(self.edge_ranges)]
            rows = dd.concat([rows, dd.from_map(_tagged_frame, items, job=job, meta=meta)])
        parts = rows.set_index("key", divisions=divisions, sort=True).to_delayed()
        number = delayed(_number_edges, pure=False)
        futures = self._compute([number(part, job, p) for p, part in enumerate(parts)],
                                keep=True)
        return futures, self._counts(futures, futures)

    def _edges_direct(self, divisions: tuple[int, ...]) -> tuple[list, NDArray[np.int64]]:
        """Stage 2 without a shuffle: every chunk cuts its sorted distinct keys at the
        divisions, and partition ``p`` receives piece ``p`` of every chunk."""
        from dask import delayed

        job = self.job
        cuts = np.array(divisions[1:-1], dtype=np.int64)
        n_parts = len(divisions) - 1
        pieces = delayed(_edge_pieces, pure=False, nout=n_parts + 1)
        sources = [pieces(r, job, cuts) for r in self.tri_ranges]
        inverses = [src[n_parts] for src in sources]
        tagged = delayed(_tagged_pieces, pure=False, nout=n_parts)
        sources += [tagged(r, job, cuts) for r in self.edge_ranges]
        number = delayed(_number_pieces, pure=False)
        futures = self._compute([number([src[p] for src in sources], job)
                                 for p in range(n_parts)] + inverses, keep=True)
        numbered = _Direct(futures[:n_parts])
        numbered.inverses = futures[n_parts:]
        return numbered, self._counts(numbered, futures)

    def _counts(self, numbered: list, kept: list) -> NDArray[np.int64]:
        """The partitions' numbers of edges (and :attr:`misused`); the ``kept`` futures are
        released if this fails (e.g. on Ctrl-C), as :meth:`run` does once they have
        served."""
        try:
            results = self.client.gather(self.client.map(_count, numbered, pure=False))
        except BaseException:
            _release(kept)
            raise
        misused = [m for _, m in results if m is not None]
        if misused:  # the smallest key: the same edge whatever the partitions
            key, total = min(misused)
            edge = (key // self.job.n, key % self.job.n)
            self.misused = ValueError(
                f"{self.job.path}: edge {edge} is shared by {total} triangles; at most two "
                "may share an edge" if total > 2 else f"{self.job.path}: the two triangles "
                f"of edge {edge} lie on the same side of it: they overlap")
        return np.asarray([count for count, _ in results], dtype=np.int64)

    def _emit(self, numbered: list, counts: NDArray[np.int64]) -> None:
        """Stage 3: triangles, cell tags, tagged edges and points of the output store."""
        from dask import delayed

        job = self.job
        job.n_out = job.n + job.k * int(counts.sum())
        group = mesh_store.new_group(self.out, self._specs(job.n_out), self._chunks(),
                                     self.metadata)
        job.out = {name: group[name] for name in mesh_store.ARRAYS + mesh_store.NODE_COORDINATES
                   if name in group}
        offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        n_targets = job.n_chunks + len(self.edge_ranges)
        if self.direct_back:
            lids = delayed(_lids_for, pure=False)
            parts = [[lids(f, j) for f in numbered] for j in range(n_targets)]
        else:
            parts = self._back_shuffle(numbered, n_targets)
        emit_chunk = delayed(_emit_chunk, pure=False)
        inverses = getattr(numbered, "inverses", [None] * job.n_chunks)
        tasks = [emit_chunk(part, job, offsets, a, b, inverse) for part, (a, b), inverse
                 in zip(parts, self.tri_ranges, inverses, strict=False)]
        split = delayed(_split_chunk, pure=False)
        tasks += [split(part, job, offsets, a, b) for part, (a, b)
                  in zip(parts[job.n_chunks:], self.edge_ranges, strict=True)]
        # every chunk runs to its end: as in memory, a clockwise triangle (the input's
        # validation) is refused before any too thin one, and the first row wins; a point
        # below the coordinate range (class 2) is refused after every level, as in memory
        # (its row stays the same in the later levels' points)
        refusals = [r for r in self._compute(tasks + self._points_tasks(numbered, counts,
                                                                         offsets)) if r]
        # as in memory: a clockwise triangle, then an edge of more than two triangles or of
        # two on one side of it (the input's validation), then a too thin one
        now = sorted((r for r in refusals if r[0] < 2), key=lambda r: r[:2])
        if now and now[0][0] == 0:
            raise now[0][2]
        if self.misused is not None:
            raise self.misused
        if now:
            raise now[0][2]
        if refusals:
            self.below_range = min(refusals, key=lambda r: r[1])[2]

    def _check_boundary(self, numbered: list, counts: NDArray[np.int64]) -> None:
        """As :func:`qdrefine.uniform.check_boundary_rounding` in memory: the refined
        boundary, its new points rounded to float64, must not cross itself, hold a new
        point on another of its edges or cover an area twice; ``ValueError`` naming the
        same triangle as in memory otherwise. The edge partitions send their boundary
        edges (those of one half-edge in the mesh) with their new points; one plane sweep
        over them here (``O(B log B)`` for ``B`` boundary edges)."""
        job = self.job
        parts = self.client.gather(self.client.map(_boundary_of, numbered, pure=False))
        offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
        found = _crossing_row(parts, offsets, job.n, job.k)
        if found is not None:
            row, as_given = found
            raise _refused(job, row, _triangles(job, row, row + 1)[0],
                           _INVALID_BOUNDARY if as_given else too_close_reason(job.coords[row]))

    def _points_tasks(self, numbered: list, counts: NDArray[np.int64],
                      offsets: NDArray[np.int64]) -> list:
        """One task per chunk of the output's points (and ``node_x``, ``node_y``): the old
        points' rows it covers, read from the source, then the slices of the edge
        partitions' new points that fall into it (partition ``p``'s are rows
        ``n + k offset_p ..``)."""
        from dask import delayed

        job = self.job
        rows_of = delayed(_new_points_rows, pure=False)
        write = delayed(_write_points, pure=False)
        starts = job.n + job.k * offsets
        stops = starts + job.k * counts
        tasks = []
        for a, b in _bounds(job.n_out, int(job.out["points"].chunks[0])):
            parts: list = [(a, min(b, job.n))] if a < job.n else []
            for p in np.flatnonzero((starts < b) & (stops > a)):
                lo, hi = max(a, starts[p]) - starts[p], min(b, stops[p]) - starts[p]
                parts.append(rows_of(numbered[p], int(lo), int(hi)))
            tasks.append(write(parts, job, a, b))
        return tasks

    def _back_shuffle(self, numbered: list, n_targets: int) -> list:
        import dask.dataframe as dd
        from dask import delayed

        back = dd.from_delayed([delayed(_back_rows)(f) for f in numbered],
                               meta=_meta("j", "key", "p", "lid", ints=4), verify_meta=False)
        return back.set_index("j", divisions=(*range(n_targets), n_targets - 1)).to_delayed()

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


def copy_store(client: Client, src: mesh_store.MeshStore, out: str, metadata: dict[str, Any],
               timeouts: dict[str, float]) -> None:
    """``levels = 0``: the source's arrays into ``out``, chunk by chunk (``node_x`` and
    ``node_y`` from the source's ``points``: a source written before them has none), each
    block checked as every read checks it (:func:`qdrefine.store.reading.written`), not
    validated as a mesh."""
    import dask.array as da
    import zarr

    group = zarr.open_group(src.path, mode="r")
    names = [n for n in mesh_store.ARRAYS if n in group]
    # tags as int64 and indices as signed integers, as a refined level writes them (their
    # fill values, int64's smallest and -1, must fit: a uint64 source's did not)
    dtypes = {n: np.dtype(np.int64) if n.endswith("tags") else
              np.dtype(index_dtype(src.n_points)) if n in ("triangles", "edges") else
              group[n].dtype for n in names}
    specs = {n: (group[n].shape, dtypes[n]) for n in names}
    target = mesh_store.new_group(out, specs, {n: int(group[n].chunks[0]) for n in names},
                                  metadata)
    # checked as they are copied: the copy of a damaged store must not be marked complete
    sources = {n: da.from_array(_Rows(src.path, group[n], n), chunks=group[n].chunks,
                                asarray=False)
               .map_blocks(_checked_block, src.path, src.n_points, n, dtypes[n],
                           dtype=dtypes[n])
               for n in names}
    sources |= mesh_store.node_coordinates(sources["points"])
    cluster.compute(client, [da.store(list(sources.values()), [target[n] for n in sources],
                                      lock=False, compute=False)], **timeouts)


class _Rows:
    """A stored array as Dask reads it, each slice through
    :func:`qdrefine.store.reading.read_rows` (a chunk that cannot be decoded is one line
    naming the store, the array and the rows, not the codec's traceback)."""

    def __init__(self, path: str, array, name: str) -> None:
        self.path, self.array, self.name = path, array, name
        self.shape, self.dtype, self.ndim = array.shape, array.dtype, array.ndim

    def __getitem__(self, index: tuple) -> NDArray:
        rows = index[0] if isinstance(index, tuple) else index
        start, stop, _ = rows.indices(self.shape[0])
        block = mesh_store.read_rows(self.path, self.array, self.name, start, stop)
        return block[(slice(None), *index[1:])] if isinstance(index, tuple) else block


def _checked_block(block: NDArray, path: str, n_points: int, name: str, dtype: np.dtype,
                   block_info: dict | None = None) -> NDArray:
    """A block of a source array, checked (:func:`qdrefine.store.reading.written`), as
    ``dtype``."""
    start = block_info[0]["array-location"][0][0] if block_info else 0
    return mesh_store.written(path, n_points, name, start, block).astype(dtype, copy=False)


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
    p = mesh_store.read_rows(job.path, job.src["points"], "points", a, b)
    try:
        check_coordinates(p)
    except ValueError as exc:  # the message names the row within the chunk: shift it
        row = re.match(r"point (\d+) (.*)", str(exc), re.DOTALL)
        where = f"point {a + int(row[1])} {row[2]}" if row else f"points {a}..{b - 1}: {exc}"
        raise ValueError(f"{job.path}: {where}") from None
    return pd.DataFrame({"x": p[:, 0], "y": p[:, 1]}, index=pd.RangeIndex(a, b))


def _triangles(job: _Job, a: int, b: int) -> NDArray[np.int64]:
    """Triangles ``a .. b - 1`` of the source, indices checked."""
    return _source(job, "triangles", a, b).astype(np.int64)


def _source(job: _Job, name: str, a: int, b: int) -> NDArray:
    """Rows ``a .. b - 1`` of the source's ``name`` array, refused where they hold the fill
    value of a chunk never written or, for tags, values beyond int64
    (:func:`qdrefine.store.reading.written`)."""
    block = mesh_store.read_rows(job.path, job.src[name], name, a, b)
    return mesh_store.written(job.path, job.n, name, a, block)


def _corners_frame(rows: tuple[int, int], job: _Job) -> pd.DataFrame:
    import pandas as pd

    a, b = rows
    t = _triangles(job, a, b)
    return pd.DataFrame({"h": np.arange(3 * a, 3 * b, dtype=np.int64), "v": t.ravel()})


def _in_order(index: NDArray, start: int, stop: int, what: str) -> None:
    """The shuffle put exactly the rows ``start .. stop - 1`` here, sorted (or it is a bug)."""
    if len(index) != stop - start or (len(index) and (index[0] != start or index[-1] != stop - 1)):
        raise RuntimeError(f"qdrefine internal error: {what} rows {start}..{stop - 1} arrived "
                           f"as {len(index)} rows")


def _vertex_requests(rows: tuple[int, int], job: _Job, starts: NDArray[np.int64]
                     ) -> list[NDArray[np.int64]]:
    """The distinct vertices of triangles ``rows``, sorted, cut at the points chunks'
    ``starts``: piece ``i`` goes to points chunk ``i``."""
    a, b = rows
    vertices = np.unique(_triangles(job, a, b))
    return np.split(vertices, np.searchsorted(vertices, starts))


def _answer_points(requests: list[NDArray[np.int64]], job: _Job, a: int, b: int
                   ) -> list[NDArray[np.float64]]:
    """Points chunk ``a .. b - 1`` (checked) answers every triangle chunk's request."""
    p = _points_frame((a, b), job)[["x", "y"]].to_numpy(np.float64)
    return [p[r - a] for r in requests]


def _write_coords_direct(answers: list[NDArray[np.float64]], job: _Job, a: int, b: int
                         ) -> None:
    t = _triangles(job, a, b)
    _, _, inverse = distinct(t.ravel())
    xy = np.concatenate(answers) if answers else np.empty((0, 2))
    job.coords[a:b] = xy[inverse.reshape(-1)].reshape(-1, 3, 2)


def _write_coords(part: pd.DataFrame, job: _Job, a: int, b: int) -> None:
    _in_order(part.index.to_numpy(), 3 * a, 3 * b, "corner")
    job.coords[a:b] = part[["x", "y"]].to_numpy(np.float64).reshape(-1, 3, 2)


def _lo_histogram(rows: tuple[int, int], job: _Job) -> NDArray[np.int64]:
    """Half-edges of triangles ``rows`` per bin of their smaller vertex."""
    a, b = rows
    t = _triangles(job, a, b)
    lo = np.minimum(t, np.roll(t, -1, axis=1)).ravel()
    bins = min(_BINS, job.n)
    return np.bincount(lo * bins // job.n, minlength=bins).astype(np.int64)


def _half_edges(t: NDArray[np.int64], n: int) -> tuple[NDArray, NDArray]:
    """``keys (C, 3)`` of the half-edges ``(v_i, v_{i+1})`` and whether each is walked from
    its larger vertex ``(C, 3) bool``."""
    t2 = np.roll(t, -1, axis=1)
    return np.minimum(t, t2) * n + np.maximum(t, t2), t > t2


def _distinct_edges(job: _Job, a: int, b: int, inverse: bool = False
                    ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray | None,
                               NDArray[np.int64]]:
    """The distinct edges of triangles ``a .. b - 1``: sorted keys ``(u,)``, the
    coordinates of the smaller and of the larger vertex ``(u, 4)``, if asked for, the
    index of each half-edge ``(v_i, v_{i+1})`` among the keys ``(3 (b - a),)`` (int32
    while it fits), and the edges' *lone* codes ``(u,)``: ``2 h + w`` for an edge of one
    half-edge ``h = 3 t + i`` here (``w`` = 1 where its triangle walks it from its larger
    vertex; for the boundary check, :func:`_lone_edges`), ``-(2 c + f)`` for an edge of
    ``c >= 2`` half-edges here, ``f`` = 1 unless they are two that walk it both ways (for
    :func:`_misused`)."""
    t = _triangles(job, a, b)
    xy = job.coords[a:b]
    if np.isnan(xy).any():  # unwritten chunk: a bug, never a wrong result
        raise RuntimeError(f"qdrefine internal error: corner coordinates of triangles "
                           f"{a}..{b - 1} are missing")
    key, from_larger = _half_edges(t, job.n)
    keys, one, back, count = distinct_counted(key.ravel())
    larger = np.bincount(back, weights=from_larger.ravel(), minlength=len(keys))
    lone = np.where(count == 1, 2 * (3 * a + one) + from_larger.ravel()[one],
                    -(2 * count + (2 * larger != count)))
    back = back.astype(index_dtype(len(keys))) if inverse else None
    return keys, edge_ends(t, xy, one), back, lone.astype(np.int64)


def _edge_frame(item: tuple[int, tuple[int, int]], job: _Job) -> pd.DataFrame:
    """The distinct edges of triangle chunk ``j``: key, ``j``, lone code, coordinates of
    the smaller and of the larger vertex."""
    import pandas as pd

    j, (a, b) = item
    keys, ends, _, lone = _distinct_edges(job, a, b)
    return pd.DataFrame({"key": keys, "j": np.full(len(keys), j, dtype=np.int64),
                         "lone": lone, "xlo": ends[:, 0], "ylo": ends[:, 1], "xhi": ends[:, 2],
                         "yhi": ends[:, 3]})


def _tagged_frame(item: tuple[int, tuple[int, int]], job: _Job) -> pd.DataFrame:
    """The distinct tagged edges of edge chunk ``j - n_chunks`` (no coordinates)."""
    import pandas as pd

    j, (a, b) = item
    e = _source(job, "edges", a, b).astype(np.int64)
    keys = np.unique(e.min(axis=1) * job.n + e.max(axis=1))
    nan = np.full(len(keys), np.nan)
    return pd.DataFrame({"key": keys, "j": np.full(len(keys), j, dtype=np.int64),
                         "lone": np.full(len(keys), -1, dtype=np.int64),
                         "xlo": nan, "ylo": nan, "xhi": nan, "yhi": nan})


def _edge_pieces(rows: tuple[int, int], job: _Job, cuts: NDArray[np.int64]) -> list:
    """:func:`_distinct_edges` of triangles ``rows``, cut at the partitions' keys: piece
    ``p`` is ``(keys, ends (u, 4), lone codes)`` of partition ``p``, keys sorted; then the
    index of every half-edge among the keys (for the chunk's emission)."""
    keys, ends, inverse, lone = _distinct_edges(job, *rows, inverse=True)
    at = np.searchsorted(keys, cuts)
    return [*zip(np.split(keys, at), np.split(ends, at), np.split(lone, at), strict=True),
            inverse]


def _tagged_pieces(rows: tuple[int, int], job: _Job, cuts: NDArray[np.int64]) -> list[tuple]:
    """The tagged edges' sorted distinct keys, cut as in :func:`_edge_pieces` (no ends)."""
    a, b = rows
    e = _source(job, "edges", a, b).astype(np.int64)
    keys = np.unique(e.min(axis=1) * job.n + e.max(axis=1))
    return [(k, None, None) for k in np.split(keys, np.searchsorted(keys, cuts))]


def _number_pieces(pieces: list[tuple], job: _Job
                   ) -> tuple[int, NDArray[np.float64], list[NDArray[np.int64]], tuple,
                              tuple[int, int] | None]:
    """Edge partition from the pieces of every triangle chunk, then every tagged edge
    chunk: its number of distinct edges, their new points, for every source the local ids
    of the keys it sent, in its order (-1: a tagged edge of no triangle), its boundary
    edges (:func:`_lone_edges`) and its first misused edge (:func:`_misused`)."""
    tri = [pc for pc in pieces if pc[1] is not None]  # the triangle chunks' come first
    keys = np.concatenate([k for k, _, _ in tri]) if tri else np.empty(0, dtype=np.int64)
    sizes = np.array([len(k) for k, _, _ in tri], dtype=np.int64)
    first, inverse = merge_sorted(keys, np.concatenate([[0], np.cumsum(sizes)]))
    unique = keys[first]
    ids = index_dtype(len(unique))
    lids = np.split(inverse.astype(ids), np.cumsum(sizes)[:-1]) if tri else []
    # each piece writes its edges' points at their places (an edge in two pieces twice,
    # the same bits): every piece is read in order, no copy of all the ends
    points = np.empty((len(unique) * job.k, 2), dtype=np.float64)
    for (_, ends, _), lid in zip(tri, lids, strict=True):
        new_points(ends, job.k, lid, points)
    # an edge sent by one piece only, from a chunk that holds one half-edge of it, is on
    # the boundary
    codes = np.concatenate([c for _, _, c in tri]) if tri else np.empty(0, dtype=np.int64)
    alone = (codes >= 0) & (np.bincount(inverse, minlength=len(unique))[inverse] == 1)
    masks = np.split(alone, np.cumsum(sizes)[:-1]) if tri else []
    ends = np.concatenate([e[m] for (_, e, _), m in zip(tri, masks, strict=True)]
                          or [np.empty((0, 4))])
    boundary = _lone_edges(codes[alone], unique, inverse[alone], ends, points, job.k)
    misused = _misused(unique, inverse, codes)
    for k, _, _ in pieces[len(tri):]:  # tagged edges: -1 where no triangle has the edge
        lid = np.searchsorted(unique, k)
        found = lid < len(unique)
        found[found] = unique[lid[found]] == k[found]
        lids.append(np.where(found, lid, -1).astype(ids))
    return len(unique), points, lids, boundary, misused


def _misused(keys: NDArray[np.int64], inverse: NDArray, codes: NDArray[np.int64]
             ) -> tuple[int, int] | None:
    """The first of an edge partition's sorted distinct ``keys`` that more than two
    half-edges use, or two that walk it the same way (their triangles overlap), as ``(key,
    half-edges)``; None if there is none. ``inverse``: each row's key; ``codes``: each
    row's lone code (:func:`_distinct_edges`; a duplicated triangle made such edges, and
    the refined store was marked complete)."""
    if not len(keys):
        return None
    lone = codes >= 0
    halves = np.where(lone, 1, -codes // 2)
    total = np.bincount(inverse, weights=halves, minlength=len(keys))
    bad = total > 2
    bad[inverse[~lone & (-codes % 2 == 1)]] = True
    # two lone half-edges (of two chunks) walking the edge the same way
    walked = np.bincount(inverse[lone], weights=codes[lone] & 1, minlength=len(keys))
    bad |= (np.bincount(inverse[lone], minlength=len(keys)) == 2) & (walked != 1)
    if not bad.any():
        return None
    i = int(np.argmax(bad))
    return int(keys[i]), int(total[i])


def _lone_edges(lone: NDArray, keys: NDArray[np.int64], lids: NDArray,
                ends: NDArray[np.float64], points: NDArray[np.float64], k: int) -> tuple:
    """An edge partition's boundary edges (of one half-edge in the whole mesh): their lone
    codes ``(B,)`` (:func:`_distinct_edges`), keys ``(B,)``, local ids ``(B,)``, ends
    ``(B, 4)`` and new points ``(B, k, 2)``, for :meth:`Level._check_boundary`."""
    return lone, keys[lids], lids, ends, points.reshape(-1, k, 2)[lids]


def _boundary_of(result: tuple) -> tuple:
    return result[3]


def _lids_for(result: tuple, j: int) -> NDArray[np.int64]:
    return result[2][j]


def _number_edges(part: pd.DataFrame, job: _Job, p: int
                  ) -> tuple[int, NDArray[np.float64], pd.DataFrame, tuple,
                             tuple[int, int] | None]:
    """Edge partition ``p`` (a range of keys, sorted): its number of distinct edges, their
    new points ``(u_p k, 2)``, the rows ``(j, key, p, local id)`` to send back (local id
    -1: a tagged edge of no triangle), its boundary edges (:func:`_lone_edges`) and its
    first misused edge (:func:`_misused`)."""
    import pandas as pd

    key = part.index.to_numpy(dtype=np.int64)
    j = part["j"].to_numpy(dtype=np.int64)
    tri = j < job.n_chunks
    keys, first, inverse, rows_per_edge = distinct_counted(key[tri])
    lid = np.searchsorted(keys, key)
    found = lid < len(keys)
    found[found] = keys[lid[found]] == key[found]
    lid = np.where(found, lid, -1)
    ends = part[["xlo", "ylo", "xhi", "yhi"]].to_numpy(dtype=np.float64)[tri][first]
    back = pd.DataFrame({"j": j, "key": key, "p": np.full(len(key), p, dtype=np.int64),
                         "lid": lid.astype(np.int64)})
    points = new_points(ends, job.k)
    codes = part["lone"].to_numpy(dtype=np.int64)[tri]
    lone = codes[first]
    on_boundary = np.flatnonzero((rows_per_edge == 1) & (lone >= 0))
    return len(keys), points, back, _lone_edges(lone[on_boundary], keys, on_boundary,
                                                ends[on_boundary], points, job.k), \
        _misused(keys, inverse, codes)


#: Why a triangle is refused whose boundary edge, as given, meets another part of the
#: boundary (the in-memory path refuses such meshes when it validates them, with the reason).
_INVALID_BOUNDARY = ("has a boundary edge that meets another part of the mesh's boundary, "
                     "before any refinement: the mesh overlaps itself, has a hanging node or "
                     "two points at one place there ('qdrefine convert STORE x.msh' and "
                     "'qdrefine check x.msh' name which)")


def _crossing_row(parts: list[tuple], offsets: NDArray[np.int64], n: int, k: int
                  ) -> tuple[int, bool] | None:
    """The row of the triangle refused by :func:`qdrefine.boundaries.first_bad_edge` on
    the boundary edges of the partitions ``parts`` (:func:`_lone_edges`, with ``offsets``,
    their first global edge ids) taken in the order of the triangles' half-edges, as in
    memory, and whether the boundary as given (without the new points) is refused already
    (then the row is that of its first refused edge: a mesh that is not valid, which this
    path does not validate as a whole); None where the refined boundary is sound."""
    if not parts:
        return None
    lone, keys, lids, ends, new = (np.concatenate(x) for x in zip(*parts, strict=True))
    p = np.repeat(np.arange(len(parts)), [len(x[0]) for x in parts])
    order = np.argsort(lone, kind="stable")
    lone, keys, gid = lone[order], keys[order], offsets[p[order]] + lids[order]
    ends, new = ends[order].reshape(-1, 2, 2), new[order]
    lo, hi = keys // n, keys % n
    walked = np.where((lone & 1)[:, None] == 1, np.stack([hi, lo], 1), np.stack([lo, hi], 1))
    pieces = edge_pieces(walked, gid, n, k).reshape(-1, 2)
    # the pieces' points, numbered in the order of their ids (which the sweep's choices
    # follow): the ends, then the new points as edge_pieces numbers them
    ids = np.concatenate([lo, hi, (n + gid[:, None] * k + np.arange(k)).ravel()])
    xy = np.concatenate([ends[:, 0], ends[:, 1], new.reshape(-1, 2)])
    unique, first = np.unique(ids, return_index=True)
    bad = first_bad_edge(xy[first], np.searchsorted(unique, pieces),
                         int(np.searchsorted(unique, n)))
    if bad is None:
        return None
    old = np.concatenate([lo, hi])
    unique, first = np.unique(old, return_index=True)
    given = first_bad_edge(np.concatenate([ends[:, 0], ends[:, 1]])[first],
                           np.searchsorted(unique, walked), len(unique))
    if given is not None:
        return int(lone[given] >> 1) // 3, True
    return int(lone[bad // (k + 1)] >> 1) // 3, False


def _count(result: tuple) -> tuple[int, tuple[int, int] | None]:
    """A partition's number of edges and its first misused edge (:func:`_misused`)."""
    return int(result[0]), result[4]


def _new_points_rows(result: tuple, lo: int, hi: int) -> NDArray[np.float64]:
    """Rows ``lo .. hi - 1`` of an edge partition's new points."""
    return result[1][lo:hi]


def _write_points(parts: list, job: _Job, a: int, b: int
                  ) -> tuple[int, int, ValueError] | None:
    """Rows ``a .. b - 1`` of the output's ``points``, ``node_x`` and ``node_y``: ``parts``
    are, in order, a range ``(start, stop)`` of the source's points and arrays of new
    points; and, where a point is below the coordinate range, 2 (a refusal after every
    level's others, as in memory), the row of the first and the ``ValueError`` naming it
    (written all the same, for the later levels)."""
    xy = np.concatenate([mesh_store.read_rows(job.path, job.src["points"], "points", *p)
                         if isinstance(p, tuple) else p
                         for p in parts])
    if len(xy) != b - a:
        raise RuntimeError(f"qdrefine internal error: {len(xy)} points for rows {a}..{b - 1}")
    size = np.abs(xy)
    low = ((size < COORDINATE_RANGE[0]) & (size != 0)).any(axis=1)
    job.out["points"][a:b] = xy
    for j, name in enumerate(mesh_store.NODE_COORDINATES):
        job.out[name][a:b] = xy[:, j]
    if low.any():  # as refine() in memory: the predicates are exact only in the range
        i = int(np.flatnonzero(low)[0])  # a row that the later levels keep
        return 2, a + i, ValueError(f"{job.origin}: {below_range(a + i, xy[i], None)}")
    return None


def _back_rows(result: tuple) -> pd.DataFrame:
    return result[2]


def _global_ids(part: pd.DataFrame | list, offsets: NDArray[np.int64],
                keys: NDArray[np.int64], inverse: NDArray | None = None
                ) -> NDArray[np.int64]:
    """The in-memory edge id of every key of ``keys`` (any shape), from the rows sent back
    (a frame after a shuffle, or the partitions' local ids of this chunk's sorted distinct
    keys, partition by partition, with ``inverse``, the index of each key among them, if
    known)."""
    if isinstance(part, list):
        lid = np.concatenate(part) if part else np.empty(0, dtype=np.int64)
        if inverse is None:
            values, _, inverse = distinct(keys.ravel())
            if len(lid) != len(values):
                raise RuntimeError("qdrefine internal error: edge ids did not come back")
        elif inverse.size != keys.size or (inverse.size and inverse.max() >= len(lid)):
            raise RuntimeError("qdrefine internal error: edge ids did not come back")
        p = np.repeat(np.arange(len(part)), [len(x) for x in part])
        gid = np.where(lid < 0, -1, offsets[p] + lid)
        return gid[inverse.reshape(keys.shape)]
    sent = part["key"].to_numpy(dtype=np.int64)
    gid = offsets[part["p"].to_numpy(dtype=np.int64)] + part["lid"].to_numpy(dtype=np.int64)
    order = np.argsort(sent, kind="stable")
    sent, gid = sent[order], gid[order]
    pos = np.minimum(np.searchsorted(sent, keys), max(len(sent) - 1, 0))
    if len(sent) == 0 or (sent[pos] != keys).any():
        raise RuntimeError("qdrefine internal error: an edge id did not come back")
    return np.where(part["lid"].to_numpy()[order][pos] < 0, -1, gid[pos])


def _emit_chunk(part: pd.DataFrame, job: _Job, offsets: NDArray[np.int64], a: int,
                b: int, inverse: NDArray | None = None) -> tuple[int, int, ValueError] | None:
    """Children of triangles ``a .. b - 1`` (rows ``a T .. b T - 1``), their cell tags and,
    with a next level, their corner coordinates (``inverse``: as for
    :func:`_global_ids`); or the first triangle refused: 0 (clockwise) or 1 (too thin),
    its row and why (nothing written)."""
    sch = get_scheme(job.scheme)
    k, tc = job.k, job.children
    t = _triangles(job, a, b)
    xy = job.coords[a:b].reshape(-1, 2)
    key, _ = _half_edges(t, job.n)
    gid = _global_ids(part, offsets, key, inverse)
    # renumber the chunk's vertices by rank: the kernel compares indices (a < b) only
    vertices, first, local = distinct(t.ravel())
    local = local.reshape(-1, 3).astype(np.int32)
    points = np.ascontiguousarray(xy[first])
    refused = _check_orientation(points, local, t, a, job.path)
    if refused:
        return refused
    u = len(vertices)
    children = np.empty((len(t) * tc, 3), dtype=index_dtype(u + k * (job.n_out - job.n)))
    with one_thread():
        suspect = emit(points, local, gid, k, sch.forms, sch.lut, sch.tables, children)
    refused = _check_rounding(job, a, t, points, local, gid, children, suspect) \
        if suspect.any() else None
    if refused:
        return refused
    glob = np.empty(children.shape, dtype=job.out["triangles"].dtype)
    global_children(children, vertices, job.n, glob)
    job.out["triangles"][a * tc:b * tc] = glob
    if "cell_tags" in job.out:
        job.out["cell_tags"][a * tc:b * tc] = np.repeat(_source(job, "cell_tags", a, b), tc)
    if job.next_coords is not None:
        job.next_coords[a * tc:b * tc] = child_coordinates(points, local, gid, children, k)


def _check_rounding(job: _Job, a: int, t: NDArray, points: NDArray, local: NDArray,
                    gid: NDArray, children: NDArray, suspect: NDArray[np.bool_]
                    ) -> tuple[int, int, ValueError] | None:
    """As :func:`qdrefine.uniform.check_rounding` in memory: the children of the parents at
    risk (``suspect``, from the kernel's certified bound) must be counter-clockwise with
    their new points rounded to float64; otherwise 1 (a rounding refusal), the first
    parent's row and the ``ValueError`` naming it."""
    tc = job.children
    rows = np.flatnonzero(np.repeat(suspect, tc))
    xy = child_coordinates(points, local[suspect], gid[suspect], children[rows],
                           job.k).reshape(-1, 2)
    signs = orient_signs(np.ascontiguousarray(xy), np.arange(len(xy)).reshape(-1, 3))
    bad = np.flatnonzero(signs <= 0)
    if bad.size:
        i = int(rows[bad[0]] // tc)
        what = "zero area" if signs[bad[0]] == 0 else "clockwise orientation"
        return 1, a + i, _refused(job, a + i, t[i], "is too thin for its distance from the "
                                  "origin: its new points rounded to float64 give a child "
                                  f"with {what}; translate the mesh nearer the origin or "
                                  "refine less")
    return None


def _refused(job: _Job, row: int, vertices: NDArray, reason: str) -> ValueError:
    """The refusal of triangle ``row`` (with ``vertices``) of this level's source, named as
    in memory (:meth:`qdrefine.uniform.RefusedTriangle.at_input`): by the run's source
    and, from level 2 on, by its triangle whose descendant it is."""
    named = f"{row} {tuple(int(v) for v in vertices)}"
    if job.level > 1:
        import zarr

        t = row // job.children ** (job.level - 1)
        first = zarr.open_group(job.origin, mode="r")["triangles"][t]
        named = (f"{t} {tuple(int(v) for v in first)} cannot be refined {job.level} levels: "
                 f"its descendant {named} of level {job.level - 1} (rows and points of that "
                 "level's mesh, from 0)")
    return ValueError(f"{job.origin}: triangle {named} {reason}")


def _check_orientation(points: NDArray, local: NDArray, t: NDArray, a: int, path: str
                       ) -> tuple[int, int, ValueError] | None:
    """The first triangle of the chunk that is not counter-clockwise: 0 (an input
    refusal), its row and the ``ValueError`` naming it; None if there is none."""
    signs = orient_signs(points, local)
    if (signs <= 0).any():
        i = int(np.flatnonzero(signs <= 0)[0])
        return 0, a + i, ValueError(f"{path}: {misoriented(a + i, t[i], signs[i] == 0)}")
    return None


def _split_chunk(part: pd.DataFrame, job: _Job, offsets: NDArray[np.int64], a: int,
                 b: int) -> None:
    """Tagged edges ``a .. b - 1`` as ``k + 1`` pieces each (rows ``a (k+1) ..``)."""
    k = job.k
    tagged = _source(job, "edges", a, b).astype(np.int64)
    lo, hi = tagged.min(axis=1), tagged.max(axis=1)
    gid = _global_ids(part, offsets, lo * job.n + hi)
    if (gid < 0).any():
        i = int(np.flatnonzero(gid < 0)[0])
        raise ValueError(f"{job.path}: edge {a + i} ({lo[i]}, {hi[i]}) is not an edge of any "
                         "triangle")
    # split_tagged_edges looks each edge up in a sorted edge list: give it these edges
    order = np.lexsort((hi, lo))
    pieces, tags = split_tagged_edges(tagged, _source(job, "edge_tags", a, b),
                                      np.stack([lo, hi], axis=1)[order], job.n, k,
                                      rank=gid[order])
    job.out["edges"][a * (k + 1):b * (k + 1)] = pieces
    job.out["edge_tags"][a * (k + 1):b * (k + 1)] = tags


