#pragma once
// Numbering: fine node and element ids (DESIGN.md invariant 3). The only
// place that knows how ids are laid out; every id formula is below.
//
// Owner order (store format 6 on). Every coarse vertex, edge and face is
// owned by the lowest coarse element (store order) that contains it. Fine
// node ids are given coarse element by coarse element, in store order; for
// element h:
//   1. the vertices h owns, in vertex id order;
//   2. the interior nodes of the edges h owns, edge by edge in edge id
//      order, each in its canonical direction: t = 1 .. n-1;
//   3. the interior nodes of the faces h owns, face by face, each in its
//      canonical frame: (u-1) + (v-1)(nu-1);
//   4. h's interior: (i-1) + (j-1)(n1-1) + (k-1)(n1-1)(n2-1) (surface mode:
//      the quad's own face is its interior, numbered as in 3).
// Vertex, edge and face ids are themselves in owner order (to_owner_order),
// so each kind's node ids rise with its entity ids. Consequences: the nodes
// owned by a contiguous range of coarse elements are one contiguous id
// range [node_first(first), node_first(end)); an entity's ids are >= its
// user's node_first exactly when that user owns it; a sweep in id order
// visits coarse elements in store order.
// Fine element ids: coarse element order, then i fastest, then j, then k,
// in the element's own local frame.
//
// Numbering (the builder) computes every first id once, at dice time, with
// overflow checks; the results are columns of the mesh tables (rows.hpp).
// The lookups below read those rows: id -> entity is a binary search over
// element rows, O(log H) rows (one page with the store's page index);
// entity -> id is O(1).
#include <array>
#include <cstdint>
#include <vector>

#include "dicer/rows.hpp"
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

// The id formulas. `first` is the entity's first id (a row column).
namespace ids {
inline Id edge_node(Id first, Id t) { return first + (t - 1); }
inline Id face_node(Id first, Id nu, Id u, Id v) { return first + (u - 1) + (v - 1) * (nu - 1); }
inline Id cell_node(Id first, const std::array<Id, 3>& n, Id i, Id j, Id k) {
  return first + (i - 1) + (n[0] - 1) * ((j - 1) + (n[1] - 1) * (k - 1));
}
inline Id element(Id first, const std::array<Id, 3>& n, Id i, Id j, Id k) { return first + i + n[0] * (j + n[1] * k); }
// Inverses: local index l (id - first) -> position.
inline std::array<Id, 3> cell_local(Id l, const std::array<Id, 3>& n) {
  const Id a = n[0] - 1, b = n[1] - 1;
  return {l % a + 1, (l / a) % b + 1, l / (a * b) + 1};
}
inline std::array<Id, 2> face_local(Id l, Id nu) { return {l % (nu - 1) + 1, l / (nu - 1) + 1}; }
inline std::array<Id, 3> element_local(Id l, const std::array<Id, 3>& n) {
  return {l % n[0], (l / n[0]) % n[1], l / (n[0] * n[1])};
}
// Interior node counts.
inline Id edge_nodes(Id n) { return n - 1; }
inline Id face_nodes(Id nu, Id nv) { return (nu - 1) * (nv - 1); }
inline Id cell_nodes(const std::array<Id, 3>& n) { return (n[0] - 1) * (n[1] - 1) * (n[2] - 1); }
}  // namespace ids

class Numbering {
 public:
  Numbering() = default;
  // topo: in owner order (to_owner_order). edge_n: interval of every edge.
  // Throws Error{Overflow} (with the numbers) when a count does not fit in
  // 63 bits or a coarse element would have more than kMaxElementPoints grid
  // points, Error{BadInput} when two opposite edges of a face disagree.
  Numbering(const Topology& topo, std::vector<Id> edge_n);

  Id num_nodes() const { return num_nodes_; }
  Id num_elements() const { return element_first_.back(); }
  Id edge_n(Id e) const { return edge_n_[e]; }
  std::array<Id, 2> face_n(Id f) const { return face_n_[f]; }
  std::array<Id, 3> elem_n(Id h) const { return elem_n_[h]; }
  Id vertex_node(Id v) const { return vertex_node_[v]; }
  Id edge_node(Id e) const { return edge_node_[e]; }
  Id face_node(Id f) const { return face_node_[f]; }
  Id cell_node(Id h) const { return cell_node_[h]; }
  Id node_first(Id h) const { return node_first_[h]; }
  Id element_first(Id h) const { return element_first_[h]; }

 private:
  std::vector<Id> edge_n_;
  std::vector<std::array<Id, 2>> face_n_;
  std::vector<std::array<Id, 3>> elem_n_;
  std::vector<Id> vertex_node_, edge_node_, face_node_, cell_node_, node_first_, element_first_;
  Id num_nodes_ = 0;
};

// Where a node sits in the coarse element that owns it: the element and
// the local corner, edge or face (orientation.hpp numbering; -1: interior).
struct NodeOwner {
  Id element = -1;
  int slot = -1;
};

// Lookups over the tables; ids must be in range (callers check: FineMesh
// does). A row that contradicts the numbering is Error{Corrupt}.
// `owner_row`, when given, receives the owner element's validated row (the
// caller then need not decode it again: a random query's largest cost),
// `owner` the element and the slot.
NodeRef locate_node(const MeshTables& t, Id id, MeshCursor& cur, ElementRow* owner_row = nullptr,
                    NodeOwner* owner = nullptr);
// The entity of element hid (its decoded row h) holding node id, which h
// owns (owner_element(id) == hid): locate_node after the search and the
// decode. Corrupt when none of h's entities holds id.
NodeRef owned_node(const MeshTables& t, Id hid, const ElementRow& h, Id id, MeshCursor& cur,
                   NodeOwner* owner = nullptr);
Id node_id(const MeshTables& t, const NodeRef& r, MeshCursor& cur);
// Fine element id -> coarse element h and (i, j, k); `row` as above, or
// with `grid_only` its grid alone (RowReader::element_grid: entity
// columns -1), all a cell inside the element's interior needs.
Id locate_element(const MeshTables& t, Id id, std::array<Id, 3>& ijk, MeshCursor& cur, ElementRow* row = nullptr,
                  bool grid_only = false);
// The coarse element owning node `id` (the last with node_first <= id).
Id owner_element(const MeshTables& t, Id id, MeshCursor& cur);
// The guide (tables.hpp IdGuide) of the node_first (by_node) or
// element_first column of in-memory tables whose rows are final. O(H).
IdGuide build_id_guide(const MeshTables& t, bool by_node);
// The same over a store's page index (MeshTables::node_index or
// element_index, increasing, `total` ids in all): row[b] is the last page
// whose first id is <= b << shift. O(pages).
IdGuide build_page_guide(const std::vector<std::int64_t>& index, Id total);
// An empty LazyIdGuide (tables.hpp) for a store's `rows` element rows and
// `total` ids, of `pages` pages; searches fill it. O(rows + pages).
std::shared_ptr<const LazyIdGuide> make_lazy_guide(Id rows, Id total, Id pages);

// Canonical intervals (nu, nv) of local face k of an element row.
inline std::array<Id, 2> face_intervals(const ElementRow& h, int k, Mode mode) {
  const int a = mode == Mode::Volume ? kHexFaceAxes[k][0] : 0, b = mode == Mode::Volume ? kHexFaceAxes[k][1] : 1;
  return code_swaps_axes(h.code(k)) ? std::array<Id, 2>{h.n[b], h.n[a]} : std::array<Id, 2>{h.n[a], h.n[b]};
}

}  // namespace dicer
