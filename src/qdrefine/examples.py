"""Small built-in meshes for demos, docs and tests (made by hand, no mesher needed)."""

from __future__ import annotations

import numpy as np

from .mesh import Mesh

__all__ = ["plate_with_hole", "square", "OUTER", "HOLE", "LEFT", "RIGHT"]

OUTER, HOLE = 1, 2  # edge tags
LEFT, RIGHT = 1, 2  # cell tags


def plate_with_hole(n_around: int = 32, n_rings: int = 6, radius: float = 0.4) -> Mesh:
    """A plate with a circular hole, meshed in rings (outer boundary: the points where
    ``n_around`` rays meet the square ``[-1, 1]^2``, so its corners are cut).

    Ring ``j`` interpolates between the circle of ``radius`` (j = 0) and the square
    (j = n_rings) along ``n_around`` rays; each quadrilateral is cut by its shorter
    diagonal. Edge tags: :data:`OUTER` on the square, :data:`HOLE` on the circle. Cell tags:
    :data:`LEFT` where the centroid has x < 0, :data:`RIGHT` elsewhere.
    """
    theta = 2 * np.pi * np.arange(n_around) / n_around + np.pi / n_around
    circle = radius * np.stack([np.cos(theta), np.sin(theta)], axis=1)
    square = circle / np.abs(circle).max(axis=1, keepdims=True)
    s = np.linspace(0.0, 1.0, n_rings + 1)[:, None, None]
    points = (circle + s * (square - circle)).reshape(-1, 2)
    idx = np.arange(points.shape[0]).reshape(n_rings + 1, n_around)
    a, b = idx[:-1], np.roll(idx[:-1], -1, axis=1)
    c, d = np.roll(idx[1:], -1, axis=1), idx[1:]
    a, b, c, d = (x.ravel() for x in (a, b, c, d))
    ac = np.linalg.norm(points[a] - points[c], axis=1)
    bd = np.linalg.norm(points[b] - points[d], axis=1)
    cut_ac = ac <= bd
    t1 = np.where(cut_ac[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    t2 = np.where(cut_ac[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    triangles = np.concatenate([t1, t2])[:, ::-1]  # rings run counter-clockwise: flip
    centroid_x = points[triangles].mean(axis=1)[:, 0]
    cell_tags = np.where(centroid_x < 0, LEFT, RIGHT)
    ring = np.arange(n_around)
    hole = np.stack([idx[0, (ring + 1) % n_around], idx[0, ring]], axis=1)
    outer = np.stack([idx[-1, ring], idx[-1, (ring + 1) % n_around]], axis=1)
    edges = np.concatenate([outer, hole])
    edge_tags = np.repeat([OUTER, HOLE], n_around)
    return Mesh(points, triangles, cell_tags, edges, edge_tags)


def square(n: int = 4) -> Mesh:
    """The unit square cut into ``2 n^2`` right isosceles triangles (many exact ties)."""
    x = np.linspace(0.0, 1.0, n + 1)
    points = np.stack(np.meshgrid(x, x, indexing="xy"), axis=-1).reshape(-1, 2)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return Mesh(points, triangles)
