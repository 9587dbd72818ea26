// Chunk partition properties and box selections against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/quality.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

FineMesh diced(const char* file, Id interval) {
  IntervalRequest r;
  r.global = interval;
  return FineMesh::dice(read_coarse_mesh(test::data_path(file)), r);
}

MeshSets sets_of(const FineMesh& m) { return MeshSets{m.coarse()->side_sets, m.coarse()->node_sets}; }

}  // namespace

TEST(Chunks, PartitionCoversEveryElementOnceWithBalancedSizes) {
  for (const char* file : {"vtkdata_mug.e", "cardinal_prism.exo", "libmesh_cylinder_shell.exo"}) {
    const FineMesh m = diced(file, 2);
    for (Id K : {1, 2, 3, 7}) {
      const auto plan = plan_chunks(m, K);
      ASSERT_EQ(static_cast<Id>(plan.size()), K);
      std::vector<Id> seen;
      Id max_coarse_fine = 0;
      FineBlock b;
      for (Id h = 0; h < m.num_coarse_elements(); ++h) {
        m.fill_block(h, b, true);
        max_coarse_fine = std::max(max_coarse_fine, b.num_elements());
      }
      const double ideal = static_cast<double>(m.num_elements()) / static_cast<double>(K);
      for (const auto& r : plan) {
        ExportChunk c(m, r);
        c.prepare(sets_of(m));
        EXPECT_EQ(c.num_elements(), r.fine_elements);
        seen.insert(seen.end(), c.element_global().begin(), c.element_global().end());
        EXPECT_LE(std::abs(static_cast<double>(r.fine_elements) - ideal), static_cast<double>(max_coarse_fine))
            << file << " K=" << K << " chunk " << r.index;
      }
      std::sort(seen.begin(), seen.end());
      ASSERT_EQ(static_cast<Id>(seen.size()), m.num_elements()) << file << " K=" << K;
      for (Id i = 0; i < static_cast<Id>(seen.size()); ++i) ASSERT_EQ(seen[i], i) << "every element exactly once";
    }
  }
}

TEST(Chunks, SharedNodesAgreeBitForBitAndTheOwnerIsTheLowestChunkHoldingThem) {
  const FineMesh m = diced("cardinal_cylinders.exo", 2);
  const Id K = 4;
  const auto plan = plan_chunks(m, K);
  std::map<Id, Id> lowest;          // node -> lowest chunk holding it (brute force)
  std::map<Id, std::int32_t> owner;  // as the chunks report it
  std::map<Id, Vec3> where;
  Id shared = 0;
  for (const auto& r : plan) {
    ExportChunk c(m, r);
    c.prepare(sets_of(m));
    // Connectivity maps back to global ids equal to element(id).
    for (Id e = 0; e < c.num_elements(); e += 97) {
      const FineElement el = m.element(c.element_global()[e]);
      for (int q = 0; q < 8; ++q) ASSERT_EQ(c.node_global()[c.connectivity()[8 * e + q]], el.nodes[q]);
      ASSERT_EQ(c.element_block()[e], el.block);
    }
    for (Id l = 0; l < c.num_nodes(); ++l) {
      const Id g = c.node_global()[l];
      const Vec3 p{c.x()[l], c.y()[l], c.z()[l]};
      auto [it, fresh] = lowest.emplace(g, r.index);
      if (!fresh) {
        ++shared;
        ASSERT_TRUE(where[g] == p) << "node " << g << " differs between chunks";
        ASSERT_EQ(owner[g], c.node_owner()[l]) << "chunks disagree on the owner of node " << g;
      } else {
        where[g] = p;
        owner[g] = c.node_owner()[l];
        ASSERT_TRUE(p == m.node(g));
      }
    }
  }
  EXPECT_GT(shared, 0);
  for (const auto& [g, low] : lowest) ASSERT_EQ(owner[g], low) << "node " << g;
  EXPECT_EQ(static_cast<Id>(lowest.size()), m.num_nodes()) << "every node is in some chunk";
}

