// Geometry-conforming dicing against CAD made with Gmsh inside the tests
// (cylinder, sphere in a box, torus, a planar box). Distances are checked
// against the shapes' analytic equations, not against Gmsh's projections.
#include <gmsh.h>
#include <gtest/gtest.h>

#include <cmath>
#include <bit>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>

#include "cad.hpp"
#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/geometry.hpp"
#include "dicer/locate.hpp"
#include "dicer/rows.hpp"
#include "dicer/orientation.hpp"
#include "dicer/quality.hpp"
#include "dicer/store.hpp"
#include "dicer/sweep.hpp"
#include "dicer/tfi.hpp"
#include "dicer/topology.hpp"
#include "dicer/transfer.hpp"
#include "dicer/batch.hpp"
#include "dicer/verify.hpp"
#include "test_support.hpp"

namespace dicer {
namespace {

using test::TempDir;

// Builds an OpenCASCADE model with Gmsh's API and writes it (BREP or STEP).
void make_cad(const std::string& path, const std::function<void()>& build) {
  geometry::gmsh_start();
  geometry::gmsh_call(ErrorKind::Io, "making " + path, [&] {
    gmsh::model::add("test_cad");
    build();
    gmsh::model::occ::synchronize();
    gmsh::write(path);
    gmsh::model::remove();
  });
}

struct Shape {
  const char* name;
  double size;
  std::function<void()> build;
  // Distance of p from the nearest analytic surface of the shape.
  std::function<double(const Vec3&)> distance;
  double diagonal;
};

double hyp(double a, double b) { return std::sqrt(a * a + b * b); }

Shape cylinder() {
  return {"cylinder", 0.8, [] { gmsh::model::occ::addCylinder(0, 0, 0, 0, 0, 2, 1); },
          [](const Vec3& p) { return std::min({std::abs(hyp(p.x, p.y) - 1), std::abs(p.z), std::abs(p.z - 2)}); },
          std::sqrt(4.0 + 4.0 + 4.0)};
}
Shape sphere_in_box() {
  return {"sphere_in_box", 0.5,
          [] {
            gmsh::model::occ::addBox(-2, -2, -2, 4, 4, 4, 1);
            gmsh::model::occ::addSphere(0, 0, 0, 1, 2);
            gmsh::vectorpair out;
            std::vector<gmsh::vectorpair> map;
            gmsh::model::occ::fragment({{3, 1}}, {{3, 2}}, out, map);
          },
          [](const Vec3& p) {
            const double r = std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z);
            return std::min({std::abs(r - 1), std::abs(std::abs(p.x) - 2), std::abs(std::abs(p.y) - 2),
                             std::abs(std::abs(p.z) - 2)});
          },
          std::sqrt(48.0)};
}
Shape torus() {
  return {"torus", 0.45, [] { gmsh::model::occ::addTorus(0, 0, 0, 2, 0.7); },
          [](const Vec3& p) { return std::abs(hyp(hyp(p.x, p.y) - 2, p.z) - 0.7); }, hyp(2 * 2.7, hyp(2 * 2.7, 1.4))};
}

// Every fine node the store says lies on a curve or surface, with its id.
void for_each_cad_node(const FineMesh& m, const std::function<void(Id, const Vec3&)>& fn) {
  MeshCursor cur;
  const MeshTables& T = m.tables();
  auto visit = [&](EntityKind k, Id ent, Id a, Id b) {
    NodeRef r;
    r.kind = k, r.entity = ent, r.local = {a, b, 0};
    fn(m.node_id(r, cur), m.node(r, cur));
  };
  for (Id v = 0; v < T.num_vertices(); ++v) {
    const auto o = m.owner(EntityKind::Vertex, v, cur);
    if (owner_dim(o) >= 0 && owner_dim(o) <= 2) visit(EntityKind::Vertex, v, 0, 0);
  }
  for (Id e = 0; e < T.edges.rows(); ++e) {
    const auto o = m.owner(EntityKind::Edge, e, cur);
    if (owner_dim(o) < 1 || owner_dim(o) > 2) continue;
    for (Id t = 1; t < RowReader(T, cur).edge(e).n; ++t) visit(EntityKind::Edge, e, t, 0);
  }
  for (Id f = 0; f < T.faces.rows(); ++f) {
    if (owner_dim(m.owner(EntityKind::Face, f, cur)) != 2) continue;
    const FaceRow r = RowReader(T, cur).face(f);
    const Id nu = r.nu, nv = r.nv;
    for (Id v = 1; v < nv; ++v)
      for (Id u = 1; u < nu; ++u) visit(EntityKind::Face, f, u, v);
  }
}

struct Case {
  Shape shape;
  std::vector<Id> intervals;
};

class CurvedPart : public ::testing::TestWithParam<int> {};

Case case_of(int k) {
  if (k == 0) return {cylinder(), {2, 3, 6}};
  if (k == 1) return {sphere_in_box(), {2, 4}};
  return {torus(), {2, 3}};
}

TEST_P(CurvedPart, FineNodesOnTheCadNoInversionConformingAndBitIdenticalThroughTheStore) {
  const Case c = case_of(GetParam());
  TempDir tmp;
  const std::string cad = tmp.path(std::string(c.shape.name) + ".brep"), msh = tmp.path("coarse.msh");
  make_cad(cad, c.shape.build);
  CoarseMeshOptions mo;
  mo.size = c.shape.size;
  const CoarseMeshReport cr = mesh_coarse(cad, msh, mo);
  ASSERT_GT(cr.elements, 0);
  for (Id n : c.intervals) {
    SCOPED_TRACE(std::string(c.shape.name) + " interval " + std::to_string(n));
    IntervalRequest req;
    req.global = n;
    FineMesh fine = FineMesh::dice(read_coarse_mesh(msh), req);
    const ConformReport rep = conform_to_geometry(fine, cad);
    EXPECT_GT(rep.faces_moved, 0);
    EXPECT_GT(rep.bounding_nodes, 0);
    EXPECT_TRUE(rep.tags_matched);  // mesh-coarse classified on this very CAD
    // On the CAD: the analytic surfaces, to 1e-12 of the diagonal (the
    // issue's bound is 1e-9; OpenCASCADE's evaluations are far better).
    double worst = 0;
    Id checked = 0;
    for_each_cad_node(fine, [&](Id, const Vec3& p) {
      worst = std::max(worst, c.shape.distance(p));
      ++checked;
    });
    EXPECT_GT(checked, fine.num_bounding_nodes());
    EXPECT_LE(worst, 1e-12 * c.shape.diagonal);
    // Every fine element valid.
    const QualityReport q = check_quality(fine);
    EXPECT_EQ(q.inverted, 0);
    EXPECT_GT(q.min_scaled_jacobian, 0.0);
    // Conformity, counts, id round trips, node(id) == block fill bit for bit,
    // both neighbours of every shared coarse face and edge agree.
    const VerifyReport vr = verify(fine);
    EXPECT_TRUE(vr.ok()) << (vr.problems.empty() ? std::string() : vr.problems.front());
    if (n != c.intervals.back()) continue;
    // Through the store: the same nodes bit for bit, and the same distances
    // measured by Gmsh against the CAD.
    const std::string store = tmp.path("fine.dice.h5");
    write_store(fine, store);
    const FineMesh s = read_store(store, StoreOptions{8ull << 20, 0});
    EXPECT_EQ(s.num_bounding_nodes(), fine.num_bounding_nodes());
    EXPECT_EQ(sweep(s, 2).checksum, sweep(fine, 1).checksum);
    EXPECT_TRUE(verify(s).ok());
    // Box queries through the spatial index see curved elements whole: the
    // same elements as a brute-force centroid test, for boxes over the
    // curved wall (where nodes leave their corners' box) and random ones.
    {
      const int nc = s.corners();
      std::vector<std::array<double, 3>> cen(static_cast<size_t>(s.num_elements()));
      double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
      {  // block by block: node(id) gives the same bits (verify checks it)
        FineBlock blk;
        for (Id h = 0; h < s.num_coarse_elements(); ++h) {
          s.fill_block(h, blk);
          for (Id e = 0; e < blk.num_elements(); ++e) {
            const Id i = e % blk.n[0], j = (e / blk.n[0]) % blk.n[1], k = e / (blk.n[0] * blk.n[1]);
            std::array<double, 3> c{0, 0, 0};
            for (int q = 0; q < nc; ++q) {
              const Id g = blk.point_index(i + kHexCorner[q][0], j + kHexCorner[q][1], k + kHexCorner[q][2]);
              c[0] += blk.x[g], c[1] += blk.y[g], c[2] += blk.z[g];
            }
            for (double& v : c) v /= nc;  // as for_each_in_box computes it
            cen[blk.first_element + e] = c;
          }
        }
      }
      for (const auto& c : cen)
        for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], c[d]), hi[d] = std::max(hi[d], c[d]);
      std::mt19937_64 rng(n);
      int walls = 0;
      for (int trial = 0; trial < 8; ++trial) {
        Box box;
        for (int d = 0; d < 3; ++d) {
          std::uniform_real_distribution<double> u(lo[d], hi[d]);
          const double a = u(rng), b = u(rng);
          box.lo[d] = std::min(a, b), box.hi[d] = std::max(a, b);
        }
        if (trial < 6) {
          // A half-space just beyond one coarse element's corners, where
          // its curved wall still has fine centroids: a search by corner
          // boxes misses them (the widest such gap along this direction).
          const int d = trial / 2;
          const double sign = trial % 2 ? 1.0 : -1.0;
          double best_gap = 0, at = sign * 1e300;
          MeshCursor cur;
          FineBlock blk;
          for (Id h = 0; h < s.num_coarse_elements(); ++h) {
            Vec3 xyz[8];
            RowReader(s.tables(), cur).corner_xyz(h, xyz);
            double edge = -sign * 1e300;
            for (int q = 0; q < nc; ++q) {
              const double v = component(xyz[q], d);
              edge = sign > 0 ? std::max(edge, v) : std::min(edge, v);
            }
            s.fill_block(h, blk);
            for (Id e = 0; e < blk.num_elements(); ++e) {
              const double gap = sign * (cen[blk.first_element + e][d] - edge);
              if (gap > best_gap) best_gap = gap, at = edge + sign * 0.5 * gap;
            }
          }
          if (best_gap <= 0) continue;  // flat along this direction (a cylinder's caps)
          ++walls;
          box.lo = {-1e9, -1e9, -1e9}, box.hi = {1e9, 1e9, 1e9};
          if (sign > 0) box.lo[d] = at; else box.hi[d] = at;
        }
        std::vector<Id> brute, streamed;
        for (Id e = 0; e < s.num_elements(); ++e)
          if (box.contains(cen[e][0], cen[e][1], cen[e][2])) brute.push_back(e);
        for_each_in_box(s, box, [&](const FineBlock& b, Id e) { streamed.push_back(b.first_element + e); });
        EXPECT_EQ(streamed, brute) << "trial " << trial;
      }
      // (On these Gmsh parts, coarse vertices sit at the extremes, so
      // `walls` may be 0; the verify above checks every node against its
      // element's bounds.)
      RecordProperty("walls_beyond_corners", walls);
    }
    // Point location in curved elements: a point inside a fine element (xi
    // away from its faces) comes back in it with its xi.
    {
      std::mt19937_64 rng(n + 100);
      std::uniform_int_distribution<Id> pick(0, s.num_elements() - 1);
      std::uniform_real_distribution<double> u(0.05, 0.95);
      for (int k = 0; k < 40; ++k) {
        const Id e = pick(rng);
        const FineElement el = s.element(e);
        std::array<std::array<double, 3>, 8> x;
        for (int q = 0; q < 8; ++q) {
          const Vec3 v = s.node(el.nodes[q]);
          x[q] = {v.x, v.y, v.z};
        }
        const std::array<double, 3> xi = {u(rng), u(rng), u(rng)};
        const Located got = locate_point(s, trilinear(x, xi));
        EXPECT_EQ(got.element, e);
        for (int d = 0; d < 3; ++d) EXPECT_NEAR(got.xi[d], xi[d], 1e-9);
      }
    }
    const GeometryCheck g = check_geometry(s, cad);
    EXPECT_LE(g.max_distance, 1e-9 * g.diagonal) << "worst node " << g.worst_node << " on " << g.worst_entity;
    EXPECT_GT(g.nodes_checked, 0);
    EXPECT_EQ(g.unplaced_faces, 0);
    EXPECT_TRUE(g.ok());
    // The same coarse mesh diced without the CAD: its boundary faces are on
    // no surface in the store, their nodes measured against the nearest
    // surface. A curved boundary's chords are off it (verify fails); the
    // sphere in a box has a planar boundary (the sphere is inside), on it.
    {
      const std::string flat = tmp.path("flat.dice.h5");
      write_store(FineMesh::dice(read_coarse_mesh(msh), req), flat);
      const GeometryCheck u = check_geometry(read_store(flat, StoreOptions{8ull << 20, 0}), cad);
      EXPECT_GT(u.unplaced_faces, 0);
      const bool curved_boundary = std::string(c.shape.name) != "sphere_in_box";
      if (curved_boundary) {
        EXPECT_GT(u.max_distance, 1e3 * u.tolerance);
      }
      EXPECT_EQ(u.ok(), !curved_boundary) << u.max_distance << " at node " << u.worst_node;
    }
    const StoreSummary sum = store_summary(store);
    EXPECT_EQ(sum.bounding_nodes, fine.num_bounding_nodes());
    // Below raw float64 (24 B per node) after the prediction + shuffle + LZ4.
    EXPECT_LT(static_cast<double>(sum.bounding_bytes), 24.0 * static_cast<double>(sum.bounding_nodes));
  }
}

