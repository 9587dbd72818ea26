// Point location: which fine element contains a point, and where in it.
//
// The search never materialises the mesh: the spatial index (groups of
// kBoundsGroup coarse elements, in memory) and each candidate's bounds row
// (rows.hpp ElementBounds) select coarse elements; a Newton solve of the
// coarse element's trilinear corner map guesses the fine cell (exact for a
// straight element: its fine nodes are that map at i/n, j/n, k/n); the
// fine cell's own trilinear map (its 8 nodes, as node(id) gives them) is
// inverted; a curved element is walked cell to cell from the guess, then
// scanned whole if the walk fails.
//
// Invariants: a found element's trilinear map at xi returns the point to
// kLocateTolerance of the element's size, and xi lies in [0,1]^3 within
// kLocateTolerance; among the elements that contain the point (a point on
// a shared face, edge or node), the lowest id is returned. Volume stores
// only (Error{Usage} for a surface store).
//
// Cost: O(groups) box tests per point (in memory), then for each candidate
// coarse element one bounds row, a few fine elements and their nodes;
// pages come through the store's cache. Thread-safe (a cursor per call).
#pragma once

#include <array>
#include <vector>

#include "dicer/fine_mesh.hpp"

namespace dicer {

inline constexpr double kLocateTolerance = 1e-10;

struct Located {
  Id element = -1;                 // -1: no element contains the point
  std::array<double, 3> xi{};      // local coordinates in the element (VTK/Exodus HEX8 corner order)
};

// One point (p: x, y, z).
Located locate_point(const FineMesh& mesh, const std::array<double, 3>& p);

// Many points (n x 3, row-major) in `threads` threads; out[i] for point i.
std::vector<Located> locate_points(const FineMesh& mesh, const std::vector<double>& xyz, int threads = 1);

// The trilinear map of 8 corners (VTK/Exodus HEX8 order) at xi.
std::array<double, 3> trilinear(const std::array<std::array<double, 3>, 8>& x, const std::array<double, 3>& xi);

}  // namespace dicer
