// The owner search (rows.hpp: RowReader::search_first), which every
// node(id) and element(id) of a store starts with, against a linear scan.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "dicer/fine_mesh.hpp"
#include "dicer/rows.hpp"
#include "random_mesh.hpp"

using namespace dicer;

// The owner search from any starting guess (rows.hpp: search_first) gives
// the first row whose node_first / element_first exceeds x, as a linear
// scan finds it: for every guess in the page, ids on and between the rows'
// values, and past both ends.
TEST(RowSearch, AnyGuessGivesTheFirstRowAbove) {
  std::mt19937_64 rng(41);
  test::BoxSpec spec;
  spec.a = 4, spec.b = 3, spec.c = 2;
  IntervalRequest req;
  req.global = 2;
  req.sheets = {{0, 1}, {1, 3}};
  const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
  MeshCursor cur;
  const RowReader R(f.tables(), cur);
  const Id H = f.num_coarse_elements();
  for (const bool by_node : {true, false}) {
    auto value = [&](Id h) { return by_node ? R.node_first(h) : R.element_first(h); };
    const Id top = by_node ? f.num_nodes() : f.num_elements();
    for (Id x = -1; x <= top; ++x) {
      Id want = 0;
      while (want < H && value(want) <= x) ++want;
      for (Id lo : {Id{0}, H / 3})
        for (Id guess = -1; guess < H; ++guess)
          ASSERT_EQ(R.search_first(lo, H, x, by_node, guess), std::max(want, lo))
              << "x " << x << " from " << lo << " guess " << guess << (by_node ? " (nodes)" : " (elements)");
    }
  }
}
