"""Uniform refinement on a CUDA device: the CPU's three passes as numba-cuda kernels, the
arrays staying on the device from one level to the next.

Per level: the edge numbering (:mod:`qdrefine.gpu.numbering`), the new points and the
decision and emission (:mod:`qdrefine.gpu.kernels`). Every decision is exact and made on
the device: the emission kernel runs the float filter and the error-free stage 2; the few
triangles some sign of which needs Shewchuk's expansions (none on grids; near-ties whose
coordinate differences are not exact in float64) are listed and decided by a second
kernel with a per-thread work buffer. The rounding check of ``strict`` counts the suspects
on the device and, only if there are any (almost never), runs
:func:`qdrefine.uniform.check_rounding` on host copies.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
from numba import cuda
from numba.core import config
from numpy.typing import NDArray

from ..arguments import as_count
from ..boundaries import boundary_edges, keep_boundary
from ..check.cells import misoriented
from ..fields import refine_point_data
from ..kernels import _frame_tables
from ..memory import MEMORY_LIMIT_VARIABLE, check_memory, memory_needed
from ..mesh import Mesh, index_dtype
from ..predicates import factor_forms
from ..schemes import Scheme, get_scheme
from ..uniform import RefusedTriangle, check_rounding, refine_uniform
from . import kernels as k
from .checks import (
    BoundaryCrossed,
    check_boundary,
    check_indices,
    check_new_points,
    check_orientation,
    check_points,
    split_boundary,
)
from .numbering import THREADS, blocks, sort_edges
from .transfer import as_device, to_host

__all__ = ["DeviceMesh", "pass_times", "refine_device", "refine_mesh", "require_gpu"]


class InputError(ValueError):
    """Bad input found while refining (reported without the ``level N:`` prefix)."""


@dataclass(frozen=True)
class DeviceMesh:
    """A refined mesh on the device (arrays as described in :func:`qdrefine.refine`).

    Attributes
    ----------
    points : (N', 2) float64
    triangles : (M', 3) int32 while the points fit, int64 beyond
    cell_tags : (M',) int64 or None
    edges : (K', 2), dtype of ``triangles``, or None
    edge_tags : (K',) int64 or None
    exact_stage : tuple of int
        Per level, the triangles some sign of which needed the exact stage (Shewchuk's
        expansions, run on the device by a second kernel; 0 on grids and most meshes).
    """

    points: object
    triangles: object
    cell_tags: object = None
    edges: object = None
    edge_tags: object = None
    exact_stage: tuple[int, ...] = ()


def refine_device(points, triangles, scheme: str | Scheme = "7t-qd", levels: int = 1, *,
                  cell_tags=None, edges=None, edge_tags=None, strict: bool = True
                  ) -> DeviceMesh:
    """Refine every triangle ``levels`` times with ``scheme`` on the CUDA device.

    Parameters
    ----------
    points : (N, 2) float64
    triangles : (M, 3) int32 or int64
        Counter-clockwise, as in a :class:`qdrefine.Mesh`. Checked on the device: shapes,
        dtypes, the index range, the coordinates (finite, 0 or in
        :data:`qdrefine.predicates.COORDINATE_RANGE`) and the orientation (exact); not
        checked: conformity, duplicate points, folds (validate with ``Mesh`` on the host).
    cell_tags : (M,) int64, optional
    edges : (K, 2) int and edge_tags : (K,) int64, optional
        Tagged edges, each an edge of some triangle (checked).
    scheme, levels, strict
        As in :func:`qdrefine.refine`.

    Every array may be on the device (anything with ``__cuda_array_interface__``: numba
    device arrays, CuPy, PyTorch; or a CUDA DLPack producer, read through CuPy) or on the
    host (copied to the device first).

    Returns
    -------
    DeviceMesh
        Device arrays equal, bit for bit, to :func:`qdrefine.refine`'s on the host: CuPy
        arrays when ``points`` is one, numba device arrays otherwise (both export
        ``__cuda_array_interface__``, so CuPy, PyTorch or JAX wrap them without a copy).

    Raises
    ------
    MemoryError
        When the work would not fit in the device's free memory.
    ValueError
        On bad shapes, dtypes or indices, and as :func:`qdrefine.refine` with ``strict``.
    """
    return _refine_device(points, triangles, scheme, levels, cell_tags=cell_tags, edges=edges,
                          edge_tags=edge_tags, strict=strict)[0]


def _refine_device(points, triangles, scheme: str | Scheme = "7t-qd", levels: int = 1, *,
                   cell_tags=None, edges=None, edge_tags=None, strict: bool = True,
                   edge_ends: bool = False, boundary: NDArray[np.int64] | None = None,
                   refined_boundary: list | None = None
                   ) -> tuple[DeviceMesh, list[NDArray[np.int64]]]:
    """:func:`refine_device`; with ``edge_ends``, also each level's edges ``(E, 2) int64``
    on the host (lower end first, in the numbering of the level's new points). With
    ``boundary`` (the mesh's directed boundary edges, :mod:`qdrefine.boundaries`), each
    level's rounded boundary is checked as on the CPU: :class:`BoundaryCrossed` if it
    crosses itself; ``refined_boundary``, if given, receives the output's (host)."""
    sch = get_scheme(scheme)
    levels = as_count(levels, "levels")
    require_gpu()
    like_cupy = type(points).__module__.split(".")[0] == "cupy"
    pts = as_device(points, "points", (np.float64,), 2)
    tri = as_device(triangles, "triangles", (np.int32, np.int64), 3)
    n, m = pts.shape[0], tri.shape[0]
    check_indices(tri, n, "triangles")
    tags = None if cell_tags is None else as_device(cell_tags, "cell_tags", (np.int64,), None)
    if tags is not None and tags.shape[0] != m:
        raise ValueError(f"cell_tags must have {m} entries, got {tags.shape[0]}")
    if (edges is None) != (edge_tags is None):
        raise ValueError("edges and edge_tags go together")
    tagged = etags = None
    if edges is not None:
        tagged = as_device(edges, "edges", (np.int32, np.int64), 2)
        etags = as_device(edge_tags, "edge_tags", (np.int64,), None)
        if etags.shape[0] != tagged.shape[0]:
            raise ValueError(f"edge_tags must have {tagged.shape[0]} entries, got "
                             f"{etags.shape[0]}")
        check_indices(tagged, n, "edges")
    check_device_memory(n, m, sch, levels, tags is not None)
    check_points(pts)
    if not levels:  # level 1 checks the orientation as it emits: here, on the host
        check_orientation(to_host(pts), to_host(tri))
    tables = _Tables(sch)
    exact: list[int] = []
    ends: list[NDArray[np.int64]] = []
    first = tri
    pieces = None if boundary is None else cuda.to_device(np.ascontiguousarray(boundary))
    for level in range(1, levels + 1):
        try:
            pts, tri, tags, tagged, etags, n_hard, pieces = _level(
                pts, tri, tags, tagged, etags, tables, strict, level == 1,
                keep=ends.append if edge_ends else None, boundary=pieces)
        except InputError as exc:
            raise ValueError(str(exc)) from None
        except RefusedTriangle as exc:  # named by the input triangle, as on the CPU
            raise exc.at_input(SimpleNamespace(triangles=to_host(first)), level,
                               sch.n_children) from None
        except ValueError as exc:
            raise ValueError(f"level {level}: {exc}" if levels > 1 else str(exc)) from None
        exact.append(n_hard)
        if pieces is not None:
            check_boundary(pts, pieces)
    if levels:
        check_new_points(pts, n, lambda: _smallest(points))
    if pieces is not None and refined_boundary is not None:
        refined_boundary.append(pieces.copy_to_host())
    arrays = (pts, tri, tags, tagged, etags)
    if like_cupy:
        import cupy

        arrays = tuple(None if a is None else cupy.asarray(a) for a in arrays)
    return DeviceMesh(*arrays, exact_stage=tuple(exact)), ends


def require_gpu() -> None:
    """Raise ``RuntimeError`` (one line) when numba finds no CUDA device and the simulator
    is off."""
    if not config.ENABLE_CUDASIM and not cuda.is_available():
        raise RuntimeError("device='cuda': no CUDA GPU is available to numba "
                           "(numba.cuda.is_available() is False; check the driver, or run "
                           "under the simulator with NUMBA_ENABLE_CUDASIM=1)")


def refine_mesh(mesh: Mesh, scheme: str | Scheme = "7t-qd", levels: int = 1,
                strict: bool = True) -> Mesh:
    """:func:`qdrefine.refine` of a host mesh on the device, copies both ways included."""
    sch = get_scheme(scheme)
    levels = as_count(levels, "levels")
    require_gpu()
    if not levels:  # the mesh itself, as on the CPU (its history included)
        return mesh
    check_memory(mesh, sch, levels)  # the result comes back to the host
    refined: list = []  # the output's boundary, kept on it as on the CPU
    try:
        out, ends = _refine_device(mesh.points, mesh.triangles, sch, levels,
                                   cell_tags=mesh.cell_tags, edges=mesh.edges,
                                   edge_tags=mesh.edge_tags, strict=strict,
                                   edge_ends=bool(mesh.point_data),
                                   boundary=boundary_edges(mesh) if strict else None,
                                   refined_boundary=refined)
    except BoundaryCrossed:  # rare: the CPU's refusal, in its words (the same arithmetic)
        refine_uniform(mesh, sch, levels, strict)
        raise RuntimeError("the GPU found a rounded boundary crossing itself where the CPU "
                           "did not: please report it") from None
    point_data = mesh.point_data
    for level_ends in ends:  # on the host, as the CPU does it (the same edge numbering)
        point_data = refine_point_data(point_data, level_ends, sch.stencil.per_edge)
    copies = sch.n_children ** levels
    cell_data = {name: np.repeat(value, copies, axis=0)
                 for name, value in (mesh.cell_data or {}).items()}
    origins = None if mesh.origins is None else np.repeat(mesh.origins, copies, axis=0)
    fine = Mesh._trusted(*(None if a is None else to_host(a) for a in
                           (out.points, out.triangles, out.cell_tags, out.edges,
                            out.edge_tags)), point_data or None, cell_data,
                         mesh.physical_names, origins=origins)
    if refined:
        keep_boundary(fine, refined[0])
    return fine


def check_device_memory(n_points: int, n_triangles: int, scheme: Scheme, levels: int,
                        tagged: bool) -> None:
    """Raise ``MemoryError`` when :func:`qdrefine.memory.memory_needed` (an upper bound of
    the device's work too) exceeds the device's free memory."""
    if levels == 0:
        return
    require_gpu()
    free = float(cuda.current_context().get_memory_info()[0])
    need = memory_needed(n_points, n_triangles, scheme, levels, tagged)
    if need > free:
        raise MemoryError(f"refining {n_triangles} triangles {levels} level"
                          f"{'s' if levels != 1 else ''} on the GPU needs about "
                          f"{need / 2**30:.3g} GiB; {free / 2**30:.3g} GiB free on the device "
                          f"({MEMORY_LIMIT_VARIABLE} caps host memory only)")


class _Tables:
    """A scheme's tables on the device, uploaded once per call."""

    def __init__(self, sch: Scheme) -> None:
        if sch.lut.size and sch.lut.min() < 0:
            raise ValueError("the scheme's lookup table has sign patterns without a row")
        self.per_edge = sch.stencil.per_edge
        self.n_children = sch.n_children
        self.width = 3 * sch.n_children
        self.forms_host = np.ascontiguousarray(sch.forms, dtype=np.float64)
        self.factors_host = factor_forms(self.forms_host)
        self.lut_host = np.ascontiguousarray(sch.lut)
        self.forms = cuda.to_device(self.forms_host)
        self.factors = cuda.to_device(self.factors_host)
        self.lut = cuda.to_device(self.lut_host)
        self.frames = cuda.to_device(
            np.ascontiguousarray(_frame_tables(sch.tables, self.per_edge).reshape(-1)))


def _level(pts, tri, tags, tagged, etags, tab: _Tables, strict: bool, check: bool,
           clock=None, keep=None, boundary=None):
    """One uniform level on device arrays (:func:`qdrefine.refine.refine_arrays`); with
    ``check`` (the input level), a triangle that is not counter-clockwise is refused.
    ``clock(name)``, if given, is called after each pass (:func:`pass_times`);
    ``keep(ends)``, if given, receives the level's edges on the host. Returns the new
    points, triangles, tags, tagged edges and their tags, the number of triangles decided
    exactly, and ``boundary`` (directed boundary edges ``(B, 2)``, or None) cut at the new
    points."""
    n, m = pts.shape[0], tri.shape[0]
    per = tab.per_edge
    ed = sort_edges(tri, n)
    if keep is not None:
        keep(ed.ends_host())
    if clock:
        clock("edge numbering")
    n_new = n + per * ed.n_edges
    new_pts = cuda.device_array((n_new, 2), dtype=np.float64)
    k.new_points[blocks(n), THREADS](pts, ed.starts, ed.first, ed.hi, per, new_pts)
    if clock:
        clock("new points")
    children = cuda.device_array((m * tab.n_children, 3), dtype=index_dtype(n_new))
    flat = children.reshape(m * tab.width)
    hard = cuda.device_array(max(m, 1), dtype=np.int64)
    counters = cuda.to_device(np.zeros(2, dtype=np.int64))
    if m:
        k.emit[blocks(m), THREADS](pts, tri, ed.starts, ed.first, ed.hi, per, tab.forms,
                                   tab.factors, tab.lut, tab.frames, tab.width, flat, hard,
                                   counters[0:1], counters[1:2], int(check))
    n_hard, n_suspect = (int(c) for c in counters.copy_to_host())
    if n_hard:
        rows = hard[:n_hard]
        labels = cuda.device_array((n_hard, 4), dtype=np.int64)
        k.decide_rows[blocks(n_hard), THREADS](pts, tri, rows, tab.forms, tab.factors,
                                               tab.lut, int(check), labels)
        if check:
            _refuse_misoriented(tri, rows.copy_to_host(), labels.copy_to_host())
        k.emit_rows[blocks(n_hard), THREADS](n, tri, ed.starts, ed.first, ed.hi, per,
                                             tab.frames, tab.width, rows, labels, flat)
    if clock:
        clock("decision and emission")
    if strict and n_suspect:
        check_rounding(to_host(pts), to_host(tri), to_host(new_pts), to_host(children), per)
        if clock:
            clock("rounding check on the host")
    new_tags = new_edges = new_etags = None
    if tags is not None:
        new_tags = cuda.device_array(m * tab.n_children, dtype=np.int64)
        k.repeat[blocks(new_tags.shape[0]), THREADS](tags, tab.n_children, new_tags)
    if tagged is not None:
        n_tagged = tagged.shape[0]
        new_edges = cuda.device_array((n_tagged * (per + 1), 2), dtype=children.dtype)
        new_etags = cuda.device_array(n_tagged * (per + 1), dtype=np.int64)
        if n_tagged:
            first_bad = cuda.to_device(np.array([n_tagged], dtype=np.int64))
            k.split_edges[blocks(n_tagged), THREADS](tagged, n, ed.starts, ed.first, ed.hi,
                                                     per, new_edges, first_bad)
            r = int(first_bad.copy_to_host()[0])
            if r < n_tagged:
                pair = tuple(int(v) for v in tagged[r:r + 1].copy_to_host()[0])
                raise InputError(f"edge {r} {pair} is not an edge of any triangle")
            k.repeat[blocks(new_etags.shape[0]), THREADS](etags, per + 1, new_etags)
    if boundary is not None:
        boundary = split_boundary(boundary, ed, n, per)
    return new_pts, children, new_tags, new_edges, new_etags, n_hard, boundary


def pass_times(points, triangles, scheme: str | Scheme = "7t-qd", strict: bool = True
               ) -> dict[str, float]:
    """Seconds of each pass of one level of :func:`refine_device` on device arrays (the
    device synchronized at each pass boundary; for benchmarks)."""
    import time

    require_gpu()
    pts = as_device(points, "points", (np.float64,), 2)
    tri = as_device(triangles, "triangles", (np.int32, np.int64), 3)
    times: dict[str, float] = {}
    cuda.synchronize()
    last = [time.perf_counter()]

    def clock(name: str) -> None:
        cuda.synchronize()
        now = time.perf_counter()
        times[name] = times.get(name, 0.0) + now - last[0]
        last[0] = now

    _level(pts, tri, None, None, None, _Tables(get_scheme(scheme)), strict, False, clock)
    return times


def _refuse_misoriented(tri, rows: NDArray, labels: NDArray) -> None:
    """``ValueError`` naming the least triangle :func:`kernels.decide_rows` found zero-area
    or clockwise (the wording of :class:`qdrefine.Mesh`)."""
    bad = labels[:, 3] < 0
    if not bad.any():
        return
    t = int(rows[bad].min())
    raise InputError(misoriented(t, tri[t:t + 1].copy_to_host()[0],
                                 labels[rows == t][0, 3] == -1))


def _smallest(points) -> float:
    """The smallest nonzero coordinate magnitude of the input ``points`` (host or device
    array), for a message."""
    a = np.abs(to_host(as_device(points, "points", (np.float64,), 2)))
    return float(np.min(a, where=a > 0, initial=np.inf))
