// Second-order coarse meshes (quadratic.hpp) over random meshes: random
// vertex renumbering and local numbering of every hex (tests/support),
// mid nodes off their chords by a smooth field, HEX27, HEX20 and mixed
// elements. Expected points come from the test's own triquadratic
// (biquadratic) Lagrange map of each element's nodes, not from dicer; the
// access paths and the store are compared bit for bit.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cmath>
#include <map>
#include <random>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/quadratic.hpp"
#include "dicer/quality.hpp"
#include "dicer/rows.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "dicer/tfi.hpp"
#include "dicer/verify.hpp"
#include "access_paths.hpp"
#include "gordon_hall.hpp"
#include "random_mesh.hpp"
#include "store_forge.hpp"
#include "test_support.hpp"

namespace dicer {
namespace {

using Key = std::vector<Id>;  // the sorted corner vertices of an edge, face or element

Vec3 bump(const Vec3& p, double amp) {
  return {amp * std::sin(1.7 * p.y + 0.3 * p.z), amp * std::cos(1.1 * p.z + 0.5 * p.x), amp * std::sin(0.9 * p.x + 1.3 * p.y)};
}
Vec3 add(const Vec3& a, const Vec3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 mean(const CoarseMesh& m, const Key& k) {
  Vec3 s{0, 0, 0};
  for (Id v : k) s = add(s, m.vertex(v));
  const double w = 1.0 / static_cast<double>(k.size());
  return {s.x * w, s.y * w, s.z * w};
}

// What each element gives: 8 (nothing), 20 (edges) or 27 (edges, faces,
// centre); surface: 4, 8 or 9.
enum class Order { Linear, Serendipity, Full };

// Slot s of a hex (surface: quad) as the set of local corners it sits between.
std::vector<int> slot_corners(Mode mode, int s) {
  if (mode == Mode::Surface) {
    if (s < 4) return {kQuadEdge[s][0], kQuadEdge[s][1]};
    return {0, 1, 2, 3};
  }
  if (s < 12) return {kHexEdge[s][0], kHexEdge[s][1]};
  if (s < 18) return {kHexFace[s - 12][0], kHexFace[s - 12][1], kHexFace[s - 12][2], kHexFace[s - 12][3]};
  return {0, 1, 2, 3, 4, 5, 6, 7};
}

// The mesh with mid nodes: each entity's node at the mean of its corners
// moved by bump() (one node per entity, shared by the elements that give
// it). `order(e)` says what element e gives. `where` records each entity's
// node, keyed by its corners, for the expectations.
void add_mid_nodes(CoarseMesh& m, double amp, const std::function<Order(Id)>& order, std::map<Key, Vec3>& where) {
  const int slots = mid_slots(m.mode), nc = m.corners_per_element();
  std::map<Key, Id> index;
  m.mid.assign(static_cast<size_t>(m.num_elements()) * slots, -1);
  for (Id e = 0; e < m.num_elements(); ++e) {
    const Order o = order(e);
    for (int s = 0; s < slots; ++s) {
      const auto lc = slot_corners(m.mode, s);
      const bool edge = lc.size() == 2;
      if (o == Order::Linear || (o == Order::Serendipity && !edge)) continue;
      Key k;
      for (int c : lc) k.push_back(m.conn[static_cast<size_t>(e) * nc + c]);
      std::sort(k.begin(), k.end());
      auto [it, fresh] = index.emplace(k, static_cast<Id>(m.mid_x.size()));
      if (fresh) {
        const Vec3 c = mean(m, k), p = add(c, bump(c, amp));
        m.mid_x.push_back(p.x), m.mid_y.push_back(p.y), m.mid_z.push_back(p.z);
        m.mid_file_id.push_back(1000000 + it->second);
        where[k] = p;
      }
      m.mid[static_cast<size_t>(e) * slots + s] = it->second;
    }
  }
  validate_coarse_mesh(m);
}

// P2 Lagrange basis on [0, 1] at nodes 0, 1/2, 1.
double lagrange(double x, int node) {
  return node == 0 ? (1 - x) * (1 - 2 * x) : node == 1 ? 4 * x * (1 - x) : x * (2 * x - 1);
}

// The element's geometry as the test sees it: the triquadratic (surface:
// biquadratic) Lagrange map through its 27 (9) nodes, where an edge no
// element gives a node for has its chord's midpoint and a face without a
// centre node the serendipity surface's centre (the Q9 map through those
// is the serendipity surface). Only its boundary is checked.
struct ElementMap {
  std::vector<std::array<int, 3>> ref;  // node position, in halves
  std::vector<Vec3> x;
  Vec3 at(double a, double b, double c) const {
    Vec3 s{0, 0, 0};
    for (size_t q = 0; q < x.size(); ++q) {
      const double w = lagrange(a, ref[q][0]) * lagrange(b, ref[q][1]) * lagrange(c, ref[q][2]);
      s = add(s, {w * x[q].x, w * x[q].y, w * x[q].z});
    }
    return s;
  }
};

ElementMap element_map(const CoarseMesh& m, Id e, const std::map<Key, Vec3>& where) {
  const int nc = m.corners_per_element(), slots = mid_slots(m.mode);
  const bool vol = m.mode == Mode::Volume;
  ElementMap em;
  auto key = [&](const std::vector<int>& lc) {
    Key k;
    for (int c : lc) k.push_back(m.conn[static_cast<size_t>(e) * nc + c]);
    std::sort(k.begin(), k.end());
    return k;
  };
  auto ref_of = [&](const std::vector<int>& lc) {
    std::array<int, 3> r{0, 0, 0};
    for (int c : lc)
      for (int d = 0; d < 3; ++d) r[d] += 2 * kHexCorner[c][d];
    for (int& v : r) v /= static_cast<int>(lc.size());
    return r;
  };
  for (int c = 0; c < nc; ++c) em.ref.push_back(ref_of({c})), em.x.push_back(m.vertex(m.conn[static_cast<size_t>(e) * nc + c]));
  std::map<Key, Vec3> edge_mid;
  for (int s = 0; s < slots; ++s) {
    const auto lc = slot_corners(m.mode, s);
    if (lc.size() != 2) continue;
    const Key k = key(lc);
    auto it = where.find(k);
    edge_mid[k] = it != where.end() ? it->second : mean(m, k);
    em.ref.push_back(ref_of(lc)), em.x.push_back(edge_mid[k]);
  }
  for (int s = 0; s < slots; ++s) {
    const auto lc = slot_corners(m.mode, s);
    if (lc.size() != 4) continue;
    const Key k = key(lc);
    auto it = where.find(k);
    Vec3 c{0, 0, 0};
    if (it != where.end()) {
      c = it->second;
    } else {
      for (int q = 0; q < 4; ++q) {
        const Vec3 mid = edge_mid[key({lc[q], lc[(q + 1) % 4]})], v = m.vertex(k[q]);
        c = add(c, {0.5 * mid.x - 0.25 * v.x, 0.5 * mid.y - 0.25 * v.y, 0.5 * mid.z - 0.25 * v.z});
      }
    }
    em.ref.push_back(ref_of(lc)), em.x.push_back(c);
  }
  if (vol) em.ref.push_back({1, 1, 1}), em.x.push_back(mean(m, key(slot_corners(m.mode, 18))));
  return em;
}

// Every grid point on the boundary of every coarse element is on the
// element's quadratic map; returns the largest distance seen.
double boundary_distance(const FineMesh& f, const CoarseMesh& input, const std::map<Key, Vec3>& where) {
  const CoarseMesh& ordered = *f.coarse();
  FineBlock b;
  MeshCursor cur;
  double worst = 0;
  for (Id h = 0; h < f.num_coarse_elements(); ++h) {
    const Id e = ordered.element_file_id[h] - 1;  // the input's element (file ids are 1..n)
    const ElementMap em = element_map(input, e, where);
    // Reference positions along each local axis: the axis's series (graded
    // sheets), i / n when equally spaced.
    const auto grading = RowReader(f.tables(), cur).element(h).grading;
    auto ref = [&](Id i, Id n, int a) {
      return grading[a].kind == tfi::Spacing::Equal ? static_cast<double>(i) / n : tfi::param(i, n, grading[a]);
    };
    f.fill_block(h, b);
    const bool vol = f.mode() == Mode::Volume;
    for (Id k = 0; k <= (vol ? b.n[2] : 0); ++k)
      for (Id j = 0; j <= b.n[1]; ++j)
        for (Id i = 0; i <= b.n[0]; ++i) {
          const bool on = i == 0 || i == b.n[0] || j == 0 || j == b.n[1] || (vol && (k == 0 || k == b.n[2]));
          if (!on) continue;
          const Vec3 want = em.at(ref(i, b.n[0], 0), ref(j, b.n[1], 1), vol ? ref(k, b.n[2], 2) : 0.0);
          const Id g = b.point_index(i, j, k);
          worst = std::max(worst, std::hypot(b.x[g] - want.x, b.y[g] - want.y, b.z[g] - want.z));
        }
  }
  return worst;
}

// Every interior grid point of every coarse hex against the textbook
// Gordon-Hall sum (gordon_hall.hpp) of the block's own boundary points, at
// the axes' series parameters; returns the largest error over the sum of
// the magnitudes it used. Curved edges and faces make every term count (a
// straight hex's face terms cancel its edge terms).
double interior_error(const FineMesh& f) {
  FineBlock b;
  MeshCursor cur;
  double worst = 0;
  for (Id h = 0; h < f.num_coarse_elements(); ++h) {
    const auto grading = RowReader(f.tables(), cur).element(h).grading;
    f.fill_block(h, b);
    const std::array<Id, 3> n = b.n;
    for (Id k = 1; k < n[2]; ++k)
      for (Id j = 1; j < n[1]; ++j)
        for (Id i = 1; i < n[0]; ++i) {
          const std::array<Id, 3> t{i, j, k};
          const std::array<double, 3> s{tfi::param(i, n[0], grading[0]), tfi::param(j, n[1], grading[1]),
                                        tfi::param(k, n[2], grading[2])};
          const Id g = b.point_index(i, j, k);
          const double* xyz[3] = {b.x.data(), b.y.data(), b.z.data()};
          for (int d = 0; d < 3; ++d) {
            const test::GordonHall want = test::gordon_hall(
                [&](std::array<int, 3> side) {
                  Id p[3];
                  for (int a = 0; a < 3; ++a) p[a] = side[a] == 2 ? t[a] : side[a] * n[a];
                  return xyz[d][b.point_index(p[0], p[1], p[2])];
                },
                s);
            worst = std::max(worst, static_cast<double>(std::fabs(xyz[d][g] - want.x) / want.magnitude));
          }
        }
  }
  return worst;
}

IntervalRequest random_intervals(const FineMesh& probe, std::mt19937_64& rng) {
  IntervalRequest req;
  std::uniform_int_distribution<Id> n(1, 4), global(2, 4);
  req.global = global(rng);
  for (Id s = 0; s < probe.info().sheets; ++s) {
    if (rng() % 2) req.sheets.push_back({s, n(rng)});
    // Graded sheets: nodes follow the curve at the series' parameters. A
    // dual bias fits every sheet; a geometric one the boxes' (untwisted).
    if (rng() % 3 == 0) {
      BiasRequest b;
      b.kind = probe.mode() == Mode::Volume && rng() % 2 ? tfi::Spacing::Geometric : tfi::Spacing::Dual;
      b.ratio = 1.1 + 0.4 * static_cast<double>(rng() % 8) / 8;
      req.sheet_bias.emplace_back(s, b);
    }
  }
  return req;
}

class RandomSecondOrder : public ::testing::TestWithParam<int> {};

TEST_P(RandomSecondOrder, BoundaryOnTheQuadraticMapAndEveryPathBitIdentical) {
  const int variant = GetParam();  // 0 HEX27, 1 HEX20, 2 mixed HEX8/20/27, 3 QUAD9, 4 QUAD8, 5 mixed quads
  test::TempDir tmp;
  for (int seed = 0; seed < 3; ++seed) {
    SCOPED_TRACE("variant " + std::to_string(variant) + " seed " + std::to_string(seed));
    std::mt19937_64 rng(1000 * variant + seed);
    CoarseMesh m;
    if (variant < 3) {
      test::BoxSpec spec;
      spec.a = 3, spec.b = 2, spec.c = 2, spec.blocks = 2;
      m = test::random_box(spec, rng);
    } else {
      m = test::random_quad_sheet(4, 3, true, rng);
    }
    std::vector<Order> order(static_cast<size_t>(m.num_elements()));
    for (auto& o : order) {
      const int pick = variant % 3 == 0 ? 2 : variant % 3 == 1 ? 1 : static_cast<int>(rng() % 3);
      o = static_cast<Order>(pick);
    }
    std::map<Key, Vec3> where;
    add_mid_nodes(m, 0.06, [&](Id e) { return order[e]; }, where);
    const CoarseMesh input = m;
    const IntervalRequest req = random_intervals(FineMesh::dice(input, IntervalRequest{}), rng);
    FineMesh f = FineMesh::dice(input, req);
    EXPECT_EQ(f.info().source_order, 2);
    const SecondOrderReport rep = apply_second_order(f);
    EXPECT_TRUE(rep.second_order);
    EXPECT_GT(rep.edges_curved, 0);
    const bool any_centre = std::any_of(order.begin(), order.end(), [](Order o) { return o == Order::Full; });
    if (variant == 1 || variant == 4) {
      EXPECT_EQ(rep.faces_curved, 0);  // serendipity faces: the TFI is exact
    }
    if (any_centre && (variant == 0 || variant == 3)) {
      EXPECT_GT(rep.faces_curved, 0);
    }
    EXPECT_GT(rep.min_scaled_jacobian, 0.0);
    // The fine nodes on coarse edges and faces lie on the quadratic map, to
    // rounding (the diagonal is ~5).
    EXPECT_LE(boundary_distance(f, input, where), 1e-13);
    // The interior: the hex TFI of that boundary, to a few roundings.
    if (f.mode() == Mode::Volume) {
      EXPECT_LE(interior_error(f), 4 * DBL_EPSILON);
    }
    // Bent boundaries: far from a first-order dice of the same corners.
    CoarseMesh linear = input;
    linear.mid.clear(), linear.mid_x.clear(), linear.mid_y.clear(), linear.mid_z.clear(), linear.mid_file_id.clear();
    EXPECT_GT(boundary_distance(FineMesh::dice(linear, req), input, where), 1e-3);
    test::expect_paths_bit_identical(f, tmp.path("s" + std::to_string(seed) + ".dice.h5"));
  }
}

std::string variant_name(const ::testing::TestParamInfo<int>& info) {
  static const char* const names[] = {"Hex27", "Hex20", "MixedHexes", "Quad9", "Quad8", "MixedQuads"};
  return names[info.param];
}
INSTANTIATE_TEST_SUITE_P(SecondOrder, RandomSecondOrder, ::testing::Range(0, 6), variant_name);

// A 2 x 1 x 1 box of unit hexes, right-handed, file order; mid nodes added by the caller.
CoarseMesh two_hexes() {
  CoarseMesh m;
  m.source = "two_hexes";
  for (int k = 0; k < 2; ++k)
    for (int j = 0; j < 2; ++j)
      for (int i = 0; i < 3; ++i) m.x.push_back(i), m.y.push_back(j), m.z.push_back(k);
  for (Id i = 0; i < 2; ++i)
    for (Id v : {i, i + 1, i + 4, i + 3, i + 6, i + 7, i + 10, i + 9}) m.conn.push_back(v);
  validate_coarse_mesh(m);
  return m;
}

TEST(SecondOrder, MidNodesAtTheChordsStoreNothingAndMatchTheFirstOrderMesh) {
  CoarseMesh m = two_hexes();
  std::map<Key, Vec3> where;
  add_mid_nodes(m, 0.0, [](Id) { return Order::Full; }, where);
  IntervalRequest req;
  req.global = 5;
  FineMesh f = FineMesh::dice(m, req);
  const SecondOrderReport rep = apply_second_order(f);
  EXPECT_TRUE(rep.second_order);
  EXPECT_EQ(rep.edges_curved + rep.faces_curved, 0);
  EXPECT_EQ(f.num_bounding_nodes(), 0);
  CoarseMesh linear = two_hexes();
  const FineMesh g = FineMesh::dice(linear, req);
  EXPECT_EQ(sweep(f, 1).checksum, sweep(g, 1).checksum);
}

TEST(SecondOrder, FirstOrderMeshIsLeftAlone) {
  FineMesh f = FineMesh::dice(two_hexes(), IntervalRequest{});
  const SecondOrderReport rep = apply_second_order(f);
  EXPECT_FALSE(rep.second_order);
  EXPECT_EQ(f.num_bounding_nodes(), 0);
  EXPECT_EQ(f.info().source_order, 1);
}

// apply_second_order throws `kind` with every one of `says` in its message.
void expect_refused(FineMesh& f, ErrorKind kind, const std::vector<std::string>& says) {
  try {
    apply_second_order(f);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), kind) << e.what();
    for (const auto& s : says) EXPECT_NE(std::string(e.what()).find(s), std::string::npos) << e.what();
  }
}

// The attribute is optional: a store written before it (none) is first order.
TEST(SecondOrder, StoreWithoutASourceOrderIsFirstOrder) {
  test::TempDir tmp;
  CoarseMesh m = two_hexes();
  std::map<Key, Vec3> where;
  add_mid_nodes(m, 0.05, [](Id) { return Order::Full; }, where);
  FineMesh f = FineMesh::dice(m, IntervalRequest{});
  apply_second_order(f);
  write_store(f, tmp.path("a.dice.h5"));
  EXPECT_EQ(read_store(tmp.path("a.dice.h5")).info().source_order, 2);
  test::edited_copy(tmp.path("a.dice.h5"), tmp.path("b.dice.h5"), [](hid_t file) { H5Adelete(file, "source_order"); });
  EXPECT_EQ(read_store(tmp.path("b.dice.h5")).info().source_order, 1);
}

TEST(SecondOrder, ElementsThatDisagreeOnASharedEdgeAreRefusedNamingBoth) {
  CoarseMesh m = two_hexes();
  std::map<Key, Vec3> where;
  add_mid_nodes(m, 0.05, [](Id) { return Order::Serendipity; }, where);
  // Element 2 gets its own node, elsewhere, for the edge it shares with
  // element 1 (local edge 4 of element 2 joins its corners 0 and 3 = the
  // vertices 1 and 4, element 1's local edge 5).
  const Id own = static_cast<Id>(m.mid_x.size());
  m.mid_x.push_back(1.02), m.mid_y.push_back(0.5), m.mid_z.push_back(0.0), m.mid_file_id.push_back(777);
  m.mid[static_cast<size_t>(kHexMidSlots) + 4] = own;
  validate_coarse_mesh(m);
  FineMesh f = FineMesh::dice(m, IntervalRequest{});
  expect_refused(f, ErrorKind::BadInput,
                 {"element 1 (block 1)", "element 2 (block 1)", "disagree on the mid node of their common edge",
                  "node 777"});
}

TEST(SecondOrder, OneNodeForTwoEdgesIsRefused) {
  CoarseMesh m = two_hexes();
  std::map<Key, Vec3> where;
  add_mid_nodes(m, 0.05, [](Id) { return Order::Serendipity; }, where);
  m.mid[1] = m.mid[0];  // element 1: edges 0 and 1 share a mid node
  validate_coarse_mesh(m);
  FineMesh f = FineMesh::dice(m, IntervalRequest{});
  expect_refused(f, ErrorKind::BadInput, {"is the mid node of two different edges"});
}

TEST(SecondOrder, AnInvertingMidNodeIsRefusedNamingTheElement) {
  CoarseMesh m = two_hexes();
  m.element_file_id = {31, 32};
  std::map<Key, Vec3> where;
  add_mid_nodes(m, 0.0, [](Id) { return Order::Serendipity; }, where);
  // Element 32's edge along y at x = 2, z = 1 bent past the middle of the box.
  const Id q = m.mid[static_cast<size_t>(kHexMidSlots) + 7];  // local edge 7: corners 5-6
  m.mid_x[q] = 0.6;
  IntervalRequest req;
  req.global = 4;
  FineMesh f = FineMesh::dice(m, req);
  expect_refused(f, ErrorKind::Geometry, {"two_hexes: the second-order geometry of element 32 (block 1) would invert"});
}

// A left-handed file (every hex numbered with i and j swapped, mid nodes
// too) is reoriented with its mid nodes: the same fine mesh, by position.
TEST(SecondOrder, LeftHandedFileIsReorientedWithItsMidNodes) {
  std::mt19937_64 rng(5);
  test::BoxSpec spec;
  spec.rotate = false;
  CoarseMesh m = test::random_box(spec, rng);
  std::map<Key, Vec3> where;
  add_mid_nodes(m, 0.05, [](Id) { return Order::Full; }, where);
  // The mirror image of each element's numbering, derived from positions:
  // new node at local (a, b, c) is the old node at (b, a, c).
  CoarseMesh left = m;
  auto ref = [](Mode mode, int s) {
    std::array<int, 3> r{0, 0, 0};
    const auto lc = slot_corners(mode, s);
    for (int c : lc)
      for (int d = 0; d < 3; ++d) r[d] += 2 * kHexCorner[c][d];
    for (int& v : r) v /= static_cast<int>(lc.size());
    return r;
  };
  for (Id e = 0; e < m.num_elements(); ++e) {
    for (int c = 0; c < 8; ++c)
      for (int o = 0; o < 8; ++o)
        if (kHexCorner[o][0] == kHexCorner[c][1] && kHexCorner[o][1] == kHexCorner[c][0] &&
            kHexCorner[o][2] == kHexCorner[c][2])
          left.conn[8 * e + c] = m.conn[8 * e + o];
    for (int s = 0; s < kHexMidSlots; ++s)
      for (int o = 0; o < kHexMidSlots; ++o) {
        const auto a = ref(Mode::Volume, s), b = ref(Mode::Volume, o);
        if (a[0] == b[1] && a[1] == b[0] && a[2] == b[2]) left.mid[kHexMidSlots * e + s] = m.mid[kHexMidSlots * e + o];
      }
  }
  left.warnings.clear();
  validate_coarse_mesh(left);
  ASSERT_FALSE(left.warnings.empty());
  EXPECT_NE(left.warnings[0].find("left-handed"), std::string::npos);
  IntervalRequest req;
  req.global = 3;
  FineMesh a = FineMesh::dice(m, req), b = FineMesh::dice(left, req);
  apply_second_order(a), apply_second_order(b);
  EXPECT_LE(boundary_distance(b, m, where), 1e-13);  // left's elements are m's, mirrored back
  auto sorted = [](const FineMesh& f) {
    std::vector<std::array<double, 3>> v;
    for (Id id = 0; id < f.num_nodes(); ++id) {
      const Vec3 p = f.node(id);
      v.push_back({p.x, p.y, p.z});
    }
    std::sort(v.begin(), v.end());
    return v;
  };
  const auto pa = sorted(a), pb = sorted(b);
  ASSERT_EQ(pa.size(), pb.size());
  for (size_t i = 0; i < pa.size(); ++i)
    for (int d = 0; d < 3; ++d) ASSERT_NEAR(pa[i][d], pb[i][d], 1e-12) << i;
}

}  // namespace
}  // namespace dicer
