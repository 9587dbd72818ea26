#pragma once
// verify: a streaming check of DESIGN.md invariants 3 (numbering, counts)
// and 4 (conformity), plus element quality. Memory: O(coarse mesh) plus one
// block; time: one fill per coarse element.
//
// What is checked, per coarse element block:
//  - every grid point's id is in range and round-trips id -> entity -> id;
//    node(id) returns the block's coordinates bit for bit (all boundary
//    points, interior points on the block diagonal);
//  - no two grid points of the block share an id unless they are the same
//    point, no two distinct ids share coordinates;
//  - every fine face inside the block is shared by exactly two fine
//    elements, every fine face on the block boundary by one;
// and across blocks:
//  - both hexes of an interior coarse face see the same fine faces (ids and
//    coordinates, order-independent hash), each coarse face is covered by
//    nu*nv fine faces exactly, boundary ones included;
//  - every hex around a coarse edge sees the same fine nodes on it;
//  - surface mode: every coarse edge is used by one (the boundary) or two
//    quads, which traverse it in opposite directions (consistent
//    orientation); fine boundary edges are counted;
//  - coincident fine nodes, exactly (bit-identical coordinates, distinct
//    ids), on the coarse boundary facets where alone they can occur, in
//    bounded memory; those on coincident coarse entities (an interface made
//    of duplicated vertices, e.g. a contact surface) are a warning, the
//    others (a non-conforming coarse mesh: hanging vertices) a failure;
//    nodes closer than 1e-9 of the diagonal but not identical, apart;
//  - node and element counts equal the closed formula of invariant 3;
//  - the sheet table (sheet_intervals, sheet_gradings) agrees with the
//    edges: each edge's interval and grading are its sheet's, an element's
//    parallel edges lie in one sheet, every sheet holds an edge (Corrupt,
//    naming the edge row, otherwise); the CLI also reads the store's sets
//    (read_store_sets checks them);
//  - minimum scaled Jacobian and the number of inverted fine elements
//    (scaled Jacobian <= 0 at some corner).
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "dicer/fine_mesh.hpp"

namespace dicer {

struct VerifyReport {
  Id nodes = 0, nodes_formula = 0;
  Id elements = 0, elements_formula = 0;
  Id fine_faces_checked = 0;   // fine faces (volume) or fine edges (surface) of every element
  Id boundary_fine_faces = 0;  // of them on the boundary: faces (volume), edges (surface)
  Id id_errors = 0;            // out of range or not round-tripping
  Id bit_identity_errors = 0;  // node(id) differs from the block's value
  Id coincident_nodes = 0;     // fine nodes sharing bit-identical coordinates with another id
  Id coincident_interface = 0; // of those, on coincident coarse entities (an interface): a warning
  Id near_coincident = 0;      // fine nodes within 1e-9 of the diagonal of another, not identical
  Id coincident_coarse_vertices = 0;  // coarse vertices sharing coordinates with another
  Id misoriented = 0;          // surface: coarse edges two quads traverse the same way
  Id conformity_errors = 0;    // fine faces shared wrongly; coarse faces and edges (one each) whose neighbours disagree
  Id inverted = 0;
  Id index_errors = 0;         // a node outside its element's bounds, an element outside its group's, a wrong neighbour
  double min_scaled_jacobian = 1.0;
  std::vector<std::string> problems;  // the first few, human readable
  std::vector<std::string> warnings;  // what is reported but not a failure (interfaces, near nodes)

  bool counts_ok() const { return nodes == nodes_formula && elements == elements_formula; }
  bool ok() const {
    return counts_ok() && id_errors == 0 && bit_identity_errors == 0 && coincident_nodes == coincident_interface &&
           conformity_errors == 0 && misoriented == 0 && inverted == 0 && index_errors == 0;
  }
};

// progress(done, total) is called after each coarse element when given.
VerifyReport verify(const FineMesh& mesh, const std::function<void(Id, Id)>& progress = {});

// The same in parts (MPI ranks): each part checks its range of coarse
// elements (everything inside one element, and hashes of what it sees of
// each coarse face and edge); verify_finish merges the parts, matches faces
// and edges across parts, and does the global checks (closed formula, page
// index, boundary, coincident nodes). verify() is one part + finish.
struct VerifyPart {
  VerifyReport report;                                       // per-element findings of the part
  std::vector<std::array<std::uint64_t, 3>> face_sides;      // (face, fine faces seen, hash) per side seen
  std::vector<std::array<std::uint64_t, 3>> edge_hashes;     // (edge, hash of its fine nodes, 1 if uses disagreed)
  std::vector<std::array<std::int64_t, 3>> edge_uses;        // surface: (edge, quads, direction sum)
};
VerifyPart verify_part(const FineMesh& mesh, Id first_coarse, Id end_coarse,
                       const std::function<void(Id, Id)>& progress = {});
VerifyReport verify_finish(const FineMesh& mesh, const std::vector<VerifyPart>& parts);

}  // namespace dicer
