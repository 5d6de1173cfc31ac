"""``qdrefine demo [OUTDIR]``: refine the built-in example, summarize, write files."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from .. import examples, report
from ..io import write
from ..io.atomic import file_set
from ..mesh import Mesh
from ..plot import mesh as plot_mesh
from ..quality import min_angles
from ..refine import refine
from ..schemes import scheme_names
from ..topology import conformity, euler_characteristic
from . import _common

HELP = "refine a built-in example (plate with a hole) with every scheme, write mesh, plot, report"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser)
    parser.epilog = ("Writes OUTDIR/plate_with_hole.msh (the example), "
                     "OUTDIR/plate_with_hole_7t-qd.msh (refined, Gmsh 4.1 with its tags), "
                     "OUTDIR/plate_with_hole_7t-qd.png (coloured by minimum angle) and "
                     "OUTDIR/report.txt (quality report).")
    parser.add_argument("outdir", metavar="OUTDIR", nargs="?", default="qdrefine-demo",
                        help="directory for the files (default ./qdrefine-demo; created)")
    parser.add_argument("--levels", type=_common.positive, default=None, metavar="N",
                        help="refinement levels, at least 1 (default 2; not with --afem)")
    parser.add_argument("--afem", action="store_true",
                        help="instead: adaptive finite elements on the Gmsh L-shape (Poisson, "
                             "scikit-fem P1, residual estimator, Doerfler 0.5) with 7t-qd, "
                             "7t-le, 4t-le and scikit-fem's own refinement; writes "
                             "OUTDIR/afem.png and OUTDIR/afem.json (needs qdrefine[fem])")
    parser.add_argument("--cycles", type=_common.positive, default=None, metavar="K",
                        help="cycles of the --afem loop (default 10; with --afem only)")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        return _run(args)


def _run(args: argparse.Namespace) -> int:
    if args.afem and args.levels is not None:
        raise _common.UsageError("--levels applies to the plate demo; --afem takes --cycles")
    if not args.afem and args.cycles is not None:
        raise _common.UsageError("--cycles applies to --afem only")
    args.levels = 2 if args.levels is None else args.levels
    args.cycles = 10 if args.cycles is None else args.cycles
    out = Path(args.outdir)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"{out}: exists and is not a directory")
    if args.afem:  # needs qdrefine[fem]: say so before OUTDIR is made
        import skfem  # noqa: F401
    else:  # and too little memory too
        report.check_study_memory(examples.plate_with_hole(), scheme_names(), args.levels,
                                  "the demo", keep_all=True)
    say = (lambda *a: None) if args.quiet else print
    with file_set(out) as tmp:  # every file, or none (and no folder made)
        names = _afem(tmp, args.cycles, say, args.quiet) if args.afem else \
            _plate(tmp, args.levels, say, args.quiet)
    say("wrote " + ", ".join(str(out / name) for name in names))
    return 0


def _plate(out: Path, levels: int, say, quiet: bool) -> list[str]:
    """The plate demo: every scheme, ``levels`` levels; the files' names in ``out``."""
    mesh = examples.plate_with_hole()
    say(f"example: plate with a hole, {mesh.n_points} points, {mesh.n_triangles} triangles, "
        f"min angle {min_angles(mesh).min():.2f} deg")
    header = (f"{'scheme':8} {'level':>5} {'triangles':>10} {'points':>9} {'conforming':>10} "
              f"{'euler':>5} {'min angle':>9} {'mean min':>9}")
    say(header)
    say("-" * len(header))
    chi0 = euler_characteristic(mesh)
    names = scheme_names()
    finest = {}
    with _common.Progress(len(names) * levels + 3, quiet) as progress:
        for name in names:
            fine = mesh
            for level in range(1, levels + 1):
                progress.step(f"{name}, level {level}")
                fine = refine(fine, name)
                finest[name] = fine
                chi = euler_characteristic(fine)
                ok = conformity(fine).ok and chi == chi0
                angles = min_angles(fine)
                say(f"{name:8} {level:>5} {fine.n_triangles:>10} {fine.n_points:>9} "
                    f"{'yes' if ok else 'NO':>10} {chi:>5} "
                    f"{angles.min():>9.3f} {np.mean(angles):>9.3f}")
        for group in _same_meshes(finest):
            say(f"{', '.join(group)}: the same meshes here (they choose differently only on "
                "some shapes; docs/schemes.md)")
        progress.step("writing meshes")
        fine = refine(mesh, "7t-qd", levels)
        stem = "plate_with_hole_7t-qd"
        files = [out / "plate_with_hole.msh", out / f"{stem}.msh", out / f"{stem}.png",
                 out / "report.txt"]
        write(files[0], mesh)
        write(files[1], fine)
        progress.step("drawing")
        counted = _common.counted(levels, "level")
        ax = plot_mesh(fine, color="min-angle",
                       title=f"Plate with a hole, 7T-QD, {counted}: "
                             f"{fine.n_triangles} triangles")
        _common.save_figure(ax.figure, files[2])
        progress.step("writing the report")
        text = (f"{files[1].name}: the example refined by 7t-qd, {counted}\n\n"
                + report.format_info(report.info(fine)) + "\n\n"
                + report.format_quality(report.quality(fine)) + "\n")
        _common.write_text(files[3], text)
    say("")
    return [f.name for f in files]


def _same_meshes(meshes: dict[str, Mesh]) -> list[list[str]]:
    """Groups of two or more names whose meshes are equal (points and triangles)."""
    groups: list[list[str]] = []
    for name, m in meshes.items():
        for group in groups:
            first = meshes[group[0]]
            if np.array_equal(first.points, m.points) and \
                    np.array_equal(first.triangles, m.triangles):
                group.append(name)
                break
        else:
            groups.append([name])
    return [g for g in groups if len(g) > 1]


def _afem(out: Path, cycles: int, say, quiet: bool) -> list[str]:
    """``--afem``: the adaptive loop of :mod:`qdrefine.afem` for every method; the files'
    names in ``out``."""
    import matplotlib.pyplot as plt

    from .. import afem

    mesh = examples.gmsh_mesh("l_shape")
    say(f"AFEM on the Gmsh L-shape ({mesh.n_triangles} triangles, min angle "
        f"{min_angles(mesh).min():.1f} deg): Poisson with the singular solution, P1, "
        f"residual estimator, Doerfler 0.5, {cycles} cycles")
    results = {}
    with _common.Progress(len(afem.METHODS), quiet) as progress:
        for method in afem.METHODS:
            progress.step(method)
            results[method] = [c.__dict__ for c in afem.run(mesh, method, cycles)]
    header = (f"{'method':11} {'DOFs':>7} {'error':>9} {'rate':>6} {'min angle/initial':>18} "
              f"{'added/marked':>14}")
    say(header)
    say("-" * len(header))
    for method, rows in results.items():
        added = [r["added"] / r["marked"] for r in rows if r["marked"]]
        rate = f"{afem.rate(rows):>6.2f}" if len(rows) > 1 else f"{'n/a':>6}"  # a slope
        spread = f"{np.median(added):>14.1f}" if added else f"{'n/a':>14}"
        say(f"{method:11} {rows[-1]['dofs']:>7} {rows[-1]['error']:>9.3g} {rate} "
            f"{min(r['min_angle_ratio'] for r in rows):>18.3f} {spread}")
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    afem.plot_error(results, axes[0])
    afem.plot_min_angle(results, axes[1])
    fig.tight_layout()
    files = [out / "afem.png", out / "afem.json"]
    _common.save_figure(fig, files[0])
    _common.write_text(files[1], json.dumps(results, indent=1) + "\n")
    return [f.name for f in files]
