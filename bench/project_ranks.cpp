// Per-rank figures of a distributed run at rank counts this machine cannot
// start, from the real partition and real sweeps in one process (issue:
// distributed, item 6). Two parts:
//
//  1. Measured: for the largest P asked, a few ranks' chunks (first,
//     middle, last) are swept exactly as `mpirun -n P dicer sweep` would
//     sweep them on that rank: a fresh store open with the given cache
//     budget, sweep() over the chunk's coarse range. Per sample: elements,
//     seconds, pages and bytes read, cache peak, and the process's peak RSS
//     (this part runs first, so the RSS is one rank's).
//  2. Partition: for every P, plan_chunks + in_process_sharing +
//     partition_stats for every rank (what make_partition would compute on
//     P ranks): elements, owned/ghost/shared nodes, neighbours and
//     communication-map entries, mean and max over ranks.
//
//   project_ranks STORE [P ...] [--samples N] [--threads T] [--cache-mb M] [--json]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "dicer/export.hpp"
#include "dicer/partition.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"

using namespace dicer;

namespace {

struct Sample {
  Id P = 0, rank = 0, elements = 0, nodes = 0;
  double seconds = 0, open_seconds = 0;
  CacheStats cache;
};

template <class F>
void mean_max(const std::vector<PartitionStats>& s, F f, double& mean, double& max) {
  double sum = 0;
  max = 0;
  for (const auto& x : s) sum += static_cast<double>(f(x)), max = std::max(max, static_cast<double>(f(x)));
  mean = s.empty() ? 0 : sum / static_cast<double>(s.size());
}

}  // namespace

