"""The paper module: lemma checks, the Qhull search, verdict helpers, figures."""



from qdrefine import diagram as dg
from qdrefine import paper


def test_lemmas_hold_and_paper_centre_is_wrong():
    out = paper.lemma_checks()
    assert len(out["results"]) == 24
    assert all(r["delaunay"] for r in out["results"])
    adp = [c for c in out["centres"] if c["triangle"].startswith("ADP")][0]
    assert adp["x_ok"] and not adp["y_ok"]
    assert all(ok for _, ok in out["steps"])


def test_qhull_failure_is_found_and_degenerate():
    out = paper.find_qhull_failure(trials=200)
    ex = out["example"]
    assert ex is not None and ex["degenerate"]
    assert len(ex["simplices"]) != 7 or ex["degenerate"]


def test_agree_verdicts():
    assert paper._agree(0.0296796254, "0.0296796") == "confirmed"
    assert paper._agree(0.0014270794, "0.0014270").startswith("confirmed (truncated")
    assert paper._agree(0.004647, "0.50") == "wrong"


def test_chain_parsing():
    assert paper._parse_chain("7D > 7TLE > 7TQD") == [("7t-d", ">", "7t-le"),
                                                     ("7t-le", ">", "7t-qd")]


def test_figures_are_written(tmp_path):
    res = dg.compute(tol=1e-8, angle_measure=False)
    sample = paper.region_sample(step=1 / 200)
    names = paper.make_figures(tmp_path, sample, res, {"available": False})
    pngs = [n for n in names if n.endswith(".png")]
    assert len(pngs) == 12 and len(names) == 24
    for n in names:
        assert (tmp_path / n).stat().st_size > 1000