INSTANTIATE_TEST_SUITE_P(Gmsh, CurvedPart, ::testing::Values(0, 1, 2), [](const auto& info) {
  return std::string(case_of(info.param).shape.name);
});

// Nested dicings on the same CAD (transfer.hpp): every node the coarser
// store has, the finer one has with the same bits, moved nodes and the
// curved elements' interiors included. The sphere in a box is the case
// that needs it: the conformer's choice between parameters and closest
// points used to depend on the interval (a quarter of the fine step), so
// its 2 -> 4 and 2 -> 6 pairs differed on 81 and 148 moved nodes; the
// choice is now made from probes at fixed parameters.
TEST(Geometry, NestedDicingsOnTheCadShareTheirCoincidentNodesBitForBit) {
  TempDir tmp;
  const Shape sh = sphere_in_box();
  const std::string cad = tmp.path("sib.brep"), msh = tmp.path("sib.msh");
  make_cad(cad, sh.build);
  CoarseMeshOptions mo;
  mo.size = sh.size;
  mesh_coarse(cad, msh, mo);
  auto dice_to = [&](Id n) {
    IntervalRequest req;
    req.global = n;
    FineMesh f = FineMesh::dice(read_coarse_mesh(msh), req);
    conform_to_geometry(f, cad);
    const std::string path = tmp.path("sib" + std::to_string(n) + ".dice.h5");
    write_store(f, path);
    return path;
  };
  const std::string s2 = dice_to(2), s4 = dice_to(4), s6 = dice_to(6);
  for (const auto& [a, b] : {std::pair{s2, s4}, std::pair{s2, s6}}) {
    SCOPED_TRACE(a + " -> " + b);
    const FineMesh coarse = read_store(a, StoreOptions{8ull << 20, 0}), fine = read_store(b, StoreOptions{8ull << 20, 0});
    const Nesting n = check_nesting(coarse, fine);
    EXPECT_TRUE(n.nested);
    EXPECT_GT(n.moved_nodes_checked, 100);
    EXPECT_EQ(n.moved_nodes_differ, 0) << n.message;
    // Every coarse node through the unit rows of P, by node(id) in both
    // stores and by the fine store's batches.
    const Prolongation p(coarse, fine);
    std::vector<Vec3> batch(static_cast<size_t>(fine.num_nodes()));
    {
      BatchCursor c(fine);
      for (FineBatch bt; c.next(bt);)
        for (Id i = 0; i < bt.num_nodes(); ++i) batch[static_cast<size_t>(bt.node_begin + i)] = {bt.x[i], bt.y[i], bt.z[i]};
    }
    Id twins = 0, curved_interior = 0;
    MeshCursor cc, fc;
    ProlongationCursor rows(p);
    for (ProlongationBatch r; rows.next(r);)
      for (Id q = 0; q < r.num_rows(); ++q) {
        if (r.offsets[q + 1] - r.offsets[q] != 1) continue;
        const Id f = r.row_begin + q, c = r.cols[r.offsets[q]];
        const Vec3 x = coarse.node(c, cc), y = fine.node(f, fc);
        ASSERT_TRUE(std::bit_cast<std::uint64_t>(x.x) == std::bit_cast<std::uint64_t>(y.x) &&
                    std::bit_cast<std::uint64_t>(x.y) == std::bit_cast<std::uint64_t>(y.y) &&
                    std::bit_cast<std::uint64_t>(x.z) == std::bit_cast<std::uint64_t>(y.z))
            << "coarse node " << c << ", fine node " << f;
        ASSERT_TRUE(batch[static_cast<size_t>(f)] == y) << "fine node " << f << " by batches";
        ++twins;
        curved_interior += fine.locate_node(f, fc).kind == EntityKind::Cell &&
                           RowReader(fine.tables(), fc).element(fine.locate_node(f, fc).entity).curved();
      }
    EXPECT_EQ(twins, coarse.num_nodes());
    EXPECT_GT(curved_interior, 0);
  }
}

