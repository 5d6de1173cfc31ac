"""Pictures of meshes and of their quality, drawn with matplotlib.

Every function draws into ``ax`` (a new figure's axes when ``ax`` is None) and returns the
:class:`~matplotlib.axes.Axes`; none of them saves or shows anything (the command line
saves). matplotlib is imported on first use; call ``matplotlib.use("Agg")`` yourself for
headless use (the command line does).

Examples
--------
>>> import matplotlib
>>> matplotlib.use("Agg")
>>> from qdrefine import examples, plot
>>> ax = plot.mesh(examples.plate_with_hole(), color="min-angle")
>>> ax.figure.savefig("plate.png")  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from . import quality
from .mesh import Mesh
from .report import physical_name, tag_label

if TYPE_CHECKING:
    from matplotlib.axes import Axes

__all__ = ["mesh", "min_angle_histogram", "compare", "edge_chains", "COLORS",
           "COMPARE_METRICS", "PALETTE", "LINE_STYLES", "MARKERS"]

#: Choices of ``color`` for :func:`mesh`.
COLORS = ("min-angle", "tag", "none")

#: Okabe and Ito's colour-blind-safe palette (black last): cell tags and compared schemes.
PALETTE = ("#E69F00", "#56B4E9", "#009E73", "#F0E442", "#0072B2", "#D55E00", "#CC79A7",
           "#000000")
#: Line styles of edge tags and compared schemes: told apart without colour.
#: Dash lengths are in line widths and short, so that they show on the short segments of
#: tagged edges too: solid, dashed, dotted, dash-dot, sparse dots, long dashes.
LINE_STYLES = ("solid", (0, (2.0, 1.2)), (0, (0.6, 1.2)), (0, (3.0, 1.2, 0.6, 1.2)),
               (0, (0.6, 3.0)), (0, (5.0, 2.0)))
#: Markers of compared schemes (drawn hollow and smaller one after the other, so that lines
#: on top of each other stay visible).
MARKERS = ("o", "s", "D", "^", "v", "<", ">")

#: Metrics :func:`compare` can draw: key in the rows -> axis label.
COMPARE_METRICS = {
    "min_angle": "smallest angle (degrees)",
    "mean_min_angle": "mean of minimum angles (degrees)",
    "similarity_classes": "similarity classes",
}


def _axes(ax: Axes | None, figsize: tuple[float, float] = (7.0, 6.0)) -> Axes:
    if ax is not None:
        return ax
    import matplotlib.pyplot as plt

    return plt.figure(figsize=figsize, layout="constrained").add_subplot()


def tag_color(i: int) -> tuple[float, float, float]:
    """RGB colour of the ``i``-th tag: :data:`PALETTE` in order, lightened on each repeat."""
    import matplotlib.colors as mcolors

    rgb = np.array(mcolors.to_rgb(PALETTE[i % len(PALETTE)]))
    lighten = 1.0 - 0.6 ** (i // len(PALETTE))
    return tuple(float(c) for c in rgb + (1.0 - rgb) * lighten)


def _choice(value: str, choices: Sequence[str], name: str) -> str:
    if value not in choices:
        raise ValueError(f"unknown {name} {value!r}; choose one of {', '.join(choices)}")
    return value


def _named(m: Mesh, dim: int, tag: int) -> str:
    """The tag as reports show it: ``"2"``, or ``"2 (hole)"`` where the mesh names it."""
    return tag_label(tag, physical_name(m, dim, tag))


def edge_chains(edges: NDArray[np.integer]) -> list[NDArray[np.int64]]:
    """The edges ``(K, 2)`` (vertex ids, either direction) joined into chains of vertex
    ids: each edge in exactly one chain, chains broken where a vertex has other than two
    of the edges; a closed loop starts and ends at the same vertex. Deterministic (edge
    order)."""
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    at: dict[int, list[int]] = {}
    for e, (a, b) in enumerate(edges.tolist()):
        at.setdefault(a, []).append(e)
        at.setdefault(b, []).append(e)
    used = np.zeros(edges.shape[0], dtype=bool)
    chains = []
    # chain ends first (vertices with one edge or three and more), then what is left: loops
    for start in [v for v, es in at.items() if len(es) != 2] + list(at):
        for first in at[start]:
            if used[first]:
                continue
            chain, v, e = [start], start, first
            while e is not None:
                used[e] = True
                a, b = edges[e]
                v = int(b) if a == v else int(a)
                chain.append(v)
                if len(at[v]) != 2:
                    break
                e = next((f for f in at[v] if not used[f]), None)
            chains.append(np.array(chain, dtype=np.int64))
    return chains


def mesh(m: Mesh, ax: Axes | None = None, *, color: str = "min-angle",
         edges: bool | None = None, colorbar: bool = True, tagged_edges: bool = True,
         title: str | None = None) -> Axes:
    """Draw ``m``'s triangles, filled by a per-triangle value, and its tagged edges.

    Parameters
    ----------
    m : Mesh
    ax : matplotlib Axes, optional
    color : {"min-angle", "tag", "none"}
        Fill by the minimum angle (degrees, 0..60, colour bar), by the cell tag (one colour
        of :data:`PALETTE` per tag, colour bar with the tag values; more than eight tags
        repeat the colours, lightened) or not at all.
    edges : bool, optional
        Draw the triangle edges; by default only when there are at most 60 000 triangles.
    colorbar : bool
        Add a colour bar for ``"min-angle"`` and ``"tag"``.
    tagged_edges : bool
        Draw the tagged edges thicker, in black on a white underlay, one line style of
        :data:`LINE_STYLES` per edge tag (so they never clash with the fill's colours), with
        a legend.
    title : str, optional
    """
    import matplotlib.colors as mcolors
    from matplotlib.collections import LineCollection
    from matplotlib.transforms import offset_copy
    from matplotlib.tri import Triangulation

    _choice(color, COLORS, "color")
    p, t = np.asarray(m.points), np.asarray(m.triangles)
    # the triangles' points only: unused points stretched the axes, the mesh in a corner
    # (review); tagged edges are edges of triangles
    used = np.unique(t)
    if ax is None:  # a figure shaped like the mesh, so the colour bar matches its height
        span = np.ptp(p[used], axis=0)
        ratio = float(np.clip(span[1] / span[0], 0.3, 2.0)) if span[0] > 0 else 1.0
        ax = _axes(None, (8.0, 6.4 * ratio + 1.4))
    tri = Triangulation(p[used, 0], p[used, 1], np.searchsorted(used, t))
    if edges is None:
        edges = m.n_triangles <= 60_000
    lw = float(np.clip(40.0 / np.sqrt(m.n_triangles), 0.05, 0.8)) if edges else 0.0
    edgecolor = "0.15" if edges else "face"
    if color == "min-angle":
        values = quality.min_angles(m)
        art = ax.tripcolor(tri, facecolors=values, cmap="viridis", vmin=0.0, vmax=60.0,
                           edgecolors=edgecolor, linewidth=lw)
        if colorbar:
            cb = ax.figure.colorbar(art, ax=ax, shrink=0.85)
            cb.set_label("minimum angle of the triangle (degrees)")
    elif color == "tag":
        if m.cell_tags is None:
            raise ValueError("the mesh has no cell tags to colour by; use color='min-angle' "
                             "or 'none'")
        tags, index = np.unique(np.asarray(m.cell_tags), return_inverse=True)
        cmap = mcolors.ListedColormap([tag_color(i) for i in range(len(tags))])
        norm = mcolors.BoundaryNorm(np.arange(len(tags) + 1) - 0.5, len(tags))
        art = ax.tripcolor(tri, facecolors=index.reshape(-1).astype(float), cmap=cmap,
                           norm=norm, edgecolors=edgecolor, linewidth=lw)
        if colorbar:
            cb = ax.figure.colorbar(art, ax=ax, shrink=0.85, ticks=np.arange(len(tags)))
            cb.ax.set_yticklabels([_named(m, 2, int(v)) for v in tags])
            cb.set_label("cell tag")
    else:
        ax.triplot(tri, color="0.2", linewidth=max(lw, 0.2))
    if tagged_edges and m.edges is not None and len(m.edges):
        etags = np.asarray(m.edge_tags)
        rows = np.asarray(m.edges)
        for i, tag in enumerate(np.unique(etags)):
            # whole chains, so that a dash pattern runs along a curve of short edges
            mine = [p[chain] for chain in edge_chains(rows[etags == tag])]
            ax.add_collection(LineCollection(mine, colors="white", linewidths=3.6))
            ax.add_collection(LineCollection(mine, colors="black", linewidths=2.0,
                                             linestyles=[LINE_STYLES[i % len(LINE_STYLES)]],
                                             label=f"edge tag {_named(m, 1, int(tag))}"))
        # below the tick labels and the axis label, whatever the axes' height
        below = offset_copy(ax.transAxes, fig=ax.figure, y=-34, units="points")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0), bbox_transform=below,
                  ncols=4, frameon=False, fontsize="small")
    ax.set_aspect("equal")
    ax.autoscale_view()
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(title if title is not None else
                 f"{m.n_triangles} triangles, {m.n_points} points")
    return ax


def min_angle_histogram(m: Mesh, ax: Axes | None = None, *, bin_width: float = 2.5,
                        label: str | None = None, title: str | None = None) -> Axes:
    """Bar chart of the per-triangle minimum angles of ``m`` (bins of ``bin_width`` degrees
    over 0..60), with the smallest and mean values marked."""
    ax = _axes(ax, (7.0, 4.0))
    counts, edges = quality.min_angle_histogram(m, bin_width=bin_width)
    ax.bar(edges[:-1], counts, width=np.diff(edges), align="edge", color="tab:blue",
           edgecolor="white", label=label)
    values = quality.min_angles(m)
    ax.axvline(values.min(), color="tab:red", linestyle="--",
               label=f"smallest {values.min():.2f}°")
    ax.axvline(values.mean(), color="tab:green", linestyle=":",
               label=f"mean {values.mean():.2f}°")
    ax.set_xlim(0, 60)
    ax.set_xlabel("minimum angle of the triangle (degrees)")
    ax.set_ylabel("triangles")
    ax.legend(loc="upper left")
    ax.set_title(title if title is not None else
                 f"Minimum angles of {m.n_triangles} triangles")
    return ax


def compare(rows: Sequence[Mapping[str, Any]], metric: str, ax: Axes | None = None, *,
            title: str | None = None) -> Axes:
    """One line per scheme of ``metric`` against the refinement level.

    ``rows`` are dictionaries with keys ``scheme``, ``level`` and ``metric`` (as made by
    :func:`qdrefine.report.compare`); ``metric`` is a key of :data:`COMPARE_METRICS`.
    """
    _choice(metric, tuple(COMPARE_METRICS), "metric")
    ax = _axes(ax, (6.0, 4.0))
    schemes = list(dict.fromkeys(r["scheme"] for r in rows))
    for i, name in enumerate(schemes):
        mine = [r for r in rows if r["scheme"] == name]
        ax.plot([r["level"] for r in mine], [r[metric] for r in mine],
                color=PALETTE[(i + 4) % len(PALETTE)], linestyle=LINE_STYLES[i % len(LINE_STYLES)],
                marker=MARKERS[i % len(MARKERS)], markerfacecolor="none",
                markersize=max(4.0, 10.0 - 1.5 * i), markeredgewidth=1.4, label=name)
    ax.set_xlabel("refinement level")
    ax.set_ylabel(COMPARE_METRICS[metric])
    levels = sorted({r["level"] for r in rows})
    ax.set_xticks(levels)
    ax.grid(alpha=0.3)
    ax.legend()
    if title is not None:
        ax.set_title(title)
    return ax
