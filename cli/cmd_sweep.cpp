// dicer sweep: every fine node and element, with a checksum.
#include <algorithm>
#include <cstdio>
#include <thread>

#include "command.hpp"
#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "sweep", "sweep STORE [--threads N] [--json] [--quiet] [store options]",
    R"(Regenerates every fine node and element through the public iterators, in
N threads, each on a contiguous range of ids, and prints the counts, the
time, the rate and an order-independent checksum of all coordinates (bit
patterns) and connectivity. The checksum does not depend on the thread
count or the cache budget: compare it across machines or stores.
)",
    R"(dicer sweep sphere.dice.h5
dicer sweep big.dice.h5 --threads 2 --cache-mb 32 --json --stats
)"};

int cmd_sweep(const std::vector<std::string>& argv) {
  Command cmd(kDoc);
  std::string path, threads_text = std::to_string(std::max(1u, std::thread::hardware_concurrency()));
  bool json = false, quiet = false;
  cmd.input("STORE", path, "the store to sweep");
  cmd.value("--threads", threads_text, "N",
            "threads to use (1 to 1024); no more than the cache budget "
            "can keep pinned (about 2.5 MiB each) are used, and the "
            "output says how many ran",
            "Options", "all cores, here " + threads_text);
  cmd.flag("--json", json,
           "one JSON object: nodes, elements, seconds, nodes_per_s, "
           "checksum (16 hex digits), threads");
  cmd.flag("--quiet", quiet, "no progress bar (--json draws none either)");
  StoreFlags store(cmd);
  if (!cmd.parse(argv)) return 0;
  const Id threads = parse_int("--threads", threads_text);
  if (threads < 1 || threads > 1024) throw Error(ErrorKind::Usage, "--threads: must be between 1 and 1024");
  const FineMesh m = read_store(path, store.options());
  SweepResult r;
  {
    Progress bar("sweep", m.num_nodes() + m.num_elements(), quiet || json);
    r = sweep(m, static_cast<unsigned>(threads), [&](Id done, Id) { bar.update(done); });
  }
  const double rate = r.seconds > 0 ? static_cast<double>(r.nodes) / r.seconds : 0;
  char checksum[24];
  std::snprintf(checksum, sizeof checksum, "%016llx", static_cast<unsigned long long>(r.checksum));
  if (json)
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
  store.report(m);
  return 0;
}

}  // namespace dicer::cli
