#pragma once
// The sets of a chunk from the coarse rows: shared by the chunk's two
// sources (ChunkStream, ExportChunk with a box). Private to export/.
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "dicer/export.hpp"
#include "dicer/rows.hpp"

namespace dicer::detail {

// Node-set membership of a fine node: every vertex of its owning entity is
// in the set. Appends the id runs of coarse element h's entities (its
// vertices, edges, faces and, in volume mode, its interior) whose corners
// are all in `sorted_vertices`; an entity shared with other elements comes
// again from each of them (callers sort and deduplicate).
void node_set_ranges(const ElementRow& h, Mode mode, const std::vector<Id>& sorted_vertices,
                     std::vector<std::array<Id, 2>>& out);

// One coarse side a side set names: coarse element h, set index, Exodus side.
struct SideRef {
  Id h;
  std::int32_t set;
  std::int8_t side;
};
// The side-set members among coarse elements [first, end), sorted by h
// (sides outside 0..5 dropped).
std::vector<SideRef> side_refs(const MeshSets& sets, Id first, Id end);

// How many fine elements lie on Exodus side `side` of a coarse element of
// intervals n (what append_side appends), as a long double: no overflow.
long double side_faces(Mode mode, const std::array<Id, 3>& n, std::int8_t side);

// Appends the fine elements on Exodus side `side` of a coarse element
// (its first fine id and intervals) to m, as (global element id, side).
// O(its fine faces).
void append_side(Mode mode, Id element_first, const std::array<Id, 3>& n, std::int8_t side, SideMembers& m);

// Sorts m's members by element, then side, and drops repeats.
void sort_members(SideMembers& m);

// Bytes as a message says them: "1.5 GiB".
std::string gib(long double bytes);

// Sorted, disjoint ranges from any list of ranges (merging those that
// overlap or touch).
void merge_ranges(std::vector<std::array<Id, 2>>& r);

}  // namespace dicer::detail