TEST(Geometry, PlanarBoxNeedsNoBoundingBytes) {
  TempDir tmp;
  const std::string cad = tmp.path("box.step"), msh = tmp.path("box.msh");
  make_cad(cad, [] { gmsh::model::occ::addBox(0, 0, 0, 1, 2, 3); });
  CoarseMeshOptions mo;
  mo.size = 0.5;
  EXPECT_EQ(mesh_coarse(cad, msh, mo).method, "transfinite");
  IntervalRequest req;
  req.global = 6;
  FineMesh fine = FineMesh::dice(read_coarse_mesh(msh), req);
  const ConformReport rep = conform_to_geometry(fine, cad);
  EXPECT_GT(rep.faces_on_surfaces, 0);
  EXPECT_EQ(rep.edges_moved + rep.faces_moved, 0);
  EXPECT_EQ(fine.num_bounding_nodes(), 0);
  const std::string store = tmp.path("box.dice.h5");
  write_store(fine, store);
  const StoreSummary sum = store_summary(store);
  EXPECT_EQ(sum.bounding_nodes, 0);
  EXPECT_EQ(sum.bounding_bytes, 0u);
  EXPECT_TRUE(verify(read_store(store, StoreOptions{8ull << 20, 0})).ok());
  // Diced without the CAD, a box is on it all the same: its unplaced faces'
  // nodes are on the nearest plane.
  const std::string flat = tmp.path("flat.dice.h5");
  write_store(FineMesh::dice(read_coarse_mesh(msh), req), flat);
  const GeometryCheck g = check_geometry(read_store(flat, StoreOptions{8ull << 20, 0}), cad);
  EXPECT_GT(g.unplaced_faces, 0);
  EXPECT_LE(g.max_distance, g.tolerance) << "node " << g.worst_node << " on " << g.worst_entity;
  EXPECT_TRUE(g.ok());
}

TEST(Geometry, RenumberedCadIsMatchedGeometrically) {
  // The same sphere-in-box built in the opposite order: OpenCASCADE numbers
  // its surfaces and curves differently from the file the mesh came from.
  TempDir tmp;
  const Shape sh = sphere_in_box();
  const std::string cad = tmp.path("a.brep"), other = tmp.path("b.step"), msh = tmp.path("a.msh");
  make_cad(cad, sh.build);
  make_cad(other, [] {
    gmsh::model::occ::addSphere(0, 0, 0, 1, 1);
    gmsh::model::occ::addBox(-2, -2, -2, 4, 4, 4, 2);
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> map;
    gmsh::model::occ::fragment({{3, 2}}, {{3, 1}}, out, map);
  });
  CoarseMeshOptions mo;
  mo.size = sh.size;
  mesh_coarse(cad, msh, mo);
  IntervalRequest req;
  req.global = 3;
  FineMesh a = FineMesh::dice(read_coarse_mesh(msh), req);
  FineMesh b = FineMesh::dice(read_coarse_mesh(msh), req);
  const ConformReport ra = conform_to_geometry(a, cad), rb = conform_to_geometry(b, other);
  EXPECT_TRUE(ra.tags_matched);
  EXPECT_FALSE(rb.tags_matched);
  EXPECT_EQ(ra.faces_on_surfaces, rb.faces_on_surfaces);
  EXPECT_EQ(ra.edges_on_curves, rb.edges_on_curves);
  double worst = 0;
  for_each_cad_node(b, [&](Id, const Vec3& p) { worst = std::max(worst, sh.distance(p)); });
  EXPECT_LE(worst, 1e-12 * sh.diagonal);
  EXPECT_EQ(check_quality(b).inverted, 0);
}

TEST(Geometry, MismatchedCadIsRefusedNamingVertexAndDistance) {
  TempDir tmp;
  const std::string cad = tmp.path("cyl.brep"), wrong = tmp.path("wide.brep"), msh = tmp.path("cyl.msh");
  make_cad(cad, [] { gmsh::model::occ::addCylinder(0, 0, 0, 0, 0, 2, 1); });
  make_cad(wrong, [] { gmsh::model::occ::addCylinder(0, 0, 0, 0, 0, 2, 1.2); });
  CoarseMeshOptions mo;
  mo.size = 0.8;
  mesh_coarse(cad, msh, mo);
  IntervalRequest req;
  req.global = 2;
  FineMesh fine = FineMesh::dice(read_coarse_mesh(msh), req);
  try {
    conform_to_geometry(fine, wrong);
    FAIL() << "a cylinder of radius 1 fitted a CAD of radius 1.2";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Geometry);
    const std::string m = e.what();
    EXPECT_NE(m.find("coarse vertex"), std::string::npos) << m;
    EXPECT_NE(m.find("from the nearest"), std::string::npos) << m;
    EXPECT_NE(m.find("wide.brep"), std::string::npos) << m;
  }
  // The CLI: exit 7, one line, no store left behind.
  const auto r = test::run_cli({"dice", msh, "--geometry", wrong, "--interval", "2", "-o", tmp.path("x.dice.h5"), "--quiet"});
  EXPECT_EQ(r.exit_code, 7) << r.err;
  EXPECT_NE(r.err.find("does not fit"), std::string::npos) << r.err;
  EXPECT_FALSE(std::filesystem::exists(tmp.path("x.dice.h5")));
  // A CAD file that is missing: exit 5 (I/O), naming it.
  const auto m = test::run_cli({"dice", msh, "--geometry", tmp.path("missing.step"), "-o", tmp.path("y.dice.h5")});
  EXPECT_EQ(m.exit_code, 5) << m.err;
  EXPECT_NE(m.err.find("missing.step"), std::string::npos) << m.err;
  EXPECT_FALSE(std::filesystem::exists(tmp.path("y.dice.h5")));
  // A STEP file that is not STEP: exit 3, and OpenCASCADE's own complaints
  // on stderr, not in the standard output a --json reader parses.
  {
    const std::string junk = tmp.path("junk.step");
    std::ofstream(junk) << "garbage";
    const auto j = test::run_cli({"dice", msh, "--geometry", junk, "--interval", "2", "-o", tmp.path("j.dice.h5"), "--quiet"});
    EXPECT_EQ(j.exit_code, 3) << j.err;
    EXPECT_EQ(j.out, "") << "stdout holds: " << j.out;
    // Bytes that OpenCASCADE's BREP reader takes as an empty model: a bad
    // input too (it was exit 7, "mesh and CAD do not fit").
    const std::string empty = tmp.path("junk.brep");
    std::ofstream(empty) << std::string(300, '\x17');
    const auto b = test::run_cli({"dice", msh, "--geometry", empty, "--interval", "2", "-o", tmp.path("j.dice.h5"), "--quiet"});
    EXPECT_EQ(b.exit_code, 3) << b.err;
    EXPECT_NE(b.err.find("holds no curve or surface"), std::string::npos) << b.err;
  }
  // transfer from the mesh file to a store diced onto the CAD: not one
  // dicing (the file has no CAD placement), said in words, the file named.
  {
    const std::string placed = tmp.path("placed.dice.h5");
    ASSERT_EQ(test::run_cli({"dice", msh, "--geometry", cad, "--interval", "2", "-o", placed, "--quiet"}).exit_code, 0);
    const auto t = test::run_cli({"transfer", msh, placed, "--check"});
    EXPECT_EQ(t.exit_code, 3) << t.err;
    EXPECT_NE(t.err.find(msh + " and " + placed + " are not dicings of one coarse mesh"), std::string::npos) << t.err;
    EXPECT_NE(t.err.find("diced with --geometry and the other not"), std::string::npos) << t.err;
  }
  // Not a CAD format.
  const auto u = test::run_cli({"dice", msh, "--geometry", msh, "-o", tmp.path("z.dice.h5")});
  EXPECT_EQ(u.exit_code, 4) << u.err;
}

