// Core benchmarks (in-memory fine mesh), each next to a baseline measured in
// the same run:
//   BM_WriteBandwidth    baseline: plain write of 3 doubles per node (memset-free loop)
//   BM_BlockIteration    fill_block over every coarse element: fine nodes/s
//                        (/N/nodes_only/graded: graded = every sheet biased)
//   BM_NodeQuery         node(id) at random ids: Time = ns per query (warm caches)
//                        (/N/graded)
//   BM_ElementQuery      element(id) at random ids: Time = ns per query
//   BM_NodeCursor        whole-mesh node iteration in id order
//   BM_Batches           the batch API: every node (coordinates) and element
//                        (connectivity) once, slab by slab (batch.hpp)
//   BM_BatchesGrid       the same with the slab's grid of node ids instead of
//                        connectivity
//   BM_BatchesLines      the same with the grid as one line per row (what the
//                        sweep reads)
//   BM_ChecksumGrid      the sweep's element checksum over every batch's grid
//                        (checksum_hex_grid), held in memory: elements/s;
//                        baseline BM_ChecksumConn: checksum_elements over the
//                        same batches' connectivity
// Mesh: the CUBIT sphere (256 hexes) at interval N (arg), so ~256 N^3 elements.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "bench_util.hpp"
#include "dicer/batch.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/sheets.hpp"
#include "dicer/sweep.hpp"

using namespace dicer;

