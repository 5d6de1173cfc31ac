"""Command-line benchmark: ``qdrefine refine`` on a 1M-triangle file (not part of the tests).

For each case (text Gmsh ``.msh``, binary ``.msh`` with ``--binary``, VTK XML ``.vtu``) it
writes the input (about 1M triangles, shuffled numbering) in that format, then

* runs ``qdrefine refine IN OUT --quiet`` as a subprocess: the **total wall time** a user
  waits, interpreter start and imports included;
* runs the same command in a child process through ``qdrefine.cli.main`` with timers around
  the three steps of ``qdrefine.cli.refine`` (``read``, ``refine``, ``write``): the split.
  ``start-up`` is the rest of the subprocess's wall time (interpreter, imports, kernels
  loaded from numba's cache).

It also times the construction (validation) of a ``Mesh`` of that size from its arrays.
Prints a table and writes JSON (``--json FILE``; default
``benchmarks/results/cli-<date>.json``). Run: ``python benchmarks/cli_bench.py [--size 1.0]``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).parent
CASES = (("msh text", ".msh", False), ("msh binary", ".msh", True), ("vtu", ".vtu", None))

_CHILD = """
import json, sys, time
import qdrefine.cli.refine as cmd
from qdrefine.cli import main
times = {}
def timed(name, f):
    def run(*a, **k):
        t0 = time.perf_counter()
        try:
            return f(*a, **k)
        finally:
            times[name] = times.get(name, 0.0) + time.perf_counter() - t0
    return run
cmd.read, cmd.refine, cmd.write = (timed("read", cmd.read), timed("refine", cmd.refine),
                                   timed("write", cmd.write))
code = main(sys.argv[1:])
print(json.dumps({"code": code, **times}))
"""


def make_input(size: float, path: Path, binary: bool | None) -> dict[str, int]:
    sys.path.insert(0, str(HERE))
    from refine_bench import grid

    import qdrefine

    mesh = grid(size, shuffled=True)
    qdrefine.write(path, mesh, binary=binary)
    return {"points": mesh.n_points, "triangles": mesh.n_triangles,
            "bytes": path.stat().st_size}


def warm_up(folder: Path) -> None:
    """Refine a small file once, so that every kernel is compiled and in numba's cache
    (a first run after installing or editing the package compiles them: about 15-30 s)."""
    make_input(0.001, folder / "warm.msh", None)
    subprocess.run([sys.executable, "-m", "qdrefine", "refine", str(folder / "warm.msh"),
                    str(folder / "warm-out.msh"), "--quiet"], check=True)


def run_case(folder: Path, ext: str, binary: bool | None, size: float) -> dict[str, object]:
    src, out = folder / f"in{ext}", folder / f"out{ext}"
    info = make_input(size, src, binary)
    argv = ["refine", str(src), str(out), "--quiet"] + (["--binary"] if binary else [])
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "qdrefine", *argv], capture_output=True,
                          text=True, check=False)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"qdrefine refine failed: {done.stderr}")
    out_bytes = out.stat().st_size
    out.unlink()
    t0 = time.perf_counter()
    child = subprocess.run([sys.executable, "-c", _CHILD, *argv], capture_output=True,
                           text=True, check=True)
    child_wall = time.perf_counter() - t0
    split = json.loads(child.stdout.strip().splitlines()[-1])
    out.unlink()
    steps = {k: round(split[k], 3) for k in ("read", "refine", "write")}
    steps["start-up"] = round(child_wall - sum(split[k] for k in ("read", "refine", "write")),
                              3)
    return {"input": info, "output_bytes": out_bytes, "subprocess_wall_s": round(wall, 3),
            "split_s": steps, "split_run_wall_s": round(child_wall, 3),
            "write_share": round(steps["write"] / child_wall, 3)}


def mesh_construction(size: float, repeat: int = 7) -> dict[str, dict[str, float]]:
    """Seconds to construct (validate) a ``Mesh`` of ``size`` million triangles from its
    arrays: wall and CPU time of this process, best and median of ``repeat``."""
    sys.path.insert(0, str(HERE))
    import numpy as np
    from refine_bench import grid

    from qdrefine import Mesh

    out = {}
    for shuffled in (False, True):
        mesh = grid(size, shuffled=shuffled)
        p, t = np.array(mesh.points), np.array(mesh.triangles)
        Mesh(p, t)  # kernels loaded
        wall, cpu = [], []
        for _ in range(repeat):
            w, c = time.perf_counter(), time.process_time()
            Mesh(p, t)
            wall.append(time.perf_counter() - w)
            cpu.append(time.process_time() - c)
        out["shuffled" if shuffled else "structured"] = {
            "triangles": mesh.n_triangles, "wall_best_s": round(min(wall), 3),
            "wall_median_s": round(float(np.median(wall)), 3),
            "cpu_best_s": round(min(cpu), 3), "cpu_median_s": round(float(np.median(cpu)), 3)}
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, default=1.0, help="input triangles, millions")
    parser.add_argument("--json", default=None, help="output JSON file")
    args = parser.parse_args()
    today = datetime.date.today().isoformat()
    target = Path(args.json) if args.json else HERE / "results" / f"cli-{today}.json"
    results = {"date": today, "python": platform.python_version(), "cpus": os.cpu_count(),
               "load_average_before": os.getloadavg(), "size_millions": args.size, "cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        warm_up(Path(tmp))
        for name, ext, binary in CASES:
            results["cases"][name] = run_case(Path(tmp), ext, binary, args.size)
    results["mesh_construction"] = mesh_construction(args.size)
    results["load_average_after"] = os.getloadavg()
    print(f"{'case':12} {'in tris':>9} {'out tris':>9} {'read':>7} {'refine':>7} {'write':>7} "
          f"{'start-up':>8} {'write %':>7} {'total (subprocess)':>19}")
    for name, r in results["cases"].items():
        s = r["split_s"]
        print(f"{name:12} {r['input']['triangles']:>9} {7 * r['input']['triangles']:>9} "
              f"{s['read']:>7.2f} {s['refine']:>7.2f} {s['write']:>7.2f} {s['start-up']:>8.2f} "
              f"{100 * r['write_share']:>6.0f}% {r['subprocess_wall_s']:>18.2f}s")
    for name, r in results["mesh_construction"].items():
        print(f"Mesh({r['triangles']} triangles, {name}): wall {r['wall_best_s']:.3f} s best, "
              f"{r['wall_median_s']:.3f} s median; CPU {r['cpu_best_s']:.3f} s best")
    target.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
