#pragma once
// Topology: the unique coarse edges and faces, in canonical orientation, and
// each element's map to them with orientation codes (DESIGN.md invariant 1).
//
// Ids, as build_topology makes them: edges in increasing (lo, hi) vertex id
// order, faces in increasing canonical (v0, v1, v2, v3) order, so both
// depend only on the vertex numbering (sheet ids rest on this). Volume
// mode: every unique quad face of the hexes. Surface mode: face f is
// element f itself. to_owner_order() renumbers them for the fine mesh.
// Layout (structure of arrays, fixed stride per element):
//   edge_v[2e+{0,1}]        lo, hi vertex of edge e
//   face_v[4f+m]            canonical corner v_m of face f
//   face_edge[4f+k]         edges of face f: k=0 v0v1 (u at v=0), 1 v3v2 (u at
//                           v=nv), 2 v0v3 (v at u=0), 3 v1v2 (v at u=nu)
//   elem_edge[12h+k]        edge of local hex edge k (kHexEdge); quads: 4
//   elem_edge_rev[12h+k]    1 when local edge k runs hi -> lo
//   elem_face[6h+k], elem_face_code[6h+k]  local face k (kHexFace), its code
//                           (surface: one face per element, the element)
//   face_elem[2f+{0,1}]     the (one or two) hexes on face f, -1 if none
//   vertex_owner_elem[v], edge_owner_elem[e], face_owner_elem[f]
//                           the lowest element containing the entity (its
//                           owner in the numbering); filled by to_owner_order
// Cost: O(n + V) time to build (keys grouped by their lowest vertex, each
// group sorted on its own), O(n) memory.
#include <cstdint>
#include <memory>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/orientation.hpp"

namespace dicer {

struct Topology {
  Mode mode = Mode::Volume;
  Id num_vertices = 0;
  std::vector<Id> edge_v;
  std::vector<Id> face_v;
  std::vector<Id> face_edge;
  std::vector<Id> elem_edge;
  std::vector<std::uint8_t> elem_edge_rev;
  std::vector<Id> elem_face;
  std::vector<FaceCode> elem_face_code;
  std::vector<Id> face_elem;
  std::vector<Id> vertex_owner_elem, edge_owner_elem, face_owner_elem;
  bool edges_sorted = true;  // edge ids in (lo, hi) order: find_edge works

  int edges_per_element() const { return mode == Mode::Volume ? 12 : 4; }
  int faces_per_element() const { return mode == Mode::Volume ? 6 : 1; }
  Id num_edges() const { return static_cast<Id>(edge_v.size() / 2); }
  Id num_faces() const { return static_cast<Id>(face_v.size() / 4); }
  Id num_elements() const { return static_cast<Id>(elem_edge.size()) / edges_per_element(); }
};

// Throws Error{BadInput} for a face shared by more than two hexes
// (non-manifold), naming the face's nodes and the hexes.
Topology build_topology(const CoarseMesh& mesh);

// The mesh's topology as build_topology makes it: the one
// validate_coarse_mesh kept (CoarseMesh::topology) when the mesh's
// connectivity, vertex count and mode are still those it was built from
// (checked by a hash of them, O(n)), else a new one. keep_topology stores
// one in the mesh for later calls.
std::shared_ptr<const Topology> topology_of(const CoarseMesh& mesh);
void keep_topology(CoarseMesh& mesh, std::shared_ptr<const Topology> t);

// Edge id of (a, b) in either order, or -1: binary search, O(log E).
// Only on a topology as build_topology made it (Error{Usage} after
// to_owner_order).
Id find_edge(const Topology& t, Id a, Id b);

// Owner order (DESIGN.md invariant 3): renumbers edges and faces by (lowest
// element containing them, first local index there), the order in which
// the numbering gives them fine node ids, and records each entity's owner
// element. Vertices must already be in first-use order of `conn` (the
// mesh's connectivity; sfc_order guarantees it): Error{Usage} otherwise.
// O(n) time and memory.
void to_owner_order(Topology& t, const std::vector<Id>& conn);

}  // namespace dicer
