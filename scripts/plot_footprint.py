#!/usr/bin/python3
"""The footprint picture of the README: bytes on disk and peak memory against
fine element count, for dicer, Gmsh 4.8 (transfinite) and an explicit HDF5
mesh, from the measurements the side-by-side harness wrote
(bench/results/side_by_side.json, scripts/bench_side_by_side.sh) and the
1e10 run (bench/results/run_1e10.json, scripts/bench_1e10.sh). Only measured
points are drawn; nothing is extrapolated.

usage: /usr/bin/python3 scripts/plot_footprint.py [--out docs/footprint.png]
"""
import argparse
import json
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "bench", "results")
MiB = 1 << 20


def load(name):
    path = os.path.join(RESULTS, name)
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return json.load(f)


def get(d, *keys):
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return None
        d = d[k]
    return d


def series(rows, *keys, scale=1.0):
    pts = [(r["fine_elements"], get(r, *keys)) for r in rows]
    pts = [(x, y * scale) for x, y in pts if y]
    return [p[0] for p in pts], [p[1] for p in pts]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "footprint.png"))
    args = ap.parse_args()
    sbs = load("side_by_side.json")
    if sbs is None:
        raise SystemExit("bench/results/side_by_side.json is missing: run scripts/bench_side_by_side.sh")
    run = load("run_1e10.json")
    box = sbs["intervals"]  # one coarse box, interval 16, 25, 40
    hexes = box[0]["coarse_hexes"]

    fig, (disk, mem) = plt.subplots(1, 2, figsize=(13, 6.4))
    style = {"dicer": ("tab:blue", "o"), "gmsh": ("tab:red", "s"), "explicit": ("dimgray", "^")}

    def line(ax, rows, keys, label, kind, dash="-", scale=1.0):
        x, y = series(rows, *keys, scale=scale)
        color, marker = style[kind]
        ax.plot(x, y, dash, color=color, marker=marker, label=label)

    line(disk, box, ("store_bytes",), "dicer store (.dice.h5)", "dicer")
    line(disk, box, ("explicit_raw", "file_bytes"), "explicit HDF5 mesh, raw", "explicit", ":")
    line(disk, box, ("explicit_lz4", "file_bytes"), "explicit HDF5 mesh, LZ4", "explicit")
    line(disk, box, ("gmsh_generate_write", "file_bytes"), "Gmsh binary MSH", "gmsh")
    line(mem, box, ("dice", "peak_rss_mib"), "dicer dice", "dicer")
    line(mem, box, ("sweep", "peak_rss_mib"), "dicer sweep (every node and element, 64 MiB cache)", "dicer", "--")
    line(mem, box, ("explicit_lz4", "peak_rss_mib"), "explicit HDF5 mesh, LZ4 write (streamed)", "explicit")
    line(mem, box, ("gmsh_generate", "peak_rss_mib"), "Gmsh transfinite generate", "gmsh")
    if run:
        n = run["fine_elements"]
        disk.plot([n], [run["store_bytes"]], "*", ms=16, color="tab:blue",
                  label=f"dicer store, {n:.2g} elements ({os.path.basename(run['mesh'])})")
        mem.plot([n], [run["sweep"]["peak_rss_mib"]], "*", ms=16, color="tab:blue",
                 label=f"dicer sweep, {n:.2g} elements")

    for ax, title, unit in ((disk, "bytes on disk", "bytes"), (mem, "peak memory (whole process RSS)", "MiB")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("fine hexahedra")
        ax.set_ylabel(unit)
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, frameon=False)
    m = sbs["machine"]
    fig.suptitle(f"Footprint: a {hexes:,}-hex box at intervals {', '.join(str(r['interval']) for r in box)} "
                 f"(medians of {sbs.get('reps', 3)} runs, {m['cpu']}, {m['cores']} cores, {m['date'][:10]}); "
                 "star: the 1e10 run", fontsize=10)
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
