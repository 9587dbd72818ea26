// See access_paths.hpp.
#include "access_paths.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <random>
#include <vector>

#include "dicer/batch.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "dicer/verify.hpp"

namespace dicer::test {
namespace {

bool same_bits(const Vec3& a, const Vec3& b) {
  return std::bit_cast<std::uint64_t>(a.x) == std::bit_cast<std::uint64_t>(b.x) &&
         std::bit_cast<std::uint64_t>(a.y) == std::bit_cast<std::uint64_t>(b.y) &&
         std::bit_cast<std::uint64_t>(a.z) == std::bit_cast<std::uint64_t>(b.z);
}

}  // namespace

void expect_paths_bit_identical(const FineMesh& f, const std::string& store_path, bool verify_store) {
  std::vector<Vec3> by_id(static_cast<size_t>(f.num_nodes()));
  for (Id id = 0; id < f.num_nodes(); ++id) by_id[id] = f.node(id);
  for (const Id slab : {Id{1}, Id{40}, kCursorSlabPoints}) {
    NodeCursor c(f, 0, f.num_nodes(), slab);
    Id id, seen = 0;
    Vec3 p;
    while (c.next(id, p)) {
      ASSERT_TRUE(same_bits(p, by_id[id])) << "cursor, node " << id << " slab " << slab;
      ++seen;
    }
    EXPECT_EQ(seen, f.num_nodes());
  }
  FineBlock b;
  for (Id h = 0; h < f.num_coarse_elements(); ++h) {
    f.fill_block(h, b);
    for (Id g = 0; g < b.num_points(); ++g)
      ASSERT_TRUE(same_bits({b.x[g], b.y[g], b.z[g]}, by_id[b.node_id[g]])) << "block " << h << " point " << g;
    for (Id e = 0; e < b.num_elements(); ++e) {
      const FineElement el = f.element(b.first_element + e);
      for (int q = 0; q < f.corners(); ++q)
        ASSERT_EQ(el.nodes[q], b.conn[static_cast<size_t>(e * f.corners() + q)]) << "block " << h << " element " << e;
    }
  }
  for (const Id slab : {Id{30}, BatchOptions{}.slab_points}) {
    BatchOptions opt;
    opt.slab_points = slab;
    BatchCursor batches(f, 0, -1, opt);
    Id batched = 0;
    for (FineBatch fb; batches.next(fb);)
      for (Id q = 0; q < fb.num_nodes(); ++q, ++batched)
        ASSERT_TRUE(same_bits({fb.x[q], fb.y[q], fb.z[q]}, by_id[fb.node_begin + q]))
            << "batch node " << fb.node_begin + q << " slab " << slab;
    EXPECT_EQ(batched, f.num_nodes());
  }

  // Batched queries over every id, shuffled, with repeats: node(id)'s and
  // element(id)'s bits, in memory and (below) from the store.
  std::mt19937_64 rng(static_cast<std::uint64_t>(f.num_nodes()));
  auto check_batched_queries = [&](const FineMesh& m, const char* where) {
    std::vector<Id> ids;
    for (Id id = 0; id < m.num_nodes(); ++id) ids.push_back(id);
    for (Id r = 0; r < m.num_nodes() / 4; ++r) ids.push_back(std::uniform_int_distribution<Id>(0, m.num_nodes() - 1)(rng));
    std::shuffle(ids.begin(), ids.end(), rng);
    std::vector<Vec3> pts(ids.size());
    MeshCursor cur;
    m.nodes(ids, pts, cur);
    for (size_t q = 0; q < ids.size(); ++q)
      ASSERT_TRUE(same_bits(pts[q], by_id[static_cast<size_t>(ids[q])])) << where << " nodes(), node " << ids[q];
    ids.clear();
    for (Id e = 0; e < m.num_elements(); ++e) ids.push_back(e);
    for (Id r = 0; r < m.num_elements() / 4; ++r)
      ids.push_back(std::uniform_int_distribution<Id>(0, m.num_elements() - 1)(rng));
    std::shuffle(ids.begin(), ids.end(), rng);
    std::vector<FineElement> els(ids.size());
    m.elements(ids, els, cur);
    for (size_t q = 0; q < ids.size(); ++q) {
      const FineElement one = f.element(ids[q]);
      ASSERT_EQ(els[q].id, one.id) << where;
      ASSERT_EQ(els[q].nodes, one.nodes) << where << " elements(), element " << ids[q];
      ASSERT_EQ(els[q].num_nodes, one.num_nodes);
      ASSERT_EQ(els[q].coarse_element, one.coarse_element);
      ASSERT_EQ(els[q].block, one.block);
      ASSERT_EQ(els[q].ijk, one.ijk) << where << " elements(), element " << ids[q];
    }
  };
  check_batched_queries(f, "in memory");

  write_store(f, store_path);
  const FineMesh s = read_store(store_path, StoreOptions{4ull << 20, 0});
  EXPECT_EQ(s.num_bounding_nodes(), f.num_bounding_nodes());
  EXPECT_EQ(s.info().source_order, f.info().source_order);
  EXPECT_EQ(s.sheet_gradings(), f.sheet_gradings());
  for (Id id = 0; id < s.num_nodes(); ++id) ASSERT_TRUE(same_bits(s.node(id), by_id[id])) << "store node " << id;
  check_batched_queries(s, "store");
  NodeCursor sc(s);
  Id id;
  Vec3 p;
  while (sc.next(id, p)) ASSERT_TRUE(same_bits(p, by_id[id])) << "store cursor node " << id;
  EXPECT_EQ(sweep(s, 2).checksum, sweep(f, 1).checksum);
  if (!verify_store) return;
  const VerifyReport vr = verify(s);
  EXPECT_TRUE(vr.ok()) << (vr.problems.empty() ? std::string() : vr.problems.front());
}

}  // namespace dicer::test
