"""A uniform grid over the diagram with every region's membership and every scheme's
minimum and mean minimum angle (the pentagon triangles), for the table and the figures."""

from __future__ import annotations

import numpy as np

from .. import diagram as dg

__all__ = ["region_sample"]


def region_sample(step: float = 1 / 1200) -> dict[str, np.ndarray]:
    """A uniform grid over ``H`` (cell centres) with exact scheme decisions.

    Returns x, y, the region masks and the min/mean angles of each scheme (pentagon).
    """
    xs = np.arange(step / 2, 0.5, step)
    ys = np.arange(step / 2, 0.87, step)
    X, Y = (a.ravel() for a in np.meshgrid(xs, ys))
    keep = dg.inside_half(X, Y)
    X, Y = X[keep], Y[keep]
    out = {"x": X, "y": Y}
    out.update(dg.region_masks(X, Y))
    out["III-shaded"] = out["III"] & ~out["shaded"]
    for s in ("7t-le", "7t-qd", "7t-d"):
        out[f"min {s}"] = dg.partition_measure(X, Y, s, "min")
        out[f"mean {s}"] = dg.partition_measure(X, Y, s, "mean")
    return out
