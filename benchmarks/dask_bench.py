"""Scale-out benchmark: refine a mesh store on a local Dask cluster whose workers have
much less memory than the refined mesh (not part of the test suite).

Builds a jittered grid of about ``--triangles`` triangles (random diagonals, shuffled vertex
numbering, cell tags 0/1, tagged boundary edges), stores it in chunks of ``--chunk`` rows,
and for each worker count of ``--workers`` starts a local cluster of that many single-thread
worker processes with ``--memory`` each, then runs
:func:`qdrefine.distributed.refine_store` for ``--levels`` levels. Reported per run:

* wall time (per level and per stage), after a warm-up run that loads the compiled kernels
  in every worker;
* peak resident memory of every worker process (sampled every 0.2 s with psutil) against
  its limit; Dask's spill (bytes written to disk by the workers' spill buffers) and every
  byte the worker processes wrote (output, scratch, shuffle buffers, spill);
* the machine's 1-minute load average during the run (mean, max): other work on a shared
  machine slows a run down;
* the size of the refined mesh as arrays (what ``qdrefine.refine`` would hold in memory)
  and on disk, and its ratio to the memory of all workers;
* a check: exact point and triangle counts (from the input's edge count), and for a random
  sample of input triangles, the rows of their descendants equal bit for bit the in-memory
  ``qdrefine.refine`` of that triangle alone (coordinates and cell tags);
* with ``--baseline`` (meshes that fit in memory): the in-memory **store-to-store** time of
  the same refinement in the same run (``store.to_mesh``, ``qdrefine.refine``,
  ``store.create`` with the same chunks, on all cores), the ratio of each Dask run to it,
  and the check that the Dask output equals the in-memory one array by array, bit for bit.

Run: ``python benchmarks/dask_bench.py --triangles 6.3e6 --levels 2 --workers 2,1
--memory 1GiB --dir /scratch/qd --json benchmarks/results/dask-DATE.json``, or for the
comparison with in-memory refinement ``--triangles 2e6 --workers 2 --memory 4GiB
--chunk 262144 --baseline``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

import qdrefine
from qdrefine import Mesh, examples, store
from qdrefine.distributed import local_client, refine_store
from qdrefine.kernels import number_edges


def jittered_grid(n_triangles: float, seed: int = 0, shuffle: str = "points") -> Mesh:
    """About ``n_triangles`` of :func:`qdrefine.examples.jittered_square`; ``shuffle``:
    ``"points"`` shuffles the vertex numbering (triangles in grid order), ``"none"`` keeps
    the grid's numbering (spatially local)."""
    n = max(1, int(round(np.sqrt(n_triangles / 2))))
    return examples.jittered_square(n, seed, shuffle=shuffle)


def expected_counts(mesh: Mesh, scheme: str, levels: int) -> tuple[int, int]:
    """Points and triangles after ``levels`` uniform levels: ``V += k E``, ``E = (k + 1) E +
    I F`` and ``F *= T`` with ``I`` interior edges per child set (6 for 7T, 3 for 4T)."""
    sch = qdrefine.get_scheme(scheme)
    k, t = sch.stencil.per_edge, sch.n_children
    inner = (3 * t - 3 * (k + 1)) // 2
    v, e, f = mesh.n_points, len(number_edges(mesh.triangles, mesh.n_points)[0]), mesh.n_triangles
    for _ in range(levels):
        v, e, f = v + k * e, (k + 1) * e + inner * f, t * f
    return v, f


def check_sample(mesh: Mesh, out: store.MeshStore, scheme: str, levels: int,
                 size: int, seed: int = 1) -> int:
    """Compare the descendants of ``size`` random input triangles with the in-memory
    refinement of each triangle alone; returns the number compared (raises if different)."""
    import zarr

    group = zarr.open_group(out.path, mode="r")
    points, triangles, tags = group["points"], group["triangles"], group["cell_tags"]
    per = qdrefine.get_scheme(scheme).n_children ** levels
    rng = np.random.default_rng(seed)
    for t in rng.choice(mesh.n_triangles, size=min(size, mesh.n_triangles), replace=False):
        alone = qdrefine.refine(Mesh(mesh.points[mesh.triangles[t]], [[0, 1, 2]]), scheme,
                                levels)
        rows = triangles[t * per:(t + 1) * per].astype(np.int64)
        used, local = np.unique(rows, return_inverse=True)
        xy = points.get_orthogonal_selection((used, slice(None)))[local.reshape(rows.shape)]
        if not np.array_equal(xy, alone.points[alone.triangles]):
            raise AssertionError(f"descendants of triangle {t} differ from refine()")
        if not (tags[t * per:(t + 1) * per] == mesh.cell_tags[t]).all():
            raise AssertionError(f"cell tags of the descendants of triangle {t} differ")
    return min(size, mesh.n_triangles)


