// Point location: which fine element contains a point (volume stores), or
// which fine element of a surface lies nearest to it, and where in it.
//
// The search never materialises the mesh. The spatial index (boxes of
// kBoundsGroup coarse elements, in memory) is put under a tree of boxes,
// 8 children each, built per call in O(G) (G groups); each group's bounds
// rows (rows.hpp ElementBounds) are then scanned from their page.
//
// Volume stores: a straight element is its corners' trilinear map (TFI
// reproduces it): one Newton solve of that map gives the fine cell and xi
// without reading a fine node. A curved element (moved onto the CAD) is
// walked cell to cell from that guess, inverting each fine cell's own
// trilinear map (its 8 nodes, as node(id) gives them); a walk that reaches
// the element's boundary with the point beyond it answers "not here", one
// that cannot decide (a cell map not invertible, a cycle) scans the
// element's cells.
//
// Surface stores: the nearest point of the surface, found best-first over
// the tree (boxes nearer than the best answer so far). A straight quad is
// its corners' bilinear map: its closest point (a 2x2 Newton solve inside,
// the four straight edges on the border) gives the cell and xi. A curved
// quad (second-order input, moved onto the CAD) is searched cell by cell,
// each cell skipped when the box of its four nodes is farther than the
// answer so far: exact, where a walk from that guess stopped in a local
// minimum of the distance (the nearest quad missed by up to 3e-3 on a
// QUAD9 patch, stop 55). Its nodes are filled once (fill_block); the last
// four filled are kept for the next points (a point near a coarse edge has
// several candidates), fewer when they would pass 64 MiB.
//
// Invariants: volume: a found element's trilinear map at xi returns the
// point to kLocateTolerance of the element's size, and xi lies in [0,1]^3
// within kLocateTolerance. Surface: xi in [0,1]^2 within kLocateTolerance
// (xi[2] = 0) and `distance` is the distance from the point to the
// element's bilinear map at xi, no more than max_distance. Among elements
// that hold the point (a shared face, edge or node) or lie equally near,
// within kLocateTolerance of their size, the lowest id is returned.
//
// Cost per point: O(log G) tree boxes and the few groups whose boxes hold
// the point (surface: whose boxes are nearer than the answer), a bounds row
// per coarse element of those groups, and for each candidate one element
// row, its corners and a Newton solve (curved volume elements: plus a
// few fine cells, 8 grid nodes each; a curved quad of interval n: its
// (n+1)^2 nodes unless it is one of the last four filled, a box per row
// of cells and a box per cell of the rows within reach: about 0.5 ms a
// point at interval 100 on one core, points in random order, where a
// straight quad takes microseconds). Memory: a curved quad's nodes, ~88 B a node (up to
// four quads kept, 64 MiB together unless one alone is larger), refused by
// name (Usage) when they cannot fit. Pages come through the store's cache.
// Thread-safe (a cursor per thread).
//
// Errors: Usage for a negative or NaN max_distance (or a finite one on a
// volume store), coordinates not a
// multiple of 3 or not finite; Corrupt for an index or rows that break
// their invariants.
#pragma once

#include <array>
#include <cmath>
#include <vector>

#include "dicer/fine_mesh.hpp"

namespace dicer {

inline constexpr double kLocateTolerance = 1e-10;

struct Located {
  Id element = -1;             // -1: no element contains the point (surface: none within max_distance)
  std::array<double, 3> xi{};  // local coordinates (VTK/Exodus HEX8 / QUAD4 corner order; surface: xi[2] = 0)
  double distance = 0;         // surface stores: from the point to the element's map at xi, infinity
                               // when element is -1; volume: 0
};

// One point (p: x, y, z). max_distance: surface stores only (points
// farther from every element come back -1); a finite one on a volume store
// is Usage (it would be ignored: a point is in an element or in none).
Located locate_point(const FineMesh& mesh, const std::array<double, 3>& p, double max_distance = INFINITY);

// Many points (n x 3, row-major) in `threads` threads; out[i] for point i.
std::vector<Located> locate_points(const FineMesh& mesh, const std::vector<double>& xyz, int threads = 1,
                                   double max_distance = INFINITY);

// The trilinear map of 8 corners (VTK/Exodus HEX8 order) at xi.
std::array<double, 3> trilinear(const std::array<std::array<double, 3>, 8>& x, const std::array<double, 3>& xi);
// The bilinear map of 4 corners (QUAD4 order) at (xi[0], xi[1]).
std::array<double, 3> bilinear(const std::array<std::array<double, 3>, 4>& x, const std::array<double, 3>& xi);

}  // namespace dicer
