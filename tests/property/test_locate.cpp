// Point location (locate.hpp) on random coarse meshes, in memory and through
// the store: a point made from a random xi in a random fine element comes
// back in that element with that xi, or in a lower-id element that also
// contains it (a shared face); points outside every element come back -1.
#include <gtest/gtest.h>

#include <map>
#include <random>

#include "dicer/error.hpp"
#include "dicer/locate.hpp"
#include "dicer/store.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

std::array<std::array<double, 3>, 8> nodes_of(const FineMesh& m, Id e) {
  const FineElement el = m.element(e);
  std::array<std::array<double, 3>, 8> x;
  for (int q = 0; q < 8; ++q) {
    const Vec3 v = m.node(el.nodes[q]);
    x[q] = {v.x, v.y, v.z};
  }
  return x;
}

double size_of(const std::array<std::array<double, 3>, 8>& x) {
  double s = 0;
  for (int q = 1; q < 8; ++q)
    for (int d = 0; d < 3; ++d) s = std::max(s, std::abs(x[q][d] - x[0][d]));
  return s;
}

// The answer for p made at xi in element e: e itself with xi, or another
// element whose map at its xi gives p (on a shared face) with a lower id.
void check_answer(const FineMesh& m, Id e, const std::array<double, 3>& xi, const std::array<double, 3>& p,
                  const Located& got) {
  ASSERT_GE(got.element, 0) << "element " << e;
  const auto x = nodes_of(m, got.element);
  const double tol = 1e-9 * size_of(x);
  const auto back = trilinear(x, got.xi);
  for (int d = 0; d < 3; ++d) {
    EXPECT_NEAR(back[d], p[d], tol) << "element " << got.element;
    EXPECT_GE(got.xi[d], -1e-9);
    EXPECT_LE(got.xi[d], 1 + 1e-9);
  }
  if (got.element == e) {
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(got.xi[d], xi[d], 1e-9) << "element " << e;
  } else {
    EXPECT_LT(got.element, e) << "a point inside element " << e << " on no shared face";
  }
}

}  // namespace

TEST(Locate, RandomPointsInRandomElementsComeBackWithTheirXi) {
  std::mt19937_64 rng(777);
  test::TempDir tmp;
  for (int trial = 0; trial < 6; ++trial) {
    test::BoxSpec spec;
    spec.a = 2 + trial % 3, spec.b = 2 + (trial / 2) % 2, spec.c = 1 + trial % 2;
    const CoarseMesh cm = test::random_box(spec, rng);
    IntervalRequest req;
    req.global = 2 + trial % 3;
    const FineMesh mem = FineMesh::dice(cm, req);
    const std::string path = tmp.path("t" + std::to_string(trial) + ".dice.h5");
    write_store(mem, path);
    const FineMesh store = read_store(path);
    std::uniform_int_distribution<Id> pick(0, mem.num_elements() - 1);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<double> batch;
    std::vector<std::pair<Id, std::array<double, 3>>> made;
    for (int k = 0; k < 60; ++k) {
      const Id e = pick(rng);
      std::array<double, 3> xi = {u(rng), u(rng), u(rng)};
      if (k % 10 == 0) xi[k % 3] = 0;  // on a face: the lowest id that holds it
      const auto p = trilinear(nodes_of(mem, e), xi);
      check_answer(mem, e, xi, p, locate_point(mem, p));
      batch.insert(batch.end(), p.begin(), p.end());
      made.emplace_back(e, xi);
    }
    // The store and the threaded batch give the same answers bit for bit.
    const std::vector<Located> a = locate_points(store, batch, 2), b = locate_points(mem, batch, 1);
    ASSERT_EQ(a.size(), made.size());
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].element, b[i].element);
      EXPECT_EQ(a[i].xi, b[i].xi);
      check_answer(store, made[i].first, made[i].second, {batch[3 * i], batch[3 * i + 1], batch[3 * i + 2]}, a[i]);
    }
    // Outside: beyond the box of all nodes.
    double hi = -1e300;
    for (Id v = 0; v < cm.num_vertices(); ++v) hi = std::max(hi, cm.vertex(v).x);
    EXPECT_EQ(locate_point(store, {hi + 0.5, 0.5, 0.5}).element, -1);
    EXPECT_EQ(locate_point(mem, {-10, -10, -10}).element, -1);
  }
}

TEST(Locate, ANodeSharedByEightElementsGivesTheLowestId) {
  std::mt19937_64 rng(3);
  test::BoxSpec spec;
  spec.a = spec.b = spec.c = 2;
  spec.perturb = 0;
  const CoarseMesh cm = test::random_box(spec, rng);
  IntervalRequest req;
  req.global = 3;
  const FineMesh m = FineMesh::dice(cm, req);
  // Every fine node: the elements using it by brute force; the answer is the lowest.
  std::map<Id, Id> lowest;
  for (Id e = m.num_elements() - 1; e >= 0; --e)
    for (Id n : m.element(e).nodes) lowest[n] = e;
  for (const auto& [n, e] : lowest) {
    const Vec3 v = m.node(n);
    const Located got = locate_point(m, {v.x, v.y, v.z});
    EXPECT_EQ(got.element, e) << "node " << n;
  }
}

TEST(Locate, SurfaceStoresAreRefused) {
  std::mt19937_64 rng(5);
  IntervalRequest req;
  req.global = 2;
  const FineMesh m = FineMesh::dice(test::random_quad_sheet(2, 2, true, rng), req);
  EXPECT_THROW(locate_point(m, {0, 0, 0}), Error);
}
