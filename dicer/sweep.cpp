#include "dicer/sweep.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "dicer/batch.hpp"
#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"
#include "clones.hpp"
#include "work_split.hpp"

namespace dicer {
namespace {

// sweep.hpp's mix: xorshift, odd multiply, xorshift, each a bijection; one
// multiply instead of murmur3's two (0.4).
inline std::uint64_t mix(std::uint64_t h) {
  h ^= h >> 32;
  h *= 0xd6e8feb86659fd93ull;
  h ^= h >> 32;
  return h;
}

constexpr const std::uint64_t* K = kChecksumKeys;

// A node's term from its id's product id K0.
inline std::uint64_t node_term_of_product(std::uint64_t idk, std::uint64_t x, std::uint64_t y, std::uint64_t z) {
  return mix(idk ^ x ^ std::rotl(y, 21) ^ std::rotl(z, 42));
}
inline std::uint64_t node_term(std::uint64_t id, std::uint64_t x, std::uint64_t y, std::uint64_t z) {
  return node_term_of_product(id * K[0], x, y, z);
}

// mix's argument for an element: id K4 + node[0] K5 + ...
template <int C>
inline std::uint64_t element_arg(std::uint64_t id, const Id* nodes) {
  std::uint64_t h = id * K[4];
  for (int q = 0; q < C; ++q) h += static_cast<std::uint64_t>(nodes[q]) * K[5 + q];
  return h;
}
template <int C>
inline std::uint64_t element_term(std::uint64_t id, const Id* nodes) {
  return mix(element_arg<C>(id, nodes));
}

// The loops over a batch: independent terms, no branch, so the compiler
// vectorises them (clones.hpp; integer arithmetic, so every clone gives the
// same sum).
// The ids' products advance by K0 per node: an add where AVX2 has no
// 64-bit multiply.
DICER_HASH_CLONES std::uint64_t sum_nodes(std::uint64_t first, const double* x, const double* y, const double* z,
                                          std::int64_t n) {
  std::uint64_t sum = 0, idk = first * K[0];
  for (std::int64_t i = 0; i < n; ++i, idk += K[0]) {
    std::uint64_t bx, by, bz;
    std::memcpy(&bx, x + i, 8), std::memcpy(&by, y + i, 8), std::memcpy(&bz, z + i, 8);
    sum += node_term_of_product(idk, bx, by, bz);
  }
  return sum;
}

template <int C>
inline std::uint64_t sum_elements(std::uint64_t first, const Id* conn, std::int64_t n) {
  std::uint64_t sum = 0;
  for (std::int64_t e = 0; e < n; ++e) sum += element_term<C>(first + static_cast<std::uint64_t>(e), conn + C * e);
  return sum;
}
// Clones cannot be templates (Clang): one function per corner count.
DICER_HASH_CLONES std::uint64_t sum_hexes(std::uint64_t first, const Id* conn, std::int64_t n) {
  return sum_elements<8>(first, conn, n);
}
DICER_HASH_CLONES std::uint64_t sum_quads(std::uint64_t first, const Id* conn, std::int64_t n) {
  return sum_elements<4>(first, conn, n);
}

// Hex terms of elements i0 .. i0 + m - 1 of one row, their corners read
// from the grid rows around it (grid_cell_corner): contiguous loads, no
// connectivity formed.
DICER_HASH_CLONES std::uint64_t sum_hex_row(std::uint64_t first, const Id* const* rows, std::int64_t i0,
                                            std::int64_t m) {
  const Id* const r[4] = {rows[0], rows[1], rows[2], rows[3]};  // held in registers
  std::uint64_t sum = 0;
  for (std::int64_t i = i0; i < i0 + m; ++i) {
    Id nodes[8];
    for (int q = 0; q < 8; ++q) nodes[q] = grid_cell_corner(r, i, q);
    sum += element_term<8>(first + static_cast<std::uint64_t>(i), nodes);
  }
  return sum;
}

// mix(a[i]), i < n: the terms whose arguments are already formed.
DICER_HASH_CLONES std::uint64_t sum_mix(const std::uint64_t* a, std::int64_t n) {
  std::uint64_t sum = 0;
  for (std::int64_t i = 0; i < n; ++i) sum += mix(a[i]);
  return sum;
}

// Arguments gathered across rows, hashed kArgs at a time: one vector loop
// (and one horizontal sum) per kArgs terms instead of per row of ~n0.
class ArgBuffer {
 public:
  static constexpr size_t kArgs = 1024;
  // Room for m <= kArgs arguments, written by the caller.
  std::uint64_t* take(size_t m) {
    if (used_ + m > kArgs) flush();
    std::uint64_t* at = a_ + used_;
    used_ += m;
    return at;
  }
  void flush() {
    sum_ += sum_mix(a_, static_cast<std::int64_t>(used_));
    used_ = 0;
  }
  std::uint64_t sum() {
    flush();
    return sum_;
  }

