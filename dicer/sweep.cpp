#include "dicer/sweep.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <exception>
#include <thread>
#include <vector>

namespace dicer {
namespace {

std::uint64_t mix(std::uint64_t h) {
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ull;
  h ^= h >> 33;
  return h;
}

}  // namespace

std::uint64_t node_checksum_term(Id id, const Vec3& x) {
  return mix(static_cast<std::uint64_t>(id) ^ mix(std::bit_cast<std::uint64_t>(x.x) ^
                                                  mix(std::bit_cast<std::uint64_t>(x.y) ^
                                                      mix(std::bit_cast<std::uint64_t>(x.z)))));
}

std::uint64_t element_checksum_term(const FineElement& e) {
  std::uint64_t h = mix(static_cast<std::uint64_t>(e.id) + 0x9e3779b97f4a7c15ull);
  for (int q = 0; q < e.num_nodes; ++q) h = mix(h ^ static_cast<std::uint64_t>(e.nodes[q]));
  return h;
}

SweepResult sweep(const FineMesh& mesh, unsigned threads, const std::function<void(Id, Id)>& progress) {
  threads = std::max(1u, threads);
  if (const auto& cache = mesh.tables().cache) {
    const std::uint64_t per_thread = 2ull * kSweepPagesPerThread * kStorePageBytes;
    threads = static_cast<unsigned>(std::clamp<std::uint64_t>(cache->budget() / per_thread, 1, threads));
  }
  const auto start = std::chrono::steady_clock::now();
  const Id nn = mesh.num_nodes(), ne = mesh.num_elements(), total = nn + ne;
  std::atomic<Id> done{0};
  std::vector<std::uint64_t> sums(threads, 0);
  std::vector<std::exception_ptr> errors(threads);
  auto work = [&](unsigned t) {
    try {
      std::uint64_t sum = 0;
      Id local = 0;
      {  // one cursor at a time: each holds a slab of a coarse block
        NodeCursor nc(mesh, nn * t / threads, nn * (t + 1) / threads);
        Id id;
        Vec3 x;
        while (nc.next(id, x)) {
          sum += node_checksum_term(id, x);
          if (++local == 65536) done += local, local = 0;
        }
      }
      ElementCursor ec(mesh, ne * t / threads, ne * (t + 1) / threads);
      FineElement el;
      while (ec.next(el)) {
        sum += element_checksum_term(el);
        if (++local == 65536) done += local, local = 0;
      }
      done += local;
      sums[t] = sum;
    } catch (...) {
      errors[t] = std::current_exception();
    }
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, t);
  if (progress) {
    std::thread first(work, 0u);
    while (done.load() < total && first.joinable()) {
      progress(done.load(), total);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      bool all_errored = false;
      for (auto& e : errors) all_errored = all_errored || e;
      if (all_errored) break;
    }
    first.join();
  } else {
    work(0);
  }
  for (auto& th : pool) th.join();
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
  SweepResult r;
  r.threads = threads;
  r.nodes = nn, r.elements = ne;
  for (auto s : sums) r.checksum += s;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (progress) progress(total, total);
  return r;
}

}  // namespace dicer
