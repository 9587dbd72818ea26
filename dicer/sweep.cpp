#include "dicer/sweep.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <exception>
#include <thread>
#include <vector>

#include "dicer/error.hpp"
#include "dicer/rows.hpp"

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

namespace {

// Coarse elements [first, end) split into `parts` ranges of about equal work
// (owned nodes + fine elements: node_first + element_first rises by exactly
// that from one element to the next). O(parts log H) rows.
std::vector<Id> split_work(const FineMesh& mesh, unsigned parts, Id first, Id end) {
  const Id H = mesh.num_coarse_elements();
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  auto work_before = [&](Id h) {
    return h < H ? static_cast<__int128>(R.node_first(h)) + R.element_first(h)
                 : static_cast<__int128>(mesh.num_nodes()) + mesh.num_elements();
  };
  const __int128 w0 = work_before(first), total = work_before(end) - w0;
  std::vector<Id> at(parts + 1, end);
  at[0] = first;
  for (unsigned p = 1; p < parts; ++p) {
    const __int128 want = w0 + total * p / parts;
    Id lo = at[p - 1], hi = end;  // first element whose work before it is >= want
    while (lo < hi) {
      const Id mid = lo + (hi - lo) / 2;
      if (work_before(mid) < want) lo = mid + 1;
      else hi = mid;
    }
    at[p] = lo;
  }
  return at;
}

}  // namespace

SweepResult sweep(const FineMesh& mesh, unsigned threads, const std::function<void(Id, Id)>& progress, Id first_coarse,
                  Id end_coarse) {
  const Id H = mesh.num_coarse_elements();
  if (end_coarse < 0) end_coarse = H;
  if (first_coarse < 0 || first_coarse > end_coarse || end_coarse > H)
    throw Error(ErrorKind::Usage, "sweep: coarse elements " + std::to_string(first_coarse) + ".." +
                                      std::to_string(end_coarse) + " outside the mesh");
  threads = std::max(1u, threads);
  if (const auto& cache = mesh.tables().cache) {
    const std::uint64_t per_thread = 2ull * kSweepPagesPerThread * kStorePageBytes;
    threads = static_cast<unsigned>(std::clamp<std::uint64_t>(cache->budget() / per_thread, 1, threads));
  }
  const auto start = std::chrono::steady_clock::now();
  Id nn = 0, ne = 0;
  {
    MeshCursor cur;
    const RowReader R(mesh.tables(), cur);
    const auto own = mesh.owned_nodes(first_coarse, end_coarse, cur);
    nn = own[1] - own[0];
    auto efirst = [&](Id h) { return h < H ? R.element_first(h) : mesh.num_elements(); };
    ne = efirst(end_coarse) - efirst(first_coarse);
  }
  const Id total = nn + ne;
  const std::vector<Id> split = split_work(mesh, threads, first_coarse, end_coarse);
  const bool vol = mesh.mode() == Mode::Volume;
  std::atomic<Id> done{0};
  std::vector<std::uint64_t> sums(threads, 0);
  std::vector<std::exception_ptr> errors(threads);
  // One pass over coarse elements in store order: a block's own nodes (ids
  // >= node_first) and its elements, slab by slab; so each page of the
  // store is read once per sweep.
  auto work = [&](unsigned t) {
    try {
      std::uint64_t sum = 0;
      Id local = 0;
      FineBlock b;
      for (Id h = split[t]; h < split[t + 1]; ++h) {
        const std::array<Id, 3> n = RowReader(mesh.tables(), b.cursor).element(h).n;
        const Id n2 = vol ? n[2] : 0;
        const Id step = std::max<Id>(1, kCursorSlabPoints / ((n[0] + 1) * (n[1] + 1)));
        for (Id k0 = 0; k0 < std::max<Id>(n2, 1); k0 += step) {
          const Id k1 = vol ? std::min(k0 + step, n2) : 0;
          mesh.fill_slab(h, k0, k1, b, true, true);
          // Nodes of planes k0 .. k1 - 1, and k1 on the last slab.
          const Id plane = (n[0] + 1) * (n[1] + 1);
          const Id points = (k1 == n2 ? k1 - k0 + 1 : k1 - k0) * plane;
          Id own = 0;
          for (Id g = 0; g < points; ++g) {
            const Id id = b.node_id[g];
            if (id < b.node_first) continue;
            sum += node_checksum_term(id, {b.x[g], b.y[g], b.z[g]});
            ++own;
          }
          FineElement el;
          el.num_nodes = mesh.corners();
          const Id m = b.num_elements();
          for (Id e = 0; e < m; ++e) {
            el.id = b.first_element + e;
            std::copy_n(&b.conn[static_cast<size_t>(e) * el.num_nodes], el.num_nodes, el.nodes.begin());
            sum += element_checksum_term(el);
          }
          local += m + own;
          if (local >= 65536) done += local, local = 0;
        }
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
      progress(std::min(done.load(), total), total);
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
