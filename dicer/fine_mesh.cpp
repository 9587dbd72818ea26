// The implicit fine mesh: random access by id. Evaluation lives in
// evaluate.cpp, block filling in fill.cpp, iteration in cursors.cpp,
// dicing in compile.cpp.
#include "dicer/fine_mesh.hpp"

#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "evaluate.hpp"

namespace dicer {

FineMesh::FineMesh(MeshInfo info, MeshTables tables, std::shared_ptr<const CoarseMesh> coarse)
    : info_(std::move(info)), tables_(std::move(tables)), coarse_(std::move(coarse)) {}

Vec3 FineMesh::node(Id id) const {
  MeshCursor cur;
  return node(id, cur);
}

Vec3 FineMesh::node(Id id, MeshCursor& cur) const {
  if (id < 0 || id >= num_nodes())
    throw Error(ErrorKind::Usage, "node id " + std::to_string(id) + " is out of range (the mesh has " +
                                      std::to_string(num_nodes()) + " nodes)");
  detail::Uninitialised<ElementRow> storage;  // locate_node writes every field
  ElementRow& row = *storage;
  NodeOwner owner;
  const NodeRef ref = dicer::locate_node(tables_, id, cur, &row, &owner);
  const detail::Evaluator E(tables_, cur);
  // The owner's row is decoded already: cell interiors, and the boundary
  // of a straight owner, come from it and its corners alone.
  if (ref.kind == EntityKind::Cell) return E.cell_point(row, ref.entity, ref.local[0], ref.local[1], ref.local[2]);
  if (!row.curved()) return E.straight_owned_point(row, owner.element, owner.slot, ref);
  return E.node(ref);
}

Vec3 FineMesh::node(const NodeRef& ref, MeshCursor& cur) const { return detail::Evaluator(tables_, cur).node(ref); }

std::array<Id, 2> FineMesh::owned_nodes(Id first, Id end, MeshCursor& cur) const {
  if (first < 0 || end > num_coarse_elements() || first > end)
    throw Error(ErrorKind::Usage, "owned_nodes: coarse elements " + std::to_string(first) + ".." + std::to_string(end) +
                                      " outside the mesh");
  const RowReader R(tables_, cur);
  auto at = [&](Id h) { return h < num_coarse_elements() ? R.element(h).node_first : num_nodes(); };
  return {at(first), first == end ? at(first) : at(end)};
}

NodeRef FineMesh::locate_node(Id id, MeshCursor& cur) const { return dicer::locate_node(tables_, id, cur); }
Id FineMesh::node_id(const NodeRef& ref, MeshCursor& cur) const { return dicer::node_id(tables_, ref, cur); }
Id FineMesh::locate_element(Id id, std::array<Id, 3>& ijk, MeshCursor& cur) const {
  return dicer::locate_element(tables_, id, ijk, cur);
}

NodeRef FineMesh::grid_node(Id h, Id i, Id j, Id k, MeshCursor& cur) const {
  const detail::Evaluator E(tables_, cur);
  return E.grid_node(E.R.element(h), h, i, j, k);
}

FineElement FineMesh::element(Id id) const {
  MeshCursor cur;
  return element(id, cur);
}

FineElement FineMesh::element(Id id, MeshCursor& cur) const {
  if (id < 0 || id >= num_elements())
    throw Error(ErrorKind::Usage, "element id " + std::to_string(id) + " is out of range (the mesh has " +
                                      std::to_string(num_elements()) + " elements)");
  FineElement el;
  el.id = id;
  detail::Uninitialised<ElementRow> storage;  // locate_element writes every field
  ElementRow& h = *storage;
  el.coarse_element = dicer::locate_element(tables_, id, el.ijk, cur, &h);
  const detail::Evaluator E(tables_, cur);
  el.block = h.block;
  const auto [i, j, k] = el.ijk;
  const bool vol = mode() == Mode::Volume;
  el.num_nodes = vol ? 8 : 4;
  if (vol && i > 0 && j > 0 && k > 0 && i + 1 < h.n[0] && j + 1 < h.n[1] && k + 1 < h.n[2]) {
    // Every corner inside the cell (most elements at large intervals): the
    // cell's own ids, with no entity lookup per corner.
    for (int q = 0; q < 8; ++q)
      el.nodes[q] = ids::cell_node(h.cell_node, h.n, i + kHexCorner[q][0], j + kHexCorner[q][1], k + kHexCorner[q][2]);
    return el;
  }
  for (int q = 0; q < el.num_nodes; ++q)
    el.nodes[q] = E.grid_node_id(h, i + kHexCorner[q][0], j + kHexCorner[q][1], vol ? k + kHexCorner[q][2] : 0);
  return el;
}

}  // namespace dicer
