// build_topology's ids against a brute-force reading of topology.hpp's
// definition: edges in increasing (lo, hi), faces in increasing canonical
// (v0, v1, v2, v3), each face's elements lowest first, every element's map
// and orientation flags consistent with its own corners. Over random boxes
// (renumbered, rotated) and pinwheels, whose axis vertices belong to many
// hexes (large groups of keys per vertex: build_topology sorts those
// differently from small ones).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>

#include "dicer/coarse_mesh.hpp"
#include "dicer/orientation.hpp"
#include "dicer/topology.hpp"
#include "random_mesh.hpp"

using namespace dicer;

namespace {

// n hexes around the z axis, one layer per level: hex i of layer l has the
// axis, ring point i, an outer point between i and i + 1, and ring point
// i + 1, at z = l and l + 1. The axis vertices belong to n (or 2n) hexes.
CoarseMesh pinwheel(int n, int layers, std::mt19937_64& rng) {
  CoarseMesh m;
  m.source = "pinwheel";
  m.mode = Mode::Volume;
  const int per = 1 + 2 * n;  // axis, n ring points, n outer points
  for (int l = 0; l <= layers; ++l) {
    m.x.push_back(0), m.y.push_back(0), m.z.push_back(l);
    for (int i = 0; i < n; ++i) {
      const double a = 2 * M_PI * i / n, b = 2 * M_PI * (i + 0.5) / n;
      m.x.push_back(std::cos(a)), m.y.push_back(std::sin(a)), m.z.push_back(l);
      m.x.push_back(1.2 * std::cos(b)), m.y.push_back(1.2 * std::sin(b)), m.z.push_back(l);
    }
  }
  auto ring = [&](int l, int i) { return Id{l} * per + 1 + 2 * (i % n); };
  for (int l = 0; l < layers; ++l)
    for (int i = 0; i < n; ++i) {
      const Id bottom[4] = {Id{l} * per, ring(l, i), ring(l, i) + 1, ring(l, i + 1)};
      for (Id v : bottom) m.conn.push_back(v);
      for (Id v : bottom) m.conn.push_back(v + per);
    }
  const Id nv = m.num_vertices(), ne = m.num_elements();
  // Random vertex ids, except that the axis keeps the lowest now and then
  // (then every key of its edges and faces falls into its group).
  std::vector<Id> perm(static_cast<size_t>(nv));
  std::iota(perm.begin(), perm.end(), Id{0});
  if (rng() % 2) std::shuffle(perm.begin(), perm.end(), rng);
  CoarseMesh r = m;
  for (Id v = 0; v < nv; ++v) r.x[perm[v]] = m.x[v], r.y[perm[v]] = m.y[v], r.z[perm[v]] = m.z[v];
  for (auto& c : r.conn) c = perm[c];
  r.vertex_file_id.resize(static_cast<size_t>(nv));
  std::iota(r.vertex_file_id.begin(), r.vertex_file_id.end(), Id{1});
  r.element_file_id.resize(static_cast<size_t>(ne));
  std::iota(r.element_file_id.begin(), r.element_file_id.end(), Id{1});
  r.element_block.assign(static_cast<size_t>(ne), 0);
  r.blocks = {Block{1, "pinwheel"}};
  validate_coarse_mesh(r);
  return r;
}

void expect_topology_as_defined(const CoarseMesh& m) {
  const Topology t = build_topology(m);
  const Id ne = m.num_elements();
  // Every edge and face of every element, brute force.
  std::map<std::pair<Id, Id>, int> edges;
  std::map<std::array<Id, 4>, std::vector<Id>> faces;  // canonical corners -> elements, in order
  for (Id e = 0; e < ne; ++e) {
    const Id* c = &m.conn[static_cast<size_t>(e) * 8];
    for (int k = 0; k < 12; ++k) {
      const Id a = c[kHexEdge[k][0]], b = c[kHexEdge[k][1]];
      edges[{std::min(a, b), std::max(a, b)}] = 1;
    }
    for (int k = 0; k < 6; ++k) {
      const CanonicalQuad q = canonical_quad({c[kHexFace[k][0]], c[kHexFace[k][1]], c[kHexFace[k][2]], c[kHexFace[k][3]]});
      auto& users = faces[q.v];
      if (users.empty() || users.back() != e) users.push_back(e);
    }
  }
  // Ids: the sorted order of the distinct keys.
  ASSERT_EQ(t.num_edges(), static_cast<Id>(edges.size()));
  Id id = 0;
  for (const auto& [ab, unused] : edges) {
    EXPECT_EQ(t.edge_v[2 * id], ab.first) << "edge " << id;
    EXPECT_EQ(t.edge_v[2 * id + 1], ab.second) << "edge " << id;
    ++id;
  }
  ASSERT_EQ(t.num_faces(), static_cast<Id>(faces.size()));
  id = 0;
  for (const auto& [v, users] : faces) {
    for (int q = 0; q < 4; ++q) EXPECT_EQ(t.face_v[4 * id + q], v[q]) << "face " << id;
    ASSERT_LE(users.size(), 2u);
    EXPECT_EQ(t.face_elem[2 * id], users[0]) << "face " << id;
    EXPECT_EQ(t.face_elem[2 * id + 1], users.size() == 2 ? users[1] : -1) << "face " << id;
    for (int q = 0; q < 4; ++q) {
      const Id a = v[kQuadEdge[q][0]], b = v[kQuadEdge[q][1]];
      const Id edge = t.face_edge[4 * id + q];
      EXPECT_EQ(t.edge_v[2 * edge], std::min(a, b)) << "face " << id << " side " << q;
      EXPECT_EQ(t.edge_v[2 * edge + 1], std::max(a, b)) << "face " << id << " side " << q;
    }
    ++id;
  }
  // Each element's maps and flags, from its own corners.
  for (Id e = 0; e < ne; ++e) {
    const Id* c = &m.conn[static_cast<size_t>(e) * 8];
    for (int k = 0; k < 12; ++k) {
      const Id a = c[kHexEdge[k][0]], b = c[kHexEdge[k][1]], edge = t.elem_edge[e * 12 + k];
      EXPECT_EQ(t.edge_v[2 * edge], std::min(a, b));
      EXPECT_EQ(t.edge_v[2 * edge + 1], std::max(a, b));
      EXPECT_EQ(t.elem_edge_rev[e * 12 + k], a > b ? 1 : 0);
    }
    for (int k = 0; k < 6; ++k) {
      const CanonicalQuad q = canonical_quad({c[kHexFace[k][0]], c[kHexFace[k][1]], c[kHexFace[k][2]], c[kHexFace[k][3]]});
      const Id f = t.elem_face[e * 6 + k];
      for (int i = 0; i < 4; ++i) EXPECT_EQ(t.face_v[4 * f + i], q.v[i]);
      EXPECT_EQ(t.elem_face_code[e * 6 + k], q.code);
    }
  }
}

}  // namespace

