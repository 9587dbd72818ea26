// Transfer operators (transfer.hpp) between two stores of the CUBIT sphere
// (256 hexes), read through their page caches as a solver would, each case
// next to baselines measured in the same run:
//   BM_Sweep/<threads>             baseline: `dicer sweep` of the fine store
//                                  (every node's coordinates and every
//                                  element's connectivity, checksummed)
//   BM_Prolong/<coarse>/<threads>     y = P x, matrix-free
//   BM_Restrict/<coarse>/<threads>    x = P^T y, matrix-free
//   BM_ExplicitCsr/<coarse>/<transpose>  baseline: the same products with P
//                                  held as an explicit CSR in memory (int64
//                                  column ids, float64 values), one thread
//   BM_WriteFile/<coarse>/<0 hdf5 | 1 petsc>  the assembled P streamed to
//                                  a file; counters: bytes per non-zero of the
//                                  file and of the explicit CSR in memory, and
//                                  the peak resident growth while writing
// Rates are fine nodes (rows of P) per second. Fine interval:
// DICER_BENCH_TRANSFER_N (default 24, 3.5e6 fine nodes); <coarse> 0: the
// coarse store at n / 2, 1: at interval 1 (the coarse mesh itself: every
// fine node reads the 8 corners of its coarse element).
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <random>

#include "bench_util.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "dicer/transfer.hpp"

using namespace dicer;