int main(int argc, char** argv) {
  std::string path;
  std::vector<Id> ranks;
  int samples = 3;
  unsigned threads = 1;
  std::uint64_t cache_mb = 64;
  bool json = false;
  for (int a = 1; a < argc; ++a) {
    const std::string s = argv[a];
    if (s == "--samples" && a + 1 < argc) samples = std::atoi(argv[++a]);
    else if (s == "--threads" && a + 1 < argc) threads = static_cast<unsigned>(std::atoi(argv[++a]));
    else if (s == "--cache-mb" && a + 1 < argc) cache_mb = std::strtoull(argv[++a], nullptr, 10);
    else if (s == "--json") json = true;
    else if (path.empty()) path = s;
    else ranks.push_back(std::atoll(s.c_str()));
  }
  if (path.empty() || samples < 0 || threads < 1) {
    std::fprintf(stderr, "usage: project_ranks STORE [P ...] [--samples N] [--threads T] [--cache-mb M] [--json]\n");
    return 2;
  }
  if (ranks.empty()) ranks = {1000, 2000, 5000, 10000};
  try {
    StoreOptions opt;
    opt.cache_bytes = cache_mb << 20;
    // Part 1: one rank's work, measured (before part 2 grows the heap).
    const Id Pmax = *std::max_element(ranks.begin(), ranks.end());
    std::vector<Sample> measured;
    {
      const FineMesh probe = read_store(path, opt);
      const auto plan = plan_chunks(probe, Pmax);
      std::vector<Id> picks;
      for (int k = 0; k < samples; ++k) picks.push_back(samples == 1 ? 0 : k * (Pmax - 1) / (samples - 1));
      picks.erase(std::unique(picks.begin(), picks.end()), picks.end());
      bench::reset_peak_rss();
      for (Id r : picks) {
        const auto t0 = std::chrono::steady_clock::now();
        const FineMesh m = read_store(path, opt);
        Sample s;
        s.open_seconds = bench::seconds_since(t0);
        const auto& c = plan[static_cast<std::size_t>(r)];
        const SweepResult res = sweep(m, threads, {}, c.first_coarse, c.end_coarse);
        s.P = Pmax, s.rank = r, s.elements = res.elements, s.nodes = res.nodes, s.seconds = res.seconds;
        s.cache = store_cache(m)->stats();
        measured.push_back(s);
      }
    }
    const double rank_rss = bench::peak_rss_bytes();

    // Part 2: the partition at every P.
    const FineMesh mesh = read_store(path, opt);
    if (json) std::printf("{\"store\":\"%s\",\"elements\":%lld,\"nodes\":%lld,\"rank_peak_rss\":%.0f,\"samples\":[", path.c_str(),
                          static_cast<long long>(mesh.num_elements()), static_cast<long long>(mesh.num_nodes()), rank_rss);
    else {
      std::printf("store %s: %lld fine elements, %lld nodes, %lld coarse elements\n", path.c_str(),
                  static_cast<long long>(mesh.num_elements()), static_cast<long long>(mesh.num_nodes()),
                  static_cast<long long>(mesh.num_coarse_elements()));
      std::printf("\nmeasured: one rank's chunk at P = %lld, %u thread(s), %llu MiB cache; peak RSS of this process %.0f MiB\n",
                  static_cast<long long>(Pmax), threads, static_cast<unsigned long long>(cache_mb), rank_rss / bench::kMiB);
      std::printf("%8s %12s %9s %9s %10s %12s %10s %12s\n", "rank", "elements", "open s", "sweep s", "Melem/s", "pages read",
                  "MiB read", "cache peak");
    }
    for (std::size_t k = 0; k < measured.size(); ++k) {
      const auto& s = measured[k];
      const double rate = s.seconds > 0 ? static_cast<double>(s.elements) / s.seconds / 1e6 : 0;
      if (json)
        std::printf("%s{\"P\":%lld,\"rank\":%lld,\"elements\":%lld,\"nodes\":%lld,\"open_seconds\":%.4f,\"seconds\":%.3f,"
                    "\"pages_read\":%llu,\"distinct_pages\":%llu,\"bytes_read\":%llu,\"cache_peak\":%llu}",
                    k ? "," : "", static_cast<long long>(s.P), static_cast<long long>(s.rank), static_cast<long long>(s.elements),
                    static_cast<long long>(s.nodes), s.open_seconds, s.seconds,
                    static_cast<unsigned long long>(s.cache.pages_read), static_cast<unsigned long long>(s.cache.distinct_pages_read),
                    static_cast<unsigned long long>(s.cache.bytes_read), static_cast<unsigned long long>(s.cache.peak_resident_bytes));
      else
        std::printf("%8lld %12lld %9.3f %9.2f %10.2f %12llu %10.2f %10.1f MiB\n", static_cast<long long>(s.rank),
                    static_cast<long long>(s.elements), s.open_seconds, s.seconds, rate,
                    static_cast<unsigned long long>(s.cache.pages_read), static_cast<double>(s.cache.bytes_read) / bench::kMiB,
                    static_cast<double>(s.cache.peak_resident_bytes) / bench::kMiB);
    }
    if (json) std::printf("],\"partitions\":[");
    else
      std::printf("\npartition (every rank, computed in one process): mean / max over ranks\n%7s %9s %19s %19s %15s %19s %10s\n", "P",
                  "build s", "elements", "ghost nodes", "neighbours", "shared nodes", "map MiB");
    for (std::size_t k = 0; k < ranks.size(); ++k) {
      const Id P = ranks[k];
      const auto t0 = std::chrono::steady_clock::now();
      const auto plan = plan_chunks(mesh, P);
      const auto sharing = in_process_sharing(mesh, plan);
      std::vector<PartitionStats> st;
      st.reserve(static_cast<std::size_t>(P));
      for (Id r = 0; r < P; ++r) st.push_back(partition_stats(r, plan, sharing[static_cast<std::size_t>(r)]));
      const double secs = bench::seconds_since(t0);
      double em, ex, gm, gx, nm, nx, sm, sx, cm, cx;
      mean_max(st, [](const PartitionStats& s) { return s.elements; }, em, ex);
      mean_max(st, [](const PartitionStats& s) { return s.ghost_nodes; }, gm, gx);
      mean_max(st, [](const PartitionStats& s) { return s.neighbors; }, nm, nx);
      mean_max(st, [](const PartitionStats& s) { return s.shared_nodes; }, sm, sx);
      mean_max(st, [](const PartitionStats& s) { return s.comm_entries; }, cm, cx);
      if (json)
        std::printf("%s{\"P\":%lld,\"seconds\":%.3f,\"elements\":[%.0f,%.0f],\"ghost_nodes\":[%.0f,%.0f],\"neighbors\":[%.2f,%.0f],"
                    "\"shared_nodes\":[%.0f,%.0f],\"comm_entries\":[%.0f,%.0f]}",
                    k ? "," : "", static_cast<long long>(P), secs, em, ex, gm, gx, nm, nx, sm, sx, cm, cx);
      else
        // map MiB: the largest rank's communication maps as local ids (8 B each).
        std::printf("%7lld %9.2f %9.3g/%9.3g %9.3g/%9.3g %7.1f/%7.0f %9.3g/%9.3g %10.2f\n", static_cast<long long>(P), secs, em, ex, gm,
                    gx, nm, nx, sm, sx, cx * 8 / bench::kMiB);
    }
    if (json) std::printf("]}\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "project_ranks: %s\n", e.what());
    return 1;
  }
  return 0;
}
