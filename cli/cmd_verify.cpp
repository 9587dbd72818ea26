// dicer verify: the streaming conformity, count and quality check.
#include <cstdio>

#include "common.hpp"
#include "exit_codes.hpp"
#include "dicer/geometry.hpp"
#include "dicer/store.hpp"
#include "dicer/verify.hpp"

namespace dicer::cli {

static const char* kHelp = R"(Usage: dicer verify STORE [--geometry CAD] [--json] [--quiet]

Regenerates every fine element, one coarse element at a time (memory stays
proportional to the coarse mesh), and checks:
  - node and element counts against the closed formula;
  - every node id round-trips id -> owning coarse entity -> id, and node(id)
    equals the block's value bit for bit;
  - every interior fine face is shared by exactly two fine elements, every
    boundary one by one; neighbours agree on shared coarse faces and edges;
    fine boundary faces cover the coarse boundary exactly once;
  - no two distinct node ids have the same coordinates;
  - minimum scaled Jacobian; number of inverted fine elements.
With --geometry CAD (the STEP/BREP file the store was diced against), also:
  - the largest distance from a fine node on a CAD curve or surface (as the
    store records its owner) to that entity; it must be at most
    max(1e-9 x the model's bounding-box diagonal, 1e-7), 1e-7 being
    OpenCASCADE's own point-confusion tolerance (Precision::Confusion).
Exit status 0 only if everything holds, 1 if a check fails.

  --geometry CAD  distance-to-CAD check (needs Gmsh; plain verify does not)
  --json    the report as one JSON object
  --quiet   no progress bar
  --cache-mb N   page cache budget in MiB (default 64)
  --stats        print the page cache counters to stderr
)";

int cmd_verify(const std::vector<std::string>& argv) {
  for (const auto& a : argv)
    if (a == "--help" || a == "-h") return std::fputs(kHelp, stdout), 0;
  std::vector<std::string> vflags = kStoreFlags;
  vflags.push_back("--geometry");
  Args args("verify", argv, vflags, {"--json", "--quiet", "--stats"}, 1);
  const std::string path = args.need_positional(0, "STORE");
  const FineMesh m = read_store(path, store_options(args));
  VerifyReport r;
  {
    Progress bar("verify", m.num_coarse_elements(), args.has("--quiet"));
    r = verify(m, [&](Id done, Id) { bar.update(done); });
  }
  const auto cad = args.value("--geometry");
  GeometryCheck g;
  bool geo_ok = true;
  if (cad) {
    Progress bar("verify: geometry", 1, args.has("--quiet"));
    g = check_geometry(m, *cad, [&](Id done, Id total) { bar.update(done, total); });
    geo_ok = g.max_distance <= g.tolerance;
  }
  const bool ok = r.ok() && geo_ok;
  auto ll = [](Id v) { return static_cast<long long>(v); };
  if (args.has("--json")) {
    std::printf("{\"ok\":%s,\"nodes\":%lld,\"nodes_formula\":%lld,\"elements\":%lld,\"elements_formula\":%lld,"
                "\"fine_faces_checked\":%lld,\"boundary_fine_faces\":%lld,\"id_errors\":%lld,\"bit_identity_errors\":%lld,"
                "\"coincident_nodes\":%lld,\"conformity_errors\":%lld,\"inverted\":%lld,\"min_scaled_jacobian\":%s,"
                "\"problems\":[",
                ok ? "true" : "false", ll(r.nodes), ll(r.nodes_formula), ll(r.elements), ll(r.elements_formula),
                ll(r.fine_faces_checked), ll(r.boundary_fine_faces), ll(r.id_errors), ll(r.bit_identity_errors),
                ll(r.coincident_nodes), ll(r.conformity_errors), ll(r.inverted), json_double(r.min_scaled_jacobian).c_str());
    for (size_t i = 0; i < r.problems.size(); ++i) std::printf("%s%s", i ? "," : "", json_string(r.problems[i]).c_str());
    std::printf("]");
    if (cad)
      std::printf(",\"geometry\":{\"max_distance\":%s,\"tolerance\":%s,\"diagonal\":%s,\"worst_node\":%lld,"
                  "\"worst_entity\":%s,\"nodes_checked\":%lld}",
                  json_double(g.max_distance).c_str(), json_double(g.tolerance).c_str(), json_double(g.diagonal).c_str(),
                  ll(g.worst_node), json_string(g.worst_entity).c_str(), ll(g.nodes_checked));
    std::printf("}\n");
  } else {
    auto mark = [](bool ok) { return ok ? "ok  " : "FAIL"; };
    std::printf("verify %s\n", path.c_str());
    std::printf("  %s counts         %lld nodes, %lld elements (formula: %lld, %lld)\n", mark(r.counts_ok()), ll(r.nodes),
                ll(r.elements), ll(r.nodes_formula), ll(r.elements_formula));
    std::printf("  %s numbering      %lld id errors, %lld bit-identity errors\n", mark(r.id_errors + r.bit_identity_errors == 0),
                ll(r.id_errors), ll(r.bit_identity_errors));
    std::printf("  %s conformity     %lld fine faces checked, %lld on the boundary, %lld mismatches\n",
                mark(r.conformity_errors == 0), ll(r.fine_faces_checked), ll(r.boundary_fine_faces), ll(r.conformity_errors));
    std::printf("  %s distinct nodes %lld coincident\n", mark(r.coincident_nodes == 0), ll(r.coincident_nodes));
    std::printf("  %s quality        min scaled Jacobian %.4f, %lld inverted\n", mark(r.inverted == 0), r.min_scaled_jacobian,
                ll(r.inverted));
    if (cad)
      std::printf("  %s geometry       max distance to the CAD %.3g (node %lld on %s; limit %.3g, %.3g of the diagonal), "
                  "%lld nodes checked\n",
                  mark(geo_ok), g.max_distance, ll(g.worst_node), g.worst_entity.empty() ? "-" : g.worst_entity.c_str(),
                  g.tolerance, g.diagonal > 0 ? g.max_distance / g.diagonal : 0.0, ll(g.nodes_checked));
    for (const auto& p : r.problems) std::printf("    %s\n", p.c_str());
    std::printf("%s\n", ok ? "all checks passed" : "VERIFY FAILED");
  }
  if (args.has("--stats")) print_cache_stats(m, "verify");
  return ok ? 0 : kExitDefect;
}

}  // namespace dicer::cli
