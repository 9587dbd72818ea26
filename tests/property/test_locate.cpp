// Point location (locate.hpp) on random coarse meshes, in memory and through
// the store: a point made from a random xi in a random fine element comes
// back in that element with that xi, or in a lower-id element that also
// contains it (a shared face); points outside every element come back -1.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>

#include "dicer/error.hpp"
#include "dicer/locate.hpp"
#include "dicer/quadratic.hpp"
#include "dicer/store.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

// The first N nodes of element e (8: HEX8, 4: QUAD4), as node(id) gives them.
template <size_t N = 8>
std::array<std::array<double, 3>, N> nodes_of(const FineMesh& m, Id e) {
  const FineElement el = m.element(e);
  std::array<std::array<double, 3>, N> x;
  for (size_t q = 0; q < N; ++q) {
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

// Surface stores: the nearest fine quad. The cylinder-facet sheets have
// planar rectangular quads (TFI of a rectangle is a grid of rectangles), so
// the nearest point of every fine quad has a closed form, independent of
// the library's Newton solve: project onto the quad's two edge directions
// and clamp. A brute force over every fine quad is the reference.
namespace {

double rect_distance(const std::array<std::array<double, 3>, 4>& x, const std::array<double, 3>& p) {
  double e1[3], e2[3], r[3], a = 0, b = 0, l1 = 0, l2 = 0;
  for (int d = 0; d < 3; ++d) {
    e1[d] = x[1][d] - x[0][d], e2[d] = x[3][d] - x[0][d], r[d] = p[d] - x[0][d];
    a += r[d] * e1[d], b += r[d] * e2[d], l1 += e1[d] * e1[d], l2 += e2[d] * e2[d];
  }
  const double s = std::clamp(a / l1, 0.0, 1.0), t = std::clamp(b / l2, 0.0, 1.0);
  double d2 = 0;
  for (int d = 0; d < 3; ++d) d2 += std::pow(x[0][d] + s * e1[d] + t * e2[d] - p[d], 2);
  return std::sqrt(d2);
}

}  // namespace

TEST(Locate, SurfacePointsGetTheNearestQuadAsABruteForceDoes) {
  std::mt19937_64 rng(5);
  test::TempDir tmp;
  for (int trial = 0; trial < 4; ++trial) {
    IntervalRequest req;
    req.global = 2 + trial % 3;
    const FineMesh mem = FineMesh::dice(test::random_quad_sheet(3 + trial % 2, 2 + trial % 2, trial > 0, rng), req);
    const std::string path = tmp.path("s" + std::to_string(trial) + ".dice.h5");
    write_store(mem, path);
    const FineMesh store = read_store(path);
    std::vector<std::array<std::array<double, 3>, 4>> quads;
    for (Id e = 0; e < mem.num_elements(); ++e) quads.push_back(nodes_of<4>(mem, e));
    // Points anywhere around the sheet (a cylinder part of radius 3,
    // height about 1): inside, outside, beyond its ends.
    std::uniform_real_distribution<double> u(-4, 4), z(-1, 2.5);
    std::vector<double> batch;
    for (int k = 0; k < 150; ++k) {
      const std::array<double, 3> p = {u(rng), u(rng), z(rng)};
      batch.insert(batch.end(), p.begin(), p.end());
      double nearest = INFINITY;
      for (const auto& q : quads) nearest = std::min(nearest, rect_distance(q, p));
      const Located got = locate_point(mem, p);
      ASSERT_GE(got.element, 0);
      const double tol = 1e-9 * 4;
      EXPECT_NEAR(got.distance, nearest, tol) << "point " << k;
      // Its xi gives the point at that distance, on its quad.
      const auto at = bilinear(quads[static_cast<size_t>(got.element)], got.xi);
      double d2 = 0;
      for (int d = 0; d < 3; ++d) d2 += std::pow(at[d] - p[d], 2);
      EXPECT_NEAR(std::sqrt(d2), got.distance, tol);
      EXPECT_EQ(got.xi[2], 0);
      for (int d = 0; d < 2; ++d) EXPECT_TRUE(got.xi[d] >= 0 && got.xi[d] <= 1) << got.xi[d];
      // The lowest id among the quads as near.
      for (Id e = 0; e < got.element; ++e)
        EXPECT_GT(rect_distance(quads[static_cast<size_t>(e)], p), nearest + 1e-12) << "element " << e << " is as near";
      // A limit below the distance finds nothing; at it, the same answer.
      const Located below = locate_point(mem, p, nearest * (1 - 1e-6));
      EXPECT_EQ(below.element, nearest > 1e-9 ? -1 : got.element);
      if (below.element < 0) {
        EXPECT_EQ(below.distance, INFINITY) << "a miss has no distance (0 would read: on it)";
      }
      EXPECT_EQ(locate_point(mem, p, nearest * (1 + 1e-6) + 1e-12).element, got.element);
    }
    // Store, threads and memory agree bit for bit.
    const std::vector<Located> a = locate_points(store, batch, 2), b = locate_points(mem, batch, 1);
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].element, b[i].element);
      EXPECT_EQ(a[i].xi, b[i].xi);
      EXPECT_EQ(a[i].distance, b[i].distance);
    }
  }
}

