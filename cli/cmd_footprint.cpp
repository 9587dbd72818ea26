// dicer footprint: store bytes vs an explicit mesh of the same fine mesh.
#include <algorithm>
#include <cstdio>

#include "command.hpp"
#include "common.hpp"
#include "dicer/footprint.hpp"
#include "dicer/store.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "footprint", "footprint STORE [--json] [--exact] [--quiet] [store options]",
    R"(What the diced mesh costs, side by side with the same fine mesh stored
explicitly (float64 x,y,z per node + int64 node ids per element, as an
explicit HDF5 or Exodus file holds it):

  store on disk        bytes of STORE (bounding arrays: the moved nodes of
                       a store diced against CAD or from a second-order
                       mesh; everything else)
  resident to open     metadata + pages read when opening
  resident to query    plus one pinned page per table (what a block fill needs)
  explicit, raw        24 B per node + 8 B per element corner
  explicit, LZ4        the same compressed in 64 KiB LZ4 pages; by default
                       measured on at most 2048 evenly spaced pages of each
                       kind and extrapolated (--exact: every page)
and the ratios explicit / store.
)",
    R"(dicer footprint sphere.dice.h5
dicer footprint sphere.dice.h5 --exact --json
)"};

int cmd_footprint(const std::vector<std::string>& argv) {
  Command cmd(kDoc);
  std::string path;
  bool json = false, exact = false;
  cmd.input("STORE", path, "the store to measure");
  cmd.flag("--json", json,
           "one JSON object: store_bytes, open_resident_bytes, "
           "query_resident_bytes, bounding_bytes, explicit_raw_bytes, "
           "explicit_lz4_bytes, lz4_sampled_fraction, ratio_raw, "
           "ratio_lz4, fine_nodes, fine_elements, bounding_nodes, "
           "rest_bytes");
  cmd.flag("--exact", exact, "compress every page of the explicit mesh, not a sample");
  cmd.quiet_accepted();
  StoreFlags store(cmd);
  if (!cmd.parse(argv)) return 0;
  const FineMesh m = read_store(path, store.options());
  const StoreSummary s = store_summary(path);
  Footprint fp = measure_footprint(m, s.file_bytes, exact ? 0 : 2048);
  fp.bounding_bytes = s.bounding_bytes;
  const double rr = static_cast<double>(fp.explicit_raw_bytes) / static_cast<double>(fp.store_bytes);
  const double rl = static_cast<double>(fp.explicit_lz4_bytes) / static_cast<double>(fp.store_bytes);
  if (json) {
    print_json({{"store_bytes", fp.store_bytes},
                {"open_resident_bytes", fp.open_resident_bytes},
                {"query_resident_bytes", fp.query_resident_bytes},
                {"bounding_bytes", fp.bounding_bytes},
                {"explicit_raw_bytes", fp.explicit_raw_bytes},
                {"explicit_lz4_bytes", fp.explicit_lz4_bytes},
                {"lz4_sampled_fraction", fp.lz4_sampled_fraction},
                {"ratio_raw", rr},
                {"ratio_lz4", rl},
                {"fine_nodes", m.num_nodes()},
                {"fine_elements", m.num_elements()},
                {"bounding_nodes", s.bounding_nodes},
                {"rest_bytes", fp.store_bytes - std::min(fp.store_bytes, fp.bounding_bytes)}});
    store.report(m);
    return 0;
  }
  const double ne = static_cast<double>(m.num_elements());
  std::printf("footprint of %s (%s fine nodes, %s fine elements)\n", printable(path).c_str(), human_count(m.num_nodes()).c_str(),
              human_count(m.num_elements()).c_str());
  std::printf("  %-22s %12s %14s\n", "", "bytes", "per fine elem");
  auto row = [&](const char* what, std::uint64_t b) {
    std::printf("  %-22s %12s %14.4f\n", what, human_bytes(b).c_str(), static_cast<double>(b) / ne);
  };
  row("store on disk", fp.store_bytes);
  row("  bounding arrays", fp.bounding_bytes);
  row("  everything else", fp.store_bytes - std::min(fp.store_bytes, fp.bounding_bytes));
  if (s.bounding_nodes > 0)
    std::printf("  %-22s %12s   (%.2f B per moved node, raw float64 24 B)\n", "  moved fine nodes",
                human_count(s.bounding_nodes).c_str(), static_cast<double>(fp.bounding_bytes) / static_cast<double>(s.bounding_nodes));
  row("resident to open", fp.open_resident_bytes);
  row("resident to query", fp.query_resident_bytes);
  row("explicit, raw", fp.explicit_raw_bytes);
  row("explicit, LZ4", fp.explicit_lz4_bytes);
  std::printf("  explicit raw / store = %.1fx, explicit LZ4 / store = %.1fx%s\n", rr, rl,
              fp.lz4_sampled_fraction < 1 ? " (LZ4 size extrapolated from a sample; --exact to measure all)" : "");
  store.report(m);
  return 0;
}

}  // namespace dicer::cli
