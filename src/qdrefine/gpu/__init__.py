"""Uniform refinement on a CUDA device (optional: ``pip install 'qdrefine[gpu]'``).

:func:`refine_device` takes device arrays (CuPy, PyTorch, numba: anything with
``__cuda_array_interface__``, or a CUDA DLPack producer) and returns device arrays;
``qdrefine.refine(mesh, device="cuda")`` does the same for a host :class:`~qdrefine.Mesh`.
The output is the CPU's, bit for bit: same points, same numbering, same triangles, same
tags. The kernels are written with numba-cuda (the CPU kernels' language) and run under
numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``) where there is no GPU, which is how the
test suite checks them. See ``docs/performance.md`` for what has been measured on a GPU.
"""

from __future__ import annotations

try:
    from numba import cuda as _cuda  # noqa: F401  (numba's own, or the numba-cuda package's)
except ImportError as exc:  # pragma: no cover - depends on the installed numba
    raise ImportError("qdrefine.gpu needs numba's CUDA target: pip install 'qdrefine[gpu]' "
                      f"({exc})") from None

from .refine import DeviceMesh, check_device_memory, refine_device, refine_mesh, require_gpu

__all__ = ["DeviceMesh", "DEVICES", "check_device_memory", "refine_device", "refine_mesh",
           "require_gpu"]

#: Values of ``device=`` that run here.
DEVICES = ("cuda",)