// A curved (second-order) surface store: the nearest fine quad of a
// QUAD9 patch on z = 0.4 sin(2.5 x) cos(1.7 y), against a brute force over
// every fine quad. The distance over a curved element's cells has more
// than one local minimum: a walk from the coarse patch's guess stopped in
// another (5 of 300 random points got a quad up to 3e-3 farther). The
// brute force samples each quad's bilinear map, then refines around the
// best sample twice: an upper bound of the true distance, within ~1e-7.
namespace {

double sampled_distance(const std::array<std::array<double, 3>, 4>& x, const std::array<double, 3>& p) {
  auto at = [&](double u, double v) {
    double d2 = 0;
    for (int d = 0; d < 3; ++d) {
      const double c = (1 - u) * (1 - v) * x[0][d] + u * (1 - v) * x[1][d] + u * v * x[2][d] + (1 - u) * v * x[3][d];
      d2 += (c - p[d]) * (c - p[d]);
    }
    return d2;
  };
  double best = INFINITY, bu = 0.5, bv = 0.5, half = 0.5;
  for (int level = 0; level < 4; ++level) {
    const double u0 = bu, v0 = bv;
    for (int i = -20; i <= 20; ++i)
      for (int j = -20; j <= 20; ++j) {
        const double u = std::clamp(u0 + half * i / 20, 0.0, 1.0), v = std::clamp(v0 + half * j / 20, 0.0, 1.0);
        if (const double d2 = at(u, v); d2 < best) best = d2, bu = u, bv = v;
      }
    half /= 10;
  }
  return std::sqrt(best);
}

}  // namespace

TEST(Locate, CurvedSurfacePointsGetTheNearestQuadAsABruteForceDoes) {
  test::TempDir tmp;
  const int a = 3, b = 2, I = 2 * a + 1, J = 2 * b + 1;
  auto node = [&](int i, int j) { return 1 + i + I * j; };
  std::string msh = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n" + std::to_string(I * J) + "\n";
  char line[160];
  for (int j = 0; j < J; ++j)
    for (int i = 0; i < I; ++i) {
      const double x = static_cast<double>(i) / (2 * a) + 0.1 * std::sin(static_cast<double>(j)), y = static_cast<double>(j) / (2 * b);
      std::snprintf(line, sizeof line, "%d %.17g %.17g %.17g\n", node(i, j), x, y, 0.4 * std::sin(2.5 * x) * std::cos(1.7 * y));
      msh += line;
    }
  msh += "$EndNodes\n$Elements\n" + std::to_string(a * b) + "\n";
  int e = 0;
  for (int j = 0; j < b; ++j)
    for (int i = 0; i < a; ++i) {
      const int c = 2 * i, r = 2 * j;  // QUAD9: corners, the sides' mid nodes (01, 12, 23, 30), the centre
      std::snprintf(line, sizeof line, "%d 10 2 1 1 %d %d %d %d %d %d %d %d %d\n", ++e, node(c, r), node(c + 2, r),
                    node(c + 2, r + 2), node(c, r + 2), node(c + 1, r), node(c + 2, r + 1), node(c + 1, r + 2),
                    node(c, r + 1), node(c + 1, r + 1));
      msh += line;
    }
  msh += "$EndElements\n";
  test::write_file(tmp.path("q9.msh"), msh);
  IntervalRequest req;
  req.global = 3;
  FineMesh mem = FineMesh::dice(read_coarse_mesh(tmp.path("q9.msh")), req);
  apply_second_order(mem);
  ASSERT_EQ(mem.num_elements(), 54);
  std::vector<std::array<std::array<double, 3>, 4>> quads;
  for (Id f = 0; f < mem.num_elements(); ++f) quads.push_back(nodes_of<4>(mem, f));
  std::mt19937_64 rng(55);
  std::uniform_real_distribution<double> ux(-0.3, 1.5), uy(-0.3, 1.3), uz(-0.6, 0.8);
  int far_by_more = 0;
  for (int k = 0; k < 300; ++k) {
    const std::array<double, 3> p = {ux(rng), uy(rng), uz(rng)};
    double nearest = INFINITY;
    for (const auto& q : quads) nearest = std::min(nearest, sampled_distance(q, p));
    const Located got = locate_point(mem, p);
    ASSERT_GE(got.element, 0);
    // Never farther than a quad the brute force found; as near as the
    // brute force's resolution allows.
    if (!(got.distance <= nearest + 1e-12)) ++far_by_more;
    EXPECT_LE(got.distance, nearest + 1e-12) << "point " << k << ": quad " << got.element;
    EXPECT_GE(got.distance, nearest - 1e-6) << "point " << k;
    EXPECT_NEAR(sampled_distance(quads[static_cast<size_t>(got.element)], p), got.distance, 1e-6) << "point " << k;
    // --max-distance just above the distance keeps the answer.
    EXPECT_EQ(locate_point(mem, p, nearest * (1 + 1e-9) + 1e-12).element, got.element) << "point " << k;
  }
  EXPECT_EQ(far_by_more, 0);
}

