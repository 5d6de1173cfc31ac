"""Made once with Gmsh 4.15 (`pip install gmsh`, not a dependency): writes two_regions_22.msh
and two_regions_41.msh, two unit squares (physical surfaces 1, 2) with tagged boundary and
interface lines (physical curves 10, 11, 12, 13, 20). Run from tests/data."""

import gmsh

gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.model.add("two_regions")
geo = gmsh.model.geo
p = [geo.addPoint(x, y, 0, 0.35) for x, y in [(0, 0), (1, 0), (2, 0), (2, 1), (1, 1), (0, 1)]]
lines = [geo.addLine(p[i], p[(i + 1) % 6]) for i in range(6)]  # 0-1,1-2,2-3,3-4,4-5,5-0
mid = geo.addLine(p[1], p[4])
left = geo.addPlaneSurface([geo.addCurveLoop([lines[0], mid, lines[4], lines[5]])])
right = geo.addPlaneSurface([geo.addCurveLoop([lines[1], lines[2], lines[3], -mid])])
geo.synchronize()
gmsh.model.addPhysicalGroup(2, [left], 1, "left")
gmsh.model.addPhysicalGroup(2, [right], 2, "right")
gmsh.model.addPhysicalGroup(1, [lines[0], lines[1]], 10, "bottom")
gmsh.model.addPhysicalGroup(1, [lines[2]], 11, "outlet")
gmsh.model.addPhysicalGroup(1, [lines[3], lines[4]], 12, "top")
gmsh.model.addPhysicalGroup(1, [lines[5]], 13, "inlet")
gmsh.model.addPhysicalGroup(1, [mid], 20, "interface")
gmsh.model.mesh.generate(2)
for v in ("2.2", "4.1"):
    gmsh.option.setNumber("Mesh.MshFileVersion", float(v))
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.write(f"two_regions_{v.replace('.', '')}.msh")
gmsh.finalize()
