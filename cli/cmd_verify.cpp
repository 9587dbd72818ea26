// dicer verify: the streaming conformity, count and quality check.
#include <cstdio>
#include <optional>

#include "command.hpp"
#include "common.hpp"
#include "exit_codes.hpp"
#include "json_out.hpp"
#include "dicer/geometry.hpp"
#include "dicer/store.hpp"
#include "dicer/verify.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "verify", "verify STORE [--geometry CAD] [--json] [--quiet] [store options]",
    R"(Regenerates every fine element, one coarse element at a time (memory stays
proportional to the coarse mesh), and checks:
  - node and element counts against the closed formula;
  - every node id round-trips id -> owning coarse entity -> id, and node(id)
    equals the block's value bit for bit;
  - every interior fine face is shared by exactly two fine elements, every
    boundary one by one; neighbours agree on shared coarse faces and edges;
    fine boundary faces cover the coarse boundary exactly once;
  - no two distinct node ids have the same coordinates;
  - minimum scaled Jacobian; number of inverted fine elements;
  - the tables the elements do not read: each edge's interval and grading
    are its sheet's, side and node sets name elements, sides and vertices
    of the mesh and no set id twice (a failure here is exit 8, naming the
    table and row).
With --geometry CAD (the STEP/BREP file the store was diced against), also:
  - the largest distance from a fine node on a CAD curve or surface (as the
    store records its owner) to that entity; it must be at most
    max(1e-9 x the model's bounding-box diagonal, 1e-7), 1e-7 being
    OpenCASCADE's own point-confusion tolerance (Precision::Confusion);
    the nodes of boundary faces the store puts on no surface (diced
    without --geometry) count with their distance to the nearest surface.
Exit status 0 only if everything holds, 1 if a check fails.
)",
    R"(dicer verify sphere.dice.h5
dicer verify part.dice.h5 --geometry part.step --json
)"};

namespace {
int report(const std::string& path, bool with_cad, const std::string& cad, bool json, bool quiet, const FineMesh& m,
           const VerifyReport& r);
}  // namespace

int cmd_verify(const std::vector<std::string>& argv) {
  Command cmd(kDoc);
  std::string path, cad;
  bool json = false, quiet = false;
  cmd.input("STORE", path, "the store to check");
  auto* o_cad = cmd.input_value("--geometry", cad, "CAD",
                                "distance-to-CAD check (runs in dicer-cad, with Gmsh; "
                                "plain verify does not need it)");
  cmd.flag("--json", json,
           "the report as one JSON object: ok, nodes, nodes_formula, "
           "elements, elements_formula, fine_faces_checked, "
           "boundary_fine_faces, id_errors, bit_identity_errors, "
           "coincident_nodes, coincident_interface, near_coincident, "
           "coincident_coarse_vertices, misoriented, conformity_errors, "
           "inverted, index_errors, min_scaled_jacobian, problems [text], "
           "warnings [text], and with --geometry "
           "geometry {max_distance, tolerance, diagonal, worst_node, "
           "worst_entity, nodes_checked, unplaced_faces}");
  cmd.flag("--quiet", quiet, "no progress bar");
  StoreFlags store(cmd);
  // Under mpirun every rank checks its chunk; rank 0 merges, matches the
  // faces and edges across ranks, finishes and prints.
  mpi::Session& mpi = session();
  std::optional<FineMesh> mesh;
  bool run = true;
  agree([&] {
    run = cmd.parse(argv);
    if (run) {
      mesh.emplace(read_store(path, store.options()));
      read_store_sets(*mesh, path);  // checks every member (Corrupt); exporters read them
    }
  });
  if (!run) return 0;
  check_same_store(path, mesh->info().uuid);
  const FineMesh& m = *mesh;
  VerifyReport r;
  if (mpi.active()) {
    Progress bar("verify", m.num_coarse_elements() / mpi.size() + 1, quiet || mpi.rank() > 0);
    r = mpi::verify_distributed(mpi.comm(), m, [&](Id done, Id) { bar.update(done); });
  } else {
    Progress bar("verify", m.num_coarse_elements(), quiet);
    r = verify(m, [&](Id done, Id) { bar.update(done); });
  }
  int code = 0;
  agree([&] { code = mpi.rank() == 0 ? report(path, cmd.given(o_cad), cad, json, quiet, m, r) : 0; });
  if (mpi.active()) MPI_Bcast(&code, 1, MPI_INT, 0, mpi.comm());
  store.report(m);  // every rank its own counters, as --stats says
  return code;
}

