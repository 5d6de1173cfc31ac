"""Random conforming test meshes."""

from __future__ import annotations

import numpy as np

from qdrefine import Mesh


def jittered_grid(n: int, seed: int, shear: float = 0.0, shuffle: bool = True) -> Mesh:
    """An ``n x n`` grid, jittered by up to 0.15 cell per coordinate (so every quad stays
    convex: a triangle's twice-area is at least (1 - 2j)^2 - 2j (1 + 2j) = 0.1 of a cell's
    for jitter j = 0.15), each quad cut by a random diagonal,
    optionally sheared (needles) and with shuffled vertex and triangle order. Boundary
    edges get tags 1..4 (bottom, right, top, left), cells tags 0/1 by diagonal."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, n + 1)
    pts = np.stack(np.meshgrid(x, x, indexing="xy"), axis=-1).reshape(-1, 2)
    inner = (pts > 0).all(1) & (pts < 1).all(1)
    pts[inner] += rng.uniform(-0.15, 0.15, size=(inner.sum(), 2)) / n
    pts = pts @ np.array([[1.0, shear], [0.0, 1.0]]).T
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    diag = rng.random(a.size) < 0.5
    t1 = np.where(diag[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    t2 = np.where(diag[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    tris = np.concatenate([t1, t2])
    tags = np.concatenate([diag, diag]).astype(int)
    r = np.arange(n)
    edges = np.concatenate([
        np.stack([idx[0, r], idx[0, r + 1]], 1), np.stack([idx[r, n], idx[r + 1, n]], 1),
        np.stack([idx[n, r + 1], idx[n, r]], 1), np.stack([idx[r + 1, 0], idx[r, 0]], 1)])
    edge_tags = np.repeat([1, 2, 3, 4], n)
    if shuffle:
        perm = rng.permutation(len(pts))
        inv = np.argsort(perm)
        pts, tris, edges = pts[perm], inv[tris], inv[edges]
        order = rng.permutation(len(tris))
        tris, tags = tris[order], tags[order]
    return Mesh(pts, tris, tags, edges, edge_tags)
