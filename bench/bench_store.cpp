// Store benchmarks: the fine mesh out of core, through the page cache, each
// next to its in-memory twin measured in the same run.
//   BM_Sweep/<budget MiB>/<store 1|memory 0>  every fine node and element of
//       disk_out_ref (7472 CUBIT hexes) at interval 52 = 1.05e9 elements,
//       block by block; counters: nodes/s, elements/s, peak RSS of the sweep,
//       pages read, peak cache residency
//   BM_RandomNode/<store 1|memory 0|store, every page pinned 2>, BM_RandomElement/...
//       node(id) / element(id) at random ids, warm 64 MiB cache: Time = ns/query;
//       1 keeps the coarse tables resident (the default), 2 does not
//   BM_RandomNodeShared/<1|2>/threads:T, BM_RandomElementShared/<1|2>/threads:T
//       the same from one store shared by T threads (one cache, a cursor
//       each): counter queries_per_s, all threads together
//   BM_RandomNodeBatch/<store|memory>/<ids>/<sorted>, BM_RandomElementBatch/...
//       nodes(ids) / elements(ids), `ids` random ids per call (sorted 1:
//       in increasing order): counter ns_per_id
//   BM_SweepPages/<ordered 1|input order 0>  pages read per 1e6 fine elements
//       swept under a 1 MiB budget, Morton-ordered store vs input order
//   BM_PageDecode/<step>  one 64 KiB page of 8-byte ids growing by small
//       random steps (like a store's id tables) through each step of a load: 0 memcpy (the baseline), 1 unshuffle, 2 the
//       CRC-32, 3 the LZ4 decode; counter bytes_per_second
//   BM_PointerChase/<KiB>  one dependent load at a time over random lines of
//       a working set that size: the memory latency under BM_Random*
#include <benchmark/benchmark.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <span>
#include <string>

#include "bench_util.hpp"
#include "dicer/store.hpp"
#include "lz4_filter.hpp"

using namespace dicer;

