// dicer query: fine nodes and elements by id.
#include <cstdio>

#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/store.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const char* kHelp = R"(Usage: dicer query STORE (--node ID | --nodes FIRST:END |
                           --element ID | --elements FIRST:END |
                           --box x0,y0,z0,x1,y1,z1 [--count]) [--json]

Regenerates fine nodes or elements by id; ids start at 0. Ranges are
half-open: --nodes 1000:2000 prints ids 1000..1999, one line each.

Node ids: coarse vertices first, then the interior nodes of each coarse
edge, face and hex. Element ids: coarse element order, then i, j, k.

  --json   one JSON object per line:
           node:    {"id":…, "xyz":[x,y,z]}   (shortest exact form)
           element: {"id":…, "nodes":[8 ids], "block":…, "coarse_element":…,
                     "ijk":[i,j,k]}   (VTK/Exodus HEX8 node order; surface
                     meshes: 4 node ids and [i,j]); block is the block id
  --box B        the ids of the fine elements whose centroid lies in the
                 axis-aligned box B (one per line, or {"id":…}); coarse
                 elements whose bounding box misses B are skipped unread
  --count        with --box: only the number of such elements
  --cache-mb N   page cache budget in MiB (default 64)
  --stats        print the page cache counters to stderr
)";

int cmd_query(const std::vector<std::string>& argv) {
  for (const auto& a : argv)
    if (a == "--help" || a == "-h") return std::fputs(kHelp, stdout), 0;
  std::vector<std::string> vflags = {"--node", "--nodes", "--element", "--elements", "--box"};
  vflags.insert(vflags.end(), kStoreFlags.begin(), kStoreFlags.end());
  Args args("query", argv, vflags, {"--json", "--stats", "--count"}, 1);
  const std::string path = args.need_positional(0, "STORE");
  int chosen = args.has("--node") + args.has("--nodes") + args.has("--element") + args.has("--elements") + args.has("--box");
  if (chosen != 1)
    throw Error(ErrorKind::Usage, "give exactly one of --node, --nodes, --element, --elements, --box");
  if (args.has("--count") && !args.has("--box")) throw Error(ErrorKind::Usage, "--count goes with --box");
  const FineMesh m = read_store(path, store_options(args));
  if (args.has("--box")) {
    const Box box = parse_box(*args.value("--box"));
    const bool count_only = args.has("--count"), json = args.has("--json");
    const Id n = for_each_in_box(m, box, [&](const FineBlock& b, Id e) {
      if (count_only) return;
      const long long id = static_cast<long long>(b.first_element + e);
      if (json) print_json({{"id", id}});
      else std::printf("%lld\n", id);
    });
    if (count_only) {
      if (json) print_json({{"count", n}});
      else std::printf("%lld\n", static_cast<long long>(n));
    }
    if (args.has("--stats")) print_cache_stats(m, "query");
    return 0;
  }
  const bool json = args.has("--json");
  auto ll = [](Id v) { return static_cast<long long>(v); };
  if (args.has("--node") || args.has("--nodes")) {
    const auto [a, b] = args.has("--node") ? parse_range("--node", *args.value("--node"))
                                           : parse_range("--nodes", *args.value("--nodes"));
    if (a < 0 || b > m.num_nodes())
      throw Error(ErrorKind::Usage, "node ids " + std::to_string(a) + ".." + std::to_string(b - 1) +
                                        " out of range (the mesh has " + std::to_string(m.num_nodes()) + " nodes, ids 0.." +
                                        std::to_string(m.num_nodes() - 1) + ")");
    NodeCursor cur(m, a, b);
    Id id;
    Vec3 p;
    while (cur.next(id, p)) {
      if (json)
        print_json({{"id", id}, {"xyz", {p.x, p.y, p.z}}});
      else
        std::printf("node %lld  %.17g %.17g %.17g\n", ll(id), p.x, p.y, p.z);
    }
    if (args.has("--stats")) print_cache_stats(m, "query");
    return 0;
  }
  const auto [a, b] = args.has("--element") ? parse_range("--element", *args.value("--element"))
                                            : parse_range("--elements", *args.value("--elements"));
  if (a < 0 || b > m.num_elements())
    throw Error(ErrorKind::Usage, "element ids " + std::to_string(a) + ".." + std::to_string(b - 1) +
                                      " out of range (the mesh has " + std::to_string(m.num_elements()) +
                                      " elements, ids 0.." + std::to_string(m.num_elements() - 1) + ")");
  ElementCursor cur(m, a, b);
  FineElement el;
  const bool vol = m.mode() == Mode::Volume;
  while (cur.next(el)) {
    const Id block = m.info().blocks.at(static_cast<size_t>(el.block)).id;
    if (json) {
      Json nodes_json = Json::array(), ijk = Json::array();
      for (int q = 0; q < el.num_nodes; ++q) nodes_json.push_back(el.nodes[q]);
      for (int d = 0; d < (vol ? 3 : 2); ++d) ijk.push_back(el.ijk[d]);
      print_json({{"id", el.id}, {"nodes", nodes_json}, {"block", block}, {"coarse_element", el.coarse_element}, {"ijk", ijk}});
    } else {
      std::string nodes_text;
      for (int q = 0; q < el.num_nodes; ++q) nodes_text += (q ? "," : "") + std::to_string(el.nodes[q]);
      std::string ijk = std::to_string(el.ijk[0]) + "," + std::to_string(el.ijk[1]);
      if (vol) ijk += "," + std::to_string(el.ijk[2]);
      std::printf("element %lld  nodes %s  block %lld  coarse element %lld  ijk %s\n", ll(el.id), nodes_text.c_str(),
                  ll(block), ll(el.coarse_element), ijk.c_str());
    }
  }
  if (args.has("--stats")) print_cache_stats(m, "query");
  return 0;
}

}  // namespace dicer::cli
