// "No allocation per block once warm" (the kernels' contract, fill_slab,
// batch.hpp): a second pass over a mesh through a reused FineBlock or
// BatchCursor allocates nothing. Its own binary, because it replaces the
// global operator new with a counting one.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <random>

#include "dicer/batch.hpp"
#include "dicer/fine_mesh.hpp"
#include "random_mesh.hpp"

namespace {
std::atomic<long> g_allocations{0};
}

void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) { return operator new(n); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
// The nothrow forms too (the store's HDF5 driver uses one): left to a
// sanitizer's runtime, they would pair its new with the free above.
void* operator new(std::size_t n, const std::nothrow_t&) noexcept {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return std::malloc(n ? n : 1);
}
void* operator new[](std::size_t n, const std::nothrow_t& t) noexcept { return operator new(n, t); }
void operator delete(void* p, const std::nothrow_t&) noexcept { std::free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { std::free(p); }

using namespace dicer;

namespace {

// Meshes whose coarse elements differ in interval along every axis, with a
// graded sheet, so a block that fits one element must grow for another:
// the first pass does that, the second must not.
std::vector<FineMesh> meshes() {
  std::mt19937_64 rng(5);
  test::BoxSpec spec;
  spec.a = 3, spec.b = 2, spec.c = 2, spec.blocks = 2;
  IntervalRequest req;
  req.global = 3;
  req.sheets = {{0, 2}, {1, 6}, {2, 4}};
  BiasRequest bias;
  bias.ratio = 1.3;
  req.sheet_bias = {{1, bias}};
  std::vector<FineMesh> out;
  out.push_back(FineMesh::dice(test::random_box(spec, rng), req));
  IntervalRequest flat;
  flat.global = 5;
  out.push_back(FineMesh::dice(test::random_quad_sheet(3, 4, true, rng), flat));
  return out;
}

long allocations_in(const auto& f) {
  const long before = g_allocations.load();
  f();
  return g_allocations.load() - before;
}

TEST(WarmAllocation, BlockFillsAllocateNothingOnceWarm) {
  for (const FineMesh& f : meshes()) {
    FineBlock b;
    Id checksum = 0;
    auto pass = [&] {
      for (Id h = 0; h < f.num_coarse_elements(); ++h) {
        f.fill_block(h, b);
        checksum += b.node_id.back() + b.conn.back();
        f.fill_block(h, b, /*nodes_only=*/true);
        if (f.mode() == Mode::Volume) f.fill_slab(h, 1, 2, b, true, true);
      }
    };
    EXPECT_GT(allocations_in(pass), 0) << "the first pass sizes the block (the counter works)";
    EXPECT_EQ(allocations_in(pass), 0) << "the second pass reuses it";
    EXPECT_GT(checksum, 0);
  }
}

TEST(WarmAllocation, BatchCursorsAllocateNothingOnceWarm) {
  for (const FineMesh& f : meshes()) {
    for (const Id slab : {Id{7}, kCursorSlabPoints})
    for (const int kind : {0, 1, 2}) {  // connectivity; the grid; its lines (the sweep's batches)
      BatchOptions opt;
      opt.slab_points = slab;
      opt.conn = kind == 0, opt.grid = kind == 1, opt.lines = kind == 2;
      BatchCursor c(f, 0, f.num_coarse_elements(), opt);
      FineBatch batch;
      Id nodes = 0;
      const long first = allocations_in([&] {
        while (c.next(batch)) nodes += batch.num_nodes();
      });
      EXPECT_GT(first, 0);
      EXPECT_EQ(nodes, f.num_nodes());
      c.reset(0);
      nodes = 0;
      EXPECT_EQ(allocations_in([&] {
                  while (c.next(batch)) nodes += batch.num_nodes();
                }),
                0)
          << "slab points " << slab;
      EXPECT_EQ(nodes, f.num_nodes());
    }
  }
}

}  // namespace
