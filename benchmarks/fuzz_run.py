"""A long fuzzing run of the readers: the mutations of ``tests/test_fuzz.py`` (byte flips,
truncations, deleted, duplicated and inserted lines and bytes, replaced number tokens; one
to three per file) applied to a valid file of every format, many times per format.

Each mutated file is read with :func:`qdrefine.read` under an alarm and sorted into
outcomes: ``read`` (a valid mesh: :func:`qdrefine.check.find` finds no error),
``refused`` (``ValueError`` / ``OSError`` / ``MemoryError`` whose message starts with the
file name), and the failures the issue counts: ``hang`` (no answer within the alarm),
``traceback`` (any other exception), ``unnamed`` (a refusal that does not name the file),
``invalid`` (a mesh that does not pass the checks), ``shortened`` (a file *truncated* by
the mutation read as a mesh with fewer triangles), ``input changed``. A deleted line that
leaves a smaller valid file (an OBJ face, a whole STL facet is not one line) is counted as
``smaller after a deleted line``: formats without declared counts cannot tell.

Needs the test extra (``pip install -e '.[test]'``: the mutations use hypothesis). Usage::

    python benchmarks/fuzz_run.py [--per-format 10000] [--json FILE] [--write-docs]

The results go to ``--json`` (default ``benchmarks/results/fuzz-DATE.json``); with
``--write-docs`` section 5 of ``docs/robustness.md`` is rewritten from them (only for a run
meant to replace the published counts).
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import sys
import tempfile
import time
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the mutations and seed files of the fuzz tests
sys.path.insert(0, str(ROOT / "benchmarks"))

from robustness.bad_input import splice  # noqa: E402

import qdrefine  # noqa: E402
from qdrefine import check  # noqa: E402
from test_fuzz import (  # noqa: E402
    ALLOWED,
    MAIN,
    SEEDS,
    TOKENS,
    Hang,
    alarm,
    mutate,
    names_file,
)

START = "<!-- fuzzing run: written by benchmarks/fuzz_run.py -->"
END = "<!-- end of fuzzing run -->"
PAGE = ROOT / "docs" / "robustness.md"
KINDS = ["flip", "truncate", "delete-line", "duplicate-line", "token", "insert"]
FAILURES = ("hang", "traceback", "unnamed", "invalid", "shortened", "input changed")


def run_format(name: str, count: int, seconds: int) -> tuple[Counter, list[str]]:
    rng = np.random.default_rng(sorted(SEEDS).index(name))
    outcomes: Counter = Counter()
    examples: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for name_, data in SEEDS[name].items():
            (folder / name_).write_bytes(data)
        path = folder / MAIN[name]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            seed_triangles = qdrefine.read(path).n_triangles
        for _ in range(count):
            files = dict(SEEDS[name])
            target = sorted(files)[int(rng.integers(len(files)))]
            ops = [(KINDS[int(rng.integers(len(KINDS)))], int(rng.integers(2**31)),
                    int(rng.integers(256)), TOKENS[int(rng.integers(len(TOKENS)))])
                   for _ in range(int(rng.integers(1, 4)))]
            files[target] = mutate(files[target], ops)
            for p in folder.iterdir():
                p.unlink()
            for name_, data in files.items():
                (folder / name_).write_bytes(data)
            outcome = _read(path, seconds, ops, seed_triangles)
            if {p.name: p.read_bytes() for p in folder.iterdir()} != files:
                outcome = "input changed"
            outcomes[outcome] += 1
            if outcome in FAILURES and len(examples) < 5:
                examples.append(f"{outcome}: {ops}")
    return outcomes, examples


def _read(path: Path, seconds: int, ops, seed_triangles: int) -> str:
    try:
        with alarm(seconds), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                mesh = qdrefine.read(path)
            except ALLOWED as exc:
                return "refused" if names_file(str(exc), path) else "unnamed"
    except Hang:
        return "hang"
    except Exception:  # noqa: BLE001 - anything else is a failure to count
        return "traceback"
    found = check.find(mesh.points, mesh.triangles, mesh.cell_tags, mesh.edges,
                       mesh.edge_tags)
    if not found.ok:
        return "invalid"
    if mesh.n_triangles < seed_triangles:
        kinds = {op[0] for op in ops}
        if "truncate" in kinds:
            return "shortened"
        if "delete-line" in kinds:
            return "smaller after a deleted line"
    return "read"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--per-format", type=int, default=10_000)
    parser.add_argument("--seconds", type=int, default=10, help="alarm per file")
    parser.add_argument("--formats", default=",".join(sorted(SEEDS)))
    parser.add_argument("--json", type=Path, default=None,
                        help="results file (default benchmarks/results/fuzz-DATE.json)")
    parser.add_argument("--write-docs", action="store_true",
                        help="also rewrite section 5 of docs/robustness.md from this run")
    args = parser.parse_args(argv)
    date = datetime.date.today().isoformat()
    result = {"date": date, "machine": platform.platform(), "per_format": args.per_format,
              "alarm_seconds": args.seconds, "formats": {}}
    for name in args.formats.split(","):
        t = time.perf_counter()
        outcomes, examples = run_format(name, args.per_format, args.seconds)
        result["formats"][name] = {"outcomes": dict(outcomes), "failure_examples": examples,
                                   "seconds": time.perf_counter() - t}
        print(name, dict(outcomes), f"{time.perf_counter() - t:.0f} s", flush=True)
    path = args.json or ROOT / "benchmarks" / "results" / f"fuzz-{date}.json"
    path.write_text(json.dumps(result, indent=1))
    print("wrote", path)
    if args.write_docs:  # was whenever --json was not given: a short try replaced the
        # published counts (newcomer review)
        PAGE.write_text(splice(PAGE.read_text(), section(result, path.name), START, END))
        print("wrote", PAGE)


COLUMNS = ("hang", "traceback", "unnamed", "invalid", "shortened", "input changed",
           "smaller after a deleted line")


def section(result: dict, name: str) -> str:
    """Section 5 of ``docs/robustness.md`` from a run's results (``name``: its JSON file)."""
    w = [START, "", "## 5. Fuzzing run of the readers (issue 17)", "",
         f"`python benchmarks/fuzz_run.py --per-format {result['per_format']}` on "
         f"{result['date']} (the shared 2-core machine; raw results in "
         f"[`{name}`](../benchmarks/results/{name})): the mutations of `tests/test_fuzz.py` "
         "(byte flips, truncations, deleted, duplicated and inserted lines and bytes, number "
         "tokens replaced by `nan`, `inf`, `-1`, `1e308`, `4294967296`, ...; one to three per "
         f"file) applied {result['per_format']:,} times to a valid file of each format, each "
         f"read by `qdrefine.read` under a {result['alarm_seconds']} s alarm that raises a "
         "`BaseException` (so no reader's `except Exception` can take a hang for a refusal). "
         "*read*: a mesh that passes every check; *refused*: one `ValueError` / `OSError` / "
         "`MemoryError` whose message starts with the file name (or with a file of its "
         "folder that it names as the file's: an XDMF file's heavy data). The failures: "
         "*hang*; "
         "*traceback* (any other exception); *unnamed* (a refusal without the file name); "
         "*invalid* (a mesh that fails the checks); *shortened* (a truncated file read as "
         "fewer triangles); *input changed*; *smaller after a deleted line* (a deleted line "
         "read as fewer triangles).", "",
         "| format | files | read | refused | " + " | ".join(COLUMNS) + " | seconds |",
         "|---" * (len(COLUMNS) + 5) + "|"]
    for fmt, r in result["formats"].items():
        o = r["outcomes"]
        w.append(f"| {fmt} | {sum(o.values()):,} | {o.get('read', 0):,} | "
                 f"{o.get('refused', 0):,} | " + " | ".join(str(o.get(k, 0)) for k in COLUMNS)
                 + f" | {r['seconds']:.0f} |")
    w += ["", "What the run cannot see: a mutation that leaves a valid mesh of the same size "
          "(a changed digit of a coordinate) is a different mesh, not a detectable error (no "
          "format here has a checksum); an OBJ file from another tool without count "
          "comments, cut exactly at a line end, is a smaller valid OBJ file. The seed files "
          "are small (18 to 52 triangles), so most mutations hit structure; the run "
          "exercises `qdrefine.read` only (`check`, the command line and the writers are in "
          "the fuzz tests, with fewer examples).", "", END]
    return "\n".join(w)


if __name__ == "__main__":
    main()
