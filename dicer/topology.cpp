// Unique edges and faces by sorting keys grouped by lowest vertex: no hashing, and ids
// that depend only on vertex ids.
#include "dicer/topology.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <string>

#include "dicer/error.hpp"

namespace dicer {

Id find_edge(const Topology& t, Id a, Id b) {
  if (!t.edges_sorted) throw Error(ErrorKind::Usage, "find_edge: the topology is in owner order, not sorted by vertex ids");
  if (a > b) std::swap(a, b);
  Id lo = 0, hi = t.num_edges();
  while (lo < hi) {
    const Id mid = lo + (hi - lo) / 2;
    const Id ma = t.edge_v[2 * mid], mb = t.edge_v[2 * mid + 1];
    if (ma < a || (ma == a && mb < b)) lo = mid + 1;
    else hi = mid;
  }
  return (lo < t.num_edges() && t.edge_v[2 * lo] == a && t.edge_v[2 * lo + 1] == b) ? lo : -1;
}

namespace {

// Keys of one group (the entities whose lowest vertex is the group's):
// the rest of the key, then the slot (element * per + local index).
struct EdgeKey {
  Id hi, slot;
  bool operator<(const EdgeKey& o) const { return hi != o.hi ? hi < o.hi : slot < o.slot; }
};
struct FaceKey {
  std::array<Id, 3> rest;
  Id slot;
  bool operator<(const FaceKey& o) const { return rest != o.rest ? rest < o.rest : slot < o.slot; }
};

// Puts the keys of slots [0, n) in increasing (lowest vertex, key) order:
// a counting sort by the lowest vertex (O(n + V)), then each vertex's
// group sorted on its own (a vertex's edges or faces: a few dozen keys).
// The same order as one comparison sort of all keys, at a fraction of its
// cost (std::sort of 24M edge keys was a fifth of dice on 1e6 hexes).
// lowest(slot): its lowest vertex; key_of(slot) -> (lowest vertex, key).
// group[v] .. group[v+1] is vertex v's range of `out` afterwards.
template <class Key, class Lowest, class KeyOf>
void group_by_lowest(Id num_vertices, Id n, std::vector<Key>& out, std::vector<Id>& group, Lowest lowest,
                     KeyOf key_of) {
  group.assign(static_cast<size_t>(num_vertices) + 1, 0);
  for (Id s = 0; s < n; ++s) ++group[lowest(s) + 1];
  for (Id v = 0; v < num_vertices; ++v) group[v + 1] += group[v];
  std::vector<Id> fill(group.begin(), group.end() - 1);
  for (Id s = 0; s < n; ++s) {
    const auto [v, key] = key_of(s);
    out[fill[v]++] = key;
  }
  for (Id v = 0; v < num_vertices; ++v) {
    Key* b = out.data() + group[v];
    Key* e = out.data() + group[v + 1];
    if (e - b <= 32) {  // insertion sort: slots arrive in increasing order, so most groups are nearly sorted
      for (Key* i = b + 1; i < e; ++i)
        for (Key* j = i; j > b && *j < *(j - 1); --j) std::swap(*j, *(j - 1));
    } else {
      std::sort(b, e);
    }
  }
}

}  // namespace

Topology build_topology(const CoarseMesh& m) {
  Topology t;
  t.mode = m.mode;
  t.num_vertices = m.num_vertices();
  const Id ne = m.num_elements();
  const int nc = m.corners_per_element();
  const int epe = t.edges_per_element();
  const bool vol = m.mode == Mode::Volume;
  auto local_edge = [&](int k, int end) { return vol ? kHexEdge[k][end] : kQuadEdge[k][end]; };

  // Edges: (lo, hi, slot) keys in increasing order, grouped by lo.
  const Id nslots = ne * epe;
  std::vector<Id> group;
  std::vector<EdgeKey> ekeys(static_cast<size_t>(nslots));
  auto edge_ends = [&](Id slot) {
    const Id* c = &m.conn[static_cast<size_t>(slot / epe) * nc];
    const int k = static_cast<int>(slot % epe);
    return std::pair<Id, Id>{c[local_edge(k, 0)], c[local_edge(k, 1)]};
  };
  group_by_lowest(
      t.num_vertices, nslots, ekeys, group,
      [&](Id slot) {
        const auto [a, b] = edge_ends(slot);
        return std::min(a, b);
      },
      [&](Id slot) {
        const auto [a, b] = edge_ends(slot);
        return std::pair<Id, EdgeKey>{std::min(a, b), EdgeKey{std::max(a, b), slot}};
      });
  t.elem_edge.resize(static_cast<size_t>(nslots));
  t.elem_edge_rev.resize(static_cast<size_t>(nslots));
  {
    Id id = -1;
    for (Id a = 0; a < t.num_vertices; ++a) {
      for (Id i = group[a]; i < group[a + 1]; ++i) {
        const Id b = ekeys[i].hi, slot = ekeys[i].slot;
        if (i == group[a] || ekeys[i - 1].hi != b) {
          ++id;
          t.edge_v.push_back(a);
          t.edge_v.push_back(b);
        } else if (!vol && i - 2 >= group[a] && ekeys[i - 2].hi == b) {
          // A surface edge has one quad (boundary) or two; three or more is a
          // T-junction of shells, which no single sheet can dice.
          const Id first = i - 2;
          std::string quads;
          for (Id j = first; j < group[a + 1] && ekeys[j].hi == b; ++j)
            quads += (j == first ? "" : ", ") + std::to_string(m.element_file_id[ekeys[j].slot / epe]);
          throw Error(ErrorKind::BadInput, m.source + ": non-manifold edge (nodes " +
                                               std::to_string(m.vertex_file_id[a]) + " " +
                                               std::to_string(m.vertex_file_id[b]) +
                                               ") is shared by more than two quadrilaterals: elements " + quads);
        }
        t.elem_edge[slot] = id;
        const Id e = slot / epe;
        const int k = static_cast<int>(slot % epe);
        t.elem_edge_rev[slot] = m.conn[static_cast<size_t>(e) * nc + local_edge(k, 0)] > a ? 1 : 0;
      }
    }
    ekeys = {};
  }

  // Faces: canonical (v0, v1, v2, v3, slot) keys in increasing order,
  // grouped by v0 (the lowest corner).
  if (vol) {
    std::vector<FaceCode> codes(static_cast<size_t>(ne) * 6);
    std::vector<FaceKey> fkeys(static_cast<size_t>(ne) * 6);
    auto corners = [&](Id slot) {
      const Id* c = &m.conn[static_cast<size_t>(slot / 6) * 8];
      const int k = static_cast<int>(slot % 6);
      return std::array<Id, 4>{c[kHexFace[k][0]], c[kHexFace[k][1]], c[kHexFace[k][2]], c[kHexFace[k][3]]};
    };
    group_by_lowest(
        t.num_vertices, ne * 6, fkeys, group,
        [&](Id slot) {
          const auto q = corners(slot);
          return std::min(std::min(q[0], q[1]), std::min(q[2], q[3]));
        },
        [&](Id slot) {
          const CanonicalQuad q = canonical_quad(corners(slot));
          codes[slot] = q.code;
          return std::pair<Id, FaceKey>{q.v[0], FaceKey{{q.v[1], q.v[2], q.v[3]}, slot}};
        });
    t.elem_face.resize(fkeys.size());
    t.elem_face_code = std::move(codes);
    Id id = -1;
    for (Id v0 = 0; v0 < t.num_vertices; ++v0) {
      for (Id i = group[v0]; i < group[v0 + 1]; ++i) {
        const Id slot = fkeys[i].slot;
        const auto& v = fkeys[i].rest;
        if (i == group[v0] || fkeys[i - 1].rest != v) {
          ++id;
          t.face_v.insert(t.face_v.end(), {v0, v[0], v[1], v[2]});
          t.face_elem.push_back(slot / 6);
          t.face_elem.push_back(-1);
        } else if (t.face_elem[2 * id + 1] < 0) {
          t.face_elem[2 * id + 1] = slot / 6;
        } else {
          auto fid = [&](Id x) { return std::to_string(m.vertex_file_id[x]); };
          auto eid = [&](Id x) { return std::to_string(m.element_file_id[x]); };
          throw Error(ErrorKind::BadInput,
                      m.source + ": non-manifold face (nodes " + fid(v0) + " " + fid(v[0]) + " " + fid(v[1]) + " " +
                          fid(v[2]) + ") is shared by more than two hexes: elements " + eid(t.face_elem[2 * id]) +
                          ", " + eid(t.face_elem[2 * id + 1]) + ", " + eid(slot / 6));
        }
        t.elem_face[slot] = id;
      }
    }
  } else {
    t.elem_face.resize(static_cast<size_t>(ne));
    t.elem_face_code.resize(static_cast<size_t>(ne));
    for (Id e = 0; e < ne; ++e) {
      const Id* c = &m.conn[static_cast<size_t>(e) * 4];
      const CanonicalQuad q = canonical_quad({c[0], c[1], c[2], c[3]});
      for (Id v : q.v) t.face_v.push_back(v);
      t.elem_face[e] = e;
      t.elem_face_code[e] = q.code;
      t.face_elem.push_back(e);
      t.face_elem.push_back(-1);
    }
  }

  // Face -> edges in the canonical frame, from the edges of an element that
  // has the face (its local edges are already numbered): O(1) per face where
  // a search of the sorted edges cost O(log n) (a sixth of dice's time).
  const Id nf = t.num_faces();
  t.face_edge.assign(static_cast<size_t>(nf) * 4, -1);
  const size_t fpe = vol ? 6 : 1;
  for (size_t slot = 0; slot < t.elem_face.size(); ++slot) {
    const Id f = t.elem_face[slot];
    if (t.face_edge[4 * f] >= 0) continue;
    const Id e = static_cast<Id>(slot / fpe);
    const Id* c = &m.conn[static_cast<size_t>(e) * nc];
    for (int q = 0; q < 4; ++q) {
      const Id a = t.face_v[4 * f + kQuadEdge[q][0]], b = t.face_v[4 * f + kQuadEdge[q][1]];
      Id edge = -1;
      for (int k = 0; k < epe && edge < 0; ++k) {
        const Id x = c[local_edge(k, 0)], y = c[local_edge(k, 1)];
        if ((x == a && y == b) || (x == b && y == a)) edge = t.elem_edge[static_cast<size_t>(e) * epe + k];
      }
      t.face_edge[4 * f + q] = edge >= 0 ? edge : find_edge(t, a, b);
    }
  }
  return t;
}

namespace {

// What a kept topology was built from: mode, vertex count, connectivity.
std::uint64_t topology_key(const CoarseMesh& m) {
  std::uint64_t h = 0x9e3779b97f4a7c15ull ^ static_cast<std::uint64_t>(m.mode) ^
                    (static_cast<std::uint64_t>(m.num_vertices()) << 8);
  for (const Id c : m.conn) {
    h ^= static_cast<std::uint64_t>(c);
    h *= 0xff51afd7ed558ccdull;
    h ^= h >> 29;
  }
  return h | 1;  // never 0: 0 means "none kept"
}

// Ranks entities by (lowest element containing them, first local index in
// it): rank[old id] = new id. slots[h * per + k] is element h's local entity k.
std::vector<Id> owner_rank(const std::vector<Id>& slots, int per, Id count, std::vector<Id>& owner) {
  std::vector<Id> rank(static_cast<size_t>(count), -1);
  owner.assign(static_cast<size_t>(count), -1);
  Id next = 0;
  for (size_t s = 0; s < slots.size(); ++s) {
    const Id x = slots[s];
    if (rank[x] >= 0) continue;
    owner[next] = static_cast<Id>(s) / per;
    rank[x] = next++;
  }
  return rank;
}

}  // namespace

std::shared_ptr<const Topology> topology_of(const CoarseMesh& mesh) {
  if (mesh.topology && mesh.topology_key == topology_key(mesh)) return mesh.topology;
  return std::make_shared<const Topology>(build_topology(mesh));
}

void keep_topology(CoarseMesh& mesh, std::shared_ptr<const Topology> t) {
  mesh.topology_key = t ? topology_key(mesh) : 0;
  mesh.topology = std::move(t);
}

void to_owner_order(Topology& t, const std::vector<Id>& conn) {
  const int cpe = t.mode == Mode::Volume ? 8 : 4, epe = t.edges_per_element(), fpe = t.faces_per_element();
  // Vertices must already be in first-use order (sfc_order makes them so):
  // the fine node ids of vertices then rise with their ids.
  {
    std::vector<Id> rank = owner_rank(conn, cpe, t.num_vertices, t.vertex_owner_elem);
    for (Id v = 0; v < t.num_vertices; ++v) DICER_ASSERT(rank[v] == v, "to_owner_order: vertices in order of first use");
  }
  const std::vector<Id> erank = owner_rank(t.elem_edge, epe, t.num_edges(), t.edge_owner_elem);
  const std::vector<Id> frank = owner_rank(t.elem_face, fpe, t.num_faces(), t.face_owner_elem);
  auto permute = [](std::vector<Id>& v, int width, const std::vector<Id>& rank) {
    std::vector<Id> out(v.size());
    for (size_t i = 0; i < rank.size(); ++i)
      std::copy_n(v.begin() + static_cast<std::ptrdiff_t>(i) * width, width,
                  out.begin() + static_cast<std::ptrdiff_t>(rank[i]) * width);
    v.swap(out);
  };
  permute(t.edge_v, 2, erank);
  permute(t.face_v, 4, frank);
  permute(t.face_edge, 4, frank);
  permute(t.face_elem, 2, frank);
  for (Id& e : t.face_edge) e = erank[e];
  for (Id& e : t.elem_edge) e = erank[e];
  for (Id& f : t.elem_face) f = frank[f];
  t.edges_sorted = false;
}

}  // namespace dicer
