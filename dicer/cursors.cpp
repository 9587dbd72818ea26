// Whole-mesh iteration in id order over the block fills (fill.cpp).
#include <algorithm>

#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/numbering.hpp"
#include "evaluate.hpp"

namespace dicer {
namespace {
// Grid planes per cursor slab: O(interval^2) values, never a whole block.
Id slab_planes(const std::array<Id, 3>& n, Id points) { return std::max<Id>(1, points / ((n[0] + 1) * (n[1] + 1))); }
}  // namespace

NodeCursor::NodeCursor(const FineMesh& mesh, Id begin, Id end, Id slab_points)
    : mesh_(mesh), next_(std::max<Id>(begin, 0)), end_(std::min(end, mesh.num_nodes())), slab_points_(slab_points) {}

bool NodeCursor::next(Id& id, Vec3& xyz) {
  if (next_ >= end_) return false;
  id = next_++;
  if ((id < own_first_ || id >= own_end_) && (id < cell_first_ || id >= cell_end_)) enter(id);
  if (id < own_end_ && id >= own_first_) {
    const auto q = static_cast<size_t>(id - own_first_);
    xyz = {own_[0][q], own_[1][q], own_[2][q]};
    return true;
  }
  // Interior: (i, j, k) from the local index, then the slab holding plane k.
  const auto [i, j, k] = ids::cell_local(id - cell_first_, n_);
  if (k < block_.plane0 || k >= block_.plane0 + block_.planes || block_.coarse_element != elem_)
    mesh_.fill_slab(elem_, k, std::min(k + slab_planes(n_, slab_points_) - 1, n_[2] - 1), block_, true, false);
  const Id g = block_.point_index(i, j, k);
  xyz = {block_.x[g], block_.y[g], block_.z[g]};
  return true;
}

// The coarse element owning node `id`: the points of everything it owns
// but its interior, at once (each entity filled whole in its frame).
void NodeCursor::enter(Id id) {
  const Id hid = owner_element(mesh_.tables(), id, cur_);
  const detail::Evaluator E(mesh_.tables(), cur_);
  const ElementRow h = E.R.element(hid);
  const bool vol = mesh_.mode() == Mode::Volume;
  elem_ = hid, n_ = h.n;
  own_first_ = h.node_first;
  own_end_ = detail::own_boundary_nodes(E, h, hid, scratch_, own_);
  cell_first_ = vol ? h.cell_node : own_end_;
  cell_end_ = vol ? h.cell_node + ids::cell_nodes(h.n) : own_end_;
  if ((id < own_first_ || id >= own_end_) && (id < cell_first_ || id >= cell_end_))
    E.R.corrupt(RowTable::Elements, hid, "node " + std::to_string(id) + " is in none of the entities it owns");
}

ElementCursor::ElementCursor(const FineMesh& mesh, Id begin, Id end, Id slab_points)
    : mesh_(mesh), next_(std::max<Id>(begin, 0)), end_(std::min(end, mesh.num_elements())), slab_points_(slab_points) {}

bool ElementCursor::next(FineElement& el) {
  if (next_ >= end_) return false;
  el.id = next_++;
  const bool held = !block_.conn.empty() && el.id >= block_.first_element &&
                    el.id < block_.first_element + block_.num_elements();
  if (!held) {
    // A slab of element layers, ids and connectivity only (no coordinates).
    std::array<Id, 3> ijk;
    const Id h = mesh_.locate_element(el.id, ijk, cur_);
    if (mesh_.mode() == Mode::Volume) {
      const std::array<Id, 3> n = RowReader(mesh_.tables(), cur_).element(h).n;
      mesh_.fill_slab(h, ijk[2], std::min(ijk[2] + slab_planes(n, slab_points_), n[2]), block_, false, true);
    } else {
      mesh_.fill_slab(h, 0, 0, block_, false, true);
    }
  }
  const Id l = el.id - block_.first_element;
  el.coarse_element = block_.coarse_element;
  el.ijk = ids::element_local(l, block_.n);
  el.ijk[2] += block_.plane0;
  el.block = block_.block;
  el.num_nodes = mesh_.corners();
  std::copy_n(&block_.conn[static_cast<size_t>(l) * el.num_nodes], el.num_nodes, el.nodes.begin());
  return true;
}

}  // namespace dicer
