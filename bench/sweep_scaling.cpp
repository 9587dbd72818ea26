// Thread scaling of the sweep past this machine's 2 cores (run it where
// there are more: bench/README.md "Thread scaling on 16 cores"). A box of
// coarse hexes diced in memory (no store, so no HDF5: the binary links the
// core library alone and can be built static), swept with each thread
// count, each the median of --repeat sweeps. Every sweep must give the
// same checksum (exit 1 otherwise).
//   sweep_scaling [--box N] [--interval I] [--repeat R] [--threads 1,2,4]
// Defaults: N = 25 (15,625 hexes) at interval 40, 1.0e9 fine elements (the
// performance issue's 16-core figures were measured on 16,000 hexes at
// interval 40); threads 1, 2, 4, ... up to the cores present.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "box_mesh.hpp"
#include "dicer/sweep.hpp"

using namespace dicer;

namespace {
// A whole number >= 1, or a message naming the option.
long long number(const std::string& option, const std::string& v) {
  size_t used = 0;
  long long x = 0;
  try {
    x = std::stoll(v, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != v.size() || v.empty() || x < 1)
    throw std::invalid_argument("option " + option + ": '" + v + "' is not a whole number >= 1");
  return x;
}

int run(int argc, char** argv) {
  Id box = 25, interval = 40;
  int repeat = 3;
  std::vector<unsigned> threads;
  for (int a = 1; a < argc; a += 2) {
    const std::string k = argv[a];
    if (k == "--help" || k == "-h") {
      std::printf(
          "sweep_scaling: thread scaling of the in-memory sweep\n"
          "  sweep_scaling [--box N] [--interval I] [--repeat R] [--threads 1,2,4]\n"
          "A box of N^3 coarse hexes (default 25) diced at interval I (default 40: 1e9 fine\n"
          "elements) in memory, swept with each thread count (default 1, 2, 4, ... up to the\n"
          "cores present), each row the median of R sweeps (default 3). Exit 1 if two\n"
          "sweeps disagree on the checksum, 2 on a bad option.\n");
      return 0;
    }
    if (a + 1 >= argc) {
      std::fprintf(stderr, "sweep_scaling: option %s needs a value (--help)\n", k.c_str());
      return 2;
    }
    const std::string v = argv[a + 1];
    if (k == "--box") box = number(k, v);
    else if (k == "--interval") interval = number(k, v);
    else if (k == "--repeat") repeat = static_cast<int>(std::min(number(k, v), 1000LL));
    else if (k == "--threads")
      for (size_t p = 0; p <= v.size();) {
        const size_t q = std::min(v.find(',', p), v.size());
        threads.push_back(static_cast<unsigned>(std::min(number(k, v.substr(p, q - p)), 4096LL)));
        p = q + 1;
      }
    else {
      std::fprintf(stderr, "sweep_scaling: unknown option %s\n", k.c_str());
      return 2;
    }
  }
  if (threads.empty())
    for (unsigned t = 1; t <= std::max(1u, std::thread::hardware_concurrency()); t *= 2) threads.push_back(t);
  IntervalRequest r;
  r.global = interval;
  const auto t0 = std::chrono::steady_clock::now();
  const FineMesh m = FineMesh::dice(bench::box_coarse_mesh(box, box, box), r);
  std::printf("box %lldx%lldx%lld at interval %lld: %lld nodes, %lld elements, diced in %.1f s, %u cores\n",
              static_cast<long long>(box), static_cast<long long>(box), static_cast<long long>(box),
              static_cast<long long>(interval), static_cast<long long>(m.num_nodes()),
              static_cast<long long>(m.num_elements()), std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), std::thread::hardware_concurrency());
  std::printf("%8s %10s %14s %9s %11s  %s\n", "threads", "median s", "nodes/s", "speed-up", "efficiency", "checksum");
  double first = 0;  // the first row's median and threads: what speed-up is over
  unsigned first_threads = 1;
  std::uint64_t checksum = 0;
  bool same = true;
  for (unsigned t : threads) {
    std::vector<double> s;
    SweepResult res;
    for (int k = 0; k < repeat; ++k) {
      res = sweep(m, t);
      s.push_back(res.seconds);
      if (checksum == 0) checksum = res.checksum;
      same &= res.checksum == checksum;
    }
    std::sort(s.begin(), s.end());
    const double med = s[s.size() / 2];
    if (first == 0) first = med, first_threads = res.threads;
    const double up = first / med;
    std::printf("%8u %10.3f %14.4g %8.2fx %10.0f%%  %016llx\n", res.threads, med,
                static_cast<double>(res.nodes) / med, up, 100.0 * up * first_threads / res.threads,
                static_cast<unsigned long long>(res.checksum));
  }
  if (!same) std::fprintf(stderr, "sweep_scaling: the checksum changed with the thread count\n");
  return same ? 0 : 1;
}
}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {  // a bad option value, a box dicing refuses
    std::fprintf(stderr, "sweep_scaling: %s\n", e.what());
    return 2;
  }
}
