// Property tests over random coarse meshes: random vertex renumbering,
// random local numbering of every hex (all 24 rotations), shuffled element
// order, mixed intervals. Expected values come from the structured geometry
// (an a x b x c box diced with per-slab intervals is a structured grid), not
// from dicer's own output.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <numeric>
#include <random>
#include <set>

#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/verify.hpp"
#include "random_mesh.hpp"

using namespace dicer;

namespace {

// Dominant axis and slab (rounded mid-point coordinate) of a sheet's first edge.
std::pair<int, long> sheet_axis_slab(const CoarseMesh& m, const Topology& t, const Sheets& s, Id sheet) {
  for (Id e = 0; e < t.num_edges(); ++e) {
    if (s.edge_sheet[e] != sheet) continue;
    const Vec3 a = m.vertex(t.edge_v[2 * e]), b = m.vertex(t.edge_v[2 * e + 1]);
    const double d[3] = {std::fabs(b.x - a.x), std::fabs(b.y - a.y), std::fabs(b.z - a.z)};
    const int axis = static_cast<int>(std::max_element(d, d + 3) - d);
    const double mid[3] = {(a.x + b.x) / 2, (a.y + b.y) / 2 / 1.3, (a.z + b.z) / 2 / 0.7};
    return {axis, std::lround(std::floor(mid[axis]))};
  }
  return {-1, 0};
}

// Interval request fixed by geometry, so that any renumbering of the same
// box gets the same fine mesh.
IntervalRequest geometric_intervals(const CoarseMesh& m) {
  const Topology t = build_topology(m);
  const Sheets s = find_sheets(m, t);
  IntervalRequest r;
  for (Id q = 0; q < s.num_sheets(); ++q) {
    const auto [axis, slab] = sheet_axis_slab(m, t, s, q);
    r.sheets.emplace_back(q, 1 + (axis * 7 + slab * 3) % 4);
  }
  return r;
}

// Same mesh, different numbering: vertex permutation, hex rotations, element shuffle.
CoarseMesh scramble(const CoarseMesh& in, std::mt19937_64& rng) {
  CoarseMesh m = in;
  const Id nv = in.num_vertices(), ne = in.num_elements();
  std::vector<Id> perm(static_cast<size_t>(nv));
  std::iota(perm.begin(), perm.end(), Id{0});
  std::shuffle(perm.begin(), perm.end(), rng);
  for (Id v = 0; v < nv; ++v) m.x[perm[v]] = in.x[v], m.y[perm[v]] = in.y[v], m.z[perm[v]] = in.z[v];
  std::vector<Id> order(static_cast<size_t>(ne));
  std::iota(order.begin(), order.end(), Id{0});
  std::shuffle(order.begin(), order.end(), rng);
  const auto rots = test::hex_rotations();
  std::uniform_int_distribution<size_t> pick(0, rots.size() - 1);
  m.conn.clear();
  m.element_block.clear();
  for (Id e : order) {
    const auto& r = rots[pick(rng)];
    for (int q = 0; q < 8; ++q) m.conn.push_back(perm[in.conn[8 * e + r[q]]]);
    m.element_block.push_back(in.element_block[e]);
  }
  m.element_file_id.clear();
  m.vertex_file_id.clear();
  validate_coarse_mesh(m);
  return m;
}

std::vector<std::array<double, 3>> sorted_nodes(const FineMesh& f) {
  std::vector<std::array<double, 3>> out;
  NodeCursor c(f);
  Id id;
  Vec3 p;
  while (c.next(id, p)) out.push_back({p.x, p.y, p.z});
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::array<double, 3>> sorted_centroids(const FineMesh& f) {
  std::vector<std::array<double, 3>> out;
  FineBlock b;
  for (Id h = 0; h < f.num_coarse_elements(); ++h) {
    f.fill_block(h, b);
    for (Id e = 0; e < b.num_elements(); ++e) {
      std::array<double, 3> c{0, 0, 0};
      for (int q = 0; q < 8; ++q) {
        const Vec3 p = f.node(b.conn[8 * e + q]);
        c[0] += p.x / 8, c[1] += p.y / 8, c[2] += p.z / 8;
      }
      out.push_back(c);
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

void expect_close_sets(const std::vector<std::array<double, 3>>& a, const std::vector<std::array<double, 3>>& b) {
  ASSERT_EQ(a.size(), b.size());
  // Sorting with a tolerance: compare after snapping to a 1e-9 grid.
  auto snap = [](std::vector<std::array<double, 3>> v) {
    for (auto& p : v)
      for (double& x : p) x = std::round(x * 1e9) / 1e9;
    std::sort(v.begin(), v.end());
    return v;
  };
  const auto sa = snap(a), sb = snap(b);
  for (size_t i = 0; i < sa.size(); ++i)
    for (int d = 0; d < 3; ++d) ASSERT_NEAR(sa[i][d], sb[i][d], 1e-9) << "point " << i;
}

}  // namespace

TEST(RandomMeshes, StructuredBoxHasABCSheetsAndGridCounts) {
  std::mt19937_64 rng(12345);
  for (int trial = 0; trial < 12; ++trial) {
    test::BoxSpec spec;
    spec.a = 1 + trial % 4, spec.b = 1 + (trial / 2) % 3, spec.c = 1 + (trial * 5) % 3;
    spec.blocks = 1 + trial % 2;
    const CoarseMesh m = test::random_box(spec, rng);
    const Topology t = build_topology(m);
    const Sheets s = find_sheets(m, t);
    EXPECT_EQ(s.num_sheets(), spec.a + spec.b + spec.c);
    // Mixed intervals: random per sheet.
    IntervalRequest req;
    std::uniform_int_distribution<Id> n(1, 5);
    Id total[3] = {0, 0, 0};
    for (Id q = 0; q < s.num_sheets(); ++q) {
      const Id v = n(rng);
      req.sheets.emplace_back(q, v);
      total[sheet_axis_slab(m, t, s, q).first] += v;
    }
    const FineMesh f = FineMesh::dice(m, req);
    EXPECT_EQ(f.num_elements(), total[0] * total[1] * total[2]);
    EXPECT_EQ(f.num_nodes(), (total[0] + 1) * (total[1] + 1) * (total[2] + 1));
    const VerifyReport r = verify(f);
    EXPECT_TRUE(r.ok()) << (r.problems.empty() ? "" : r.problems[0]);
    EXPECT_GT(r.min_scaled_jacobian, 0.0);
    // Boundary fine faces: the surface of an X x Y x Z grid.
    EXPECT_EQ(r.boundary_fine_faces, 2 * (total[0] * total[1] + total[1] * total[2] + total[0] * total[2]));
  }
}

TEST(RandomMeshes, RenumberedAndRotatedMeshGivesTheSameGeometricFineMesh) {
  std::mt19937_64 rng(777);
  for (int trial = 0; trial < 6; ++trial) {
    test::BoxSpec spec;
    spec.a = 2 + trial % 2, spec.b = 2, spec.c = 1 + trial % 3;
    spec.renumber = false, spec.rotate = false;
    const CoarseMesh base = test::random_box(spec, rng);
    const CoarseMesh other = scramble(base, rng);
    const FineMesh fa = FineMesh::dice(base, geometric_intervals(base));
    const FineMesh fb = FineMesh::dice(other, geometric_intervals(other));
    ASSERT_EQ(fa.num_nodes(), fb.num_nodes());
    ASSERT_EQ(fa.num_elements(), fb.num_elements());
    expect_close_sets(sorted_nodes(fa), sorted_nodes(fb));
    expect_close_sets(sorted_centroids(fa), sorted_centroids(fb));
    EXPECT_TRUE(verify(fb).ok());
  }
}

TEST(RandomMeshes, EveryAccessPathIsBitIdentical) {
  std::mt19937_64 rng(99);
  test::BoxSpec spec;
  spec.a = 3, spec.b = 2, spec.c = 2;
  const CoarseMesh m = test::random_box(spec, rng);
  IntervalRequest req;
  req.global = 3;
  req.sheets = {{0, 5}, {2, 2}};
  const FineMesh f = FineMesh::dice(m, req);
  // node(id) vs the cursor.
  std::vector<Vec3> by_id(static_cast<size_t>(f.num_nodes()));
  for (Id id = 0; id < f.num_nodes(); ++id) by_id[id] = f.node(id);
  // Slabs of 1 point (one plane at a time), a few planes, the default.
  for (const Id slab : {Id{1}, Id{40}, kCursorSlabPoints}) {
    NodeCursor c(f, 0, f.num_nodes(), slab);
    Id id;
    Vec3 p;
    Id seen = 0;
    while (c.next(id, p)) {
      ASSERT_EQ(id, seen++);
      ASSERT_EQ(std::bit_cast<std::uint64_t>(p.x), std::bit_cast<std::uint64_t>(by_id[id].x)) << "slab " << slab;
      ASSERT_EQ(std::bit_cast<std::uint64_t>(p.y), std::bit_cast<std::uint64_t>(by_id[id].y)) << "slab " << slab;
      ASSERT_EQ(std::bit_cast<std::uint64_t>(p.z), std::bit_cast<std::uint64_t>(by_id[id].z)) << "slab " << slab;
    }
    EXPECT_EQ(seen, f.num_nodes());
  }
  // Every block (so both neighbours of every shared face) vs node(id).
  FineBlock b;
  for (Id h = 0; h < f.num_coarse_elements(); ++h) {
    f.fill_block(h, b);
    for (Id g = 0; g < b.num_points(); ++g) {
      const Vec3 q = by_id[b.node_id[g]];
      ASSERT_TRUE(q.x == b.x[g] && q.y == b.y[g] && q.z == b.z[g]) << "coarse " << h << " point " << g;
    }
    // element(id) vs the block's connectivity.
    for (Id e = 0; e < b.num_elements(); ++e) {
      const FineElement el = f.element(b.first_element + e);
      ASSERT_EQ(el.coarse_element, h);
      for (int q = 0; q < 8; ++q) ASSERT_EQ(el.nodes[q], b.conn[8 * e + q]);
    }
  }
  // Element cursor vs element(id), slabs of one layer up to whole blocks.
  for (const Id slab : {Id{1}, Id{40}, kCursorSlabPoints}) {
    ElementCursor ec(f, 0, f.num_elements(), slab);
    FineElement el;
    Id seen = 0;
    while (ec.next(el)) {
      ASSERT_EQ(el.id, seen++);
      const FineElement ref = f.element(el.id);
      ASSERT_EQ(ref.nodes, el.nodes) << "slab " << slab;
      ASSERT_EQ(ref.ijk, el.ijk) << "slab " << slab;
      ASSERT_EQ(ref.coarse_element, el.coarse_element);
    }
    EXPECT_EQ(seen, f.num_elements());
  }
}

// fill_slab gives exactly the block's planes and layers, with and without
// coordinates, whatever was filled before with the same FineBlock (its
// cached boundary is keyed on the mesh: a second mesh must not see the
// first one's boundary).
TEST(RandomMeshes, SlabsAreTheBlocksPlanesBitForBit) {
  std::mt19937_64 rng(77);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 2, spec.c = 2;
  IntervalRequest req;
  req.global = 4;
  req.sheets = {{0, 6}, {1, 1}};
  const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
  const FineMesh g = FineMesh::dice(test::random_box(spec, rng), req);  // other coordinates, same structure
  FineBlock whole, slab;
  for (Id h = 0; h < f.num_coarse_elements(); ++h)
    for (const FineMesh* m : {&f, &g, &f}) {
      m->fill_block(h, whole);
      const Id n2 = whole.n[2];
      std::uniform_int_distribution<Id> pick(0, n2 - 1);
      for (int trial = 0; trial < 6; ++trial) {
        const Id k0 = pick(rng), k1 = std::uniform_int_distribution<Id>(k0 + 1, n2)(rng);
        const bool coords = trial % 3 != 0;
        m->fill_slab(h, k0, k1, slab, coords, true);
        ASSERT_EQ(slab.plane0, k0);
        ASSERT_EQ(slab.planes, k1 - k0 + 1);
        ASSERT_EQ(slab.num_elements(), whole.n[0] * whole.n[1] * (k1 - k0));
        ASSERT_EQ(slab.first_element, whole.first_element + whole.n[0] * whole.n[1] * k0);
        ASSERT_EQ(slab.x.empty(), !coords);
        for (Id k = k0; k <= k1; ++k)
          for (Id j = 0; j <= whole.n[1]; ++j)
            for (Id i = 0; i <= whole.n[0]; ++i) {
              const Id a = whole.point_index(i, j, k), b = slab.point_index(i, j, k);
              ASSERT_EQ(slab.node_id[b], whole.node_id[a]) << h << " " << i << " " << j << " " << k;
              if (coords) {
                ASSERT_TRUE(std::bit_cast<std::uint64_t>(slab.x[b]) == std::bit_cast<std::uint64_t>(whole.x[a]) &&
                            std::bit_cast<std::uint64_t>(slab.y[b]) == std::bit_cast<std::uint64_t>(whole.y[a]) &&
                            std::bit_cast<std::uint64_t>(slab.z[b]) == std::bit_cast<std::uint64_t>(whole.z[a]));
              }
            }
        const size_t first = static_cast<size_t>(whole.n[0] * whole.n[1] * k0) * 8;
        ASSERT_TRUE(std::equal(slab.conn.begin(), slab.conn.end(), whole.conn.begin() + static_cast<std::ptrdiff_t>(first)));
      }
    }
  // Out-of-range planes are refused, not read.
  FineBlock b;
  EXPECT_THROW(f.fill_slab(0, 2, 1, b, true, false), Error);
  EXPECT_THROW(f.fill_slab(0, 0, 100, b, true, false), Error);
  EXPECT_THROW(f.fill_slab(0, 1, 1, b, false, true), Error);  // no element layer between one plane
}

TEST(RandomMeshes, NumberingRoundTripsAndFollowsTheLayout) {
  std::mt19937_64 rng(5);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 3, spec.c = 2;
  const CoarseMesh m = test::random_box(spec, rng);
  IntervalRequest req;
  req.global = 4;
  req.sheets = {{1, 2}, {3, 1}};
  const FineMesh f = FineMesh::dice(m, req);
  MeshCursor cur;
  // The owner of every node, by brute force: the first coarse element (store
  // order) whose block holds it.
  std::vector<Id> owner(static_cast<size_t>(f.num_nodes()), -1);
  {
    FineBlock b;
    for (Id h = 0; h < f.num_coarse_elements(); ++h) {
      f.fill_block(h, b, true);
      for (Id g = 0; g < b.num_points(); ++g)
        if (owner[b.node_id[g]] < 0) owner[b.node_id[g]] = h;
    }
  }
  // Owner order: ids run through the owners in store order; within an
  // owner: vertices, edges, faces, interior; within a kind, entity ids rise;
  // within an entity, the canonical position rises (first axis fastest).
  Id prev_owner = 0, prev_entity = -1;
  int prev_kind = -1;
  std::array<Id, 3> prev_local{};
  for (Id id = 0; id < f.num_nodes(); ++id) {
    ASSERT_GE(owner[id], 0) << "node " << id << " is in no block";
    const NodeRef r = f.locate_node(id, cur);
    ASSERT_EQ(f.node_id(r, cur), id);
    const int kind = static_cast<int>(r.kind);
    if (owner[id] != prev_owner) {
      ASSERT_GT(owner[id], prev_owner) << "node " << id;
      prev_kind = -1, prev_entity = -1;
    }
    ASSERT_TRUE(kind > prev_kind || (kind == prev_kind && r.entity >= prev_entity)) << "node " << id;
    if (kind == prev_kind && r.entity == prev_entity) {
      const std::array<Id, 3> a{r.local[2], r.local[1], r.local[0]}, b{prev_local[2], prev_local[1], prev_local[0]};
      ASSERT_GT(a, b) << "node " << id;
    }
    prev_owner = owner[id], prev_kind = kind, prev_entity = r.entity, prev_local = r.local;
  }
  // (a) what a contiguous range of coarse elements owns is one id range.
  for (Id a = 0; a <= f.num_coarse_elements(); ++a)
    for (Id e = a; e <= f.num_coarse_elements(); ++e) {
      const auto [lo, hi] = f.owned_nodes(a, e, cur);
      const Id count = std::count_if(owner.begin(), owner.end(), [&](Id h) { return h >= a && h < e; });
      ASSERT_EQ(hi - lo, count);
      for (Id id = lo; id < hi; ++id) ASSERT_TRUE(owner[id] >= a && owner[id] < e);
    }
  // Element ids: coarse element order, then i fastest, then j, then k.
  FineBlock b;
  Id expected = 0;
  for (Id h = 0; h < f.num_coarse_elements(); ++h) {
    f.fill_block(h, b, true);
    ASSERT_EQ(b.first_element, expected);
    for (Id e = 0; e < b.num_elements(); ++e) {
      std::array<Id, 3> ijk;
      ASSERT_EQ(f.locate_element(expected + e, ijk, cur), h);
      ASSERT_EQ(ijk[0] + b.n[0] * (ijk[1] + b.n[1] * ijk[2]), e);
    }
    expected += b.num_elements();
  }
  EXPECT_EQ(expected, f.num_elements());
}

TEST(RandomMeshes, SurfaceSheetCountsAndConformity) {
  std::mt19937_64 rng(31);
  for (int trial = 0; trial < 6; ++trial) {
    const int a = 2 + trial, b = 1 + trial % 3;
    const CoarseMesh m = test::random_quad_sheet(a, b, trial % 2 == 0, rng);
    const Topology t = build_topology(m);
    const Sheets s = find_sheets(m, t);
    EXPECT_EQ(s.num_sheets(), a + b);
    IntervalRequest req;
    req.global = 2 + trial % 3;
    const FineMesh f = FineMesh::dice(m, req);
    const Id n = *req.global;
    EXPECT_EQ(f.num_elements(), a * n * b * n);
    EXPECT_EQ(f.num_nodes(), (a * n + 1) * (b * n + 1));
    const VerifyReport r = verify(f);
    EXPECT_TRUE(r.ok()) << (r.problems.empty() ? "" : r.problems[0]);
  }
}

namespace {

// Fine nodes (distinct ids) that share bit-identical coordinates with
// another, and those within `tol` of another without being identical: by
// brute force over every node (small meshes only).
std::pair<Id, Id> brute_coincident(const FineMesh& f, double tol) {
  std::vector<std::pair<std::array<double, 3>, Id>> pts;
  NodeCursor c(f);
  Id id;
  Vec3 p;
  while (c.next(id, p)) pts.push_back({{p.x, p.y, p.z}, id});
  std::sort(pts.begin(), pts.end());
  std::set<Id> same, near;
  for (size_t i = 0; i < pts.size(); ++i)
    for (size_t j = i + 1; j < pts.size() && pts[j].first[0] - pts[i].first[0] <= tol; ++j) {
      const auto& a = pts[i].first;
      const auto& b = pts[j].first;
      if (a == b) {
        same.insert(pts[i].second), same.insert(pts[j].second);
      } else if (std::hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]) <= tol) {
        near.insert(pts[i].second), near.insert(pts[j].second);
      }
    }
  return {static_cast<Id>(same.size()), static_cast<Id>(near.size())};
}

CoarseMesh two_hexes_with_a_crack(double shift) {
  // Two hexes side by side whose shared face uses duplicated vertices (an
  // interface, as in contact meshes); `shift` moves the duplicates along y.
  CoarseMesh m;
  m.source = "crack";
  const double pts[12][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1},
                             {1, 1, 1}, {0, 1, 1}, {2, 0, 0}, {2, 1, 0}, {2, 0, 1}, {2, 1, 1}};
  for (auto& p : pts) m.x.push_back(p[0]), m.y.push_back(p[1]), m.z.push_back(p[2]);
  for (int v : {1, 2, 5, 6}) m.x.push_back(pts[v][0]), m.y.push_back(pts[v][1] + shift), m.z.push_back(pts[v][2]);
  m.conn = {0, 1, 2, 3, 4, 5, 6, 7, 12, 8, 9, 13, 14, 10, 11, 15};
  validate_coarse_mesh(m);
  return m;
}

}  // namespace

TEST(RandomMeshes, VerifyCountsCoincidentNodesExactlyAndTellsInterfacesFromNonConformity) {
  IntervalRequest req;
  req.global = 2;
  {  // An interface of coincident coarse vertices: a warning, every fine node on it counted.
    const FineMesh f = FineMesh::dice(two_hexes_with_a_crack(0), req);
    const VerifyReport r = verify(f);
    const auto [same, near] = brute_coincident(f, 1e-9 * std::sqrt(4.0 + 1 + 1));
    EXPECT_EQ(same, 18);  // 3 x 3 fine nodes on each side of the shared face
    EXPECT_EQ(r.coincident_nodes, same);
    EXPECT_EQ(r.coincident_interface, same);
    EXPECT_EQ(r.coincident_coarse_vertices, 8);
    EXPECT_EQ(near, 0);
    EXPECT_TRUE(r.ok()) << (r.problems.empty() ? "" : r.problems[0]);
    EXPECT_FALSE(r.warnings.empty());
  }
  {  // The notes name the place exactly: coordinates that read back to the
     // node's bits (thirds, so six decimals would not).
    CoarseMesh m = two_hexes_with_a_crack(0);
    for (auto* c : {&m.x, &m.y, &m.z})
      for (double& v : *c) v /= 3;
    const FineMesh f = FineMesh::dice(m, req);
    const VerifyReport r = verify(f);
    int checked = 0;
    for (const std::string& w : r.warnings) {
      long long a = -1, b = -1;
      char xyz[3][64];
      if (std::sscanf(w.c_str(), "fine nodes %lld and %lld coincide at (%63[^,], %63[^,], %63[^)])", &a, &b, xyz[0], xyz[1],
                      xyz[2]) != 5)
        continue;
      const Vec3 p = f.node(a);
      const double want[3] = {p.x, p.y, p.z};
      for (int d = 0; d < 3; ++d)
        EXPECT_EQ(std::bit_cast<std::uint64_t>(std::strtod(xyz[d], nullptr)), std::bit_cast<std::uint64_t>(want[d])) << w;
      ++checked;
    }
    EXPECT_GT(checked, 0) << (r.warnings.empty() ? "no warning" : r.warnings[0]);
  }
  {  // The same, apart by 1e-11: nothing identical, every node near.
    const FineMesh f = FineMesh::dice(two_hexes_with_a_crack(1e-11), req);
    const VerifyReport r = verify(f);
    const auto [same, near] = brute_coincident(f, 1e-9 * std::sqrt(4.0 + 1 + 1));
    EXPECT_EQ(same, 0);
    EXPECT_EQ(near, 18);
    EXPECT_EQ(r.coincident_nodes, 0);
    EXPECT_EQ(r.near_coincident, near);
    EXPECT_TRUE(r.ok());
  }
  {  // A hanging vertex: hex A against two hexes B1, B2 that split its face.
    CoarseMesh m;
    m.source = "hanging";
    const double pts[14][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1},   {1, 0, 1},   {1, 1, 1},
                               {0, 1, 1}, {2, 0, 0}, {2, 1, 0}, {2, 0, 1}, {2, 1, 1}, {1, .5, 0}, {1, .5, 1}};
    for (auto& p : pts) m.x.push_back(p[0]), m.y.push_back(p[1]), m.z.push_back(p[2]);
    const double mid[2][3] = {{2, .5, 0}, {2, .5, 1}};
    for (auto& p : mid) m.x.push_back(p[0]), m.y.push_back(p[1]), m.z.push_back(p[2]);
    // A; B1 = [1,2] x [0,.5]; B2 = [1,2] x [.5,1]
    m.conn = {0, 1, 2, 3, 4, 5, 6, 7, 1, 8, 14, 12, 5, 10, 15, 13, 12, 14, 9, 2, 13, 15, 11, 6};
    validate_coarse_mesh(m);
    const FineMesh f = FineMesh::dice(m, req);
    const VerifyReport r = verify(f);
    const auto [same, near] = brute_coincident(f, 1e-9 * std::sqrt(6.0));
    EXPECT_EQ(same, 6);  // on the line y = .5 of the x = 1 face: 3 nodes of A, 3 of B1/B2
    EXPECT_EQ(r.coincident_nodes, same);
    EXPECT_EQ(r.coincident_interface, 0);
    EXPECT_FALSE(r.ok()) << "a non-conforming coarse mesh must fail";
  }
}

