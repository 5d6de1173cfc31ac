"""Every figure, table and numeric claim of the 7T-QD paper, recomputed.

:func:`write_all` draws the paper's figures (matplotlib, Agg backend, imported lazily) and
writes ``report.md``: each claim of the paper quoted beside the value computed here, with a
verdict and a sentence derived from the computed values at run time. The paper's own figures
appear only in :data:`PAPER_CLAIMS` and :data:`PAPER_TABLE1` (quotations, never results).

Modules, one concern each: :mod:`.claims` (the quotations), :mod:`.sample` (the grid over
the diagram), :mod:`.table1` (Table 1 and the tolerance for "similar"), :mod:`.verdicts`
(every other claim), :mod:`.cost` (decision times), :mod:`.lemmas` (SymPy), :mod:`.qhull`
(Fig. 3), :mod:`.iterated` (iterated refinement), :mod:`.figures`, :mod:`.report`.

SciPy (Fig. 3) and SymPy (Lemmas 1 and 2) are optional (``pip install qdrefine[paper]``);
without them the report says what could not be checked.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .. import diagram as dg
from ..io import atomic_path
from ..io.atomic import file_set
from .claims import PAPER_CLAIMS, PAPER_TABLE1
from .cost import decision_costs
from .figures import save_all
from .iterated import counterexample_search, diagram_grid, iterate
from .lemmas import has, lemma_checks
from .qhull import find_qhull_failure, nine_points
from .report import build_report
from .sample import region_sample
from .verdicts import measure

__all__ = ["PAPER_CLAIMS", "PAPER_TABLE1", "write_all", "lemma_checks", "find_qhull_failure",
           "region_sample", "compute_context", "ITERATED_SCHEMES", "nine_points"]

#: Schemes of the iterated study.
ITERATED_SCHEMES = ("7t-qd", "7t-le", "7t-d", "4t-le", "4t-red")

#: How many ``progress`` calls :func:`compute_context` makes.
CONTEXT_STEPS = 3 + len(ITERATED_SCHEMES)


def _qhull_ns(n: int = 2000, seed: int = 0) -> float | None:
    """Time per triangle of ``scipy.spatial.Delaunay`` on the nine points (float)."""
    if not has("scipy"):
        return None
    from scipy.spatial import Delaunay

    rng = np.random.default_rng(seed)
    pts = [nine_points(v) for v in rng.uniform(0, 1, (n, 3, 2))]
    t0 = time.perf_counter()
    for p in pts:
        Delaunay(p)
    return (time.perf_counter() - t0) / n * 1e9


def compute_context(step: float = 1 / 1200, tol: float = 1e-10, iterated_grid: int = 60,
                    levels: int = 6, angle_measure: bool = True,
                    progress: Callable[[str], None] | None = None) -> dict:
    """Every number the report and the figures need (see :mod:`.report`); ``progress(text)``
    is called as each of the :data:`CONTEXT_STEPS` parts starts."""
    say = progress or (lambda _: None)
    say("the diagram's regions")
    res = dg.compute(tol=tol, angle_measure=angle_measure)
    res.extra_areas = {
        "qd_mean_above_d": dg.region_area("qd_mean_above_d", tol=tol).value,
        "I_II_differ": dg.arc_area(lambda x, y: dg._pred("shaded")(x, y)
                                   & (dg._pred("I")(x, y) | dg._pred("II")(x, y))),
    }
    say("sampling the diagram")
    sample = region_sample(step)
    m = measure(res, sample, decision_costs(), _qhull_ns())
    t0 = time.perf_counter()
    pts = diagram_grid(iterated_grid)
    its, search = {}, {}
    for s in ITERATED_SCHEMES:
        say(f"iterating {s}")
        its[s] = iterate(s, pts, levels)
        search[s] = counterexample_search(s, levels)
    iterated_s = time.perf_counter() - t0
    say("lemmas and Fig. 3")
    lemmas, qhull = lemma_checks(), find_qhull_failure()
    return {"res": res, "sample": sample, "m": m, "lemmas": lemmas,
            "qhull": qhull, "iterated": its, "search": search,
            "iterated_seconds": iterated_s, "claims": PAPER_CLAIMS, "table": PAPER_TABLE1,
            "step": step}


def write_all(outdir: str | Path, figures: bool = True,
              progress: Callable[[str], None] | None = None) -> Path:
    """Recompute everything and write the figures and ``report.md`` into ``outdir``;
    ``progress(text)`` is called as each of ``CONTEXT_STEPS + 2`` parts starts (``+ 1``
    without figures)."""
    start = time.time()
    if not os.fspath(outdir):  # Path("") is the working directory
        raise ValueError("the output directory is an empty name")
    out = Path(outdir)
    if out.exists() and not out.is_dir():  # before a minute of work, not after it
        raise NotADirectoryError(f"{out}: exists and is not a directory")
    if out.is_dir() and not os.access(out, os.W_OK | os.X_OK):
        raise PermissionError(f"{out}: cannot write into this directory")
    say = progress or (lambda _: None)
    path = out / "report.md"
    # the figures and the report, or none of them; the folder made before a minute of work
    with file_set(out) as folder:
        ctx = compute_context(progress=say)
        if figures:
            say("drawing the figures")
        ctx["figures"] = save_all(folder, ctx) if figures else []
        ctx["seconds"] = time.time() - start
        say(f"writing {path}")
        with atomic_path(folder / path.name) as tmp:  # the error names the file
            Path(tmp).write_text(build_report(ctx), encoding="utf-8")
    return path
