// The owner search (rows.hpp: RowReader::search_first), which every
// node(id) and element(id) of a store starts with, against a linear scan.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "dicer/fine_mesh.hpp"
#include "dicer/numbering.hpp"
#include "dicer/rows.hpp"
#include "dicer/store.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

// The owner search (rows.hpp: search_first) gives the first row whose
// node_first / element_first exceeds x, as a linear scan finds it: for ids
// on and between the rows' values and past both ends, from any start row,
// without hints (it reads the ends) and with any hints: true ones (the
// values a page index would give), and wrong ones, which may only cost
// probes. The intervals vary by sheet, so rows own unequal id counts and
// the interpolation misses.
TEST(RowSearch, AnyHintsGiveTheFirstRowAbove) {
  std::mt19937_64 rng(41);
  test::BoxSpec spec;
  spec.a = 4, spec.b = 3, spec.c = 2;
  IntervalRequest req;
  req.global = 2;
  req.sheets = {{0, 1}, {1, 3}, {3, 7}};
  const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
  MeshCursor cur;
  const RowReader R(f.tables(), cur);
  const Id H = f.num_coarse_elements();
  for (const bool by_node : {true, false}) {
    auto value = [&](Id h) { return by_node ? R.node_first(h) : R.element_first(h); };
    const Id top = by_node ? f.num_nodes() : f.num_elements();
    std::uniform_int_distribution<std::int64_t> any(-5, top + 5);
    for (Id x = -1; x <= top; ++x) {
      Id want = 0;
      while (want < H && value(want) <= x) ++want;
      for (Id lo : {Id{0}, H / 3, H - 1}) {
        const Id expect = std::max(want, lo);
        ASSERT_EQ(R.search_first(lo, H, x, by_node), expect) << "x " << x << " from " << lo;
        std::vector<RowReader::SearchHints> hints = {{value(lo), top}, {value(lo), value(lo)}, {top, 0}, {x, x + 1}};
        for (int k = 0; k < 8; ++k) hints.push_back({any(rng), any(rng)});
        for (const auto& h : hints)
          ASSERT_EQ(R.search_first(lo, H, x, by_node, &h), expect)
              << "x " << x << " from " << lo << " hints " << h.at_lo << ", " << h.at_hi << (by_node ? " (nodes)" : " (elements)");
      }
    }
  }
}

// In memory the search starts from the id guide (tables.hpp IdGuide) and
// reads the dense search columns (Table::derive_in_memory), both built by
// FineMesh's constructor: every node and element id must still find the
// owner a linear scan of the rows finds, on meshes whose sheets have 1 to
// 7 intervals, with the guide taken away (the plain search), and after the
// element table was written to (its dense columns dropped: the guide must
// go unused).
TEST(RowSearch, InMemoryGuideFindsTheOwnerOfEveryId) {
  std::mt19937_64 rng(43);
  for (int trial = 0; trial < 6; ++trial) {
    test::BoxSpec spec;
    spec.a = 2 + static_cast<int>(rng() % 4), spec.b = 1 + static_cast<int>(rng() % 3), spec.c = 1 + static_cast<int>(rng() % 3);
    IntervalRequest req;
    req.global = 1 + static_cast<Id>(rng() % 3);
    req.sheets = {{0, 1 + static_cast<Id>(rng() % 7)}, {1, 1}};
    const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
    const MeshTables& t = f.tables();
    ASSERT_FALSE(t.node_guide.row.empty());
    ASSERT_FALSE(t.element_guide.row.empty());
    MeshCursor cur;
    ASSERT_NE(t.elements.derived(0, 0, cur.elements), nullptr) << "the dense columns are in place";
    MeshTables plain = t;
    plain.node_guide = IdGuide{}, plain.element_guide = IdGuide{};
    MeshTables written = t;  // a table written to drops its dense columns, and the guide goes unused
    written.elements.memory();
    ASSERT_EQ(written.elements.derived(0, 0, cur.elements), nullptr);
    const RowReader R(t, cur);
    const Id H = f.num_coarse_elements();
    for (const bool by_node : {true, false}) {
      const Id top = by_node ? f.num_nodes() : f.num_elements();
      Id want = -1;  // the last row whose first id is <= x
      for (Id x = 0; x < top; ++x) {
        while (want + 1 < H && (by_node ? R.node_first(want + 1) : R.element_first(want + 1)) <= x) ++want;
        std::array<Id, 3> ijk{};
        for (const MeshTables* m : {&t, static_cast<const MeshTables*>(&plain), static_cast<const MeshTables*>(&written)}) {
          const Id got = by_node ? owner_element(*m, x, cur) : locate_element(*m, x, ijk, cur);
          ASSERT_EQ(got, want) << (by_node ? "node " : "element ") << x
                               << (m == &t ? " (guide)" : m == &plain ? " (no guide)" : " (rows written to)") << " trial " << trial;
        }
      }
    }
  }
}

