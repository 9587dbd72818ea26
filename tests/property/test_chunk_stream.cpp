// ChunkStream (export.hpp), the writers' streaming source, against brute
// force on random multi-block meshes with side and node sets, volume and
// surface, cut into chunks: every pass checked node by node and element by
// element against node(id) / element(id) and the coarse rows, and the MSH
// files written from it against those written from the held ExportChunk,
// byte for byte.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/numbering.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"
#include "random_mesh.hpp"
#include "test_support.hpp"

using namespace dicer;

namespace {

// Random sets: some sides of some elements, the vertices below a plane.
void add_random_sets(CoarseMesh& c, std::mt19937_64& rng) {
  const bool vol = c.mode == Mode::Volume;
  std::uniform_int_distribution<int> side(0, 5), pick(0, 3);
  SideSet ss{5, "some sides", {}, {}};
  for (Id e = 0; e < static_cast<Id>(c.element_block.size()); ++e)
    if (pick(rng) == 0) ss.element.push_back(e), ss.side.push_back(static_cast<std::int8_t>(side(rng)));
  if (!ss.element.empty()) ss.element.push_back(ss.element.front()), ss.side.push_back(ss.side.front());  // a repeat
  c.side_sets.push_back(ss);
  c.side_sets.push_back(SideSet{9, "", {}, {}});  // empty
  double zmin = c.z[0], zmax = c.z[0];
  for (double z : c.z) zmin = std::min(zmin, z), zmax = std::max(zmax, z);
  NodeSet ns{2, "low", {}};
  for (Id v = 0; v < static_cast<Id>(c.z.size()); ++v)
    if (c.z[v] <= zmin + 0.6 * (zmax - zmin) || (!vol && c.x[v] < 0.5)) ns.vertex.push_back(v);
  c.node_sets.push_back(ns);
}

// What the chunk holds, by brute force over every fine element of the mesh.
struct Truth {
  std::vector<Id> elements;             // global ids of the chunk's elements, ascending
  std::vector<Id> nodes;                // global ids they use, ascending
  std::map<Id, std::set<std::int32_t>> users;  // node -> blocks of the chunk's elements using it
};

Truth truth(const FineMesh& m, const ChunkRange& r) {
  Truth t;
  std::set<Id> nodes;
  for (Id id = 0; id < m.num_elements(); ++id) {
    const FineElement fe = m.element(id);
    if (fe.coarse_element < r.first_coarse || fe.coarse_element >= r.end_coarse) continue;
    t.elements.push_back(id);
    for (int q = 0; q < fe.num_nodes; ++q) nodes.insert(fe.nodes[q]), t.users[fe.nodes[q]].insert(fe.block);
  }
  t.nodes.assign(nodes.begin(), nodes.end());
  return t;
}

// The vertices of the coarse entity owning node `id`.
std::vector<Id> owner_vertices(const FineMesh& m, Id id) {
  MeshCursor cur;
  const NodeRef ref = m.locate_node(id, cur);
  const RowReader R(m.tables(), cur);
  switch (ref.kind) {
    case EntityKind::Vertex: return {ref.entity};
    case EntityKind::Edge: {
      const EdgeRow e = R.edge(ref.entity);
      return {e.lo, e.hi};
    }
    case EntityKind::Face: {
      const FaceRow f = R.face(ref.entity);
      return {f.v.begin(), f.v.end()};
    }
    case EntityKind::Cell: {
      const ElementRow h = R.element(ref.entity);
      return {h.corner.begin(), h.corner.begin() + 8};
    }
  }
  return {};
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void check_chunk(const FineMesh& m, const MeshSets& sets, const ChunkRange& r, const test::TempDir& dir) {
  SCOPED_TRACE("chunk " + std::to_string(r.index) + " of " + std::to_string(r.count));
  const Truth t = truth(m, r);
  const ChunkStream s(m, r, sets);
  ASSERT_EQ(s.num_nodes(), static_cast<Id>(t.nodes.size()));
  ASSERT_EQ(s.num_elements(), static_cast<Id>(t.elements.size()));
  const auto& user_sets = s.user_sets();
  for (std::int32_t b = 0; b < static_cast<std::int32_t>(m.info().blocks.size()); ++b)
    ASSERT_EQ(user_sets.at(static_cast<size_t>(b)), std::vector<std::int32_t>{b});

  // Nodes, with and without coordinates: local order = global order.
  for (bool coords : {true, false}) {
    Id next = 0;
    s.nodes({coords, -1}, [&](const NodeSpan& span) {
      ASSERT_EQ(span.first, next);
      ASSERT_EQ(span.x != nullptr, coords);
      for (Id q = 0; q < span.count; ++q) {
        const Id g = span.global[q];
        ASSERT_EQ(g, t.nodes.at(static_cast<size_t>(next + q)));
        const auto& want = t.users.at(g);
        const auto& got = user_sets.at(span.users[q]);
        ASSERT_EQ(std::set<std::int32_t>(got.begin(), got.end()), want) << "node " << g;
        if (coords) {
          const Vec3 p = m.node(g);
          ASSERT_EQ(std::bit_cast<std::uint64_t>(span.x[q]), std::bit_cast<std::uint64_t>(p.x)) << "node " << g;
          ASSERT_EQ(std::bit_cast<std::uint64_t>(span.y[q]), std::bit_cast<std::uint64_t>(p.y)) << "node " << g;
          ASSERT_EQ(std::bit_cast<std::uint64_t>(span.z[q]), std::bit_cast<std::uint64_t>(p.z)) << "node " << g;
        }
        ASSERT_EQ(s.local_of(g), next + q);
      }
      next += span.count;
    });
    ASSERT_EQ(next, s.num_nodes());
  }
  // A node outside the chunk has no local id.
  for (Id g = 0; g < m.num_nodes(); g += 7)
    if (!std::binary_search(t.nodes.begin(), t.nodes.end(), g)) {
      ASSERT_EQ(s.local_of(g), -1) << g;
    }

  // Per lowest using block: exactly those nodes, in order, with their local ids.
  for (std::int32_t b = 0; b < static_cast<std::int32_t>(m.info().blocks.size()); ++b) {
    std::vector<Id> want, got;
    for (Id g : t.nodes)
      if (*t.users.at(g).begin() == b) want.push_back(g);
    for (bool coords : {true, false})
      s.nodes({coords, b}, [&](const NodeSpan& span) {
        for (Id q = 0; q < span.count; ++q) {
          got.push_back(span.global[q]);
          ASSERT_EQ(s.local_of(span.global[q]), span.first + q);
          if (coords) {
            ASSERT_EQ(std::bit_cast<std::uint64_t>(span.x[q]), std::bit_cast<std::uint64_t>(m.node(span.global[q]).x));
          }
        }
      });
    want.insert(want.end(), want.begin(), want.end());  // once per pass
    ASSERT_EQ(got, want) << "lowest user block " << b;
  }

  // Elements, all and per block, local and global connectivity.
  const int nc = m.corners();
  std::vector<Id> per_block(m.info().blocks.size(), 0);
  for (Id g : t.elements) ++per_block[static_cast<size_t>(m.element(g).block)];
  EXPECT_EQ(s.block_counts(), per_block);
  for (std::int32_t only = -1; only < static_cast<std::int32_t>(m.info().blocks.size()); ++only)
    for (bool global : {false, true}) {
      std::vector<Id> seen;
      Id last = -1;
      s.elements({only, global}, [&](const ElementSpan& span) {
        ASSERT_GT(span.first, last);
        for (Id e = 0; e < span.count; ++e) {
          const Id g = span.global[e];
          ASSERT_EQ(g, t.elements.at(static_cast<size_t>(span.first + e)));
          const FineElement fe = m.element(g);
          ASSERT_EQ(span.block, fe.block);
          if (only >= 0) {
            ASSERT_EQ(fe.block, only);
          }
          for (int q = 0; q < nc; ++q) {
            const Id c = span.conn[e * nc + q];
            ASSERT_EQ(global ? c : t.nodes.at(static_cast<size_t>(c)), fe.nodes[q]) << "element " << g;
          }
          seen.push_back(g);
        }
        last = span.first + span.count - 1;
      });
      ASSERT_EQ(static_cast<Id>(seen.size()), only < 0 ? s.num_elements() : per_block[static_cast<size_t>(only)]);
    }
  if (!t.elements.empty()) {
    EXPECT_EQ(s.element_ids(), (std::array<Id, 2>{t.elements.front(), t.elements.back()}));
  }

  // Side sets: every fine element on a named coarse side, by its grid
  // position, as (local element, side), sorted, once.
  ASSERT_EQ(s.side_sets().size(), sets.side_sets.size());
  MeshCursor cur;
  const RowReader R(m.tables(), cur);
  for (size_t k = 0; k < sets.side_sets.size(); ++k) {
    std::set<std::pair<Id, std::int8_t>> want;
    const auto& ss = sets.side_sets[k];
    for (size_t q = 0; q < ss.element.size(); ++q) {
      const Id h = ss.element[q];
      if (h < r.first_coarse || h >= r.end_coarse) continue;
      const auto n = R.element(h).n;
      const SidePlane plane = exodus_side_plane(m.mode(), ss.side[q]);
      for (size_t l = 0; l < t.elements.size(); ++l) {
        const FineElement fe = m.element(t.elements[l]);
        if (fe.coarse_element != h) continue;
        if (plane.axis < 0 || fe.ijk[plane.axis] == (plane.high ? n[plane.axis] - 1 : 0))
          want.emplace(static_cast<Id>(l), ss.side[q]);
      }
    }
    const SideMembers& got = s.side_sets()[k];
    EXPECT_EQ(got.id, ss.id);
    ASSERT_EQ(got.element.size(), want.size()) << "side set " << ss.id;
    size_t i = 0;
    for (const auto& [e, side] : want) {
      EXPECT_EQ(got.element[i], e);
      EXPECT_EQ(got.side[i], side);
      ++i;
    }
  }

  // Node sets: a node is in when every vertex of its owning entity is.
  ASSERT_EQ(s.node_set_ranges().size(), sets.node_sets.size());
  for (size_t k = 0; k < sets.node_sets.size(); ++k) {
    const std::set<Id> in(sets.node_sets[k].vertex.begin(), sets.node_sets[k].vertex.end());
    std::vector<Id> want, got;
    for (size_t l = 0; l < t.nodes.size(); ++l) {
      const auto vs = owner_vertices(m, t.nodes[l]);
      if (std::all_of(vs.begin(), vs.end(), [&](Id v) { return in.count(v) > 0; })) want.push_back(static_cast<Id>(l));
    }
    const auto& ranges = s.node_set_ranges()[k].local;
    for (size_t i = 0; i < ranges.size(); ++i) {
      ASSERT_LT(ranges[i][0], ranges[i][1]);
      if (i > 0) {
        ASSERT_LT(ranges[i - 1][1], ranges[i][0]) << "ranges are disjoint, sorted and merged";
      }
      for (Id l = ranges[i][0]; l < ranges[i][1]; ++l) got.push_back(l);
    }
    EXPECT_EQ(got, want) << "node set " << sets.node_sets[k].id;
  }

  // The writers see the same chunk through either source.
  ExportChunk held(m, r);
  held.prepare(sets);
  for (bool binary : {true, false}) {
    const std::string a = dir.path("stream.msh"), b = dir.path("held.msh");
    write_msh(s, a, binary);
    write_msh(held, b, binary);
    const std::string sa = slurp(a), sb = slurp(b);
    ASSERT_FALSE(sa.empty());
    EXPECT_TRUE(sa == sb) << (binary ? "binary" : "ASCII") << " MSH differs between the sources";
  }
}

}  // namespace

TEST(ChunkStream, PassesMatchBruteForceOnRandomMultiBlockVolumes) {
  std::mt19937_64 rng(20261125);
  test::TempDir dir;
  for (int trial = 0; trial < 4; ++trial) {
    test::BoxSpec spec;
    spec.a = 3 + trial % 2, spec.b = 2, spec.c = 2 + trial / 2;
    spec.blocks = 1 + trial % 3;
    CoarseMesh c = test::random_box(spec, rng);
    add_random_sets(c, rng);
    IntervalRequest req;
    req.global = 2 + trial % 2;
    const FineMesh m = FineMesh::dice(c, req);
    const MeshSets sets{m.coarse()->side_sets, m.coarse()->node_sets};
    SCOPED_TRACE("trial " + std::to_string(trial) + ", " + std::to_string(spec.blocks) + " blocks");
    for (Id K : {1, 3})
      for (const ChunkRange& r : plan_chunks(m, K)) check_chunk(m, sets, r, dir);
  }
}

TEST(ChunkStream, PassesMatchBruteForceOnSurfaces) {
  std::mt19937_64 rng(77);
  test::TempDir dir;
  CoarseMesh c = test::random_quad_sheet(4, 3, true, rng);
  // Two blocks, by quad index.
  c.blocks = {Block{1, "left"}, Block{4, "right"}};
  for (size_t e = 0; e < c.element_block.size(); ++e) c.element_block[e] = e % 3 == 0 ? 1 : 0;
  add_random_sets(c, rng);
  IntervalRequest req;
  req.global = 3;
  const FineMesh m = FineMesh::dice(c, req);
  ASSERT_EQ(m.mode(), Mode::Surface);
  const MeshSets sets{m.coarse()->side_sets, m.coarse()->node_sets};
  for (Id K : {1, 2, 4})
    for (const ChunkRange& r : plan_chunks(m, K)) check_chunk(m, sets, r, dir);
}

TEST(ChunkStream, RealMultiBlockMeshWithSets) {
  IntervalRequest req;
  req.global = 2;
  const FineMesh m = FineMesh::dice(read_coarse_mesh(test::data_path("vtkdata_mug.e")), req);  // 2 blocks, both set kinds
  ASSERT_EQ(m.info().blocks.size(), 2u);
  const MeshSets sets{m.coarse()->side_sets, m.coarse()->node_sets};
  test::TempDir dir;
  for (const ChunkRange& r : plan_chunks(m, 2)) check_chunk(m, sets, r, dir);
}

TEST(ChunkStream, ProgressCountsAnnouncedPassesAndCancelStops) {
  IntervalRequest req;
  req.global = 3;
  const FineMesh m = FineMesh::dice(read_coarse_mesh(test::data_path("cardinal_sphere.e")), req);
  const ChunkRange r = plan_chunks(m, 1)[0];
  std::vector<std::pair<Id, Id>> calls;
  const ChunkStream s(m, r, {}, [&](Id done, Id total) { calls.emplace_back(done, total); });
  s.expect_passes(2);
  s.nodes({true, -1}, [](const NodeSpan&) {});
  s.elements({}, [](const ElementSpan&) {});
  ASSERT_FALSE(calls.empty());
  const Id span = r.end_coarse - r.first_coarse;
  for (size_t i = 0; i < calls.size(); ++i) {
    EXPECT_EQ(calls[i].second, 2 * span);
    if (i > 0) {
      EXPECT_GT(calls[i].first, calls[i - 1].first);
    }
  }
  EXPECT_EQ(calls.back().first, 2 * span) << "every coarse element of both passes counted once";

  int polls = 0;
  const ChunkStream stop(m, r, {}, {}, [&] { return ++polls > 3; });
  try {
    stop.nodes({true, -1}, [](const NodeSpan&) {});
    FAIL() << "a cancelled pass must throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), ErrorKind::Cancelled);
  }
}
