#!/usr/bin/env python3
"""The side-by-side harness (issue 6 item 3), driven by
scripts/bench_side_by_side.sh. Every tool run is its own process, so its
peak RSS (getrusage of the child, ru_maxrss) is its own; each is repeated
--reps times and the median kept; each tool's empty-run floor (the same
command on a 1-hex mesh at interval 1) is measured the same way and
subtracted ("net").

Mesh: a box of coarse hexes (scripts/bench_box_msh.py, interior vertices
jittered so the hexes are not all congruent), diced at several global
intervals. At each interval, all on the same fine mesh:
  (a) write-bandwidth baseline          bench_side_by_side BM_WriteBandwidth
                                        (and BM_WriteBandwidthConn: the same
                                        with the connectivity the batch API
                                        writes, 8 ids per element)
  (b) dicer block iteration + sweep     BM_BlockIteration, `dicer sweep --threads 2`,
                                        BM_Batches (the batch API alone: nodes +
                                        connectivity, no checksum)
(a) and (b) run interleaved, a round of each at a time, and each ratio
over (a) is the median of the rounds' ratios (interleaved()).
  (c) Gmsh transfinite                  BM_Gmsh/0 (generate), BM_Gmsh/1 (+ binary MSH 4.1)
  (d) explicit HDF5 mesh                BM_Explicit/0 raw, /1 LZ4, /2 shuffle + LZ4
  (e) dicer dice, store size, `dicer export --format msh` (whole mesh)
A second box (10x10x20 = 2000 hexes) at interval 20 gives the same 1.6e7
fine elements from 8x fewer coarse hexes, every tool again. The store-size target (>= 1e4 coarse hexes at interval 20) adds dice +
explicit LZ4 at interval 20 (no Gmsh there: it would not fit in memory),
for the jittered box and for the exact lattice (whose explicit mesh
compresses best, the worst case for the ratio). Optional: the curved
cylinder at interval 16 when `dicer dice --help` offers --geometry.

Results: one JSON file (default bench/results/side_by_side.json).
Standard library only.
"""
import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def log(*a):
    print(*a, file=sys.stderr, flush=True)


def run(cmd, env=None, cwd=None):
    """Runs cmd in its own process; returns wall seconds, peak RSS and output."""
    full_env = dict(os.environ)
    full_env.update(env or {})
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.monotonic()
        p = subprocess.Popen(cmd, stdout=out, stderr=err, env=full_env, cwd=cwd)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.monotonic() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        r = {"cmd": " ".join(cmd), "rc": p.returncode, "wall_s": wall,
             "peak_rss_mib": ru.ru_maxrss / 1024.0,  # Linux: KiB
             "stdout": out.read().decode(errors="replace"), "stderr": err.read().decode(errors="replace")}
    if r["rc"] != 0:
        raise RuntimeError("%s failed (%d): %s" % (r["cmd"], r["rc"], r["stderr"][-2000:]))
    return r


def med(xs):
    return statistics.median(xs) if xs else None


def summarize(runs):
    """Runs (dicts of numbers) -> the medians and every run."""
    keys = [k for k, v in runs[0].items() if isinstance(v, (int, float)) and not isinstance(v, bool)]
    m = {k: med([r[k] for r in runs]) for k in keys}
    m["runs"] = [{k: r[k] for k in keys} for r in runs]
    return m


def repeat(fn, reps):
    """fn() -> dict of numbers; returns the medians and every run."""
    return summarize([fn() for _ in range(reps)])


