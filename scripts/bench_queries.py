#!/usr/bin/python3
"""Box-query cost against box volume (bench/README.md, "Spatial index"):
`dicer query STORE --box ... --count --stats` for cubes of 0.1%, 0.5%, 1%,
10% and 100% of the 1e9-element box (1e6 coarse hexes at interval 10), the
distinct pages of each element table read, wall time and peak RSS, medians
of --repeat runs. Writes bench/results/box_query.json; scripts/bench_plot.py
turns it into the README table.

usage: /usr/bin/python3 scripts/bench_queries.py [--build build] [--work DIR] [--repeat 3]
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--work", default="/tmp/dicer_bench_queries")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    dicer = os.path.join(a.build, "dicer")
    os.makedirs(a.work, exist_ok=True)
    msh, store = os.path.join(a.work, "box100.msh"), os.path.join(a.work, "box100_i10.dice.h5")
    if not os.path.exists(msh):
        subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "bench_box_msh.py"), "100", "100", "100", msh], check=True)
    if not os.path.exists(store):
        subprocess.run([dicer, "dice", msh, "--interval", "10", "-o", store, "--quiet"], check=True)
    commit = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    out = {"commit": commit, "date": time.strftime("%Y-%m-%d %H:%M"), "store": os.path.basename(store), "queries": []}
    for frac in (0.001, 0.005, 0.01, 0.1, 1.0):
        side = 100 * frac ** (1 / 3)
        walls, rss = [], []
        for _ in range(a.repeat):
            r = subprocess.run(["/usr/bin/time", "-f", "TIME %e %M", dicer, "query", store, "--box",
                                "0,0,0,%r,%r,%r" % (side, side, side), "--count", "--stats"],
                               capture_output=True, text=True, check=True)
            t = re.search(r"TIME ([\d.]+) (\d+)", r.stderr)
            walls.append(float(t.group(1))), rss.append(int(t.group(2)) / 1024)
            tables = {m.group(1): (int(m.group(2)), int(m.group(3)))
                      for m in re.finditer(r"(\w+) (\d+) of (\d+) pages", r.stderr)}
            count = int(r.stdout.strip())
        out["queries"].append({"fraction": frac, "side": side, "count": count, "wall_s": statistics.median(walls),
                               "all_wall_s": walls, "peak_rss_mib": statistics.median(rss),
                               "pages": {k: {"read": v[0], "of": v[1]} for k, v in tables.items()}})
        print(out["queries"][-1])
    with open(os.path.join(ROOT, "bench", "results", "box_query.json"), "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
