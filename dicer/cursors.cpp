// Whole-mesh iteration in id order, one node or element per call, over the
// batches of batch.cpp (one place for the slab walk).
#include <algorithm>

#include "dicer/batch.hpp"
#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/numbering.hpp"

namespace dicer {

NodeCursor::NodeCursor(const FineMesh& mesh, Id begin, Id end, Id slab_points)
    : mesh_(mesh), next_(std::max<Id>(begin, 0)), end_(std::min(end, mesh.num_nodes())), slab_points_(slab_points) {}

NodeCursor::~NodeCursor() = default;

bool NodeCursor::next(Id& id, Vec3& xyz) {
  if (next_ >= end_) return false;
  if (!batches_) {
    // The owner of the first node, from the slab holding its grid plane.
    MeshCursor cur;
    const RowReader R(mesh_.tables(), cur);
    const Id h = owner_element(mesh_.tables(), next_, cur);
    const ElementRow row = R.element(h);
    BatchOptions opt;
    opt.conn = false, opt.slab_points = slab_points_;
    const Id in = (row.n[0] - 1) * (row.n[1] - 1);
    if (mesh_.mode() == Mode::Volume && in > 0 && next_ >= row.cell_node)
      opt.first_layer = std::min((next_ - row.cell_node) / in, row.n[2] - 1);  // the slab before plane k holds it
    batches_ = std::make_unique<BatchCursor>(mesh_, h, mesh_.num_coarse_elements(), opt);
    batch_ = std::make_unique<FineBatch>();
  }
  while (next_ >= batch_->node_end)
    if (!batches_->next(*batch_))
      throw Error(ErrorKind::Corrupt, mesh_.tables().origin + ": node " + std::to_string(next_) +
                                          " lies past the last coarse element's own nodes");
  // A lying page index can start the walk past the node (its owner found too late).
  if (next_ < batch_->node_begin)
    throw Error(ErrorKind::Corrupt, mesh_.tables().origin + ": numbering/element_page_node: node " +
                                        std::to_string(next_) + " is not where the page index puts it");
  id = next_++;
  const auto q = static_cast<size_t>(id - batch_->node_begin);
  xyz = {batch_->x[q], batch_->y[q], batch_->z[q]};
  return true;
}

ElementCursor::ElementCursor(const FineMesh& mesh, Id begin, Id end, Id slab_points)
    : mesh_(mesh), next_(std::max<Id>(begin, 0)), end_(std::min(end, mesh.num_elements())), slab_points_(slab_points) {}

ElementCursor::~ElementCursor() = default;

bool ElementCursor::next(FineElement& el) {
  if (next_ >= end_) return false;
  if (!batches_) {
    std::array<Id, 3> ijk;
    MeshCursor cur;
    const Id h = mesh_.locate_element(next_, ijk, cur);
    BatchOptions opt;
    opt.coords = false, opt.slab_points = slab_points_;
    opt.first_layer = mesh_.mode() == Mode::Volume ? ijk[2] : 0;
    batches_ = std::make_unique<BatchCursor>(mesh_, h, mesh_.num_coarse_elements(), opt);
    batch_ = std::make_unique<FineBatch>();
  }
  while (next_ >= batch_->element_end)
    if (!batches_->next(*batch_))
      throw Error(ErrorKind::Corrupt, mesh_.tables().origin + ": element " + std::to_string(next_) +
                                          " lies past the last coarse element's elements");
  if (next_ < batch_->element_begin)
    throw Error(ErrorKind::Corrupt, mesh_.tables().origin + ": numbering/element_page_element: element " +
                                        std::to_string(next_) + " is not where the page index puts it");
  el.id = next_++;
  const FineBatch& b = *batch_;
  const Id l = el.id - b.element_begin;
  el.coarse_element = b.coarse_element;
  el.ijk = ids::element_local(l, b.n);
  el.ijk[2] += b.first_layer;
  el.block = b.block;
  el.num_nodes = b.corners;
  std::copy_n(&b.conn[static_cast<size_t>(l) * b.corners], b.corners, el.nodes.begin());
  return true;
}

}  // namespace dicer
