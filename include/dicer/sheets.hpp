#pragma once
// Dicer sheets: the classes of coarse edges that must share one interval,
// found by union-find over the opposite edges of every quad face (the
// paper's "dicer loops & sheets"). A structured a x b x c box has a+b+c.
//
// Sheet ids are ordered by the lowest edge id in each sheet, and edge ids by
// vertex ids, so a sheet id depends only on the input file.
#include <cstdint>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/topology.hpp"

namespace dicer {

struct Sheets {
  std::vector<Id> edge_sheet;          // sheet of each edge
  std::vector<Id> edge_count;          // edges in each sheet
  // Blocks (indices into CoarseMesh::blocks) each sheet touches, CSR.
  std::vector<Id> block_offset;        // size num_sheets()+1
  std::vector<std::int32_t> block_index;
  Id num_sheets() const { return static_cast<Id>(edge_count.size()); }
};

// O(n alpha(n)) union-find plus an O(n log n) sort for the block lists.
Sheets find_sheets(const CoarseMesh& mesh, const Topology& topo);

// A direction across each sheet, for graded sheets (intervals.hpp): the
// sheet's lowest edge runs lo -> hi, and the direction crosses each face
// from one side edge to the opposite one keeping the face's axis sense
// (the canonical u of sides v0v1 and v3v2, the v of v0v3 and v1v2). A
// sheet that comes back to an edge with the other sense (a Moebius-like
// ring) has no direction: `twisted`.
// Cost: O(E + F) time and memory (a breadth-first walk of each sheet).
struct SheetDirections {
  std::vector<std::uint8_t> edge_flip;  // per edge: 1 when the sheet's direction runs hi -> lo along it
  std::vector<std::uint8_t> twisted;    // per sheet: 1 when no direction is consistent
};
SheetDirections orient_sheets(const Topology& topo, const Sheets& sheets);

}  // namespace dicer
