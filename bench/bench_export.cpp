// Export benchmarks: one chunk of ~1e7 fine elements out of a store of
// ~1e9, written in every format, next to Gmsh generating the same fine mesh
// as a transfinite mesh (the baseline: what a user without dicer runs).
//   BM_ExportStream/<vtkhdf|vtkhdf_deflate1|vtkhdf_deflate6|msh_binary|msh_ascii|exodus>
//       what `dicer export` does: a ChunkStream (the chunk's rows, ghosts)
//       + the writer generating the chunk pass by pass; counters:
//       elements_per_s (prepare + write), prepare_s, write_s,
//       file_bytes_per_element, peak RSS of the export (VmHWM reset
//       before) and its rise over the RSS before, nodes
//   BM_ExportHeld/msh_binary
//       the chunk held in memory first (ExportChunk::prepare), then the
//       writer: what export did before it streamed
//   BM_GmshTransfinite/<write 0|1>
//       Gmsh (built-in kernel, transfinite + recombine) meshing the chunk's
//       coarse hexes at the same intervals; /1 also writes binary MSH 4.1;
//       counters: build_s, generate_s, write_s, hexes_per_s, peak RSS,
//       memory per hex, file bytes per hex, Gmsh's hex count next to the
//       chunk's; ratios against the BM_ExportStream/msh_binary run before it
//   BM_GmshEmpty  gmsh::initialize + finalize with nothing: the floor
// Mesh: tests/data/vtkdata_disk_out_ref.ex2 (7472 hexes) diced at interval
// 52 (1.05e9 fine elements), 100 chunks, the middle one (~75 coarse hexes,
// ~1.05e7 fine elements). Every case runs one iteration (minutes in all).
// Environment: DICER_BENCH_SMALL=1 (interval 20, ~6e5 elements per chunk,
// a smoke run), DICER_BENCH_INTERVAL, DICER_BENCH_CHUNKS, DICER_BENCH_CHUNK
// (which chunk, default the middle one) override.
#include <benchmark/benchmark.h>
#include <malloc.h>
#include <unistd.h>

#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "bench_util.hpp"
#include "dicer/export.hpp"
#include "dicer/store.hpp"
#include "gmsh_transfinite.hpp"

using namespace dicer;

