#!/usr/bin/python3
"""Independent reader for dicer's Exodus II export (write_exodus).

Usage: /usr/bin/python3 exodus_check.py FILE.e

Reads FILE with meshio (points, cells, node sets), which itself reads Exodus
through netCDF4-python, and reads what meshio does not expose (block ids and
names, id maps, side sets) with netCDF4-python directly, never with the
Exodus library or dicer's code. Prints a JSON object with one key per line,
so the C++ test can pick a line by key:

  format        netCDF data model ("NETCDF4", ...)
  num_points    meshio point count
  cells         [[meshio cell type, count], ...] per block, in file order
  point_first, point_mid, point_last
                meshio points 0, n // 2, n - 1 as [x, y, z] (repr floats:
                strtod gives back the same bits)
  point_digest  sum over i of (i + 1) * (64-bit pattern of the i-th value of
                the points array flattened x0 y0 z0 x1 ...), modulo 2^64
  conn_digest   the same over meshio's 0-based connectivity, blocks in file
                order, rows flattened
  point_sets    {name: size} from meshio
  id_types      netCDF types of node_num_map, elem_num_map, eb_prop1 (those present)
  block_ids, block_names, block_types
                eb_prop1, eb_names, connect*.elem_type
  node_map_digest, elem_map_digest
                digests of node_num_map / elem_num_map (absent map: 1..n)
  side_sets     [[id, name, size, element digest, side digest], ...]
  node_sets     [[id, name, size, node digest], ...]

Exit status: 0 on success, 77 when meshio/netCDF4/numpy cannot be imported
(the test skips, or fails under CI), 1 when the file cannot be read.
"""
import json
import sys

try:
    import meshio
    import netCDF4
    import numpy as np
except ImportError as exc:  # pragma: no cover - environment without the readers
    print(f"exodus_check: cannot import the independent readers: {exc}", file=sys.stderr)
    sys.exit(77)


def digest(values, dtype):
    flat = np.ascontiguousarray(np.asarray(values, dtype=dtype)).reshape(-1)
    if flat.size == 0:
        return 0
    bits = flat.view(np.uint64)
    weights = np.arange(1, flat.size + 1, dtype=np.uint64)
    with np.errstate(over="ignore"):
        return int(np.sum(bits * weights, dtype=np.uint64))


def names(nc, var, count):
    if var not in nc.variables:
        return [""] * count
    v = nc.variables[var]
    v.set_auto_mask(False)
    return [b"".join(row).decode("UTF-8").rstrip("\x00").strip() for row in v[:]]


def ints(nc, var):
    v = nc.variables[var]
    v.set_auto_mask(False)
    return np.asarray(v[:], dtype=np.int64)


def dim(nc, name):
    return len(nc.dimensions[name]) if name in nc.dimensions else 0


def main(argv):
    if len(argv) != 2:
        print("usage: exodus_check.py FILE.e", file=sys.stderr)
        return 2
    path = argv[1]
    mesh = meshio.read(path, file_format="exodus")
    points = np.asarray(mesh.points, dtype=np.float64)
    n = points.shape[0]
    out = {
        "num_points": int(n),
        "cells": [[block.type, int(len(block.data))] for block in mesh.cells],
        "point_first": [float(v) for v in points[0]] if n else [],
        "point_mid": [float(v) for v in points[n // 2]] if n else [],
        "point_last": [float(v) for v in points[n - 1]] if n else [],
        "point_digest": digest(points, np.float64),
        "conn_digest": digest(np.concatenate([np.asarray(b.data, dtype=np.int64).reshape(-1) for b in mesh.cells])
                              if mesh.cells else [], np.int64),
        "point_sets": {name: int(len(v)) for name, v in mesh.point_sets.items()},
    }

    with netCDF4.Dataset(path) as nc:
        out["format"] = nc.data_model
        out["id_types"] = [str(nc.variables[v].dtype) for v in ("node_num_map", "elem_num_map", "eb_prop1")
                           if v in nc.variables]
        nblk = dim(nc, "num_el_blk")
        out["block_ids"] = [int(v) for v in ints(nc, "eb_prop1")] if nblk else []
        out["block_names"] = names(nc, "eb_names", nblk)
        out["block_types"] = [nc.variables[f"connect{k + 1}"].elem_type for k in range(nblk)]
        num_nodes, num_elem = dim(nc, "num_nodes"), dim(nc, "num_elem")
        out["node_map_digest"] = digest(ints(nc, "node_num_map") if "node_num_map" in nc.variables
                                        else np.arange(1, num_nodes + 1), np.int64)
        out["elem_map_digest"] = digest(ints(nc, "elem_num_map") if "elem_num_map" in nc.variables
                                        else np.arange(1, num_elem + 1), np.int64)
        nss = dim(nc, "num_side_sets")
        ss_ids = [int(v) for v in ints(nc, "ss_prop1")] if nss else []
        ss_names = names(nc, "ss_names", nss)
        out["side_sets"] = []
        for k in range(nss):
            size = dim(nc, f"num_side_ss{k + 1}")
            elems = ints(nc, f"elem_ss{k + 1}") if size else []
            sides = ints(nc, f"side_ss{k + 1}") if size else []
            out["side_sets"].append([ss_ids[k], ss_names[k], size, digest(elems, np.int64), digest(sides, np.int64)])
        nns = dim(nc, "num_node_sets")
        ns_ids = [int(v) for v in ints(nc, "ns_prop1")] if nns else []
        ns_names = names(nc, "ns_names", nns)
        out["node_sets"] = []
        for k in range(nns):
            size = dim(nc, f"num_nod_ns{k + 1}")
            nodes = ints(nc, f"node_ns{k + 1}") if size else []
            out["node_sets"].append([ns_ids[k], ns_names[k], size, digest(nodes, np.int64)])

    print("{")
    items = list(out.items())
    for i, (key, value) in enumerate(items):
        sep = "," if i + 1 < len(items) else ""
        print(json.dumps(key) + ": " + json.dumps(value) + sep)
    print("}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except Exception as exc:  # a read failure is the finding, not a crash
        print(f"exodus_check: {type(exc).__name__}: {exc}", file=sys.stderr)
        sys.exit(1)
