"""Command-line and I/O benchmark: ``qdrefine refine`` on a 1M-triangle file, against meshio
in the same run (not part of the tests).

For each case (Gmsh MSH 4.1 text and binary, MSH 2.2 text, VTU, XDMF) it writes the input
(about ``--size`` million triangles, shuffled numbering) in that format (case
``gmsh-sdk-41``: an unstructured mesh of that size made and written by the Gmsh SDK, with
named physical groups), then

* runs ``qdrefine refine IN OUT --quiet`` as a subprocess: the **total wall time** a user
  waits, interpreter start and imports included;
* runs the same command in a child process through ``qdrefine.cli.main`` with timers around
  the stages: ``read`` (parsing the file, :func:`qdrefine.io.read_raw`), ``check`` (the
  validation of what was read, :func:`qdrefine.check.find`), ``refine`` and ``write``;
  ``start-up`` is the rest of that child's wall time (interpreter, imports, kernels loaded
  from numba's cache);
* times, in this process, ``qdrefine.read`` / ``qdrefine.io.read_raw`` against
  ``meshio.read`` on the same input file, and ``qdrefine.write`` against ``meshio.write`` of
  the same refined mesh in the same format (meshio's ``gmsh`` writer is MSH 4.1, ``gmsh22``
  2.2; binary where the case is binary; XDMF with HDF5 data).

Prints a table and writes JSON (``--json FILE``; default
``benchmarks/results/cli-<date>.json``). Run: ``python benchmarks/cli_bench.py [--size 1.0]
[--cases msh41-text,vtu] [--no-meshio]``. The machine's load average is recorded before and
after: on a shared machine, compare figures of one run only.
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

#: name -> (extension, options of qdrefine.write, CLI options, meshio format, meshio options)
CASES = {
    "msh41-text": (".msh", {}, [], "gmsh", {"binary": False}),
    "msh41-binary": (".msh", {"binary": True}, ["--binary"], "gmsh", {"binary": True}),
    "msh22-text": (".msh", {"format_version": "2.2"}, ["--format-version", "2.2"], "gmsh22",
                   {"binary": False}),
    "vtu": (".vtu", {}, [], "vtu", {"binary": True}),
    "xdmf": (".xdmf", {}, [], "xdmf", {"data_format": "HDF"}),
    "gmsh-sdk-41": (".msh", {}, [], "gmsh", {"binary": False}),
}

_CHILD = """
import json, sys, time
import qdrefine.io as io
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
io.read_raw, io.find = timed("read", io.read_raw), timed("check", io.find)
cmd.read_raw = io.read_raw  # the command imports it by name
cmd.refine, cmd.write = timed("refine", cmd.refine), timed("write", cmd.write)
code = main(sys.argv[1:])
print(json.dumps({"code": code, **times}))
"""


def gmsh_file(size: float, path: Path) -> None:
    """An unstructured mesh of about ``size`` million triangles made and written (MSH 4.1,
    text) by the Gmsh SDK itself: a unit square with two named physical surfaces and named
    boundary curves."""
    import gmsh

    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        occ = gmsh.model.occ
        a = occ.addRectangle(0, 0, 0, 0.5, 1)
        b = occ.addRectangle(0.5, 0, 0, 0.5, 1)
        occ.fragment([(2, a)], [(2, b)])
        occ.synchronize()
        surfaces = [t for _, t in gmsh.model.getEntities(2)]
        gmsh.model.addPhysicalGroup(2, surfaces[:1], 1, name="left")
        gmsh.model.addPhysicalGroup(2, surfaces[1:], 2, name="right")
        curves = [t for _, t in gmsh.model.getEntities(1)]
        gmsh.model.addPhysicalGroup(1, curves, 10, name="lines")
        h = (2.0 / (size * 1e6 * 1.15)) ** 0.5  # about 2 / h^2 / 1.15 triangles
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.Algorithm", 5)
        gmsh.model.mesh.generate(2)
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()


def make_mesh(size: float):
    sys.path.insert(0, str(HERE))
    from refine_bench import grid

    return grid(size, shuffled=True)


def warm_up(folder: Path) -> None:
    """Refine a small file once, so that every kernel is compiled and in numba's cache."""
    import qdrefine

    qdrefine.write(folder / "warm.msh", make_mesh(0.001))
    subprocess.run([sys.executable, "-m", "qdrefine", "refine", str(folder / "warm.msh"),
                    str(folder / "warm-out.msh"), "--quiet"], check=True)


