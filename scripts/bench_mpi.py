#!/usr/bin/python3
"""Distributed rates on this machine (bench/README.md, "Many ranks"):
`mpirun -n P dicer sweep` and `mpirun -n P dicer export` (Nemesis Exodus
and one collective VTKHDF) at P = 1 and 2 ranks of one thread each, the
medians of --repeat runs, and the parallel efficiency
rate(P) / (P x rate(1)); then bench/project_ranks on the 1e12-element box
(1e6 coarse hexes at interval 100) for 1e3-1e4 ranks. Writes
bench/results/mpi.json and bench/results/project_ranks.json.

usage: /usr/bin/python3 scripts/bench_mpi.py [--build build] [--work DIR]
       [--repeat 3] [--skip-projection]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
for k in ("PYTHONPATH", "PYTHONHOME"):
    ENV.pop(k, None)


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, capture_output=True, text=True, env=ENV, **kw)


def mpirun(P, args):
    return ["mpirun", "-q", "--oversubscribe", "--bind-to", "none", "-n", str(P)] + args


def git_commit():
    try:
        return run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"]).stdout.strip()
    except Exception:
        return "unknown"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--work", default="/tmp/dicer_bench_mpi")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-projection", action="store_true")
    a = ap.parse_args()
    dicer = os.path.join(a.build, "dicer")
    os.makedirs(a.work, exist_ok=True)
    box = os.path.join(a.work, "box40.msh")
    if not os.path.exists(box):
        run([sys.executable, os.path.join(ROOT, "scripts", "bench_box_msh.py"), "40", "40", "40", box])
    sweep_store = os.path.join(a.work, "box40_i12.dice.h5")   # 64,000 x 12^3 = 1.1e8 elements
    export_store = os.path.join(a.work, "box40_i4.dice.h5")   # 64,000 x 4^3 = 4.1e6 elements
    for store, n in ((sweep_store, 12), (export_store, 4)):
        if not os.path.exists(store):
            run([dicer, "dice", box, "--interval", str(n), "-o", store, "--quiet"])

    out = {"commit": git_commit(), "date": time.strftime("%Y-%m-%d %H:%M"), "machine": os.cpu_count(),
           "sweep_store": os.path.basename(sweep_store), "export_store": os.path.basename(export_store), "runs": []}
    for P in (1, 2):
        # Sweep: the slowest rank's seconds (what the job takes).
        secs, imb, pages = [], [], []
        for _ in range(a.repeat):
            j = json.loads(run(mpirun(P, [dicer, "sweep", sweep_store, "--threads", "1", "--json"])).stdout)
            secs.append(j["seconds"]), imb.append(j.get("imbalance", 1.0)), pages.append(sum(j.get("rank_pages_read", [0])))
            elements = j["elements"]
            checksum = j["checksum"]
        out["runs"].append({"P": P, "what": "sweep", "elements": elements, "checksum": checksum,
                            "seconds": statistics.median(secs), "all_seconds": secs,
                            "imbalance": statistics.median(imb), "pages_read": statistics.median(pages)})
        for fmt, name in (("exodus", "x.e"), ("vtkhdf", "x.vtkhdf")):
            secs = []
            for _ in range(a.repeat):
                target = os.path.join(a.work, name)
                t0 = time.monotonic()
                run(mpirun(P, [dicer, "export", export_store, "--format", fmt, "-o", target, "--quiet"]))
                secs.append(time.monotonic() - t0)
                for f in os.listdir(a.work):
                    if f.startswith(name):
                        os.remove(os.path.join(a.work, f))
            out["runs"].append({"P": P, "what": "export " + fmt, "elements": 64000 * 64,
                                "seconds": statistics.median(secs), "all_seconds": secs})
    base = {r["what"]: r for r in out["runs"] if r["P"] == 1}
    for r in out["runs"]:
        r["elements_per_s"] = r["elements"] / r["seconds"]
        r["efficiency"] = base[r["what"]]["seconds"] / (r["P"] * r["seconds"])
    with open(os.path.join(ROOT, "bench", "results", "mpi.json"), "w") as f:
        json.dump(out, f, indent=1)
    print(json.dumps(out["runs"], indent=1))

    if a.skip_projection:
        return
    big = os.path.join(a.work, "box100.msh")
    store = os.path.join(a.work, "box100_i100.dice.h5")   # 1e6 x 100^3 = 1e12 elements
    if not os.path.exists(store):
        if not os.path.exists(big):
            run([sys.executable, os.path.join(ROOT, "scripts", "bench_box_msh.py"), "100", "100", "100", big])
        t0 = time.monotonic()
        run([dicer, "dice", big, "--interval", "100", "-o", store, "--quiet"])
        dice_s = time.monotonic() - t0
    else:
        dice_s = None
    proj = json.loads(run([os.path.join(a.build, "bench", "project_ranks"), store, "1000", "2000", "5000", "10000",
                           "--samples", "3", "--json"]).stdout)
    proj.update({"commit": out["commit"], "date": out["date"], "store_bytes": os.path.getsize(store),
                 "dice_seconds": dice_s})
    with open(os.path.join(ROOT, "bench", "results", "project_ranks.json"), "w") as f:
        json.dump(proj, f, indent=1)
    print(json.dumps(proj, indent=1))


if __name__ == "__main__":
    main()
