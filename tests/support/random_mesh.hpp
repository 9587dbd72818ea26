#pragma once
// Random coarse meshes for property tests: perturbed structured boxes with
// random vertex renumbering and random (valid, right-handed) local
// numberings of every hex, built directly as CoarseMesh.
#include <array>
#include <random>
#include <vector>

#include "dicer/coarse_mesh.hpp"

namespace dicer::test {

// The 24 rotations of a hex's local numbering, as corner permutations
// (new corner k = old corner perm[k]); all keep the hex right-handed.
std::vector<std::array<int, 8>> hex_rotations();

struct BoxSpec {
  int a = 2, b = 2, c = 2;        // coarse hexes per axis
  double perturb = 0.15;          // interior vertex jitter, fraction of spacing
  bool renumber = true;           // random vertex permutation
  bool rotate = true;             // random local numbering per hex
  int blocks = 1;                 // blocks assigned by x slab
};

CoarseMesh random_box(const BoxSpec& spec, std::mt19937_64& rng);

// A structured quad surface (a x b) on a bent sheet, for surface mode.
CoarseMesh random_quad_sheet(int a, int b, bool renumber, std::mt19937_64& rng);

}  // namespace dicer::test
