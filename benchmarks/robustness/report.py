"""The study's page (markdown) and raw results (JSON), from the results of ``study.run``.

Every number and every verdict on the page is computed here from the results; the paper's
statements appear only in :data:`PAPER` (quotations).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from .families import EXACT, FAMILIES, PLACEMENTS

#: The paper's robustness statements, quoted (section in brackets).
PAPER = {
    "distances": "to measure a distance between pairs of points is easier and far more "
                 "robust than compare angles or doing circumcircle tests (Sec. 1)",
    "general_position": "they [Delaunay refinement algorithms] are not robust dealing with "
                        "point sets that are not in general position ... longest edge "
                        "refinements always present point sets that are not in general "
                        "position (Sec. 1)",
    "collinear": "when introducing a point in the middle of an edge inevitable floating point "
                 "errors would make the three points not perfectly collinear paving the way "
                 "to the creation of degenerate triangles (Sec. 2)",
    "fig3": "Fig. 3. A failed output triangulation using CGAL in Matlab R2009b. ... The "
            "output ... reveals a triangle with collinear coordinates (Sec. 2)",
    "more_robust": "The new partition performs similarly compared to the Delaunay "
                   "triangulation (7T-D) with the benefit of being more robust (Abstract)",
}

DESCRIPTION = {
    "needle": "one short edge, smallest angle down to about 1e-8 rad",
    "cap": "one angle near pi (apex height down to 1e-8 of the base)",
    "near-equilateral": "apex within 1e-16..1e-2 of the equilateral one",
    "near-right": "apex on Thales' circle, radius off by 1e-16..1e-2",
    "near-tie": "apex on a tie curve of a decision, moved off by 1e-17..1e-3 (or not)",
    "exact-tie": "apex exactly on a tie curve, integer coordinates (exact points)",
    "exact-lattice": "integer triangles, angles down to about 1e-8 rad (exact points)",
}


def to_json(results: dict) -> str:
    return json.dumps(results, indent=1, sort_keys=False, default=_plain) + "\n"


def _plain(x):
    if hasattr(x, "item"):
        return x.item()
    return str(x)


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """95% Wilson score interval of a rate ``k / n``."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return max(0.0, c - h), min(1.0, c + h)


def _pct(x: float) -> str:
    """A percentage with two significant digits, ``100`` and ``99.x`` kept readable."""
    return f"{x:.1f}".removesuffix(".0") if x >= 10 else f"{x:.2g}"


def _rate(k: int, n: int) -> str:
    lo, hi = wilson(k, n)
    if k == 0:
        return f"0 of {n:,} (95% upper bound {_pct(100 * hi)}%)"
    return (f"{k:,} of {n:,} ({_pct(100 * k / n)}%, 95% CI {_pct(100 * lo)}-"
            f"{_pct(100 * hi)}%)")


def _keys(exact: bool | None = None, placement: str | None = None) -> list[str]:
    return [f"{f}/{p}" for f in FAMILIES for p in PLACEMENTS
            if (exact is None or (f in EXACT) == exact) and (placement in (None, p))]


def _sum(table: dict, field: str, keys: list[str]) -> int:
    return int(sum(table[k][field] for k in keys))


def _msum(results: dict, method: str, field: str, keys: list[str]) -> int:
    return int(sum(results["delaunay"][k]["methods"][method][field] for k in keys
                   if method in results["delaunay"][k]["methods"]))


# ----------------------------------------------------------------------------------------
# summary numbers and verdicts


