"""Generate worlds/meshes/liver.msh: a liver-like organ as linear tetrahedra, for worlds/liver.toml.

The shape is an adult liver's at about 0.8 scale: a large right lobe (an ellipsoid of semi-axes 60 x 45 x 30 mm
centred at (20, 0, -30)) fused with a thinner left lobe (40 x 30 x 18 mm at (-45, 10, -30)), with its
posterior (bottom) face cut flat at z = -45 mm where it rests on the tray and is fixed. The right lobe's dome
peaks at z = 0, under the device origins, so the probes press it from above like the pad. Overall about
165 x 90 x 45 mm.

Regenerate (needs the `gmsh` Python package; CI does not, the .msh output is committed):

    python3 -m pip install gmsh
    python3 worlds/meshes/make_liver.py 7.0 worlds/meshes/liver.msh

Arguments: target element size in mm (default 7.0), output path. The output is deterministic for a given gmsh
version (the committed file came from gmsh 4.15.2). Only the volume is written; the server computes the
boundary surface from the tetrahedra.
"""

import sys

import gmsh

size_mm = float(sys.argv[1]) if len(sys.argv) > 1 else 7.0
out = sys.argv[2] if len(sys.argv) > 2 else "liver.msh"

gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.option.setNumber("General.NumThreads", 1)  # deterministic output
gmsh.model.add("liver")
occ = gmsh.model.occ
right = occ.addSphere(0.0, 0.0, 0.0, 1.0)
occ.dilate([(3, right)], 0.0, 0.0, 0.0, 60.0, 45.0, 30.0)
occ.translate([(3, right)], 20.0, 0.0, -30.0)
left = occ.addSphere(0.0, 0.0, 0.0, 1.0)
occ.dilate([(3, left)], 0.0, 0.0, 0.0, 40.0, 30.0, 18.0)
occ.translate([(3, left)], -45.0, 10.0, -30.0)
fused, _ = occ.fuse([(3, right)], [(3, left)])
# Flat posterior face: keep z >= -45.
tray = occ.addBox(-200.0, -200.0, -200.0, 400.0, 400.0, 155.0)
organ, _ = occ.cut(fused, [(3, tray)])
occ.synchronize()
volumes = [tag for dim, tag in organ if dim == 3]
gmsh.model.addPhysicalGroup(3, volumes, name="liver")
gmsh.option.setNumber("Mesh.MeshSizeMin", size_mm)
gmsh.option.setNumber("Mesh.MeshSizeMax", size_mm)
gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay
gmsh.model.mesh.generate(3)
gmsh.model.mesh.optimize("Netgen")
gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
gmsh.option.setNumber("Mesh.Binary", 0)
gmsh.option.setNumber("Mesh.SaveAll", 0)
gmsh.write(out)

tags, _, _ = gmsh.model.mesh.getNodes()
types, element_tags, _ = gmsh.model.mesh.getElements(3)
tets = sum(len(t) for kind, t in zip(types, element_tags) if kind == 4)
print(f"size {size_mm} mm: {len(tags)} nodes, {tets} tetrahedra -> {out}")
gmsh.finalize()
