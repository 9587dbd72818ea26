// The in-process parts of the side-by-side harness (scripts/bench_side_by_side.sh
// runs each case in its own process, so that each tool's peak RSS is its
// own, and also runs the dicer CLI; see bench/README.md).
//   BM_WriteBandwidth      baseline: x, y, z of every fine node written into a
//                          block-sized buffer, block after block (what block
//                          iteration would cost if TFI were free)
//   BM_WriteBandwidthConn  the same with what the batch API hands out per
//                          coarse element: x, y, z of its points and 8 node
//                          ids of each of its elements (n0 n1 n2 of them),
//                          a second baseline of the bytes BM_Batches writes
//   BM_BlockIteration/<nodes only 1|with connectivity 0>
//                          fill_block over every coarse element of the store
//   BM_Batches             the batch API (batch.hpp) over the whole store:
//                          every node once with coordinates, every element
//                          with connectivity, no checksum (issue 13's
//                          "batch API alone")
//   BM_SweepColdWarm/<threads>
//                          dicer::sweep (what `dicer sweep --threads T`
//                          times) twice on one store opened just before:
//                          the first sweep reads and decodes the pages it
//                          needs (the CLI's case), the second finds the
//                          kept coarse tables resident. Time: the first;
//                          counters cold_s, warm_s, their node rates and
//                          cold_over_warm, the share a sweep spends on its
//                          first read of the store (bench/README.md, stop 45)
//   BM_Gmsh/<write 0|1>    Gmsh 4.8 transfinite (bench/gmsh_transfinite.cpp) on
//                          the store's coarse hexes and intervals: build +
//                          generate(3), /1 also gmsh::write binary MSH 4.1
//   BM_Explicit/<raw 0|lz4 1|shuffle+lz4 2>
//                          the same fine mesh written explicitly to HDF5
//                          (float64 xyz per node in id order, int64 8 node ids
//                          per hex in id order; chunks of ~1 MiB), without a
//                          filter, with LZ4 (filter 32004), with byte shuffle +
//                          LZ4; the coordinates come from NodeCursor and the
//                          connectivity from fill_block (generation and HDF5
//                          write are timed apart)
//   BM_RandomQueries/<node 0|element 1>
//                          node(id) / element(id) at uniform random ids from a
//                          store opened cold (the 1e10 run, scripts/bench_1e10.sh):
//                          DICER_SBS_QUERIES queries (default 1e6) under a
//                          DICER_SBS_CACHE_MB budget (default 256); counters:
//                          seconds, ns per query, hit rate, pages read, peak RSS
// Environment: DICER_SBS_STORE (the store, required), DICER_SBS_OUT (folder
// for the files written; each is deleted after its size is taken; default
// the temporary folder).
// Every case but the two streaming ones is one iteration. Counters in
// seconds, bytes and MiB; peak_rss_MiB is VmHWM reset just before the work,
// rss_rise_MiB its rise over the RSS then.
#include <benchmark/benchmark.h>
#include <hdf5.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <mutex>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_util.hpp"
#include "hdf5_lock.hpp"
#include "dicer/rows.hpp"
#include "dicer/batch.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "gmsh_transfinite.hpp"

using namespace dicer;
using dicer::bench::kMiB;

