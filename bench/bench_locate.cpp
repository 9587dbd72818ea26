// Point location (locate.hpp) against its baselines, in one run.
//   BM_Locate/<threads>   1e6 points (random xi in random fine elements) of
//       disk_out_ref (7472 CUBIT hexes) at interval 52 = 1.05e9 elements,
//       from the store under a 64 MiB cache, warmed by one pass first:
//       Time = ns per point (wall), counters: points/s, found
//   BM_ElementQuery       element(id) at the same points' element ids, same
//       store and cache: the id query, ns per query
//   BM_BruteForce         the same kind of points in a small mesh
//       (cardinal_sphere, 256 hexes, at interval 2: 2048 elements), each
//       tested against the box of every fine element, nodes in memory (a
//       lower bound of a brute-force search): ns per point
//   BM_LocateSurface/<threads>  the nearest quad of a surface store (in
//       memory): 1e5 points near the libMesh cylinder shell at interval 100
// DICER_BENCH_POINTS overrides the number of points (default 1e6).
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>

#include "dicer/locate.hpp"
#include "dicer/store.hpp"

using namespace dicer;

namespace {

std::string data(const char* f) { return std::string(DICER_BENCH_DATA) + "/" + f; }

size_t num_points() {
  const char* e = std::getenv("DICER_BENCH_POINTS");
  return e ? static_cast<size_t>(std::atoll(e)) : 1000000;
}

std::array<std::array<double, 3>, 8> cell(const FineMesh& m, Id e, MeshCursor& cur) {
  const FineElement el = m.element(e, cur);
  std::array<std::array<double, 3>, 8> x;
  for (int q = 0; q < 8; ++q) {
    const Vec3 v = m.node(el.nodes[q], cur);
    x[q] = {v.x, v.y, v.z};
  }
  return x;
}

struct Points {
  std::vector<double> xyz;
  std::vector<Id> element;
};

Points make_points(const FineMesh& m, size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<Id> pick(0, m.num_elements() - 1);
  std::uniform_real_distribution<double> u(0.01, 0.99);
  Points p;
  MeshCursor cur;
  for (size_t i = 0; i < n; ++i) {
    const Id e = pick(rng);
    const auto x = trilinear(cell(m, e, cur), {u(rng), u(rng), u(rng)});
    p.xyz.insert(p.xyz.end(), x.begin(), x.end());
    p.element.push_back(e);
  }
  return p;
}

struct Big {
  std::string path;
  FineMesh mesh;
  Points points;
};

Big& big() {
  static Big* b = [] {
    const std::string dir = std::filesystem::temp_directory_path() / ("dicer-bench-locate-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const std::string p = dir + "/disk_52.dice.h5";
    IntervalRequest r;
    r.global = 52;
    write_store(FineMesh::dice(read_coarse_mesh(data("vtkdata_disk_out_ref.ex2")), r), p);
    FineMesh m = read_store(p, StoreOptions{64ull << 20, 0});
    Points pts = make_points(m, num_points(), 1);
    locate_points(m, pts.xyz, 2);  // warm the cache
    return new Big{p, std::move(m), std::move(pts)};
  }();
  return *b;
}

void BM_Locate(benchmark::State& st) {
  Big& b = big();
  const int threads = static_cast<int>(st.range(0));
  Id found = 0;
  for (auto _ : st) {
    const std::vector<Located> out = locate_points(b.mesh, b.points.xyz, threads);
    found = 0;
    for (size_t i = 0; i < out.size(); ++i) found += out[i].element == b.points.element[i];
    benchmark::DoNotOptimize(out.data());
  }
  const double n = static_cast<double>(b.points.element.size());
  st.counters["ns_per_point"] = benchmark::Counter(n * static_cast<double>(st.iterations()),
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  st.counters["points"] = n;
  st.counters["in_their_element"] = static_cast<double>(found) / n;
}

void BM_ElementQuery(benchmark::State& st) {
  Big& b = big();
  MeshCursor cur;
  for (auto _ : st)
    for (Id e : b.points.element) benchmark::DoNotOptimize(b.mesh.element(e, cur).nodes[0]);
  const double n = static_cast<double>(b.points.element.size());
  st.counters["ns_per_query"] = benchmark::Counter(n * static_cast<double>(st.iterations()),
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_BruteForce(benchmark::State& st) {
  static const FineMesh m = [] {
    IntervalRequest r;
    r.global = 2;
    return FineMesh::dice(read_coarse_mesh(data("cardinal_sphere.e")), r);
  }();
  static const Points pts = make_points(m, 1000, 2);
  std::vector<std::array<std::array<double, 3>, 8>> cells;
  MeshCursor cur;
  for (Id e = 0; e < m.num_elements(); ++e) cells.push_back(cell(m, e, cur));
  Id found = 0;
  for (auto _ : st) {
    found = 0;
    for (size_t i = 0; i < pts.element.size(); ++i) {
      const std::array<double, 3> p = {pts.xyz[3 * i], pts.xyz[3 * i + 1], pts.xyz[3 * i + 2]};
      // Every element's bounding box (precomputed cells, no inversion: a
      // lower bound of what a brute-force search costs).
      for (Id e = 0; e < static_cast<Id>(cells.size()); ++e) {
        const auto& x = cells[e];
        double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
        for (const auto& c : x)
          for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], c[d]), hi[d] = std::max(hi[d], c[d]);
        bool in = true;
        for (int d = 0; d < 3; ++d) in = in && p[d] >= lo[d] && p[d] <= hi[d];
        if (in && e == pts.element[i]) ++found;
      }
    }
  }
  st.counters["ns_per_point"] = benchmark::Counter(static_cast<double>(pts.element.size() * st.iterations()),
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  st.counters["elements"] = static_cast<double>(m.num_elements());
  st.counters["found"] = static_cast<double>(found);
}

// Surface stores: the nearest quad, best-first over the same tree. The
// libMesh cylinder shell at interval 100 (quads on a curved CAD-free skin:
// straight coarse quads), points made at random xi in random fine quads and
// moved off the surface by up to 1% of the shell's size in a random
// direction: ns per point, and the share whose nearest quad is the one
// they were made in (points moved off near an edge may be nearer another).
void BM_LocateSurface(benchmark::State& st) {
  static const auto* s = [] {
    struct S {
      FineMesh mesh;
      std::vector<double> xyz;
      std::vector<Id> element;
    };
    IntervalRequest r;
    r.global = 100;
    auto* out = new S{FineMesh::dice(read_coarse_mesh(data("libmesh_cylinder_shell.exo")), r), {}, {}};
    std::mt19937_64 rng(3);
    std::uniform_int_distribution<Id> pick(0, out->mesh.num_elements() - 1);
    std::uniform_real_distribution<double> u(0.01, 0.99), off(-1e-4, 1e-4);
    MeshCursor cur;
    for (size_t i = 0; i < num_points() / 10; ++i) {
      const Id e = pick(rng);
      const FineElement el = out->mesh.element(e, cur);
      std::array<std::array<double, 3>, 4> x;
      for (int q = 0; q < 4; ++q) {
        const Vec3 v = out->mesh.node(el.nodes[q], cur);
        x[q] = {v.x, v.y, v.z};
      }
      const auto p = bilinear(x, {u(rng), u(rng), 0});
      for (int d = 0; d < 3; ++d) out->xyz.push_back(p[d] + off(rng));
      out->element.push_back(e);
    }
    return out;
  }();
  const int threads = static_cast<int>(st.range(0));
  Id found = 0;
  for (auto _ : st) {
    const std::vector<Located> out = locate_points(s->mesh, s->xyz, threads);
    found = 0;
    for (size_t i = 0; i < out.size(); ++i) found += out[i].element == s->element[i];
    benchmark::DoNotOptimize(out.data());
  }
  const double n = static_cast<double>(s->element.size());
  st.counters["ns_per_point"] = benchmark::Counter(n * static_cast<double>(st.iterations()),
                                                   benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  st.counters["points"] = n;
  st.counters["elements"] = static_cast<double>(s->mesh.num_elements());
  st.counters["in_their_element"] = static_cast<double>(found) / n;
}

}  // namespace

BENCHMARK(BM_LocateSurface)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();
BENCHMARK(BM_Locate)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();
BENCHMARK(BM_ElementQuery)->Unit(benchmark::kMillisecond)->Iterations(1)->UseRealTime();
BENCHMARK(BM_BruteForce)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_MAIN();