def interleaved(cases, reps):
    """cases: {name: fn}, the first the baseline. Each round runs every case
    once, in order, so a case and the baseline it is divided by run seconds
    apart: this machine's speed drifts over minutes (a 1-thread write
    bandwidth of one store 1.0-1.6 G nodes/s within an hour), and medians
    of separate blocks of runs divided each other's drift. Returns
    {name: summarize(runs)}, per case the ratio of each round's case to
    that round's baseline (in nodes/s), and the rounds."""
    rounds = [{k: fn() for k, fn in cases.items()} for _ in range(reps)]
    base = next(iter(cases))
    out = {k: summarize([r[k] for r in rounds]) for k in cases}
    paired = {}
    for k in cases:
        if k != base:
            paired[k] = [r[k]["nodes_per_s"] / r[base]["nodes_per_s"] for r in rounds]
    return out, paired, rounds


class Harness:
    def __init__(self, args):
        self.a = args
        self.dicer = os.path.join(args.build, "dicer")
        self.bench = os.path.join(args.build, "bench", "bench_side_by_side")
        os.makedirs(args.work, exist_ok=True)

    def path(self, name):
        return os.path.join(self.a.work, name)

    # --- tools ------------------------------------------------------------
    def dice(self, mesh, interval, store, extra=()):
        r = run([self.dicer, "dice", mesh, "--interval", str(interval), "-o", store, "--quiet", *extra])
        return {"wall_s": r["wall_s"], "peak_rss_mib": r["peak_rss_mib"], "store_bytes": os.path.getsize(store)}

    def info(self, store):
        return json.loads(run([self.dicer, "info", store, "--json"])["stdout"])

    def sweep(self, store):
        r = run([self.dicer, "sweep", store, "--threads", "2", "--json", "--stats"])
        j = json.loads(r["stdout"])
        return {"wall_s": r["wall_s"], "peak_rss_mib": r["peak_rss_mib"], "seconds": j["seconds"],
                "nodes_per_s": j["nodes_per_s"], "threads": j.get("threads", 2), "checksum": j["checksum"]}

    def export_msh(self, store):
        out = self.path("export.msh")
        r = run([self.dicer, "export", store, "--format", "msh", "-o", out, "--quiet"])
        size = os.path.getsize(out)
        os.remove(out)
        return {"wall_s": r["wall_s"], "peak_rss_mib": r["peak_rss_mib"], "file_bytes": size}

    def bench_case(self, store, name):
        """One Google Benchmark case of bench_side_by_side in its own process."""
        r = run([self.bench, "--benchmark_filter=^%s$" % name, "--benchmark_format=json"],
                env={"DICER_SBS_STORE": store, "DICER_SBS_OUT": self.a.work})
        j = json.loads(r["stdout"])
        b = [x for x in j["benchmarks"] if x.get("run_type", "iteration") == "iteration"]
        if not b:
            raise RuntimeError("%s: no result" % name)
        b = b[0]
        if b.get("error_occurred"):
            raise RuntimeError("%s: %s" % (name, b.get("error_message")))
        res = {k: v for k, v in b.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}
        res["wall_s"] = r["wall_s"]
        res["peak_rss_mib"] = r["peak_rss_mib"]
        return res

    # --- one mesh at one interval -----------------------------------------
    def measure(self, mesh, interval, floor, full=True):
        reps = self.a.reps
        store = self.path("box_%d.dice.h5" % interval)
        log("interval %d: dice" % interval)
        rec = {"interval": interval}
        rec["dice"] = repeat(lambda: self.dice(mesh, interval, store), reps)
        info = self.info(store)
        rec["store_bytes"] = os.path.getsize(store)
        rec["fine_elements"] = info.get("fine_elements", info.get("elements"))
        rec["fine_nodes"] = info.get("fine_nodes", info.get("nodes"))
        rec["coarse_hexes"] = info.get("coarse_elements", info.get("coarse_hexes"))
        rec["info"] = info
        explicit = ("0", "1", "2") if full else ("1", "2")
        for f in explicit:
            name = {"0": "raw", "1": "lz4", "2": "shuffle_lz4"}[f]
            log("interval %d: explicit %s" % (interval, name))
            rec["explicit_" + name] = repeat(lambda: self.bench_case(store, "BM_Explicit/%s/iterations:1/manual_time" % f),
                                             reps if full else 1)
        if full:
            log("interval %d: write bandwidth, sweep, batches, block iteration (interleaved)" % interval)
            cases = {"write_bandwidth": lambda: self.bench_case(store, "BM_WriteBandwidth"),
                     "sweep": lambda: self.sweep(store),
                     "batches": lambda: self.bench_case(store, "BM_Batches"),
                     "write_bandwidth_conn": lambda: self.bench_case(store, "BM_WriteBandwidthConn"),
                     "block_iteration_nodes": lambda: self.bench_case(store, "BM_BlockIteration/1"),
                     "block_iteration_conn": lambda: self.bench_case(store, "BM_BlockIteration/0")}
            got, paired, rounds = interleaved(cases, reps)
            rec.update(got)
            rec["paired_over_write_bandwidth"] = paired
            # The batch API against a write of the bytes it hands out.
            rec["paired_batches_over_write_bandwidth_conn"] = [
                r["batches"]["nodes_per_s"] / r["write_bandwidth_conn"]["nodes_per_s"] for r in rounds]
            log("interval %d: export msh" % interval)
            rec["export_msh"] = repeat(lambda: self.export_msh(store), reps)
            log("interval %d: gmsh" % interval)
            rec["gmsh_generate"] = repeat(lambda: self.bench_case(store, "BM_Gmsh/0/iterations:1/manual_time"), reps)
            rec["gmsh_generate_write"] = repeat(lambda: self.bench_case(store, "BM_Gmsh/1/iterations:1/manual_time"), reps)
        for k, v in list(rec.items()):
            if isinstance(v, dict) and k in floor:
                for q in ("wall_s", "peak_rss_mib"):
                    if q in v and q in floor[k]:
                        v["net_" + q] = v[q] - floor[k][q]
        if not self.a.keep:
            os.remove(store)
        return rec

    def floors(self, one_mesh):
        """Each tool on a 1-hex mesh at interval 1: the process floor."""
        reps = self.a.reps
        store = self.path("one.dice.h5")
        log("floors (1 hex, interval 1)")
        f = {"dice": repeat(lambda: self.dice(one_mesh, 1, store), reps)}
        f["sweep"] = repeat(lambda: self.sweep(store), reps)
        f["export_msh"] = repeat(lambda: self.export_msh(store), reps)
        for key, case in (("gmsh_generate", "BM_Gmsh/0/iterations:1/manual_time"),
                          ("gmsh_generate_write", "BM_Gmsh/1/iterations:1/manual_time"),
                          ("explicit_raw", "BM_Explicit/0/iterations:1/manual_time"),
                          ("explicit_lz4", "BM_Explicit/1/iterations:1/manual_time"),
                          ("explicit_shuffle_lz4", "BM_Explicit/2/iterations:1/manual_time")):
            f[key] = repeat(lambda: self.bench_case(store, case), reps)
        return f

    def cylinder(self):
        """The curved case (interval 16), only when dicer can dice onto CAD."""
        help_dice = run([self.dicer, "dice", "--help"])["stdout"]
        help_all = run([self.dicer, "--help"])["stdout"]
        if "--geometry" not in help_dice:
            return {"skipped": "`dicer dice --help` does not offer --geometry (CAD dicing not built yet)"}
        if "mesh-coarse" not in help_all:
            return {"skipped": "`dicer mesh-coarse` is not available (no coarse hex mesh of the cylinder)"}
        brep, msh, store = self.path("cyl.brep"), self.path("cyl.msh"), self.path("cyl.dice.h5")
        code = ("import gmsh; gmsh.initialize(); gmsh.option.setNumber('General.Terminal', 0); "
                "gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, 4, 1); gmsh.model.occ.synchronize(); "
                "gmsh.write(%r); gmsh.finalize()" % brep)
        run(["/usr/bin/python3", "-c", code])
        run([self.dicer, "mesh-coarse", brep, "--size", str(self.a.cyl_size), "-o", msh])
        rec = {"interval": 16, "size": self.a.cyl_size}
        rec["dice"] = self.dice(msh, 16, store, extra=("--geometry", brep))
        rec["store_bytes"] = os.path.getsize(store)
        rec["info"] = self.info(store)
        rec["explicit_lz4"] = self.bench_case(store, "BM_Explicit/1/iterations:1/manual_time")
        rec["ratio_explicit_lz4_over_store"] = rec["explicit_lz4"]["file_bytes"] / rec["store_bytes"]
        rec["target_ratio"] = 50
        if not self.a.keep:
            os.remove(store)
        return rec


