// Partitions and communication maps against brute force over the fine
// mesh: every element once, owned ranges tiling the node ids, coordinates
// bit-identical to node(id), and shared node lists that are exactly the
// nodes two ranks' elements both use, in the same order on both sides.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "dicer/partition.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

void check_partitions(const FineMesh& m, Id P) {
  SCOPED_TRACE("P = " + std::to_string(P));
  const auto plan = plan_chunks(m, P);
  const auto sharing = in_process_sharing(m, plan);
  std::vector<std::vector<NodeRun>> ghosts;
  for (Id c = 0; c < P; ++c) ghosts.push_back(ghost_runs(m, plan, c));
  std::vector<Partition> parts;
  for (Id r = 0; r < P; ++r) {
    EXPECT_EQ(sharing_for(r, plan, ghosts), sharing[static_cast<size_t>(r)]) << "rank " << r;
    parts.emplace_back(m, plan, r, sharing[static_cast<size_t>(r)]);
  }
  // Nodes each rank's elements use (global), by brute force from connectivity.
  std::vector<std::set<Id>> used(static_cast<size_t>(P));
  std::vector<Id> element_seen;
  Id owned_total = 0, next_owned = 0;
  for (Id r = 0; r < P; ++r) {
    const Partition& p = parts[static_cast<size_t>(r)];
    const int nc = p.corners();
    EXPECT_EQ(p.range().node_begin, next_owned) << "owned ranges tile the node ids in rank order";
    next_owned = p.range().node_end;
    owned_total += p.num_owned();
    for (Id e = 0; e < p.num_elements(); ++e) {
      const Id gid = p.element_begin() + e;
      element_seen.push_back(gid);
      const FineElement el = m.element(gid);
      for (int q = 0; q < nc; ++q) {
        const Id l = p.connectivity()[static_cast<size_t>(e * nc + q)];
        ASSERT_EQ(p.node_global()[static_cast<size_t>(l)], el.nodes[q]);
        used[static_cast<size_t>(r)].insert(el.nodes[q]);
      }
    }
    EXPECT_EQ(static_cast<Id>(used[static_cast<size_t>(r)].size()), p.num_nodes()) << "a partition's nodes are what its elements use";
    for (Id l = 0; l < p.num_nodes(); ++l) {
      const Id g = p.node_global()[static_cast<size_t>(l)];
      const Vec3 x = m.node(g);
      ASSERT_TRUE(x.x == p.x()[l] && x.y == p.y()[l] && x.z == p.z()[l]) << "node " << g;
      const bool owned = l < p.num_owned();
      EXPECT_EQ(owned, g >= p.range().node_begin && g < p.range().node_end);
      EXPECT_EQ(p.node_owner()[l] == r, owned);
      if (!owned) {  // its owner really owns it, and is lower
        const auto& o = plan[static_cast<size_t>(p.node_owner()[l])];
        EXPECT_TRUE(g >= o.node_begin && g < o.node_end);
        EXPECT_LT(p.node_owner()[l], r);
      }
    }
    const PartitionStats s = partition_stats(r, plan, sharing[static_cast<size_t>(r)]);
    EXPECT_EQ(s.owned_nodes, p.num_owned());
    EXPECT_EQ(s.ghost_nodes, p.num_nodes() - p.num_owned());
    EXPECT_EQ(s.neighbors, static_cast<Id>(p.neighbors().size()));
  }
  EXPECT_EQ(owned_total, m.num_nodes());
  std::sort(element_seen.begin(), element_seen.end());
  ASSERT_EQ(static_cast<Id>(element_seen.size()), m.num_elements());
  for (Id i = 0; i < m.num_elements(); ++i) ASSERT_EQ(element_seen[static_cast<size_t>(i)], i);

  // Communication maps: symmetric, same order, and exactly used(r) & used(q).
  for (Id r = 0; r < P; ++r) {
    const Partition& p = parts[static_cast<size_t>(r)];
    std::set<std::int32_t> expect_nbr;
    for (Id q = 0; q < P; ++q) {
      if (q == r) continue;
      std::vector<Id> both;
      std::set_intersection(used[r].begin(), used[r].end(), used[q].begin(), used[q].end(), std::back_inserter(both));
      if (!both.empty()) expect_nbr.insert(static_cast<std::int32_t>(q));
      const auto it = std::find(p.neighbors().begin(), p.neighbors().end(), q);
      if (both.empty()) {
        EXPECT_EQ(it, p.neighbors().end()) << r << " and " << q << " share nothing";
        continue;
      }
      ASSERT_NE(it, p.neighbors().end()) << r << " and " << q << " share " << both.size() << " nodes";
      const auto& mine = p.shared_nodes()[static_cast<size_t>(it - p.neighbors().begin())];
      std::vector<Id> mine_global;
      for (Id l : mine) mine_global.push_back(p.node_global()[static_cast<size_t>(l)]);
      EXPECT_EQ(mine_global, both) << "rank " << r << " with " << q;
      const Partition& o = parts[static_cast<size_t>(q)];
      const auto jt = std::find(o.neighbors().begin(), o.neighbors().end(), static_cast<std::int32_t>(r));
      ASSERT_NE(jt, o.neighbors().end());
      const auto& theirs = o.shared_nodes()[static_cast<size_t>(jt - o.neighbors().begin())];
      ASSERT_EQ(theirs.size(), mine.size());
      for (size_t k = 0; k < mine.size(); ++k)
        EXPECT_EQ(o.node_global()[static_cast<size_t>(theirs[k])], mine_global[k]) << "same order on both sides";
    }
    EXPECT_EQ(std::set<std::int32_t>(p.neighbors().begin(), p.neighbors().end()), expect_nbr);
    if (P > 1) {
      EXPECT_FALSE(p.neighbors().empty()) << "a connected mesh split in " << P << " has neighbours";
    }
  }
}

}  // namespace

TEST(Partition, RandomBoxesAgreeWithBruteForce) {
  std::mt19937_64 rng(2024);
  for (int trial = 0; trial < 4; ++trial) {
    test::BoxSpec spec;
    spec.a = 3 + trial % 2, spec.b = 2 + trial % 3, spec.c = 2;
    IntervalRequest req;
    req.global = 2 + trial % 2;
    const FineMesh m = FineMesh::dice(test::random_box(spec, rng), req);
    for (Id P : {1, 2, 3, 5}) check_partitions(m, P);
  }
}

TEST(Partition, RealMeshesVolumeAndSurface) {
  for (const char* file : {"cardinal_sphere.e", "libmesh_cylinder_shell.exo"}) {
    SCOPED_TRACE(file);
    IntervalRequest req;
    req.global = 2;
    const FineMesh m = FineMesh::dice(read_coarse_mesh(test::data_path(file)), req);
    for (Id P : {2, 4, 7}) check_partitions(m, P);
  }
}