namespace {

Id fine_n() { return bench::env_int("DICER_BENCH_TRANSFER_N", 24); }

std::string dir() {
  static const std::string d = std::filesystem::temp_directory_path() / ("dicer-bench-transfer-" + std::to_string(::getpid()));
  std::filesystem::create_directories(d);
  return d;
}

const FineMesh& level(Id n) {
  static std::map<Id, FineMesh> open;
  auto it = open.find(n);
  if (it != open.end()) return it->second;
  const std::string path = dir() + "/sphere" + std::to_string(n) + ".dice.h5";
  IntervalRequest r;
  r.global = n;
  write_store(FineMesh::dice(read_coarse_mesh(std::string(DICER_BENCH_DATA) + "/cardinal_sphere.e"), r), path);
  return open.emplace(n, read_store(path, StoreOptions{64ull << 20, 4})).first->second;
}

const Prolongation& prolongation(Id coarse) {
  const Id coarse_n = coarse == 0 ? fine_n() / 2 : 1;
  static std::map<Id, Prolongation> ps;
  auto it = ps.find(coarse_n);
  if (it != ps.end()) return it->second;
  return ps.try_emplace(coarse_n, level(coarse_n), level(fine_n())).first->second;
}

std::vector<double> random_vector(Id n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> v(static_cast<size_t>(n));
  for (double& x : v) x = u(rng);
  return v;
}

void rate(benchmark::State& st, Id rows) {
  st.counters["fine_nodes_per_s"] =
      benchmark::Counter(static_cast<double>(rows) * static_cast<double>(st.iterations()), benchmark::Counter::kIsRate);
}

void BM_Sweep(benchmark::State& st) {
  const FineMesh& m = level(fine_n());
  for (auto _ : st) benchmark::DoNotOptimize(sweep(m, static_cast<unsigned>(st.range(0))).checksum);
  rate(st, m.num_nodes());
}

void BM_Prolong(benchmark::State& st) {
  const Prolongation& p = prolongation(st.range(0));
  const auto x = random_vector(p.cols(), 1);
  std::vector<double> y(static_cast<size_t>(p.rows()));
  for (auto _ : st) {
    p.apply(x, y, static_cast<unsigned>(st.range(1)));
    benchmark::DoNotOptimize(y.data());
  }
  rate(st, p.rows());
}

void BM_Restrict(benchmark::State& st) {
  const Prolongation& p = prolongation(st.range(0));
  const auto y = random_vector(p.rows(), 2);
  std::vector<double> x(static_cast<size_t>(p.cols()));
  for (auto _ : st) {
    p.apply_transpose(y, x, static_cast<unsigned>(st.range(1)));
    benchmark::DoNotOptimize(x.data());
  }
  rate(st, p.rows());
}

struct Csr {
  std::vector<Id> indptr, indices;
  std::vector<double> data;
  double bytes() const { return 8.0 * static_cast<double>(indptr.size() + indices.size() + data.size()); }
};

const Csr& explicit_csr(Id coarse) {
  static std::map<Id, Csr> held;
  auto it = held.find(coarse);
  if (it != held.end()) return it->second;
  const Prolongation& p = prolongation(coarse);
  Csr c;
  c.indptr.reserve(static_cast<size_t>(p.rows()) + 1), c.indices.reserve(static_cast<size_t>(p.nonzeros()));
  c.data.reserve(static_cast<size_t>(p.nonzeros()));
  c.indptr.push_back(0);
  ProlongationCursor cur(p);
  for (ProlongationBatch b; cur.next(b);) {
    for (Id r = 0; r < b.num_rows(); ++r) c.indptr.push_back(c.indptr.back() + b.offsets[r + 1] - b.offsets[r]);
    c.indices.insert(c.indices.end(), b.cols.begin(), b.cols.end());
    c.data.insert(c.data.end(), b.weights.begin(), b.weights.end());
  }
  return held.emplace(coarse, std::move(c)).first->second;
}

void BM_ExplicitCsr(benchmark::State& st) {
  const Prolongation& p = prolongation(st.range(0));
  const Csr& c = explicit_csr(st.range(0));
  const bool transpose = st.range(1) != 0;
  const auto in = random_vector(transpose ? p.rows() : p.cols(), 3);
  std::vector<double> out(static_cast<size_t>(transpose ? p.cols() : p.rows()));
  for (auto _ : st) {
    if (transpose) {
      std::fill(out.begin(), out.end(), 0.0);
      for (Id r = 0; r < p.rows(); ++r)
        for (Id e = c.indptr[r]; e < c.indptr[r + 1]; ++e) out[static_cast<size_t>(c.indices[e])] += c.data[e] * in[r];
    } else {
      for (Id r = 0; r < p.rows(); ++r) {
        double s = 0;
        for (Id e = c.indptr[r]; e < c.indptr[r + 1]; ++e) s += c.data[e] * in[static_cast<size_t>(c.indices[e])];
        out[static_cast<size_t>(r)] = s;
      }
    }
    benchmark::DoNotOptimize(out.data());
  }
  rate(st, p.rows());
  st.counters["memory_bytes_per_nnz"] = c.bytes() / static_cast<double>(p.nonzeros());
}

void BM_WriteFile(benchmark::State& st) {
  const Prolongation& p = prolongation(st.range(0));
  const bool petsc = st.range(1) != 0;
  const std::string path = dir() + (petsc ? "/P.bin" : "/P.h5");
  const double rss0 = bench::rss_bytes();
  bench::reset_peak_rss();
  for (auto _ : st) {
    if (petsc) write_prolongation_petsc(p, path);
    else write_prolongation_hdf5(p, path);
  }
  st.counters["rss_growth_mib"] = (bench::peak_rss_bytes() - rss0) / bench::kMiB;
  rate(st, p.rows());
  const double nnz = static_cast<double>(p.nonzeros());
  st.counters["file_bytes_per_nnz"] = static_cast<double>(std::filesystem::file_size(path)) / nnz;
  // The explicit CSR a solver would hold instead: int64 indices + float64
  // values + an int64 row pointer (int32 indices: 12 B + 4 B per row).
  st.counters["csr64_bytes_per_nnz"] = (16.0 * nnz + 8.0 * static_cast<double>(p.rows() + 1)) / nnz;
  st.counters["nnz_per_row"] = nnz / static_cast<double>(p.rows());
}

}  // namespace

BENCHMARK(BM_Sweep)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Prolong)->ArgsProduct({{0, 1}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Restrict)->ArgsProduct({{0, 1}, {1, 2}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ExplicitCsr)->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WriteFile)->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

BENCHMARK_MAIN();
