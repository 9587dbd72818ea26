"""Bounded memory (DESIGN.md invariant 7) through Python: iterating every batch
of a 1e8-element store whose file is several times the cache budget keeps the
process's resident set (VmRSS) within the budget plus a batch plus a small
constant. Measured in a fresh interpreter, so memory freed by earlier work
in this one cannot hide growth."""
import json
import os
import subprocess
import sys
import textwrap

import dicer
from conftest import write_box_msh

MiB = 1 << 20

CHILD = textwrap.dedent("""
    import gc, json, sys
    import numpy as np
    import dicer

    def rss():
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024

    path, cache_mb, mode = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    s = dicer.open(path, cache_mb=cache_mb)
    it = s.blocks()
    next(it)  # warm up: numpy, the first batch, the allocator's pools
    gc.collect()
    before = peak = rss()
    elements = nodes = 0
    if mode == "blocks":
        for b in it:
            elements += len(b.connectivity)
            nodes += int(b.owned.sum())
            peak = max(peak, rss())
    else:  # slices of 1e6 nodes and elements, in id order, to the end
        step = 1_000_000
        for a in range(0, s.num_nodes, step):
            nodes += len(s.nodes(a, min(a + step, s.num_nodes)))
            peak = max(peak, rss())
        for a in range(0, s.num_elements, step):
            elements += len(s.elements(a, min(a + step, s.num_elements)))
            peak = max(peak, rss())
    print(json.dumps({"growth": peak - before, "elements": elements, "nodes": nodes,
                      "num_elements": s.num_elements, "num_nodes": s.num_nodes, "stats": s.cache_stats()}))
""")


def run_child(path, cache_mb, mode):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONHOME",)}
    out = subprocess.run([sys.executable, "-c", CHILD, str(path), str(cache_mb), mode], env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def big_store(tmp_path):
    # 46 x 46 x 48 = 101,568 coarse hexes at interval 10: 1.02e8 fine hexes,
    # a ~27 MB store (the coarse tables), far more than the cache below.
    coarse = write_box_msh(tmp_path / "box.msh", 46, 46, 48)
    store = dicer.dice(coarse, tmp_path / "box.dice.h5", interval=10)
    assert store.num_elements == 101_568 * 1000
    store.close()
    return tmp_path / "box.dice.h5"


def test_iterating_1e8_elements_stays_in_the_cache_budget(tmp_path):
    path = big_store(tmp_path)
    cache_mb = 4
    assert os.path.getsize(path) > 4 * cache_mb * MiB
    r = run_child(path, cache_mb, "blocks")
    assert r["elements"] + 1000 == r["num_elements"]  # every batch after the warm-up one
    stats = r["stats"]
    assert stats["evictions"] > 0, "the store must not fit the cache, or the budget is not tested"
    assert stats["peak_resident_bytes"] <= cache_mb * MiB
    batch = 11 ** 3 * 33 + 10 ** 3 * 64  # points (id, xyz, owned flag) and connectivity of one batch
    limit = cache_mb * MiB + 2 * batch + 16 * MiB
    assert r["growth"] < limit, f"RSS grew {r['growth'] / MiB:.1f} MiB (limit {limit / MiB:.1f} MiB)"


def test_slicing_nodes_and_elements_stays_bounded(tmp_path):
    """nodes(a, b) / elements(a, b) over the whole 1e8 store, a million at a time."""
    path = big_store(tmp_path)
    cache_mb = 4
    r = run_child(path, cache_mb, "slices")
    assert r["nodes"] == r["num_nodes"] and r["elements"] == r["num_elements"]
    slice_bytes = 1_000_000 * 64  # the larger result: 1e6 elements x 8 ids
    limit = cache_mb * MiB + 2 * slice_bytes + 16 * MiB
    assert r["growth"] < limit, f"RSS grew {r['growth'] / MiB:.1f} MiB (limit {limit / MiB:.1f} MiB)"
