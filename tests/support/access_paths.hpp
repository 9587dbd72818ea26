#pragma once
// One check of DESIGN invariant 2 for any mesh diced in the test: every
// access path gives the same bits for every node id (gtest assertions).
#include <string>

#include "dicer/fine_mesh.hpp"

namespace dicer::test {

// node(id), the node cursor (one-plane, 40-point and whole-block slabs),
// the block fill (and its connectivity against element(id)), the batches
// (small and default slabs), and the store written to `store_path` and read
// back (node(id), its cursor, its sheet gradings, the sweep checksum and,
// with verify_store, verify): the same bits.
void expect_paths_bit_identical(const FineMesh& mesh, const std::string& store_path, bool verify_store = true);

}  // namespace dicer::test
