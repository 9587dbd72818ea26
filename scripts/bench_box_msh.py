#!/usr/bin/env python3
"""Writes an NX x NY x NZ box of unit hexes as Gmsh MSH 4.1 (ASCII): the
planar-bounded coarse mesh of the side-by-side and 1e10 benchmarks.

One volume entity in one physical group ("box"), no boundary elements, so
dicer makes one block and Gmsh's transfinite baseline sees exactly the
same hexes. Nodes are numbered x fastest; each hex lists its bottom face
(k) then its top face (k+1), both counter-clockwise seen from +z: Gmsh's
HEX8 order, right-handed (dicer needs no reorientation).
Standard library only, so it runs under any python3.

usage: bench_box_msh.py NX NY NZ OUT.msh [--jitter F]
  --jitter F  moves every interior vertex by up to F (fraction of the
              spacing, deterministic), so the coarse hexes are not all
              congruent (the explicit mesh then cannot compress a lattice)
"""
import random
import sys


def main():
    args = sys.argv[1:]
    jitter = 0.0
    if "--jitter" in args:
        k = args.index("--jitter")
        jitter = float(args[k + 1])
        del args[k:k + 2]
    if len(args) != 4:
        sys.exit(__doc__)
    nx, ny, nz = (int(a) for a in args[:3])
    out = args[3]
    rng = random.Random(12345)
    nn = (nx + 1) * (ny + 1) * (nz + 1)
    ne = nx * ny * nz

    def nid(i, j, k):
        return 1 + i + (nx + 1) * (j + (ny + 1) * k)

    with open(out, "w") as f:
        f.write("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")
        f.write('$PhysicalNames\n1\n3 1 "box"\n$EndPhysicalNames\n')
        f.write("$Entities\n0 0 0 1\n1 0 0 0 %d %d %d 1 1 0\n$EndEntities\n" % (nx, ny, nz))
        f.write("$Nodes\n1 %d 1 %d\n3 1 0 %d\n" % (nn, nn, nn))
        f.write("".join("%d\n" % t for t in range(1, nn + 1)))
        lines = []
        for k in range(nz + 1):
            for j in range(ny + 1):
                for i in range(nx + 1):
                    p = [float(i), float(j), float(k)]
                    if jitter > 0:
                        for d, (c, n) in enumerate(((i, nx), (j, ny), (k, nz))):
                            if 0 < c < n:
                                p[d] += jitter * (2 * rng.random() - 1)
                    lines.append("%.17g %.17g %.17g\n" % tuple(p))
        f.write("".join(lines))
        f.write("$EndNodes\n")
        f.write("$Elements\n1 %d 1 %d\n3 1 5 %d\n" % (ne, ne, ne))
        lines = []
        e = 0
        for k in range(nz):
            for j in range(ny):
                for i in range(nx):
                    e += 1
                    lines.append("%d %d %d %d %d %d %d %d %d\n" % (
                        e, nid(i, j, k), nid(i + 1, j, k), nid(i + 1, j + 1, k), nid(i, j + 1, k),
                        nid(i, j, k + 1), nid(i + 1, j, k + 1), nid(i + 1, j + 1, k + 1), nid(i, j + 1, k + 1)))
        f.write("".join(lines))
        f.write("$EndElements\n")


if __name__ == "__main__":
    main()
