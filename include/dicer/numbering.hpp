#pragma once
// Numbering: fine node and element ids (DESIGN.md invariant 3).
//
// Fine node ids: coarse vertices first (id = vertex index), then the interior
// nodes of each coarse edge (edge order, t = 1..n-1), then of each face (face
// order, u fastest: (u-1) + (v-1)(nu-1)), then of each hex interior (hex
// order, (i-1) + (j-1)(n1-1) + (k-1)(n1-1)(n2-1)). Surface mode: vertices,
// edges, quads. Fine element ids: coarse element order, then i fastest, then
// j, then k, in the element's own local frame.
// Cost: O(coarse) memory (one prefix array per entity kind); id -> entity is
// a binary search, O(log n); entity -> id is O(1).
#include <array>
#include <cstdint>
#include <vector>

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
  const std::vector<Id>& edge_intervals() const { return edge_n_; }
  std::array<Id, 2> face_n(Id f) const { return face_n_[f]; }
  // Intervals of a coarse element along its local i, j (, k); 1 for k in surface mode.
  std::array<Id, 3> elem_n(Id h) const { return elem_n_[h]; }
  Id elem_first_element(Id h) const { return elem_offset_[h]; }
  Id elem_num_elements(Id h) const { return elem_offset_[h + 1] - elem_offset_[h]; }

  Id node_id(const NodeRef& r) const;
  NodeRef locate_node(Id id) const;  // precondition 0 <= id < num_nodes()
  // Fine element id <-> (coarse element, i, j, k).
  Id element_id(Id h, Id i, Id j, Id k) const;
  Id locate_element(Id id, std::array<Id, 3>& ijk) const;

  // First node id of each kind: [vertices, edges, faces, cells, end).
  std::array<Id, 5> kind_offsets() const { return {0, base_[1], base_[2], base_[3], num_nodes_}; }
  Id edge_node_offset(Id e) const { return base_[1] + edge_off_[e]; }
  Id face_node_offset(Id f) const { return base_[2] + face_off_[f]; }
  Id cell_node_offset(Id h) const { return base_[3] + cell_off_[h]; }

 private:
  Mode mode_ = Mode::Volume;
  std::vector<Id> edge_n_;
  std::vector<std::array<Id, 2>> face_n_;
  std::vector<std::array<Id, 3>> elem_n_;
  std::vector<Id> edge_off_, face_off_, cell_off_, elem_offset_;  // prefix sums, size n+1
  std::array<Id, 4> base_{};
  Id num_nodes_ = 0;
};

}  // namespace dicer
