// dicer sheets: the dicer sheets of a coarse mesh and the interval each would get.
#include <cstdio>

#include "command.hpp"
#include "common.hpp"
#include "dicer/coarse_mesh.hpp"
#include "dicer/intervals.hpp"
#include "dicer/sheets.hpp"
#include "dicer/topology.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "sheets", "sheets MESH [--json] [--edges] [--quiet] [interval options]",
    R"(A dicer sheet is a set of coarse edges that must all be cut into the same
number of intervals, so that the fine mesh stays conforming: opposite edges
of every quad face are in the same sheet. A structured a x b x c box has
a+b+c sheets. Sheet ids depend only on the input file, so you can name them
in --sheet-interval or an intervals file.

Prints per sheet: id, number of edges, blocks it touches, the interval it
gets under the interval options (the same as `dice`'s) and its grading:
"-" (equal spacing), R@V (a geometric series of ratio R starting at file
node V) or "dual R". A bias's direction crosses the sheet from face to
face; a sheet that closes on itself reversed (a Moebius-like ring) takes
only a dual bias. To grade toward a wall, bias the sheet whose edges cross
it, starting at a node on the wall (--edges lists each sheet's edges).
)",
    R"(dicer sheets part.exo
dicer sheets part.exo --block-interval 2=4 --json --edges
dicer sheets part.exo --sheet-interval 3=12 --sheet-bias 3=1.2@17
dicer sheets part.msh --entity-interval 2:5=8 --sheet-dual-bias 1=first:0.01
)"};

int cmd_sheets(const std::vector<std::string>& argv) {
  Command cmd(kDoc);
  std::string path;
  bool json = false, edges = false;
  cmd.input("MESH", path, "the coarse mesh (Exodus II or Gmsh MSH)");
  cmd.flag("--json", json,
           "one JSON object: {\"mode\", \"sheets\": [{\"id\", \"edge_count\", "
           "\"blocks\", \"interval\", \"grading\" (null or {\"kind\", "
           "\"ratio\", \"start\"}), \"edges\"?}], \"notes\"}");
  cmd.flag("--edges", edges,
           "also list each sheet's edges as node-id pairs, numbered "
           "as in the input file");
  IntervalFlags intervals(cmd);
  cmd.quiet_accepted();
  if (!cmd.parse(argv)) return 0;
  const CoarseMesh mesh = read_coarse_mesh(path);
  const auto topo_kept = topology_of(mesh);
  const Topology& topo = *topo_kept;
  const Sheets sheets = find_sheets(mesh, topo);
  const IntervalPlan plan = resolve_intervals(mesh, topo, sheets, intervals.request());
  for (const auto& w : mesh.warnings)
    std::fprintf(stderr, "dicer sheets: warning: %s: %s\n", printable(mesh.source).c_str(), printable(w).c_str());
  for (const auto& n : plan.notes) std::fprintf(stderr, "dicer sheets: note: %s\n", printable(n).c_str());

  std::vector<std::vector<Id>> sheet_edges;
  if (edges) {
    sheet_edges.resize(static_cast<size_t>(sheets.num_sheets()));
    for (Id e = 0; e < topo.num_edges(); ++e) sheet_edges[sheets.edge_sheet[e]].push_back(e);
  }
  auto file_id = [&](Id e, int end) { return mesh.vertex_file_id[topo.edge_v[2 * e + end]]; };
  auto start_id = [&](Id s) { return plan.sheet_start[s] < 0 ? Id{-1} : mesh.vertex_file_id[plan.sheet_start[s]]; };
  auto blocks_of = [&](Id s) {
    std::vector<Id> ids;
    for (Id i = sheets.block_offset[s]; i < sheets.block_offset[s + 1]; ++i) ids.push_back(mesh.blocks[sheets.block_index[i]].id);
    return ids;
  };
  if (json) {
    // One sheet at a time: the edges of a big mesh as one JSON tree would
    // cost ~100 B each.
    std::printf("{\"mode\":%s,\"sheets\":[", json_text(mode_name(mesh.mode)).c_str());
    for (Id s = 0; s < sheets.num_sheets(); ++s) {
      Json j = {{"id", s},
                {"edge_count", sheets.edge_count[s]},
                {"blocks", blocks_of(s)},
                {"interval", plan.sheet_interval[s]},
                {"grading", grading_json(plan.sheet_grading[s], start_id(s))}};
      if (edges) {
        Json list = Json::array();
        for (Id e : sheet_edges[s]) list.push_back({file_id(e, 0), file_id(e, 1)});
        j["edges"] = std::move(list);
      }
      std::printf("%s%s", s ? "," : "", json_text(j).c_str());
    }
    std::printf("],\"notes\":%s}\n", json_text(plan.notes).c_str());
    return 0;
  }
  std::printf("%lld sheets in %s\n%8s %8s %8s %16s  %s\n", static_cast<long long>(sheets.num_sheets()),
              printable(mesh.source).c_str(), "sheet", "edges", "interval", "bias", "blocks");
  for (Id s = 0; s < sheets.num_sheets(); ++s) {
    std::string blocks;
    for (Id b : blocks_of(s)) blocks += (blocks.empty() ? "" : " ") + std::to_string(b);
    std::printf("%8lld %8lld %8lld %16s  %s\n", static_cast<long long>(s), static_cast<long long>(sheets.edge_count[s]),
                static_cast<long long>(plan.sheet_interval[s]),
                grading_text(plan.sheet_grading[s], start_id(s)).c_str(), blocks.c_str());
    if (edges) {
      std::printf("         edges:");
      for (Id e : sheet_edges[s]) std::printf(" %lld-%lld", static_cast<long long>(file_id(e, 0)), static_cast<long long>(file_id(e, 1)));
      std::printf("\n");
    }
  }
  return 0;
}

}  // namespace dicer::cli