def div(a, b):
    """a / b, None when b is not positive (a net figure lost in the noise)."""
    return a / b if b and b > 0 else None


def ratios(rec):
    """dicer / baseline figures of one interval (absent where not measured)."""
    r = {}
    g, gw, d, ex = rec.get("gmsh_generate"), rec.get("gmsh_generate_write"), rec.get("dice"), rec.get("export_msh")
    e = rec["fine_elements"]
    if g and d:
        r["gmsh_generate_over_dice_time_net"] = div(g["net_wall_s"], d["net_wall_s"])
        r["gmsh_generate_over_dice_rss_net"] = div(g["net_peak_rss_mib"], d["net_peak_rss_mib"])
        r["gmsh_generate_over_dice_time_raw"] = g["wall_s"] / d["wall_s"]
        r["gmsh_generate_over_dice_rss_raw"] = g["peak_rss_mib"] / d["peak_rss_mib"]
    if gw and ex:
        r["export_rate_over_gmsh_generate_write_net"] = div(gw["net_wall_s"], ex["net_wall_s"])
        r["export_rate_over_gmsh_generate_write_inprocess"] = (gw["build_s"] + gw["generate_s"] + gw["write_s"]) / ex["wall_s"]
        r["export_rss_over_gmsh_generate_write_net"] = div(ex["net_peak_rss_mib"], gw["net_peak_rss_mib"])
    for k in ("raw", "lz4", "shuffle_lz4"):
        x = rec.get("explicit_" + k)
        if x:
            r["explicit_%s_over_store" % k] = x["file_bytes"] / rec["store_bytes"]
    if rec.get("write_bandwidth") and rec.get("block_iteration_nodes"):
        # The median of each round's ratio (interleaved()); where a record
        # has no rounds (older JSON), the ratio of the medians.
        wb = rec["write_bandwidth"]["nodes_per_s"]
        paired = rec.get("paired_over_write_bandwidth", {})
        for key in ("block_iteration_nodes", "block_iteration_conn", "sweep", "batches", "write_bandwidth_conn"):
            if rec.get(key):
                r[key + "_over_write_bandwidth"] = med(paired[key]) if key in paired else rec[key]["nodes_per_s"] / wb
                r[key + "_over_write_bandwidth_of_medians"] = rec[key]["nodes_per_s"] / wb
        if rec.get("paired_batches_over_write_bandwidth_conn"):
            r["batches_over_write_bandwidth_conn"] = med(rec["paired_batches_over_write_bandwidth_conn"])
    if ex:
        r["export_elements_per_s_net"] = div(e, ex["net_wall_s"])
    if gw:
        r["gmsh_generate_write_hexes_per_s_net"] = div(e, gw["net_wall_s"])
    return r


