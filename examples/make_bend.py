#!/usr/bin/python3
"""Writes examples/bend.brep: a rectangular duct (1 x 1 section) with a
90-degree bend (inner radius 1, outer 2, about the z axis) between two
straight legs of length 2; three volumes, every face 4-sided, so
`dicer mesh-coarse` meshes it transfinitely. Made with Gmsh's OpenCASCADE
kernel (Debian's python3-gmsh 4.8.4).

usage: /usr/bin/python3 examples/make_bend.py [examples/bend.brep]
"""
import math
import os
import sys

import gmsh

out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "bend.brep")
gmsh.initialize()
gmsh.option.setNumber("General.Terminal", 0)
occ = gmsh.model.occ
section = occ.addRectangle(1, 0, 0, 1, 1)                       # x 1..2, y 0..1 at z = 0
occ.rotate([(2, section)], 0, 0, 0, 1, 0, 0, math.pi / 2)       # into the xz plane: x 1..2, z 0..1
bend = occ.revolve([(2, section)], 0, 0, 0, 0, 0, 1, math.pi / 2)
occ.extrude([(2, section)], 0, -2, 0)                           # leg along -y
occ.extrude([bend[0]], -2, 0, 0)                                # leg along -x from the bend's end face
occ.synchronize()
occ.fragment(occ.getEntities(3), [])                            # one conforming model, shared faces
occ.synchronize()
gmsh.write(out)
gmsh.finalize()
print(f"wrote {out}")