class MemorySampler:
    """Peak RSS of some processes and the machine's 1-minute load average, sampled every
    ``interval`` seconds in a thread (the machine may be shared: the load says how much)."""

    def __init__(self, pids: list[int], interval: float = 0.2) -> None:
        import psutil

        self.procs = {pid: psutil.Process(pid) for pid in pids}
        self.peak = dict.fromkeys(pids, 0)
        self.load: list[float] = []
        self.interval = interval
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            self.load.append(os.getloadavg()[0])
            for pid, proc in self.procs.items():
                try:
                    self.peak[pid] = max(self.peak[pid], proc.memory_info().rss)
                except Exception:  # noqa: BLE001 (a worker restarted: keep sampling others)
                    pass
            self._stop.wait(self.interval)

    def __enter__(self) -> MemorySampler:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def _worker_io(dask_worker) -> dict:
    import psutil

    io = psutil.Process().io_counters()
    spill = {f"{k[0]}-{k[1]}": v for k, v in dask_worker.data.cumulative_metrics.items()}
    return {"pid": os.getpid(), "write_bytes": io.write_bytes, "spill": spill}


def array_bytes(s: store.MeshStore) -> int:
    arrays = (s.points, s.triangles, s.cell_tags, s.edges, s.edge_tags)
    return int(sum(a.nbytes for a in arrays if a is not None))


def disk_bytes(path: Path) -> int:
    return int(subprocess.run(["du", "-sb", str(path)], capture_output=True, text=True,
                              check=True).stdout.split()[0])


def baseline(args: argparse.Namespace, source: str) -> dict:
    """In-memory store-to-store refinement of ``source``: read, refine, write."""
    target = args.dir / "in-memory.zarr"
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    mesh = store.to_mesh(source)
    t1 = time.perf_counter()
    fine = qdrefine.refine(mesh, args.scheme, args.levels)
    t2 = time.perf_counter()
    store.create(target, fine, chunk_size=args.chunk)
    t3 = time.perf_counter()
    return {"seconds": t3 - t0, "read_seconds": t1 - t0, "refine_seconds": t2 - t1,
            "write_seconds": t3 - t2, "load_average_1min": [load, os.getloadavg()[0]],
            "numba_threads": _numba_threads(),
            "target": str(target)}


def identical(a: str, b: str) -> bool:
    """Whether two stores hold the same arrays, bit for bit (loaded one array at a time)."""
    import zarr

    ga, gb = zarr.open_group(a, mode="r"), zarr.open_group(b, mode="r")
    for name in store.ARRAYS:
        if (name in ga) != (name in gb):
            return False
        if name in ga:
            x, y = ga[name][...], gb[name][...]
            if x.dtype != y.dtype or not np.array_equal(x, y):
                return False
    return True


