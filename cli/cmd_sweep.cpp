// dicer sweep: every fine node and element, with a checksum.
#include <cstdio>
#include <thread>

#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const char* kHelp = R"(Usage: dicer sweep STORE [--threads N] [--json] [--quiet] [--cache-mb N] [--stats]

Regenerates every fine node and element through the public iterators, in
N threads (default: all cores), each on a contiguous range of ids, and prints
the counts, the time, the rate and an order-independent checksum of all
coordinates (bit patterns) and connectivity. The checksum does not depend on
the thread count or the cache budget: compare it across machines or stores.

  --threads N  threads to use; no more than the cache budget can keep
               pinned (about 2.5 MiB each) are used, and the output says
               how many ran
  --json   {"nodes", "elements", "seconds", "nodes_per_s", "checksum", "threads"}
)";

int cmd_sweep(const std::vector<std::string>& argv) {
  for (const auto& a : argv)
    if (a == "--help" || a == "-h") return std::fputs(kHelp, stdout), 0;
  std::vector<std::string> vflags = {"--threads"};
  vflags.insert(vflags.end(), kStoreFlags.begin(), kStoreFlags.end());
  Args args("sweep", argv, vflags, {"--json", "--quiet", "--stats"}, 1);
  const std::string path = args.need_positional(0, "STORE");
  const Id threads = args.int_value("--threads", std::max(1u, std::thread::hardware_concurrency()));
  if (threads < 1 || threads > 1024) throw Error(ErrorKind::Usage, "--threads: must be between 1 and 1024");
  const FineMesh m = read_store(path, store_options(args));
  SweepResult r;
  {
    Progress bar("sweep", m.num_nodes() + m.num_elements(), args.has("--quiet") || args.has("--json"));
    r = sweep(m, static_cast<unsigned>(threads), [&](Id done, Id) { bar.update(done); });
  }
  const double rate = r.seconds > 0 ? static_cast<double>(r.nodes) / r.seconds : 0;
  char checksum[24];
  std::snprintf(checksum, sizeof checksum, "%016llx", static_cast<unsigned long long>(r.checksum));
  if (args.has("--json"))
    print_json({{"nodes", r.nodes},
                {"elements", r.elements},
                {"seconds", r.seconds},
                {"nodes_per_s", rate},
                {"checksum", checksum},
                {"threads", r.threads}});
  else
    std::printf("swept %s nodes and %s elements in %.3f s (%s nodes/s, %lld threads), checksum %s\n",
                human_count(r.nodes).c_str(), human_count(r.elements).c_str(), r.seconds,
                human_count(static_cast<Id>(rate)).c_str(), static_cast<long long>(r.threads), checksum);
  if (args.has("--stats")) print_cache_stats(m, "sweep");
  return 0;
}

}  // namespace dicer::cli
