// Chunk partition properties and box selections against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
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