TEST(Chunks, SideSetsCarryToEveryFineFaceOfTheCoarseSide) {
  const FineMesh m = diced("cardinal_prism.exo", 3);
  ExportChunk c(m, plan_chunks(m, 1)[0]);
  c.prepare(sets_of(m));
  ASSERT_EQ(c.side_sets().size(), m.coarse()->side_sets.size());
  for (size_t s = 0; s < c.side_sets().size(); ++s) {
    // Every coarse side of a hex diced at 3 everywhere has 3 x 3 fine faces.
    EXPECT_EQ(c.side_sets()[s].element.size(), 9 * m.coarse()->side_sets[s].element.size()) << c.side_sets()[s].name;
    EXPECT_EQ(c.side_sets()[s].name, m.coarse()->side_sets[s].name);
  }
}

TEST(Chunks, BoxSelectionMatchesBruteForce) {
  const FineMesh m = diced("vtkdata_mug.e", 2);
  std::mt19937_64 rng(11);
  // Bounding box of the coarse vertices.
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (Id v = 0; v < m.coarse()->num_vertices(); ++v) {
    const Vec3 p = m.coarse()->vertex(v);
    const double c[3] = {p.x, p.y, p.z};
    for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], c[d]), hi[d] = std::max(hi[d], c[d]);
  }
  for (int trial = 0; trial < 4; ++trial) {
    Box box;
    for (int d = 0; d < 3; ++d) {
      std::uniform_real_distribution<double> u(lo[d], hi[d]);
      double a = u(rng), b = u(rng);
      box.lo[d] = std::min(a, b), box.hi[d] = std::max(a, b);
    }
    std::vector<Id> brute;
    for (Id e = 0; e < m.num_elements(); ++e) {
      const FineElement el = m.element(e);
      double c[3] = {0, 0, 0};
      for (int q = 0; q < 8; ++q) {
        const Vec3 p = m.node(el.nodes[q]);
        c[0] += p.x, c[1] += p.y, c[2] += p.z;
      }
      for (double& v : c) v /= 8;
      if (box.contains(c[0], c[1], c[2])) brute.push_back(e);
    }
    std::vector<Id> streamed;
    const Id n = for_each_in_box(m, box, [&](const FineBlock& b, Id e) { streamed.push_back(b.first_element + e); });
    EXPECT_EQ(n, static_cast<Id>(brute.size()));
    EXPECT_EQ(streamed, brute) << "trial " << trial;
    ExportChunk c(m, plan_chunks(m, 1)[0], box);
    c.prepare(sets_of(m));
    EXPECT_EQ(std::vector<Id>(c.element_global().begin(), c.element_global().end()), brute);
  }
  EXPECT_THROW(parse_box("0,0,0,1,1"), Error);
  EXPECT_THROW(parse_box("0,0,0,1,1,x"), Error);
  EXPECT_THROW(parse_box("1,0,0,0,1,1"), Error);
  EXPECT_NO_THROW(parse_box("-1,-2e-3,0,1,1,1"));
}