TEST(Geometry, SurfaceModeOnACurvedShell) {
  TempDir tmp;
  const std::string cad = tmp.path("cyl.brep"), msh = tmp.path("skin.msh");
  make_cad(cad, [] { gmsh::model::occ::addCylinder(0, 0, 0, 0, 0, 2, 1); });
  CoarseMeshOptions mo;
  mo.size = 0.8;
  mo.surface = true;
  mesh_coarse(cad, msh, mo);
  const CoarseMesh cm = read_coarse_mesh(msh);
  ASSERT_EQ(cm.mode, Mode::Surface);
  IntervalRequest req;
  req.global = 6;
  FineMesh fine = FineMesh::dice(read_coarse_mesh(msh), req);
  const ConformReport rep = conform_to_geometry(fine, cad);
  EXPECT_GT(rep.faces_moved, 0);
  double worst = 0;
  Id n = 0;
  NodeCursor cur(fine);  // surface mode: every fine node is on the CAD
  Id id;
  Vec3 p;
  while (cur.next(id, p)) worst = std::max(worst, cylinder().distance(p)), ++n;
  EXPECT_EQ(n, fine.num_nodes());
  EXPECT_LE(worst, 1e-12 * cylinder().diagonal);
  EXPECT_EQ(check_quality(fine).inverted, 0);
  const std::string store = tmp.path("skin.dice.h5");
  write_store(fine, store);
  const FineMesh s = read_store(store, StoreOptions{8ull << 20, 0});
  EXPECT_TRUE(verify(s).ok());
  EXPECT_EQ(sweep(s, 1).checksum, sweep(fine, 1).checksum);
  EXPECT_LE(check_geometry(s, cad).max_distance, 1e-9 * cylinder().diagonal);
  // Point location on the curved skin (its quads are moved onto the CAD:
  // found by descent over fine cells): a point made at xi of a fine quad,
  // on it or moved a little along its normal, comes back there.
  std::mt19937_64 rng(4);
  std::uniform_int_distribution<Id> pick(0, s.num_elements() - 1);
  std::uniform_real_distribution<double> in(0.25, 0.75), off(-0.01, 0.01);
  int on_curved = 0;
  for (int k = 0; k < 200; ++k) {
    const Id e = pick(rng);
    const FineElement el = s.element(e);
    std::array<std::array<double, 3>, 4> x;
    for (int q = 0; q < 4; ++q) {
      const Vec3 v = s.node(el.nodes[q]);
      x[q] = {v.x, v.y, v.z};
    }
    const std::array<double, 3> xi = {in(rng), in(rng), 0}, p0 = bilinear(x, xi);
    double xu[3], xv[3];
    for (int d = 0; d < 3; ++d) {
      xu[d] = (x[1][d] - x[0][d]) * (1 - xi[1]) + (x[2][d] - x[3][d]) * xi[1];
      xv[d] = (x[3][d] - x[0][d]) * (1 - xi[0]) + (x[2][d] - x[1][d]) * xi[0];
    }
    const std::array<double, 3> n = {xu[1] * xv[2] - xu[2] * xv[1], xu[2] * xv[0] - xu[0] * xv[2], xu[0] * xv[1] - xu[1] * xv[0]};
    const double len = std::hypot(n[0], n[1], n[2]), h = std::hypot(xu[0], xu[1], xu[2]);
    const double delta = k % 2 ? off(rng) * h : 0.0;
    std::array<double, 3> p;
    for (int d = 0; d < 3; ++d) p[d] = p0[d] + delta * n[d] / len;
    const Located got = locate_point(s, p);
    ASSERT_EQ(got.element, e) << "point " << k;
    EXPECT_NEAR(got.xi[0], xi[0], 1e-8);
    EXPECT_NEAR(got.xi[1], xi[1], 1e-8);
    EXPECT_NEAR(got.distance, std::abs(delta), 1e-9 * h);
    bool side = true;  // a quad of the cylinder's side, not of its flat ends
    for (const auto& c : x) side = side && std::abs(c[2]) > 1e-9 && std::abs(c[2] - 2) > 1e-9;
    on_curved += side;
  }
  EXPECT_GT(on_curved, 50);
}

TEST(Geometry, BoundingCodeIsLosslessForEveryPair) {
  std::mt19937_64 rng(7);
  const double special[] = {0.0, -0.0, 1e-308, -1e-308, 5e-324, 1.0, -1.0, 1e308, -1e308, INFINITY, -INFINITY};
  std::vector<double> vals(std::begin(special), std::end(special));
  for (int i = 0; i < 2000; ++i) vals.push_back(std::ldexp(std::uniform_real_distribution<double>(-1, 1)(rng), static_cast<int>(rng() % 200) - 100));
  for (double a : vals)
    for (int k = 0; k < 8; ++k) {
      const double b = vals[rng() % vals.size()];
      const double back = tfi::bounding_apply(a, tfi::bounding_code(a, b));
      ASSERT_EQ(std::bit_cast<std::uint64_t>(back), std::bit_cast<std::uint64_t>(b)) << a << " " << b;
    }
  // Small corrections have small codes (the point of the zigzag).
  EXPECT_EQ(tfi::bounding_code(1.0, std::nextafter(1.0, 2.0)), 2);
  EXPECT_EQ(tfi::bounding_code(1.0, std::nextafter(1.0, 0.0)), 1);
}

// ---------------------------------------------------------------- grading

// Graded sheets on the CAD: edge nodes moved onto a circle keep the
// sheet's series in the circle's parameter (its angle), measured here from
// the coordinates against the series summed independently.
TEST(Geometry, BiasedSheetsKeepTheSeriesInTheCurvesParameter) {
  TempDir tmp;
  const Shape sh = cylinder();
  const std::string cad = tmp.path("cyl.brep"), msh = tmp.path("cyl.msh");
  make_cad(cad, sh.build);
  CoarseMeshOptions mo;
  mo.size = sh.size;
  mesh_coarse(cad, msh, mo);
  const CoarseMesh cm = read_coarse_mesh(msh);
  const Sheets sheets = find_sheets(cm, build_topology(cm));
  const double R = 1.4;
  IntervalRequest req;
  req.global = 5;
  for (Id q = 0; q < sheets.num_sheets(); ++q) req.sheet_bias.emplace_back(q, BiasRequest{tfi::Spacing::Geometric, R, 0, 0, std::nullopt});
  FineMesh fine = FineMesh::dice(cm, req);
  conform_to_geometry(fine, cad);
  EXPECT_EQ(check_quality(fine).inverted, 0);
  const VerifyReport vr = verify(fine);
  EXPECT_TRUE(vr.ok()) << (vr.problems.empty() ? std::string() : vr.problems.front());
  double worst = 0;
  for_each_cad_node(fine, [&](Id, const Vec3& p) { worst = std::max(worst, sh.distance(p)); });
  EXPECT_LE(worst, 1e-12 * sh.diagonal);
  // The series from one end: h, hR, ..., n = 5.
  std::vector<double> frac(5, 1.0);
  for (int k = 1; k < 5; ++k) frac[k] = frac[k - 1] * R;
  const double sum = frac[0] + frac[1] + frac[2] + frac[3] + frac[4];
  for (double& f : frac) f /= sum;
  MeshCursor cur;
  const RowReader Rr(fine.tables(), cur);
  int circles = 0;
  for (Id e = 0; e < fine.tables().edges.rows(); ++e) {
    const EdgeRow row = Rr.edge(e);
    const Vec3 a = Rr.xyz(row.lo), b = Rr.xyz(row.hi);
    const bool on_circle = owner_dim(row.geo) == 1 && std::abs(a.z - b.z) < 1e-12 && std::abs(hyp(a.x, a.y) - 1) < 1e-9 &&
                           std::abs(hyp(b.x, b.y) - 1) < 1e-9;
    if (!on_circle) continue;
    std::vector<double> th;
    for (Id t = 0; t <= row.n; ++t) {
      const Vec3 p = t == 0 ? a : t == row.n ? b : fine.node(NodeRef{EntityKind::Edge, e, {t, 0, 0}}, cur);
      double v = std::atan2(p.y, p.x);
      if (!th.empty()) v += 2 * M_PI * std::round((th.back() - v) / (2 * M_PI));  // unwrapped
      th.push_back(v);
    }
    const double total = th.back() - th.front();
    bool fw = true, bw = true;
    for (int k = 0; k < 5; ++k) {
      const double d = th[k + 1] - th[k];
      fw = fw && std::abs(d - total * frac[k]) <= 1e-9 * std::abs(total);
      bw = bw && std::abs(d - total * frac[4 - k]) <= 1e-9 * std::abs(total);
    }
    EXPECT_TRUE(fw || bw) << "edge " << e << " on a circle is not spaced like the series in its angle";
    ++circles;
  }
  EXPECT_GT(circles, 4);
  // Through the store, bit for bit.
  const std::string store = tmp.path("cyl.dice.h5");
  write_store(fine, store);
  const FineMesh s = read_store(store, StoreOptions{8ull << 20, 0});
  EXPECT_EQ(sweep(s, 2).checksum, sweep(fine, 1).checksum);
  EXPECT_TRUE(verify(s).ok());
  EXPECT_LE(check_geometry(s, cad).max_distance, 1e-9 * sh.diagonal);
}

