"""The paper's figures, recomputed, plus the maps its gray figures hide and the iterated
study's maps. One function per figure; each returns a matplotlib Figure (Agg backend,
imported lazily) and never saves it: :func:`save_all` does. One concern (the figures), hence
over 400 lines.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .. import diagram as dg
from ..diagram.extrema import CORNERS
from ..io import atomic_path
from ..partition import partition
from ..stencil import SEVEN

__all__ = ["save_all", "FIGURES"]

_XLABEL = "x (apex abscissa; longest edge (0,0)-(1,0))"
_YLABEL = "y (apex height)"
#: the zoom on the shaded region used by Figs. 9-11
ZOOM = (0.395, 0.5, 0.0, 0.32)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _draw_partition(ax, vertices, scheme, title, labels=True):
    pts, tris = partition(np.asarray(vertices, dtype=float), scheme)
    ax.triplot(pts[:, 0], pts[:, 1], tris, color="k", lw=1.2)
    if labels:
        # name every point by the stencil of the canonical labelling
        xy = dg.to_diagram(np.asarray(vertices, float)[None])[0]
        stencil = dg.stencil_points([xy[0]], [xy[1]])[0]
        v = np.asarray(vertices, float)
        m, n = v[0], v[1]
        u = n - m
        rot = np.array([[u[0], -u[1]], [u[1], u[0]]])
        world = stencil @ rot.T + m
        centre = v.mean(axis=0)
        for name, p in zip(SEVEN.names, world, strict=True):
            d = p - centre
            d = d / (np.linalg.norm(d) + 1e-12) * 0.045 * np.linalg.norm(u)
            ax.text(*(p + d), name, ha="center", va="center", fontsize=11, clip_on=False)
            ax.plot(*p, "o", color="C3", ms=3)
    ax.set_title(title, fontsize=11, pad=18)
    ax.set_aspect("equal")
    ax.margins(0.08)
    ax.axis("off")
    return ax


def _sample_triangle(x, y):
    return np.array([[0.0, 0.0], [1.0, 0.0], [x, y]])


_EXAMPLES = {"I": (0.2, 0.6), "II": (0.35, 0.3), "III": (0.47, 0.2), "shaded": (0.415, 0.1)}


def _half_outline(ax, full=False):
    t = np.linspace(0, np.pi / 3, 200)
    ax.plot(1 - np.cos(t), np.sin(t), "k", lw=1)
    if full:
        ax.plot(np.cos(t), np.sin(t), "k", lw=1)
        ax.plot([0, 1], [0, 0], "k", lw=1)
        ax.axvline(0.5, color="0.5", ls=":", lw=1)
    else:
        ax.plot([0, 0.5], [0, 0], "k", lw=1)
        ax.plot([0.5, 0.5], [0, math.sqrt(3) / 2], "k", lw=1)
    ax.set_aspect("equal")


#: Where the II/III arc ends: the corner it shares with the I/III arc; beyond it, in
#: region I, the circle bounds nothing (it was drawn on to x = 1/2).
II_III_END = CORNERS["I-III / II-III"][0]


def _arc(ax, cx, r, x0, x1, **kw):
    x = np.linspace(x0, x1, 400)
    yy = np.sqrt(np.maximum(r * r - (x - cx) ** 2, 0))
    ax.plot(x, yy, **kw)


def _region_image(ax, mask_fn, extent, n=700, cmap="Greys", **kw):
    x0, x1, y0, y1 = extent
    xs = np.linspace(x0, x1, n)
    ys = np.linspace(y0, y1, n)
    X, Y = np.meshgrid(xs, ys)
    val = mask_fn(X.ravel(), Y.ravel()).reshape(X.shape).astype(float)
    val[val == 0] = np.nan
    ax.imshow(val, origin="lower", extent=extent, cmap=cmap, vmin=0, vmax=1.3, aspect="equal",
              interpolation="nearest", **kw)


def _save_one(fig, outdir: Path, name: str, written: list[str]):
    for ext in ("png", "svg"):
        with atomic_path(outdir / f"{name}.{ext}") as tmp:  # whole pictures or none
            fig.savefig(tmp, format=ext, dpi=130, bbox_inches="tight")
        written.append(f"{name}.{ext}")
    fig.clf()
    _plt().close(fig)


def _labels(ax):
    ax.set_xlabel(_XLABEL)
    ax.set_ylabel(_YLABEL)
    return ax


def _zoom_grid(n=500):
    xs = np.linspace(ZOOM[0], ZOOM[1], n)
    ys = np.linspace(1e-4, ZOOM[3], n)
    X, Y = np.meshgrid(xs, ys)
    return X, Y


def fig01(ctx):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5, 4))
    _draw_partition(ax, _sample_triangle(*_EXAMPLES["II"]), "7t-le",
                    "Fig. 1: 7T-LE partition of a triangle t0")
    return fig


def fig02(ctx):
    plt = _plt()
    fig, axs = plt.subplots(1, 2, figsize=(9, 3))
    t = _sample_triangle(*_EXAMPLES["II"])
    _draw_partition(axs[0], t, "7t-le", "7T-LE")
    _draw_partition(axs[1], t, "7t-d", "7T-D (exact Delaunay)")
    fig.suptitle("Fig. 2: 7T-LE and 7T-D on the same triangle (region II)")
    return fig


def fig03(ctx):
    plt = _plt()
    qhull = ctx["qhull"]
    fig, axs = plt.subplots(1, 2, figsize=(10, 4.5))
    ex = qhull.get("example") if qhull.get("available") else None
    if ex:
        p = np.array(ex["points"])
        s = np.array(ex["simplices"])
        axs[0].triplot(p[:, 0], p[:, 1], s, color="k", lw=1)
        for d in ex["degenerate"]:
            q = p[d + [d[0]]]
            axs[0].plot(q[:, 0], q[:, 1], color="C3", lw=3, alpha=0.6)
        for i, q in enumerate(p):
            axs[0].annotate(str(i + 1), q, textcoords="offset points", xytext=(4, 4),
                            fontsize=9)
        axs[0].set_title(f"SciPy/Qhull Delaunay: {len(s)} triangles,\n"
                         f"{len(ex['degenerate'])} with 3 points on one edge (red)", fontsize=10)
        axs[0].set_aspect("equal")
        axs[0].set_xlabel("x")
        axs[0].set_ylabel("y")
        _draw_partition(axs[1], np.array(ex["vertices"]), "7t-d",
                        "qdrefine 7T-D (exact): 7 triangles", labels=False)
        fig.suptitle(f"Fig. 3: vertices {ex['vertices']}", y=1.04)
    else:
        for a in axs:
            a.axis("off")
        msg = ("SciPy is not installed: pip install qdrefine[paper]"
               if not qhull.get("available") else "no failure found")
        axs[0].text(0.5, 0.5, msg, ha="center")
    return fig


def fig04(ctx):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 5))
    _half_outline(ax, full=True)
    xo, yo = 0.3, 0.55
    ax.plot([0, xo, 1], [0, yo, 0], color="C0", lw=1.5)
    ax.annotate("O", (xo, yo), xytext=(4, 4), textcoords="offset points")
    ax.set_title("Fig. 4: mapping diagram (left half: x <= 1/2)")
    return _labels(ax).figure


def fig05(ctx):
    plt = _plt()
    fig, axs = plt.subplots(1, 3, figsize=(13, 4))
    for a, case in zip(axs, ("I", "II", "III"), strict=True):
        _draw_partition(a, _sample_triangle(*_EXAMPLES[case]), "7t-qd", f"7T-QD, Case {case}")
    fig.suptitle("Fig. 5: the 7T-QD partition (pentagon A-D-C-B-O split by fan B, D, O)")
    return fig


def fig06(ctx):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5, 7))
    _half_outline(ax)
    colours = {"I": 0.25, "II": 0.55, "III": 0.9}
    xs = np.linspace(0, 0.5, 600)
    ys = np.linspace(0, 0.87, 1000)
    X, Y = np.meshgrid(xs, ys)
    img = np.full(X.shape, np.nan)
    m = dg.region_masks(X.ravel(), Y.ravel(), exact=False)
    for k, v in colours.items():
        img.ravel()[m[k]] = v
    ax.imshow(img, origin="lower", extent=(0, 0.5, 0, 0.87), cmap="Greys", vmin=0, vmax=1.3,
              aspect="equal", interpolation="nearest")
    _arc(ax, 1 / 3, 1 / 3, 0, 0.5, color="C0", lw=2, label="(x-1/3)^2+y^2=1/9")
    _arc(ax, 6 / 5, 4 / 5, 0.4, II_III_END, color="C3", lw=2, label="(x-6/5)^2+y^2=16/25")
    for k, (px, py) in {"I": (0.15, 0.5), "II": (0.25, 0.15), "III": (0.465, 0.12)}.items():
        ax.text(px, py, k, fontsize=14, ha="center")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("Fig. 6: regions I, II, III of 7T-QD")
    return _labels(ax).figure


def fig07(ctx):
    plt = _plt()
    res = ctx["res"]
    fig, ax = plt.subplots(figsize=(5, 7))
    _half_outline(ax)
    _region_image(ax, dg._pred("shaded"), (0, 0.5, 0, 0.87), n=900)
    _arc(ax, 1 / 3, 1 / 3, 0, 0.5, color="0.6", lw=1)
    _arc(ax, 6 / 5, 4 / 5, 0.4, II_III_END, color="0.6", lw=1)
    _arc(ax, 1, 1 / math.sqrt(3), 1 - 1 / math.sqrt(3), 0.5, color="C3", lw=1.5,
         label="(x-1)^2+y^2=1/3")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"Fig. 7: 7T-QD != 7T-D ({100 * res.fractions['shaded']:.4f}% of H)")
    return _labels(ax).figure


def _fig08(ctx, meas, tag, label):
    plt = _plt()
    sample = ctx["sample"]
    sh = sample["shaded"]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for s, c, ls in (("7t-le", "C2", ":"), ("7t-qd", "C0", "-"), ("7t-d", "C3", "--")):
        v = np.sort(sample[f"{meas} {s}"][sh])
        ax.plot(v, color=c, ls=ls, label=s.upper())
    ax.set_xlabel(f"triangles of the shaded region ({int(sh.sum())} grid points), sorted")
    ax.set_ylabel(f"{label} of the pentagon triangles (deg)")
    ax.legend()
    ax.set_title(f"Fig. 8({tag}): sorted {label}")
    return fig


def fig08a(ctx):
    return _fig08(ctx, "min", "a", "minimum angle")


def fig08b(ctx):
    return _fig08(ctx, "mean", "b", "mean minimum angle")


def _shaded_maps(ctx):
    """min / mean angle of QD and D on the zoom grid, NaN outside the shaded region."""
    if "maps" not in ctx:
        X, Y = _zoom_grid()
        shm = dg._pred("shaded")(X.ravel(), Y.ravel())
        maps = {"X": X, "Y": Y}
        for s in ("7t-qd", "7t-d", "7t-le"):
            for meas in ("min", "mean"):
                v = np.full(X.size, np.nan)
                v[shm] = dg.partition_measure(X.ravel()[shm], Y.ravel()[shm], s, meas,
                                              exact=False)
                maps[f"{meas} {s}"] = v.reshape(X.shape)
        ctx["maps"] = maps
    return ctx["maps"]


def _boundaries(ax):
    _arc(ax, 1, 1 / math.sqrt(3), 1 - 1 / math.sqrt(3), 0.5, color="0.4", lw=0.8)
    _arc(ax, 6 / 5, 4 / 5, 0.4, II_III_END, color="0.4", lw=0.8)
    _arc(ax, 1 / 3, 1 / 3, 0.4, 0.5, color="0.4", lw=0.8)
    ax.set_xlim(ZOOM[0], ZOOM[1])
    ax.set_ylim(ZOOM[2], ZOOM[3])


def fig09(ctx):
    plt = _plt()
    maps = _shaded_maps(ctx)
    fig, axs = plt.subplots(1, 2, figsize=(11, 5.5))
    vals = [maps["min 7t-qd"], maps["min 7t-d"]]
    vmin = min(np.nanmin(v) for v in vals)
    vmax = max(np.nanmax(v) for v in vals)
    for a, s, v in zip(axs, ("7T-QD", "7T-D"), vals, strict=True):
        im = a.imshow(v, origin="lower", extent=ZOOM, cmap="gray", vmin=vmin, vmax=vmax,
                      aspect="equal")
        _boundaries(a)
        _labels(a)
        a.set_title(f"{s}: min angle of the pentagon triangles")
    fig.colorbar(im, ax=axs, shrink=0.8, label="minimum angle (deg)")
    fig.suptitle("Fig. 9: min angle over the shaded region (the paper's gray maps)")
    return fig


def fig09_difference(ctx):
    plt = _plt()
    maps = _shaded_maps(ctx)
    res = ctx["res"]
    fig, axs = plt.subplots(1, 2, figsize=(11, 5.5))
    diff = maps["min 7t-d"] - maps["min 7t-qd"]
    im = axs[0].imshow(diff, origin="lower", extent=ZOOM, cmap="viridis", aspect="equal",
                       vmin=0)
    fig.colorbar(im, ax=axs[0], shrink=0.8, label="min angle 7T-D - 7T-QD (deg)")
    axs[0].set_title("difference: where is 7T-QD worse?")
    ratio = maps["min 7t-qd"] / maps["min 7t-d"]
    im = axs[1].imshow(ratio, origin="lower", extent=ZOOM, cmap="magma", aspect="equal",
                       vmax=1)
    fig.colorbar(im, ax=axs[1], shrink=0.8, label="min angle 7T-QD / 7T-D")
    w = res.worst["pentagon"]
    axs[1].plot(*w.point, "c*", ms=14, label=f"certified worst {w.value:.6f}")
    axs[1].legend(loc="upper left", fontsize=8)
    axs[1].set_title("ratio (the paper's '20% worse')")
    for a in axs:
        _boundaries(a)
        _labels(a)
    fig.suptitle("Fig. 9, made readable: min-angle difference and ratio, pentagon triangles")
    return fig


def fig09_mean_difference(ctx):
    plt = _plt()
    maps = _shaded_maps(ctx)
    fig, ax = plt.subplots(figsize=(6, 6))
    diff = maps["mean 7t-qd"] - maps["mean 7t-d"]
    lim = np.nanmax(np.abs(diff))
    im = ax.imshow(diff, origin="lower", extent=ZOOM, cmap="RdBu", aspect="equal",
                   vmin=-lim, vmax=lim)
    # masked, not NaN-filled: a fill value drew the zero line along the region's edges too
    ax.contour(maps["X"], maps["Y"], np.ma.masked_invalid(diff), levels=[0], colors="k",
               linewidths=1)
    fig.colorbar(im, ax=ax, shrink=0.8, label="mean min angle 7T-QD - 7T-D (deg)")
    _boundaries(ax)
    _labels(ax)
    ax.set_title("mean of min angles, 7T-QD - 7T-D (black: zero)")
    return fig


def _region_fig(ctx, num, pred, title, frac):
    plt = _plt()
    fig, ax = plt.subplots(figsize=(5.5, 6.5))
    _region_image(ax, dg._pred("shaded"), ZOOM, n=700, cmap="Greys", alpha=0.35)
    _region_image(ax, pred, ZOOM, n=700, cmap="Greys")
    _boundaries(ax)
    _labels(ax)
    ax.set_title(f"Fig. {num}: {title}\n({100 * frac:.4f}% of H, black; rest of the shaded "
                 "region grey)", fontsize=10)
    return fig


def fig10(ctx):
    f = ctx["res"].fractions
    return _region_fig(ctx, 10, dg._pred("C1"), "C1: min angle 7T-LE > 7T-QD", f["C1"])


def fig11(ctx):
    res = ctx["res"]
    frac = res.extra_areas["qd_mean_above_d"] / res.diagram_area
    return _region_fig(ctx, 11, dg._pred("qd_mean_above_d"),
                       "mean min angle 7T-QD > 7T-D (as the paper draws it)", frac)


def fig11_table1_c2(ctx):
    f = ctx["res"].fractions
    return _region_fig(ctx, "11 (Table 1's C2)", dg._pred("C2"),
                       "C2 = mean QD > mean D, minus C1", f["C2"])


def _grid_image(points, values):
    """Values on the cell centres of :func:`qdrefine.paper.iterated.diagram_grid` as an
    image ``(ny, nx)`` (NaN outside ``H``) and its extent."""
    xs = np.unique(points[:, 0])
    h = xs[1] - xs[0] if xs.size > 1 else 0.5
    ix = np.round((points[:, 0] - h / 2) / h).astype(int)
    iy = np.round((points[:, 1] - h / 2) / h).astype(int)
    img = np.full((iy.max() + 1, ix.max() + 1), np.nan)
    img[iy, ix] = values
    return img, (0.0, (ix.max() + 1) * h, 0.0, (iy.max() + 1) * h)


def _iterated_fig(ctx, scheme):
    plt = _plt()
    it = ctx["iterated"][scheme]
    p = it.points
    fig, axs = plt.subplots(1, 2, figsize=(10, 6), layout="constrained")
    img, ext = _grid_image(p, it.worst[-1])
    im = axs[0].imshow(img, origin="lower", extent=ext, cmap="viridis", aspect="equal",
                       interpolation="nearest", vmin=min(0.5, float(np.nanmin(img))),
                       vmax=max(1.0, float(np.nanmax(img))))  # one scale for every scheme
    fig.colorbar(im, ax=axs[0], shrink=0.8,
                 label=f"worst descendant min angle / initial, levels 1-{it.levels}")
    img, ext = _grid_image(p, it.classes[-1])
    im = axs[1].imshow(img, origin="lower", extent=ext, cmap="cividis", aspect="equal",
                       interpolation="nearest", norm=_lognorm(it.classes[-1]))
    fig.colorbar(im, ax=axs[1], shrink=0.8, label=f"similarity classes at level {it.levels}")
    for a in axs:
        _half_outline(a)
        _labels(a)
    axs[0].set_title(f"{scheme.upper()}: worst ratio (min {it.worst[-1].min():.4f})")
    axs[1].set_title(f"{scheme.upper()}: shapes at level {it.levels}\n"
                     f"(closed on {100 * it.closed.mean():.0f}% of the triangles)")
    fig.suptitle(f"Iterated {scheme.upper()} over the diagram ({len(p)} triangles)")
    return fig


def _lognorm(v):
    from matplotlib.colors import LogNorm

    return LogNorm(vmin=max(1, v.min()), vmax=max(2, v.max()))


#: name -> figure function (the paper's numbering).
FIGURES = {
    "fig01_7t_le": fig01,
    "fig02_7t_le_7t_d": fig02,
    "fig03_qhull": fig03,
    "fig04_diagram": fig04,
    "fig05_7t_qd": fig05,
    "fig06_regions": fig06,
    "fig07_shaded": fig07,
    "fig08a_sorted_min": fig08a,
    "fig08b_sorted_mean": fig08b,
    "fig09_min_angle_maps": fig09,
    "fig09b_difference_ratio": fig09_difference,
    "fig09c_mean_difference": fig09_mean_difference,
    "fig10_C1": fig10,
    "fig11_mean_qd_above_d": fig11,
    "fig11b_table1_C2": fig11_table1_c2,
}


def save_all(outdir: Path, ctx: dict) -> list[str]:
    """Draw every figure (and one iterated-study map per scheme in ``ctx['iterated']``) into
    ``outdir`` as PNG and SVG; returns the file names."""
    written: list[str] = []
    for name, fn in FIGURES.items():
        _save_one(fn(ctx), outdir, name, written)
    for scheme in ctx.get("iterated", {}):
        _save_one(_iterated_fig(ctx, scheme), outdir, f"iterated_{scheme.replace('-', '_')}",
                  written)
    return written
