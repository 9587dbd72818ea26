#pragma once
// Helpers shared by the benchmark binaries: peak-RSS probes, clocks,
// environment overrides, and (box_mesh.hpp) a generated box of coarse hexes.
#include <benchmark/benchmark.h>
#include <malloc.h>

#include <chrono>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <string>

#include "box_mesh.hpp"
#include "dicer/coarse_mesh.hpp"

namespace dicer::bench {

inline constexpr double kMiB = 1 << 20;

// Peak RSS since the last reset (Linux: writing 5 to clear_refs resets VmHWM).
inline void reset_peak_rss() { std::ofstream("/proc/self/clear_refs") << "5"; }
// A "Key:   N kB" line of /proc/self/status, in bytes (0 if absent).
inline double status_bytes(const char* key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string k = key;
  while (std::getline(in, line))
    if (line.rfind(k, 0) == 0) return std::stod(line.substr(k.size())) * 1024.0;
  return 0;
}
inline double peak_rss_bytes() { return status_bytes("VmHWM:"); }
// The RSS now, after handing free heap pages back (an earlier case's freed
// memory would otherwise hide this case's rise).
inline double rss_bytes() {
  ::malloc_trim(0);
  return status_bytes("VmRSS:");
}

inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
// Process CPU seconds (user + system, all threads): what the shared
// machine's load does not inflate.
inline double cpu_now() {
  timespec ts{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

inline long long env_int(const char* name, long long fallback) {
  const char* v = std::getenv(name);
  return v && *v ? std::atoll(v) : fallback;
}
inline std::string env_str(const char* name, const std::string& fallback = {}) {
  const char* v = std::getenv(name);
  return v && *v ? std::string(v) : fallback;
}

// The write-bandwidth baseline's inner loop: x, y, z of n points set to
// v, v + 1, v + 2 (a value per block, so the stores cannot be elided or
// turned into a memset), then made visible to the optimiser as used.
inline void write_xyz(double* x, double* y, double* z, size_t n, double v) {
  for (size_t i = 0; i < n; ++i) x[i] = v, y[i] = v + 1, z[i] = v + 2;
  benchmark::DoNotOptimize(x);
  benchmark::DoNotOptimize(y);
  benchmark::DoNotOptimize(z);
  benchmark::ClobberMemory();
}

// n ids written into a block-sized buffer: a pattern the vectoriser turns
// into plain stores (the connectivity of BM_WriteBandwidthConn).
inline void write_ids(std::int64_t* ids, size_t n, std::int64_t v) {
  for (size_t i = 0; i < n; ++i) ids[i] = v + static_cast<std::int64_t>(i);
  benchmark::DoNotOptimize(ids);
  benchmark::ClobberMemory();
}

}  // namespace dicer::bench
