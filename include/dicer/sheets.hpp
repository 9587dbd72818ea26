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

}  // namespace dicer