def totals(r: dict) -> dict:
    """The headline counts of the study."""
    allk, exk, flk = _keys(), _keys(True), _keys(False)
    q = r["qd"]
    t = {
        "qd_n": _sum(q, "triangles", allk),
        "qd_vs_exact": _sum(q, "qdrefine_vs_exact", allk),
        "fraction": (_sum(q, "fraction_agree", allk), _sum(q, "fraction_checked", allk)),
        "naive_differs": _sum(q, "naive_differs", allk),
        "naive_differs_tie": _sum(q, "naive_differs_at_tie", allk),
        "naive_bad_decision": _sum(q, "naive_invalid_not_qdrefine", allk),
        "naive_order": _sum(q, "naive_order_dependent", allk),
        "qd_order": _sum(q, "qdrefine_order_dependent", allk),
        "qd_invalid": _sum(q, "qdrefine_invalid", allk),
        "qd_invalid_rows": [k for k in allk if q[k]["qdrefine_invalid"]],
        "naive_rows": {k: q[k]["naive_differs"] for k in allk if q[k]["naive_differs"]},
    }
    d = r["delaunay"]
    t["sets"] = _sum(d, "sets", allk)
    t["sets_exact"] = _sum(d, "sets", exk)
    t["sets_float"] = _sum(d, "sets", flk)
    t["off_line"] = _sum(d, "off_line", flk)
    t["not_distinct"] = _sum(d, "not_distinct", allk)
    for m in r["methods"]:
        for field in ("wrong_delaunay", "usable_7t", "zero_area", "missing_point", "errors",
                      "not_7", "expected_count", "broken", "inverted"):
            t[f"{m}:{field}"] = _msum(r, m, field, allk)
            t[f"{m}:{field}:exact"] = _msum(r, m, field, exk)
            t[f"{m}:{field}:exact-near"] = _msum(r, m, field, _keys(True, "near"))
            t[f"{m}:{field}:float"] = _msum(r, m, field, flk)
    frac = [d[k]["methods"].get("qdrefine 7t-d", {}) for k in allk]
    t["fraction_d"] = (sum(x.get("fraction_delaunay", 0) for x in frac),
                       sum(x.get("fraction_checked", 0) for x in frac))
    return t


def verdicts(r: dict, t: dict) -> list[tuple[str, str, str]]:
    """(quoted claim, what we measured, verdict) for each of the paper's statements."""
    out = []
    has_tri = "triangle" in r["methods"]
    sc_wrong = t.get("scipy:wrong_delaunay", 0)
    sc_broken = t.get("scipy:broken", 0)
    measured = (f"float64 7T-QD decision differs from the exact one on "
                f"{_rate(t['naive_differs'], t['qd_n'])} triangles; invalid partitions caused "
                f"by a float decision: {t['naive_bad_decision']}. SciPy's float Delaunay "
                f"returns an error, a zero-area or clockwise triangle or leaves a point out on "
                f"{_rate(sc_broken, t['sets'])} nine-point sets")
    if t["naive_bad_decision"] == 0 and sc_broken > 0:
        v = ("**confirmed for validity**: a wrong float comparison still yields a valid "
             "partition (the inner pentagon is convex, every fan of it is valid), while the "
             "float circumcircle code returns invalid triangulations. The float decision "
             "itself is not exact: it differs near ties")
    else:
        v = "**not confirmed**: float distance comparisons produced invalid partitions"
    out.append((PAPER["distances"], measured, v))
    ex = t["sets_exact"]
    s_ex = t.get("scipy:wrong_delaunay:exact", 0)
    s_near = t.get("scipy:wrong_delaunay:exact-near", 0)
    tri_wrong = t.get("triangle:wrong_delaunay", 0)
    measured = (f"on exact integer nine-point sets (collinear triples on every edge, exact ties "
                f"in `exact-tie`), SciPy/Qhull is wrong on {_rate(s_ex, ex)} sets ({s_near} of "
                f"them near the origin, the rest translated far from it)")
    if has_tri:
        measured += f"; Triangle is wrong on {_rate(tri_wrong, t['sets'])} sets of all families"
    v = ("**confirmed for SciPy/Qhull**" if s_ex else "**not reproduced with SciPy**")
    if has_tri:
        v += (", **not for a code with exact predicates** (Triangle returned the exact Delaunay "
              "triangulation of every input)" if tri_wrong == 0 else ", and for Triangle")
    out.append((PAPER["general_position"], measured, v))
    tri_not7 = t.get("triangle:not_7:float", 0)
    measured = (f"a rounded trisection point is off its edge line in "
                f"{_rate(t['off_line'], t['sets_float'])} float nine-point sets")
    if has_tri:
        measured += (f"; the exact Delaunay triangulation of those float points (Triangle) "
                     f"then has more than 7 triangles (slivers along the edges) in "
                     f"{_rate(tri_not7, t['sets_float'])}")
    measured += (f"; SciPy returns a zero-area triangle in "
                 f"{_rate(t.get('scipy:zero_area:float', 0), t['sets_float'])}")
    v = ("**confirmed**" if t["off_line"] > t["sets_float"] / 2 else "**partly**") + \
        (": the points are almost never collinear after rounding; an exact Delaunay code then "
         "triangulates slivers and a float one may return degenerate triangles. qdrefine "
         "decides on the exact points and always emits the 7-triangle pattern (see the "
         "limits below for what rounding still does to its output)")
    out.append((PAPER["collinear"], measured, v))
    c = r["exhibits"].get("collinear")
    if c:
        verts = ", ".join(f"({x:g}, {y:g})" for x, y in c["vertices"])
        bad = c["scipy"]["zero_area_triangles"][0]
        measured = (f"SciPy {r['meta']['machine']['versions'].get('scipy')} on the nine points "
                    f"of {verts}: triangle {'-'.join(str(i + 1) for i in bad)} has exactly "
                    "collinear vertices (figure below)")
        v = "**reproduced** with SciPy/Qhull (not with CGAL/Matlab, which we did not run)"
    else:
        measured, v = "no small-integer example found", "**not reproduced**"
    out.append((PAPER["fig3"], measured, v))
    d_ok = t.get("qdrefine 7t-d:usable_7t", 0)
    measured = (f"with exact predicates (qdrefine) both decisions are exact: 7T-QD agrees with "
                f"the exact reference on all but {t['qd_vs_exact']} of {t['qd_n']:,} triangles "
                f"and 7T-D is Delaunay for the exact points on {t['fraction_d'][0]} of "
                f"{t['fraction_d'][1]} Fraction-checked sets; 7T-D emitted a valid 7-triangle "
                f"partition on {d_ok:,} of {t['sets']:,} sets. In plain float64: 7T-QD "
                f"{t['naive_bad_decision']} invalid partitions, SciPy's Delaunay {sc_wrong:,} "
                "wrong triangulations")
    v = ("**true of floating-point implementations only**: implemented with exact predicates "
         "7T-D is exactly as robust as 7T-QD")
    out.append((PAPER["more_robust"], measured, v))
    return out