def best(f, repeat: int = 1) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def run_case(folder: Path, name: str, mesh, fine, with_meshio: bool) -> dict[str, object]:
    import qdrefine

    ext, options, cli, meshio_format, meshio_options = CASES[name]
    src, out = folder / f"in{ext}", folder / f"out{ext}"
    if name == "gmsh-sdk-41":  # a file Gmsh wrote: its own mesh, refined for the writes
        gmsh_file(mesh, src)
        mesh = qdrefine.read(src)
        fine = qdrefine.refine(mesh)
    else:
        qdrefine.write(src, mesh, **options)
    argv = ["refine", str(src), str(out), "--quiet", *cli]
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
    stages = ("read", "check", "refine", "write")
    steps = {k: round(split.get(k, 0.0), 3) for k in stages}
    steps["start-up"] = round(child_wall - sum(split.get(k, 0.0) for k in stages), 3)
    result = {"input": {"points": mesh.n_points, "triangles": mesh.n_triangles,
                        "bytes": src.stat().st_size,
                        "made by": "Gmsh SDK" if name == "gmsh-sdk-41" else "qdrefine"},
              "output": {"triangles": fine.n_triangles, "bytes": out_bytes},
              "subprocess_wall_s": round(wall, 3), "split_s": steps,
              "split_run_wall_s": round(child_wall, 3)}
    # the same files in this process: qdrefine against meshio
    ours = {"read_raw_s": best(lambda: qdrefine.io.read_raw(src)),
            "read_s": best(lambda: qdrefine.read(src)),
            "write_s": best(lambda: qdrefine.write(out, fine, **options))}
    result["qdrefine"] = {k: round(v, 3) for k, v in ours.items()}
    if with_meshio:
        import meshio
        import numpy as np

        tags = np.zeros(fine.n_triangles, int) if fine.cell_tags is None else \
            np.asarray(fine.cell_tags)
        cells, physical = [("triangle", np.asarray(fine.triangles))], [tags]
        if fine.edges is not None:
            cells.append(("line", np.asarray(fine.edges)))
            physical.append(np.asarray(fine.edge_tags))
        point_data = {}
        if meshio_format == "gmsh" and len(cells) > 1:  # meshio's MSH 4.1 writer needs it
            point_data["gmsh:dim_tags"] = np.tile([2, 1], (fine.n_points, 1))
        m = meshio.Mesh(np.column_stack([fine.points, np.zeros(fine.n_points)]), cells,
                        point_data=point_data,
                        cell_data={"gmsh:physical": physical,
                                   "gmsh:geometrical": [t + 1 for t in physical]})
        theirs = {"read_s": best(lambda: meshio.read(src)),
                  "write_s": best(lambda: meshio.write(folder / f"meshio{ext}", m,
                                                       file_format=meshio_format,
                                                       **meshio_options))}
        result["meshio"] = {k: round(v, 3) for k, v in theirs.items()}
        result["speed-up"] = {
            "read (parse only)": round(theirs["read_s"] / ours["read_raw_s"], 1),
            "read (with checks)": round(theirs["read_s"] / ours["read_s"], 1),
            "write": round(theirs["write_s"] / ours["write_s"], 1)}
    for p in folder.glob("out*"):
        p.unlink()
    for p in folder.glob("meshio*"):
        p.unlink()
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, default=1.0, help="input triangles, millions")
    parser.add_argument("--cases", default=",".join(CASES), help="comma-separated cases")
    parser.add_argument("--no-meshio", action="store_true", help="skip the meshio timings")
    parser.add_argument("--json", default=None, help="output JSON file")
    args = parser.parse_args()
    import qdrefine

    today = datetime.date.today().isoformat()
    target = Path(args.json) if args.json else HERE / "results" / f"cli-{today}.json"
    results = {"date": today, "python": platform.python_version(), "cpus": os.cpu_count(),
               "load_average_before": os.getloadavg(), "size_millions": args.size,
               "cases": {}}
    mesh = make_mesh(args.size)
    fine = qdrefine.refine(mesh)
    with tempfile.TemporaryDirectory(dir=os.environ.get("BENCH_TMP")) as tmp:
        warm_up(Path(tmp))
        for name in args.cases.split(","):
            print(f"{name} ...", file=sys.stderr, flush=True)
            results["cases"][name] = run_case(
                Path(tmp), name, args.size if name == "gmsh-sdk-41" else mesh, fine,
                not args.no_meshio)
    results["load_average_after"] = os.getloadavg()
    print(f"{'case':13} {'read':>6} {'check':>6} {'refine':>6} {'write':>6} {'start':>6} "
          f"{'total':>7} | {'read x':>7} {'write x':>7}  (seconds; x: meshio / qdrefine)")
    for name, r in results["cases"].items():
        s, x = r["split_s"], r.get("speed-up", {})
        print(f"{name:13} {s['read']:>6.2f} {s['check']:>6.2f} {s['refine']:>6.2f} "
              f"{s['write']:>6.2f} {s['start-up']:>6.2f} {r['subprocess_wall_s']:>7.2f} | "
              f"{x.get('read (parse only)', float('nan')):>7.1f} "
              f"{x.get('write', float('nan')):>7.1f}")
    target.write_text(json.dumps(results, indent=2) + "\n")
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
