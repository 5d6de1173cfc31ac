"""``qdrefine refine IN OUT``: refine every triangle of a mesh file, or only marked ones."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..adaptive import HistoryMismatch, refine_marked
from ..io import RawMesh, mesh_of, read_raw
from ..memory import check_memory
from ..mesh import Mesh
from ..refine import refine
from ..schemes import get_scheme, scheme_names
from ..uniform import RefusedTriangle
from . import _common, marks

HELP = "refine every triangle of a mesh file, or only marked ones, with a 7T (or 4T) scheme"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser)
    parser.epilog = ("Formats follow the extensions (.msh, .vtk, .vtu, .xdmf, .mesh, .off, "
                     ".obj, .stl, .ply, Triangle's .node/.ele/.poly). Cell tags are inherited "
                     "and each tagged edge is split with its tag. Examples: qdrefine refine "
                     "in.msh out.msh --levels 2; qdrefine refine in.msh out.msh --mark-box "
                     "0,0,0.1,0.1 --cycles 5")
    _common.add_mesh_in_out(parser, lambda: parser.add_argument(
        "--scheme", default="7t-qd", metavar="NAME", type=_common.scheme_name,
        help=f"one of {', '.join(scheme_names())} (default 7t-qd)"))
    parser.add_argument("--levels", type=_common.non_negative, default=None, metavar="N",
                        help="refine every triangle N times (default 1; 7T schemes multiply "
                             "the triangles by 7 per level); not with a mark")
    parser.add_argument("--dask", nargs="?", const="", default=None, metavar="ADDRESS",
                        help="refine the Zarr store IN into the store OUT (names ending in "
                             ".zarr; see 'qdrefine convert') on Dask: a local cluster sized "
                             "to the machine, or the scheduler at ADDRESS (tcp://host:8786); "
                             "uniform refinement only (docs/scale-out.md)")
    local = parser.add_argument_group(
        "local refinement", "Refine only marked triangles (and a conforming closure around "
        "them); transitions are coarsened before a later cycle refines them "
        "(docs/adaptive.md).")
    marks.add_options(local.add_mutually_exclusive_group())
    local.add_argument("--cycles", type=_common.non_negative, default=None, metavar="K",
                       help="mark and refine K times (default 1); tags and boxes are "
                            "re-evaluated on each cycle's mesh")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        steps = _check_options(args)
        if args.dask is not None:
            return _on_dask(args)
        _common.check_mesh_output(args)
        start = time.perf_counter()
        with _common.Progress(steps + 2, args.quiet) as progress:
            progress.step(f"reading {args.input}")
            raw = read_raw(args.input)
            mesh = mesh_of(raw)
            read_s, start = time.perf_counter() - start, time.perf_counter()
            try:
                fine, summary = _refiner(args)(mesh, args, progress, raw)
            except HistoryMismatch as exc:
                raise _common.history_mismatch(args.input, args.scheme, exc) from None
            except ValueError as exc:  # e.g. a triangle too thin for float64 children
                named = [args.input]  # a mark file's errors name it, not the mesh
                if getattr(args, "mark_file", None):  # as given, or as Path spells it
                    named += [args.mark_file, str(Path(args.mark_file))]
                if str(exc).startswith(tuple(f"{n}{c}" for n in named for c in ":,")):
                    raise
                raise ValueError(f"{args.input}: {exc}") from None
            refine_s, start = time.perf_counter() - start, time.perf_counter()
            progress.step(f"writing {args.output}")
            _common.write_mesh(args, fine)
            write_s = time.perf_counter() - start
        if not args.quiet:
            print(f"{args.output}: {_common.counted(fine.n_triangles, 'triangle')}, "
                  f"{_common.counted(fine.n_points, 'point')} ({summary}; read {read_s:.2f} s, "
                  f"refined {refine_s:.2f} s, written {write_s:.2f} s)")
    return 0


def _check_options(args: argparse.Namespace) -> int:
    """Option combinations argparse cannot express; returns the number of refinements."""
    marked = marks.given(args)
    if args.cycles is not None and not marked:
        raise _common.UsageError("--cycles needs a mark: --mark-tag, --mark-box or --mark-file")
    if args.levels is not None and marked:
        raise _common.UsageError("--levels refines every triangle; with a mark use --cycles")
    if args.dask is not None and marked:
        raise _common.UsageError("--dask refines every triangle; it takes no mark")
    value = args.cycles if marked else args.levels
    return 1 if value is None else value


def _refiner(args: argparse.Namespace):
    """The refinement path for these options: ``f(mesh, args, progress) -> (mesh, text)``."""
    if marks.given(args):
        return _local
    return _uniform


def _uniform(mesh: Mesh, args: argparse.Namespace, progress: _common.Progress,
             raw: RawMesh) -> tuple[Mesh, str]:
    levels = 1 if args.levels is None else args.levels
    check_memory(mesh, args.scheme, levels)  # all levels, before the first one allocates
    n0, first = mesh.n_triangles, mesh
    for level in range(1, levels + 1):
        progress.step(f"refining, level {level}/{levels}")
        try:
            mesh = refine(mesh, args.scheme)
        except RefusedTriangle as exc:  # named by the triangle of IN, in IN's numbering
            exc = exc.at_input(first, level, get_scheme(args.scheme).n_children)
            if raw.triangle_numbers is not None and raw.point_numbers is not None:
                exc = exc.numbered(int(raw.triangle_numbers[exc.triangle]),
                                   tuple(int(raw.point_numbers[v]) for v in exc.vertices))
            raise exc from None
    if not levels:
        return mesh, f"{_common.counted(n0, 'triangle')} copied, 0 levels"
    return mesh, (f"{_common.counted(n0, 'triangle')} refined by {args.scheme}, "
                  f"{_common.counted(levels, 'level')}")


def _on_dask(args: argparse.Namespace) -> int:
    """``--dask``: store to store on a Dask cluster (:func:`qdrefine.distributed.refine_store`)."""
    from ..distributed import refine_store
    from ..store import is_store, location
    from ..store.layout import group_of

    _common.check_compress(args.output, args.compress)
    _common.check_format_version(args.output, args.format_version)
    if not is_store(args.input):
        if args.input.rstrip("/").lower().endswith(_common.STORE) or "://" in args.input:
            group_of(location(args.input))  # why it is not one: incomplete, missing, ...
        raise ValueError(f"{args.input}: --dask needs a Zarr mesh store as IN (a path or URL); "
                         f"make one with 'qdrefine convert {args.input} IN.zarr'")
    if "://" in args.output:  # a URL (s3://, memory://, ...): no local checks apply
        if not args.output.rstrip("/").lower().endswith(_common.STORE) or args.binary:
            raise ValueError(f"{args.output}: expected a Zarr mesh store (a name ending in "
                             f"{_common.STORE}), without --binary")
    else:
        _common.check_output(args.output, (args.input,), kinds="store", binary=args.binary)
    levels = 1 if args.levels is None else args.levels
    with _common.Progress(1, args.quiet) as bar:
        def progress(text: str, done: int, total: int) -> None:  # noqa: ARG001
            if text.startswith("dask"):  # the dashboard link (or "cluster ready")
                if not args.quiet:
                    print(text, file=sys.stderr)
            else:
                bar.step(text, total)

        summary = refine_store(args.input, args.output, args.scheme, levels,
                               address=args.dask or None, progress=progress)
    if not args.quiet:
        print(f"{args.output}: {summary.n_triangles} triangles, {summary.n_points} points "
              f"({args.scheme}, {levels} level{'s' if levels != 1 else ''} on "
              f"{summary.n_workers} Dask worker{'s' if summary.n_workers != 1 else ''}, "
              f"{summary.seconds:.2f} s)")
    return 0


def _local(mesh: Mesh, args: argparse.Namespace, progress: _common.Progress,
           raw: RawMesh) -> tuple[Mesh, str]:
    """``--cycles`` rounds of mark and refine (transitions coarsened before refined)."""
    cycles = 1 if args.cycles is None else args.cycles
    mark, mesh = marks.marker(mesh, args)
    n0, n_marked = mesh.n_triangles, 0
    for cycle in range(1, cycles + 1):
        progress.step(f"refining, cycle {cycle}/{cycles}")
        marked = mark(mesh)
        n_marked += int(marked.sum())
        mesh = refine_marked(mesh, marked, args.scheme)[0]
    mesh = marks.without_marks(mesh, args)
    return mesh, (f"{_common.counted(n_marked, 'triangle')} marked, {mesh.n_triangles - n0} "
                  f"added by {args.scheme} in {_common.counted(cycles, 'cycle')}")
