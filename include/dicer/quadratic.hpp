#pragma once
// Second-order coarse meshes (HEX20, HEX27; QUAD8, QUAD9): the fine mesh
// follows the quadratic geometry the mid nodes describe, without any CAD.
//
// The corners make the coarse mesh (topology, sheets, numbering: as for a
// first-order file). The nodes after them (CoarseMesh::mid) shape it:
//  - Edges. The curve through an edge's ends a, b and its mid node m at
//    parameter 1/2 (isoparametric Lagrange P2). Fine node t of n sits at
//    s = tfi::param(t, n, grading), the parameter the (graded) TFI gives
//    it, at
//        x(s) = lerp(a, b, s) + 4 s (1 - s) (m - (a + b) / 2),
//    the P2 curve written as the straight edge plus its bubble.
//  - Faces. The serendipity surface (QUAD8, HEX20 faces) is, exactly, the
//    Coons patch of its four P2 edges: both are the one function of the
//    8-term serendipity space through the 8 nodes. So the TFI of the moved
//    edges already puts such a face's nodes on it, and nothing is stored. A
//    face with a centre node c (QUAD9, HEX27 faces) is biquadratic: the
//    serendipity surface plus the face bubble 16 u(1-u) v(1-v) times
//    (c - the serendipity surface's centre); its nodes get that bubble.
//  - Interiors (the HEX27 centre node included): TFI of the moved boundary,
//    as for CAD moves (geometry.hpp), so every access path stays bit-identical.
// Moves are stored like CAD moves (FineMesh::move_nodes: bounding rows of
// the store, edges before faces). Where the mid node lies at the chord's
// midpoint, or a centre node at the serendipity centre, within 1e-12 of
// the coarse mesh's bounding-box diagonal (a writer's rounding), the entity
// is straight and stores nothing.
//
// Checks (Error{BadInput}, naming the file's element and node ids): two
// elements that give a shared edge or face different mid nodes (coordinates
// not identical); one node given as the mid node of two entities. A file
// mixing first- and second-order elements is accepted: an edge or face is
// quadratic when any element holding it gives its mid node (all that do
// must agree), straight otherwise, and the TFI keeps the mesh conforming.
// Inversion: every fine element of a coarse element with moved nodes is
// checked with the one scaled Jacobian (quality.hpp); any <= 0 is refused
// (Error{Geometry}) naming the coarse element, as for a CAD projection.
// Cost: O(coarse entities + moved fine nodes) time, plus the quality check
// of every fine element of a curved coarse element (as for CAD moves);
// O(coarse entities) memory.
#include "dicer/fine_mesh.hpp"

namespace dicer {

struct SecondOrderReport {
  bool second_order = false;      // the mesh had mid nodes (else nothing was done)
  Id edges_curved = 0, faces_curved = 0;  // entities whose fine nodes moved
  Id bounding_nodes = 0;          // rows of the bounding arrays after the moves
  double min_scaled_jacobian = 1; // over the fine elements of curved coarse elements
  Id elements_checked = 0;
};

// Moves the fine nodes on the quadratic edges and faces of a mesh diced in
// this process from a second-order coarse mesh (FineMesh::coarse() holds its
// mid nodes); a first-order mesh is left as it is. Call it at most once, and
// not together with conform_to_geometry (both move the same nodes; the CLI
// lets the CAD win). Throws as described above; the mesh is then unusable.
SecondOrderReport apply_second_order(FineMesh& mesh);

}  // namespace dicer