def run(args: argparse.Namespace, mesh: Mesh, source: Path, workers: int) -> dict:
    work = args.dir / f"dask-{workers}"
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    client = local_client(n_workers=workers, memory_limit=args.memory, processes=True,
                          local_directory=str(work), dashboard_address=None)
    try:
        memory_limit = min(w["memory_limit"] for w in client.scheduler_info()["workers"].values())
        t0 = time.perf_counter()  # warm-up: every worker loads the compiled kernels
        warm = store.create(work / "warm.zarr", jittered_grid(2000), chunk_size=500)
        refine_store(warm.path, work / "warm-out.zarr", args.scheme, 2, client=client)
        warm_seconds = time.perf_counter() - t0
        before = client.run(_worker_io)
        stages: list[tuple[float, str]] = []

        def progress(text: str, done: int, total: int) -> None:
            stages.append((time.perf_counter(), text))
            print(f"  [{workers} workers] {time.strftime('%H:%M:%S')} {done}/{total} {text}",
                  flush=True)

        target = work / "out.zarr"
        with MemorySampler([info["pid"] for info in before.values()]) as sampler:
            summary = refine_store(source, target, args.scheme, args.levels, client=client,
                                   progress=progress)
        after = client.run(_worker_io)
    finally:
        client.close()
    out = store.open(target)
    checked = check_sample(mesh, out, args.scheme, args.levels, args.sample)
    n_points, n_triangles = expected_counts(mesh, args.scheme, args.levels)
    if (out.n_points, out.n_triangles) != (n_points, n_triangles):
        raise AssertionError(f"counts {(out.n_points, out.n_triangles)} != expected "
                             f"{(n_points, n_triangles)}")
    out_bytes = array_bytes(out)
    same = identical(out.path, args.baseline_target) if args.baseline_target else None
    result = {
        "identical_to_in_memory": same,
        "workers": workers,
        "memory_limit_per_worker": memory_limit,
        "seconds": summary.seconds,
        "level_seconds": list(summary.level_seconds),
        "stage_seconds": [[text, round(t1 - t0_, 2)] for (t0_, text), (t1, _)
                          in zip(stages, stages[1:], strict=False)],
        "warm_up_seconds": warm_seconds,
        "output_triangles": out.n_triangles,
        "output_points": out.n_points,
        "output_triangles_per_second": out.n_triangles / summary.seconds,
        "output_array_bytes": out_bytes,
        "output_disk_bytes": disk_bytes(target),
        "output_over_total_worker_memory": out_bytes / (memory_limit * workers),
        "peak_worker_rss": sorted(sampler.peak.values(), reverse=True),
        "peak_worker_rss_over_limit": max(sampler.peak.values()) / memory_limit,
        "worker_write_bytes": [after[w]["write_bytes"] - before[w]["write_bytes"]
                               for w in before],
        "spill": [{k: v - before[w]["spill"].get(k, 0) for k, v in after[w]["spill"].items()}
                  for w in before],
        "load_average_1min": {"mean": float(np.mean(sampler.load)),
                              "max": float(np.max(sampler.load))},
        "checked_parents": checked,
        "counts_exact": True,
    }
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--triangles", type=float, default=6.3e6)
    parser.add_argument("--levels", type=int, default=2)
    parser.add_argument("--scheme", default="7t-qd")
    parser.add_argument("--workers", default="2,1")
    parser.add_argument("--memory", default="1GiB", help="memory limit per worker")
    parser.add_argument("--chunk", type=int, default=1 << 17, help="rows per chunk")
    parser.add_argument("--sample", type=int, default=300, help="input triangles checked")
    parser.add_argument("--dir", type=Path, default=Path("dask-bench"))
    parser.add_argument("--keep", action="store_true", help="keep the refined stores")
    parser.add_argument("--json", type=Path)
    parser.add_argument("--order", choices=("shuffled", "grid"), default="shuffled",
                        help="vertex numbering of the input: shuffled (default) or the grid's "
                             "own, spatially local one")
    parser.add_argument("--baseline", action="store_true",
                        help="also time the in-memory store-to-store refinement and compare")
    args = parser.parse_args(argv)
    args.baseline_target = None
    args.dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    mesh = jittered_grid(args.triangles, shuffle="points" if args.order == "shuffled" else "none")
    source = store.create(args.dir / "input.zarr", mesh, chunk_size=args.chunk).path
    print(f"input: {mesh} in chunks of {args.chunk} ({time.perf_counter() - t0:.1f} s)")
    report = {
        "command": " ".join([Path(sys.argv[0]).name] + (argv or sys.argv[1:])),
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                    "memory_bytes": _total_memory(), "load_average_start": os.getloadavg()},
        "versions": _versions(),
        "code": {"qdrefine": str(Path(qdrefine.__file__).parent), "git_head": _git_head()},
        "input": {"triangles": mesh.n_triangles, "points": mesh.n_points, "order": args.order,
                  "tagged_edges": len(mesh.edges), "chunk": args.chunk},
        "scheme": args.scheme, "levels": args.levels, "runs": [],
    }
    if args.baseline:
        report["in_memory"] = baseline(args, source)
        args.baseline_target = report["in_memory"]["target"]
        print(f"in memory, store to store: {report['in_memory']['seconds']:.1f} s", flush=True)
    for workers in (int(w) for w in args.workers.split(",")):
        result = run(args, mesh, source, workers)
        if args.baseline:
            result["over_in_memory"] = result["seconds"] / report["in_memory"]["seconds"]
        report["runs"].append(result)
        print(json.dumps(result, indent=1), flush=True)
        if args.json:  # after every run: a long benchmark keeps what it measured
            report["machine"]["load_average_end"] = os.getloadavg()
            args.json.write_text(json.dumps(report, indent=1) + "\n")
    return 0


def _numba_threads() -> int:
    import numba

    return int(numba.get_num_threads())


def _git_head() -> str | None:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                              cwd=Path(__file__).parent, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def _total_memory() -> int:
    import psutil

    return int(psutil.virtual_memory().total)


def _versions() -> dict:
    import dask
    import distributed
    import numba
    import pandas
    import zarr

    return {"qdrefine": qdrefine.__version__, "python": platform.python_version(),
            "numpy": np.__version__, "numba": numba.__version__, "dask": dask.__version__,
            "distributed": distributed.__version__, "pandas": pandas.__version__,
            "zarr": zarr.__version__}


if __name__ == "__main__":
    sys.exit(main())
