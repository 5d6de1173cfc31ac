"""GPU refinement benchmark: CPU (all cores) against the GPU (not part of the test suite).

For each size (millions of input triangles, default 2, 20 and 100) of the structured grid
:func:`qdrefine.examples.square` (vertices renumbered and triangles reordered at random with
``--shuffled``), one scheme (default 7T-QD) and ``--levels`` levels, it reports as a table
and, with ``--json FILE``, as JSON:

* the device's name and its measured write bandwidth (a kernel filling arrays the size of
  the output, best of ``--repeat``), and the time that bandwidth needs to write the output;
* GPU, device-resident: :func:`qdrefine.gpu.refine_device` on arrays already on the device,
  output left there (best of ``--repeat`` after one warm-up call that compiles the kernels):
  seconds, output triangles/s, and the fraction of the write bandwidth achieved (output
  bytes / time / bandwidth);
* GPU, host to host: ``refine(mesh, device="cuda")``, copies both ways included;
* CPU, all cores: ``refine(mesh)`` (numba's default thread count), and the speed-up;
* the GPU's time per pass (edge numbering, new points, decision and emission), the device
  synchronized between passes;
* whether the GPU output equals the CPU output bit for bit (points, triangles), and how many
  triangles needed the exact stage on the device;
* the load average before and after (other processes make times noisy).

Run on a machine with a CUDA GPU and ``pip install -e '.[gpu]'``:
``python benchmarks/gpu_bench.py --json benchmarks/results/gpu-DATE.json``.
Under numba's CUDA simulator (no GPU; a smoke test of the script only, the times mean
nothing): ``NUMBA_ENABLE_CUDASIM=1 python benchmarks/gpu_bench.py --sizes 0.0002 --repeat 1``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numba
import numpy as np
from numba import cuda

from qdrefine import Mesh, examples, get_scheme, refine
from qdrefine.gpu import refine_device
from qdrefine.gpu.refine import pass_times
from qdrefine.mesh import index_dtype


def grid(millions: float, shuffled: bool, seed: int = 0) -> Mesh:
    """The grid of :func:`qdrefine.examples.square` with about ``millions`` million
    triangles, built without the validation pass (it is valid by construction, and the
    validation of 100 M triangles would dominate the run)."""
    n = max(int(round(np.sqrt(millions * 1e6 / 2))), 1)
    points, _, (a, b, c, d) = examples._grid(n)
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    if shuffled:
        rng = np.random.default_rng(seed)
        perm = rng.permutation(len(points))
        triangles = np.argsort(perm)[triangles][rng.permutation(len(triangles))]
        points = points[perm]
    dtype = index_dtype(len(points))
    return Mesh._trusted(np.ascontiguousarray(points), np.ascontiguousarray(triangles,
                                                                            dtype=dtype))


def timed(f, repeat: int, sync: bool) -> tuple[float, object]:
    """Best wall time of ``repeat`` calls of ``f`` (device synchronized), and the last result."""
    times, out = [], None
    for _ in range(repeat):
        out = None  # free the previous output first
        if sync:
            cuda.synchronize()
        t0 = time.perf_counter()
        out = f()
        if sync:
            cuda.synchronize()
        times.append(time.perf_counter() - t0)
    return min(times), out


@cuda.jit
def _fill(points, triangles):
    i = cuda.grid(1)
    stride = cuda.gridsize(1)
    for j in range(i, points.shape[0], stride):
        points[j, 0] = 1.0
        points[j, 1] = 1.0
    for j in range(i, triangles.shape[0], stride):
        triangles[j, 0] = 1
        triangles[j, 1] = 1
        triangles[j, 2] = 1


def write_bandwidth(n_points: int, n_triangles: int, dtype, repeat: int) -> dict:
    """Bytes/s of a kernel writing arrays the size of the output, and its time."""
    points = cuda.device_array((n_points, 2), dtype=np.float64)
    triangles = cuda.device_array((n_triangles, 3), dtype=dtype)
    blocks = min(max((max(n_points, n_triangles) + 255) // 256, 1), 65536)
    seconds, _ = timed(lambda: _fill[blocks, 256](points, triangles), repeat, True)
    nbytes = points.nbytes + triangles.nbytes
    return {"bytes": int(nbytes), "seconds": seconds, "bytes_per_s": nbytes / seconds}


def device_name() -> str:
    if cuda.is_available() and not numba.config.ENABLE_CUDASIM:
        name = cuda.get_current_device().name
        return name.decode() if isinstance(name, bytes) else str(name)
    return "numba CUDA simulator (no GPU: times are meaningless)"


def run_size(millions: float, scheme: str, levels: int, shuffled: bool, repeat: int) -> dict:
    mesh = grid(millions, shuffled)
    sch = get_scheme(scheme)
    out_triangles = mesh.n_triangles * sch.n_children ** levels
    row = {"millions": millions, "n_triangles": mesh.n_triangles, "n_points": mesh.n_points,
           "out_triangles": out_triangles}

    refine(grid(0.001, shuffled), sch, levels)  # load the CPU kernels from numba's cache
    t_cpu, cpu = timed(lambda: refine(mesh, sch, levels), repeat, False)
    row["cpu_s"] = t_cpu
    row["cpu_threads"] = numba.get_num_threads()
    out_bytes = cpu.points.nbytes + cpu.triangles.nbytes
    row["out_bytes"] = int(out_bytes)
    row["out_points"] = cpu.n_points
    out_dtype = cpu.triangles.dtype

    d_points = cuda.to_device(mesh.points)
    d_triangles = cuda.to_device(mesh.triangles)
    refine_device(d_points, d_triangles, sch, levels)  # compile the kernels
    t_dev, dev = timed(lambda: refine_device(d_points, d_triangles, sch, levels), repeat, True)
    row["gpu_device_s"] = t_dev
    row["gpu_passes_s"] = min((pass_times(d_points, d_triangles, sch) for _ in range(repeat)),
                              key=lambda p: sum(p.values()))
    row["exact_stage"] = list(dev.exact_stage)
    row["identical"] = bool(np.array_equal(dev.points.copy_to_host(), cpu.points)
                            and np.array_equal(dev.triangles.copy_to_host(), cpu.triangles))
    del dev, cpu
    t_host, _ = timed(lambda: refine(mesh, sch, levels, device="cuda"), repeat, True)
    row["gpu_host_s"] = t_host

    bw = write_bandwidth(row["out_points"], out_triangles, out_dtype, repeat)
    row["write_bandwidth"] = bw
    for key in ("cpu_s", "gpu_device_s", "gpu_host_s"):
        row[key.replace("_s", "_triangles_per_s")] = out_triangles / row[key]
    row["gpu_device_fraction_of_write_bandwidth"] = out_bytes / t_dev / bw["bytes_per_s"]
    row["gpu_host_fraction_of_write_bandwidth"] = out_bytes / t_host / bw["bytes_per_s"]
    row["speedup_device_vs_cpu"] = t_cpu / t_dev
    row["speedup_host_vs_cpu"] = t_cpu / t_host
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="2,20,100", help="input sizes in millions of triangles")
    ap.add_argument("--scheme", default="7t-qd")
    ap.add_argument("--levels", type=int, default=1)
    ap.add_argument("--shuffled", action="store_true", help="random vertex and triangle order")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", help="write the results to this JSON file")
    args = ap.parse_args()
    result = {"device": device_name(), "scheme": args.scheme, "levels": args.levels,
              "shuffled": args.shuffled, "load_before": os.getloadavg(),
              "cpu_count": os.cpu_count(), "python": sys.version.split()[0],
              "numba": numba.__version__, "sizes": []}
    print(f"device: {result['device']}; CPU: {os.cpu_count()} cores, "
          f"{numba.get_num_threads()} numba threads")
    print(f"{'M in':>8} {'M out':>9} {'CPU s':>8} {'GPU dev s':>10} {'GPU h2h s':>10} "
          f"{'dev Gtri/s':>10} {'of write bw':>11} {'x CPU':>6} {'same':>5}")
    for size in (float(s) for s in args.sizes.split(",")):
        row = run_size(size, args.scheme, args.levels, args.shuffled, args.repeat)
        result["sizes"].append(row)
        print(f"{row['n_triangles'] / 1e6:8.3f} {row['out_triangles'] / 1e6:9.3f} "
              f"{row['cpu_s']:8.4f} {row['gpu_device_s']:10.4f} {row['gpu_host_s']:10.4f} "
              f"{row['gpu_device_triangles_per_s'] / 1e9:10.3f} "
              f"{row['gpu_device_fraction_of_write_bandwidth']:11.1%} "
              f"{row['speedup_device_vs_cpu']:6.1f} {str(row['identical']):>5}")
        print("         GPU passes (s): " + ", ".join(f"{name} {t:.4f}" for name, t in
                                                   row["gpu_passes_s"].items()))
    result["load_after"] = os.getloadavg()
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(result, fh, indent=1)


if __name__ == "__main__":
    main()
