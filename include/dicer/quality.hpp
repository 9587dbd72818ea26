#pragma once
// Element quality of the fine mesh: the scaled Jacobian, streamed block by
// block so it never needs more than one coarse element's fine nodes.
//
// The one definition of element quality (verify, dice --geometry and the
// benchmarks call these). Scaled Jacobian of a hex: the minimum over its 8
// corners of det(e1, e2, e3) / (|e1| |e2| |e3|) with e1..e3 the corner's
// three edges in right-handed order (1 for a cube, <= 0 when the element
// is inverted, 0 when an edge has collapsed). Of a quad (surface mode): the
// minimum over its 4 corners of the corner normal (e1 x e2) / (|e1| |e2|)
// projected on a reference unit normal: the coarse quad's (so a fine quad
// folded over against its coarse element is <= 0), or, without one, the
// quad's own mean normal.
#include <functional>

#include "dicer/fine_mesh.hpp"

namespace dicer {

double hex_scaled_jacobian(const Vec3 (&p)[8]);  // VTK/Exodus HEX8 corner order
double quad_scaled_jacobian(const Vec3 (&p)[4]);
double quad_scaled_jacobian(const Vec3 (&p)[4], const Vec3& normal);
// Normal of a coarse quad (the cross product of its diagonals, not unit)
// from the corner points of a block (surface mode).
Vec3 block_normal(const FineBlock& b);
// Scaled Jacobian of fine element (i, j, k) of a filled block (surface
// mode: against `normal`, block_normal(b)).
double element_scaled_jacobian(const FineBlock& b, Id i, Id j, Id k, const Vec3& normal);

struct QualityReport {
  double min_scaled_jacobian = 1.0;
  Id worst_element = -1;         // fine element id where the minimum is
  Id worst_coarse_element = -1;  // its coarse element (file id in messages comes from the row)
  Id inverted = 0;               // fine elements with scaled Jacobian <= 0
  Id elements_checked = 0;
};

// Folds b into a: what one check over the elements of both gives (counts
// summed; the minimum, and at equal minima the lower fine element id, as a
// single pass in id order keeps the first). For checks shared out over
// processes (ConformOptions::parts).
void merge_quality(QualityReport& a, const QualityReport& b);

// Checks every fine element of the coarse elements h with select(h) true
// (all when select is empty). progress(done, total) in coarse elements.
QualityReport check_quality(const FineMesh& mesh, const std::function<bool(Id)>& select = {},
                            const std::function<void(Id, Id)>& progress = {});
// The elements moved nodes can invert: every fine element of the coarse
// elements with moved nodes (ElementRow::curved; after finish_moves). What
// dice --geometry and second-order input (quadratic.hpp) check before they
// accept their moves.
QualityReport check_moved_quality(const FineMesh& mesh, const std::function<void(Id, Id)>& progress = {});

}  // namespace dicer
