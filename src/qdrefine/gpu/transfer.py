"""Arrays in and out of the device: anything with ``__cuda_array_interface__`` (numba,
CuPy, PyTorch), CUDA DLPack producers (through CuPy) and host arrays (copied, their dtype
cast only where no value changes), checked for dtype, shape and layout."""

from __future__ import annotations

import numpy as np
from numba import cuda
from numpy.typing import NDArray

from ..arguments import refuse_masked
from .checks import cast_host

__all__ = ["as_device", "to_host"]


def as_device(a, name: str, dtypes: tuple, columns: int | None):
    """``a`` as a C-contiguous numba device array (no copy when it is on the device
    already), checked for dtype and shape."""
    if hasattr(a, "copy_to_host") and hasattr(a, "shape"):  # a numba device array
        d = a
    elif hasattr(a, "__cuda_array_interface__"):
        d = cuda.as_cuda_array(a)
    elif hasattr(a, "__dlpack__") and _dlpack_on_cuda(a):
        try:
            import cupy
        except ImportError:
            raise ValueError(f"{name}: reading a CUDA DLPack array needs CuPy "
                             "(pip install 'qdrefine[gpu]')") from None
        d = cuda.as_cuda_array(cupy.from_dlpack(a))
    else:
        refuse_masked(a, name)  # np.asarray drops the mask: the masked rows were refined
        host = np.asarray(a)
        if host.dtype not in dtypes and host.size:
            host = cast_host(host, name, np.dtype(dtypes[0]).kind == "f")
        d = cuda.to_device(np.ascontiguousarray(host))
    if d.dtype not in dtypes:
        raise ValueError(f"{name} must have dtype {' or '.join(np.dtype(t).name for t in dtypes)}"
                         f" on the device, got {d.dtype}")
    want = 1 if columns is None else 2
    if len(d.shape) != want or (columns is not None and d.shape[1] != columns):
        shape = "(n,)" if columns is None else f"(n, {columns})"
        raise ValueError(f"{name} must have shape {shape}, got {tuple(d.shape)}")
    if not d.is_c_contiguous():
        raise ValueError(f"{name} must be C-contiguous on the device")
    return d


def _dlpack_on_cuda(a) -> bool:
    try:
        return int(a.__dlpack_device__()[0]) in (2, 3, 13)  # kDLCUDA, pinned, managed
    except (AttributeError, TypeError, ValueError):
        return False


def to_host(a) -> NDArray:
    return a.copy_to_host() if hasattr(a, "copy_to_host") else np.asarray(a.get())
