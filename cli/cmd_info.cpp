// dicer info: counts, blocks and settings of a store.
#include <cstdio>

#include "common.hpp"
#include "dicer/store.hpp"

namespace dicer::cli {

static const char* kHelp = R"(Usage: dicer info STORE [--json]

Prints what a store holds: mode (volume or surface), coarse counts
(vertices, edges, faces, elements), number of sheets, fine node and element
counts, and per block its id, name, coarse and fine element counts.

  --json   one JSON object with keys mode, coarse_vertices, coarse_edges,
           coarse_faces, coarse_elements, sheets, fine_nodes, fine_elements,
           blocks [{id, name, coarse_elements, fine_elements}], side_sets,
           node_sets, format_version, store_bytes, source
)";

int cmd_info(const std::vector<std::string>& argv) {
  for (const auto& a : argv)
    if (a == "--help" || a == "-h") return std::fputs(kHelp, stdout), 0;
  Args args("info", argv, {}, {"--json"}, 1);
  const std::string path = args.need_positional(0, "STORE");
  const FineMesh m = read_store(path);
  const StoreSummary s = store_summary(path);
  const CoarseMesh& c = m.coarse();
  const Topology& t = m.topology();
  std::vector<Id> coarse_per_block(c.blocks.size(), 0);
  for (auto b : c.element_block) ++coarse_per_block[b];
  const std::vector<Id> fine_per_block = m.block_fine_elements();
  auto ll = [](Id v) { return static_cast<long long>(v); };
  if (args.has("--json")) {
    std::printf("{\"mode\":\"%s\",\"source\":%s,\"format_version\":%d,\"store_bytes\":%llu,", mode_name(m.mode()),
                json_string(c.source).c_str(), s.format_version, static_cast<unsigned long long>(s.file_bytes));
    std::printf("\"coarse_vertices\":%lld,\"coarse_edges\":%lld,\"coarse_faces\":%lld,\"coarse_elements\":%lld,", ll(c.num_vertices()),
                ll(t.num_edges()), ll(t.num_faces()), ll(t.num_elements()));
    std::printf("\"sheets\":%lld,\"fine_nodes\":%lld,\"fine_elements\":%lld,\"blocks\":[", ll(static_cast<Id>(m.sheet_intervals().size())),
                ll(m.num_nodes()), ll(m.num_elements()));
    for (size_t b = 0; b < c.blocks.size(); ++b)
      std::printf("%s{\"id\":%lld,\"name\":%s,\"coarse_elements\":%lld,\"fine_elements\":%lld}", b ? "," : "",
                  ll(c.blocks[b].id), json_string(c.blocks[b].name).c_str(), ll(coarse_per_block[b]), ll(fine_per_block[b]));
    std::printf("],\"side_sets\":[");
    for (size_t i = 0; i < c.side_sets.size(); ++i)
      std::printf("%s{\"id\":%lld,\"name\":%s,\"coarse_sides\":%lld}", i ? "," : "", ll(c.side_sets[i].id),
                  json_string(c.side_sets[i].name).c_str(), ll(static_cast<Id>(c.side_sets[i].element.size())));
    std::printf("],\"node_sets\":[");
    for (size_t i = 0; i < c.node_sets.size(); ++i)
      std::printf("%s{\"id\":%lld,\"name\":%s,\"coarse_nodes\":%lld}", i ? "," : "", ll(c.node_sets[i].id),
                  json_string(c.node_sets[i].name).c_str(), ll(static_cast<Id>(c.node_sets[i].vertex.size())));
    std::printf("]}\n");
    return 0;
  }
  std::printf("store      %s (%s, format version %d)\n", path.c_str(), human_bytes(s.file_bytes).c_str(), s.format_version);
  std::printf("source     %s\nmode       %s\n", c.source.c_str(), mode_name(m.mode()));
  std::printf("coarse     %lld vertices, %lld edges, %lld faces, %lld %s\n", ll(c.num_vertices()), ll(t.num_edges()),
              ll(t.num_faces()), ll(t.num_elements()), m.mode() == Mode::Volume ? "hexes" : "quads");
  std::printf("sheets     %lld\n", ll(static_cast<Id>(m.sheet_intervals().size())));
  std::printf("fine       %lld nodes (%s), %lld elements (%s)\n", ll(m.num_nodes()), human_count(m.num_nodes()).c_str(),
              ll(m.num_elements()), human_count(m.num_elements()).c_str());
  std::printf("blocks     %8s %-20s %12s %16s\n", "id", "name", "coarse", "fine");
  for (size_t b = 0; b < c.blocks.size(); ++b)
    std::printf("           %8lld %-20s %12lld %16lld\n", ll(c.blocks[b].id), c.blocks[b].name.c_str(), ll(coarse_per_block[b]),
                ll(fine_per_block[b]));
  return 0;
}

}  // namespace dicer::cli
