// Cache behaviour: one store read through the page cache under budgets of
// 1% to 100% of its decoded page bytes, in four access patterns.
//   BM_Cache/<pattern>/<budget %>/<read-ahead pages>
//     pattern 0 sweep      fill_block over every coarse element in store order
//     pattern 1 nodes      node(id) at uniform random ids
//     pattern 2 elements   element(id) at uniform random ids
//     pattern 3 boxes      for_each_in_box over boxes of 1% of the domain
//                          volume at random positions
//     read-ahead: 4 (the store's default) for every pattern; the sweep also
//     with 0, to tell re-reads after eviction from speculative reads
// Counters (all of the pattern alone: the cache is opened cold and its
// counters reset after opening):
//   hit_rate            hits / (hits + misses) of pin() calls
//   pages_read          pages the loader read (pins and read-ahead)
//   distinct_pages      pages the same pattern touches, measured once with a
//                       budget above the whole store and no read-ahead (so
//                       every touched page is read exactly once, never evicted)
//   read_amplification  pages_read / distinct_pages: 1 = every page read once;
//                       above 1 = re-reads after eviction or read-ahead
//                       past what the pattern needed
//   decoded_MiB, file_MiB  bytes decompressed / read from the file
//   store_pages, store_decoded_MiB  all pages of the store (every paged
//                       dataset except the per-page CRC companions), the
//                       100% of the budget
// Mesh: a box of 56^3 = 175,616 unit hexes (generated in memory, one block,
// planar), diced at interval 2 (1.4e6 fine elements): the store is ~130 MiB
// decoded, so 1% is above read_store's 1 MiB minimum. The interval only
// changes the TFI work per page, not which pages are read.
// Environment: DICER_BENCH_BOX (edge in hexes, default 56),
// DICER_BENCH_INTERVAL (default 2), DICER_BENCH_QUERIES (random queries per
// case, default 20000), DICER_BENCH_BOXES (box queries per case, default 16).
#include <benchmark/benchmark.h>
#include <hdf5.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <random>
#include <string>

#include "bench_util.hpp"
#include "dicer/export.hpp"
#include "hdf5_lock.hpp"
#include "dicer/store.hpp"

using namespace dicer;
using dicer::bench::kMiB;

