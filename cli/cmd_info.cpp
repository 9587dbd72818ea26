// dicer info: counts, blocks and settings of a store.
#include <cstdio>

#include "command.hpp"
#include "common.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "info", "info STORE [--json] [--quiet] [store options]",
    R"(Prints what a store holds: mode (volume or surface), coarse counts
(vertices, edges, faces, elements), number of sheets, fine node and element
counts, and per block its id, name, coarse and fine element counts. Only a
few hundred bytes of metadata are read. The source's order is 2 when it
was a second-order mesh (HEX20/27, QUAD8/9): the fine mesh then follows
its quadratic edges and faces, unless a CAD model placed it (see dicer
dice --help).
)",
    R"(dicer info sphere.dice.h5
dicer info sphere.dice.h5 --json --stats
)"};

int cmd_info(const std::vector<std::string>& argv) {
  Command cmd(kDoc);
  std::string path;
  bool json = false;
  cmd.input("STORE", path, "the store to describe (.dice.h5, written by dicer dice)");
  cmd.flag("--json", json,
           "one JSON object with keys mode, source, source_order (1 or 2), geometry (the "
           "CAD file the boundary was put on, or null), format_version, "
           "store_bytes, coarse_vertices, coarse_edges, coarse_faces, "
           "coarse_elements, sheets, sheet_intervals (one per sheet, "
           "in dicer sheets' numbering), sheet_gradings (one per sheet: "
           "null, or {kind, ratio, start}), fine_nodes, fine_elements, "
           "blocks [{id, name, coarse_elements, fine_elements}]");
  cmd.quiet_accepted();
  StoreFlags store(cmd);
  if (!cmd.parse(argv)) return 0;

  const FineMesh m = read_store(path, store.options());
  const StoreSummary s = store_summary(path);
  const MeshInfo& c = m.info();
  const std::vector<Id>& coarse_per_block = c.block_coarse_elements;
  const std::vector<Id>& fine_per_block = c.block_fine_elements;
  auto ll = [](Id v) { return static_cast<long long>(v); };
  Json gradings = Json::array();
  std::string graded;
  for (size_t q = 0; q < m.sheet_gradings().size(); ++q) {
    const SheetGrading& g = m.sheet_gradings()[q];
    gradings.push_back(grading_json(g.grading, g.start));
    if (g.grading.kind != tfi::Spacing::Equal)
      graded += (graded.empty() ? "" : ", ") + std::to_string(q) + ": " + grading_text(g.grading, g.start);
  }
  if (json) {
    Json blocks = Json::array();
    for (size_t b = 0; b < c.blocks.size(); ++b)
      blocks.push_back({{"id", c.blocks[b].id},
                        {"name", c.blocks[b].name},
                        {"coarse_elements", coarse_per_block[b]},
                        {"fine_elements", fine_per_block[b]}});
    print_json({{"mode", mode_name(m.mode())},
                {"source", c.source},
                {"source_order", c.source_order},
                {"geometry", c.geometry.empty() ? Json(nullptr) : Json(c.geometry)},
                {"format_version", s.format_version},
                {"store_bytes", s.file_bytes},
                {"coarse_vertices", c.coarse_vertices},
                {"coarse_edges", c.coarse_edges},
                {"coarse_faces", c.coarse_faces},
                {"coarse_elements", c.coarse_elements},
                {"sheets", c.sheets},
                {"sheet_intervals", m.sheet_intervals()},
                {"sheet_gradings", gradings},
                {"fine_nodes", m.num_nodes()},
                {"fine_elements", m.num_elements()},
                {"blocks", blocks}});
  } else {
    std::printf("store      %s (%s, format version %d)\n", printable(path).c_str(), human_bytes(s.file_bytes).c_str(), s.format_version);
    std::printf("source     %s%s\nmode       %s\n", printable(c.source).c_str(),
                c.source_order == 2 ? " (second order: HEX20/27 or QUAD8/9)" : "", mode_name(m.mode()));
    if (!c.geometry.empty()) std::printf("geometry   %s (the CAD its boundary was put on)\n", printable(c.geometry).c_str());
    std::printf("coarse     %lld vertices, %lld edges, %lld faces, %lld %s\n", ll(c.coarse_vertices), ll(c.coarse_edges),
                ll(c.coarse_faces), ll(c.coarse_elements), m.mode() == Mode::Volume ? "hexes" : "quads");
    std::printf("sheets     %lld%s%s\n", ll(c.sheets), graded.empty() ? "" : "; graded (ratio@start node): ",
                graded.c_str());
    std::printf("fine       %lld nodes (%s), %lld elements (%s)\n", ll(m.num_nodes()), human_count(m.num_nodes()).c_str(),
                ll(m.num_elements()), human_count(m.num_elements()).c_str());
    std::printf("blocks     %8s %-20s %12s %16s\n", "id", "name", "coarse", "fine");
    for (size_t b = 0; b < c.blocks.size(); ++b)
      std::printf("           %8lld %-20s %12lld %16lld\n", ll(c.blocks[b].id), printable(c.blocks[b].name).c_str(),
                  ll(coarse_per_block[b]), ll(fine_per_block[b]));
  }
  store.report(m);
  return 0;
}

}  // namespace dicer::cli
