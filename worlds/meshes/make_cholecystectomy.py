"""Generate the two volumes of worlds/cholecystectomy.toml: a liver with a gallbladder bed, and the gallbladder on
its plate of connective tissue.

- cholecystectomy_liver.msh: worlds/meshes/liver.msh's organ (a right lobe of semi-axes 60 x 45 x 30 mm at
  (20, 0, -30) fused with a left lobe of 40 x 30 x 18 mm at (-45, 10, -30), the posterior face flat at z = -45 mm)
  with a shallow bed cut into the right lobe's dome: the box x in [-2, 52], y in [-22, 22] above z = -4 mm is
  removed, so the bed's floor is flat at z = -4 mm (the gallbladder fossa).
- gallbladder.msh: the gallbladder, an ellipsoid of semi-axes 24 x 9 x 8 mm at (20, 0, 6), fused with the plate
  that joins it to the bed, a slab x in [0, 48], y in [-9, 9], z in [-4, -1] mm. The bed is wider than the plate
  on every side, so a hook can be lowered into it beside the plate and drawn across under the gallbladder. The plate's bottom face lies on
  the bed's floor (the world fixes the nodes on it); the gallbladder's lowest millimetre is sunk into the plate's
  top. The plate is meshed finer (2.5 mm) than the gallbladder (5 mm).

Regenerate (needs the `gmsh` Python package; CI does not, the .msh outputs are committed):

    python3 -m pip install gmsh
    python3 worlds/meshes/make_cholecystectomy.py worlds/meshes

Argument: the output directory. Deterministic for a given gmsh version (the committed files came from gmsh 4.15.2).
Only the volumes are written; the server computes each boundary surface from the tetrahedra.
"""

import os
import sys

import gmsh

out_dir = sys.argv[1] if len(sys.argv) > 1 else "."

BED = dict(x0=-2.0, x1=52.0, y0=-22.0, y1=22.0, floor_z=-4.0)
PLATE = dict(x0=0.0, x1=48.0, y0=-9.0, y1=9.0, z0=-4.0, z1=-1.0)


def finish(name, size_mm, out, size_field=None):
    gmsh.model.occ.synchronize()
    volumes = [tag for dim, tag in gmsh.model.getEntities(3)]
    gmsh.model.addPhysicalGroup(3, volumes, name=name)
    gmsh.option.setNumber("Mesh.MeshSizeMin", size_mm if size_field is None else 0.5)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size_mm)
    if size_field is not None:
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.model.mesh.field.setAsBackgroundMesh(size_field)
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
    print(f"{name}: {len(tags)} nodes, {tets} tetrahedra -> {out}")


def liver(out):
    gmsh.model.add("liver")
    occ = gmsh.model.occ
    right = occ.addSphere(0.0, 0.0, 0.0, 1.0)
    occ.dilate([(3, right)], 0.0, 0.0, 0.0, 60.0, 45.0, 30.0)
    occ.translate([(3, right)], 20.0, 0.0, -30.0)
    left = occ.addSphere(0.0, 0.0, 0.0, 1.0)
    occ.dilate([(3, left)], 0.0, 0.0, 0.0, 40.0, 30.0, 18.0)
    occ.translate([(3, left)], -45.0, 10.0, -30.0)
    fused, _ = occ.fuse([(3, right)], [(3, left)])
    tray = occ.addBox(-200.0, -200.0, -200.0, 400.0, 400.0, 155.0)
    bed = occ.addBox(
        BED["x0"], BED["y0"], BED["floor_z"], BED["x1"] - BED["x0"], BED["y1"] - BED["y0"], 40.0
    )
    occ.cut(fused, [(3, tray), (3, bed)])
    finish("liver", 7.0, out)


def gallbladder(out):
    gmsh.model.add("gallbladder")
    occ = gmsh.model.occ
    body = occ.addSphere(0.0, 0.0, 0.0, 1.0)
    occ.dilate([(3, body)], 0.0, 0.0, 0.0, 24.0, 9.0, 8.0)
    occ.translate([(3, body)], 20.0, 0.0, 6.0)
    plate = occ.addBox(
        PLATE["x0"],
        PLATE["y0"],
        PLATE["z0"],
        PLATE["x1"] - PLATE["x0"],
        PLATE["y1"] - PLATE["y0"],
        PLATE["z1"] - PLATE["z0"],
    )
    occ.fuse([(3, body)], [(3, plate)])
    occ.synchronize()
    field = gmsh.model.mesh.field
    fine = field.add("Box")
    field.setNumber(fine, "VIn", 2.5)
    field.setNumber(fine, "VOut", 5.0)
    for key, value in [
        ("XMin", PLATE["x0"] - 1.0),
        ("XMax", PLATE["x1"] + 1.0),
        ("YMin", PLATE["y0"] - 1.0),
        ("YMax", PLATE["y1"] + 1.0),
        ("ZMin", PLATE["z0"] - 1.0),
        ("ZMax", PLATE["z1"] + 0.5),
        ("Thickness", 2.0),
    ]:
        field.setNumber(fine, key, value)
    finish("gallbladder", 5.0, out, size_field=fine)


gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
gmsh.option.setNumber("General.NumThreads", 1)  # deterministic output
liver(os.path.join(out_dir, "cholecystectomy_liver.msh"))
gmsh.clear()
gallbladder(os.path.join(out_dir, "gallbladder.msh"))
gmsh.finalize()
