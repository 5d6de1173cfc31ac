"""Plots draw into the given Axes, return it, and never save."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from qdrefine import examples, plot, quality, refine, report  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    yield
    assert list(tmp_path.iterdir()) == []  # nothing saved
    plt.close("all")


def test_mesh_by_min_angle_has_one_face_per_triangle_and_a_colour_bar():
    m = examples.plate_with_hole()
    ax = plot.mesh(m)
    faces = [c for c in ax.collections if hasattr(c, "get_array") and c.get_array() is not None
             and len(c.get_array()) == m.n_triangles]
    assert len(faces) == 1
    values = np.asarray(faces[0].get_array())
    np.testing.assert_allclose(values, quality.min_angles(m))
    assert len(ax.figure.axes) == 2  # the mesh and its colour bar
    assert "minimum angle" in ax.figure.axes[1].get_ylabel()
    assert len(ax.get_legend().get_texts()) == 2  # two edge tags


def test_mesh_by_tag_draws_into_the_given_axes():
    fig, ax = plt.subplots()
    m = examples.plate_with_hole()
    assert plot.mesh(m, ax, color="tag") is ax
    labels = [t.get_text() for t in fig.axes[1].get_yticklabels()]
    assert labels == ["1", "2"]
    with pytest.raises(ValueError, match="no cell tags"):
        plot.mesh(examples.square(2), color="tag")
    with pytest.raises(ValueError, match="choose one of min-angle, tag, none"):
        plot.mesh(m, color="rainbow")
    ax2 = plot.mesh(examples.square(2), color="none")
    assert len(ax2.figure.axes) == 1  # no colour bar


def test_histogram_bars_count_every_triangle():
    m = refine(examples.plate_with_hole(), "7t-qd")
    ax = plot.min_angle_histogram(m)
    assert sum(p.get_height() for p in ax.patches) == m.n_triangles


def test_compare_draws_one_line_per_scheme():
    rows = report.compare(examples.square(2), ["7t-qd", "4t-red"], levels=2)
    ax = plot.compare(rows, "similarity_classes")
    assert [line.get_label() for line in ax.get_lines()] == ["7t-qd", "4t-red"]
    np.testing.assert_array_equal(ax.get_lines()[1].get_ydata(), [1, 1, 1])
    with pytest.raises(ValueError, match="unknown metric"):
        plot.compare(rows, "beauty")


def test_tags_are_told_apart_without_colour_clashes():
    """Cell tags take the colour-blind-safe palette; edge tags are black lines of distinct
    styles (never a fill colour), each over a white underlay."""
    import matplotlib.colors as mcolors

    m = examples.plate_with_hole()
    ax = plot.mesh(m, color="tag")
    faces = next(c for c in ax.collections if c.get_array() is not None)
    fill = {tuple(np.round(c[:3], 6)) for c in faces.cmap(faces.norm(faces.get_array()))}
    assert fill == {tuple(np.round(mcolors.to_rgb(c), 6)) for c in plot.PALETTE[:2]}
    labelled = [c for c in ax.collections if not c.get_label().startswith("_")]
    assert [c.get_label() for c in labelled] == ["edge tag 1", "edge tag 2"]
    styles = [tuple(map(str, c.get_linestyle()[0])) for c in labelled]
    assert len(set(styles)) == 2
    for c in labelled:
        assert mcolors.to_hex(c.get_edgecolor()[0]) == "#000000"
    assert not {mcolors.to_hex(c.get_edgecolor()[0]) for c in labelled} & set(plot.PALETTE[:2])
    # more tags than colours: repeats are lightened, never the same colour twice
    assert len({plot.tag_color(i) for i in range(3 * len(plot.PALETTE))}) == 24


@pytest.mark.parametrize("levels", [0, 2])
def test_tagged_edges_are_drawn_as_whole_chains(levels):
    """Each edge tag of the plate is one closed loop (outer boundary, hole), drawn as one
    path, so a dashed style stays dashed along a curve made of many short edges; each
    tagged edge is in exactly one chain, in either direction."""
    m = refine(examples.plate_with_hole(), levels=levels)
    ax = plot.mesh(m, color="none")
    labelled = [c for c in ax.collections if not c.get_label().startswith("_")]
    for tag, collection in zip((1, 2), labelled, strict=True):
        rows = m.edges[m.edge_tags == tag]
        chains = plot.edge_chains(rows)
        assert len(chains) == 1 and chains[0][0] == chains[0][-1]  # one closed loop
        steps = {frozenset(s) for c in chains for s in zip(c[:-1], c[1:], strict=True)}
        assert steps == {frozenset(r) for r in rows.tolist()}
        assert sum(len(c) - 1 for c in chains) == len(rows)
        assert len(collection.get_paths()) == 1
    assert [c.tolist() for c in plot.edge_chains([[0, 1], [1, 2], [1, 3]])] == \
        [[0, 1], [1, 2], [1, 3]]  # a vertex of three edges ends three chains


def test_compared_schemes_differ_in_line_style_and_marker():
    """Two schemes with the same numbers (7T-QD and 7T-LE on a grid) stay both visible:
    different line styles, hollow markers of different sizes, palette colours."""
    rows = report.compare(examples.square(2), ["7t-qd", "7t-le", "4t-red"], levels=1)
    lines = plot.compare(rows, "min_angle").get_lines()
    assert len({(str(line.get_linestyle()), line.get_marker()) for line in lines}) == 3
    assert len({line.get_markersize() for line in lines}) == 3
    assert all(line.get_markerfacecolor() == "none" for line in lines)
    assert {line.get_color() for line in lines} <= set(plot.PALETTE)


def test_physical_names_label_the_tags():
    """Gmsh physical names, where the mesh has them, label edge tags in the legend, cell
    tags on the colour bar and both in the info report (text and JSON)."""
    m = examples.gmsh_mesh("step")
    ax = plot.mesh(m, color="tag")
    labels = [c.get_label() for c in ax.collections if not c.get_label().startswith("_")]
    assert labels == ["edge tag 1 (inlet)", "edge tag 2 (outlet)", "edge tag 3 (wall)"]
    bar = ax.figure.axes[-1]
    assert [t.get_text() for t in bar.get_yticklabels()] == ["1 (inlet region)", "2 (channel)"]
    info = report.info(m)
    assert info["cell_tags"]["2"]["name"] == "channel" and "name" in info["edge_tags"]["3"]
    text = report.format_info(info)
    assert "1 (inlet region): 225 triangles" in text and "3 (wall): 86 edges" in text
    assert report.info(examples.plate_with_hole())["cell_tags"]["1"]["name"] is None  # unnamed


@pytest.mark.parametrize("color", ["min-angle", "none"])
def test_unused_points_do_not_frame_the_picture(color):
    """A file's unused points (kept on reading) stretched the axes: the mesh sat in one
    corner of the picture, while ``info`` gave the triangles' box (review)."""
    from qdrefine import Mesh

    square = examples.square(2)
    m = Mesh(np.vstack([square.points, [[5.0, 5.0]]]), square.triangles)
    ax = plot.mesh(m, color=color)
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    assert x1 < 1.5 and y1 < 1.5 and x0 > -0.5 and y0 > -0.5