namespace {

int report(const std::string& path, bool with_cad, const std::string& cad, bool json, bool quiet, const FineMesh& m,
           const VerifyReport& r) {
  GeometryCheck g;
  bool geo_ok = true;
  if (with_cad) {
    Progress bar("verify: geometry", 1, quiet);
    g = check_geometry(m, cad, [&](Id done, Id total) { bar.update(done, total); });
    warn_cad_reader("verify", cad, g.cad_reader_said);
    geo_ok = g.ok();
  }
  const bool ok = r.ok() && geo_ok;
  auto ll = [](Id v) { return static_cast<long long>(v); };
  if (json) {
    Json j = {{"ok", ok},
              {"nodes", r.nodes},
              {"nodes_formula", r.nodes_formula},
              {"elements", r.elements},
              {"elements_formula", r.elements_formula},
              {"fine_faces_checked", r.fine_faces_checked},
              {"boundary_fine_faces", r.boundary_fine_faces},
              {"id_errors", r.id_errors},
              {"bit_identity_errors", r.bit_identity_errors},
              {"coincident_nodes", r.coincident_nodes},
              {"coincident_interface", r.coincident_interface},
              {"near_coincident", r.near_coincident},
              {"coincident_coarse_vertices", r.coincident_coarse_vertices},
              {"misoriented", r.misoriented},
              {"conformity_errors", r.conformity_errors},
              {"inverted", r.inverted},
              {"index_errors", r.index_errors},
              {"min_scaled_jacobian", r.min_scaled_jacobian},
              {"problems", r.problems},
              {"warnings", r.warnings}};
    if (with_cad)
      j["geometry"] = {{"max_distance", g.max_distance}, {"tolerance", g.tolerance}, {"diagonal", g.diagonal},
                       {"worst_node", g.worst_node},     {"worst_entity", g.worst_entity}, {"nodes_checked", g.nodes_checked},
                       {"unplaced_faces", g.unplaced_faces}};
    print_json(j);
  } else {
    auto mark = [](bool ok) { return ok ? "ok  " : "FAIL"; };
    std::printf("verify %s\n", printable(path).c_str());
    std::printf("  %s counts         %lld nodes, %lld elements (formula: %lld, %lld)\n", mark(r.counts_ok()), ll(r.nodes),
                ll(r.elements), ll(r.nodes_formula), ll(r.elements_formula));
    std::printf("  %s numbering      %lld id errors, %lld bit-identity errors\n", mark(r.id_errors + r.bit_identity_errors == 0),
                ll(r.id_errors), ll(r.bit_identity_errors));
    const bool surface = m.mode() == Mode::Surface;
    std::printf("  %s conformity     %lld fine %s checked, %lld on the boundary, %lld mismatches%s\n",
                mark(r.conformity_errors == 0 && r.misoriented == 0), ll(r.fine_faces_checked),
                surface ? "edges" : "faces", ll(r.boundary_fine_faces), ll(r.conformity_errors),
                r.misoriented ? (", " + std::to_string(r.misoriented) + " misoriented coarse edges").c_str() : "");
    std::printf("  %s distinct nodes %lld coincident (%lld on an interface of %lld coincident coarse vertices), "
                "%lld within 1e-9 of the diagonal\n",
                mark(r.coincident_nodes == r.coincident_interface), ll(r.coincident_nodes), ll(r.coincident_interface),
                ll(r.coincident_coarse_vertices), ll(r.near_coincident));
    std::printf("  %s quality        min scaled Jacobian %.4f, %lld inverted\n", mark(r.inverted == 0), r.min_scaled_jacobian,
                ll(r.inverted));
    std::printf("  %s index          %lld errors (element and group bounds, neighbours)\n", mark(r.index_errors == 0),
                ll(r.index_errors));
    if (with_cad)
      std::printf("  %s geometry       max distance to the CAD %.3g (node %lld on %s; limit %.3g, %.3g of the diagonal), "
                  "%lld nodes checked\n",
                  mark(geo_ok), g.max_distance, ll(g.worst_node), g.worst_entity.empty() ? "-" : g.worst_entity.c_str(),
                  g.tolerance, g.diagonal > 0 ? g.max_distance / g.diagonal : 0.0, ll(g.nodes_checked));
    if (with_cad && g.nodes_checked == 0)
      std::printf("    no node of the store was measured: none is on a CAD curve or surface%s (dice with --geometry %s)\n",
                  g.unplaced_faces > 0 ? ", and its unplaced boundary faces have no interior nodes" : "", printable(cad).c_str());
    else if (with_cad && g.unplaced_faces > 0)
      std::printf("    %lld boundary coarse faces are on no CAD surface in the store (diced without --geometry): "
                  "their nodes measured against the nearest surface%s\n",
                  ll(g.unplaced_faces), geo_ok ? "" : "; dice with --geometry to put them on it");
    for (const auto& p : r.problems) std::printf("    %s\n", printable(p).c_str());
    for (const auto& w : r.warnings) std::printf("    warning: %s\n", printable(w).c_str());
    std::printf("%s\n", ok ? "all checks passed" : "VERIFY FAILED");
  }
  (void)quiet;
  return ok ? 0 : kExitDefect;
}

}  // namespace

}  // namespace dicer::cli