namespace {

// graded: every sheet a geometric series of ratio 1.15 from its default start.
const FineMesh& sphere(Id n, bool graded = false) {
  static std::vector<std::pair<Id, FineMesh>> cache;
  const Id key = graded ? -n : n;
  for (auto& [k, m] : cache)
    if (k == key) return m;
  IntervalRequest r;
  r.global = n;
  CoarseMesh c = read_coarse_mesh(std::string(DICER_BENCH_DATA) + "/cardinal_sphere.e");
  if (graded) {
    const Id sheets = find_sheets(c, build_topology(c)).num_sheets();
    for (Id q = 0; q < sheets; ++q) r.sheet_bias.emplace_back(q, BiasRequest{tfi::Spacing::Geometric, 1.15, 0, 0, {}});
  }
  cache.emplace_back(key, FineMesh::dice(std::move(c), r));
  return cache.back().second;
}

// Baseline: the fastest a block iteration could be if TFI were free: writing
// x, y, z for the same number of nodes into a block-sized buffer (reused).
void BM_WriteBandwidth(benchmark::State& st) {
  const Id n = st.range(0);
  const FineMesh& m = sphere(n);
  const size_t per_block = static_cast<size_t>((n + 1) * (n + 1) * (n + 1));
  std::vector<double> x(per_block), y(per_block), z(per_block);
  Id nodes = 0;
  for (auto _ : st) {
    for (Id h = 0; h < m.num_coarse_elements(); ++h) {
      bench::write_xyz(x.data(), y.data(), z.data(), per_block, static_cast<double>(h));
      nodes += static_cast<Id>(per_block);
    }
  }
  st.counters["nodes_per_s"] = benchmark::Counter(static_cast<double>(nodes), benchmark::Counter::kIsRate);
}

// Arg 1: 1 = nodes only, 0 = nodes and element connectivity; arg 2: 1 =
// every sheet graded (BM_BlockIteration/N/1/1: the graded store's cost).
void BM_BlockIteration(benchmark::State& st) {
  const FineMesh& m = sphere(st.range(0), st.range(2) != 0);
  const bool nodes_only = st.range(1) != 0;
  FineBlock b;
  Id nodes = 0;
  for (auto _ : st) {
    for (Id h = 0; h < m.num_coarse_elements(); ++h) {
      m.fill_block(h, b, nodes_only);
      benchmark::DoNotOptimize(b.x.data());
      nodes += b.num_points();
    }
  }
  st.counters["nodes_per_s"] = benchmark::Counter(static_cast<double>(nodes), benchmark::Counter::kIsRate);
}

// Arg 1: 1 = every sheet graded.
void BM_NodeQuery(benchmark::State& st) {
  const FineMesh& m = sphere(st.range(0), st.range(1) != 0);
  std::mt19937_64 rng(1);
  std::uniform_int_distribution<Id> pick(0, m.num_nodes() - 1);
  std::vector<Id> ids(1 << 16);
  for (auto& i : ids) i = pick(rng);
  size_t k = 0;
  for (auto _ : st) {
    benchmark::DoNotOptimize(m.node(ids[k++ & 0xffff]));
  }
}

void BM_ElementQuery(benchmark::State& st) {
  const FineMesh& m = sphere(st.range(0));
  std::mt19937_64 rng(2);
  std::uniform_int_distribution<Id> pick(0, m.num_elements() - 1);
  std::vector<Id> ids(1 << 16);
  for (auto& i : ids) i = pick(rng);
  size_t k = 0;
  for (auto _ : st) {
    benchmark::DoNotOptimize(m.element(ids[k++ & 0xffff]));
  }
}

void BM_NodeCursor(benchmark::State& st) {
  const FineMesh& m = sphere(st.range(0));
  Id nodes = 0;
  for (auto _ : st) {
    NodeCursor c(m);
    Id id;
    Vec3 p;
    double sum = 0;
    while (c.next(id, p)) sum += p.x;
    benchmark::DoNotOptimize(sum);
    nodes += m.num_nodes();
  }
  st.counters["nodes_per_s"] = benchmark::Counter(static_cast<double>(nodes), benchmark::Counter::kIsRate);
}

// The batch API alone (batch.hpp): every node once with coordinates and
// every element with its connectivity, slab by slab, no checksum.
// Every batch of the sphere at interval st.range(0), with the arrays `opt` asks.
void batches_rate(benchmark::State& st, const BatchOptions& opt) {
  const FineMesh& m = sphere(st.range(0));
  Id nodes = 0;
  for (auto _ : st) {
    BatchCursor c(m, 0, -1, opt);
    FineBatch b;
    while (c.next(b)) {
      benchmark::DoNotOptimize(b.x.data());
      benchmark::DoNotOptimize(b.conn.data());
      benchmark::DoNotOptimize(b.grid.data());
    }
    nodes += m.num_nodes();
  }
  st.counters["nodes_per_s"] = benchmark::Counter(static_cast<double>(nodes), benchmark::Counter::kIsRate);
}
void BM_Batches(benchmark::State& st) { batches_rate(st, {}); }
// Coordinates and the slab's grid of node ids, no connectivity formed
// (BatchOptions::grid).
void BM_BatchesGrid(benchmark::State& st) {
  BatchOptions opt;
  opt.conn = false, opt.grid = true;
  batches_rate(st, opt);
}
// The sweep's batches: coordinates and the grid as one line per row
// (BatchOptions::lines), no grid or connectivity formed.
void BM_BatchesLines(benchmark::State& st) {
  BatchOptions opt;
  opt.conn = false, opt.lines = true;
  batches_rate(st, opt);
}

// Every batch of the sphere at interval n, its grid or its connectivity
// copied out (the checksums alone are timed, not the batches).
struct HeldBatch {
  Id first = 0, layers = 0;
  std::array<Id, 3> n{};
  std::vector<Id> ids;
};
const std::vector<HeldBatch>& held_batches(Id n, bool grid) {
  static std::vector<std::pair<Id, std::vector<HeldBatch>>> cache;
  const Id key = grid ? n : -n;
  for (auto& [k, v] : cache)
    if (k == key) return v;
  BatchOptions opt;
  opt.coords = false, opt.conn = !grid, opt.grid = grid;
  BatchCursor c(sphere(n), 0, -1, opt);
  std::vector<HeldBatch> v;
  FineBatch b;
  while (c.next(b)) {
    const auto ids = grid ? b.grid : b.conn;
    v.push_back({b.element_begin, b.num_elements() / (b.n[0] * b.n[1]), b.n, {ids.begin(), ids.end()}});
  }
  cache.emplace_back(key, std::move(v));
  return cache.back().second;
}
void checksum_rate(benchmark::State& st, bool grid) {
  const auto& batches = held_batches(st.range(0), grid);
  Id elements = 0;
  for (auto _ : st) {
    std::uint64_t sum = 0;
    for (const HeldBatch& b : batches) {
      sum += grid ? checksum_hex_grid(b.first, b.n, b.layers, b.ids) : checksum_elements(b.first, 8, b.ids);
      elements += b.layers * b.n[0] * b.n[1];
    }
    benchmark::DoNotOptimize(sum);
  }
  st.counters["elements_per_s"] = benchmark::Counter(static_cast<double>(elements), benchmark::Counter::kIsRate);
}
void BM_ChecksumGrid(benchmark::State& st) { checksum_rate(st, true); }
void BM_ChecksumConn(benchmark::State& st) { checksum_rate(st, false); }

}  // namespace

BENCHMARK(BM_WriteBandwidth)->Arg(8)->Arg(32)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BlockIteration)
    ->Args({8, 1, 0})->Args({32, 1, 0})->Args({8, 0, 0})->Args({32, 0, 0})->Args({8, 1, 1})->Args({32, 1, 1})
    ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_NodeQuery)->Args({8, 0})->Args({32, 0})->Args({8, 1})->Args({32, 1});
BENCHMARK(BM_ElementQuery)->Arg(8)->Arg(32);
BENCHMARK(BM_NodeCursor)->Arg(8)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Batches)->Arg(8)->Arg(32)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BatchesGrid)->Arg(8)->Arg(32)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BatchesLines)->Arg(8)->Arg(32)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ChecksumConn)->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_ChecksumGrid)->Arg(10)->Arg(20)->Unit(benchmark::kMillisecond);
BENCHMARK_MAIN();
