#pragma once
// Batch iteration: the fine mesh a slab at a time, as contiguous arrays.
//
// BatchCursor visits coarse elements [first, end) in store order and, for
// each, hands out slabs of its grid planes. A batch holds
//  - nodes [node_begin, node_end): consecutive ids, the ones the coarse
//    element owns (owner order, numbering.hpp), coordinates at index
//    id - node_begin. The first batch of an element holds its own vertices,
//    edges and faces, then interior planes; later batches interior planes;
//  - elements [element_begin, element_end): consecutive ids, connectivity
//    in global node ids, `corners` per element (VTK/Exodus HEX8 or QUAD4
//    order).
// Over [first, end) every fine element and every node those coarse elements
// own comes exactly once, in increasing id order; over coarse elements
// [0, H) that is the whole mesh in id order. The bits equal node(id),
// element(id) and the cursors' (property tests compare them).
//
// Cost: O(slab) per batch, no per-node call; the arrays are reused, so a
// warm cursor allocates nothing. Memory: one slab (about `slab_points`
// grid points, whole planes) plus an element's boundary (O(interval^2)).
// Thread safety: one BatchCursor per thread (each holds its own page pins);
// the mesh may be shared. Errors: a corrupt row is Error{Corrupt}; a range
// outside the mesh is Error{Usage}.
#include <array>
#include <span>
#include <vector>

#include "dicer/fine_mesh.hpp"

namespace dicer {

struct FineBatch {
  Id coarse_element = -1;
  std::int32_t block = -1;                // index into MeshInfo::blocks
  std::array<Id, 3> n{};                  // the coarse element's intervals (n[2] = 1 in surface mode)
  Id first_layer = 0;                     // element layer k of element_begin (its ijk is (0, 0, first_layer))
  Id node_begin = 0, node_end = 0;        // consecutive node ids
  std::span<const double> x, y, z;        // node_end - node_begin each (empty without coordinates)
  Id element_begin = 0, element_end = 0;  // consecutive element ids
  int corners = 8;
  std::span<const Id> conn;               // corners * (element_end - element_begin) (empty without connectivity)
  // The slab's grid (BatchOptions::grid; empty otherwise): the node id of
  // each grid point (i, j, k) of the planes the batch's elements span,
  // k = first_layer .. first_layer + L with L = num_elements() / (n[0] n[1])
  // element layers (surface: the one plane, k = 0), at
  // i + (n[0] + 1) * (j + (n[1] + 1) * (k - first_layer)). An element's
  // corners are its cell's grid points (what conn lists): consumers that
  // use the structure read it instead of conn.
  // Along each grid row (fixed j, k) the interior points i = 1 .. n[0] - 1
  // are one entity's (a cell's interior, a face's or an edge's) and their
  // ids an arithmetic progression (step 1, -1 or a row of a face's
  // canonical grid): `lines` below relies on it.
  std::span<const Id> grid;
  // The same grid, row by row, as lines (BatchOptions::lines; empty
  // otherwise): grid row r = j + (n[1] + 1) * (k - first_layer), one entry
  // per row of the planes `grid` spans, holds the id of point i = 0 in
  // lines.start[r], of i = n[0] in lines.end[r], and of 0 < i < n[0] in
  // lines.first[r] + (i - 1) * lines.step[r] (n[0] < 3: step 0; n[0] = 1:
  // first = end). 4 (n[1] + 1) ids a plane where the grid has
  // (n[0] + 1) (n[1] + 1): the sweep's checksum reads these, and the
  // batch never writes the grid point by point for them.
  struct Lines {
    std::span<const Id> start, first, step, end;
  } lines;
  Id num_nodes() const { return node_end - node_begin; }
  Id num_elements() const { return element_end - element_begin; }
};

struct BatchOptions {
  bool coords = true;  // node coordinates
  bool conn = true;    // element connectivity
  Id slab_points = kCursorSlabPoints;
  // The first coarse element's batches start at element layer first_layer
  // (0 <= first_layer < n[2]; surface mode: 0): its elements before that
  // layer and its nodes up to grid plane first_layer (its own boundary
  // included) are skipped. The cursors start mid-element with it.
  Id first_layer = 0;
  bool grid = false;   // the slab's grid of node ids (FineBatch::grid)
  bool lines = false;  // the grid as one line per row (FineBatch::lines)
};

class BatchCursor {
 public:
  // Coarse elements [first, end); end = -1: to the last.
  BatchCursor(const FineMesh& mesh, Id first = 0, Id end = -1, BatchOptions options = {});
  // The next batch (valid until the next call); false at the end.
  // Memory: a slab of whole grid planes and the element's boundary,
  // O(interval^2) per coarse element; Error{Usage} naming the element when
  // that cannot be allocated.
  bool next(FineBatch& out);
  // Starts over at coarse elements [first, end) (end = -1: to the last)
  // from layer 0 (BatchOptions::first_layer applies to the first pass only),
  // keeping the buffers: a warm cursor allocates nothing on a repeated pass.
  // Error{Usage} as the constructor.
  void reset(Id first, Id end = -1);

 private:
  bool next_batch(FineBatch& out);
  double slab_bytes() const;
  [[noreturn]] void throw_too_big() const;
  void enter();
  const FineMesh& mesh_;
  Id h_, end_;
  BatchOptions opt_;
  Id k0_ = 0, step_ = 1, n2_ = 0;  // next slab starts at layer k0_ of element h_; n2_ layers (0: surface)
  bool entered_ = false;
  std::array<Id, 3> n_{};
  Id own_end_ = 0;  // the element's own boundary nodes end here (its interior follows)
  ElementRow row_;  // the element's validated row, decoded once on entry
  FineBlock block_;
  std::vector<double> xyz_[3];  // the batch's nodes
  std::vector<Id> lines_;       // FineBatch::lines: start, first, step, end
};

}  // namespace dicer
