// Point location: which fine element contains a point, and where in it.
//
// The search never materialises the mesh: the spatial index (boxes of
// kBoundsGroup coarse elements, in memory, under a second level of 64
// groups built per call) and each candidate's bounds row (rows.hpp
// ElementBounds) select coarse elements. A straight element is its corners'
// trilinear map (TFI reproduces it): one Newton solve of that map gives the
// fine cell and xi without reading a fine node. A curved element (moved
// onto the CAD) is walked cell to cell from that guess, inverting each fine
// cell's own trilinear map (its 8 nodes, as node(id) gives them); a walk
// that reaches the element's boundary with the point beyond it answers
// "not here", one that cannot decide (a cell map not invertible, a cycle)
// scans the element's cells.
//
// Invariants: a found element's trilinear map at xi returns the point to
// kLocateTolerance of the element's size, and xi lies in [0,1]^3 within
// kLocateTolerance; among the elements that contain the point (a point on
// a shared face, edge or node), the lowest id is returned. Volume stores
// only (Error{Usage} for a surface store).
//
// Cost per point: O(G / 64 + 64) box tests in memory (G groups), a bounds
// row per coarse element of the groups that hold the point, and for each
// candidate one element row, its corners and a 3x3 Newton solve (curved:
// plus a few fine cells). Pages come through the store's cache; a call
// builds the second index level, O(G). Thread-safe (a cursor per thread).
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