namespace {

const std::string& store_path() {
  static const std::string p = bench::env_str("DICER_SBS_STORE");
  if (p.empty()) throw std::runtime_error("set DICER_SBS_STORE to the store to benchmark");
  return p;
}
std::string out_path(const std::string& name) {
  const std::string dir = bench::env_str("DICER_SBS_OUT", std::filesystem::temp_directory_path().string());
  return dir + "/sbs-" + std::to_string(::getpid()) + "-" + name;
}

FineMesh open_store() { return read_store(store_path(), StoreOptions{64ull << 20, 4}); }

// Intervals of coarse element h, from its table row (the same row
// gmsh_transfinite reads).
std::array<Id, 3> block_intervals(const FineMesh& m, Id h, MeshCursor& cur) { return RowReader(m.tables(), cur).element(h).n; }

// The baseline; with conn, also 8 ids per element of each block (the
// bytes BM_Batches writes).
template <bool conn>
void BM_WriteBandwidth(benchmark::State& st) {
  const FineMesh m = open_store();
  std::vector<Id> points(static_cast<size_t>(m.num_coarse_elements())), cells(points.size());
  MeshCursor cur;
  for (Id h = 0; h < m.num_coarse_elements(); ++h) {
    const auto n = block_intervals(m, h, cur);
    points[static_cast<size_t>(h)] = (n[0] + 1) * (n[1] + 1) * (n[2] + 1);
    cells[static_cast<size_t>(h)] = n[0] * n[1] * n[2];
  }
  cur.release();
  const size_t most = static_cast<size_t>(*std::max_element(points.begin(), points.end()));
  std::vector<double> x(most), y(most), z(most);
  std::vector<Id> ids(conn ? 8 * static_cast<size_t>(*std::max_element(cells.begin(), cells.end())) : 0);
  Id nodes = 0;
  for (auto _ : st) {
    for (Id h = 0; h < m.num_coarse_elements(); ++h) {
      const Id n = points[static_cast<size_t>(h)];
      bench::write_xyz(x.data(), y.data(), z.data(), static_cast<size_t>(n), static_cast<double>(h));
      if constexpr (conn) bench::write_ids(ids.data(), static_cast<size_t>(8 * cells[static_cast<size_t>(h)]), h);
      nodes += n;
    }
  }
  st.counters["nodes_per_s"] = benchmark::Counter(static_cast<double>(nodes), benchmark::Counter::kIsRate);
}

void BM_BlockIteration(benchmark::State& st) {
  const FineMesh m = open_store();
  const bool nodes_only = st.range(0) != 0;
  FineBlock b;
  Id nodes = 0, elements = 0;
  for (auto _ : st) {
    for (Id h = 0; h < m.num_coarse_elements(); ++h) {
      m.fill_block(h, b, nodes_only);
      benchmark::DoNotOptimize(b.x.data());
      nodes += b.num_points();
      elements += b.num_elements();
    }
  }
  st.counters["nodes_per_s"] = benchmark::Counter(static_cast<double>(nodes), benchmark::Counter::kIsRate);
  st.counters["elements_per_s"] = benchmark::Counter(static_cast<double>(elements), benchmark::Counter::kIsRate);
}

void BM_Batches(benchmark::State& st) {
  const FineMesh m = open_store();
  BatchCursor c(m);  // default slabs (kCursorSlabPoints): smaller ones measured no faster
  FineBatch b;
  Id nodes = 0, elements = 0;
  for (auto _ : st) {
    c.reset(0);
    while (c.next(b)) {
      benchmark::DoNotOptimize(b.x.data());
      benchmark::DoNotOptimize(b.conn.data());
    }
    nodes += m.num_nodes();
    elements += m.num_elements();
  }
  st.counters["nodes_per_s"] = benchmark::Counter(static_cast<double>(nodes), benchmark::Counter::kIsRate);
  st.counters["elements_per_s"] = benchmark::Counter(static_cast<double>(elements), benchmark::Counter::kIsRate);
}

void BM_Gmsh(benchmark::State& st) {
  const bool write = st.range(0) != 0;
  // The input is read first and the store closed, so the RSS rise below is Gmsh's alone.
  bench::TransfiniteInput in;
  Id fine_elements = 0;
  {
    const FineMesh m = open_store();
    in = bench::transfinite_input(m, 0, m.num_coarse_elements());
    fine_elements = m.num_elements();
  }
  const std::string out = out_path("gmsh.msh");
  double build_s = 0, generate_s = 0, write_s = 0, before = 0, peak_generate = 0, peak = 0, file_bytes = 0;
  bench::GmshSession::Counts n;
  for (auto _ : st) {
    before = bench::rss_bytes();
    bench::reset_peak_rss();
    bench::GmshSession g;
    auto t0 = std::chrono::steady_clock::now();
    g.build(in);
    build_s = bench::seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    g.generate();
    generate_s = bench::seconds_since(t0);
    peak_generate = bench::peak_rss_bytes();
    if (write) {
      t0 = std::chrono::steady_clock::now();
      g.write_msh(out, true);
      write_s = bench::seconds_since(t0);
      file_bytes = static_cast<double>(std::filesystem::file_size(out));
      std::filesystem::remove(out);
    }
    peak = bench::peak_rss_bytes();
    n = g.counts();
    st.SetIterationTime(build_s + generate_s + write_s);
  }
  const double h = static_cast<double>(n.hexes);
  st.counters["build_s"] = build_s;
  st.counters["generate_s"] = generate_s;
  st.counters["write_s"] = write_s;
  st.counters["hexes"] = h;
  st.counters["nodes"] = static_cast<double>(n.nodes);
  st.counters["elements_all_dims"] = static_cast<double>(n.elements);
  st.counters["hexes_per_s"] = h / (build_s + generate_s + write_s);
  st.counters["peak_rss_MiB"] = peak / kMiB;
  st.counters["rss_rise_MiB"] = (peak - before) / kMiB;
  st.counters["generate_rss_rise_bytes_per_hex"] = (peak_generate - before) / std::max(h, 1.0);
  st.counters["file_bytes"] = file_bytes;
  if (n.hexes != fine_elements)
    st.SkipWithError(("Gmsh made " + std::to_string(n.hexes) + " hexes, the store has " + std::to_string(fine_elements)).c_str());
}

// One chunked 2-D dataset written chunk by chunk (each H5Dwrite is exactly one
// chunk, so HDF5 compresses it and writes it once, with no chunk cache churn).
class ChunkedWriter {
 public:
  ChunkedWriter(hid_t file, const char* name, hid_t type, hsize_t rows, hsize_t width, hsize_t chunk_rows, int filter)
      : type_(type), rows_(rows), width_(width), chunk_rows_(std::min(chunk_rows, std::max<hsize_t>(rows, 1))) {
    const hsize_t dims[2] = {rows, width}, chunk[2] = {chunk_rows_, width};
    const hid_t space = H5Screate_simple(2, dims, nullptr);
    const hid_t dcpl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(dcpl, 2, chunk);
    if (filter == 2) H5Pset_shuffle(dcpl);
    if (filter >= 1 && H5Pset_filter(dcpl, 32004, H5Z_FLAG_MANDATORY, 0, nullptr) < 0)
      throw std::runtime_error("HDF5 refuses the LZ4 filter 32004");
    dset_ = H5Dcreate2(file, name, type, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    H5Pclose(dcpl), H5Sclose(space);
    if (dset_ < 0) throw std::runtime_error(std::string("cannot create dataset ") + name);
  }
  ~ChunkedWriter() { H5Dclose(dset_); }
  // Rows [first, first + count) from buf (count <= chunk_rows, first a multiple of it).
  void write(hsize_t first, hsize_t count, const void* buf) {
    const hsize_t start[2] = {first, 0}, size[2] = {count, width_};
    const hid_t fs = H5Dget_space(dset_), ms = H5Screate_simple(2, size, nullptr);
    H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, nullptr, size, nullptr);
    const herr_t rc = H5Dwrite(dset_, type_, ms, fs, H5P_DEFAULT, buf);
    H5Sclose(ms), H5Sclose(fs);
    if (rc < 0) throw std::runtime_error("H5Dwrite failed");
  }
  hsize_t chunk_rows() const { return chunk_rows_; }
  hsize_t rows() const { return rows_; }

