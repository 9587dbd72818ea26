#!/usr/bin/python3
"""Independent reader for dicer's Gmsh MSH 4.1 export (ASCII or binary).

Usage: /usr/bin/python3 msh_check.py FILE.msh

Reads FILE with meshio (Debian's python3-meshio, not dicer's code) and prints
a JSON object, one key per line so the C++ test can pick a line by key:
  "points": number of points
  "cells_<type>": number of cells of each meshio type (hexahedron, quad, line)
  "physical_<dim>_<tag>": name of each physical group (meshio field_data)
  "tagged_<type>_<tag>": number of cells of that type with gmsh:physical tag
  "first_<type>": coordinates of the corners of the first cell of each type,
                  as a flat list x0, y0, z0, x1, ... (repr: exact doubles)
  "bbox": min x, y, z then max x, y, z of all points

Exit status: 0 on success, 77 when meshio cannot be imported (the test skips,
or fails under CI), 1 when the file cannot be read.
"""
import json
import sys

try:
    import meshio
    import numpy as np
except ImportError as exc:  # pragma: no cover - environment without the reader
    print(f"msh_check: cannot import meshio: {exc}", file=sys.stderr)
    sys.exit(77)


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    try:
        mesh = meshio.read(sys.argv[1], file_format="gmsh")
    except Exception as exc:  # noqa: BLE001 - any reader failure is a test failure
        print(f"msh_check: meshio cannot read {sys.argv[1]}: {exc}", file=sys.stderr)
        return 1

    out = {"points": int(len(mesh.points))}
    counts = {}
    tagged = {}
    first = {}
    physical = mesh.cell_data.get("gmsh:physical")
    for i, block in enumerate(mesh.cells):
        counts[block.type] = counts.get(block.type, 0) + int(len(block.data))
        if block.type not in first and len(block.data):
            first[block.type] = [float(v) for v in mesh.points[block.data[0]].reshape(-1)]
        if physical is not None:
            for tag, n in zip(*np.unique(physical[i], return_counts=True)):
                key = f"tagged_{block.type}_{int(tag)}"
                tagged[key] = tagged.get(key, 0) + int(n)
    for t in sorted(counts):
        out[f"cells_{t}"] = counts[t]
    for name, (tag, dim) in sorted(mesh.field_data.items(), key=lambda kv: (int(kv[1][1]), int(kv[1][0]))):
        out[f"physical_{int(dim)}_{int(tag)}"] = name
    out.update(sorted(tagged.items()))
    for t in sorted(first):
        out[f"first_{t}"] = first[t]
    if len(mesh.points):
        out["bbox"] = [float(v) for v in mesh.points.min(axis=0)] + [float(v) for v in mesh.points.max(axis=0)]

    print("{")
    items = list(out.items())
    for k, (key, value) in enumerate(items):
        print(f"{json.dumps(key)}: {json.dumps(value)}" + ("," if k + 1 < len(items) else ""))
    print("}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
