#!/usr/bin/env python3
"""Streaming export against Gmsh, on the side-by-side meshes (issue 13 item
5; bench/README.md "Streaming export"). Driven like the side-by-side
harness, whose helpers it uses: every run its own process, wall time and
peak RSS (ru_maxrss of the child), --reps runs interleaved, medians, each
tool's 1-hex floor subtracted ("net").

Meshes: the side-by-side boxes, 16x25x40 jittered hexes at interval 10
and 10x10x20 at interval 20 (1.6e7 fine elements each).
Per mesh, in every repetition, in this order:
  dicer export --format msh             (this build: binary MSH 4.1, whole mesh)
  BEFORE export --format msh            (--before: another dicer binary, e.g. the commit before streaming)
  bench_side_by_side BM_Gmsh/1          (Gmsh 4.8 transfinite generate + binary MSH 4.1 write)
  dicer export --format msh-ascii | exodus | vtkhdf | vtkhdf --deflate 1 | vtkhdf --deflate 6
                                        (this build; --formats to choose)
Output: --out (default bench/results/export_stream.json) and a Markdown
table on stdout. Standard library only.

usage: bench_export_stream.py [--build build] [--before /path/to/old/dicer] [--reps 3]
                              [--work DIR] [--formats msh-ascii,exodus,vtkhdf,vtkhdf1,vtkhdf6]
                              [--meshes '16,25,40:10;10,10,20:20'] [--no-gmsh] [--out FILE]
"""
import argparse
import datetime
import json
import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_side_by_side as sbs  # noqa: E402  (run, med, log, machine)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FORMATS = {  # name -> export arguments
    "msh": ["--format", "msh"],
    "msh-ascii": ["--format", "msh-ascii"],
    "exodus": ["--format", "exodus"],
    "vtkhdf": ["--format", "vtkhdf"],
    "vtkhdf1": ["--format", "vtkhdf", "--deflate", "1"],
    "vtkhdf6": ["--format", "vtkhdf", "--deflate", "6"],
}


def export(dicer, store, args, out):
    r = sbs.run([dicer, "export", store, "-o", out, "--quiet", *args])
    size = os.path.getsize(out)
    os.remove(out)
    return {"wall_s": r["wall_s"], "peak_rss_mib": r["peak_rss_mib"], "file_bytes": size}


def gmsh(bench, store, work):
    r = sbs.run([bench, "--benchmark_filter=^BM_Gmsh/1/iterations:1/manual_time$", "--benchmark_format=json"],
                env={"DICER_SBS_STORE": store, "DICER_SBS_OUT": work})
    b = [x for x in json.loads(r["stdout"])["benchmarks"] if x.get("run_type", "iteration") == "iteration"][0]
    if b.get("error_occurred"):
        raise RuntimeError(b.get("error_message"))
    return {"wall_s": r["wall_s"], "peak_rss_mib": r["peak_rss_mib"], "hexes": b.get("gmsh_hexes"),
            "file_bytes": b.get("file_bytes")}


