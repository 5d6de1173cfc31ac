"""``refine_device`` on CuPy arrays, PyTorch CUDA tensors (``__cuda_array_interface__``) and
a DLPack-only producer, each against the CPU bit for bit; and PyTorch wrapping the output
without a copy (not part of the test suite: it needs a GPU, CuPy and PyTorch).

Run on a machine with a CUDA GPU: ``python benchmarks/gpu_interop.py [--json FILE]``.
Prints one line per kind of input (and writes them as JSON); exit status 1 if any kind
failed or differed from the CPU.
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from qdrefine import examples, refine
from qdrefine.gpu import refine_device


class DLPackOnly:
    """A device array seen only through DLPack (no ``__cuda_array_interface__``)."""

    def __init__(self, array) -> None:
        self.array = array

    def __dlpack__(self, **kwargs):
        return self.array.__dlpack__(**kwargs)

    def __dlpack_device__(self):
        return self.array.__dlpack_device__()


def main() -> int:
    """Run each kind of input; return the exit status."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--json", help="write the results to this JSON file")
    args = ap.parse_args()
    mesh = examples.jittered_square(30, 3, 0.5, "all")
    cpu = refine(mesh, "7t-qd", 2)
    results: dict[str, object] = {}

    def same(out, to_host) -> bool:
        return bool(np.array_equal(to_host(out.points), cpu.points)
                    and np.array_equal(to_host(out.triangles), cpu.triangles))

    try:
        import cupy

        out = refine_device(cupy.asarray(mesh.points), cupy.asarray(mesh.triangles), "7t-qd", 2)
        results["cupy"] = {"out": type(out.points).__module__,
                           "identical": same(out, cupy.asnumpy)}
    except Exception as exc:  # report and go on to the next kind
        results["cupy"] = {"failed": f"{type(exc).__name__}: {exc}"}
    try:
        import torch

        points = torch.from_numpy(mesh.points.copy()).cuda()
        triangles = torch.from_numpy(mesh.triangles.copy()).cuda()
        for name, p, t in (("pytorch", points, triangles),
                           ("dlpack_only", DLPackOnly(points), DLPackOnly(triangles))):
            out = refine_device(p, t, "7t-qd", 2)
            results[name] = {"out": type(out.points).__module__,
                             "identical": same(out, lambda a: a.copy_to_host())}
        wrapped = torch.as_tensor(out.points, device="cuda")
        results["pytorch_wraps_output_without_copy"] = {
            "identical": wrapped.data_ptr() == out.points.__cuda_array_interface__["data"][0]}
    except Exception as exc:
        results["pytorch"] = {"failed": f"{type(exc).__name__}: {exc}"}
    for name, row in results.items():
        print(name, row)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=1)
    return 0 if all(row.get("identical") for row in results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
