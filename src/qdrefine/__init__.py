"""qdrefine: refine 2D triangle meshes with longest-edge seven-triangle partitions.

The 7T-QD (Seven Triangle Quasi-Delaunay) partition, with 7T-LE, 7T-D and the classic
four-triangle schemes for comparison. See :func:`refine` and :func:`partition`.
"""

from . import jit  # noqa: F401, I001  (first: where numba caches the kernels)
from . import marking  # noqa: I001
from .adaptive import coarsen, refine_cycles
from .io import read, write
from .mesh import Mesh
from .partition import partition, partition_many
from .refine import refine, refine_with_parents
from .schemes import SCHEMES, get_scheme, scheme_names

__all__ = [
    "Mesh",
    "SCHEMES",
    "coarsen",
    "get_scheme",
    "marking",
    "partition",
    "partition_many",
    "read",
    "refine",
    "refine_cycles",
    "refine_with_parents",
    "scheme_names",
    "write",
]

__version__ = "0.1.0"
