#pragma once
// Coarse-mesh conformity, checked before dicing: the two ways a coarse mesh
// that passes validate_coarse_mesh() still gives a fine mesh with
// coincident or hanging fine nodes.
//
//  - Coincident vertices: distinct vertices with bit-identical coordinates
//    (a contact interface or a split mesh, common in MOOSE inputs). Dicing
//    keeps them apart, so every fine node of the coincident coarse edges
//    and faces coincides too; `verify` counts those fine nodes exactly.
//  - Hanging vertices: a boundary vertex lying inside a boundary facet (a
//    quad face in a volume mesh, an edge in a surface mesh) that it is not
//    a corner of, e.g. the mid-edge or mid-face vertex of a 2:1 refined
//    neighbour. Such a mesh is non-conforming and so is its fine mesh.
//
// Only boundary facets (used by one element) can host a hanging vertex: a
// vertex inside an interior face would make the face non-manifold, which
// build_topology refuses. "Inside" is within 1e-6 of the facet's size and
// not within that distance of the facet's corners (those are coincident
// vertices or the facet's own).
//
// Cost: O(V log V) for coincident vertices; O(B log B) plus the facets
// near each boundary vertex (a uniform grid of the facets' median size)
// for hanging ones, B the boundary size. Memory O(B).
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/topology.hpp"

namespace dicer {

struct CoarseConformity {
  struct Coincident {
    Id a = 0, b = 0;  // vertex indices, a < b, equal x, y, z
  };
  struct Hanging {
    Id vertex = 0;
    Id element = 0;  // the element whose boundary facet holds it
    int slot = 0;    // local face (volume: kHexFace) or edge (surface: kQuadEdge) of that element
  };
  Id coincident_pairs = 0;  // pairs (a group of k vertices counts k - 1)
  Id hanging_vertices = 0;
  std::vector<Coincident> coincident;  // the first few, by coordinates
  std::vector<Hanging> hanging;        // the first few, by vertex
  bool ok() const { return coincident_pairs == 0 && hanging_vertices == 0; }
};

// `examples`: how many of each kind to keep.
CoarseConformity check_coarse_conformity(const CoarseMesh& mesh, const Topology& topology, int examples = 5);

// One warning sentence per kind found (file ids and coordinates of the
// examples), for `dice` and `verify` to print; empty when ok().
std::vector<std::string> conformity_warnings(const CoarseMesh& mesh, const CoarseConformity& c);

}  // namespace dicer
