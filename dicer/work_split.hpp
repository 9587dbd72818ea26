#pragma once
// Private to dicer/: how whole-mesh passes (sweep, transfer) split coarse
// elements over threads. Defined in sweep.cpp.
#include <vector>

#include "dicer/fine_mesh.hpp"

namespace dicer::detail {

// Coarse elements [first, end) split into `parts` ranges of about equal work
// (owned nodes + fine elements: node_first + element_first rises by exactly
// that from one element to the next): parts + 1 bounds, first and end
// included, never decreasing. O(parts log H): a store's from its page index
// alone (no page read; balanced to within a page), in memory from the rows.
std::vector<Id> split_work(const FineMesh& mesh, unsigned parts, Id first, Id end);

// At least 1 and at most `threads`: no more than a store's cache budget can
// keep pinned twice over (kSweepPagesPerThread pages each).
unsigned threads_for_cache(const FineMesh& mesh, unsigned threads);

}  // namespace dicer::detail
