// dicer info: counts, blocks and settings of a store.
#include <cstdio>

#include "common.hpp"
#include "json_out.hpp"
#include "dicer/store.hpp"

namespace dicer::cli {

static const char* kHelp = R"(Usage: dicer info STORE [--json] [--stats] [--cache-mb N]

Prints what a store holds: mode (volume or surface), coarse counts
(vertices, edges, faces, elements), number of sheets, fine node and element
counts, and per block its id, name, coarse and fine element counts.

  --json   one JSON object with keys mode, coarse_vertices, coarse_edges,
           coarse_faces, coarse_elements, sheets, fine_nodes, fine_elements,
           blocks [{id, name, coarse_elements, fine_elements}],
           format_version, store_bytes, source
  --cache-mb N   page cache budget in MiB (default 64)
  --stats        print the page cache counters to stderr
)";

int cmd_info(const std::vector<std::string>& argv) {
  for (const auto& a : argv)
    if (a == "--help" || a == "-h") return std::fputs(kHelp, stdout), 0;
  Args args("info", argv, kStoreFlags, {"--json", "--stats"}, 1);
  const std::string path = args.need_positional(0, "STORE");
  const FineMesh m = read_store(path, store_options(args));
  const StoreSummary s = store_summary(path);
  const MeshInfo& c = m.info();
  const std::vector<Id>& coarse_per_block = c.block_coarse_elements;
  const std::vector<Id>& fine_per_block = c.block_fine_elements;
  auto ll = [](Id v) { return static_cast<long long>(v); };
  if (args.has("--json")) {
    Json blocks = Json::array();
    for (size_t b = 0; b < c.blocks.size(); ++b)
      blocks.push_back({{"id", c.blocks[b].id},
                        {"name", c.blocks[b].name},
                        {"coarse_elements", coarse_per_block[b]},
                        {"fine_elements", fine_per_block[b]}});
    print_json({{"mode", mode_name(m.mode())},
                {"source", c.source},
                {"format_version", s.format_version},
                {"store_bytes", s.file_bytes},
                {"coarse_vertices", c.coarse_vertices},
                {"coarse_edges", c.coarse_edges},
                {"coarse_faces", c.coarse_faces},
                {"coarse_elements", c.coarse_elements},
                {"sheets", c.sheets},
                {"fine_nodes", m.num_nodes()},
                {"fine_elements", m.num_elements()},
                {"blocks", blocks}});
    return 0;
  }
  std::printf("store      %s (%s, format version %d)\n", path.c_str(), human_bytes(s.file_bytes).c_str(), s.format_version);
  std::printf("source     %s\nmode       %s\n", c.source.c_str(), mode_name(m.mode()));
  std::printf("coarse     %lld vertices, %lld edges, %lld faces, %lld %s\n", ll(c.coarse_vertices), ll(c.coarse_edges),
              ll(c.coarse_faces), ll(c.coarse_elements), m.mode() == Mode::Volume ? "hexes" : "quads");
  std::printf("sheets     %lld\n", ll(c.sheets));
  std::printf("fine       %lld nodes (%s), %lld elements (%s)\n", ll(m.num_nodes()), human_count(m.num_nodes()).c_str(),
              ll(m.num_elements()), human_count(m.num_elements()).c_str());
  std::printf("blocks     %8s %-20s %12s %16s\n", "id", "name", "coarse", "fine");
  for (size_t b = 0; b < c.blocks.size(); ++b)
    std::printf("           %8lld %-20s %12lld %16lld\n", ll(c.blocks[b].id), c.blocks[b].name.c_str(), ll(coarse_per_block[b]),
                ll(fine_per_block[b]));
  if (args.has("--stats")) print_cache_stats(m, "info");
  return 0;
}

}  // namespace dicer::cli
