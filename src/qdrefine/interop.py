"""Bridges to the libraries users hold their meshes in: meshio, scikit-fem and matplotlib.

Each converter keeps what the other side can hold: tags, tagged edges, physical names,
point and cell data (meshio); boundaries and subdomains as names (scikit-fem); and the
plain arrays (matplotlib). The peers are imported on first use (they are optional).

Examples
--------
>>> import qdrefine
>>> from qdrefine import examples, interop
>>> mesh = examples.gmsh_mesh("plate_with_hole")
>>> back = interop.from_meshio(interop.to_meshio(mesh))
>>> back.physical_names == mesh.physical_names and back.n_triangles == mesh.n_triangles
True
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .arguments import as_ids
from .io import mesh_of
from .io._core import RawMesh
from .io.meshio_formats import meshio_mesh, raw_from_meshio
from .mesh import Mesh
from .numbering import edge_ids

__all__ = ["to_meshio", "from_meshio", "to_skfem", "from_skfem", "to_triangulation",
           "from_triangulation"]

#: The name a converted peer mesh has in error messages.
_PEER = Path("<{}>")


def to_meshio(mesh: Mesh):
    """``mesh`` as a ``meshio.Mesh``: points ``(N, 3)`` with ``z = 0``, a ``line`` block of
    the tagged edges and a ``triangle`` block, tags as the cell data ``gmsh:physical``
    (untagged triangles: 0), the physical names as ``field_data`` (``name -> [tag, dim]``),
    point data, cell data (the edge rows zero) and the refinement history as the cell data
    ``qdrefine:transitions`` and ``qdrefine:origins``. Not every meshio writer takes all
    of that: its Gmsh 4.1 writer wants ``gmsh:dim_tags``, its Gmsh 2.2 writer fields of
    1, 3 or 9 components; :func:`qdrefine.write` to ``.msh`` keeps everything."""
    if mesh.edge_tags is not None and (mesh.edge_tags == 0).any():  # as qdrefine.write says
        warnings.warn(f"<meshio.Mesh>: {int((mesh.edge_tags == 0).sum())} edges have tag 0, "
                      "which reads back as untagged", stacklevel=2)
    return meshio_mesh(mesh, "gmsh:physical", names=True, for_files=False)


def from_meshio(m) -> Mesh:
    """The :class:`Mesh` of a ``meshio.Mesh`` (as :func:`qdrefine.read` makes it of a file):
    triangles, ``line`` cells with tags as tagged edges, tags from the first cell data of
    ``gmsh:physical``, ``medit:ref``, ``tag``, ``cell_tags``, physical names from
    ``field_data``, numeric point and cell data; other cell types are an error, as in
    files. ``ValueError`` for what is not a valid flat triangle mesh."""
    return mesh_of(raw_from_meshio(m, Path(str(_PEER).format("meshio.Mesh"))))


def to_skfem(mesh: Mesh):
    """``mesh`` as a ``skfem.MeshTri`` with the same point and triangle numbering (triangle
    rows are not sorted), tagged edges as boundaries and cell tags as subdomains, each named
    by its physical name or ``"tag <n>"``; tag 0 ("untagged") makes neither, so that
    :func:`from_skfem` gives those triangles tag 0 again."""
    import skfem

    m = skfem.MeshTri(np.ascontiguousarray(mesh.points.T, dtype=np.float64),
                      np.ascontiguousarray(mesh.triangles.T, dtype=np.int64), sort_t=False)
    names = mesh.physical_names or {}
    boundaries: dict[str, NDArray] = {}
    subdomains: dict[str, NDArray] = {}
    if mesh.edges is not None and len(mesh.edges):
        facets = _facet_ids(m.facets.T, np.asarray(mesh.edges), mesh.n_points)
        for tag in np.unique(mesh.edge_tags[mesh.edge_tags != 0]):  # one name: one boundary
            name = names.get((1, int(tag)), f"tag {tag}")
            boundaries[name] = np.unique(np.concatenate(
                [boundaries.get(name, facets[:0]), facets[mesh.edge_tags == tag]]))
    if mesh.cell_tags is not None:
        for tag in np.unique(mesh.cell_tags[mesh.cell_tags != 0]):
            name = names.get((2, int(tag)), f"tag {tag}")
            subdomains[name] = np.union1d(subdomains.get(name, []),
                                          np.flatnonzero(mesh.cell_tags == tag)).astype(np.int64)
    if boundaries:
        m = m.with_boundaries(boundaries, boundaries_only=False)
    if subdomains:
        m = m.with_subdomains(subdomains)
    return m


def from_skfem(m) -> Mesh:
    """The :class:`Mesh` of a ``skfem.MeshTri`` (P1 geometry): points and triangles
    (clockwise ones flipped, with a warning), named boundaries as tagged edges and named
    subdomains as cell tags (tags 1, 2, ... in name order, the names as physical names;
    triangles in no subdomain get tag 0)."""
    elem = getattr(m, "elem", None)
    if elem is not None and getattr(elem, "__name__", "") != "ElementTriP1":
        raise ValueError(f"from_skfem takes a linear triangle mesh (skfem.MeshTri), got "
                         f"{type(m).__name__} (its {elem.__name__} geometry would be lost)")
    points = np.ascontiguousarray(np.asarray(m.p, dtype=np.float64).T)
    triangles = np.ascontiguousarray(np.asarray(m.t, dtype=np.int64).T)
    if triangles.ndim != 2 or triangles.shape[1] != 3 or points.shape[1] != 2:
        raise ValueError("from_skfem takes a 2D triangle mesh (skfem.MeshTri)")
    raw = RawMesh(Path(str(_PEER).format("skfem.MeshTri")), points, triangles)
    subdomains = getattr(m, "subdomains", None) or {}
    if subdomains:
        raw.cell_tags = np.zeros(len(triangles), dtype=np.int64)
        owner: dict[int, str] = {}
        for tag, name in enumerate(sorted(subdomains), start=1):
            ids = as_ids(subdomains[name], len(triangles), f"{raw.path}: subdomain {name!r}",
                         "triangles")
            taken = ids[raw.cell_tags[ids] != 0]
            if taken.size:  # a cell tag is one per triangle
                raise ValueError(f"{raw.path}: triangle {int(taken[0])} is in the subdomains "
                                 f"{owner[int(raw.cell_tags[taken[0]])]!r} and {name!r}; cell "
                                 "tags hold one subdomain per triangle")
            raw.cell_tags[ids] = tag
            owner[tag] = name
            raw.physical_names[(2, tag)] = name
    boundaries = getattr(m, "boundaries", None) or {}
    if boundaries:
        facets = np.asarray(m.facets, dtype=np.int64).T
        edges, tags = [], []
        for tag, name in enumerate(sorted(boundaries), start=1):
            ids = as_ids(boundaries[name], len(facets), f"{raw.path}: boundary {name!r}",
                         "facets")
            edges.append(facets[ids])
            tags.append(np.full(len(ids), tag, dtype=np.int64))
            raw.physical_names[(1, tag)] = name
        raw.edges, raw.edge_tags = np.concatenate(edges), np.concatenate(tags)
    return mesh_of(raw)


def to_triangulation(mesh: Mesh):
    """``mesh`` as a ``matplotlib.tri.Triangulation`` (same numbering), for ``tripcolor``,
    ``tricontour`` and friends."""
    from matplotlib.tri import Triangulation

    return Triangulation(mesh.points[:, 0], mesh.points[:, 1], np.asarray(mesh.triangles))


def from_triangulation(tri) -> Mesh:
    """The :class:`Mesh` of a ``matplotlib.tri.Triangulation``: its points and its
    triangles but the masked ones (clockwise ones flipped, with a warning); the points of
    masked triangles stay, unused."""
    points = np.column_stack([np.asarray(tri.x, dtype=np.float64),
                              np.asarray(tri.y, dtype=np.float64)])
    triangles = np.asarray(tri.triangles, dtype=np.int64)
    if tri.mask is not None:
        triangles = triangles[~np.asarray(tri.mask, dtype=bool)]
    return mesh_of(RawMesh(Path(str(_PEER).format("Triangulation")), points, triangles))


def _facet_ids(facets: NDArray, edges: NDArray, n: int) -> NDArray[np.int64]:
    """Row of each edge ``(K, 2)`` in skfem's facets ``(F, 2)``; ``ValueError`` if one is
    missing."""
    lo_hi = np.sort(facets, axis=1).astype(np.int64)
    order = np.argsort(lo_hi[:, 0] * n + lo_hi[:, 1])
    ids = edge_ids(lo_hi[order], edges, n)
    if (ids < 0).any():
        raise ValueError("a tagged edge is not an edge of the mesh")
    return order[ids]