// Table's page arithmetic (tables.hpp FixedDivisor) against the hardware
// division: every divisor up to 300 and random ones up to 2^40, dividends
// at and around multiples of the divisor, random ones, and the extremes.
TEST(RowSearch, FixedDivisorEqualsDivision) {
  std::mt19937_64 rng(47);
  std::vector<std::uint64_t> divisors;
  for (std::uint64_t d = 1; d <= 300; ++d) divisors.push_back(d);
  for (int i = 0; i < 200; ++i) divisors.push_back(1 + rng() % (std::uint64_t{1} << (1 + rng() % 40)));
  divisors.push_back((std::uint64_t{1} << 62) - 1);
  for (const std::uint64_t d : divisors) {
    const FixedDivisor div(d);
    std::vector<std::uint64_t> ns = {0, 1, d - 1, d, d + 1, 2 * d - 1, 2 * d, ~std::uint64_t{0}, ~std::uint64_t{0} - d,
                                     std::uint64_t{1} << 63, (std::uint64_t{1} << 63) - 1};
    for (int i = 0; i < 200; ++i) ns.push_back(rng() >> (rng() % 64));
    for (int i = 0; i < 50; ++i) {
      const std::uint64_t k = rng() % (~std::uint64_t{0} / d);
      ns.insert(ns.end(), {k * d, k * d + d - 1, k * d - 1});
    }
    for (const std::uint64_t n : ns) ASSERT_EQ(div(n), n / d) << n << " / " << d;
  }
}

// A store whose element table is kept fills its node-id guide (tables.hpp
// LazyIdGuide) page by page as searches land: every node's owner is the
// bisection's answer on the first pass (guide filling) and the second
// (guide filled), and the filled guide equals the in-memory guide built
// from all rows at once. Intervals vary by sheet and include 1 (elements
// that own no node: equal first ids, also across page ends), and the box
// spans several pages of rows.
TEST(RowSearch, StoreNodeGuideFilledAsItGoesFindsEveryOwner) {
  std::mt19937_64 rng(53);
  test::TempDir tmp;
  for (int trial = 0; trial < 3; ++trial) {
    test::BoxSpec spec;
    spec.a = 9, spec.b = 7, spec.c = 4 + trial;
    IntervalRequest req;
    req.global = 1;
    req.sheets = {{0, 1 + static_cast<Id>(rng() % 4)}, {2, 3}, {5, 2}};
    const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
    const std::string path = tmp.path("g" + std::to_string(trial) + ".dice.h5");
    write_store(f, path);
    const FineMesh s = read_store(path);
    const MeshTables& t = s.tables();
    ASSERT_TRUE(t.elements.kept_resident());
    ASSERT_GT(t.elements.pages(), 1) << "the test needs rows on several pages";
    ASSERT_TRUE(t.node_row_guide);
    const LazyIdGuide& g = *t.node_row_guide;
    const IdGuide mem = build_id_guide(t, true);  // over the store's rows, all at once
    ASSERT_EQ(g.shift, mem.shift);
    ASSERT_EQ(g.buckets, mem.row.size());
    MeshCursor cur, scan;
    const RowReader R(t, scan);
    const Id H = s.num_coarse_elements();
    for (int pass = 0; pass < 2; ++pass) {
      // Ids in a random order, so buckets fill in no particular order.
      std::vector<Id> ids(static_cast<size_t>(s.num_nodes()));
      for (size_t i = 0; i < ids.size(); ++i) ids[i] = static_cast<Id>(i);
      std::shuffle(ids.begin(), ids.end(), rng);
      for (const Id x : ids) {
        Id lo = 0, hi = H;  // the last row whose first id is <= x: lo - 1
        while (lo < hi) {
          const Id mid = lo + (hi - lo) / 2;
          if (R.node_first(mid) <= x) lo = mid + 1;
          else hi = mid;
        }
        ASSERT_EQ(owner_element(t, x, cur), lo - 1) << "node " << x << " pass " << pass << " trial " << trial;
      }
    }
    for (size_t b = 0; b < g.buckets; ++b) ASSERT_EQ(g.row[b].load(), mem.row[b]) << "bucket " << b;
  }
}
