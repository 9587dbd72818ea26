// Coincident and hanging coarse vertices found before dicing
// (coarse_conformity.hpp), on meshes whose answer is known by
// construction, and the warning `dice` prints with file ids.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <set>
#include <sstream>

#include "dicer/coarse_conformity.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

CoarseMesh make(Mode mode, const std::vector<std::array<double, 3>>& pts, std::vector<Id> conn) {
  CoarseMesh m;
  m.source = "built";
  m.mode = mode;
  for (const auto& p : pts) m.x.push_back(p[0]), m.y.push_back(p[1]), m.z.push_back(p[2]);
  m.conn = std::move(conn);
  validate_coarse_mesh(m);
  return m;
}

// A 2 x 2 x 2 hex [0,2]^3 next to four unit hexes in x in [2,3] that share
// its x = 2 face's corners (same vertex ids): the small faces' mid-edge and
// centre vertices, (2,1,0), (2,0,1), (2,2,1), (2,1,2) and (2,1,1), lie in
// the big hex's face: 5 hanging vertices.
CoarseMesh two_to_one() {
  std::vector<std::array<double, 3>> pts = {{0, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0},
                                            {0, 0, 2}, {2, 0, 2}, {2, 2, 2}, {0, 2, 2}};
  // Grid points of x in {2, 3}, y, z in {0, 1, 2}; x = 2 corners reuse 1, 2, 5, 6.
  auto id = [&](int i, int j, int k) -> Id {
    if (i == 0 && (j == 0 || j == 2) && (k == 0 || k == 2)) return j == 0 ? (k == 0 ? 1 : 5) : (k == 0 ? 2 : 6);
    const std::array<double, 3> p = {2.0 + i, static_cast<double>(j), static_cast<double>(k)};
    for (size_t q = 0; q < pts.size(); ++q)
      if (pts[q] == p) return static_cast<Id>(q);
    pts.push_back(p);
    return static_cast<Id>(pts.size() - 1);
  };
  std::vector<Id> conn = {0, 1, 2, 3, 4, 5, 6, 7};
  for (int j = 0; j < 2; ++j)
    for (int k = 0; k < 2; ++k)
      for (const auto& c : {std::array<int, 3>{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}})
        conn.push_back(id(c[0], j + c[1], k + c[2]));
  return make(Mode::Volume, pts, conn);
}

CoarseConformity check(const CoarseMesh& m) { return check_coarse_conformity(m, build_topology(m)); }

}  // namespace

TEST(CoarseConformity, ConformingRandomMeshesAreClean) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 6; ++trial) {
    test::BoxSpec spec;
    spec.a = 2 + trial % 3, spec.b = 2 + trial % 2, spec.c = 1 + trial % 3;
    const CoarseMesh m = test::random_box(spec, rng);
    const CoarseConformity c = check(m);
    EXPECT_TRUE(c.ok()) << c.coincident_pairs << " coincident, " << c.hanging_vertices << " hanging";
    EXPECT_TRUE(check(test::random_quad_sheet(2 + trial, 3, true, rng)).ok());
  }
}

TEST(CoarseConformity, TwoToOneInterfaceHasFiveHangingVertices) {
  const CoarseMesh m = two_to_one();
  const CoarseConformity c = check(m);
  EXPECT_EQ(c.coincident_pairs, 0);
  EXPECT_EQ(c.hanging_vertices, 5);
  ASSERT_FALSE(c.hanging.empty());
  for (const auto& h : c.hanging) {
    EXPECT_EQ(h.element, 0) << "only the big hex's face holds them";
    EXPECT_EQ(m.x[h.vertex], 2.0);
  }
  // validate_coarse_mesh said so, with the ids as in the file (1-based here).
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_NE(m.warnings[0].find("5 hanging coarse vertice"), std::string::npos) << m.warnings[0];
  EXPECT_NE(m.warnings[0].find("inside the boundary face ["), std::string::npos) << m.warnings[0];
  EXPECT_NE(m.warnings[0].find("] of element 1"), std::string::npos) << m.warnings[0];
  // Not "dicer verify fails on it": verify passes elements that overlap.
  EXPECT_NE(m.warnings[0].find("(a T-junction, or elements that overlap)"), std::string::npos) << m.warnings[0];
}