 private:
  std::uint64_t a_[kArgs];
  size_t used_ = 0;
  std::uint64_t sum_ = 0;
};

// Whether p[1..m] is an arithmetic progression (mod 2^64, the arithmetic
// of the terms: no overflow on any input), any step (a cell's interior rows
// step by 1, a face's rows by 1, -1, or a row of the face's canonical grid,
// an edge's by 1 or -1); its common difference in d.
bool progression(const Id* p, std::int64_t m, std::uint64_t& d) {
  const auto at = [p](std::int64_t t) { return static_cast<std::uint64_t>(p[t]); };
  d = at(2) - at(1);
  bool ok = true;
  for (std::int64_t t = 2; t < m; ++t) ok &= at(t + 1) - at(t) == d;
  return ok;
}

// The keys of the corners read from each of a cell's four grid rows,
// summed (grid_cell_row): a row's step times its sum is what its corners
// add to the step of a progression of arguments (products distribute mod
// 2^64).
constexpr std::array<std::uint64_t, 4> kRowKeys = [] {
  std::array<std::uint64_t, 4> k{};
  for (int q = 0; q < 8; ++q) k[grid_cell_row(q)] += kChecksumKeys[5 + q];
  return k;
}();

}  // namespace

std::uint64_t checksum_hex_grid(Id first, const std::array<Id, 3>& n, Id layers, std::span<const Id> grid) {
  // Sizes checked in 128 bits: no overflow on any input.
  const __int128 want = static_cast<__int128>(n[0] + __int128{1}) * (n[1] + __int128{1}) * (layers + __int128{1});
  if (n[0] < 1 || n[1] < 1 || layers < 0 || want != static_cast<__int128>(grid.size()))
    throw Error(ErrorKind::Usage, "checksum_hex_grid: a grid of " + std::to_string(grid.size()) +
                                      " ids for " + std::to_string(layers) + " layers of " + std::to_string(n[0]) +
                                      " x " + std::to_string(n[1]));
  const Id ni = n[0] + 1;
  // Each grid row's interior [1, n0 - 1] checked once: its step, if it is a
  // progression (n0 >= 3: at least two interior points; a row of more than
  // the buffer's room takes the general path).
  const Id grid_rows = (n[1] + 1) * (layers + 1);
  const bool rows_may_step = n[0] >= 3 && n[0] <= static_cast<Id>(ArgBuffer::kArgs);
  // Warm after the first batch: no allocation per batch.
  thread_local std::vector<std::uint64_t> step_of;
  thread_local std::vector<std::uint8_t> steps;
  step_of.resize(static_cast<size_t>(grid_rows)), steps.resize(static_cast<size_t>(grid_rows));
  std::uint64_t* const st = step_of.data();
  std::uint8_t* const ok = steps.data();
  for (Id r = 0; r < grid_rows; ++r) ok[r] = rows_may_step && progression(grid.data() + r * ni, n[0] - 1, st[r]);
  std::uint64_t sum = 0;
  ArgBuffer args;  // 8 KiB on the stack
  auto id = static_cast<std::uint64_t>(first);
  for (Id k = 0; k < layers; ++k)
    for (Id j = 0; j < n[1]; ++j, id += static_cast<std::uint64_t>(n[0])) {
      const Id ra = j + (n[1] + 1) * k, rc = ra + n[1] + 1;
      const Id* const rows[4] = {grid.data() + ra * ni, grid.data() + (ra + 1) * ni, grid.data() + rc * ni,
                                 grid.data() + (rc + 1) * ni};
      if (!(ok[ra] & ok[ra + 1] & ok[rc] & ok[rc + 1])) {
        sum += sum_hex_row(id, rows, 0, n[0]);
        continue;
      }
      // Elements 1 .. n0 - 2 read only the rows' interiors, each a
      // progression: each term's argument is the one before plus `step`
      // (K4 for the id, each row's step times its corners' keys). The two
      // end elements' arguments in full.
      const std::uint64_t step =
          K[4] + st[ra] * kRowKeys[0] + st[ra + 1] * kRowKeys[1] + st[rc] * kRowKeys[2] + st[rc + 1] * kRowKeys[3];
      auto arg = [&](Id i) {
        Id nodes[8];
        for (int q = 0; q < 8; ++q) nodes[q] = grid_cell_corner(rows, i, q);
        return element_arg<8>(id + static_cast<std::uint64_t>(i), nodes);
      };
      const Id m = n[0];
      std::uint64_t* const a = args.take(static_cast<size_t>(m));
      a[0] = arg(0);
      std::uint64_t h = arg(1);
      for (Id i = 1; i < m - 1; ++i, h += step) a[i] = h;
      a[m - 1] = arg(m - 1);
    }
  return sum + args.sum();
}

std::uint64_t node_checksum_term(Id id, const Vec3& x) {
  return node_term(static_cast<std::uint64_t>(id), std::bit_cast<std::uint64_t>(x.x), std::bit_cast<std::uint64_t>(x.y),
                   std::bit_cast<std::uint64_t>(x.z));
}

std::uint64_t element_checksum_term(const FineElement& e) {
  return e.num_nodes == 8 ? element_term<8>(static_cast<std::uint64_t>(e.id), e.nodes.data())
                          : element_term<4>(static_cast<std::uint64_t>(e.id), e.nodes.data());
}

std::uint64_t checksum_nodes(Id first, std::span<const double> x, std::span<const double> y,
                             std::span<const double> z) {
  DICER_ASSERT(x.size() == y.size() && x.size() == z.size(), "checksum_nodes: x, y, z of one length");
  return sum_nodes(static_cast<std::uint64_t>(first), x.data(), y.data(), z.data(), static_cast<std::int64_t>(x.size()));
}

std::uint64_t checksum_elements(Id first, int corners, std::span<const Id> conn) {
  DICER_ASSERT(corners == 8 || corners == 4, "checksum_elements: 8 or 4 corners");
  const auto n = static_cast<std::int64_t>(conn.size()) / corners;
  return corners == 8 ? sum_hexes(static_cast<std::uint64_t>(first), conn.data(), n)
                      : sum_quads(static_cast<std::uint64_t>(first), conn.data(), n);
}

namespace detail {

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

unsigned threads_for_cache(const FineMesh& mesh, unsigned threads) {
  threads = std::max(1u, threads);
  if (const auto& cache = mesh.tables().cache) {
    const std::uint64_t per_thread = 2ull * kSweepPagesPerThread * kStorePageBytes;
    threads = static_cast<unsigned>(std::clamp<std::uint64_t>(cache->budget() / per_thread, 1, threads));
  }
  return threads;
}

}  // namespace detail

SweepResult sweep(const FineMesh& mesh, unsigned threads, const std::function<void(Id, Id)>& progress, Id first_coarse,
                  Id end_coarse) {
  const Id H = mesh.num_coarse_elements();
  if (end_coarse < 0) end_coarse = H;
  if (first_coarse < 0 || first_coarse > end_coarse || end_coarse > H)
    throw Error(ErrorKind::Usage, "sweep: coarse elements " + std::to_string(first_coarse) + ".." +
                                      std::to_string(end_coarse) + " outside the mesh");
  threads = detail::threads_for_cache(mesh, threads);
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
  // Chunks of about equal work, taken by whichever thread is free: a static
  // split of one range per thread left the whole sweep waiting on its
  // slowest core (16 cores: bench/README.md, thread scaling).
  const unsigned chunks = threads == 1 ? 1 : threads * kSweepChunksPerThread;
  const std::vector<Id> split = detail::split_work(mesh, chunks, first_coarse, end_coarse);
  std::atomic<unsigned> next_chunk{0};
  std::atomic<Id> done{0};
  std::vector<std::uint64_t> sums(threads, 0);
  std::vector<std::exception_ptr> errors(threads);
  // Coarse elements in store order, a batch (slab) at a time: each chunk a
  // contiguous run, so a page of the store is read about once per sweep.
  auto work = [&](unsigned t) {
    try {
      std::uint64_t sum = 0;
      Id local = 0;
      // Hexes from the slab's grid (no connectivity formed), quads from conn.
      BatchOptions opt;
      opt.grid = mesh.mode() == Mode::Volume;
      opt.conn = !opt.grid;
      std::optional<BatchCursor> batches;
      FineBatch b;
      for (unsigned c = next_chunk++; c < chunks; c = next_chunk++) {
        if (batches) batches->reset(split[c], split[c + 1]);
        else batches.emplace(mesh, split[c], split[c + 1], opt);
        while (batches->next(b)) {
          sum += checksum_nodes(b.node_begin, b.x, b.y, b.z);
          sum += opt.grid ? checksum_hex_grid(b.element_begin, b.n, b.num_elements() / (b.n[0] * b.n[1]), b.grid)
                          : checksum_elements(b.element_begin, b.corners, b.conn);
          local += b.num_nodes() + b.num_elements();
          if (local >= 65536) done += local, local = 0;
        }
      }
      done += local;
      sums[t] = sum;
    } catch (...) {
      errors[t] = std::current_exception();
      next_chunk = chunks;  // the others stop after their current chunk
    }
  };
  // Workers count themselves out, so the progress loop wakes the moment the
  // last one ends (a fixed sleep added up to 100 ms to every sweep) and
  // never waits on work that an exception cut short.
  std::mutex m;
  std::condition_variable cv;
  unsigned finished = 0;
  auto run = [&](unsigned t) {
    work(t);
    {
      std::lock_guard lock(m);
      ++finished;
    }
    cv.notify_one();
  };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back(run, t);
  if (progress) {
    pool.emplace_back(run, 0u);
    std::unique_lock lock(m);
    while (!cv.wait_for(lock, std::chrono::milliseconds(100), [&] { return finished == threads; })) {
      lock.unlock();
      progress(std::min(done.load(), total), total);
      lock.lock();
    }
  } else {
    run(0);
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
