"""Generate worlds/meshes/hertz_block.msh: the block the Hertz contact validation presses a sphere into.

A 120 x 120 x 60 mm block (x, y in [-60, 60], z in [-60, 0]; top face on z = 0), much larger than the 8 mm
sphere and its contact (radius sqrt(R d) <= 4.9 mm at 3 mm), as unstructured linear tetrahedra graded from
`fine` mm at the top centre, where the sphere presses, growing 0.25 mm per mm of distance beyond 5 mm, up to
15 mm. Unstructured on purpose: spring calibrations are fitted element by element, and on a structured grid
every element has the same orientation, so their per-element anisotropy adds up instead of averaging out
(on Kuhn cubes calibrated springs are 1.6-2.3x too stiff in this test).

Regenerate (needs the `gmsh` Python package; CI does not, the .msh output is committed):

    python3 -m pip install gmsh
    python3 worlds/meshes/make_hertz_block.py 0.5 worlds/meshes/hertz_block.msh

Arguments: the fine size in mm (default 0.5: 4203 nodes, 20,789 tetrahedra, binary MSH 4.1, ~1 MB) and the
output path. Frontal 3-D meshing (gmsh's Delaunay crashed on this size field at 0.6 and 1.0 mm); one thread,
so the output is deterministic for a given gmsh version (the committed file came from gmsh 4.15.2).
"""

import sys

import gmsh

fine_mm = float(sys.argv[1]) if len(sys.argv) > 1 else 0.5
out = sys.argv[2] if len(sys.argv) > 2 else "hertz_block.msh"

gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.option.setNumber("General.NumThreads", 1)
gmsh.model.add("hertz_block")
block = gmsh.model.occ.addBox(-60.0, -60.0, -60.0, 120.0, 120.0, 60.0)
centre = gmsh.model.occ.addPoint(0.0, 0.0, 0.0)
gmsh.model.occ.synchronize()
gmsh.model.mesh.embed(0, [centre], 3, block)
fields = gmsh.model.mesh.field
fields.add("Distance", 1)
fields.setNumbers(1, "PointsList", [centre])
fields.add("MathEval", 2)
fields.setString(2, "F", f"Max({fine_mm}, Min(15, {fine_mm} + 0.25 * (F1 - 5)))")
fields.setAsBackgroundMesh(2)
gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
# Only the volume is saved: a physical group on it makes gmsh drop the surface and line elements.
gmsh.model.addPhysicalGroup(3, [block], name="tissue")
gmsh.option.setNumber("Mesh.Algorithm3D", 4)  # Frontal
gmsh.model.mesh.generate(3)
gmsh.model.mesh.optimize("Netgen")
gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
gmsh.option.setNumber("Mesh.Binary", 1)
gmsh.option.setNumber("Mesh.SaveAll", 0)
gmsh.write(out)

tags, _, _ = gmsh.model.mesh.getNodes()
types, element_tags, _ = gmsh.model.mesh.getElements(3)
tets = sum(len(t) for kind, t in zip(types, element_tags) if kind == 4)
print(f"fine {fine_mm} mm: {len(tags)} nodes, {tets} tetrahedra -> {out}")
gmsh.finalize()
