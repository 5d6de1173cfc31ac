"""Small built-in meshes for demos, docs and tests: made by hand (no mesher needed), and a
few unstructured meshes made by Gmsh (shipped as files)."""

from __future__ import annotations

from importlib.resources import as_file, files

import numpy as np

from .io import read
from .mesh import Mesh

__all__ = ["plate_with_hole", "square", "jittered_square", "gmsh_mesh", "GMSH_MESHES",
           "OUTER", "HOLE", "LEFT", "RIGHT"]

#: The Gmsh-made meshes of :func:`gmsh_mesh`: name, what it is.
GMSH_MESHES = {
    "l_shape": "the L-shape [-1, 1]^2 minus (0, 1]^2, 126 near-equilateral triangles, "
               "smallest angle 42.1 deg",
    "plate_with_hole": "a square plate with a circular hole, finer at the hole, 560 "
                       "triangles, smallest angle 34.4 deg, physical names",
    "step": "a backward-facing step channel, two regions, finer at the step corner, 888 "
            "triangles, smallest angle 38.7 deg",
    "graded": "a square graded by a size field (MeshAdapt), 314 triangles over a factor of "
              "thirty in size, smallest angle 27.9 deg",
    "boundary_layer": "a channel with a Gmsh boundary layer on its bottom wall, 620 "
                      "triangles, 250 of them under 10 deg, smallest angle 0.7 deg",
}


def gmsh_mesh(name: str) -> Mesh:
    """One of the unstructured meshes made by Gmsh 4 (Frontal-Delaunay or MeshAdapt), as
    users bring them: near-equilateral triangles, size grading, tagged boundaries and
    regions. ``benchmarks/make_gmsh_meshes.py`` records how they were made; the smallest
    angles in :data:`GMSH_MESHES` are those of the files (tested)."""
    if name not in GMSH_MESHES:
        raise ValueError(f"unknown Gmsh example {name!r}; choose one of: "
                         f"{', '.join(GMSH_MESHES)}")
    with as_file(files("qdrefine") / "data" / "gmsh" / f"{name}.msh") as path:
        return read(path)

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
    points, idx, (a, b, c, d) = _grid(n)
    triangles = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return Mesh(points, triangles)


def jittered_square(n: int = 4, seed: int = 0, shear: float = 0.0,
                    shuffle: str = "all") -> Mesh:
    """The unit square cut into ``n x n`` quads, each split by a random diagonal, with no ties.

    Inner points move by up to 0.15 cell per coordinate, so every quad stays convex (a
    triangle's twice-area is at least ``(1 - 2j)^2 - 2j (1 + 2j) = 0.1`` of a cell's for
    jitter ``j = 0.15``); ``shear`` maps ``x -> x + shear y`` (needles). Boundary edges are
    tagged 1..4 (bottom, right, top, left), cells 0/1 by diagonal. ``shuffle``: ``"all"``
    renumbers the vertices and reorders the triangles at random, ``"points"`` only renumbers
    the vertices, ``"none"`` keeps the grid order.
    """
    rng = np.random.default_rng(seed)
    points, idx, (a, b, c, d) = _grid(n)
    inner = (points > 0).all(1) & (points < 1).all(1)
    points[inner] += rng.uniform(-0.15, 0.15, size=(int(inner.sum()), 2)) / n
    points = points @ np.array([[1.0, shear], [0.0, 1.0]]).T
    diag = rng.random(a.size) < 0.5
    t1 = np.where(diag[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    t2 = np.where(diag[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    triangles = np.concatenate([t1, t2])
    tags = np.concatenate([diag, diag]).astype(np.int64)
    r = np.arange(n)
    edges = np.concatenate([
        np.stack([idx[0, r], idx[0, r + 1]], 1), np.stack([idx[r, n], idx[r + 1, n]], 1),
        np.stack([idx[n, r + 1], idx[n, r]], 1), np.stack([idx[r + 1, 0], idx[r, 0]], 1)])
    edge_tags = np.repeat([1, 2, 3, 4], n)
    if shuffle not in ("all", "points", "none"):
        raise ValueError(f"shuffle must be 'all', 'points' or 'none', got {shuffle!r}")
    if shuffle != "none":
        perm = rng.permutation(len(points))
        inv = np.argsort(perm)
        points, triangles, edges = points[perm], inv[triangles], inv[edges]
    if shuffle == "all":
        order = rng.permutation(len(triangles))
        triangles, tags = triangles[order], tags[order]
    return Mesh(points, triangles, tags, edges, edge_tags)


def _grid(n: int) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
    """``(n+1)^2`` grid points of the unit square, their index grid, and the corners
    ``a, b, c, d`` (counter-clockwise from the lower left) of every cell."""
    x = np.linspace(0.0, 1.0, n + 1)
    points = np.stack(np.meshgrid(x, x, indexing="xy"), axis=-1).reshape(-1, 2)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    corners = (idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(),
               idx[1:, :-1].ravel())
    return points, idx, corners
