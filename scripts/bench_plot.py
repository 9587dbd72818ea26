#!/usr/bin/python3
"""Turns the side-by-side JSON into bench/results/side_by_side.png and
regenerates the numbers tables of bench/README.md between marker comments
(<!-- BEGIN name --> ... <!-- END name -->), so the picture and the tables
always come from the same files:
  side-by-side, store-target, targets   from side_by_side.json
  run-1e10                               from run_1e10.json (scripts/bench_1e10.sh), if present
  cache                                  from cache.json (bench_cache), if present
  box-query                              from box_query.json (scripts/bench_queries.py), if present
  locate                                 from locate.json (bench/bench_locate), if present
  mpi, project-ranks                     from mpi.json, project_ranks.json (scripts/bench_mpi.py), if present

usage: /usr/bin/python3 scripts/bench_plot.py [bench/results/side_by_side.json]
                                              [--png PATH] [--no-readme] [--tables-only]
(--tables-only: the README tables without the picture; no matplotlib needed)
Needs matplotlib (Debian: python3-matplotlib, scripts/bench_deps.sh).
"""
import argparse
import json
import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, "bench", "results")
# Published per-element figures (issue 6, measured on this kind of machine).
GMSH_BYTES_PER_HEX = 211.0     # Gmsh 4.8 transfinite, RSS per hex (bench_export: 211 B)
P4EST_BYTES_PER_OCTANT = 98.0  # p4est forest + lnodes
MACHINE_GIB = 24


def load(path):
    if path and os.path.exists(path):
        with open(path) as f:
            return json.load(f)
    return None


