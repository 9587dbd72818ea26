// Batch iteration (batch.hpp): a coarse element's own boundary nodes once
// (a straight hex's written there by fill_slab, others copied by
// own_boundary_nodes), then its slabs through fill_slab, which writes the
// interior planes of each slab straight into the batch's arrays.
#include "dicer/batch.hpp"

#include <algorithm>
#include <cstdio>
#include <new>

#include "dicer/error.hpp"
#include "evaluate.hpp"

namespace dicer {

namespace {
const char* const kHow = "is read a slab of grid planes at a time with its boundary";
}  // namespace

BatchCursor::BatchCursor(const FineMesh& mesh, Id first, Id end, BatchOptions options) : mesh_(mesh), opt_(options) {
  const Id layer = opt_.first_layer;
  reset(first, end);
  opt_.first_layer = layer;  // the first element of the first pass only
}

void BatchCursor::reset(Id first, Id end) {
  if (end < 0) end = mesh_.num_coarse_elements();
  if (first < 0 || first > end || end > mesh_.num_coarse_elements())
    throw Error(ErrorKind::Usage, "batches: coarse elements " + std::to_string(first) + ".." + std::to_string(end) +
                                      " outside the mesh (" + std::to_string(mesh_.num_coarse_elements()) + ")");
  h_ = first, end_ = end, k0_ = 0, entered_ = false, opt_.first_layer = 0;
}

void BatchCursor::enter() {
  RowReader(mesh_.tables(), block_.cursor).element(h_, row_);
  const ElementRow& h = row_;
  const bool vol = mesh_.mode() == Mode::Volume;
  n_ = h.n;
  n2_ = vol ? n_[2] : 0;
  step_ = std::max<Id>(1, opt_.slab_points / ((n_[0] + 1) * (n_[1] + 1)));
  own_end_ = vol ? h.cell_node : h.cell_node + ids::face_nodes(n_[0], n_[1]);
  k0_ = 0;
  if (opt_.first_layer != 0) {
    if (opt_.first_layer < 0 || opt_.first_layer >= std::max<Id>(n2_, 1))
      throw Error(ErrorKind::Usage, "batches: first layer " + std::to_string(opt_.first_layer) + " outside the element");
    k0_ = opt_.first_layer;
    opt_.first_layer = 0;  // the first element only
  }
  // What the cursor holds from the last element is reused, not added (an
  // element as large as the last one that fitted fits).
  double held = static_cast<double>(block_.held_bytes() + lines_.capacity() * sizeof(Id));
  for (const auto& a : xyz_) held += static_cast<double>(a.capacity() * sizeof(double));
  check_element_memory(mesh_, h_, n_, kHow, slab_bytes(), held);
  entered_ = true;
}

// Memory is O(interval^2) per coarse element (a slab of whole grid planes
// and the element's boundary): an element of interval 10,000 needs
// gigabytes. A failed allocation says which element and why, not only
// "out of memory".
bool BatchCursor::next(FineBatch& out) {
  try {
    return next_batch(out);
  } catch (const std::bad_alloc&) {
    throw_too_big();
  }
}

// About what a slab of the entered element holds: ids (and coordinates,
// when asked) of its planes and of the element's boundary, connectivity of
// its layers. A surface element is one plane, all boundary, which with
// coordinates is held four times (the boundary scratch, its canonical
// face, the block and the batch): 128 B a point (measured: 1.29 GB peak
// for a quad of interval 3000).
double BatchCursor::slab_bytes() const {
  const bool vol = n2_ > 0;
  const double n0 = static_cast<double>(n_[0]), n1 = static_cast<double>(n_[1]), n2 = static_cast<double>(n_[2]);
  const double plane = (n0 + 1) * (n1 + 1), conn = opt_.conn ? n0 * n1 * 8 * mesh_.corners() : 0;
  if (!vol) return plane * (opt_.coords ? 128 : 16) + conn;
  const double boundary = 2 * (n0 * n1 + n1 * n2 + n0 * n2), layers = static_cast<double>(step_);
  return (plane * (layers + 1) + boundary) * (opt_.coords ? 32 : 8) + conn * layers;
}

void BatchCursor::throw_too_big() const { throw element_too_big(mesh_, h_, n_, kHow, slab_bytes()); }

bool BatchCursor::next_batch(FineBatch& out) {
  if (h_ >= end_) return false;
  if (!entered_) enter();
  const bool vol = n2_ > 0;
  const Id k0 = k0_, k1 = vol ? std::min(k0 + step_, n2_) : 0;
  out.coarse_element = h_;
  out.block = row_.block;
  out.n = n_;
  out.first_layer = k0;
  out.corners = mesh_.corners();
  // Nodes: the own boundary on the first slab, then the interior planes k
  // in (k0, k1], k < n2 (ids follow cell_node in plane order).
  const Id in = (n_[0] - 1) * (n_[1] - 1);
  const Id p_lo = vol ? k0 + 1 : 1, p_hi = vol ? std::min(k1, n2_ - 1) : 0;  // interior planes held
  out.node_begin = k0 == 0 ? row_.node_first : row_.cell_node + in * (p_lo - 1);
  out.node_end = vol ? row_.cell_node + in * std::max<Id>(p_hi, p_lo - 1) : own_end_;
  if (opt_.coords) {
    // The own boundary first (k0 = 0), then the interior, which fill_slab
    // writes there directly (volume; a surface element's interior is its
    // face, part of its own boundary).
    const Id own = k0 == 0 ? own_end_ - row_.node_first : 0;
    const Id total = out.node_end - out.node_begin;
    // No more than the element's boundary points (a hostile row must not
    // make us allocate its whole id gap before the entities are checked).
    const Id grid = (n_[0] + 1) * (n_[1] + 1) * (vol ? n2_ + 1 : 1);
    const Id boundary = vol ? grid - (n_[0] - 1) * (n_[1] - 1) * (n2_ - 1) : grid;
    if (own < 0 || total < own || own > boundary)
      detail::Evaluator(mesh_.tables(), block_.cursor).R.corrupt(RowTable::Elements, h_,
                                                                "the element's own node range disagrees with its intervals");
    for (auto& a : xyz_) a.resize(static_cast<size_t>(total + detail::kPatchSlack));  // fill_slab's room
    double* const interior[3] = {xyz_[0].data() + own, xyz_[1].data() + own, xyz_[2].data() + own};
    double* const front[3] = {xyz_[0].data(), xyz_[1].data(), xyz_[2].data()};
    // A straight hex's own boundary straight into the batch; otherwise
    // (a curved hex, whose interior needs its whole boundary; a surface
    // element) by way of the block's scratch.
    const bool direct = k0 == 0 && vol && !row_.curved();
    mesh_.fill_slab(h_, k0, k1, block_, true, opt_.conn, opt_.grid, vol ? interior : nullptr, &row_, direct ? front : nullptr, own);
    if (k0 == 0 && !direct) {
      // fill_slab has just evaluated the element's owned entities (at
      // least) into the block's scratch, in their canonical frames.
      const detail::Evaluator E(mesh_.tables(), block_.cursor);
      const Id end = detail::own_boundary_nodes(E, row_, h_, block_.scratch, front, own);
      DICER_ASSERT(end == own_end_, "batches: the own range of the row");
    }
    const auto nodes = static_cast<size_t>(total);
    out.x = std::span<const double>(xyz_[0]).first(nodes);
    out.y = std::span<const double>(xyz_[1]).first(nodes);
    out.z = std::span<const double>(xyz_[2]).first(nodes);
  } else {
    if (opt_.conn || opt_.grid || opt_.lines) mesh_.fill_slab(h_, k0, k1, block_, false, opt_.conn, opt_.grid, nullptr, &row_);
    out.x = out.y = out.z = {};
  }
  // Elements: layers [k0, k1) (surface: the element's one layer).
  const Id layer = n_[0] * n_[1];
  out.element_begin = row_.element_first + layer * k0;
  out.element_end = row_.element_first + layer * (vol ? k1 : 1);
  out.conn = opt_.conn ? std::span<const Id>(block_.conn) : std::span<const Id>();
  out.grid = opt_.grid ? std::span<const Id>(block_.node_id) : std::span<const Id>();
  out.lines = {};
  if (opt_.lines) {
    // From the element's boundary ids, which fill_slab keeps in the
    // block, and its cell's numbering: no grid written.
    const Id rows = (n_[1] + 1) * (vol ? k1 - k0 + 1 : 1);
    const auto r = static_cast<size_t>(rows);
    lines_.resize(4 * r);
    Id* const l = lines_.data();
    DICER_ASSERT(block_.scratch.boundary.h == h_, "batches: the lines read the element's own boundary");
    detail::slab_lines(block_.scratch.boundary, row_.cell_node, k0, k1, l, l + rows, l + 2 * rows, l + 3 * rows);
    const std::span<const Id> all(lines_);
    out.lines = {all.first(r), all.subspan(r, r), all.subspan(2 * r, r), all.subspan(3 * r, r)};
  }
  // Advance.
  if (vol && k1 < n2_) {
    k0_ = k1;
  } else {
    ++h_;
    entered_ = false;
  }
  return true;
}

}  // namespace dicer
