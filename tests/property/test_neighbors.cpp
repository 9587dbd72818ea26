// element_neighbors and node_elements (neighbors.hpp) against a brute-force matching of fine
// faces (edges) by their sorted node ids, on random coarse meshes whose hexes
// have random local numberings (so coarse faces meet rotated and flipped),
// in memory and through the store; and symmetry.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>

#include "dicer/error.hpp"
#include "dicer/neighbors.hpp"
#include "dicer/orientation.hpp"
#include "dicer/store.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

// For every element and Exodus side: the other element with the same side
// nodes, or -1.
std::vector<std::vector<Id>> brute_force(const FineMesh& m) {
  const bool vol = m.mode() == Mode::Volume;
  const int sides = vol ? 6 : 4, per = vol ? 4 : 2;
  std::map<std::vector<Id>, std::vector<std::pair<Id, int>>> by_nodes;
  for (Id e = 0; e < m.num_elements(); ++e) {
    const FineElement el = m.element(e);
    for (int s = 0; s < sides; ++s) {
      std::vector<Id> key;
      for (int q = 0; q < per; ++q) key.push_back(el.nodes[vol ? kHexSideCorners[s][q] : kShellSideCorners[s][q]]);
      std::sort(key.begin(), key.end());
      by_nodes[key].emplace_back(e, s);
    }
  }
  std::vector<std::vector<Id>> out(static_cast<size_t>(m.num_elements()), std::vector<Id>(sides, -1));
  for (const auto& [key, users] : by_nodes) {
    EXPECT_LE(users.size(), 2u);
    if (users.size() == 2) {
      out[users[0].first][users[0].second] = users[1].first;
      out[users[1].first][users[1].second] = users[0].first;
    }
  }
  return out;
}

void check(const FineMesh& m) {
  // node_elements: every node's elements, by brute force.
  {
    std::vector<std::vector<Id>> users(static_cast<size_t>(m.num_nodes()));
    for (Id e = 0; e < m.num_elements(); ++e) {
      const FineElement el = m.element(e);
      for (int q = 0; q < m.corners(); ++q) users[el.nodes[q]].push_back(e);
    }
    for (Id n = 0; n < m.num_nodes(); ++n) ASSERT_EQ(node_elements(m, n), users[n]) << "node " << n;
  }
  const auto want = brute_force(m);
  for (Id e = 0; e < m.num_elements(); ++e) {
    const std::vector<Id> got = element_neighbors(m, e);
    ASSERT_EQ(got, want[e]) << "element " << e;
    for (Id n : got)
      if (n >= 0) {
        const auto back = element_neighbors(m, n);
        EXPECT_NE(std::find(back.begin(), back.end(), e), back.end()) << e << " -> " << n << " but not back";
      }
  }
}

}  // namespace

TEST(Neighbors, RandomRotatedHexesAgreeWithBruteForceAndAreSymmetric) {
  std::mt19937_64 rng(4242);
  test::TempDir tmp;
  for (int trial = 0; trial < 6; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    test::BoxSpec spec;
    spec.a = 2 + trial % 2, spec.b = 2, spec.c = 1 + trial % 3;
    const CoarseMesh cm = test::random_box(spec, rng);
    IntervalRequest req;
    std::uniform_int_distribution<Id> n(1, 3);
    for (Id q = 0; q < spec.a + spec.b + spec.c; ++q) req.sheets.emplace_back(q, n(rng));  // mixed intervals
    const FineMesh m = FineMesh::dice(cm, req);
    check(m);
    if (trial < 2) {
      const std::string path = tmp.path("n.dice.h5");
      write_store(m, path);
      check(read_store(path));
    }
  }
}

TEST(Neighbors, RandomQuadSheetsAgreeWithBruteForce) {
  std::mt19937_64 rng(99);
  for (int trial = 0; trial < 4; ++trial) {
    IntervalRequest req;
    req.global = 1 + trial;
    check(FineMesh::dice(test::random_quad_sheet(2 + trial % 2, 3, true, rng), req));
  }
}

TEST(Neighbors, IdOutsideTheMeshIsAUsageError) {
  std::mt19937_64 rng(1);
  IntervalRequest req;
  req.global = 2;
  const FineMesh m = FineMesh::dice(test::random_box(test::BoxSpec{}, rng), req);
  EXPECT_THROW(element_neighbors(m, m.num_elements()), Error);
  EXPECT_THROW(element_neighbors(m, -1), Error);
  EXPECT_THROW(node_elements(m, m.num_nodes()), Error);
}