TEST(TopologyOrder, RandomBoxesMatchTheDefinition) {
  std::mt19937_64 rng(2026);
  for (int trial = 0; trial < 8; ++trial) {
    test::BoxSpec spec;
    spec.a = 1 + trial % 4, spec.b = 2 + trial % 3, spec.c = 1 + (trial * 3) % 4;
    SCOPED_TRACE("trial " + std::to_string(trial));
    expect_topology_as_defined(test::random_box(spec, rng));
  }
}

TEST(TopologyOrder, ManyHexesAroundOneVertexMatchTheDefinition) {
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 6; ++trial) {
    const int n = 8 + 9 * trial, layers = 1 + trial % 3;  // up to 53 hexes on one axis edge
    SCOPED_TRACE("n " + std::to_string(n));
    expect_topology_as_defined(pinwheel(n, layers, rng));
  }
}

TEST(TopologyOrder, KeptTopologyIsUsedOnlyForTheConnectivityItWasBuiltFrom) {
  std::mt19937_64 rng(5);
  test::BoxSpec spec;
  spec.a = 3;
  CoarseMesh m = test::random_box(spec, rng);
  validate_coarse_mesh(m);
  ASSERT_TRUE(m.topology);
  EXPECT_EQ(topology_of(m).get(), m.topology.get());
  // Any change of the connectivity makes it stale: a fresh one is built.
  std::swap(m.conn[0], m.conn[1]);
  const auto fresh = topology_of(m);
  EXPECT_NE(fresh.get(), m.topology.get());
  EXPECT_EQ(fresh->elem_edge, build_topology(m).elem_edge);
}