// A box over coarse elements too large to hold whole (interval 45: each is
// read in two slabs of grid planes, for_each_slab in export/chunk.cpp)
// gives what the whole-chunk path and brute force give: ids, coordinates,
// connectivity and the side and node sets that follow the slabs' element
// ids.
TEST(Chunks, BoxSelectionOfLargeElementsReadInSlabsMatchesTheWholeChunk) {
  std::mt19937_64 rng(5);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 1, spec.c = 1;
  CoarseMesh cm = test::random_box(spec, rng);
  for (std::int8_t s = 0; s < 6; ++s) cm.side_sets.push_back({10 + s, "side" + std::to_string(s), {s % 2}, {s}});
  cm.node_sets.push_back({7, "corners", {0, 3, 5}});
  IntervalRequest req;
  req.global = 45;
  const FineMesh m = FineMesh::dice(cm, req);
  const MeshSets sets = sets_of(m);
  ExportChunk whole(m, plan_chunks(m, 1)[0]);
  whole.prepare(sets);
  Box all;
  for (int d = 0; d < 3; ++d) all.lo[d] = -10, all.hi[d] = 10;
  ExportChunk boxed(m, plan_chunks(m, 1)[0], all);
  boxed.prepare(sets);
  ASSERT_EQ(boxed.num_elements(), m.num_elements());
  auto eq = [](const auto& a, const auto& b) { return std::equal(a.begin(), a.end(), b.begin(), b.end()); };
  EXPECT_TRUE(eq(boxed.element_global(), whole.element_global()));
  EXPECT_TRUE(eq(boxed.node_global(), whole.node_global()));
  EXPECT_TRUE(eq(boxed.connectivity(), whole.connectivity()));
  EXPECT_TRUE(eq(boxed.x(), whole.x()) && eq(boxed.y(), whole.y()) && eq(boxed.z(), whole.z()));
  ASSERT_EQ(boxed.side_sets().size(), 6u);
  for (size_t s = 0; s < 6; ++s) {
    EXPECT_EQ(boxed.side_sets()[s].element, whole.side_sets()[s].element) << s;
    EXPECT_EQ(boxed.side_sets()[s].side, whole.side_sets()[s].side) << s;
    EXPECT_EQ(boxed.side_sets()[s].element.size(), 45u * 45u) << s;
  }
  ASSERT_EQ(boxed.node_sets().size(), 1u);
  EXPECT_EQ(boxed.node_sets()[0].node, whole.node_sets()[0].node);
  // A box through the middle: brute force over every element's centroid.
  Box mid;
  mid.lo = {0.7, 0.2, 0.3}, mid.hi = {1.3, 0.6, 0.45};
  std::vector<Id> brute;
  for (Id e = 0; e < m.num_elements(); ++e) {
    const FineElement el = m.element(e);
    double c[3] = {0, 0, 0};
    for (int q = 0; q < 8; ++q) {
      const Vec3 p = m.node(el.nodes[q]);
      c[0] += p.x, c[1] += p.y, c[2] += p.z;
    }
    for (double& v : c) v /= 8;
    if (mid.contains(c[0], c[1], c[2])) brute.push_back(e);
  }
  ASSERT_GT(brute.size(), 1000u);
  std::vector<Id> streamed;
  EXPECT_EQ(for_each_in_box(m, mid, [&](const FineBlock& b, Id e) { streamed.push_back(b.first_element + e); }),
            static_cast<Id>(brute.size()));
  EXPECT_EQ(streamed, brute);
  ExportChunk part(m, plan_chunks(m, 1)[0], mid);
  part.prepare(sets);
  EXPECT_TRUE(eq(part.element_global(), brute));
  for (Id e = 0; e < part.num_elements(); e += 37) {
    const FineElement el = m.element(part.element_global()[e]);
    for (int q = 0; q < 8; ++q) {
      const Id l = part.connectivity()[8 * e + q];
      ASSERT_EQ(part.node_global()[l], el.nodes[q]);
      ASSERT_TRUE((Vec3{part.x()[l], part.y()[l], part.z()[l]} == m.node(el.nodes[q])));
    }
  }
}

// check_quality reads large elements in slabs too (FineMesh::for_each_slab):
// the worst element and the inverted count as brute force over element(id)
// finds them.
TEST(Chunks, QualityOfLargeElementsReadInSlabsMatchesBruteForce) {
  std::mt19937_64 rng(6);
  test::BoxSpec spec;
  spec.a = 2, spec.b = 1, spec.c = 1, spec.perturb = 0.3;
  IntervalRequest req;
  req.global = 45;
  const FineMesh m = FineMesh::dice(test::random_box(spec, rng), req);
  double worst = 2;
  Id worst_id = -1, inverted = 0;
  for (Id e = 0; e < m.num_elements(); ++e) {
    const FineElement el = m.element(e);
    Vec3 p[8];
    for (int q = 0; q < 8; ++q) p[q] = m.node(el.nodes[q]);
    const double sj = hex_scaled_jacobian(p);
    inverted += !(sj > 0);
    if (sj < worst) worst = sj, worst_id = e;
  }
  const QualityReport r = check_quality(m);
  EXPECT_EQ(r.elements_checked, m.num_elements());
  EXPECT_EQ(r.inverted, inverted);
  EXPECT_EQ(r.min_scaled_jacobian, worst);
  EXPECT_EQ(r.worst_element, worst_id);
}