TEST(Locate, SurfacePointsOnAndOffTwistedQuadsComeBackWithTheirXi) {
  // Non-planar coarse quads (each vertex lifted at random): bilinear
  // patches, not planes. A point made at xi of a fine quad, moved along the
  // quad's normal there by less than its size, has that foot point as its
  // nearest: the same element and xi, at the distance moved.
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 3; ++trial) {
    CoarseMesh cm = test::random_quad_sheet(3, 3, true, rng);
    std::uniform_real_distribution<double> lift(-0.15, 0.15);
    for (Id v = 0; v < cm.num_vertices(); ++v) {
      const double r = 1 + lift(rng);
      cm.x[v] *= r, cm.y[v] *= r;
    }
    IntervalRequest req;
    req.global = 2 + trial;
    const FineMesh m = FineMesh::dice(cm, req);
    std::uniform_int_distribution<Id> pick(0, m.num_elements() - 1);
    std::uniform_real_distribution<double> in(0.25, 0.75), off(-0.02, 0.02);
    for (int k = 0; k < 80; ++k) {
      const Id e = pick(rng);
      const auto x = nodes_of<4>(m, e);
      const std::array<double, 3> xi = {in(rng), in(rng), 0};
      const auto p0 = bilinear(x, xi);
      // The normal: the cross product of the map's derivatives at xi.
      double xu[3], xv[3];
      for (int d = 0; d < 3; ++d) {
        xu[d] = (x[1][d] - x[0][d]) * (1 - xi[1]) + (x[2][d] - x[3][d]) * xi[1];
        xv[d] = (x[3][d] - x[0][d]) * (1 - xi[0]) + (x[2][d] - x[1][d]) * xi[0];
      }
      std::array<double, 3> n = {xu[1] * xv[2] - xu[2] * xv[1], xu[2] * xv[0] - xu[0] * xv[2], xu[0] * xv[1] - xu[1] * xv[0]};
      const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), h = std::sqrt(xu[0] * xu[0] + xu[1] * xu[1] + xu[2] * xu[2]);
      const double delta = k % 4 == 0 ? 0.0 : off(rng) * h;
      std::array<double, 3> p;
      for (int d = 0; d < 3; ++d) p[d] = p0[d] + delta * n[d] / len;
      const Located got = locate_point(m, p);
      ASSERT_EQ(got.element, e) << "point " << k << " made in element " << e;
      EXPECT_NEAR(got.xi[0], xi[0], 1e-8);
      EXPECT_NEAR(got.xi[1], xi[1], 1e-8);
      EXPECT_NEAR(got.distance, std::abs(delta), 1e-10 * h);
    }
  }
}

TEST(Locate, ANegativeOrNanLimitIsAUsageError) {
  std::mt19937_64 rng(5);
  IntervalRequest req;
  req.global = 2;
  const FineMesh m = FineMesh::dice(test::random_quad_sheet(2, 2, true, rng), req);
  for (double bad : {-1.0, std::nan("")}) {
    try {
      locate_point(m, {0, 0, 0}, bad);
      ADD_FAILURE() << "limit " << bad << " accepted";
    } catch (const Error& e) {
      EXPECT_EQ(e.kind(), ErrorKind::Usage);
    }
  }
}
