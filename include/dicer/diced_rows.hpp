#pragma once
// DicedRows: a coarse mesh diced (store order, topology, sheets, intervals,
// gradings, numbering) whose mesh-table rows (tables.hpp, rows.hpp) are made
// on demand instead of held.
//
// Why: the tables take about 1.4 KB per coarse hex (the element row alone
// ~520 bytes), more than everything they are made from. FineMesh::dice
// compiles them all into memory, which geometry-conforming dicing and
// second-order input need (they move nodes in them); write_store(const
// DicedRows&, ...) (store.hpp) writes them a page at a time, so dicing
// straight to a store holds this object and one page per table: about 1.2
// KB per coarse hex at the peak, where the compiled tables add ~1.4 KB more
// (bench/README.md, "Dicing straight to a store").
//
// Invariant: every row, and so every store byte but the uuid, is the same
// whichever way the tables are made (tests: DicedRows.*).
//
// Errors: the constructor throws what FineMesh::dice throws (topology,
// intervals, numbering: Error{BadInput|Overflow|Usage}).
#include <memory>
#include <string>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/intervals.hpp"
#include "dicer/numbering.hpp"
#include "dicer/rows.hpp"
#include "dicer/topology.hpp"

namespace dicer {

class DicedRows {
 public:
  // As FineMesh::dice: elements in space-filling-curve order of their
  // centroids unless locality_order is false; sheet ids those of the input
  // file; `notes` receives how interval conflicts were resolved. Time
  // O(elements log elements); memory O(coarse mesh) (the input's own
  // arrays are released before the topology of the ordered mesh is built).
  DicedRows(CoarseMesh coarse, const IntervalRequest& request, std::vector<std::string>* notes = nullptr,
            bool locality_order = true);

  Mode mode() const { return info_.mode; }
  // Counts, blocks and per-block counts, as FineMesh::info() will hold them.
  const MeshInfo& info() const { return info_; }
  // The ordered coarse mesh (sets, file ids, coordinates).
  const CoarseMesh& coarse() const { return *mesh_; }
  const std::vector<Id>& sheet_intervals() const { return sheet_intervals_; }
  const std::vector<SheetGrading>& sheet_gradings() const { return sheet_gradings_; }

  // Row i of each table; ids must be in range (0 <= i < count). O(1).
  VertexRow vertex(Id v) const;
  EdgeRow edge(Id e) const;
  FaceRow face(Id f) const;
  ElementRow element(Id h) const;
  // Coarse element h's corner coordinates (corners() of them).
  void corners(Id h, Vec3* xyz) const;
  // geometry/vertex_owner: (dim, tag) per vertex from the mesh file's
  // classification, (-1, -1) where it has none.
  std::vector<std::int32_t> vertex_owners() const;

  // The tables in memory (FineMesh::dice). Leaves this object moved from.
  FineMesh compile() &&;

 private:
  tfi::Grading edge_grading(Id e) const {
    return edge_grading_.empty() ? tfi::Grading{} : edge_grading_[static_cast<size_t>(e)];
  }
  std::shared_ptr<const CoarseMesh> mesh_;
  Topology t_;
  Numbering num_;
  std::vector<Id> edge_sheet_, edge_other_;
  std::vector<tfi::Grading> edge_grading_;  // one per edge, or empty when no sheet is graded
  MeshInfo info_;
  std::vector<Id> sheet_intervals_;
  std::vector<SheetGrading> sheet_gradings_;
};

}  // namespace dicer