TEST(RandomMeshes, SurfaceVerifySeesTheBoundaryAndTheOrientation) {
  std::mt19937_64 rng(8);
  for (int trial = 0; trial < 4; ++trial) {
    const int a = 2 + trial, b = 1 + trial % 2;
    CoarseMesh m = test::random_quad_sheet(a, b, trial % 2 == 1, rng);
    IntervalRequest req;
    req.global = 3;
    const Id n = 3;
    const VerifyReport r = verify(FineMesh::dice(m, req));
    EXPECT_TRUE(r.ok()) << (r.problems.empty() ? "" : r.problems[0]);
    EXPECT_EQ(r.boundary_fine_faces, 2 * (a + b) * n) << "the fine edges around an a x b sheet";
    // One quad wound the other way: its shared edges are traversed the same
    // way as by its neighbours.
    std::reverse(m.conn.begin(), m.conn.begin() + 4);
    validate_coarse_mesh(m);
    const VerifyReport flipped = verify(FineMesh::dice(m, req));
    EXPECT_FALSE(flipped.ok());
    EXPECT_GT(flipped.misoriented, 0);
  }
}

// verify in parts (the MPI ranks) reports what one process reports: a
// coarse edge whose users disagree on its fine nodes is one finding, however
// its users are split among parts. The disagreement is forged in the parts'
// hashes (a stored mesh cannot make two users of one edge row differ
// without a row check failing first).
TEST(RandomMeshes, VerifyInPartsCountsADisagreeingEdgeOnceHoweverItIsSplit) {
  std::mt19937_64 rng(91);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 2, spec.c = 1;
  const CoarseMesh m = test::random_box(spec, rng);
  IntervalRequest req;
  req.global = 2;
  const FineMesh f = FineMesh::dice(m, req);
  const Id H = f.tables().elements.rows();
  ASSERT_EQ(H, 4);
  const VerifyReport whole = verify(f);
  ASSERT_TRUE(whole.ok()) << (whole.problems.empty() ? "" : whole.problems[0]);
  std::vector<VerifyPart> one_each;
  for (Id h = 0; h < H; ++h) one_each.push_back(verify_part(f, h, h + 1));
  EXPECT_EQ(verify_finish(f, one_each).conformity_errors, 0);
  // The edge all four hexes use: the box's middle vertical edge.
  std::map<std::uint64_t, int> users;
  for (const VerifyPart& p : one_each)
    for (const auto& e : p.edge_hashes) ++users[e[0]];
  std::uint64_t mid = ~std::uint64_t{0};
  for (const auto& [e, n] : users)
    if (n == 4) mid = e;
  ASSERT_NE(mid, ~std::uint64_t{0}) << "no edge of four hexes";
  auto forge = [&](VerifyPart& p, std::uint64_t hash, std::uint64_t bad) {
    for (auto& e : p.edge_hashes)
      if (e[0] == mid) e[1] ^= hash, e[2] = bad;
  };
  auto finding = [&](const VerifyReport& r) {
    int notes = 0;
    for (const std::string& s : r.problems) notes += s.find("coarse edge " + std::to_string(mid) + ":") != std::string::npos;
    return std::make_pair(r.conformity_errors, notes);
  };
  const std::pair<Id, int> once{1, 1};
  {  // two of four users differ, each alone in its part (the old count: 2)
    auto parts = one_each;
    forge(parts[2], 1, 0), forge(parts[3], 1, 0);
    EXPECT_EQ(finding(verify_finish(f, parts)), once);
  }
  {  // the same users as two parts of two: the second part agrees within itself
    std::vector<VerifyPart> halves{verify_part(f, 0, 2), verify_part(f, 2, 4)};
    forge(halves[1], 1, 0);
    EXPECT_EQ(finding(verify_finish(f, halves)), once);
  }
  {  // one part whose own users disagreed: its flag alone is the finding
    std::vector<VerifyPart> all{verify_part(f, 0, H)};
    forge(all[0], 0, 1);
    EXPECT_EQ(finding(verify_finish(f, all)), once);
  }
}