TEST(CoarseConformity, DuplicatedInterfaceVerticesAreCoincidentNotHanging) {
  // Two unit hexes whose shared face has its own copies of the 4 vertices,
  // one of them at -0.0 (the same point).
  const CoarseMesh m =
      make(Mode::Volume,
           {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}, {2, 0, 0}, {2, 1, 0},
            {2, 0, 1}, {2, 1, 1}, {1, -0.0, 0}, {1, 1, 0}, {1, 0, 1}, {1, 1, 1}},
           {0, 1, 2, 3, 4, 5, 6, 7, 12, 8, 9, 13, 14, 10, 11, 15});
  const CoarseConformity c = check(m);
  EXPECT_EQ(c.coincident_pairs, 4);
  EXPECT_EQ(c.hanging_vertices, 0);
  ASSERT_EQ(c.coincident.size(), 4u);
  std::set<std::pair<Id, Id>> pairs;
  for (const auto& p : c.coincident) pairs.insert({p.a, p.b});
  EXPECT_EQ(pairs, (std::set<std::pair<Id, Id>>{{1, 12}, {2, 13}, {5, 14}, {6, 15}})) << "each face vertex with its copy";
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_NE(m.warnings[0].find("4 pair(s) of coarse vertices share coordinates (nodes 2 and 13 at (1, 0, 0)"),
            std::string::npos)
      << m.warnings[0];
}

TEST(CoarseConformity, SurfaceHangingVertexOnABoundaryEdge) {
  // A 2 x 2 quad and two unit quads splitting its right edge: (2,1,0) hangs.
  const CoarseMesh m = make(Mode::Surface, {{0, 0, 0}, {2, 0, 0}, {2, 2, 0}, {0, 2, 0}, {3, 0, 0}, {3, 1, 0}, {2, 1, 0}, {3, 2, 0}},
                            {0, 1, 2, 3, 1, 4, 5, 6, 6, 5, 7, 2});
  const CoarseConformity c = check(m);
  EXPECT_EQ(c.hanging_vertices, 1);
  ASSERT_EQ(c.hanging.size(), 1u);
  EXPECT_EQ(c.hanging[0].vertex, 6);
  EXPECT_EQ(c.coincident_pairs, 0);
}

TEST(CoarseConformity, CoordinatesFarBeyondTheFacetSizeGiveTheSameAnswer) {
  // The 2:1 interface and a hex 1e300 away (1e284 long in x, where a unit
  // step vanishes, 1 in y and z): the grid's cell is about a facet (1.4),
  // so that hex's cells are no integer (a fuzzed mesh cast them anyway:
  // undefined). The answer is the 2:1 interface's alone.
  CoarseMesh m = two_to_one();
  const Id v0 = static_cast<Id>(m.x.size());
  for (const auto& c : {std::array<int, 3>{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}}) {
    m.x.push_back(1e300 + c[0] * 1e284), m.y.push_back(c[1]), m.z.push_back(c[2]);
    m.conn.push_back(static_cast<Id>(m.x.size()) - 1);
  }
  ASSERT_EQ(m.conn.size(), 6u * 8u);
  ASSERT_EQ(m.conn[40], v0);
  const CoarseConformity c = check(m);
  EXPECT_EQ(c.hanging_vertices, 5);
  EXPECT_EQ(c.coincident_pairs, 0);
  // Two hexes so large that a facet's diagonal overflows (its size and
  // tolerance are infinite): conforming, so nothing hangs.
  const double s = 1e307;
  const CoarseMesh big = make(Mode::Volume,
                              {{0, 0, 0}, {s, 0, 0}, {s, s, 0}, {0, s, 0}, {0, 0, s}, {s, 0, s}, {s, s, s}, {0, s, s},
                               {-s, 0, 0}, {-s, s, 0}, {-s, 0, s}, {-s, s, s}},
                              {8, 0, 3, 9, 10, 4, 7, 11, 0, 1, 2, 3, 4, 5, 6, 7});
  const CoarseConformity cb = check(big);
  EXPECT_EQ(cb.hanging_vertices, 0);
  EXPECT_EQ(cb.coincident_pairs, 0);
}

