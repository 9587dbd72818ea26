// dicer sweep: every fine node and element, with a checksum.
#include <algorithm>
#include <cstdio>
#include <optional>
#include <string>
#include <thread>

#include "command.hpp"
#include "common.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "json_out.hpp"

namespace dicer::cli {

static const CommandDoc kDoc = {
    "sweep", "sweep STORE [--threads N] [--json] [--quiet] [store options]",
    R"(Regenerates every fine node and element through the batch API (a slab of
one coarse element's grid at a time), on N threads that take chunks of
about equal work in turn, and prints the counts, the time, the rate and an
order-independent checksum of all coordinates (bit patterns) and
connectivity. The checksum does not depend on the thread count or the
cache budget: compare it across machines or stores.
)",
    R"(dicer sweep sphere.dice.h5
dicer sweep big.dice.h5 --threads 2 --cache-mb 32 --json --stats
)"};

namespace {

// Rank 0 gathers every rank's result and prints the whole sweep: counts and
// checksums add up (mod 2^64), the time is the slowest rank's.
int report_ranks(mpi::Session& mpi, const SweepResult& r, const FineMesh& m, bool json, const StoreFlags& store) {
  const int P = mpi.size();
  const std::uint64_t mine[4] = {r.checksum, static_cast<std::uint64_t>(r.nodes), static_cast<std::uint64_t>(r.elements),
                                 static_cast<std::uint64_t>(r.threads)};
  double secs = r.seconds;
  CacheStats st;
  if (auto c = store_cache(m)) st = c->stats();
  const std::uint64_t pages[2] = {st.pages_read, st.distinct_pages_read};
  std::vector<std::uint64_t> all(4 * static_cast<size_t>(P)), all_pages(2 * static_cast<size_t>(P));
  std::vector<double> all_secs(static_cast<size_t>(P));
  MPI_Gather(mine, 4, MPI_UINT64_T, all.data(), 4, MPI_UINT64_T, 0, mpi.comm());
  MPI_Gather(&secs, 1, MPI_DOUBLE, all_secs.data(), 1, MPI_DOUBLE, 0, mpi.comm());
  MPI_Gather(pages, 2, MPI_UINT64_T, all_pages.data(), 2, MPI_UINT64_T, 0, mpi.comm());
  if (mpi.rank() != 0) return 0;
  std::uint64_t checksum = 0, nodes = 0, elements = 0, pages_read = 0;
  double slowest = 0, sum_secs = 0;
  Json rank_seconds = Json::array(), rank_pages = Json::array();
  for (int q = 0; q < P; ++q) {
    checksum += all[4 * q], nodes += all[4 * q + 1], elements += all[4 * q + 2];
    slowest = std::max(slowest, all_secs[q]), sum_secs += all_secs[q];
    rank_seconds.push_back(all_secs[q]);
    rank_pages.push_back(all_pages[2 * q]);
    pages_read += all_pages[2 * q];
  }
  const double imbalance = sum_secs > 0 ? slowest / (sum_secs / P) : 1.0;
  const double rate = slowest > 0 ? static_cast<double>(nodes) / slowest : 0;
  char hex[24];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(checksum));
  if (json)
    print_json({{"nodes", nodes},
                {"elements", elements},
                {"seconds", slowest},
                {"nodes_per_s", rate},
                {"checksum", hex},
                {"threads", all[3]},
                {"ranks", P},
                {"rank_seconds", rank_seconds},
                {"imbalance", imbalance},
                {"rank_pages_read", rank_pages}});
  else
    std::printf("swept %s nodes and %s elements in %.3f s on %d ranks (%s nodes/s; imbalance %.2f), checksum %s\n",
                human_count(static_cast<Id>(nodes)).c_str(), human_count(static_cast<Id>(elements)).c_str(), slowest, P,
                human_count(static_cast<Id>(rate)).c_str(), imbalance, hex);
  if (store.stats()) {
    // Pages near a chunk boundary are read by both ranks: the sum against
    // the single process's count is the read amplification of P ranks.
    std::string per;
    for (int q = 0; q < P; ++q) per += (q ? " " : "") + std::to_string(all_pages[2 * q]);
    std::fprintf(stderr, "dicer sweep: cache: pages read per rank: %s (sum %llu; compare `dicer sweep --stats` alone)\n",
                 per.c_str(), static_cast<unsigned long long>(pages_read));
  }
  return 0;
}

}  // namespace

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
           "checksum (16 hex digits), threads; under mpirun also ranks, "
           "rank_seconds [per rank], imbalance (slowest / mean), "
           "rank_pages_read [per rank]");
  cmd.flag("--quiet", quiet, "no progress bar (--json draws none either)");
  StoreFlags store(cmd);
  // Under mpirun: rank r sweeps chunk r of P (the nodes it owns and its
  // elements); rank 0 prints the sum of the checksums (the single
  // process's), per-rank times and the imbalance.
  mpi::Session& mpi = session();
  std::optional<FineMesh> mesh;
  Id threads = 1;
  ChunkRange range;
  bool run = true;
  agree([&] {
    run = cmd.parse(argv);
    if (!run) return;
    threads = parse_threads(threads_text);
    mesh.emplace(read_store(path, store.options()));
    if (mpi.active()) range = plan_chunks(*mesh, mpi.size())[static_cast<size_t>(mpi.rank())];
    else range = ChunkRange{0, 1, 0, mesh->num_coarse_elements(), mesh->num_elements()};
  });
  if (!run) return 0;
  check_same_store(path, mesh->info().uuid);
  const FineMesh& m = *mesh;
  SweepResult r;
  agree([&] {
    Progress bar("sweep", m.num_nodes() + m.num_elements(), quiet || json || mpi.rank() > 0);
    r = sweep(m, static_cast<unsigned>(threads), [&](Id done, Id) { bar.update(done); }, range.first_coarse,
              range.end_coarse);
  });
  if (mpi.active()) return report_ranks(mpi, r, m, json, store);
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