// Intervals by entity on a transfinite box (4 x 2 x 2 hexes, Gmsh's MSH
// 4.1 classification): a curve's sheets, a face's (with its boundary
// curves), the volume's; precedence against blocks and sheets; and the
// CAD's classification (dice --geometry) equal to the file's.
TEST(Geometry, IntervalsByEntity) {
  TempDir tmp;
  const std::string cad = tmp.path("box.brep"), msh = tmp.path("box.msh");
  make_cad(cad, [] { gmsh::model::occ::addBox(0, 0, 0, 2, 1, 1); });
  CoarseMeshOptions mo;
  mo.size = 0.5;
  ASSERT_EQ(mesh_coarse(cad, msh, mo).method, "transfinite");
  const CoarseMesh cm = read_coarse_mesh(msh);
  ASSERT_FALSE(cm.geo_entities.empty());
  // Tags from the nodes' classification: a node inside the x edge at y = z = 0,
  // inside the face x = 0, inside the box.
  auto tag_where = [&](int dim, const std::function<bool(double, double, double)>& at) {
    for (Id v = 0; v < cm.num_vertices(); ++v)
      if (cm.vertex_geo_dim[v] == dim && at(cm.x[v], cm.y[v], cm.z[v])) return static_cast<int>(cm.vertex_geo_tag[v]);
    ADD_FAILURE() << "no node classified on such a " << dim << "-entity";
    return -1;
  };
  const int curve = tag_where(1, [](double, double y, double z) { return std::abs(y) + std::abs(z) < 1e-12; });
  const int face = tag_where(2, [](double x, double, double) { return std::abs(x) < 1e-12; });
  const int volume = tag_where(3, [](double, double, double) { return true; });
  // Coarse x edges along that curve (one per x slab).
  Id slabs = 0;
  {
    const Topology t0 = build_topology(cm);
    for (Id e = 0; e < t0.num_edges(); ++e) {
      const Id a = t0.edge_v[2 * e], b = t0.edge_v[2 * e + 1];
      slabs += std::abs(cm.y[a]) + std::abs(cm.z[a]) + std::abs(cm.y[b]) + std::abs(cm.z[b]) < 1e-12;
    }
  }
  ASSERT_GT(slabs, 1);
  // Intervals along x, y, z of each coarse edge, by direction.
  auto per_axis = [](const FineMesh& f) {
    std::array<std::set<Id>, 3> n;
    MeshCursor cur;
    const RowReader R(f.tables(), cur);
    for (Id e = 0; e < f.tables().edges.rows(); ++e) {
      const EdgeRow row = R.edge(e);
      const Vec3 a = R.xyz(row.lo), b = R.xyz(row.hi);
      const int axis = std::abs(a.x - b.x) > 1e-9 ? 0 : std::abs(a.y - b.y) > 1e-9 ? 1 : 2;
      n[axis].insert(row.n);
    }
    return n;
  };
  using S = std::set<Id>;
  {
    IntervalRequest req;
    req.entities = {{{1, curve}, 7}};
    const auto n = per_axis(FineMesh::dice(cm, req));
    EXPECT_EQ(n, (std::array<S, 3>{S{7}, S{1}, S{1}}));
  }
  {
    IntervalRequest req;
    req.global = 2;
    req.entities = {{{2, face}, 3}};
    const auto n = per_axis(FineMesh::dice(cm, req));
    EXPECT_EQ(n, (std::array<S, 3>{S{2}, S{3}, S{3}}));
  }
  {
    IntervalRequest req;
    req.entities = {{{3, volume}, 4}};
    const auto n = per_axis(FineMesh::dice(cm, req));
    EXPECT_EQ(n, (std::array<S, 3>{S{4}, S{4}, S{4}}));
  }
  {  // Ranked with blocks: the largest, reported; a sheet request wins, reported.
    IntervalRequest req;
    req.entities = {{{1, curve}, 7}};
    req.blocks = {{std::to_string(cm.blocks[0].id), 9}};
    req.sheets = {{0, 5}};
    std::vector<std::string> notes;
    const FineMesh f = FineMesh::dice(cm, req, &notes);
    bool largest = false, sheet = false;
    for (const auto& note : notes) {
      largest |= note.find("using the largest, 9") != std::string::npos && note.find("curve " + std::to_string(curve)) != std::string::npos;
      sheet |= note.find("sheet 0: sheet interval 5 overrides") != std::string::npos;
    }
    EXPECT_TRUE(largest && sheet) << ::testing::PrintToString(notes);
    EXPECT_EQ(f.sheet_intervals()[0], 5);
  }
  {  // An entity bias with a start node: on the sheet holding the node, it starts there.
    Id origin = -1;
    for (Id v = 0; v < cm.num_vertices(); ++v)
      if (std::abs(cm.x[v]) + std::abs(cm.y[v]) + std::abs(cm.z[v]) < 1e-12) origin = cm.vertex_file_id[v];
    IntervalRequest req;
    req.global = 4;
    BiasRequest b;
    b.ratio = 2;
    b.start = origin;
    req.entity_bias = {{{1, curve}, b}};
    std::vector<std::string> notes;
    const FineMesh f = FineMesh::dice(cm, req, &notes);
    int started = 0, defaulted = 0;
    for (const SheetGrading& g : f.sheet_gradings()) started += g.start == origin, defaulted += g.start >= 0 && g.start != origin;
    EXPECT_EQ(started, 1);
    EXPECT_EQ(defaulted, slabs - 1);  // the other x slabs along the curve, reported
    int reported = 0;
    for (const auto& note : notes) reported += note.find("is on none of its edges") != std::string::npos;
    EXPECT_EQ(reported, slabs - 1);
    // The x edge at the origin: its first cell (at x = 0) is the series' h = L / (1 + 2 + 4 + 8).
    MeshCursor cur;
    const RowReader R(f.tables(), cur);
    int at_origin = 0;
    for (Id e = 0; e < f.tables().edges.rows(); ++e) {
      const EdgeRow row = R.edge(e);
      const Vec3 a = R.xyz(row.lo), c = R.xyz(row.hi);
      if (std::abs(a.y) + std::abs(a.z) + std::abs(c.y) + std::abs(c.z) > 1e-12 || std::min(a.x, c.x) > 1e-12) continue;
      const Vec3 p = f.node(NodeRef{EntityKind::Edge, e, {a.x < c.x ? 1 : row.n - 1, 0, 0}}, cur);
      EXPECT_NEAR(p.x, std::max(a.x, c.x) / 15, 1e-15);
      ++at_origin;
    }
    EXPECT_EQ(at_origin, 1);
  }
  // The CAD's classification of the same mesh, from nothing: the same edges on the same entities.
  CoarseMesh bare = cm;
  std::fill(bare.vertex_geo_dim.begin(), bare.vertex_geo_dim.end(), std::int8_t{-1});
  std::fill(bare.vertex_geo_tag.begin(), bare.vertex_geo_tag.end(), -1);
  bare.geo_entities.clear();
  classify_on_geometry(bare, cad);
  const Topology t = build_topology(cm);
  const auto want = edge_entities(cm, t), got = edge_entities(bare, t);
  EXPECT_EQ(got, want);
  EXPECT_EQ(std::count(want.begin(), want.end(), std::int64_t{-1}), 0);
  // The command: dice --geometry with an entity interval (dicer-cad classifies first).
  const std::string store = tmp.path("box.dice.h5");
  const auto r = test::run_cli({"dice", msh, "--geometry", cad, "--entity-interval", "1:" + std::to_string(curve) + "=7",
                                "--sheet-bias", "0=1.3", "-o", store, "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto n = per_axis(read_store(store));
  EXPECT_EQ(n, (std::array<S, 3>{S{7}, S{1}, S{1}}));
}

// --size is what sizes the mesh: Gmsh's own sizes at the imported CAD
// points capped every size above a tenth or so of the model (a 2 x 1 x 1
// box got 225 hexes at --size 5, 1, 0.5 and 0.25 alike). A box whose edges
// are all shorter than the size needs one element per edge: one hex.
TEST(MeshCoarse, SizeSetsTheElementCountUpToOneHex) {
  TempDir tmp;
  const std::string cad = tmp.path("box.step");
  make_cad(cad, [] { gmsh::model::occ::addBox(0, 0, 0, 2, 1, 1); });
  Id previous = 0;
  // Through the command (one dicer-cad per size): see mesh_coarse on Gmsh's
  // state between models in one process.
  for (const double size : {0.25, 0.5, 1.0, 5.0}) {
    const std::string msh = tmp.path("b" + std::to_string(size) + ".msh");
    const test::CliResult r = test::run_cli({"mesh-coarse", cad, "--size", std::to_string(size), "-o", msh, "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const CoarseMesh m = read_coarse_mesh(msh);
    // Every edge at most `size` long (a transfinite box: axis-aligned hexes).
    double longest = 0;
    for (Id e = 0; e < m.num_elements(); ++e)
      for (int k = 0; k < 12; ++k) {
        const Id a = m.conn[e * 8 + kHexEdge[k][0]], b = m.conn[e * 8 + kHexEdge[k][1]];
        longest = std::max(longest, std::hypot(m.x[a] - m.x[b], m.y[a] - m.y[b], m.z[a] - m.z[b]));
      }
    EXPECT_LE(longest, size * (1 + 1e-9)) << "size " << size;
    if (previous > 0) {
      EXPECT_LT(m.num_elements(), previous) << "size " << size;
    }
    previous = m.num_elements();
  }
  EXPECT_EQ(previous, 1);
}

// A size that would make a huge "coarse" mesh is refused before Gmsh runs
// (it grew by hundreds of MB a second at 1e-3 of this box, and wrote one
// hex at 1e-12; 1e7 quads took it a minute), and so is an output folder
// that does not exist.
TEST(MeshCoarse, HugeCountsAndMissingFoldersAreRefusedBeforeMeshing) {
  TempDir tmp;
  const std::string cad = tmp.path("box.step"), msh = tmp.path("x.msh");
  make_cad(cad, [] { gmsh::model::occ::addBox(0, 0, 0, 2, 1, 1); });
  for (const bool surface : {false, true})
    for (const double size : {surface ? 2e-4 : 1e-3, 1e-12}) {
      CoarseMeshOptions mo;
      mo.size = size;
      mo.surface = surface;
      try {
        mesh_coarse(cad, msh, mo);
        ADD_FAILURE() << "size " << size << " meshed";
      } catch (const Error& e) {
        EXPECT_EQ(e.kind(), ErrorKind::Usage) << e.what();
        EXPECT_NE(std::string(e.what()).find("--size"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(surface ? "area 10 " : "volume 2 "), std::string::npos) << e.what();
      }
    }
  EXPECT_FALSE(std::filesystem::exists(msh));
  CoarseMeshOptions mo;
  mo.size = 1;
  try {
    mesh_coarse(cad, tmp.path("no-such-folder/x.msh"), mo);
    ADD_FAILURE() << "wrote into a missing folder";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Io) << e.what();
    EXPECT_NE(std::string(e.what()).find("no-such-folder"), std::string::npos) << e.what();
  }
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(tmp.path("")), {}), 1);  // box.step alone
}

// A sphere's one face has 4 curves in Gmsh's list (its seam twice and two
// degenerate pole curves) but is no 4-sided patch: --surface used to try
// transfinite meshing and fail; it subdivides, and the quads are on the
// sphere.
TEST(MeshCoarse, SurfaceOfASphereIsSubdivided) {
  TempDir tmp;
  const std::string cad = tmp.path("sphere.step"), msh = tmp.path("s.msh");
  make_cad(cad, [] { gmsh::model::occ::addSphere(0, 0, 0, 1); });
  CoarseMeshOptions mo;
  mo.size = 0.5;
  mo.surface = true;
  EXPECT_EQ(mesh_coarse(cad, msh, mo).method, "subdivision");
  const CoarseMesh m = read_coarse_mesh(msh);
  ASSERT_EQ(m.mode, Mode::Surface);
  EXPECT_GT(m.num_elements(), 24);
  for (Id v = 0; v < m.num_vertices(); ++v) EXPECT_NEAR(std::hypot(m.x[v], m.y[v], m.z[v]), 1.0, 1e-9) << v;
  // A closed shell: V - E + F = 2.
  const Topology t = build_topology(m);
  EXPECT_EQ(t.num_vertices - t.num_edges() + m.num_elements(), 2);
}

// An open tube's side is 4-sided although a seam is two of its sides (its
// two circles and the seam, twice): it stays transfinite, while a sphere's
// face (a seam twice and two degenerate pole curves) and a torus's (two
// seams) are subdivided.
TEST(MeshCoarse, SeamsAndPolesDecideTransfiniteOrSubdivision) {
  TempDir tmp;
  struct Case {
    const char* name;
    std::function<void()> build;
    const char* method;
  };
  const Case cases[] = {
      {"tube",
       [] {
         const int c = gmsh::model::occ::addCircle(0, 0, 0, 1);
         gmsh::vectorpair out;
         gmsh::model::occ::extrude({{1, c}}, 0, 0, 2, out);
       },
       "transfinite"},
      {"sphere", [] { gmsh::model::occ::addSphere(0, 0, 0, 1); }, "subdivision"},
      {"torus", [] { gmsh::model::occ::addTorus(0, 0, 0, 2, 0.7); }, "subdivision"}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string cad = tmp.path(std::string(c.name) + ".brep"), msh = tmp.path(std::string(c.name) + ".msh");
    make_cad(cad, c.build);
    // Through the command: one Gmsh meshing per process.
    const test::CliResult r = test::run_cli({"mesh-coarse", cad, "--size", "0.5", "--surface", "-o", msh});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find(std::string(" by ") + c.method + ":"), std::string::npos) << r.out;
    EXPECT_EQ(read_coarse_mesh(msh).mode, Mode::Surface);
  }
}

// --surface on two boxes sharing a face: the shared face would give edges
// of three quads (refused as non-manifold, "try a smaller --size", at any
// size). The skin is meshed and diced on the CAD, which has a surface no
// quad covers.
TEST(MeshCoarse, SurfaceOfTwoVolumesIsTheirSkin) {
  TempDir tmp;
  const std::string cad = tmp.path("two.step"), msh = tmp.path("t.msh");
  make_cad(cad, [] {
    gmsh::model::occ::addBox(0, 0, 0, 1, 1, 1, 1);
    gmsh::model::occ::addBox(1, 0, 0, 1, 1, 1, 2);
    gmsh::vectorpair out;
    std::vector<gmsh::vectorpair> map;
    gmsh::model::occ::fragment({{3, 1}}, {{3, 2}}, out, map);
  });
  CoarseMeshOptions mo;
  mo.size = 0.5;
  mo.surface = true;
  const CoarseMeshReport r = mesh_coarse(cad, msh, mo);
  EXPECT_EQ(r.interfaces_left_out, 1);
  const CoarseMesh m = read_coarse_mesh(msh);
  // The skin of a 2 x 1 x 1 box: area 10, no quad inside at x = 1.
  double area = 0;
  for (Id e = 0; e < m.num_elements(); ++e) {
    const Id* c = &m.conn[e * 4];
    double cx = 0;
    for (int q = 0; q < 4; ++q) cx += 0.25 * m.x[c[q]];
    const bool across_x = std::abs(m.x[c[0]] - m.x[c[2]]) > 1e-9 || std::abs(m.x[c[1]] - m.x[c[3]]) > 1e-9;
    EXPECT_FALSE(!across_x && std::abs(cx - 1) < 1e-9) << "a quad on the interface, element " << e;
    const double ux = m.x[c[1]] - m.x[c[0]], uy = m.y[c[1]] - m.y[c[0]], uz = m.z[c[1]] - m.z[c[0]];
    const double vx = m.x[c[3]] - m.x[c[0]], vy = m.y[c[3]] - m.y[c[0]], vz = m.z[c[3]] - m.z[c[0]];
    area += std::hypot(uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx);  // planar rectangles
  }
  EXPECT_NEAR(area, 10.0, 1e-9);
  IntervalRequest req;
  req.global = 3;
  FineMesh fine = FineMesh::dice(read_coarse_mesh(msh), req);
  const ConformReport rep = conform_to_geometry(fine, cad);
  EXPECT_GT(rep.faces_on_surfaces, 0);
  EXPECT_TRUE(verify(fine).ok());
}

// A STEP file with one line deleted (a dangling reference) crashes
// OpenCASCADE's reader (SIGSEGV) on Debian 12: dicer-cad said nothing and
// died by the signal (exit 139), for mesh-coarse and dice --geometry alike.
// Now one message names the model and the exit code is 70 or, should
// OpenCASCADE refuse the file cleanly one day, 3; never a signal, and no
// output left behind.
TEST(MeshCoarse, CadThatCrashesOpenCascadeIsAnErrorNamingIt) {
  TempDir tmp;
  const std::string good = tmp.path("sphere.step"), bad = tmp.path("broken.step");
  make_cad(good, [] { gmsh::model::occ::addSphere(0, 0, 0, 1); });
  {
    std::ifstream in(good);
    std::ofstream out(bad);
    std::string line;
    int dropped = 0;
    while (std::getline(in, line)) {
      if (line.find("= VERTEX_LOOP(") != std::string::npos && dropped++ == 0) continue;
      out << line << "\n";
    }
    ASSERT_EQ(dropped, 1) << "no VERTEX_LOOP in Gmsh's STEP of a sphere";
  }
  const std::string msh = tmp.path("c.msh"), store = tmp.path("c.dice.h5");
  CoarseMeshOptions mo;
  mo.size = 0.5;
  mesh_coarse(good, msh, mo);
  const std::vector<std::vector<std::string>> runs = {
      {"mesh-coarse", bad, "--size", "0.5", "-o", tmp.path("x.msh")},
      {"dice", msh, "--geometry", bad, "--interval", "2", "-o", tmp.path("x.dice.h5")}};
  for (const auto& args : runs) {
    const test::CliResult r = test::run_cli(args);
    SCOPED_TRACE(args[0]);
    EXPECT_TRUE(r.exit_code == 70 || r.exit_code == 3) << r.exit_code << " " << r.err;
    EXPECT_NE(r.err.find("dicer " + args[0] + ": error: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(bad), std::string::npos) << r.err;
    if (r.exit_code == 70) {
      EXPECT_NE(r.err.find("crashed with SIGSEGV"), std::string::npos) << r.err;
      // What OpenCASCADE said before it crashed, inside the one message.
      EXPECT_NE(r.err.find("(OpenCASCADE reported: "), std::string::npos) << r.err;
    }
    EXPECT_EQ(r.err.find('\x1b'), std::string::npos) << "an ANSI escape on stderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
  std::vector<std::string> left;
  for (const auto& e : std::filesystem::directory_iterator(tmp.path(""))) left.push_back(e.path().filename().string());
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"broken.step", "c.msh", "sphere.step"}));
}

// OpenCASCADE's readers print their complaints in ANSI colours straight to
// the standard streams, before and apart from dicer's message, whose own
// words were only Gmsh's "Could not read file". A damaged STEP file may
// also read with parts missing, which only those lines said: a file with
// one broken entity was meshed without a word, another ended in "holds no
// curve or surface". Now their text is in dicer's one message.
TEST(MeshCoarse, OpenCascadesComplaintsAreInDicersMessages) {
  TempDir tmp;
  const std::string good = tmp.path("box.step");
  make_cad(good, [] { gmsh::model::occ::addBox(0, 0, 0, 2, 1, 1); });
  std::vector<std::string> lines;
  {
    std::ifstream in(good);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
  }
  auto write_without = [&](const std::string& name, const std::string& marker) {
    std::ofstream out(tmp.path(name));
    int dropped = 0;
    for (size_t i = 0; i < lines.size(); ++i) {
      if (lines[i].find(marker) != std::string::npos && dropped++ == 0) {
        // The entity must go on on the next line, which is then an orphan.
        EXPECT_TRUE(marker != "APPLICATION_PROTOCOL_DEFINITION(" || (i + 1 < lines.size() && lines[i + 1].rfind("#", 0) != 0))
            << "OpenCASCADE wrote " << marker << " on one line";
        continue;
      }
      out << lines[i] << "\n";
    }
    EXPECT_EQ(dropped, 1) << marker;
    return tmp.path(name);
  };
  // A broken entity that names nothing of the shape: meshed, with a warning.
  const std::string syntax = write_without("syntax.step", "APPLICATION_PROTOCOL_DEFINITION(");
  // The shell gone: the model is empty, and the error says why.
  const std::string shell = write_without("shell.step", "CLOSED_SHELL(");
  // Cut in the middle: the parser's line and complaint.
  const std::string cut = tmp.path("cut.step");
  {
    std::ifstream in(good, std::ios::binary);
    std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(cut, std::ios::binary) << all.substr(0, all.size() / 2);
  }
  auto one_clean_line = [](const test::CliResult& r) {
    EXPECT_EQ(r.err.find('\x1b'), std::string::npos) << "an ANSI escape on stderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.err.find("****"), std::string::npos) << r.err;
  };
  {
    const test::CliResult r = test::run_cli({"mesh-coarse", syntax, "--size", "0.5", "-o", tmp.path("s.msh")});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(r.out.find("meshed"), std::string::npos) << r.out;
    EXPECT_NE(r.err.find("dicer mesh-coarse: warning: " + syntax + ": OpenCASCADE reported problems reading it: "),
              std::string::npos) << r.err;
    EXPECT_NE(r.err.find("Incorrect Syntax"), std::string::npos) << r.err;
    one_clean_line(r);
    // dice and verify --geometry say it too, once (dice reads the CAD twice
    // with intervals by entity); --json's stdout stays a document.
    const std::string store = tmp.path("s.dice.h5");
    const test::CliResult d = test::run_cli(
        {"dice", tmp.path("s.msh"), "--geometry", syntax, "--interval", "2", "--entity-interval", "3:1=3", "-o", store});
    EXPECT_EQ(d.exit_code, 0) << d.err;
    EXPECT_NE(d.err.find("dicer dice: warning: " + syntax + ": OpenCASCADE reported problems"), std::string::npos) << d.err;
    one_clean_line(d);
    const test::CliResult v = test::run_cli({"verify", store, "--geometry", syntax, "--json"});
    EXPECT_EQ(v.exit_code, 0) << v.err;
    EXPECT_EQ(v.out.rfind("{", 0), 0u) << v.out;
    EXPECT_NE(v.err.find("dicer verify: warning: "), std::string::npos) << v.err;
    one_clean_line(v);
    // The library's report holds it; the streams are back afterwards.
    CoarseMeshOptions mo;
    mo.size = 0.5;
    const CoarseMeshReport rep = mesh_coarse(syntax, tmp.path("s2.msh"), mo);
    EXPECT_NE(rep.cad_reader_said.find("Incorrect Syntax"), std::string::npos) << rep.cad_reader_said;
    EXPECT_EQ(mesh_coarse(good, tmp.path("g.msh"), mo).cad_reader_said, "");
  }
  {
    const test::CliResult r = test::run_cli({"mesh-coarse", shell, "--size", "0.5", "-o", tmp.path("x.msh")});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find("holds no curve or surface"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("OpenCASCADE reported: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("Unresolved Reference"), std::string::npos) << r.err;
    one_clean_line(r);
  }
  {
    const test::CliResult r = test::run_cli({"mesh-coarse", cut, "--size", "0.5", "-o", tmp.path("x.msh")});
    EXPECT_EQ(r.exit_code, 3) << r.err;
    EXPECT_NE(r.err.find(cut + ": OpenCASCADE cannot read the CAD file: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("Line "), std::string::npos) << "the parser's line: " << r.err;
    EXPECT_EQ(r.err.find("Could not read file"), std::string::npos) << r.err;
    one_clean_line(r);
  }
  EXPECT_FALSE(std::filesystem::exists(tmp.path("x.msh")));
}

// OpenCASCADE's BREP reader looped for hours on some truncated files (a
// shape count it never read), about half the runs, as its garbage count
// depends on the address space's layout: mesh-coarse and dice --geometry
// hung. dicer-cad's watchdog ends a read past its limit (exit 3, one line
// naming the file). setarch -R fixes the layout, so that a given head
// loops or fails in every run of one build; which heads loop differs
// between builds, so the test cuts several.
TEST(MeshCoarse, CadReadThatDoesNotEndIsEndedByTheWatchdog) {
  TempDir tmp;
  const std::string good = tmp.path("cyl.brep");
  make_cad(good, [] { gmsh::model::occ::addCylinder(0, 0, 0, 0, 0, 2, 0.5); });
  std::string all;
  {
    std::ifstream in(good, std::ios::binary);
    all.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  ASSERT_GT(all.size(), 500u);
  if (!std::filesystem::exists("/usr/bin/setarch") || !std::filesystem::exists("/usr/bin/timeout"))
    GTEST_SKIP() << "no /usr/bin/setarch (util-linux) or /usr/bin/timeout (coreutils)";
  int ended = 0, failed = 0;
  const std::string out = tmp.path("x.msh");
  for (int k = 6; k <= 16; ++k) {
    const std::string head = tmp.path("head" + std::to_string(k) + ".brep");
    std::ofstream(head, std::ios::binary) << all.substr(0, all.size() * k / 20);
    // timeout: without the watchdog a looping head fails here, not at ctest's limit.
    const test::CliResult r =
        test::run_process({"/usr/bin/timeout", "60", "/usr/bin/setarch", "-R", DICER_CLI, "mesh-coarse", head, "--size", "0.8", "-o", out},
                          {{"DICER_CAD_READ_SECONDS", "1"}});
    if (r.exit_code != 0 && r.err.find("setarch") != std::string::npos && r.err.find("dicer") == std::string::npos)
      GTEST_SKIP() << "setarch -R is not allowed here: " << r.err;
    SCOPED_TRACE(head);
    if (r.exit_code == 0) continue;  // a head that is a smaller model
    ++failed;
    EXPECT_TRUE(r.exit_code == 3 || r.exit_code == 7 || r.exit_code == 70) << r.exit_code << " " << r.err;
    EXPECT_NE(r.err.find("dicer mesh-coarse: error: " + head), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_EQ(r.err.find('\x1b'), std::string::npos) << r.err;
    if (r.err.find("OpenCASCADE did not finish reading the CAD file in ") != std::string::npos) {
      ++ended;
      EXPECT_EQ(r.exit_code, 3);
      EXPECT_NE(r.err.find("(limit 1 s, from DICER_CAD_READ_SECONDS)"), std::string::npos) << r.err;
    }
    EXPECT_FALSE(std::filesystem::exists(out));
  }
  EXPECT_GT(failed, 0);
  if (ended == 0) GTEST_SKIP() << "no head of the BREP file looped in this build (" << failed << " failed at once)";
}

// A cylinder whose STEP file lost its closed circle edge read with one
// complaint, and Gmsh's meshing of it then ran for minutes (in its
// Delaunay; not seen to end). The watchdog ends the meshing past its limit
// (exit 7, one line, what OpenCASCADE reported included); a bad limit is a
// usage error.
TEST(MeshCoarse, MeshingThatDoesNotEndIsEndedByTheWatchdog) {
  TempDir tmp;
  const std::string good = tmp.path("cyl.step"), bad = tmp.path("open.step"), out = tmp.path("x.msh");
  if (!std::filesystem::exists("/usr/bin/timeout")) GTEST_SKIP() << "no /usr/bin/timeout (coreutils)";
  make_cad(good, [] { gmsh::model::occ::addCylinder(0, 0, 0, 0, 0, 3, 1); });
  {
    std::ifstream in(good);
    std::ofstream o(bad);
    int closed = 0;
    for (std::string line; std::getline(in, line);) {
      // The second circle, "#78 = EDGE_CURVE('',#56,#56,#79,.T.);": from a
      // vertex to itself.
      const auto at = line.find("EDGE_CURVE('',#");
      if (at != std::string::npos) {
        const std::string rest = line.substr(at + 14);
        const std::string v = rest.substr(0, rest.find(','));
        if (rest.compare(v.size() + 1, v.size(), v) == 0 && ++closed == 2) continue;
      }
      o << line << "\n";
    }
    ASSERT_EQ(closed, 2) << "not two closed EDGE_CURVEs in Gmsh's STEP of a cylinder";
  }
  const test::CliResult r = test::run_process(
      {"/usr/bin/timeout", "120", DICER_CLI, "mesh-coarse", bad, "--size", "0.5", "-o", out}, {{"DICER_CAD_MESH_SECONDS", "2"}});
  if (r.exit_code != 7 || r.err.find("did not finish meshing") == std::string::npos) {
    // This Gmsh meshes or refuses the model: nothing to end.
    EXPECT_TRUE(r.exit_code == 0 || r.exit_code == 3 || r.exit_code == 7 || r.exit_code == 70) << r.exit_code << " " << r.err;
    GTEST_SKIP() << "Gmsh ended on its own (" << r.exit_code << "): " << r.err;
  }
  EXPECT_NE(r.err.find("dicer mesh-coarse: error: " + bad + ": Gmsh did not finish meshing the model at --size 0.5 in "),
            std::string::npos) << r.err;
  EXPECT_NE(r.err.find("(limit 2 s, from DICER_CAD_MESH_SECONDS); reading it, OpenCASCADE reported: "), std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_FALSE(std::filesystem::exists(out));
  for (const char* var : {"DICER_CAD_MESH_SECONDS", "DICER_CAD_READ_SECONDS"}) {
    const test::CliResult u = test::run_process({DICER_CLI, "mesh-coarse", good, "--size", "0.5", "-o", out}, {{var, "-1"}});
    EXPECT_EQ(u.exit_code, 2) << u.err;
    EXPECT_NE(u.err.find(std::string(var) + "=-1: not a positive number of seconds"), std::string::npos) << u.err;
  }
}

// Under a file size limit SIGXFSZ killed dicer-cad (exit 153) with its
// temporary left, and once ignored, Gmsh's unchecked write would cut the
// file short for the reader to blame the mesh. Now: exit 5, one line
// naming the output and the limit, nothing left.
TEST(MeshCoarse, FileSizeLimitIsAnIoErrorAndLeavesNothing) {
  TempDir tmp;
  const std::string cad = tmp.path("box.step"), out = tmp.path("out.msh");
  make_cad(cad, [] { gmsh::model::occ::addBox(0, 0, 0, 1, 1, 1); });
  const test::CliResult r = test::run_process(
      {"/bin/sh", "-c", "ulimit -f 2 && exec \"$0\" mesh-coarse \"$1\" --size 0.2 -o \"$2\"", DICER_CLI, cad, out});
  EXPECT_EQ(r.exit_code, 5) << r.err;
  // (dash counts ulimit -f in 512-byte blocks, bash in 1024.)
  EXPECT_NE(r.err.find("dicer mesh-coarse: error: " + out + ": cannot write the coarse mesh: it reached the file size limit (ulimit -f) of "),
            std::string::npos) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  std::vector<std::string> left;
  for (const auto& e : std::filesystem::directory_iterator(tmp.path(""))) left.push_back(e.path().filename().string());
  EXPECT_EQ(left, std::vector<std::string>{"box.step"});
}

TEST(MeshCoarse, ReaderTextIsOneCleanLine) {
  auto clean = [](const std::string& in, size_t cap = 256) {
    std::string out(cap, '?');
    out.resize(geometry::clean_reader_text(in.data(), in.size(), out.data(), out.size()));
    return out;
  };
  EXPECT_EQ(clean("\x1b[31;1m**** ERR StepFile : Undefined Parsing: Line 2: unexpected TYPE    ****\x1b[0m\n"
                  "\n\x1b[32;1m*** ERR StepReaderData : Unresolved Reference : Fails Count : 1 ***\x1b[0m\n"),
            "ERR StepFile: Undefined Parsing: Line 2: unexpected TYPE; ERR StepReaderData: Unresolved Reference: Fails Count: 1");
  EXPECT_EQ(clean(""), "");
  EXPECT_EQ(clean("\n\r\n  ***  \n"), "");
  EXPECT_EQ(clean("a\tb\x07" "c\r\nd"), "a b?c; d");
  EXPECT_EQ(clean("abcdefghijkl", 5), "abcd");
  EXPECT_EQ(clean("ab\ncd\nef", 6), "ab; c");
  std::string nul(4, 'x');
  EXPECT_EQ(geometry::clean_reader_text("xyz", 3, nul.data(), 1), 0u);
  EXPECT_EQ(nul[0], '\0');
}

// dicer-cad's crash handler was inherited by the isolated Exodus reader's
// child: HDF5 crashing there (under a 1 MiB limit) was said as "dicer-cad
// crashed ... the CAD model box.step" and then "the isolated reader ended
// without an answer". The child's crash is the reader's to say, naming the
// mesh file. (Under ASan the child has no address-space limit and reads.)
TEST(MeshCoarse, ReaderCrashUnderDicerCadIsNotBlamedOnTheCad) {
  TempDir tmp;
  const std::string cad = tmp.path("box.step"), msh = tmp.path("box.msh"), store = tmp.path("box.dice.h5");
  const std::string exo = tmp.path("box.e");
  make_cad(cad, [] { gmsh::model::occ::addBox(0, 0, 0, 1, 1, 1); });
  CoarseMeshOptions mo;
  mo.size = 0.5;
  mesh_coarse(cad, msh, mo);
  ASSERT_EQ(test::run_cli({"dice", msh, "--interval", "1", "-o", store, "--quiet"}).exit_code, 0);
  const test::CliResult x = test::run_cli({"export", store, "-o", exo});
  ASSERT_EQ(x.exit_code, 0) << x.err;
  const test::CliResult r = test::run_process(
      {DICER_CLI, "dice", exo, "--geometry", cad, "--interval", "2", "-o", tmp.path("out.dice.h5"), "--quiet"},
      {{"DICER_READER_MEMORY_MB", "1"}});
  EXPECT_EQ(r.err.find("dicer-cad crashed"), std::string::npos) << r.err;
  EXPECT_NE(r.exit_code, 70) << r.err;
  if (r.exit_code != 0) {
    EXPECT_NE(r.err.find(exo), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  }
}

// Which CAD a store's boundary was put on was nowhere in the store: info
// now says it (text and JSON), from the geometry_source attribute; a store
// diced without a CAD has none (JSON null).
TEST(Geometry, StoreRecordsTheCadItWasDicedOn) {
  TempDir tmp;
  const std::string cad = tmp.path("cyl.brep"), msh = tmp.path("cyl.msh");
  const std::string on = tmp.path("on.dice.h5"), off = tmp.path("off.dice.h5");
  make_cad(cad, [] { gmsh::model::occ::addCylinder(0, 0, 0, 0, 0, 2, 1); });
  CoarseMeshOptions mo;
  mo.size = 0.8;
  mesh_coarse(cad, msh, mo);
  ASSERT_EQ(test::run_cli({"dice", msh, "--geometry", cad, "--interval", "2", "-o", on, "--quiet"}).exit_code, 0);
  ASSERT_EQ(test::run_cli({"dice", msh, "--interval", "2", "-o", off, "--quiet"}).exit_code, 0);
  EXPECT_EQ(read_store(on, StoreOptions{8ull << 20, 0}).info().geometry, cad);
  EXPECT_EQ(read_store(off, StoreOptions{8ull << 20, 0}).info().geometry, "");
  test::CliResult r = test::run_cli({"info", on});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("geometry   " + cad), std::string::npos) << r.out;
  r = test::run_cli({"info", on, "--json"});
  EXPECT_NE(r.out.find("\"geometry\":\"" + cad + "\""), std::string::npos) << r.out;
  r = test::run_cli({"info", off, "--json"});
  EXPECT_NE(r.out.find("\"geometry\":null"), std::string::npos) << r.out;
  r = test::run_cli({"info", off});
  EXPECT_EQ(r.out.find("geometry "), std::string::npos) << r.out;
}

}  // namespace
}  // namespace dicer
