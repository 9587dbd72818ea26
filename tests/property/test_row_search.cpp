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
