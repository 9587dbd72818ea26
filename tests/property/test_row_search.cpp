// The owner search (rows.hpp: RowReader::search_first), which every
// node(id) and element(id) of a store starts with, against a linear scan.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "dicer/fine_mesh.hpp"
#include "dicer/rows.hpp"
#include "random_mesh.hpp"

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