TEST(CoarseConformity, DiceWarnsWithFileIds) {
  // MSH 2.2 with file node ids offset by 100: the warning names those.
  const CoarseMesh m = two_to_one();
  std::ostringstream s;
  s << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n" << m.num_vertices() << "\n";
  s.precision(17);
  for (Id v = 0; v < m.num_vertices(); ++v) s << 101 + v << " " << m.x[v] << " " << m.y[v] << " " << m.z[v] << "\n";
  s << "$EndNodes\n$Elements\n" << m.num_elements() << "\n";
  for (Id e = 0; e < m.num_elements(); ++e) {
    s << e + 1 << " 5 2 1 1";
    for (int k = 0; k < 8; ++k) s << " " << 101 + m.conn[8 * e + k];
    s << "\n";
  }
  s << "$EndElements\n";
  const test::TempDir dir;
  test::write_file(dir.path("two_to_one.msh"), s.str());
  const auto r = test::run_cli({"dice", dir.path("two_to_one.msh"), "--interval", "2", "-o", dir.path("t.dice.h5"), "--quiet"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("warning: " + dir.path("two_to_one.msh") + ": 5 hanging coarse vertice"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("of element 1"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("node 1"), std::string::npos) << "file ids are 101..: " << r.err;
  EXPECT_NE(r.err.find("inside the boundary face [102 "), std::string::npos) << "the big hex's corners are 101..108: " << r.err;
}

// Surface meshes whose quads do not all run one way round: a Moebius strip
// (no orientation exists: the half twist reverses one edge, the strip's
// closing one) and a strip with its middle quad flipped (both of its inner
// edges). Each is said when read; a consistently numbered strip and a
// random sheet are not. Counts by construction.
TEST(CoarseConformity, QuadsRunningBothWaysRoundAreSaid) {
  auto warned = [](const CoarseMesh& m) {
    for (const auto& w : m.warnings)
      if (w.find("do not all run one way round") != std::string::npos) return w;
    return std::string();
  };
  // Moebius: k quads round a ring of radius 3, the strip's width vector
  // turning half a turn on the way.
  const int k = 8;
  std::vector<std::array<double, 3>> pts;
  for (int i = 0; i < k; ++i) {
    const double t = 2 * std::numbers::pi * i / k, c = std::cos(t), s = std::sin(t), w = 0.5 * std::cos(t / 2), h = 0.5 * std::sin(t / 2);
    pts.push_back({(3 + w) * c, (3 + w) * s, h});  // vertex 2i: one side
    pts.push_back({(3 - w) * c, (3 - w) * s, -h});  // 2i + 1: the other
  }
  std::vector<Id> conn;
  for (int i = 0; i < k - 1; ++i) conn.insert(conn.end(), {2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1});
  conn.insert(conn.end(), {2 * (k - 1), 1, 0, 2 * (k - 1) + 1});  // the twist: side 0 meets side 1
  const std::string moebius = warned(make(Mode::Surface, pts, conn));
  EXPECT_NE(moebius.find(": 1 coarse edge(s)"), std::string::npos) << moebius;
  // A flat strip of three quads; then its middle quad numbered the other way round.
  const std::vector<std::array<double, 3>> flat = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 0, 0},
                                                   {0, 1, 0}, {1, 1, 0}, {2, 1, 0}, {3, 1, 0}};
  EXPECT_EQ(warned(make(Mode::Surface, flat, {0, 1, 5, 4, 1, 2, 6, 5, 2, 3, 7, 6})), "");
  const std::string flipped = warned(make(Mode::Surface, flat, {0, 1, 5, 4, 1, 5, 6, 2, 2, 3, 7, 6}));
  EXPECT_NE(flipped.find(": 2 coarse edge(s)"), std::string::npos) << flipped;
  std::mt19937_64 rng(3);
  EXPECT_EQ(warned(test::random_quad_sheet(4, 3, true, rng)), "");
}
