#!/usr/bin/python3
"""Independent reader for a Nemesis set (dicer export --nemesis / mpirun).

Usage: /usr/bin/python3 nemesis_check.py OUT P NODES ELEMENTS

Reads OUT.P.r for r in 0..P-1 with netCDF4-python only (never the Exodus
library or dicer) and checks what a parallel solver relies on:
  - every file names P processors and the global counts NODES, ELEMENTS;
  - every global element (elem_num_map) is in exactly one file;
  - every global node is in some file, with the same coordinates in every
    file that has it;
  - node communication maps are symmetric: the nodes file r lists for
    processor q are, in the same order, those file q lists for r, and they
    are exactly the nodes the two files have in common;
  - internal + border node maps cover each file's nodes once.
Prints a JSON object on success; exit 1 with a message on the first
violation; exit 77 when netCDF4/numpy cannot be imported.
"""
import json
import sys

try:
    import netCDF4
    import numpy as np
except ImportError as e:  # pragma: no cover
    print("missing python module:", e, file=sys.stderr)
    sys.exit(77)


def fail(msg):
    print("nemesis_check: " + msg, file=sys.stderr)
    sys.exit(1)


def main():
    out, P, nodes, elements = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
    width = len(str(P))
    files = []
    for r in range(P):
        name = "%s.%d.%0*d" % (out, P, width, r)
        d = netCDF4.Dataset(name)
        d.set_auto_mask(False)
        files.append((name, d))
    elem_seen = np.zeros(elements, dtype=np.int64)
    node_xyz = {}
    shared_total = 0
    per_file = []
    for r, (name, d) in enumerate(files):
        v = d.variables
        gmap = v["node_num_map"][:].astype(np.int64) - 1
        emap = v["elem_num_map"][:].astype(np.int64) - 1
        xyz = np.stack([v["coordx"][:], v["coordy"][:], v["coordz"][:]], axis=1)
        # The global counts are dimensions of the file (Exodus 6.02's layout).
        for key, want in (("num_nodes_global", nodes), ("num_elems_global", elements)):
            got = d.dimensions[key].size
            if got != want:
                fail("%s: %s is %d, the store has %d" % (name, key, got, want))
        if d.dimensions["num_processors"].size != P:
            fail("%s: %d processors, expected %d" % (name, d.dimensions["num_processors"].size, P))
        np.add.at(elem_seen, emap, 1)
        for g, p in zip(gmap, xyz):
            t = tuple(p)
            old = node_xyz.setdefault(int(g), t)
            if old != t:
                fail("%s: node %d has coordinates %s here and %s elsewhere" % (name, g, t, old))
        mi = v["node_mapi"][:] if "node_mapi" in v else np.array([], dtype=np.int64)
        mb = v["node_mapb"][:] if "node_mapb" in v else np.array([], dtype=np.int64)
        allmap = np.sort(np.concatenate([mi, mb]))
        if not np.array_equal(allmap, np.arange(1, len(gmap) + 1)):
            fail("%s: internal and border node maps do not cover the nodes once" % name)
        cmaps = {}
        if "n_comm_ids" in v:
            ids = v["n_comm_ids"][:]
            idx = v["n_comm_data_idx"][:]
            nids = v["n_comm_nids"][:]
            procs = v["n_comm_proc"][:]
            start = 0
            for k, q in enumerate(ids):
                seg = slice(start, int(idx[k]))
                if not np.all(procs[seg] == q):
                    fail("%s: map to %d names other processors" % (name, q))
                cmaps[int(q)] = gmap[nids[seg] - 1]
                start = int(idx[k])
        per_file.append((name, set(gmap.tolist()), cmaps))
    if not np.all(elem_seen == 1):
        bad = int(np.argmax(elem_seen != 1))
        fail("global element %d is in %d files" % (bad, elem_seen[bad]))
    if len(node_xyz) != nodes:
        fail("%d distinct global nodes in the files, the store has %d" % (len(node_xyz), nodes))
    for r, (name, gset, cmaps) in enumerate(per_file):
        for q in range(P):
            if q == r:
                continue
            common = sorted(gset & per_file[q][1])
            mine = cmaps.get(q)
            if not common:
                if mine is not None and len(mine):
                    fail("%s lists nodes for %d but they share none" % (name, q))
                continue
            if mine is None:
                fail("%s has no map for %d although they share %d nodes" % (name, q, len(common)))
            if list(mine) != common:
                fail("%s: map for %d is not the sorted common nodes" % (name, q))
            theirs = per_file[q][2].get(r)
            if theirs is None or list(theirs) != list(mine):
                fail("maps of %s and %s for each other differ" % (name, per_file[q][0]))
            shared_total += len(mine)
    print(json.dumps({"files": P, "elements": int(elem_seen.sum()), "nodes": len(node_xyz),
                      "shared_entries": shared_total}))


if __name__ == "__main__":
    main()
