"""Hostile geometry and environment through the real command line (issue 17, items 4 to 6).

Usage (from the repository root)::

    python benchmarks/robustness/bad_input.py [--soup 300000]

Every case writes its input to a fresh folder, runs ``qdrefine refine IN OUT`` (and
``qdrefine check IN``, or the command the case names) as a subprocess and records: the exit
code, the number of lines on stderr and the first one, whether OUT exists afterwards, whether
the folder holds exactly the input files with their bytes unchanged, and the wall time. The
adversarial soups (``--soup`` separate triangles) are timed through the Python API
(``Mesh(points, triangles)``). Results go to ``benchmarks/robustness/bad_input.json`` and to
the section of ``docs/robustness.md`` between the markers below (``study.py`` keeps it).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import qdrefine  # noqa: E402
from qdrefine import examples  # noqa: E402

START = "<!-- hostile input: written by benchmarks/robustness/bad_input.py -->"
END = "<!-- end of hostile input -->"

Case = tuple[str, dict[str, str], list[str], bool]  # name, files, command, should succeed


def _needles() -> str:
    points = np.array([[0, 0], [1, 0], [0.5, 0.9], [0.5, -1e-8]]) + 1e7
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "n.msh"
        qdrefine.write(path, qdrefine.Mesh(points, [[0, 1, 2], [0, 3, 1]]))
        return path.read_text()


def _square(n: int) -> str:
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "s.msh"
        qdrefine.write(path, examples.square(n))
        return path.read_text()


def cases() -> list[Case]:
    from test_bad_input import HANGING, HANGING_TRIS, INNER, INNER_TRIS, SQ, SQ_TRIS, msh22

    crack = HANGING[:3] + [(1.0, -4e-18)] + HANGING[4:]
    inside = HANGING[:3] + [(1.0, 4e-18)] + HANGING[4:]
    return [
        ("boundary edges crossing", {"in.msh": msh22(
            [(0, 0), (2, 0), (0, 2), (1, -1), (1.5, -1), (1.2, 3)], [(0, 1, 2), (3, 4, 5)])},
         ["refine", "in.msh", "out.vtu"], False),
        ("separate piece on top (no crossing)", {"in.msh": msh22(
            SQ + [(0.2, 0.2), (0.4, 0.2), (0.2, 0.4)], SQ_TRIS + [(4, 5, 6)])},
         ["refine", "in.msh", "out.vtu"], False),
        ("vertex inside a triangle by 4e-18", {"in.msh": msh22(inside, HANGING_TRIS)},
         ["refine", "in.msh", "out.vtu"], False),
        ("copy of an inner vertex", {"in.msh": msh22(INNER, INNER_TRIS)},
         ["refine", "in.msh", "out.vtu"], False),
        ("vertex outside by 4e-18 (a crack): refines", {"in.msh": msh22(crack, HANGING_TRIS)},
         ["refine", "in.msh", "out.vtu", "-q"], True),
        ("crack: check passes with a warning", {"in.msh": msh22(crack, HANGING_TRIS)},
         ["check", "in.msh"], True),
        ("refused at level 2: names the input triangle", {"in.msh": _needles()},
         ["refine", "in.msh", "out.msh", "--levels", "2"], False),
        ("reading over the memory limit", {"in.msh": _square(30)},
         ["refine", "in.msh", "out.vtu", "ENV:QDREFINE_MEMORY_LIMIT=50KiB"], False),
    ]


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def run_case(case: Case) -> dict:
    name, files, command, succeed = case
    env = dict(os.environ)
    args = [a for a in command if not a.startswith("ENV:")]
    for a in command:
        if a.startswith("ENV:"):
            k, v = a[4:].split("=", 1)
            env[k] = v
    with tempfile.TemporaryDirectory() as d:
        folder = Path(d)
        for f, text in files.items():
            (folder / f).write_text(text)
        before = _snapshot(folder)
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-m", "qdrefine", *args], cwd=folder, env=env,
                           capture_output=True, text=True, timeout=120)
        seconds = time.perf_counter() - t0
        outputs = [a for a in args[2:] if "." in a and a.split(".")[-1] in ("vtu", "msh")]
        made = any((folder / o).exists() for o in outputs)
        after = _snapshot(folder)
        untouched = all(after.get(k) == v for k, v in before.items())
        extra = sorted(set(after) - set(before) - set(outputs))
    lines = r.stderr.splitlines()
    ok = (r.returncode == 0 and not lines) if succeed else (
        r.returncode != 0 and len(lines) == 1 and not made)
    return {"case": name, "command": "qdrefine " + " ".join(command), "exit": r.returncode,
            "stderr_lines": len(lines), "stderr": lines[0] if lines else "",
            "output_written": made, "input_untouched": untouched, "stray_files": extra,
            "seconds": seconds, "as_expected": bool(ok and untouched and not extra)}


def read_only_import() -> dict:
    """Install folder and user cache unwritable (both replaced by files): import works."""
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        pkg = tmp / "site" / "qdrefine"
        shutil.copytree(Path(qdrefine.__file__).parent, pkg,
                        ignore=shutil.ignore_patterns("__pycache__"))
        for folder in [pkg, *[p for p in pkg.rglob("*") if p.is_dir()]]:
            (folder / "__pycache__").write_text("")
        (tmp / "cache").write_text("")
        (tmp / "t").mkdir()
        env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
        env |= {"PYTHONPATH": str(tmp / "site"), "XDG_CACHE_HOME": str(tmp / "cache"),
                "HOME": str(tmp / "cache"), "TMPDIR": str(tmp / "t"),
                "PYTHONDONTWRITEBYTECODE": "1"}
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-c", "import qdrefine"], env=env,
                           capture_output=True, text=True, timeout=120)
        seconds = time.perf_counter() - t0
    lines = r.stderr.splitlines()
    return {"case": "import from a read-only install", "command": "python -c 'import qdrefine'",
            "exit": r.returncode, "stderr_lines": len(lines),
            "stderr": lines[0] if lines else "", "output_written": False,
            "input_untouched": True, "stray_files": [], "seconds": seconds,
            "as_expected": r.returncode == 0 and len(lines) == 1}


def soups(m: int) -> list[dict]:
    from validation_bench import soup

    out = []
    for kind in ("stacked", "slivers", "scattered", "grid"):
        p, t = soup(kind, m)
        c0, t0 = time.process_time(), time.perf_counter()
        try:
            qdrefine.Mesh(p, t)
            verdict = "valid"
        except ValueError as exc:
            verdict = str(exc).split(":")[0]
        out.append({"soup": kind, "triangles": len(t), "seconds": time.perf_counter() - t0,
                    "cpu_seconds": time.process_time() - c0, "verdict": verdict})
    return out


def section(res: dict) -> str:
    w = [START, "", "## 4. Hostile geometry and environment (issue 17)", "",
         f"Generated by `python benchmarks/robustness/bad_input.py --soup {res['soup']}` on "
         f"{res['date']} (load average {res['load'][0]:.1f} before, {res['load_after'][0]:.1f}"
         " after, on the shared 2-core machine); raw results in "
         "[`bad_input.json`](../benchmarks/robustness/bad_input.json). A failing case must "
         "exit non-zero with one line on stderr, write no output and leave the input "
         "unchanged; a case marked *refines* must succeed silently.", "",
         "| case | command | exit | stderr | output written | input untouched | seconds | "
         "as expected |", "|---|---|---|---|---|---|---|---|"]
    for c in res["cases"]:
        msg = c["stderr"].replace("|", "\\|")
        w.append(f"| {c['case']} | `{c['command']}` | {c['exit']} | {c['stderr_lines']} line: "
                 f"`{msg[:160]}{'...' if len(msg) > 160 else ''}` | {c['output_written']} | "
                 f"{c['input_untouched']} | {c['seconds']:.2f} | {c['as_expected']} |")
    w += ["", "Adversarial soups of separate triangles, `Mesh(points, triangles)` (the "
          "validation of every reader too): `stacked` long parallel slivers whose bounding "
          "boxes all overlap (valid; the plane sweep runs to the end), `slivers` and "
          "`scattered` random overlapping ones (refused at the first crossing), `grid` small "
          "separate ones (valid).", "",
          "| soup | triangles | verdict | seconds (wall) | seconds (CPU) |",
          "|---|---|---|---|---|"]
    for s in res["soups"]:
        w.append(f"| {s['soup']} | {s['triangles']:,} | {s['verdict']} | {s['seconds']:.2f} | "
                 f"{s['cpu_seconds']:.2f} |")
    return "\n".join(w + ["", END])


def keep(path: Path, page: str) -> str:
    """``page`` (a new ``docs/robustness.md``) with the hostile-input section of the page
    now at ``path``, if it has one (for ``study.py``)."""
    old = path.read_text() if path.exists() else ""
    if START in old and END in old:
        return splice(page, old[old.index(START):old.index(END) + len(END)])
    return page


def splice(page: str, part: str, start: str = START, end: str = END) -> str:
    """``page`` with its section between the markers ``start`` and ``end`` (default: the
    hostile-input section) replaced by ``part`` (appended if absent)."""
    if start in page and end in page:
        return page[:page.index(start)] + part + page[page.index(end) + len(end):]
    return page.rstrip("\n") + "\n\n" + part + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--soup", type=int, default=300_000)
    args = ap.parse_args()
    from datetime import date

    res = {"date": str(date.today()), "soup": args.soup, "load": os.getloadavg(),
           "cases": [run_case(c) for c in cases()] + [read_only_import()],
           "soups": soups(args.soup)}
    res["load_after"] = os.getloadavg()
    (ROOT / "benchmarks" / "robustness" / "bad_input.json").write_text(
        json.dumps(res, indent=1))
    page = ROOT / "docs" / "robustness.md"
    page.write_text(splice(page.read_text(), section(res)))
    print(section(res))


if __name__ == "__main__":
    main()
