"""Generate worlds/meshes/tet_block.msh: a 40 x 30 x 10 mm block of tissue as linear tetrahedra.

The block spans x in [-20, 20], y in [-15, 15], z in [-10, 0] mm: its top face lies on z = 0 with outward
normal +z, like the pad, so the demo probes press it from above.

Regenerate (needs the `gmsh` Python package; CI does not, the .msh output is committed):

    python3 -m venv /tmp/gmshvenv && /tmp/gmshvenv/bin/pip install gmsh
    /tmp/gmshvenv/bin/python worlds/meshes/make_tet_block.py 3.0 worlds/meshes/tet_block.msh

Arguments: target element size in mm (default 3.0: 796 nodes, 2875 tetrahedra, ~100 KB), output path, and
optionally `binary` for a binary MSH 4.1. The output is deterministic for a given gmsh version (the committed
file came from gmsh 4.15.2). The server computes the boundary surface from the tetrahedra itself, so the
file's own surface triangles are not needed and not written (the only physical group is the volume, so only
the 3-D elements are saved).
"""

import sys

import gmsh


def mesh_box(name, origin_mm, size_mm, element_mm, out, binary=False):
    """Mesh the box from `origin_mm` spanning `size_mm` (x, y, z) in linear tetrahedra of about `element_mm` and
    write its volume to `out` as MSH 4.1."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.add(name)
    block = gmsh.model.occ.addBox(*origin_mm, *size_mm)
    gmsh.model.occ.synchronize()
    # Only the volume is saved: a physical group on it makes gmsh drop the surface and line elements.
    gmsh.model.addPhysicalGroup(3, [block], name="tissue")
    gmsh.option.setNumber("Mesh.MeshSizeMin", element_mm)
    gmsh.option.setNumber("Mesh.MeshSizeMax", element_mm)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.optimize("Netgen")
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 1 if binary else 0)
    gmsh.option.setNumber("Mesh.SaveAll", 0)
    gmsh.write(out)

    tags, _, _ = gmsh.model.mesh.getNodes()
    types, element_tags, _ = gmsh.model.mesh.getElements(3)
    tets = sum(len(t) for kind, t in zip(types, element_tags) if kind == 4)
    print(f"size {element_mm} mm: {len(tags)} nodes, {tets} tetrahedra -> {out}")
    gmsh.finalize()


if __name__ == "__main__":
    size = float(sys.argv[1]) if len(sys.argv) > 1 else 3.0
    path = sys.argv[2] if len(sys.argv) > 2 else "tet_block.msh"
    as_binary = len(sys.argv) > 3 and sys.argv[3] == "binary"
    mesh_box("tet_block", (-20.0, -15.0, -10.0), (40.0, 30.0, 10.0), size, path, as_binary)
