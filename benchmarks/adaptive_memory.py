"""Memory of local refinement, phase by phase, against the constants its checks use
(:func:`qdrefine.memory.local_memory_needed`).

A step's output size is known only once its closure is, so the adaptive code checks each
phase before it allocates: the working mesh of a pass (``LOCAL_PER_WORKING`` bytes per
working triangle) and the output of a pass, emitted, stitched and finished
(``LOCAL_PER_OUTPUT`` bytes per output triangle). This measures both, in a fresh process
per case, from the resident set's high-water mark (``VmHWM``, reset through
``/proc/self/clear_refs`` at the start of each phase, Linux only):

* *working*: from the start of a pass (before its working mesh is built) to the start of
  its emission, the high-water mark over the resident set at the start, per working
  triangle (the triangles that are not transition children, plus one per family);
* *output*: from the start of an emission to the start of the next pass (or the end of
  the call), the high-water mark over the resident set at the start, per triangle emitted.

Cases, on the Gmsh L-shape of ``adaptive_bench.py`` (864,514 triangles): 1%, 10%, 30% and
all triangles marked at random; the second cycle of 1% scattered marks (a mesh with
history, two passes); and 30% of a 200,000-triangle piece of it. Usage::

    python benchmarks/adaptive_memory.py [--json benchmarks/results/F.json]
"""

from __future__ import annotations

import argparse
import datetime
import gc
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import numpy as np

CASES = ["random 1%", "random 10%", "random 30%", "all", "second cycle, random 1%",
         "random 30% of 200,000"]


def _status(key: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(key):
            return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {key} in /proc/self/status")


def _reset_peak() -> int:
    """Reset the high-water mark; the resident set now."""
    Path("/proc/self/clear_refs").write_text("5")
    return _status("VmRSS")


def _mesh_and_marks(case: str):
    from adaptive_bench import big_l_shape

    import qdrefine
    from qdrefine.marking import mark_random

    mesh = big_l_shape()
    if case == "random 30% of 200,000":
        t = mesh.triangles[:200_000]
        used = np.unique(t)
        new = np.full(mesh.n_points, -1, dtype=np.int64)
        new[used] = np.arange(used.size)
        mesh = qdrefine.Mesh(mesh.points[used], new[t])
    if case.startswith("second"):
        mesh = qdrefine.refine(mesh, "7t-qd", marked=mark_random(mesh, 0.01))
        return mesh, mark_random(mesh, 0.01, seed=1)
    if case == "all":
        return mesh, np.ones(mesh.n_triangles, dtype=bool)
    fraction = float(case.split()[1].rstrip("%")) / 100
    return mesh, mark_random(mesh, fraction, seed=1)


def measure(case: str) -> dict:
    """One case in this process: the phases' growth and sizes."""
    import qdrefine
    from qdrefine import examples
    from qdrefine.adaptive import step as step_module

    mesh, marked = _mesh_and_marks(case)
    qdrefine.refine(examples.square(2), marked=[0])  # compile outside the measurement
    gc.collect()
    phases: list[dict] = []
    at = {"rss": 0}

    def close_phase() -> None:
        if phases:
            phases[-1]["bytes"] = _status("VmHWM") - at["rss"]

    start, emit = step_module.start, step_module.emit_step

    def measured_start(mesh_, marked_, fam_marked, sch, fam, earlier=None):
        close_phase()
        at["rss"] = _reset_peak()
        working = int((fam.member < 0).sum()) + fam.n_families
        phases.append({"phase": "working", "triangles": working})
        return start(mesh_, marked_, fam_marked, sch, fam, earlier)

    def measured_emit(inp, tree, cl):
        close_phase()
        at["rss"] = _reset_peak()
        out = emit(inp, tree, cl)
        phases.append({"phase": "output", "triangles": out[0].n_triangles})
        return out

    step_module.start, step_module.emit_step = measured_start, measured_emit
    out = qdrefine.refine(mesh, "7t-qd", marked=marked)
    close_phase()
    # the last output phase ends with the call: stitched and finished, the whole output
    phases[-1]["triangles"] = max(phases[-1]["triangles"], out.n_triangles)
    for p in phases:
        p["bytes_per_triangle"] = p["bytes"] / max(p["triangles"], 1)
    return {"case": case, "triangles": mesh.n_triangles, "marked": int(marked.sum()),
            "output_triangles": out.n_triangles, "phases": phases}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--case", help=argparse.SUPPRESS)  # one case, in a child process
    args = parser.parse_args(argv)
    if args.case:
        print(json.dumps(measure(args.case)))
        return
    from qdrefine.memory import LOCAL_PER_OUTPUT, LOCAL_PER_WORKING

    rows = []
    for case in CASES:
        done = subprocess.run([sys.executable, __file__, "--case", case], check=True,
                              capture_output=True, text=True,
                              cwd=Path(__file__).parent)
        row = json.loads(done.stdout.strip().splitlines()[-1])
        rows.append(row)
        text = ", ".join(f"{p['phase']} {p['bytes'] / 2**20:.0f} MiB for {p['triangles']} "
                         f"({p['bytes_per_triangle']:.0f} B each)" for p in row["phases"])
        print(f"{case}: {row['triangles']} triangles, {row['marked']} marked -> "
              f"{row['output_triangles']}: {text}")
    worst = {kind: max(p["bytes_per_triangle"] for r in rows for p in r["phases"]
                       if p["phase"] == kind) for kind in ("working", "output")}
    print(f"largest per working triangle {worst['working']:.0f} B (checks use "
          f"{LOCAL_PER_WORKING}); per output triangle {worst['output']:.0f} B (checks use "
          f"{LOCAL_PER_OUTPUT})")
    result = {"date": datetime.date.today().isoformat(), "machine": platform.platform(),
              "cpus": os.cpu_count(), "constants": {"LOCAL_PER_WORKING": LOCAL_PER_WORKING,
                                                    "LOCAL_PER_OUTPUT": LOCAL_PER_OUTPUT},
              "largest": worst, "cases": rows}
    path = args.json or (Path(__file__).parent / "results"
                         / f"adaptive-memory-{result['date']}.json")
    path.write_text(json.dumps(result, indent=1))
    print("wrote", path)


if __name__ == "__main__":
    main()