namespace {

std::string data(const char* f) { return std::string(DICER_BENCH_DATA) + "/" + f; }

Id env_id(const char* name, Id fallback) {
  const char* v = std::getenv(name);
  return v && *v ? static_cast<Id>(std::atoll(v)) : fallback;
}

struct Config {
  Id interval, chunks, chunk;
};
Config config() {
  const bool small = std::getenv("DICER_BENCH_SMALL") && std::string(std::getenv("DICER_BENCH_SMALL")) == "1";
  Config c;
  c.interval = env_id("DICER_BENCH_INTERVAL", small ? 20 : 52);
  c.chunks = env_id("DICER_BENCH_CHUNKS", 100);
  c.chunk = env_id("DICER_BENCH_CHUNK", c.chunks / 2);
  return c;
}

std::string temp_dir() {
  return std::filesystem::temp_directory_path() / ("dicer-bench-export-" + std::to_string(::getpid()));
}

using bench::cpu_now;
using bench::kMiB;
using bench::peak_rss_bytes;
using bench::reset_peak_rss;
using bench::rss_bytes;
using bench::seconds_since;

// The store (written once per process), the chunk and what Gmsh needs.
struct Setup {
  Config cfg;
  std::string path;
  MeshSets sets;
  ChunkRange range;
  Id store_elements = 0;
  bench::TransfiniteInput gmsh_input;
};
const Setup& setup() {
  static std::optional<Setup> s;
  if (s) return *s;
  Setup x;
  x.cfg = config();
  std::filesystem::create_directories(temp_dir());
  x.path = temp_dir() + "/disk_" + std::to_string(x.cfg.interval) + ".dice.h5";
  {
    IntervalRequest r;
    r.global = x.cfg.interval;
    write_store(FineMesh::dice(read_coarse_mesh(data("vtkdata_disk_out_ref.ex2")), r), x.path);
  }
  StoreSets ss = read_store_sets(x.path);
  x.sets.side_sets = std::move(ss.side_sets);
  x.sets.node_sets = std::move(ss.node_sets);
  const FineMesh m = read_store(x.path, StoreOptions{64ull << 20});
  x.store_elements = m.num_elements();
  const auto plan = plan_chunks(m, x.cfg.chunks);
  x.range = plan.at(static_cast<size_t>(x.cfg.chunk));
  x.gmsh_input = bench::transfinite_input(m, x.range.first_coarse, x.range.end_coarse);
  s = std::move(x);
  return *s;
}

// What later cases compare against.
struct Run {
  double elements_per_s = 0, generate_per_s = 0, peak_rss = 0, rss_rise = 0, elements_per_cpu_s = 0, generate_per_cpu_s = 0;
};
std::map<std::string, Run>& runs() {
  static std::map<std::string, Run> r;
  return r;
}

enum class Format { VtkHdf, VtkHdfDeflate1, VtkHdfDeflate6, MshBinary, MshAscii, Exodus };

void BM_ExportChunk(benchmark::State& st, Format format, std::string name, bool held) {
  const Setup& s = setup();
  const bool vtkhdf = format == Format::VtkHdf || format == Format::VtkHdfDeflate1 || format == Format::VtkHdfDeflate6;
  const std::string out = temp_dir() + "/chunk" + (vtkhdf ? ".vtkhdf" : format == Format::Exodus ? ".exo" : ".msh");
  double prepare_s = 0, write_s = 0, prepare_cpu = 0, write_cpu = 0, peak = 0, before = 0, file_bytes = 0;
  Id elements = 0, nodes = 0;
  for (auto _ : st) {
    const FineMesh m = read_store(s.path, StoreOptions{64ull << 20});
    before = rss_bytes();
    reset_peak_rss();
    try {
      auto t0 = std::chrono::steady_clock::now();
      double c0 = cpu_now();
      std::unique_ptr<ChunkSource> source;
      if (held) {
        auto c = std::make_unique<ExportChunk>(m, s.range);
        c->prepare(s.sets);
        source = std::move(c);
      } else {
        source = std::make_unique<ChunkStream>(m, s.range, s.sets);
      }
      const ChunkSource& c = *source;
      prepare_s = seconds_since(t0), prepare_cpu = cpu_now() - c0;
      t0 = std::chrono::steady_clock::now(), c0 = cpu_now();
      switch (format) {
        case Format::VtkHdf:
        case Format::VtkHdfDeflate1:
        case Format::VtkHdfDeflate6: {
          VtkHdfWriter w(out, 1, format == Format::VtkHdf ? 0 : format == Format::VtkHdfDeflate1 ? 1 : 6);
          w.write_partition(c);
          w.finish();
          break;
        }
        case Format::MshBinary: write_msh(c, out, true); break;
        case Format::MshAscii: write_msh(c, out, false); break;
        case Format::Exodus: write_exodus(c, out); break;
      }
      write_s = seconds_since(t0), write_cpu = cpu_now() - c0;
      elements = c.num_elements(), nodes = c.num_nodes();
      peak = peak_rss_bytes();
    } catch (const std::exception& e) {
      std::error_code ec;
      std::filesystem::remove(out, ec);
      st.SkipWithError(e.what());
      return;
    }
    file_bytes = static_cast<double>(std::filesystem::file_size(out));
    std::filesystem::remove(out);
    st.SetIterationTime(prepare_s + write_s);
  }
  const double e = static_cast<double>(elements);
  st.counters["elements_per_s"] = e / (prepare_s + write_s);
  st.counters["elements_per_cpu_s"] = e / (prepare_cpu + write_cpu);
  st.counters["prepare_s"] = prepare_s;
  st.counters["write_s"] = write_s;
  st.counters["prepare_cpu_s"] = prepare_cpu;
  st.counters["write_cpu_s"] = write_cpu;
  st.counters["prepare_elements_per_s"] = e / prepare_s;
  st.counters["write_elements_per_s"] = e / write_s;
  st.counters["file_bytes_per_element"] = file_bytes / e;
  st.counters["peak_rss_MiB"] = peak / kMiB;
  st.counters["rss_rise_MiB"] = (peak - before) / kMiB;
  st.counters["rss_rise_bytes_per_element"] = (peak - before) / e;
  st.counters["fine_elements"] = e;
  st.counters["nodes"] = static_cast<double>(nodes);
  st.counters["coarse_elements"] = static_cast<double>(s.range.end_coarse - s.range.first_coarse);
  st.counters["store_elements"] = static_cast<double>(s.store_elements);
  if (elements != s.range.fine_elements) st.SkipWithError("chunk element count differs from the plan");
  if (held) return;
  runs()[name] = Run{e / (prepare_s + write_s), e / prepare_s, peak, peak - before, e / (prepare_cpu + write_cpu),
                     e / prepare_cpu};
}

void BM_GmshTransfinite(benchmark::State& st) {
  const Setup& s = setup();
  const bool write = st.range(0) != 0;
  const std::string out = temp_dir() + "/gmsh.msh";
  double build_s = 0, generate_s = 0, write_s = 0, peak_generate = 0, peak = 0, before = 0, file_bytes = 0;
  double build_cpu = 0, generate_cpu = 0, write_cpu = 0;
  bench::GmshSession::Counts n;
  for (auto _ : st) {
    try {
      before = rss_bytes();
      reset_peak_rss();
      bench::GmshSession g;
      auto t0 = std::chrono::steady_clock::now();
      double c0 = cpu_now();
      g.build(s.gmsh_input);
      build_s = seconds_since(t0), build_cpu = cpu_now() - c0;
      t0 = std::chrono::steady_clock::now(), c0 = cpu_now();
      g.generate();
      generate_s = seconds_since(t0), generate_cpu = cpu_now() - c0;
      peak_generate = peak_rss_bytes();
      if (write) {
        t0 = std::chrono::steady_clock::now(), c0 = cpu_now();
        g.write_msh(out, true);
        write_s = seconds_since(t0), write_cpu = cpu_now() - c0;
        file_bytes = static_cast<double>(std::filesystem::file_size(out));
        std::filesystem::remove(out);
      }
      peak = peak_rss_bytes();
      n = g.counts();
    } catch (const std::exception& e) {
      st.SkipWithError(e.what());
      break;
    }
    st.SetIterationTime(build_s + generate_s + write_s);
  }
  const double h = static_cast<double>(n.hexes);
  const double total_s = build_s + generate_s + write_s, total_cpu = build_cpu + generate_cpu + write_cpu;
  st.counters["hexes_per_s"] = h / total_s;
  st.counters["hexes_per_cpu_s"] = h / total_cpu;
  st.counters["generate_cpu_s"] = generate_cpu;
  st.counters["generate_hexes_per_s"] = h / generate_s;
  st.counters["build_s"] = build_s;
  st.counters["generate_s"] = generate_s;
  st.counters["peak_rss_MiB"] = peak / kMiB;
  st.counters["rss_rise_MiB"] = (peak - before) / kMiB;
  st.counters["rss_rise_bytes_per_hex"] = (peak - before) / h;
  st.counters["generate_rss_rise_bytes_per_hex"] = (peak_generate - before) / h;
  st.counters["gmsh_hexes"] = h;
  st.counters["chunk_fine_elements"] = static_cast<double>(s.range.fine_elements);
  st.counters["gmsh_nodes"] = static_cast<double>(n.nodes);
  st.counters["gmsh_elements_all_dims"] = static_cast<double>(n.elements);
  if (write) {
    st.counters["write_s"] = write_s;
    st.counters["write_cpu_s"] = write_cpu;
    st.counters["write_hexes_per_s"] = h / write_s;
    st.counters["file_bytes_per_hex"] = file_bytes / h;
  }
  // Ratios against the dicer runs of this process (skipped when filtered out).
  auto& r = runs();
  if (auto it = r.find("msh_binary"); it != r.end()) {
    if (write) {
      st.counters["x_msh_export_vs_gmsh_gen_write"] = it->second.elements_per_s / (h / total_s);
      st.counters["x_msh_export_vs_gmsh_gen_write_cpu"] = it->second.elements_per_cpu_s / (h / total_cpu);
      st.counters["x_peak_rss_dicer_over_gmsh"] = it->second.peak_rss / peak;
      st.counters["x_rss_rise_dicer_over_gmsh"] = it->second.rss_rise / (peak - before);
    } else {
      st.counters["x_prepare_vs_gmsh_generate"] = it->second.generate_per_s / (h / (build_s + generate_s));
      st.counters["x_prepare_vs_gmsh_generate_cpu"] = it->second.generate_per_cpu_s / (h / (build_cpu + generate_cpu));
    }
  }
  if (n.hexes != s.range.fine_elements && n.hexes != 0)
    st.SkipWithError(("Gmsh made " + std::to_string(n.hexes) + " hexes, the chunk has " +
                      std::to_string(s.range.fine_elements))
                         .c_str());
}

void BM_GmshEmpty(benchmark::State& st) {
  double before = 0, peak = 0;
  for (auto _ : st) {
    st.PauseTiming();
    before = rss_bytes();
    reset_peak_rss();
    st.ResumeTiming();
    { bench::GmshSession g; }
    st.PauseTiming();
    peak = peak_rss_bytes();
    st.ResumeTiming();
  }
  st.counters["rss_rise_MiB"] = (peak - before) / kMiB;
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  const std::pair<Format, const char*> formats[] = {
      {Format::VtkHdf, "vtkhdf"},         {Format::VtkHdfDeflate1, "vtkhdf_deflate1"},
      {Format::VtkHdfDeflate6, "vtkhdf_deflate6"}, {Format::MshBinary, "msh_binary"},
      {Format::MshAscii, "msh_ascii"},    {Format::Exodus, "exodus"}};
  for (const auto& [f, name] : formats)
    benchmark::RegisterBenchmark((std::string("BM_ExportStream/") + name).c_str(), BM_ExportChunk, f, std::string(name),
                                 false)
        ->Iterations(1)
        ->UseManualTime()
        ->Unit(benchmark::kSecond);
  benchmark::RegisterBenchmark("BM_ExportHeld/msh_binary", BM_ExportChunk, Format::MshBinary, std::string("msh_binary"), true)
      ->Iterations(1)
      ->UseManualTime()
      ->Unit(benchmark::kSecond);
  benchmark::RegisterBenchmark("BM_GmshTransfinite", BM_GmshTransfinite)
      ->Arg(0)
      ->Arg(1)
      ->Iterations(1)
      ->UseManualTime()
      ->Unit(benchmark::kSecond);
  benchmark::RegisterBenchmark("BM_GmshEmpty", BM_GmshEmpty)->Iterations(5)->Unit(benchmark::kMillisecond);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::error_code ec;
  std::filesystem::remove_all(temp_dir(), ec);
  return 0;
}