namespace {

std::string data(const char* f) { return std::string(DICER_BENCH_DATA) + "/" + f; }

// Stores written once per process into a temporary folder.
const std::string& store_path(Id interval, bool ordered) {
  static std::map<std::pair<Id, bool>, std::string> paths;
  auto it = paths.find({interval, ordered});
  if (it != paths.end()) return it->second;
  const std::string dir = std::filesystem::temp_directory_path() / ("dicer-bench-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string p = dir + "/disk_" + std::to_string(interval) + (ordered ? "" : "_input") + ".dice.h5";
  IntervalRequest r;
  r.global = interval;
  write_store(FineMesh::dice(read_coarse_mesh(data("vtkdata_disk_out_ref.ex2")), r, nullptr, ordered), p);
  return paths.emplace(std::make_pair(interval, ordered), p).first->second;
}

const FineMesh& memory_mesh(Id interval) {
  static std::map<Id, FineMesh> meshes;
  auto it = meshes.find(interval);
  if (it != meshes.end()) return it->second;
  IntervalRequest r;
  r.global = interval;
  return meshes.emplace(interval, FineMesh::dice(read_coarse_mesh(data("vtkdata_disk_out_ref.ex2")), r)).first->second;
}

using bench::peak_rss_bytes;
using bench::reset_peak_rss;

void BM_Sweep(benchmark::State& st) {
  const Id interval = 52;
  const std::uint64_t budget = static_cast<std::uint64_t>(st.range(0)) << 20;
  const bool from_store = st.range(1) != 0;
  const std::string& path = store_path(interval, true);
  Id nodes = 0, elements = 0;
  double rss = 0;
  CacheStats cs;
  for (auto _ : st) {
    st.PauseTiming();
    FineMesh opened = from_store ? read_store(path, StoreOptions{budget, 4}) : FineMesh();
    const FineMesh& m = from_store ? opened : memory_mesh(interval);
    reset_peak_rss();
    st.ResumeTiming();
    FineBlock b;
    double sum = 0;
    for (Id h = 0; h < m.num_coarse_elements(); ++h) {
      m.fill_block(h, b);
      sum += b.x[b.num_points() / 2] + static_cast<double>(b.conn[b.conn.size() / 2]);
      nodes += b.num_points();
      elements += b.num_elements();
    }
    benchmark::DoNotOptimize(sum);
    st.PauseTiming();
    rss = peak_rss_bytes();
    if (from_store) cs = store_cache(m)->stats();
    st.ResumeTiming();
  }
  st.counters["block_nodes_per_s"] = benchmark::Counter(static_cast<double>(nodes), benchmark::Counter::kIsRate);
  st.counters["elements_per_s"] = benchmark::Counter(static_cast<double>(elements), benchmark::Counter::kIsRate);
  st.counters["fine_elements"] = static_cast<double>(elements) / static_cast<double>(st.iterations());
  st.counters["peak_rss_MiB"] = rss / (1 << 20);
  st.counters["pages_read"] = static_cast<double>(cs.pages_read);
  st.counters["cache_peak_MiB"] = static_cast<double>(cs.peak_resident_bytes) / (1 << 20);
}

// What BM_Random* query: the disk at interval 8, and 65,536 random node
// (element) ids of it. source 0: in memory; 1: its store under a 64 MiB
// cache (the default options: coarse tables kept resident); 2: the same
// store with every page pinned per read (keep_coarse_tables off).
StoreOptions random_options(int source) {
  StoreOptions o{64ull << 20, 4};
  o.keep_coarse_tables = source != 2;
  return o;
}

template <bool Element>
struct RandomQueries {
  FineMesh opened;
  const FineMesh* m;
  std::vector<Id> ids = std::vector<Id>(1 << 16);
  explicit RandomQueries(int source)
      : opened(source != 0 ? read_store(store_path(8, true), random_options(source)) : FineMesh()),
        m(source != 0 ? &opened : &memory_mesh(8)) {
    std::mt19937_64 rng(7);
    const Id n = Element ? m->num_elements() : m->num_nodes();
    for (auto& i : ids) i = std::uniform_int_distribution<Id>(0, n - 1)(rng);
  }
};

// One query of BM_Random*: element(id) or node(id).
template <bool Element>
void query(const FineMesh& m, Id id, MeshCursor& cur) {
  if constexpr (Element) benchmark::DoNotOptimize(m.element(id, cur));
  else benchmark::DoNotOptimize(m.node(id, cur));
}

template <bool Element>
void BM_Random(benchmark::State& st) {
  const RandomQueries<Element> q(static_cast<int>(st.range(0)));
  const FineMesh& m = *q.m;
  const std::vector<Id>& ids = q.ids;
  MeshCursor cur;
  for (Id i : ids) query<Element>(m, i, cur);  // warm the cache
  size_t k = 0;
  for (auto _ : st) query<Element>(m, ids[k++ & 0xffff], cur);
}

// BM_Random from one store (one page cache) shared by every thread, each
// with its own cursor: what concurrent callers (threads of a solver) see
// of the cache's pins. Counter queries_per_s over all threads.
template <bool Element>
void BM_RandomShared(benchmark::State& st) {
  // Opened by the first thread; thread-safe static init.
  static const RandomQueries<Element> kept(1), pinned(2);
  const RandomQueries<Element>& q = st.range(0) == 2 ? pinned : kept;
  const FineMesh& m = *q.m;
  MeshCursor cur;
  size_t k = static_cast<size_t>(st.thread_index()) * 9973;
  for (Id i : q.ids) query<Element>(m, i, cur);  // warm the cache and this thread's cursor
  for (auto _ : st) query<Element>(m, q.ids[k++ & 0xffff], cur);
  st.counters["queries_per_s"] = benchmark::Counter(static_cast<double>(st.iterations()), benchmark::Counter::kIsRate);
}

// nodes(ids) / elements(ids): `batch` of BM_Random's ids per call; Time =
// ns per call, ns_per_id the figure to set beside BM_RandomNode /
// BM_RandomElement.
template <bool Element>
void BM_RandomBatch(benchmark::State& st) {
  RandomQueries<Element> q(static_cast<int>(st.range(0)));
  const FineMesh& m = *q.m;
  std::vector<Id>& ids = q.ids;
  const auto batch = static_cast<size_t>(st.range(1));
  if (st.range(2) != 0)  // each call's ids in increasing order (a node set, say): no sort inside
    for (size_t k = 0; k < ids.size() / batch; ++k)
      std::sort(ids.begin() + static_cast<std::ptrdiff_t>(k * batch),
                ids.begin() + static_cast<std::ptrdiff_t>((k + 1) * batch));
  std::vector<Vec3> pts(batch);
  std::vector<FineElement> els(batch);
  MeshCursor cur;
  auto call = [&](size_t k) {
    const std::span<const Id> some = std::span<const Id>(ids).subspan((k * batch) % ids.size(), batch);
    if constexpr (Element) m.elements(some, els, cur);
    else m.nodes(some, pts, cur);
  };
  for (size_t k = 0; k < ids.size() / batch; ++k) call(k);  // warm the cache
  size_t k = 0;
  for (auto _ : st) {
    call(k++);
    benchmark::DoNotOptimize(pts.data());
    benchmark::DoNotOptimize(els.data());
  }
  st.counters["ns_per_id"] = benchmark::Counter(static_cast<double>(st.iterations() * batch) * 1e-9,
                                                benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_SweepPages(benchmark::State& st) {
  const Id interval = 4;
  const bool ordered = st.range(0) != 0;
  const std::string& path = store_path(interval, ordered);
  double per_million = 0;
  for (auto _ : st) {
    const FineMesh m = read_store(path, StoreOptions{1ull << 20, 0});
    store_cache(m)->reset_stats();
    FineBlock b;
    Id elements = 0;
    for (Id h = 0; h < m.num_coarse_elements(); ++h) {
      m.fill_block(h, b);
      elements += b.num_elements();
    }
    per_million = static_cast<double>(store_cache(m)->stats().pages_read) / (static_cast<double>(elements) / 1e6);
  }
  st.counters["pages_per_1e6_elements"] = per_million;
}

void BM_PageDecode(benchmark::State& st) {
  // A page like the store's element rows: ids that grow by small steps,
  // what the shuffle and LZ4 see on a real table.
  std::vector<std::uint8_t> plain(kStorePageBytes);
  std::mt19937_64 rng(5);
  std::int64_t id = 1 << 20;
  for (size_t i = 0; i < plain.size(); i += 8) {
    id += static_cast<std::int64_t>(rng() % 97);
    std::memcpy(plain.data() + i, &id, 8);
  }
  std::vector<std::uint8_t> shuffled, out;
  store::shuffle_bytes(plain, 8, shuffled);
  const std::vector<std::uint8_t> stored = store::encode_page(shuffled);
  std::uint32_t crc = 0;
  for (auto _ : st) {
    switch (st.range(0)) {
      case 0: out.assign(shuffled.begin(), shuffled.end()); break;
      case 1: store::unshuffle_bytes(shuffled, 8, out); break;
      case 2: crc += store::page_crc(plain); break;
      case 3: store::decode_page(stored, out, plain.size(), "bench"); break;
    }
    benchmark::DoNotOptimize(out.data());
    benchmark::DoNotOptimize(crc);
  }
  st.counters["bytes_per_second"] =
      benchmark::Counter(static_cast<double>(st.iterations()) * static_cast<double>(plain.size()), benchmark::Counter::kIsRate);
}

// The floor under a random query: one dependent load at a time over
// random cache lines of a working set of range(0) KiB (a random cyclic
// order, so no prefetcher guesses the next line). Time = ns per load.
void BM_PointerChase(benchmark::State& st) {
  const size_t lines = static_cast<size_t>(st.range(0)) * 1024 / 64;
  std::vector<size_t> order(lines);
  for (size_t i = 0; i < lines; ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), std::mt19937_64(3));
  std::vector<std::uint64_t> a(lines * 8);
  for (size_t i = 0; i < lines; ++i) a[order[i] * 8] = order[(i + 1) % lines] * 8;
  std::uint64_t p = 0;
  for (size_t i = 0; i < lines; ++i) p = a[p];  // warm
  for (auto _ : st) p = a[p];
  benchmark::DoNotOptimize(p);
}

}  // namespace

BENCHMARK(BM_PageDecode)->DenseRange(0, 3);
BENCHMARK(BM_PointerChase)->Arg(32)->Arg(512)->Arg(5 << 10)->Arg(16 << 10)->Arg(64 << 10);
BENCHMARK(BM_Sweep)->Args({64, 1})->Args({64, 0})->Iterations(1)->Unit(benchmark::kSecond);
BENCHMARK_TEMPLATE(BM_Random, false)->Arg(1)->Arg(0)->Arg(2)->Name("BM_RandomNode");
BENCHMARK_TEMPLATE(BM_Random, true)->Arg(1)->Arg(0)->Arg(2)->Name("BM_RandomElement");
BENCHMARK_TEMPLATE(BM_RandomShared, false)->Arg(1)->Arg(2)->ThreadRange(1, 16)->UseRealTime()->Name("BM_RandomNodeShared");
BENCHMARK_TEMPLATE(BM_RandomShared, true)->Arg(1)->Arg(2)->ThreadRange(1, 16)->UseRealTime()->Name("BM_RandomElementShared");
BENCHMARK_TEMPLATE(BM_RandomBatch, false)->ArgsProduct({{1, 0}, {4096, 65536}, {0, 1}})->Name("BM_RandomNodeBatch");
BENCHMARK_TEMPLATE(BM_RandomBatch, true)->ArgsProduct({{1, 0}, {4096, 65536}, {0, 1}})->Name("BM_RandomElementBatch");
BENCHMARK(BM_SweepPages)->Arg(1)->Arg(0)->Iterations(1);

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::error_code ec;
  std::filesystem::remove_all(std::filesystem::temp_directory_path() / ("dicer-bench-" + std::to_string(::getpid())), ec);
  return 0;
}