# ----------------------------------------------------------------------------------------
# tables


def _row_label(key: str) -> str:
    fam, place = key.split("/")
    return f"{fam} | {place}"


def qd_table(r: dict) -> list[str]:
    lines = ["| family | placement | triangles | float != exact | of which labelling / case / "
             "at an exact tie | float output invalid | invalid because of the float decision "
             "| float depends on vertex order | qdrefine != exact | Fraction check | qdrefine "
             "output invalid (zero-area / clockwise) | children area = parent area exactly |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for k in _keys():
        q = r["qd"][k]
        lines.append(
            f"| {_row_label(k)} | {q['triangles']:,} | {q['naive_differs']} | "
            f"{q['naive_differs_label']} / {q['naive_differs_case']} / "
            f"{q['naive_differs_at_tie']} | {q['naive_invalid']} | "
            f"{q['naive_invalid_not_qdrefine']} | {q['naive_order_dependent']} | "
            f"{q['qdrefine_vs_exact']} | {q['fraction_agree']}/{q['fraction_checked']} | "
            f"{q['qdrefine_invalid']} ({q['qdrefine_zero_area']} / {q['qdrefine_inverted']}) | "
            f"{q['area_exact']:,} |")
    return lines


def delaunay_summary(r: dict, t: dict) -> list[str]:
    lines = ["| method | sets | broken: error, zero-area or clockwise triangle, or point left "
             "out | of which error / zero-area / clockwise / point left out | not the Delaunay "
             "triangulation of its input | of which on exact integer sets | usable 7-triangle "
             "partition |", "|---|---|---|---|---|---|---|"]
    for m in r["methods"]:
        lines.append(
            f"| {m} | {t['sets']:,} | {t[f'{m}:broken']:,} | {t[f'{m}:errors']:,} / "
            f"{t[f'{m}:zero_area']:,} / {t[f'{m}:inverted']:,} / {t[f'{m}:missing_point']:,} | "
            f"{t[f'{m}:wrong_delaunay']:,} | {t[f'{m}:wrong_delaunay:exact']:,} of "
            f"{t['sets_exact']:,} | {t[f'{m}:usable_7t']:,} |")
    return lines


def delaunay_table(r: dict) -> list[str]:
    lines = ["| family | placement | method | sets | error | != 7 triangles | point left out | "
             "zero-area | clockwise | not a triangulation | not Delaunay | wrong (any of "
             "these) | usable 7-triangle partition |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for k in _keys():
        d = r["delaunay"][k]
        for m, x in d["methods"].items():
            lines.append(
                f"| {_row_label(k)} | {m} | {d['sets']:,} | {x['errors']:,} | {x['not_7']:,} | "
                f"{x['missing_point']:,} | {x['zero_area']:,} | {x['inverted']:,} | "
                f"{x['not_triangulation']:,} | {x['not_delaunay']:,} | "
                f"{x['wrong_delaunay']:,} | {x['usable_7t']:,} |")
    return lines


def refinement_table(r: dict, levels: int) -> list[str]:
    head = " | ".join(f"level {i + 1}" for i in range(levels))
    lines = [f"| scheme | family | placement | patches | {head} | area exact at level "
             f"{levels} | largest relative area change |",
             "|---|---|---|---|" + "---|" * levels + "---|---|"]
    for scheme, table in r["refinement"].items():
        for k in _keys():
            s = table[k]
            cells = " | ".join(f"{x['non_conforming']} / {x['zero_area']} / {x['inverted']}"
                               for x in s["levels"])
            last = s["levels"][-1]
            exact = s["patches"] - last["area_changed"]
            worst = max(x["max_relative_area_change"] for x in s["levels"])
            lines.append(f"| {scheme} | {_row_label(k)} | {s['patches']} | {cells} | "
                         f"{exact} | {worst:.1e} |")
    return lines


def families_table(r: dict) -> list[str]:
    lines = ["| family | placement | shapes | exact points | generated | dropped (collinear "
             "in float) | longest edge | smallest angle (min / median, rad) | distance from "
             "origin / size (median / max) |", "|---|---|---|---|---|---|---|---|---|"]
    for k in _keys():
        f = r["families"][k]
        g = f["ranges"]
        lines.append(
            f"| {_row_label(k)} | {DESCRIPTION[k.split('/')[0]]} | "
            f"{'yes' if f['exact_points'] else 'no'} | {f['generated']:,} | "
            f"{f['dropped_collinear']} | {g['longest_edge_min']:.0e} .. "
            f"{g['longest_edge_max']:.0e} | {g['smallest_angle_min']:.1e} / "
            f"{g['smallest_angle_median']:.1e} | {g['offset_over_size_median']:.1e} / "
            f"{g['offset_over_size_max']:.1e} |")
    return lines


# ----------------------------------------------------------------------------------------
# the page


def _refinement_totals(r: dict) -> dict:
    out = {}
    for scheme, table in r["refinement"].items():
        last = {k: table[k]["levels"][-1] for k in table}
        bad = [f"`{k}` {x['non_conforming']} / {x['zero_area']} / {x['inverted']} of "
               f"{table[k]['patches']}" for k, x in last.items()
               if x["non_conforming"] or x["zero_area"] or x["inverted"]]
        out[scheme] = {"patches": sum(table[k]["patches"] for k in table),
                       "last": "; ".join(bad) or "none"}
    return out


def markdown(r: dict, out: Path, img: Path, json_path: Path) -> str:
    """The whole page ``docs/robustness.md``."""
    t = totals(r)
    meta = r["meta"]
    mach = meta["machine"]
    ver = mach["versions"]
    src = mach["qdrefine_source"]
    rel = Path(os.path.relpath(img, out.parent))
    json_rel = os.path.relpath(json_path, out.parent)
    ref = _refinement_totals(r)
    w: list[str] = []
    a = w.append
    a("# Geometry robustness: floating point versus exact decisions\n")
    a(f"Generated by `{meta['command']}` (run from the repository root) on {meta['date']} in "
      f"{meta['seconds']:.0f} s; raw counts in [`{Path(json_rel).name}`]({json_rel}). Every "
      "number and every verdict on this page is computed by that command; the paper's "
      "statements are quoted, never used as results. Seeds are fixed (`--seed "
      f"{meta['seed']}`), so a rerun reproduces every count; `--page-only` rewrites this "
      "page from the JSON file without rerunning.\n")
    a("## Summary\n")
    naive_rows = ", ".join(f"`{k}` {v}" for k, v in t["naive_rows"].items()) or "none"
    a(f"- **7T-QD in plain float64** (squared lengths compared in float, the paper's rule) "
      f"differs from the exact decision on {_rate(t['naive_differs'], t['qd_n'])} triangles "
      f"({t['naive_differs_tie']} of them at an exact tie). Rows: {naive_rows}. "
      f"Invalid partitions caused by the float decision: **{t['naive_bad_decision']}**. "
      f"The float result depends on the order in which the vertices are listed for "
      f"{t['naive_order']} triangles (qdrefine: {t['qd_order']}).")
    a(f"- **qdrefine's 7T-QD** equals the exact reference (integer arithmetic) on all but "
      f"{t['qd_vs_exact']} of {t['qd_n']:,} triangles and equals the `fractions.Fraction` "
      f"oracle on {t['fraction'][0]} of {t['fraction'][1]} rechecked ones.")
    for m in r["methods"]:
        if m == "qdrefine 7t-d":
            a(f"- **qdrefine 7T-D** on the nine points: a usable 7-triangle partition on "
              f"{t[f'{m}:usable_7t']:,} of {t['sets']:,} sets, Delaunay for the exact points "
              f"on {t['fraction_d'][0]} of {t['fraction_d'][1]} Fraction-checked sets and on "
              f"{t['sets_exact'] - t[f'{m}:wrong_delaunay:exact']:,} of {t['sets_exact']:,} "
              "exact integer sets; by design not the Delaunay triangulation of the *rounded* "
              "points (section 2). "
              + (f"The other {t['sets'] - t[f'{m}:usable_7t']:,} sets (rows "
                 + ", ".join(f"`{k}`" for k in _keys() if r['delaunay'][k]['methods'][m]
                             ['usable_7t'] < r['delaunay'][k]['sets'])
                 + ") have a zero-area or clockwise triangle among the rounded points."
                 if t[f"{m}:usable_7t"] < t["sets"] else ""))
            continue
        a(f"- **{m}** on the nine points: broken output (error, zero-area or clockwise "
          f"triangle, point left out) on {_rate(t[f'{m}:broken'], t['sets'])} sets; "
          f"not the Delaunay triangulation of its input on "
          f"{_rate(t[f'{m}:wrong_delaunay'], t['sets'])} sets "
          f"({t[f'{m}:wrong_delaunay:exact']:,} of {t['sets_exact']:,} exact integer sets); "
          f"a usable 7-triangle partition on {t[f'{m}:usable_7t']:,} of {t['sets']:,}.")
    bad = ", ".join(f"`{k}`" for k in t["qd_invalid_rows"]) or "none"
    ref_bad = any(x["last"] != "none" for x in ref.values())
    a(f"- **Rounding still bites qdrefine**: its decisions are exact but the new points are "
      f"stored as float64 roundings. On {t['qd_invalid']} of {t['qd_n']:,} triangles (rows "
      f"{bad}) the stored 7T-QD children include a zero-area or clockwise triangle"
      + ("; refined meshes show the same (section 3)." if ref_bad else ".")
      + " This is a limitation of float64 output. qdrefine therefore checks its output: "
      "`refine`, `partition` and `partition_many` raise a clear `ValueError` (\"triangle i "
      "... is too thin for its distance from the origin ...\") instead of returning such "
      "children; this study calls them with `strict=False` to measure the raw effect.")
    for scheme, x in ref.items():
        a(f"- **Uniform refinement with {scheme}**, 1 to {meta['levels']} levels on "
          f"{x['patches']} patches: at level {meta['levels']}, patches with a non-conforming "
          f"mesh / a zero-area / a clockwise triangle: {x['last']}"
          + ("." if x["last"] == "none" else "; all other rows clean."))
    a("")
    a("## The paper's robustness claims\n")
    a("| the paper says (quoted) | measured here | verdict |")
    a("|---|---|---|")
    for claim, measured, verdict in verdicts(r, t):
        a(f"| \"{claim}\" | {measured} | {verdict} |")
    a("")
    _exhibits(a, r, rel)
    _method(a, r, meta, mach, ver, src)
    a("## 1. 7T-QD: float64 decision versus exact decision\n")
    a("`float != exact`: the float partition (as a set of triangles over the nine points) "
      "differs from the exact one; split into a different canonical labelling (longest edge, "
      "or the endpoint nearer the apex) and a different Case of Definition 1, and counted "
      "again when the exact comparison is a tie (both sides defensible). `invalid`: a child "
      "with zero or negative exact area, or children that do not tile the nine-point "
      "polygon. `because of the float decision`: invalid in float but valid in qdrefine (same "
      "points). `vertex order`: the float partition changes for one of the 5 other vertex "
      "orders. `Fraction check`: qdrefine against the oracle in `fractions.Fraction`. "
      "`children area = parent area`: the exact sum of the 7 children areas equals the exact "
      "area of the input triangle (only possible when the trisection points are exact "
      "floats; otherwise they sum exactly to the area of the nine-point polygon, which the "
      "tiling check implies). Conformity with neighbours does not depend on the decision: a "
      "partition that tiles its nine-point polygon has exactly the edge pieces cut at the "
      "shared trisection points on its boundary, whatever the labelling and the Case; "
      "section 3 checks whole meshes. The float lengths are symmetric in the two endpoints, "
      "so the float result cannot depend on the vertex order either (column measured "
      "anyway).\n")
    w.extend(qd_table(r))
    a("")
    a("Largest relative difference between the children's total area and the parent's: "
      + ", ".join(f"`{k}` {r['qd'][k]['max_relative_area_change']:.1e}" for k in _keys()) + ".\n")
    a("## 2. Delaunay of the nine points: SciPy/Qhull, Triangle, qdrefine 7T-D\n")
    nd_rows = ", ".join(f"`{k}` {r['delaunay'][k]['not_distinct']}" for k in _keys()
                        if r["delaunay"][k]["not_distinct"]) or "none"
    a(f"Each method triangulates the nine float64 points qdrefine stores (`partition_many`). "
      f"Sets whose nine points are not distinct (rounded onto each other or onto a vertex; "
      f"{t['not_distinct']}: {nd_rows}) are left out. `not a triangulation`: "
      "the triangles do not tile the exact convex hull of the points (zero-area, clockwise, "
      "overlapping, gaps or T-junctions). `not Delaunay`: a point strictly inside the "
      "circumcircle of a triangle. `wrong`: error, point left out, not a triangulation or "
      "not Delaunay: the output is not the Delaunay triangulation of the input. `usable "
      "7-triangle partition`: 7 counter-clockwise triangles tiling the nine-point polygon with "
      "all nine points, what a refinement needs. For float inputs these differ: the rounded "
      "trisection points are rarely on the edges, so the true Delaunay triangulation of the "
      "float points has slivers (more than 7 triangles), and qdrefine's 7T-D, Delaunay for "
      "the *exact* points, is not the Delaunay triangulation of the *rounded* ones. On the "
      "exact integer rows the two notions coincide.\n")
    w.extend(delaunay_summary(r, t))
    a("")
    hn = _sum(r["delaunay"], "hull_is_ninegon", _keys(True))
    a(f"**Why 7.** A triangulation of `n` points of which `h` lie on the boundary of their "
      f"convex hull has `2n - h - 2` triangles (Euler's formula with `3T + h = 2E`). The "
      f"nine exact points all lie on the boundary of the input triangle, so `h = 9` and "
      f"`T = 7`: the exact hull is the nine-point polygon on {hn:,} of {t['sets_exact']:,} "
      f"exact integer sets. ")
    if "triangle" in r["methods"]:
        a(f"Triangle's triangle count equals `2n - h - 2` for the exact `h` of the float "
          f"points on {t['triangle:expected_count']:,} of {t['sets']:,} sets.")
    a("")
    a(f"qdrefine 7T-D checked again with `fractions.Fraction` (empty circumcircles for the "
      f"exact nine points): {t['fraction_d'][0]} of {t['fraction_d'][1]} sets.\n")
    w.extend(delaunay_table(r))
    a("")
    a(f"## 3. Uniform refinement, 1 to {meta['levels']} levels\n")
    a("Each triangle becomes a four-triangle conforming patch (the triangle and its point "
      "reflections through its edge midpoints), refined level by level with `qdrefine.refine`. "
      "Cells: patches with a non-conforming mesh (`qdrefine.topology.conformity`: an edge "
      "used more than twice, misoriented, a hanging node or duplicate points) / with a "
      "zero-area triangle / with a clockwise triangle (exact orientation). `area exact`: "
      "patches whose refined mesh has exactly the patch's area (exact sums).\n")
    w.extend(refinement_table(r, meta["levels"]))
    a("")
    _limits(a, r, t)
    return "\n".join(w) + "\n"


def _exhibits(a, r: dict, rel: Path) -> None:
    ex = r["exhibits"]
    a("## Fig. 3, reproduced with SciPy\n")
    if ex.get("figure"):
        a(f"![SciPy/Qhull failures on two nine-point sets, and qdrefine's 7T-D]"
          f"({(rel / 'scipy_failures.png').as_posix()})\n")
    c, d = ex.get("collinear"), ex.get("dropped")
    if c:
        s = c["scipy"]
        a(f"- **Collinear triangle** (the paper's failure): searching the triangles `(0,0), "
          f"(a,b), (c,d)` with integers `0..9` in order, the {c['tried']}th counter-clockwise "
          f"one, `{c['vertices']}`, gives nine points on which `scipy.spatial.Delaunay` returns "
          f"{s['triangles']} triangles, among them "
          f"{', '.join(str([i + 1 for i in t]) for t in s['zero_area_triangles'])} (points "
          "numbered 1-9 in the order M N O D C Q B A P) whose three float vertices are exactly "
          "collinear: a zero-area triangle, which no triangulation may contain.")
    if d:
        s = d["scipy"]
        a(f"- **Points left out, exact input**: the right needle `{d['vertices']}` "
          f"(legs 3e{d['power']} and 3; all nine points are integers, so every collinear "
          f"triple is exact and the answer is unambiguous: 7 triangles). SciPy returns "
          f"{s['triangles']} triangles, leaves out points "
          f"{', '.join(str(i + 1) for i in s['missing_points'])} and "
          f"{len(s['non_delaunay_triangles'])} of its triangles are not Delaunay. The "
          f"needles of this form with legs 3e1 .. 3e{d['power'] - 1} are triangulated "
          "correctly.")
    p = ex.get("paper_example") or {}
    if p.get("example", True) and p.get("vertices"):
        s = p["scipy"]
        a(f"- The paper module's own Fig. 3 search (`qdrefine.paper.find_qhull_failure`, "
          f"one-decimal vertices, {p['failures']} of {p['trials']} trials flagged) finds "
          f"`{p['vertices']}`; judged exactly, SciPy's output there has "
          f"{len(s['zero_area_triangles'])} zero-area and {len(s['inverted_triangles'])} "
          f"clockwise triangle(s) and is {'not ' if not s['valid'] else ''}a Delaunay "
          "triangulation of its points; the triangles it flags as lying on an edge "
          f"({', '.join(str([i + 1 for i in t]) for t in p['degenerate'])}) are "
          + ("exactly collinear." if s["zero_area_triangles"] else
             "not exactly collinear for the rounded points (slivers, one of them clockwise)."
             if s["inverted_triangles"] else "not exactly collinear for the rounded points."))
    a("- In both cases qdrefine's 7T-D (right) decides on the exact trisection points with "
      "exact predicates and returns the 7 triangles.\n")


def _method(a, r: dict, meta: dict, mach: dict, ver: dict, src: dict) -> None:
    a("## Method\n")
    a("**Families** (seeded, `benchmarks/robustness/families.py`; the ranges are measured on "
      "the generated triangles):\n")
    for line in families_table(r):
        a(line)
    a("")
    curves = r["families"].get("near-tie/near", {}).get("curves", [])
    rc = r["families"].get("exact-tie/near", {}).get("curves", [])
    a(f"Tie curves (in the paper's frame `M=(0,0), N=(1,0), O=(x,y)`, left half `H`): "
      f"{'; '.join(curves)}. Those with rational points (used by `exact-tie`): "
      f"{'; '.join(rc)}. `near` placement: random rotation, longest edge 1e-12..1e12, "
      "near the origin; `far`: also translated by 1e2..1e9 sizes. The exact families move "
      "only by exact operations (dihedral and Pythagorean rotations, powers of two, lattice "
      "translations, all integers below 2^50), so their `far` rows reach at most the offsets "
      "listed. Vertices are listed in random order.\n")
    a(f"**Samples per row**: {meta['n_qd']:,} triangles (section 1), {meta['n_delaunay']:,} "
      f"nine-point sets (section 2), {meta['n_fraction']} rechecked with `fractions.Fraction` "
      f"per part, {meta['patches']} patches refined {meta['levels']} levels with 7T-QD and "
      "with 7T-D (section 3).\n")
    a("**Exact arithmetic** (`benchmarks/robustness/exact.py`, independent of qdrefine's "
      "predicates): a float64 is an integer times a power of two, so each small point set is "
      "scaled to Python integers and orientation, incircle and areas are evaluated exactly. "
      "Orientation and incircle signs are first evaluated in float64 and accepted when the "
      "value exceeds `1e-14` (orientation) or `1e-13` (incircle) times the permanent, 30 to "
      "90 times Shewchuk's proven bounds; the rest go to integers. The tests check these "
      "signs against `fractions.Fraction` and the exact 7T-QD reference against "
      "`tests/oracle.py`.\n")
    a("qdrefine runs with one numba thread (the arrays are tiny; its outputs do not depend "
      "on the thread count).\n")
    a("**Accuracy**: every count is exact for the sampled triangles (no tolerance anywhere). "
      "As an estimate of a family's rate a count has sampling error only; rates in the "
      "summary carry a 95% Wilson interval, and for zero counts the 95% upper bound.\n")
    a(f"**Machine**: {mach['cpu']}, {mach['cores']} cores (shared with other jobs during the "
      f"run), {mach['memory']}, {mach['platform']}. Python {ver['python']}, NumPy "
      f"{ver['numpy']}, SciPy {ver['scipy']}, Triangle {ver['triangle']}, qdrefine "
      f"{ver['qdrefine']} (commit {src.get('commit', '?')}"
      f"{', with uncommitted changes in src/' if src.get('src_modified') else ''}). Time per "
      "part: " + ", ".join(f"{k} {v:.0f} s" for k, v in r["timing"].items()) + ".\n")


def _limits(a, r: dict, t: dict) -> None:
    a("## Limits and open points\n")
    a("- **Stored points are rounded.** qdrefine decides every pattern exactly, but the "
      "trisection points it stores are float64 roundings. When a triangle is tiny compared "
      "with its distance from the origin (rows `far`), rounding can move a new point across "
      "an edge or onto another point, and the emitted children then include zero-area or "
      "clockwise triangles (section 1: "
      f"{t['qd_invalid']} triangles; section 3). With the default `strict=True`, "
      "`partition_many` and `refine` find the triangles at risk by a certified float bound "
      "(every child's corners lie on the parent's 1/3 lattice, so its area is at least 1/9 "
      "of the parent's; rounding moves a point by at most 4 eps times the largest "
      "coordinate) and check only their children exactly, then refuse with an error naming "
      "the triangle; local refinement checks every new triangle exactly. The study measures "
      "the raw output with `strict=False`. Translating the mesh nearer the origin avoids "
      "the problem in most cases.")
    a("- The float 7T-QD is a faithful but particular naive implementation: squared lengths "
      "from float points, qdrefine's tie rules on the float values. Other naive choices "
      "(e.g. the paper's Case III for the tie `|AB| = |OD|`, or `M + (N - M)/3` for the "
      "points, which is not symmetric in `M` and `N`) were not measured.")
    a("- SciPy is run with its default Qhull options; we did not try `QJ` (joggle), which "
      "perturbs the input. CGAL (the paper's Fig. 3) was not run.")
    a("- The exact families cannot be translated as far as the float ones (integers must "
      "stay below 2^50 to keep every point exact).")


__all__ = ["PAPER", "markdown", "to_json", "totals", "verdicts", "wilson"]
