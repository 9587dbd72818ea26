#!/usr/bin/python3
"""What the Python package costs over the library: the batch and block
iterations of a store, each beside the floor of handing out arrays that
Python owns, measured in the same run.

    PYTHONPATH=build/python /usr/bin/python3 bench/bench_python.py STORE [--rounds 7]

Per round, interleaved, each in a process of its own (what the allocator
did for one phase would otherwise steer the next: a phase's rate depends on
whether its arrays' pages come back from the heap or fault in anew):
  batches   for b in store.batches(): b.points, b.connectivity  (nodes/s)
  blocks    for b in store.blocks(): b.points, b.connectivity   (block nodes/s:
            every node of each coarse element's block, shared ones again)
  copy      for each batch's shapes, its bytes copied once (numpy.copyto)
            into arrays allocated before the loop: the floor of handing a
            batch over, without the allocator (nodes/s of the batches)
  library   store.sweep(threads=1) (nodes/s of the sweep, which hashes every
            node and element from the C++ batches: not a copy, the rate the
            library reaches without Python arrays)
Prints each round and the medians; ratios batches/copy and blocks/copy.
"""
import argparse
import statistics
import subprocess
import sys
import time

import numpy as np

import dicer


def rate(nodes, seconds):
    return nodes / seconds if seconds > 0 else float("nan")


def time_iteration(batches):
    """nodes/s of a loop that takes each batch's points and connectivity."""
    t = time.perf_counter()
    n = 0
    for b in batches:
        n += b.points.shape[0]
        b.connectivity.shape
    return rate(n, time.perf_counter() - t)


def time_copy(shapes, src_points, src_conn):
    dst_points = np.empty_like(src_points)
    dst_conn = np.empty_like(src_conn)
    t = time.perf_counter()
    n = 0
    for ps, cs in shapes:
        np.copyto(dst_points[: ps[0] * 3], src_points[: ps[0] * 3])
        np.copyto(dst_conn[: cs[0] * cs[1]], src_conn[: cs[0] * cs[1]])
        n += ps[0]
    return rate(n, time.perf_counter() - t)


PHASES = ("batches", "copy", "blocks", "library")


def run_phase(store_path, cache_mb, phase):
    store = dicer.open(store_path, cache_mb=cache_mb)
    if phase == "batches":
        return time_iteration(store.batches())
    if phase == "blocks":
        return time_iteration(store.blocks())
    if phase == "library":
        return store.sweep(threads=1)["nodes_per_s"]
    shapes = [(b.points.shape, b.connectivity.shape) for b in store.batches()]
    src_points = np.arange(3 * max(s[0][0] for s in shapes), dtype=np.float64)
    src_conn = np.arange(max(s[1][0] * s[1][1] for s in shapes), dtype=np.int64)
    return time_copy(shapes, src_points, src_conn)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("store")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--cache-mb", type=int, default=64)
    ap.add_argument("--phase", choices=PHASES, help=argparse.SUPPRESS)  # one measurement, in this process
    a = ap.parse_args()
    if a.phase:
        print(repr(run_phase(a.store, a.cache_mb, a.phase)))
        return 0
    store = dicer.open(a.store, cache_mb=a.cache_mb)
    first = next(iter(store.batches()))
    print(f"{a.store}: {store.num_nodes} nodes, {store.num_elements} elements, {store.num_coarse_elements} "
          f"coarse elements (first batch {first.points.shape[0]} nodes, {first.connectivity.shape[0]} elements); "
          f"dicer {dicer.__version__}")
    del first, store
    rows = []
    for r in range(a.rounds):
        row = {}
        for phase in PHASES:
            out = subprocess.run([sys.executable, __file__, a.store, "--cache-mb", str(a.cache_mb), "--phase", phase],
                                 capture_output=True, text=True, check=True).stdout
            row[phase] = float(out.strip().splitlines()[-1])
        rows.append(row)
        print("round %d: " % (r + 1) + ", ".join("%s %.0f M nodes/s" % (k, v / 1e6) for k, v in row.items()), flush=True)
    med = {k: statistics.median(x[k] for x in rows) for k in rows[0]}
    print("median: " + ", ".join("%s %.0f M nodes/s" % (k, v / 1e6) for k, v in med.items()))
    for k in ("batches", "blocks"):
        ratios = [x[k] / x["copy"] for x in rows]
        print("%s / copy: median %.2f (rounds %.2f-%.2f)" % (k, statistics.median(ratios), min(ratios), max(ratios)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
