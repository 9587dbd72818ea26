// Adjacency of fine elements, from the numbering and one table row per
// coarse face or edge crossed: no search.
//
// Inside a coarse element a neighbour is a step of i, j or k. Across a
// coarse face (volume) or edge (surface) the store names the other coarse
// element (FORMAT.md: faces column 14, edges column 8); the fine face's
// cell in the face's canonical grid (orientation.hpp FaceMap) is mapped
// into the other element's local grid through that element's face code.
//
// Cost: O(1) rows per answer (the element's row, at most one face or edge
// row and the other element's row per side). Errors: Error{Usage} for an
// id outside the mesh; Corrupt rows as RowReader reports them.
#pragma once

#include <vector>

#include "dicer/fine_mesh.hpp"

namespace dicer {

// The fine elements across each side of element `id` in Exodus side order
// (HEX8: the 6 faces of kHexSideCorners; QUAD4: the 4 edges of
// kShellSideCorners), -1 on the boundary (and on a non-manifold edge).
std::vector<Id> element_neighbors(const FineMesh& mesh, Id id);

// The fine elements that use node `id`, ascending: from one element the
// node's owner row places it in, then across faces (edges) to the
// elements that also use it. O(elements found) rows. Elements that touch
// the node but connect to the others through no face (two blocks meeting
// at one vertex only) are not reached.
std::vector<Id> node_elements(const FineMesh& mesh, Id id);

}  // namespace dicer