def machine():
    cpu = ""
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(l.split(":", 1)[1].strip() for l in f if l.startswith("model name"))
    except (OSError, StopIteration):
        pass
    rev = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    dirty = subprocess.run(["git", "-C", ROOT, "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip() != ""
    return {"date": datetime.datetime.now().isoformat(timespec="seconds"), "cpu": cpu, "cores": os.cpu_count(),
            "mem_gib": os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30,
            "kernel": platform.release(), "git": rev + ("-dirty" if dirty else ""), "load_before": os.getloadavg()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=os.path.join(ROOT, "build-bench"))
    ap.add_argument("--work", default=os.path.join(tempfile.gettempdir(), "dicer-side-by-side"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "side_by_side.json"))
    ap.add_argument("--box", default="16,25,40", help="coarse hexes along x,y,z (default 16,25,40: 16000 hexes)")
    ap.add_argument("--jitter", type=float, default=0.15, help="interior vertex jitter, fraction of the spacing")
    ap.add_argument("--intervals", default="2,5,10", help="intervals with every tool (10: 1.6e7 elements)")
    ap.add_argument("--store-interval", type=int, default=20, help="the store-size target's interval (0: skip)")
    ap.add_argument("--coarser-box", default="10,10,20",
                    help="a second box giving the same fine count at --coarser-interval ('' to skip)")
    ap.add_argument("--coarser-interval", type=int, default=20)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--cyl-size", type=float, default=0.25)
    ap.add_argument("--keep", action="store_true", help="keep the stores in --work")
    ap.add_argument("--no-cylinder", action="store_true", help="skip the curved case (smoke runs)")
    a = ap.parse_args()
    h = Harness(a)
    res = {"machine": machine(), "box": [int(x) for x in a.box.split(",")], "jitter": a.jitter, "reps": a.reps,
           "command": "bash scripts/bench_side_by_side.sh " + " ".join(sys.argv[1:])}
    nx, ny, nz = res["box"]
    mesh, lattice, one = h.path("box.msh"), h.path("box_lattice.msh"), h.path("one.msh")
    gen = os.path.join(ROOT, "scripts", "bench_box_msh.py")
    run([sys.executable, gen, str(nx), str(ny), str(nz), mesh, "--jitter", str(a.jitter)])
    run([sys.executable, gen, "1", "1", "1", one])
    t0 = time.monotonic()
    res["floor"] = h.floors(one)
    res["intervals"] = []
    for n in [int(x) for x in a.intervals.split(",") if x]:
        rec = h.measure(mesh, n, res["floor"])
        rec["ratios"] = ratios(rec)
        res["intervals"].append(rec)
        log(json.dumps(rec["ratios"], indent=1))
    if a.coarser_box:
        # The same fine element count from 8x fewer, 8x larger coarse hexes:
        # dice's memory follows the coarse mesh, Gmsh's the fine one.
        cx, cy, cz = (int(x) for x in a.coarser_box.split(","))
        cmesh = h.path("box_coarser.msh")
        run([sys.executable, gen, str(cx), str(cy), str(cz), cmesh, "--jitter", str(a.jitter)])
        rec = h.measure(cmesh, a.coarser_interval, res["floor"])
        rec["box"] = [cx, cy, cz]
        rec["ratios"] = ratios(rec)
        res["coarser"] = rec
        log("coarser", json.dumps(rec["ratios"], indent=1))
    if a.store_interval:
        st = {}
        for key, m in (("jittered", mesh), ("lattice", lattice)):
            if key == "lattice":
                run([sys.executable, gen, str(nx), str(ny), str(nz), lattice])
            rec = h.measure(m, a.store_interval, res["floor"], full=False)
            rec["ratios"] = ratios(rec)
            st[key] = rec
            log(key, json.dumps(rec["ratios"], indent=1))
        res["store_target"] = st
    res["cylinder"] = {"skipped": "--no-cylinder"} if a.no_cylinder else h.cylinder()
    log("cylinder:", json.dumps({k: v for k, v in res["cylinder"].items() if k != "info"}))
    res["harness_seconds"] = time.monotonic() - t0
    res["machine"]["load_after"] = os.getloadavg()
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as f:
        json.dump(res, f, indent=1)
    log("wrote", a.out, "in %.0f s" % res["harness_seconds"])


if __name__ == "__main__":
    main()
