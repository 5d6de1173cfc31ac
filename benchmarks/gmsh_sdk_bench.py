"""The Gmsh SDK's own MSH 4.1 reader and writer against qdrefine's (not part of the tests).

Reads the 1M-triangle grid of ``cli_bench.py`` written as text MSH 4.1 (Gmsh:
``gmsh.open`` plus ``getNodes`` / ``getElements``, the arrays a caller needs; qdrefine:
:func:`qdrefine.io.read_raw`) and writes its 7M-triangle 7T-QD refinement (Gmsh: loading the
arrays into a discrete entity with ``addNodes`` / ``addElementsByType``, then ``gmsh.write``;
qdrefine: :func:`qdrefine.write`), text and binary. Writes JSON (default
``benchmarks/results/gmsh-sdk-<date>.json``). Run: ``python benchmarks/gmsh_sdk_bench.py``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=float, default=1.0, help="input triangles, millions")
    parser.add_argument("--json", default=None)
    args = parser.parse_args()
    import gmsh

    import qdrefine

    sys.path.insert(0, str(HERE))
    from refine_bench import grid

    today = datetime.date.today().isoformat()
    target = Path(args.json) if args.json else HERE / "results" / f"gmsh-sdk-{today}.json"
    mesh = grid(args.size, shuffled=True)
    fine = qdrefine.refine(mesh)
    out: dict[str, object] = {"date": today, "load_average_before": os.getloadavg(),
                              "input_triangles": mesh.n_triangles,
                              "output_triangles": fine.n_triangles, "gmsh": gmsh.__version__}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        qdrefine.write(folder / "in.msh", mesh)
        gmsh.initialize(interruptible=False)
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            t = time.perf_counter()
            gmsh.open(str(folder / "in.msh"))
            gmsh.model.mesh.getNodes()
            gmsh.model.mesh.getElements(2)
            out["read_text_gmsh_s"] = time.perf_counter() - t
            t = time.perf_counter()
            qdrefine.io.read_raw(folder / "in.msh")
            out["read_text_qdrefine_s"] = time.perf_counter() - t
            gmsh.clear()
            gmsh.model.add("fine")
            t = time.perf_counter()
            s = gmsh.model.addDiscreteEntity(2)
            n = fine.n_points
            gmsh.model.mesh.addNodes(2, s, np.arange(1, n + 1),
                                     np.column_stack([fine.points, np.zeros(n)]).ravel())
            gmsh.model.mesh.addElementsByType(
                s, 2, np.arange(1, fine.n_triangles + 1),
                (np.asarray(fine.triangles, np.int64) + 1).ravel())
            out["load_arrays_gmsh_s"] = time.perf_counter() - t
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.option.setNumber("Mesh.SaveAll", 1)
            for binary in (0, 1):
                gmsh.option.setNumber("Mesh.Binary", binary)
                kind = "binary" if binary else "text"
                t = time.perf_counter()
                gmsh.write(str(folder / f"gmsh-{kind}.msh"))
                out[f"write_{kind}_gmsh_s"] = time.perf_counter() - t
                t = time.perf_counter()
                qdrefine.write(folder / f"ours-{kind}.msh", fine, binary=bool(binary))
                out[f"write_{kind}_qdrefine_s"] = time.perf_counter() - t
        finally:
            gmsh.finalize()
    out["load_average_after"] = os.getloadavg()
    out = {k: round(v, 3) if isinstance(v, float) else v for k, v in out.items()}
    target.write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