 private:
  hid_t type_, dset_ = -1;
  hsize_t rows_, width_, chunk_rows_;
};

void BM_Explicit(benchmark::State& st) {
  const int filter = static_cast<int>(st.range(0));
  const std::string out = out_path("explicit.h5");
  double generate_s = 0, write_s = 0, file_bytes = 0, before = 0, peak = 0;
  Id nodes = 0, elements = 0;
  for (auto _ : st) {
    const FineMesh m = open_store();
    nodes = m.num_nodes(), elements = m.num_elements();
    before = bench::rss_bytes();
    bench::reset_peak_rss();
    const auto t_all = std::chrono::steady_clock::now();
    generate_s = write_s = 0;
    {
      // The store's own page loads (read-ahead thread) call HDF5 too: every
      // HDF5 call here holds the process-wide lock (Debian's HDF5 is serial).
      std::unique_lock lock(hdf5_lock());
      const hid_t f = H5Fcreate(out.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
      if (f < 0) throw std::runtime_error(out + ": cannot create");
      {
        // ~1 MiB chunks: 43690 nodes x 24 B, 16384 hexes x 64 B.
        ChunkedWriter xyz(f, "coordinates", H5T_NATIVE_DOUBLE, static_cast<hsize_t>(nodes), 3, 43690, filter);
        ChunkedWriter conn(f, "connectivity", H5T_NATIVE_INT64, static_cast<hsize_t>(elements), 8, 16384, filter);
        lock.unlock();
        std::vector<double> cbuf;
        NodeCursor nc(m);
        Id id;
        Vec3 p;
        for (hsize_t first = 0; first < xyz.rows(); first += xyz.chunk_rows()) {
          const hsize_t count = std::min(xyz.chunk_rows(), xyz.rows() - first);
          auto t0 = std::chrono::steady_clock::now();
          cbuf.clear();
          for (hsize_t i = 0; i < count && nc.next(id, p); ++i) cbuf.insert(cbuf.end(), {p.x, p.y, p.z});
          generate_s += bench::seconds_since(t0);
          t0 = std::chrono::steady_clock::now();
          lock.lock();
          xyz.write(first, count, cbuf.data());
          lock.unlock();
          write_s += bench::seconds_since(t0);
        }
        // Element ids run block after block (coarse element order), so the
        // blocks' connectivity, concatenated, is the id-ordered array.
        std::vector<std::int64_t> ebuf;
        FineBlock b;
        hsize_t first = 0;
        auto flush = [&](hsize_t count) {
          const auto t0 = std::chrono::steady_clock::now();
          lock.lock();
          conn.write(first, count, ebuf.data());
          lock.unlock();
          write_s += bench::seconds_since(t0);
          ebuf.erase(ebuf.begin(), ebuf.begin() + static_cast<std::ptrdiff_t>(8 * count));
          first += count;
        };
        for (Id h = 0; h < m.num_coarse_elements(); ++h) {
          const auto t0 = std::chrono::steady_clock::now();
          m.fill_block(h, b);
          ebuf.insert(ebuf.end(), b.conn.begin(), b.conn.end());
          generate_s += bench::seconds_since(t0);
          while (ebuf.size() >= 8 * conn.chunk_rows()) flush(conn.chunk_rows());
        }
        if (!ebuf.empty()) flush(ebuf.size() / 8);
        lock.lock();
      }
      H5Fclose(f);
    }
    const double total = bench::seconds_since(t_all);
    peak = bench::peak_rss_bytes();
    file_bytes = static_cast<double>(std::filesystem::file_size(out));
    std::filesystem::remove(out);
    st.SetIterationTime(total);
  }
  const double e = static_cast<double>(elements);
  st.counters["generate_s"] = generate_s;
  st.counters["write_s"] = write_s;
  st.counters["file_bytes"] = file_bytes;
  st.counters["bytes_per_element"] = file_bytes / e;
  st.counters["elements"] = e;
  st.counters["nodes"] = static_cast<double>(nodes);
  st.counters["peak_rss_MiB"] = peak / kMiB;
  st.counters["rss_rise_MiB"] = (peak - before) / kMiB;
}

void BM_RandomQueries(benchmark::State& st) {
  const bool elements = st.range(0) != 0;
  const Id queries = static_cast<Id>(bench::env_int("DICER_SBS_QUERIES", 1000000));
  const std::uint64_t budget = static_cast<std::uint64_t>(bench::env_int("DICER_SBS_CACHE_MB", 256)) << 20;
  double seconds = 0, peak = 0, sum = 0;
  CacheStats cs;
  for (auto _ : st) {
    const FineMesh m = read_store(store_path(), StoreOptions{budget, 4});
    store_cache(m)->reset_stats();
    bench::reset_peak_rss();
    std::mt19937_64 rng(20261122);
    std::uniform_int_distribution<Id> pick(0, (elements ? m.num_elements() : m.num_nodes()) - 1);
    MeshCursor cur;
    const auto t0 = std::chrono::steady_clock::now();
    for (Id q = 0; q < queries; ++q) {
      if (elements) sum += static_cast<double>(m.element(pick(rng), cur).nodes[7]);
      else sum += m.node(pick(rng), cur).z;
    }
    seconds = bench::seconds_since(t0);
    cur.release();
    peak = bench::peak_rss_bytes();
    cs = store_cache(m)->stats();
    st.SetIterationTime(seconds);
  }
  benchmark::DoNotOptimize(sum);
  const double pins = static_cast<double>(cs.hits + cs.misses);
  st.counters["queries"] = static_cast<double>(queries);
  st.counters["seconds"] = seconds;
  st.counters["ns_per_query"] = 1e9 * seconds / static_cast<double>(queries);
  st.counters["hit_rate"] = pins > 0 ? static_cast<double>(cs.hits) / pins : 0.0;
  st.counters["pages_read"] = static_cast<double>(cs.pages_read);
  st.counters["cache_peak_MiB"] = static_cast<double>(cs.peak_resident_bytes) / kMiB;
  st.counters["peak_rss_MiB"] = peak / kMiB;
}

void BM_SweepColdWarm(benchmark::State& st) {
  const auto threads = static_cast<unsigned>(st.range(0));
  double cold = 0, warm = 0, nodes = 0;
  for (auto _ : st) {
    const FineMesh m = open_store();
    const SweepResult first = sweep(m, threads), second = sweep(m, threads);
    if (first.checksum != second.checksum) throw std::runtime_error("BM_SweepColdWarm: the two sweeps' checksums differ");
    st.SetIterationTime(first.seconds);
    cold += first.seconds, warm += second.seconds, nodes += static_cast<double>(first.nodes);
  }
  st.counters["cold_s"] = cold / static_cast<double>(st.iterations());
  st.counters["warm_s"] = warm / static_cast<double>(st.iterations());
  st.counters["cold_nodes_per_s"] = nodes / cold;
  st.counters["warm_nodes_per_s"] = nodes / warm;
  st.counters["cold_over_warm"] = cold / warm;
}

// A case that throws (a store of another format version, Gmsh or HDF5
// refusing) is reported as skipped with the message, not a crash.
template <void (*Case)(benchmark::State&)>
void guarded(benchmark::State& st) {
  try {
    Case(st);
  } catch (const std::exception& e) {
    st.SkipWithError(e.what());
  }
}

}  // namespace

BENCHMARK(guarded<BM_WriteBandwidth<false>>)->Name("BM_WriteBandwidth")->Unit(benchmark::kMillisecond);
BENCHMARK(guarded<BM_WriteBandwidth<true>>)->Name("BM_WriteBandwidthConn")->Unit(benchmark::kMillisecond);
BENCHMARK(guarded<BM_BlockIteration>)->Name("BM_BlockIteration")->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond);
BENCHMARK(guarded<BM_Batches>)->Name("BM_Batches")->Unit(benchmark::kMillisecond);
BENCHMARK(guarded<BM_SweepColdWarm>)->Name("BM_SweepColdWarm")->Arg(1)->Arg(2)->Iterations(1)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(guarded<BM_Gmsh>)->Name("BM_Gmsh")->Arg(0)->Arg(1)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);
BENCHMARK(guarded<BM_RandomQueries>)->Name("BM_RandomQueries")->Arg(0)->Arg(1)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);
BENCHMARK(guarded<BM_Explicit>)->Name("BM_Explicit")->Arg(0)->Arg(1)->Arg(2)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  try {
    store_path();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_side_by_side: %s\n", e.what());
    return 2;
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
