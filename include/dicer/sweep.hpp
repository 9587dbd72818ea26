#pragma once
// Sweep: visit every fine node and element once through the public cursors
// (NodeCursor, ElementCursor), split into contiguous id ranges over threads,
// and fold them into an order-independent checksum: the same for every
// thread count and cache budget (a test pins it), so two sweeps, two
// machines or two stores of the same mesh can be compared by one number.
#include <cstdint>
#include <functional>

#include "dicer/fine_mesh.hpp"
#include "dicer/store.hpp"

namespace dicer {

struct SweepResult {
  Id nodes = 0, elements = 0;
  unsigned threads = 1;        // threads used (see sweep())
  double seconds = 0;
  std::uint64_t checksum = 0;  // sum over nodes of h(id, x, y, z bits) + over elements of h(id, node ids)
};

// threads >= 1. A thread pins up to kSweepPagesPerThread pages of a store's
// cache, so no more threads are used than the budget can hold pinned twice
// over (the result says how many ran); the checksum is the same anyway.
// progress(done, total) is called from the calling thread only, in units of
// nodes + elements.
inline constexpr unsigned kSweepPagesPerThread = 20;
// [first_coarse, end_coarse) restricts the sweep to those coarse elements
// (end -1: the last): their fine elements and the nodes they own (an MPI
// rank's chunk); the checksums of a partition of the mesh add up to the
// whole mesh's (mod 2^64).
SweepResult sweep(const FineMesh& mesh, unsigned threads, const std::function<void(Id, Id)>& progress = {},
                  Id first_coarse = 0, Id end_coarse = -1);

// The checksum terms, exposed so tests can compute the same sum independently.
std::uint64_t node_checksum_term(Id id, const Vec3& x);
std::uint64_t element_checksum_term(const FineElement& e);

}  // namespace dicer