def summary(runs):
    keys = [k for k, v in runs[0].items() if isinstance(v, (int, float)) and not isinstance(v, bool)]
    out = {k: sbs.med([r[k] for r in runs if r.get(k) is not None]) for k in keys}
    out["runs"] = runs
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--before", default="", help="another dicer binary measured the same way (the 'before')")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "dicer-export-stream"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "export_stream.json"))
    ap.add_argument("--formats", default="msh-ascii,exodus,vtkhdf,vtkhdf1,vtkhdf6")
    ap.add_argument("--no-gmsh", action="store_true")
    ap.add_argument("--meshes", default="16,25,40:10;10,10,20:20",
                    help="boxes and intervals, BOX:INTERVAL;... (a smoke run: '4,5,8:2;2,2,4:4')")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    dicer = os.path.join(a.build, "dicer")
    bench = os.path.join(a.build, "bench", "bench_side_by_side")
    gen = os.path.join(ROOT, "scripts", "bench_box_msh.py")
    tools = [("msh", dicer, FORMATS["msh"])]
    if a.before:
        tools.append(("before_msh", a.before, FORMATS["msh"]))
    tools += [(f, dicer, FORMATS[f]) for f in a.formats.split(",") if f]
    res = {"machine": sbs.machine(), "reps": a.reps, "before": a.before,
           "command": "/usr/bin/python3 scripts/bench_export_stream.py " + " ".join(sys.argv[1:]), "meshes": []}
    one = os.path.join(a.work, "one.msh")
    sbs.run([sys.executable, gen, "1", "1", "1", one])
    one_store = os.path.join(a.work, "one.dice.h5")
    sbs.run([dicer, "dice", one, "--interval", "1", "-o", one_store, "--quiet"])
    floor = {}
    for name, exe, args in tools:
        floor[name] = summary([export(exe, one_store, args, os.path.join(a.work, "out")) for _ in range(a.reps)])
    if not a.no_gmsh:
        floor["gmsh"] = summary([gmsh(bench, one_store, a.work) for _ in range(a.reps)])
    res["floor"] = floor
    for item in a.meshes.split(";"):
        box, interval = item.split(":")[0], int(item.split(":")[1])
        nx, ny, nz = box.split(",")
        mesh = os.path.join(a.work, "box_%s.msh" % box.replace(",", "x"))
        store = os.path.join(a.work, "box_%s_%d.dice.h5" % (box.replace(",", "x"), interval))
        sbs.run([sys.executable, gen, nx, ny, nz, mesh, "--jitter", "0.15"])
        sbs.run([dicer, "dice", mesh, "--interval", str(interval), "-o", store, "--quiet"])
        info = json.loads(sbs.run([dicer, "info", store, "--json"])["stdout"])
        runs = {name: [] for name, _, _ in tools}
        if not a.no_gmsh:
            runs["gmsh"] = []
        head = [t for t in tools if t[0] in ("msh", "before_msh")]
        rest = [t for t in tools if t[0] not in ("msh", "before_msh")]
        for rep in range(a.reps):
            for name, exe, args in head:
                sbs.log("%s interval %d rep %d: %s" % (box, interval, rep, name))
                runs[name].append(export(exe, store, args, os.path.join(a.work, "out")))
            if not a.no_gmsh:
                sbs.log("%s interval %d rep %d: gmsh" % (box, interval, rep))
                runs["gmsh"].append(gmsh(bench, store, a.work))
            for name, exe, args in rest:
                sbs.log("%s interval %d rep %d: %s" % (box, interval, rep, name))
                runs[name].append(export(exe, store, args, os.path.join(a.work, "out")))
        rec = {"box": box, "interval": interval, "fine_elements": info["fine_elements"],
               "fine_nodes": info["fine_nodes"], "coarse": info["coarse_elements"]}
        for name, r in runs.items():
            s = summary(r)
            s["net_wall_s"] = s["wall_s"] - floor[name]["wall_s"]
            s["net_peak_rss_mib"] = s["peak_rss_mib"] - floor[name]["peak_rss_mib"]
            s["elements_per_s_net"] = info["fine_elements"] / s["net_wall_s"]
            rec[name] = s
        if "gmsh" in rec:
            g = rec["gmsh"]["net_wall_s"]
            rec["ratio_msh_rate_over_gmsh_generate_write_net"] = g / rec["msh"]["net_wall_s"]
            if "before_msh" in rec:
                rec["ratio_before_msh_rate_over_gmsh_generate_write_net"] = g / rec["before_msh"]["net_wall_s"]
        res["meshes"].append(rec)
        os.remove(store)
    res["machine"]["load_after"] = os.getloadavg()
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as f:
        json.dump(res, f, indent=1)
    # The table.
    names = [n for n, _, _ in tools] + ([] if a.no_gmsh else ["gmsh"])
    print("| run | " + " | ".join("%s x %d (%.3g M elements)" % (m["box"], m["interval"], m["fine_elements"] / 1e6)
                                   for m in res["meshes"]) + " |")
    print("|---|" + "---|" * len(res["meshes"]))
    for n in names:
        cells = []
        for m in res["meshes"]:
            s = m[n]
            cells.append("%.2f s net (%s), %.0f MiB peak RSS, %.3g MB" %
                         (s["net_wall_s"], ", ".join("%.2f" % r["wall_s"] for r in s["runs"]), s["peak_rss_mib"],
                          (s.get("file_bytes") or 0) / 1e6))
        print("| %s | %s |" % (n, " | ".join(cells)))
    for key in ("ratio_msh_rate_over_gmsh_generate_write_net", "ratio_before_msh_rate_over_gmsh_generate_write_net"):
        if key in res["meshes"][0]:
            print("| %s | %s |" % (key, " | ".join("%.2fx" % m[key] for m in res["meshes"])))
    print("load before %s, after %s; %s" % (res["machine"]["load_before"], res["machine"]["load_after"],
                                            datetime.datetime.now().isoformat(timespec="minutes")), file=sys.stderr)


if __name__ == "__main__":
    main()
