#!/usr/bin/env python3
"""The 10^10 run (issue 6 item 5), driven by scripts/bench_1e10.sh.

Dices a coarse mesh to >= 1e10 fine elements, sweeps every fine node and
element (`dicer sweep --threads 2 --cache-mb 256 --json --stats`) and
answers 1e6 random node and 1e6 random element queries from a 256 MiB
cache (bench_side_by_side BM_RandomQueries), each step its own process
(wall time and peak RSS from getrusage of the child). Writes
bench/results/run_1e10.json. Standard library only.

Default mesh: tests/data/vtkdata_disk_out_ref.ex2 (7472 CUBIT hexes) at
interval 112: 7472 * 112^3 = 1.05e10 fine elements.
"""
import argparse
import json
import os
import re
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_side_by_side import ROOT, log, machine, run  # noqa: E402


def parse_stats(text):
    """The `--stats` line: 'cache: N pages read, X MiB read from file, ...'."""
    s = {}
    for key, pat in (("pages_read", r"([\d]+) pages read"), ("mib_read", r"([\d.]+) MiB read from file"),
                     ("mib_decompressed", r"([\d.]+) MiB decompressed"), ("hits", r"([\d]+) hits"),
                     ("misses", r"([\d]+) misses"), ("evictions", r"([\d]+) evictions"),
                     ("peak_resident_mib", r"peak resident ([\d.]+) MiB")):
        m = re.search(pat, text)
        if m:
            s[key] = float(m.group(1))
    return s


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(ROOT, "build-bench"))
    ap.add_argument("--mesh", default=os.path.join(ROOT, "tests", "data", "vtkdata_disk_out_ref.ex2"))
    ap.add_argument("--interval", type=int, default=112)
    ap.add_argument("--cache-mb", type=int, default=256)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--queries", type=int, default=1000000)
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "dicer-1e10"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "run_1e10.json"))
    ap.add_argument("--skip-sweep", action="store_true", help="dice and queries only (a dry run of the plumbing)")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    dicer = os.path.join(a.build, "dicer")
    store = os.path.join(a.work, "run.dice.h5")
    res = {"machine": machine(), "mesh": os.path.relpath(a.mesh, ROOT), "interval": a.interval, "cache_mb": a.cache_mb,
           "command": "bash scripts/bench_1e10.sh " + " ".join(sys.argv[1:])}
    log("dice")
    r = run([dicer, "dice", a.mesh, "--interval", str(a.interval), "-o", store, "--quiet"])
    res["dice"] = {"wall_s": r["wall_s"], "peak_rss_mib": r["peak_rss_mib"]}
    info = json.loads(run([dicer, "info", store, "--json"])["stdout"])
    res.update(info=info, store_bytes=os.path.getsize(store), fine_elements=info["fine_elements"],
               fine_nodes=info["fine_nodes"], coarse_hexes=info["coarse_elements"])
    log("store %d bytes, %.3g fine elements, %.3g nodes" % (res["store_bytes"], res["fine_elements"], res["fine_nodes"]))
    if not a.skip_sweep:
        log("sweep (minutes)")
        r = run([dicer, "sweep", store, "--threads", str(a.threads), "--cache-mb", str(a.cache_mb), "--json", "--stats"])
        res["sweep"] = dict(json.loads(r["stdout"]), wall_s=r["wall_s"], peak_rss_mib=r["peak_rss_mib"],
                            stats=parse_stats(r["stderr"]), stats_line=r["stderr"].strip())
        log(json.dumps(res["sweep"]))
    q = {}
    for k, arg in (("nodes", 0), ("elements", 1)):
        log("random %s queries" % k)
        r = run([os.path.join(a.build, "bench", "bench_side_by_side"),
                 "--benchmark_filter=^BM_RandomQueries/%d/" % arg, "--benchmark_format=json"],
                env={"DICER_SBS_STORE": store, "DICER_SBS_QUERIES": str(a.queries), "DICER_SBS_CACHE_MB": str(a.cache_mb)})
        b = json.loads(r["stdout"])["benchmarks"][0]
        if b.get("error_occurred"):
            raise RuntimeError(b.get("error_message"))
        q[k] = {key: b[key] for key in ("queries", "seconds", "ns_per_query", "hit_rate", "pages_read", "cache_peak_MiB",
                                         "peak_rss_MiB")}
        q[k]["process_wall_s"], q[k]["process_peak_rss_mib"] = r["wall_s"], r["peak_rss_mib"]
        log(json.dumps(q[k]))
    q["peak_rss_mib"] = max(q["nodes"]["process_peak_rss_mib"], q["elements"]["process_peak_rss_mib"])
    res["queries"] = q
    res["machine"]["load_after"] = os.getloadavg()
    os.remove(store)
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as f:
        json.dump(res, f, indent=1)
    log("wrote", a.out)


if __name__ == "__main__":
    main()
