"""Geometry robustness study of qdrefine (issue 7, part 1): run everything, write the page.

Usage (from the repository root; Triangle comes with ``pip install -e '.[bench]'``)::

    python benchmarks/robustness/study.py            # the full study, about 5 minutes
    python benchmarks/robustness/study.py --quick    # a smoke run with small samples
    python benchmarks/robustness/study.py --page-only  # rewrite the page from the JSON

Before measuring, it runs its own self-checks (``python -m pytest benchmarks/robustness``:
exact signs, oracles, checks that must catch known bad cases) and stops if one fails.

writes ``docs/robustness.md`` (tables, method, verdicts), ``benchmarks/robustness/
results.json`` (every count) and ``docs/img/robustness/scipy_failures.{png,svg}``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from datetime import date
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path[0] = str(ROOT / "benchmarks")  # import the package, not its modules one by one

import numba  # noqa: E402
import numpy as np  # noqa: E402

import qdrefine  # noqa: E402
from robustness import (  # noqa: E402
    bad_input,
    delaunay,
    exhibit,
    families,
    refinement,
    report,
    rows,
)


def machine() -> dict:
    """The machine and software the study ran on."""
    cpu = "unknown"
    mem = "unknown"
    try:
        cpu = next(ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo")
                   if ln.startswith("model name"))
        kb = next(int(ln.split()[1]) for ln in open("/proc/meminfo") if ln.startswith("MemTotal"))
        mem = f"{kb / 2**20:.0f} GiB"
    except (OSError, StopIteration):
        pass
    versions = {"python": platform.python_version(), "numpy": np.__version__,
                "qdrefine": qdrefine.__version__}
    for m in ("scipy", "triangle"):
        versions[m] = delaunay.version(m) if delaunay.available(m) else "not installed"
    import matplotlib

    versions["matplotlib"] = matplotlib.__version__
    return {"platform": platform.platform(), "cpu": cpu, "cores": os.cpu_count(),
            "memory": mem, "versions": versions, "qdrefine_source": _source()}


def _source() -> dict:
    out = {"path": str(Path(qdrefine.__file__).parent)}
    try:
        git = ["git", "-C", str(ROOT)]
        out["commit"] = subprocess.run(git + ["rev-parse", "--short", "HEAD"], check=True,
                                       capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(git + ["status", "--porcelain", "src"], check=True,
                               capture_output=True, text=True).stdout.strip()
        out["src_modified"] = bool(dirty)
    except (OSError, subprocess.CalledProcessError):
        pass
    return out


def run(n_qd: int, n_delaunay: int, n_fraction: int, n_patches: int, levels: int,
        seed: int, img: Path | None, log=print) -> dict:
    """Every part of the study; returns the JSON-ready results."""
    numba.set_num_threads(1)  # tiny arrays; outputs do not depend on the thread count
    methods = tuple(m for m in delaunay.METHODS if delaunay.available(m))
    out: dict = {"families": {}, "qd": {}, "delaunay": {}, "refinement": {}, "timing": {}}
    clock = {"qd": 0.0, "delaunay": 0.0, "refinement": 0.0}
    for fam in families.FAMILIES:
        for place in families.PLACEMENTS:
            key = f"{fam}/{place}"
            b = families.make(fam, place, max(n_qd, n_delaunay, n_patches), seed)
            out["families"][key] = {"generated": b.generated, "dropped_collinear": b.dropped,
                                    "exact_points": b.exact_points, "curves": b.curves,
                                    "ranges": families.describe(b.vertices)}
            t = time.perf_counter()
            out["qd"][key] = rows.qd_row(b.vertices[:n_qd], n_fraction, seed)
            clock["qd"] += time.perf_counter() - t
            t = time.perf_counter()
            out["delaunay"][key] = rows.delaunay_row(b.vertices[:n_delaunay], methods,
                                                     n_fraction, seed)
            clock["delaunay"] += time.perf_counter() - t
            t = time.perf_counter()
            for scheme in ("7t-qd", "7t-d"):
                out["refinement"].setdefault(scheme, {})[key] = refinement.study(
                    b.vertices[:n_patches], scheme, levels)
            clock["refinement"] += time.perf_counter() - t
            log(f"{key}: done ({sum(clock.values()):.0f} s)")
    t = time.perf_counter()
    ex = {"collinear": exhibit.find_collinear(), "dropped": exhibit.find_dropped(),
          "paper_example": exhibit.paper_example()}
    if img is not None and ex["collinear"] and ex["dropped"]:
        img.mkdir(parents=True, exist_ok=True)
        files = exhibit.draw(ex["collinear"], ex["dropped"], img / "scipy_failures")
        ex["figure"] = [str(f) for f in files]
    out["exhibits"] = ex
    clock["exhibits"] = time.perf_counter() - t
    out["timing"] = {k: round(v, 1) for k, v in clock.items()}
    out["methods"] = list(methods)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "robustness.md")
    ap.add_argument("--json", type=Path, default=ROOT / "benchmarks" / "robustness"
                    / "results.json")
    ap.add_argument("--img", type=Path, default=ROOT / "docs" / "img" / "robustness")
    ap.add_argument("--n-qd", type=int, default=10000, help="triangles per row, 7T-QD part")
    ap.add_argument("--n-delaunay", type=int, default=3000, help="nine-point sets per row")
    ap.add_argument("--n-fraction", type=int, default=50,
                    help="triangles per row checked again with fractions.Fraction")
    ap.add_argument("--patches", type=int, default=30, help="patches per row, refinement")
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="small samples (smoke test)")
    ap.add_argument("--page-only", action="store_true",
                    help="rewrite the page from the existing --json results, run nothing")
    args = ap.parse_args(argv)
    if args.page_only:
        results = json.loads(args.json.read_text())
        args.out.write_text(bad_input.keep(args.out, report.markdown(
            results, args.out, args.img, args.json)))
        print(f"wrote {args.out} from {args.json}")
        return 0
    if args.quick:
        args.n_qd, args.n_delaunay, args.n_fraction, args.patches = 300, 100, 10, 3
    # the instruments first: exact signs, oracles, checks that must catch known bad cases
    check = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                            str(Path(__file__).with_name("test_study.py"))], cwd=ROOT)
    if check.returncode:
        print("the study's self-checks failed: nothing measured", file=sys.stderr)
        return 1
    start = time.perf_counter()
    results = run(args.n_qd, args.n_delaunay, args.n_fraction, args.patches, args.levels,
                  args.seed, args.img)
    results["meta"] = {
        "command": "python benchmarks/robustness/study.py" + (" --quick" if args.quick else ""),
        "date": date.today().isoformat(), "seconds": round(time.perf_counter() - start, 1),
        "seed": args.seed, "n_qd": args.n_qd, "n_delaunay": args.n_delaunay,
        "n_fraction": args.n_fraction, "patches": args.patches, "levels": args.levels,
        "machine": machine()}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(report.to_json(results))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(bad_input.keep(args.out, report.markdown(
        results, args.out, args.img, args.json)))
    print(f"wrote {args.out}, {args.json} ({results['meta']['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
