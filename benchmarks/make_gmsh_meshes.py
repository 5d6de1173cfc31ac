"""Make the Gmsh-generated example meshes of ``src/qdrefine/data/gmsh/`` with the Gmsh SDK
(:func:`qdrefine.examples.gmsh_mesh` reads them).

These are the unstructured meshes users bring (Gmsh's default Frontal-Delaunay 2D mesher):
near-equilateral triangles, graded meshes with a size field, a boundary layer of anisotropic
triangles. The files are committed so that the tests do not depend on a Gmsh version; this
script records how they were made. Usage (needs ``pip install gmsh``)::

    python benchmarks/make_gmsh_meshes.py [src/qdrefine/data/gmsh]
"""

from __future__ import annotations

import sys
from pathlib import Path

import gmsh


def _start(name: str) -> None:
    gmsh.initialize(interruptible=False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.model.add(name)


def _polygon(xy: list[tuple[float, float]], h: float) -> tuple[int, list[int]]:
    occ = gmsh.model.geo
    pts = [occ.addPoint(x, y, 0, h) for x, y in xy]
    lines = [occ.addLine(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts))]
    return occ.addCurveLoop(lines), lines


def _finish(path: Path, lines_by_tag: dict[int, list[int]], surface_by_tag: dict[int, list[int]],
            names: dict[tuple[int, int], str]) -> None:
    gmsh.model.geo.synchronize()
    for tag, lines in lines_by_tag.items():
        gmsh.model.addPhysicalGroup(1, lines, tag, names.get((1, tag), ""))
    for tag, surfaces in surface_by_tag.items():
        gmsh.model.addPhysicalGroup(2, surfaces, tag, names.get((2, tag), ""))
    gmsh.model.mesh.generate(2)
    gmsh.write(str(path))
    gmsh.finalize()


def l_shape(path: Path, h: float = 0.25) -> None:
    """The L-shape ``[-1, 1]^2 minus (0, 1] x (0, 1]`` of the singular Poisson problem."""
    _start("l_shape")
    loop, lines = _polygon([(-1, -1), (1, -1), (1, 0), (0, 0), (0, 1), (-1, 1)], h)
    s = gmsh.model.geo.addPlaneSurface([loop])
    _finish(path, {1: lines}, {1: [s]}, {(1, 1): "boundary", (2, 1): "domain"})


def plate_with_hole(path: Path, h: float = 0.1) -> None:
    """A unit square plate with a hole of radius 0.2, finer at the hole."""
    _start("plate")
    geo = gmsh.model.geo
    outer, outer_lines = _polygon([(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)], h)
    c = geo.addPoint(0, 0, 0, h / 3)
    ring = [geo.addPoint(0.2 * x, 0.2 * y, 0, h / 3) for x, y in ((1, 0), (0, 1), (-1, 0),
                                                                     (0, -1))]
    arcs = [geo.addCircleArc(ring[i], c, ring[(i + 1) % 4]) for i in range(4)]
    hole = geo.addCurveLoop(arcs)
    s = geo.addPlaneSurface([outer, hole])
    _finish(path, {1: outer_lines, 2: arcs}, {1: [s]},
            {(1, 1): "outer", (1, 2): "hole", (2, 1): "plate"})


def step_channel(path: Path, h: float = 0.12) -> None:
    """A backward-facing step channel with two material regions (inlet and main)."""
    _start("step")
    geo = gmsh.model.geo
    p = [geo.addPoint(x, y, 0, h) for x, y in ((0, 0.5), (1, 0.5), (1, 0), (4, 0), (4, 1),
                                               (1, 1), (0, 1))]
    p_corner = p[1]
    gmsh.model.geo.mesh.setSize([(0, p_corner)], h / 6)
    lines = [geo.addLine(p[i], p[(i + 1) % 7]) for i in range(7)]
    inlet = geo.addLine(p[1], p[5])
    left = geo.addCurveLoop([lines[0], inlet, lines[5], lines[6]])
    right = geo.addCurveLoop([lines[1], lines[2], lines[3], lines[4], -inlet])
    s1 = geo.addPlaneSurface([left])
    s2 = geo.addPlaneSurface([right])
    _finish(path, {1: [lines[6]], 2: [lines[3]], 3: [lines[0], lines[1], lines[2], lines[4],
                                                     lines[5]]},
            {1: [s1], 2: [s2]},
            {(1, 1): "inlet", (1, 2): "outlet", (1, 3): "wall", (2, 1): "inlet region",
             (2, 2): "channel"})


def graded(path: Path) -> None:
    """A unit square graded towards its bottom edge and its middle by a size field, meshed
    with Gmsh's MeshAdapt algorithm: minimum angles near 28 degrees, sizes over a factor of
    thirty (the kind of mesh whose smallest angles are 25-30 degrees)."""
    _start("graded")
    loop, lines = _polygon([(0, 0), (1, 0), (1, 1), (0, 1)], 0.1)
    s = gmsh.model.geo.addPlaneSurface([loop])
    gmsh.model.geo.synchronize()
    f = gmsh.model.mesh.field
    f.add("MathEval", 1)
    f.setString(1, "F", "0.01 + 0.5 * (x - 0.5) * (x - 0.5) + 0.3 * y")
    f.setAsBackgroundMesh(1)
    gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 1)
    _finish(path, {1: [lines[0]], 2: lines[1:]}, {1: [s]},
            {(1, 1): "wall", (1, 2): "far"})


def boundary_layer(path: Path, h: float = 0.08) -> None:
    """A channel ``[0, 2] x [0, 0.5]`` with a Gmsh boundary layer (field ``BoundaryLayer``,
    triangles) on its bottom wall: first layer 0.004 thick, growth 1.3, 0.06 in all;
    anisotropic triangles with smallest angles of a few degrees under near-equilateral
    ones."""
    _start("boundary_layer")
    loop, lines = _polygon([(0, 0), (2, 0), (2, 0.5), (0, 0.5)], h)
    s = gmsh.model.geo.addPlaneSurface([loop])
    gmsh.model.geo.synchronize()
    f = gmsh.model.mesh.field
    f.add("BoundaryLayer", 1)
    f.setNumbers(1, "CurvesList", [lines[0]])
    f.setNumber(1, "Size", 0.004)
    f.setNumber(1, "Ratio", 1.3)
    f.setNumber(1, "Thickness", 0.06)
    f.setNumber(1, "Quads", 0)
    f.setAsBoundaryLayer(1)
    _finish(path, {1: [lines[0]], 2: lines[1:]}, {1: [s]},
            {(1, 1): "wall", (1, 2): "far"})


MESHES = {"l_shape.msh": l_shape, "plate_with_hole.msh": plate_with_hole,
          "step.msh": step_channel, "graded.msh": graded,
          "boundary_layer.msh": boundary_layer}


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for name, make in MESHES.items():
        make(out / name)
        print("wrote", out / name)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1
         else Path(__file__).parents[1] / "src" / "qdrefine" / "data" / "gmsh")
