"""Generate worlds/meshes/wound_half.msh: one side of a wound, a 17.5 x 30 x 10 mm block of skin-like tissue
as linear tetrahedra.

The block spans x in [0, 17.5], y in [-15, 15], z in [-10, 0] mm: its top face lies on z = 0, its face x = 0
is the wound's edge. worlds/suture.toml places two of them 5 mm apart (x in [-20, -2.5] and [2.5, 20]), each
fixed at its far side: a wound of 5 mm gap without a cut mesh.

Regenerate (needs the `gmsh` Python package; CI does not, the .msh output is committed):

    python3 -m venv /tmp/gmshvenv && /tmp/gmshvenv/bin/pip install gmsh
    /tmp/gmshvenv/bin/python worlds/meshes/make_wound_half.py 3.0 worlds/meshes/wound_half.msh

Arguments: target element size in mm (default 3.0), output path. Deterministic for a given gmsh version (the
committed file came from gmsh 4.15.2). The meshing is make_tet_block.py's.
"""

import sys

from make_tet_block import mesh_box

if __name__ == "__main__":
    size = float(sys.argv[1]) if len(sys.argv) > 1 else 3.0
    path = sys.argv[2] if len(sys.argv) > 2 else "wound_half.msh"
    mesh_box("wound_half", (0.0, -15.0, -10.0), (17.5, 30.0, 10.0), size, path)