def fmt(x, unit="", digits=3):
    if x is None:
        return "n/a"
    ax = abs(x)
    for div, suf in ((1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k")):
        if ax >= div:
            return "%.*g %s%s" % (digits, x / div, suf, unit)
    return "%.*g %s" % (digits, x, unit) if unit else "%.*g" % (digits, x)


def mib(x):
    return "n/a" if x is None else ("%.0f MiB" % x if abs(x) >= 10 else "%.1f MiB" % x)


def secs(x):
    return "n/a" if x is None else ("%.3f s" % x if abs(x) < 1 else "%.2f s" % x if abs(x) < 10 else "%.1f s" % x)


def ratio(x):
    return "n/a" if x is None else ("%.0fx" % x if x >= 10 else "%.2fx" % x)


def g(d, *keys):
    for k in keys:
        if d is None or k not in d:
            return None
        d = d[k]
    return d


# ---------------------------------------------------------------- tables
def columns(res):
    """Every fully measured mesh: the intervals of the main box, then the coarser box."""
    return res["intervals"] + ([res["coarser"]] if res.get("coarser") else [])


def table_side_by_side(res):
    cols = columns(res)
    rows = ["| fine elements = coarse hexes x interval^3 | " + " | ".join(
        "%s = %s x %d^3" % (fmt(r["fine_elements"]), fmt(r["coarse_hexes"]), r["interval"]) for r in cols) + " |",
            "|---|" + "---|" * len(cols)]

    def row(label, f):
        rows.append("| %s | %s |" % (label, " | ".join(f(r) for r in cols)))

    row("(a) write-bandwidth baseline", lambda r: fmt(g(r, "write_bandwidth", "nodes_per_s"), " nodes/s"))
    row("(a) the same + 8 ids per element (the batch API's bytes)",
        lambda r: fmt(g(r, "write_bandwidth_conn", "nodes_per_s"), " nodes/s"))
    row("(b) block iteration, nodes only", lambda r: fmt(g(r, "block_iteration_nodes", "nodes_per_s"), " nodes/s"))
    row("(b) block iteration, + connectivity", lambda r: fmt(g(r, "block_iteration_conn", "nodes_per_s"), " nodes/s"))
    row("(b) batch API (`BatchCursor`: nodes + connectivity)", lambda r: fmt(g(r, "batches", "nodes_per_s"), " nodes/s"))
    row("(b) `dicer sweep --threads 2`", lambda r: "%s (%s nodes/s)" % (secs(g(r, "sweep", "seconds")),
                                                                          fmt(g(r, "sweep", "nodes_per_s"))))
    row("(b) sweep peak RSS", lambda r: mib(g(r, "sweep", "peak_rss_mib")))
    row("(c) Gmsh generate, net time", lambda r: secs(g(r, "gmsh_generate", "net_wall_s")))
    row("(c) Gmsh generate, net peak RSS", lambda r: mib(g(r, "gmsh_generate", "net_peak_rss_mib")))
    row("(c) Gmsh generate + write MSH, net time", lambda r: secs(g(r, "gmsh_generate_write", "net_wall_s")))
    row("(c) Gmsh MSH file", lambda r: fmt(g(r, "gmsh_generate_write", "file_bytes"), "B"))
    row("(d) explicit HDF5 raw", lambda r: "%s, %s" % (fmt(g(r, "explicit_raw", "file_bytes"), "B"),
                                                      secs(g(r, "explicit_raw", "net_wall_s"))))
    row("(d) explicit HDF5 LZ4", lambda r: "%s, %s" % (fmt(g(r, "explicit_lz4", "file_bytes"), "B"),
                                                      secs(g(r, "explicit_lz4", "net_wall_s"))))
    row("(d) explicit HDF5 shuffle + LZ4", lambda r: "%s, %s" % (fmt(g(r, "explicit_shuffle_lz4", "file_bytes"), "B"),
                                                                secs(g(r, "explicit_shuffle_lz4", "net_wall_s"))))
    row("(e) `dicer dice`, net time", lambda r: secs(g(r, "dice", "net_wall_s")))
    row("(e) `dicer dice`, net peak RSS", lambda r: mib(g(r, "dice", "net_peak_rss_mib")))
    row("(e) store", lambda r: fmt(r["store_bytes"], "B"))
    row("(e) `dicer export --format msh`, net time", lambda r: secs(g(r, "export_msh", "net_wall_s")))
    row("(e) export net peak RSS", lambda r: mib(g(r, "export_msh", "net_peak_rss_mib")))
    row("(e) dicer MSH file", lambda r: fmt(g(r, "export_msh", "file_bytes"), "B"))
    rows.append("| **ratios** |" + " |" * len(cols))
    row("Gmsh generate / dice, time (net)", lambda r: ratio(g(r, "ratios", "gmsh_generate_over_dice_time_net")))
    row("Gmsh generate / dice, peak RSS (net)", lambda r: ratio(g(r, "ratios", "gmsh_generate_over_dice_rss_net")))
    row("dicer MSH export rate / Gmsh generate + write rate (net)",
        lambda r: ratio(g(r, "ratios", "export_rate_over_gmsh_generate_write_net")))
    row("explicit LZ4 / store", lambda r: ratio(g(r, "ratios", "explicit_lz4_over_store")))
    row("explicit shuffle + LZ4 / store", lambda r: ratio(g(r, "ratios", "explicit_shuffle_lz4_over_store")))
    row("block iteration (nodes) / write bandwidth", lambda r: "%.3f" % g(r, "ratios", "block_iteration_nodes_over_write_bandwidth")
        if g(r, "ratios", "block_iteration_nodes_over_write_bandwidth") is not None else "n/a")
    def paired(r, key):
        """The median of the rounds' ratios, and their range (interleaved runs)."""
        v = g(r, "ratios", key + "_over_write_bandwidth")
        if v is None:
            return "n/a"
        runs = (r.get("paired_over_write_bandwidth") or {}).get(key)
        return "%.3f" % v + (" (rounds %.3f-%.3f)" % (min(runs), max(runs)) if runs else "")

    for key, label in (("batches", "batch API / write bandwidth, median of rounds"),
                       ("write_bandwidth_conn", "writing the batch API's bytes / write bandwidth, median of rounds"),
                       ("sweep", "sweep / write bandwidth, median of rounds")):
        row(label, lambda r, key=key: paired(r, key))

    def same_bytes(r):
        v = g(r, "ratios", "batches_over_write_bandwidth_conn")
        runs = r.get("paired_batches_over_write_bandwidth_conn")
        if v is None:
            return "n/a"
        return "%.3f" % v + (" (rounds %.3f-%.3f)" % (min(runs), max(runs)) if runs else "")

    row("batch API / writing its bytes, median of rounds", same_bytes)
    f = res["floor"]
    rows.append("")
    rows.append("Floors (1 hex, interval 1, medians): dice %s / %s, sweep %s / %s, export %s / %s, "
                "Gmsh generate %s / %s, explicit LZ4 %s / %s (wall / peak RSS of the process)." % (
                    secs(f["dice"]["wall_s"]), mib(f["dice"]["peak_rss_mib"]), secs(f["sweep"]["wall_s"]),
                    mib(f["sweep"]["peak_rss_mib"]), secs(f["export_msh"]["wall_s"]), mib(f["export_msh"]["peak_rss_mib"]),
                    secs(f["gmsh_generate"]["wall_s"]), mib(f["gmsh_generate"]["peak_rss_mib"]),
                    secs(f["explicit_lz4"]["wall_s"]), mib(f["explicit_lz4"]["peak_rss_mib"])))
    return "\n".join(rows)


def table_store_target(res):
    st = res.get("store_target")
    if not st:
        return "(not run)"
    rows = ["| box %s, interval %d | coarse hexes | fine elements | store | explicit LZ4 | explicit shuffle + LZ4 | LZ4 / store | shuffle + LZ4 / store |"
            % ("x".join(map(str, res["box"])), next(iter(st.values()))["interval"]), "|---|---|---|---|---|---|---|---|"]
    for key, r in st.items():
        rows.append("| %s | %s | %s | %s | %s | %s | **%s** | %s |" % (
            key, fmt(r["coarse_hexes"]), fmt(r["fine_elements"]), fmt(r["store_bytes"], "B"),
            fmt(g(r, "explicit_lz4", "file_bytes"), "B"), fmt(g(r, "explicit_shuffle_lz4", "file_bytes"), "B"),
            ratio(g(r, "ratios", "explicit_lz4_over_store")), ratio(g(r, "ratios", "explicit_shuffle_lz4_over_store"))))
    cyl = res.get("cylinder", {})
    rows.append("")
    if "skipped" in cyl:
        rows.append("Curved cylinder at interval 16: **skipped**: %s." % cyl["skipped"])
    else:
        rows.append("Curved cylinder at interval 16 (coarse size %s): store %s, explicit LZ4 %s, ratio **%s** (target 50x)."
                    % (cyl.get("size"), fmt(cyl.get("store_bytes"), "B"), fmt(g(cyl, "explicit_lz4", "file_bytes"), "B"),
                       ratio(cyl.get("ratio_explicit_lz4_over_store"))))
    return "\n".join(rows)


def main_interval(res):
    """The interval closest to 1.6e7 fine elements (the issue's Gmsh figure)."""
    return min(res["intervals"], key=lambda r: abs(r["fine_elements"] - 1.6e7))


def table_targets(res):
    r = main_interval(res)
    st = g(res, "store_target", "jittered")
    lat = g(res, "store_target", "lattice")
    cyl = res.get("cylinder", {})

    def verdict(x, t):
        return "n/a" if x is None else ("**met**" if x >= t else "**not met**")

    rows = ["| target (issue 6) | measured | verdict |", "|---|---|---|"]
    x = g(r, "ratios", "gmsh_generate_over_dice_time_net")
    rows.append("| dice 100x less time than Gmsh meshing the same %s-element mesh (net of floors) | %s | %s |"
                % (fmt(r["fine_elements"]), ratio(x), verdict(x, 100)))
    x = g(r, "ratios", "gmsh_generate_over_dice_rss_net")
    rows.append("| dice 1000x less peak memory than Gmsh (net of floors) | %s | %s |" % (ratio(x), verdict(x, 1000)))
    c = res.get("coarser")
    if c:
        xt, xm = g(c, "ratios", "gmsh_generate_over_dice_time_net"), g(c, "ratios", "gmsh_generate_over_dice_rss_net")
        rows.append("| the same two, %s elements from %s coarse hexes at interval %d | time %s, memory %s | time %s, memory %s |"
                    % (fmt(c["fine_elements"]), fmt(c["coarse_hexes"]), c["interval"], ratio(xt), ratio(xm),
                       verdict(xt, 100), verdict(xm, 1000)))
    x = g(r, "ratios", "export_rate_over_gmsh_generate_write_net")
    rows.append("| MSH export >= 5x Gmsh generate + write rate | %s | %s |" % (ratio(x), verdict(x, 5)))
    if c:
        x = g(c, "ratios", "export_rate_over_gmsh_generate_write_net")
        rows.append("| the same, %s coarse hexes at interval %d | %s | %s |" % (fmt(c["coarse_hexes"]), c["interval"], ratio(x), verdict(x, 5)))
    x = g(st, "ratios", "explicit_lz4_over_store")
    xl = g(lat, "ratios", "explicit_lz4_over_store")
    rows.append("| store >= 1000x smaller than explicit LZ4, >= 1e4 coarse hexes at interval 20 | %s (exact lattice: %s) | %s |"
                % (ratio(x), ratio(xl), verdict(x, 1000) + ("" if xl is None or (xl >= 1000) == (x >= 1000) else
                                                            " (lattice: %s)" % verdict(xl, 1000))))
    if "skipped" in cyl:
        rows.append("| store >= 50x smaller than explicit LZ4, curved cylinder at interval 16 | skipped | not measured |")
    else:
        x = cyl.get("ratio_explicit_lz4_over_store")
        rows.append("| store >= 50x smaller than explicit LZ4, curved cylinder at interval 16 | %s | %s |" % (ratio(x), verdict(x, 50)))
    return "\n".join(rows)


def table_1e10(run):
    if not run:
        return "(not run yet: `bash scripts/bench_1e10.sh`)"
    rows = ["| step | wall time | peak RSS | pages read | other |", "|---|---|---|---|---|"]
    d, s, q = run["dice"], run["sweep"], run.get("queries", {})
    rows.append("| `dicer dice` (%s coarse hexes, interval %d) | %s | %s | | store %s, %s fine elements, %s nodes |" % (
        fmt(run["coarse_hexes"]), run["interval"], secs(d["wall_s"]), mib(d["peak_rss_mib"]),
        fmt(run["store_bytes"], "B"), fmt(run["fine_elements"]), fmt(run["fine_nodes"])))
    rows.append("| `dicer sweep --threads %d --cache-mb %d` | %s | %s | %s | %s nodes/s, checksum %s |" % (
        s.get("threads", 2), run["cache_mb"], secs(s["wall_s"]), mib(s["peak_rss_mib"]), fmt(g(s, "stats", "pages_read")),
        fmt(s.get("nodes_per_s")), s.get("checksum")))
    for k, label in (("nodes", "node(id)"), ("elements", "element(id)")):
        if k in q:
            rows.append("| %s random %s queries, 256 MiB cache | %s | %s | %s | %s ns/query, hit rate %.4f |" % (
                fmt(q[k]["queries"]), label, secs(q[k]["seconds"]), mib(q["peak_rss_mib"]), fmt(q[k]["pages_read"]),
                "%.0f" % (1e9 * q[k]["seconds"] / q[k]["queries"]), q[k]["hit_rate"]))
    e = run["fine_elements"]
    rows.append("")
    rows.append("What the same %s elements would need held in memory: Gmsh %.1f TiB (%.0f B/hex), p4est with lnodes "
                "%.2f TiB (%.0f B/octant); this machine has %d GiB. The explicit mesh on disk: %.2f TiB raw "
                "(24 B/node + 64 B/hex)." % (fmt(e), e * GMSH_BYTES_PER_HEX / 2**40, GMSH_BYTES_PER_HEX,
                                               e * P4EST_BYTES_PER_OCTANT / 2**40, P4EST_BYTES_PER_OCTANT, MACHINE_GIB,
                                               (24 * run["fine_nodes"] + 64 * e) / 2**40))
    return "\n".join(rows)


def table_cache(cache):
    if not cache:
        return "(not run yet: see the command above)"
    names = {0: "sweep (fill_block, store order)", 1: "random node(id)", 2: "random element(id)", 3: "box queries (1% of the volume)"}
    res = {}
    for b in cache["benchmarks"]:
        m = re.match(r"BM_Cache/pattern:(\d)/pct:(\d+)/ra:(\d)", b["name"])
        if not m or b.get("run_type") == "aggregate" and b.get("aggregate_name") != "median":
            continue
        if b.get("run_type") == "iteration" and any(x.get("aggregate_name") == "median" for x in cache["benchmarks"]):
            continue
        res[(int(m.group(1)), int(m.group(3)), int(m.group(2)))] = b
    pcts = sorted({k[2] for k in res})
    rows = ["| pattern (read-ahead) | " + " | ".join("%d%%" % p for p in pcts) + " |", "|---|" + "---|" * len(pcts)]
    for (pat, ra) in sorted({(k[0], k[1]) for k in res}, key=lambda t: (t[0], -t[1])):
        cells = []
        for p in pcts:
            b = res.get((pat, ra, p))
            cells.append("n/a" if b is None else "%.3f / **%.2f** / %s" % (b["hit_rate"], b["read_amplification"],
                                                                          fmt(b["pages_read"])))
        rows.append("| %s (%d) | %s |" % (names[pat], ra, " | ".join(cells)))
    any_b = next(iter(res.values()))
    rows.append("")
    rows.append("Cells: hit rate / **read amplification** (pages read / distinct pages the pattern touches) / pages read. "
                "Store: %d pages, %.1f MiB decoded (the 100%% budget)." % (any_b["store_pages"], any_b["store_decoded_MiB"]))
    return "\n".join(rows)


def table_box_query(j):
    if not j:
        return "(not run yet: `/usr/bin/python3 scripts/bench_queries.py`)"
    rows = ["| box (share of the domain) | elements found | wall (median) | peak RSS | element pages read | corner pages | bounds pages |",
            "|---|---|---|---|---|---|---|"]
    for q in j["queries"]:
        pg = q["pages"]

        def cell(k):
            return "%d of %d (%.2f%%)" % (pg[k]["read"], pg[k]["of"], 100.0 * pg[k]["read"] / pg[k]["of"]) if k in pg else "n/a"
        rows.append("| %.1f%% | %s | %s | %s | %s | %s | %s |" % (100 * q["fraction"], fmt(q["count"]), secs(q["wall_s"]),
                                                            mib(q["peak_rss_mib"]), cell("elements"), cell("element_corners"),
                                                            cell("element_bounds")))
    rows.append("")
    rows.append("Store %s, commit %s, %s; `dicer query --box ... --count --stats`, medians of %d runs."
                % (j["store"], j["commit"], j["date"], len(j["queries"][0]["all_wall_s"])))
    return "\n".join(rows)


def table_locate(j):
    if not j:
        return "(not run yet: see the command above)"
    b = {x["name"]: x for x in j["benchmarks"]}
    rows = ["| case | per point / query | note |", "|---|---|---|"]
    for name, label in (("BM_Locate/1/iterations:1/real_time", "locate, 1 thread"),
                        ("BM_Locate/2/iterations:1/real_time", "locate, 2 threads")):
        if name in b:
            rows.append("| %s | %.2f us | %s points, %.4f in the element they were made in (the rest in a lower-id element sharing the face) |"
                        % (label, b[name]["ns_per_point"] * 1e6, fmt(b[name]["points"]), b[name]["in_their_element"]))
    if "BM_ElementQuery/iterations:1/real_time" in b:
        rows.append("| baseline: element(id), same ids | %.2f us | the id query of the same store and cache |"
                    % (b["BM_ElementQuery/iterations:1/real_time"]["ns_per_query"] * 1e6))
    if "BM_BruteForce/real_time" in b:
        x = b["BM_BruteForce/real_time"]
        rows.append("| baseline: brute force, %s elements in memory | %.2f us | box test of every element, no inversion (a lower bound) |"
                    % (fmt(x["elements"]), x["ns_per_point"] * 1e6))
    ctx = j.get("context", {})
    rows.append("")
    rows.append("%s, %s CPUs, %s." % (ctx.get("host_name", "?"), ctx.get("num_cpus", "?"), ctx.get("date", "?")))
    return "\n".join(rows)


def table_mpi(j):
    if not j:
        return "(not run yet: `/usr/bin/python3 scripts/bench_mpi.py`)"
    rows = ["| ranks | what | elements | seconds (median) | elements/s | efficiency | note |", "|---|---|---|---|---|---|---|"]
    for r in j["runs"]:
        note = ("imbalance %.2f, %s pages read, checksum %s" % (r["imbalance"], fmt(r["pages_read"]), r["checksum"])
                if r["what"] == "sweep" else "")
        rows.append("| %d | %s | %s | %s | %s | %.2f | %s |" % (r["P"], r["what"], fmt(r["elements"]), secs(r["seconds"]),
                                                           fmt(r["elements_per_s"]), r["efficiency"], note))
    rows.append("")
    rows.append("Commit %s, %s, %d cores; one thread per rank; efficiency = rate(P) / (P x rate(1))." % (j["commit"], j["date"], j["machine"]))
    return "\n".join(rows)


def table_project(j):
    if not j:
        return "(not run yet: `/usr/bin/python3 scripts/bench_mpi.py`)"
    rows = ["| ranks | build (one process) | elements per rank | ghost nodes (mean / max) | neighbours (mean / max) | shared nodes (mean / max) | maps, largest rank |",
            "|---|---|---|---|---|---|---|"]
    for p in j["partitions"]:
        rows.append("| %s | %s | %s | %s / %s | %.1f / %d | %s / %s | %s |" % (
            fmt(p["P"]), secs(p["seconds"]), fmt(p["elements"][1]), fmt(p["ghost_nodes"][0]), fmt(p["ghost_nodes"][1]),
            p["neighbors"][0], p["neighbors"][1], fmt(p["shared_nodes"][0]), fmt(p["shared_nodes"][1]),
            mib(p["comm_entries"][1] * 8 / 2**20)))
    rows.append("")
    rows.append("| sampled rank (of P) | elements | sweep, 1 thread | elements/s | pages read | bytes read | cache peak |")
    rows.append("|---|---|---|---|---|---|---|")
    for x in j["samples"]:
        rows.append("| %d of %s | %s | %s | %s | %d | %s | %s |" % (x["rank"], fmt(x["P"]), fmt(x["elements"]), secs(x["seconds"]),
                                                               fmt(x["elements"] / x["seconds"]), x["pages_read"],
                                                               fmt(x["bytes_read"], "B"), fmt(x["cache_peak"], "B")))
    rows.append("")
    rows.append("Store %s: %s fine elements (%s on disk), peak RSS of the sampling process %s; commit %s, %s."
                % (os.path.basename(j["store"]), fmt(j["elements"]), fmt(j.get("store_bytes"), "B"),
                   mib(j["rank_peak_rss"] / 2**20), j.get("commit", "?"), j.get("date", "?")))
    return "\n".join(rows)


def replace_block(text, name, body):
    pat = re.compile(r"(<!-- BEGIN %s -->\n).*?(<!-- END %s -->)" % (name, name), re.S)
    if not pat.search(text):
        print("bench/README.md has no %s markers; table not written" % name, file=sys.stderr)
        return text
    return pat.sub(lambda m: m.group(1) + body + "\n" + m.group(2), text)


# ---------------------------------------------------------------- picture
# (record key, field, label, line style, colour) of each curve, per panel.
TIME_SERIES = [
    ("gmsh_generate", "net_wall_s", "Gmsh transfinite generate", "s-", "tab:red"),
    ("gmsh_generate_write", "net_wall_s", "Gmsh generate + write MSH", "s--", "tab:red"),
    ("explicit_lz4", "net_wall_s", "explicit HDF5 LZ4 write (dicer-generated)", "^-", "tab:gray"),
    ("export_msh", "net_wall_s", "dicer export MSH", "o--", "tab:blue"),
    ("sweep", "seconds", "dicer sweep (2 threads)", "o:", "tab:green"),
    ("dice", "net_wall_s", "dicer dice", "o-", "tab:blue"),
]
MEMORY_SERIES = [
    ("gmsh_generate", "net_peak_rss_mib", "Gmsh generate", "s-", "tab:red"),
    ("export_msh", "net_peak_rss_mib", "dicer export MSH (one chunk = whole mesh)", "o--", "tab:blue"),
    ("dice", "net_peak_rss_mib", "dicer dice", "o-", "tab:blue"),
    ("sweep", "peak_rss_mib", "dicer sweep (whole process, 64 MiB cache)", "o:", "tab:green"),
]
DISK_SERIES = [
    ("explicit_raw", "file_bytes", "explicit HDF5 raw", "^-", "tab:gray"),
    ("explicit_lz4", "file_bytes", "explicit HDF5 LZ4", "^--", "tab:gray"),
    ("explicit_shuffle_lz4", "file_bytes", "explicit HDF5 shuffle + LZ4", "^:", "tab:gray"),
    ("gmsh_generate_write", "file_bytes", "Gmsh binary MSH", "s-", "tab:red"),
]


def plot(res, run, png):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    iv = res["intervals"]
    E = [r["fine_elements"] for r in iv]
    fig, ax = plt.subplots(1, 3, figsize=(17, 5.4))

    def series(a, key, field, label, style, color):
        xs = [r["fine_elements"] for r in iv if g(r, key, field) is not None and g(r, key, field) > 0]
        ys = [g(r, key, field) for r in iv if g(r, key, field) is not None and g(r, key, field) > 0]
        if xs:
            a.plot(xs, ys, style, label=label, color=color)

    def coarser(a, field):
        """dice and Gmsh on the coarser box (same fine count, fewer coarse hexes): hollow markers."""
        c = res.get("coarser")
        if not c:
            return
        for key, col, lab in (("dice", "tab:blue", "dicer dice"), ("gmsh_generate", "tab:red", "Gmsh generate")):
            a.plot([c["fine_elements"]], [c[key][field]], "o", mfc="none", ms=10, color=col,
                   label="%s, %d coarse hexes at interval %d" % (lab, c["coarse_hexes"], c["interval"]))

    def panel(a, specs, field, stars, title, ylabel):
        """The measured curves, the coarser box's points, the 1e10 run's stars."""
        for spec in specs:
            series(a, *spec)
        coarser(a, field)
        for y, col, lab in stars if run else []:
            a.plot([run["fine_elements"]], [y], "*", ms=14, color=col, label=lab)
        a.set_title(title)
        a.set_ylabel(ylabel)

    panel(ax[0], TIME_SERIES, "net_wall_s",
          [(g(run, "sweep", "wall_s"), "tab:green", "dicer sweep, 1e10 run"),
           (g(run, "dice", "wall_s"), "tab:blue", "dicer dice, 1e10 run")],
          "time (net of each tool's 1-hex floor)", "seconds")
    a = ax[1]
    xs = [min(E), 2e10]
    a.plot(xs, [x * GMSH_BYTES_PER_HEX / 2**20 for x in xs], "-", color="tab:red", alpha=0.3, lw=6,
           label="Gmsh %.0f B/hex, extrapolated" % GMSH_BYTES_PER_HEX)
    a.plot(xs, [x * P4EST_BYTES_PER_OCTANT / 2**20 for x in xs], "-", color="tab:purple", alpha=0.5,
           label="p4est + lnodes %.0f B/octant" % P4EST_BYTES_PER_OCTANT)
    a.axhline(MACHINE_GIB * 1024, color="k", ls=":", lw=1, label="this machine: %d GiB" % MACHINE_GIB)
    panel(a, MEMORY_SERIES, "net_peak_rss_mib",
          [(g(run, "sweep", "peak_rss_mib"), "tab:green", "dicer sweep, 1e10 run (whole process)")],
          "peak memory", "MiB")

    # Bytes on disk.
    a = ax[2]
    for spec in DISK_SERIES:
        series(a, *spec)
    xs = [min(E), 2e10]
    a.plot(xs, [88 * x for x in xs], "-", color="tab:gray", alpha=0.3, lw=6, label="explicit raw, 88 B/hex, extrapolated")
    xs = [r["fine_elements"] for r in iv]
    a.plot(xs, [r["store_bytes"] for r in iv], "o-", color="tab:blue", label="dicer store")
    for key, mk in (("jittered", "D"), ("lattice", "d")):
        st = g(res, "store_target", key)
        if st:
            a.plot([st["fine_elements"]], [st["store_bytes"]], mk, color="tab:blue", label="dicer store (%s, interval %d)" % (key, st["interval"]))
            a.plot([st["fine_elements"]], [g(st, "explicit_lz4", "file_bytes")], mk, color="tab:gray",
                   label="explicit LZ4 (%s, interval %d)" % (key, st["interval"]))
    if run:
        a.plot([run["fine_elements"]], [run["store_bytes"]], "*", ms=14, color="tab:blue", label="dicer store, 1e10 run")
    a.set_title("bytes on disk")
    a.set_ylabel("bytes")
    for a in ax:
        a.set_xscale("log")
        a.set_yscale("log")
        a.set_xlabel("fine elements")
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    m = res["machine"]
    fig.suptitle("dicer vs Gmsh 4.8 transfinite, p4est and an explicit HDF5 mesh: box %s coarse hexes; %s, %d cores; "
                 "medians of %d runs, %s" % ("x".join(map(str, res["box"])), m["cpu"], m["cores"], res["reps"], m["date"][:10]),
                 fontsize=10)
    fig.tight_layout()
    os.makedirs(os.path.dirname(png), exist_ok=True)
    fig.savefig(png, dpi=90)
    print("wrote", png)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("json", nargs="?", default=os.path.join(RESULTS, "side_by_side.json"))
    ap.add_argument("--png", default=os.path.join(RESULTS, "side_by_side.png"))
    ap.add_argument("--run1e10", default=os.path.join(RESULTS, "run_1e10.json"))
    ap.add_argument("--cache", default=os.path.join(RESULTS, "cache.json"))
    ap.add_argument("--readme", default=os.path.join(ROOT, "bench", "README.md"))
    ap.add_argument("--no-readme", action="store_true")
    ap.add_argument("--tables-only", action="store_true")
    a = ap.parse_args()
    res = load(a.json)
    run = load(a.run1e10)
    if not a.tables_only:
        plot(res, run, a.png)
    if a.no_readme:
        return
    with open(a.readme) as f:
        text = f.read()
    if res:
        text = replace_block(text, "side-by-side", table_side_by_side(res))
        text = replace_block(text, "store-target", table_store_target(res))
        text = replace_block(text, "targets", table_targets(res))
    text = replace_block(text, "run-1e10", table_1e10(run))
    text = replace_block(text, "cache", table_cache(load(a.cache)))
    text = replace_block(text, "box-query", table_box_query(load(os.path.join(RESULTS, "box_query.json"))))
    text = replace_block(text, "locate", table_locate(load(os.path.join(RESULTS, "locate.json"))))
    text = replace_block(text, "mpi", table_mpi(load(os.path.join(RESULTS, "mpi.json"))))
    text = replace_block(text, "project-ranks", table_project(load(os.path.join(RESULTS, "project_ranks.json"))))
    with open(a.readme, "w") as f:
        f.write(text)
    print("updated", a.readme)


if __name__ == "__main__":
    main()
