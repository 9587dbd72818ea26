#pragma once
// Numbering: fine node and element ids (DESIGN.md invariant 3). The only
// place that knows how ids are laid out.
//
// Fine node ids: coarse vertices first (id = vertex index), then the interior
// nodes of each coarse edge (edge order, t = 1..n-1), then of each face (face
// order, u fastest: (u-1) + (v-1)(nu-1)), then of each hex interior (hex
// order, (i-1) + (j-1)(n1-1) + (k-1)(n1-1)(n2-1)). Surface mode: vertices,
// edges, quads. Fine element ids: coarse element order, then i fastest, then
// j, then k, in the element's own local frame.
//
// Numbering (the builder) computes every entity's first id once, at dice
// time, with overflow checks; the results are columns of the mesh tables.
// The lookups below work on those tables: id -> entity is a binary search,
// O(log n) rows touched; entity -> id is O(1).
#include <array>
#include <cstdint>
#include <vector>

#include "dicer/tables.hpp"
#include "dicer/topology.hpp"

namespace dicer {

enum class EntityKind : std::uint8_t { Vertex = 0, Edge = 1, Face = 2, Cell = 3 };

// A fine node named by the coarse entity that owns it and its index in that
// entity's canonical frame: edge (t), face (u, v), cell (i, j, k).
struct NodeRef {
  EntityKind kind = EntityKind::Vertex;
  Id entity = 0;
  std::array<Id, 3> local{0, 0, 0};
  friend bool operator==(const NodeRef&, const NodeRef&) = default;
};

class Numbering {
 public:
  Numbering() = default;
  // edge_n: interval of every edge. Throws Error{Overflow} (with the
  // numbers) when a count does not fit in 63 bits, Error{BadInput} when two
  // opposite edges of a face disagree.
  Numbering(const Topology& topo, std::vector<Id> edge_n);

  Id num_nodes() const { return num_nodes_; }
  Id num_elements() const { return elem_offset_.back(); }
  Id edge_n(Id e) const { return edge_n_[e]; }
  std::array<Id, 2> face_n(Id f) const { return face_n_[f]; }
  std::array<Id, 3> elem_n(Id h) const { return elem_n_[h]; }
  // First node id of each kind: vertices, edges, faces, cells.
  std::array<Id, 4> kind_base() const { return base_; }
  Id edge_node_offset(Id e) const { return base_[1] + edge_off_[e]; }
  Id face_node_offset(Id f) const { return base_[2] + face_off_[f]; }
  Id cell_node_offset(Id h) const { return base_[3] + cell_off_[h]; }
  Id elem_first_element(Id h) const { return elem_offset_[h]; }

 private:
  std::vector<Id> edge_n_;
  std::vector<std::array<Id, 2>> face_n_;
  std::vector<std::array<Id, 3>> elem_n_;
  std::vector<Id> edge_off_, face_off_, cell_off_, elem_offset_;  // prefix sums, size n+1
  std::array<Id, 4> base_{};
  Id num_nodes_ = 0;
};

// Lookups over the tables. `base` is MeshInfo::kind_base, `nodes` the fine
// node count; ids must be in range (callers check).
NodeRef locate_node(const MeshTables& t, const std::array<Id, 4>& base, Id nodes, Id id, MeshCursor& cur);
Id node_id(const MeshTables& t, const std::array<Id, 4>& base, const NodeRef& r, MeshCursor& cur);
// Fine element id -> coarse element h and (i, j, k).
Id locate_element(const MeshTables& t, Id id, std::array<Id, 3>& ijk, MeshCursor& cur);

}  // namespace dicer
