"""Gmsh MSH 2.2 and 4.1, ASCII and binary: read and write, with physical names, tagged lines
and point / cell data (``$NodeData`` / ``$ElementData``).

Reading parses each section with whole-array NumPy operations (``np.fromstring`` for text,
``np.frombuffer`` for binary); writing formats whole arrays at once. Files in MSH 2.0-2.2
and 4.1 are read (4.0 goes to meshio); 4.1 is written by default, 2.2 on request.

Layout of the files written
---------------------------
- Points are node tags ``1..N`` in one node block; z is written as 0.
- Triangles are elements ``1..M`` (in mesh order), tagged lines ``M+1..M+K``. In MSH 2.2
  each element carries its physical tag (0: none) and a geometrical tag; in MSH 4.1 the
  elements are grouped into one entity per tag value (a surface for each cell tag, a curve
  for each edge tag), whose physical tag is the tag (none for 0). Reading sorts elements by
  element tag, so the mesh order survives the grouping.
- ``$PhysicalNames`` holds :attr:`~qdrefine.Mesh.physical_names`.
- Each point-data field is a ``$NodeData`` view, each cell-data field an ``$ElementData``
  view over the triangles, named by the field. Gmsh views have 1, 3 or 9 components and
  hold doubles: other widths are padded with zeros, and a ``$QdrefineData`` section (which
  Gmsh and meshio skip) records each field's shape and dtype so that qdrefine reads the field
  back as it was. It comes before the mesh: a file cut short keeps it, and a view it records
  that the file lacks is an error. Integer data of 2**53 or more in magnitude is refused:
  a double holds 2**53 exactly, but 2**53 + 1 rounds to it.
"""

from __future__ import annotations

from .common import ELEMENTS, VERSIONS, GmshError
from .reading import read
from .writing import write

__all__ = ["read", "write", "VERSIONS", "ELEMENTS", "GmshError"]