namespace {

std::string temp_dir() {
  return std::filesystem::temp_directory_path() / ("dicer-bench-cache-" + std::to_string(::getpid()));
}

struct StoreTotals {
  std::uint64_t decoded_bytes = 0, pages = 0;
};

// Decoded bytes and chunk (page) count of every dataset of the store, the
// per-page CRC companions left out (the loader's own bookkeeping, not
// pages the cache holds). Read with HDF5 directly: the public store API
// does not expose dataset shapes.
StoreTotals store_totals(const std::string& path) {
  std::lock_guard lock(hdf5_lock());
  StoreTotals t;
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (f < 0) throw std::runtime_error(path + ": cannot open");
  auto visit = [](hid_t obj, const char* name, const H5O_info_t* info, void* data) -> herr_t {
    if (info->type != H5O_TYPE_DATASET) return 0;
    const std::string n = name;
    if (n.size() >= 4 && n.compare(n.size() - 4, 4, "_crc") == 0) return 0;
    auto& tot = *static_cast<StoreTotals*>(data);
    const hid_t d = H5Dopen2(obj, name, H5P_DEFAULT);
    const hid_t sp = H5Dget_space(d), ty = H5Dget_type(d), pl = H5Dget_create_plist(d);
    hsize_t dims[8] = {}, chunk[8] = {};
    const int rank = H5Sget_simple_extent_dims(sp, dims, nullptr);
    tot.decoded_bytes += static_cast<std::uint64_t>(H5Sget_simple_extent_npoints(sp)) * H5Tget_size(ty);
    if (H5Pget_layout(pl) == H5D_CHUNKED && H5Pget_chunk(pl, 8, chunk) == rank) {
      std::uint64_t pages = 1;
      for (int i = 0; i < rank; ++i) pages *= (dims[i] + chunk[i] - 1) / chunk[i];
      tot.pages += pages;
    }
    H5Pclose(pl), H5Tclose(ty), H5Sclose(sp), H5Dclose(d);
    return 0;
  };
  H5Ovisit2(f, H5_INDEX_NAME, H5_ITER_NATIVE, visit, &t, H5O_INFO_BASIC);
  H5Fclose(f);
  return t;
}

struct Setup {
  std::string path;
  StoreTotals totals;
  Id box_edge = 0;
};
const Setup& setup() {
  static std::optional<Setup> s;
  if (s) return *s;
  Setup x;
  x.box_edge = static_cast<Id>(bench::env_int("DICER_BENCH_BOX", 56));
  std::filesystem::create_directories(temp_dir());
  x.path = temp_dir() + "/box.dice.h5";
  IntervalRequest r;
  r.global = static_cast<Id>(bench::env_int("DICER_BENCH_INTERVAL", 2));
  write_store(FineMesh::dice(bench::box_coarse_mesh(x.box_edge, x.box_edge, x.box_edge), r), x.path);
  x.totals = store_totals(x.path);
  s = std::move(x);
  return *s;
}

enum Pattern { kSweep = 0, kNodes = 1, kElements = 2, kBoxes = 3 };

// Runs one pattern on an opened mesh; returns the units of work done
// (elements swept, queries answered, elements found in boxes).
double run_pattern(const FineMesh& m, int pattern, Id box_edge) {
  const Id queries = static_cast<Id>(bench::env_int("DICER_BENCH_QUERIES", 20000));
  std::mt19937_64 rng(42);  // the same ids and boxes for every budget and for the reference run
  double work = 0, sum = 0;
  switch (pattern) {
    case kSweep: {
      FineBlock b;
      for (Id h = 0; h < m.num_coarse_elements(); ++h) {
        m.fill_block(h, b);
        sum += b.x[0];
        work += static_cast<double>(b.num_elements());
      }
      break;
    }
    case kNodes:
    case kElements: {
      const Id n = pattern == kNodes ? m.num_nodes() : m.num_elements();
      std::uniform_int_distribution<Id> pick(0, n - 1);
      MeshCursor cur;
      for (Id q = 0; q < queries; ++q) {
        if (pattern == kNodes) sum += m.node(pick(rng), cur).x;
        else sum += static_cast<double>(m.element(pick(rng), cur).nodes[0]);
      }
      work = static_cast<double>(queries);
      break;
    }
    case kBoxes: {
      const double side = std::cbrt(0.01) * static_cast<double>(box_edge);  // 1% of the volume
      std::uniform_real_distribution<double> at(0.0, static_cast<double>(box_edge) - side);
      const Id boxes = static_cast<Id>(bench::env_int("DICER_BENCH_BOXES", 16));
      for (Id q = 0; q < boxes; ++q) {
        Box b;
        for (int d = 0; d < 3; ++d) b.lo[d] = at(rng), b.hi[d] = b.lo[d] + side;
        work += static_cast<double>(for_each_in_box(m, b, nullptr));
      }
      break;
    }
  }
  benchmark::DoNotOptimize(sum);
  return work;
}

// Pages the pattern touches: read once each under a budget that holds the
// whole store, without read-ahead.
const CacheStats& reference(int pattern) {
  static std::map<int, CacheStats> refs;
  static std::mutex mu;
  std::lock_guard lock(mu);
  if (auto it = refs.find(pattern); it != refs.end()) return it->second;
  const Setup& s = setup();
  const FineMesh m = read_store(s.path, StoreOptions{s.totals.decoded_bytes + (64ull << 20), 0});
  store_cache(m)->reset_stats();
  run_pattern(m, pattern, s.box_edge);
  return refs.emplace(pattern, store_cache(m)->stats()).first->second;
}

void BM_Cache(benchmark::State& st) {
  const Setup& s = setup();
  const int pattern = static_cast<int>(st.range(0));
  const double percent = static_cast<double>(st.range(1));
  const auto read_ahead = static_cast<unsigned>(st.range(2));
  const CacheStats& ref = reference(pattern);
  // read_store refuses budgets under 1 MiB; the counters say when that floor applied.
  const std::uint64_t budget =
      std::max<std::uint64_t>(1ull << 20, static_cast<std::uint64_t>(percent / 100.0 * static_cast<double>(s.totals.decoded_bytes)));
  CacheStats cs;
  double work = 0, seconds = 0;
  for (auto _ : st) {
    const FineMesh m = read_store(s.path, StoreOptions{budget, read_ahead});
    store_cache(m)->reset_stats();
    const auto t0 = std::chrono::steady_clock::now();
    work = run_pattern(m, pattern, s.box_edge);
    seconds = bench::seconds_since(t0);
    cs = store_cache(m)->stats();
    st.SetIterationTime(seconds);
  }
  const double pins = static_cast<double>(cs.hits + cs.misses);
  st.counters["hit_rate"] = pins > 0 ? static_cast<double>(cs.hits) / pins : 0.0;
  st.counters["pages_read"] = static_cast<double>(cs.pages_read);
  st.counters["distinct_pages"] = static_cast<double>(ref.pages_read);
  st.counters["read_amplification"] = static_cast<double>(cs.pages_read) / static_cast<double>(ref.pages_read);
  st.counters["decoded_MiB"] = static_cast<double>(cs.bytes_decompressed) / kMiB;
  st.counters["file_MiB"] = static_cast<double>(cs.bytes_read) / kMiB;
  st.counters["evictions"] = static_cast<double>(cs.evictions);
  st.counters["budget_MiB"] = static_cast<double>(budget) / kMiB;
  st.counters["peak_resident_MiB"] = static_cast<double>(cs.peak_resident_bytes) / kMiB;
  st.counters["store_pages"] = static_cast<double>(s.totals.pages);
  st.counters["store_decoded_MiB"] = static_cast<double>(s.totals.decoded_bytes) / kMiB;
  st.counters["work_per_s"] = work / seconds;
}

}  // namespace

BENCHMARK(BM_Cache)
    ->ArgsProduct({{kSweep, kNodes, kElements, kBoxes}, {1, 5, 10, 25, 50, 100}, {4}})
    ->ArgsProduct({{kSweep}, {1, 5, 10, 25, 50, 100}, {0}})
    ->ArgNames({"pattern", "pct", "ra"})
    ->Iterations(1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond);

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::error_code ec;
  std::filesystem::remove_all(temp_dir(), ec);
  return 0;
}
