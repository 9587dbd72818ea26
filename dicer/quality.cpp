// Scaled Jacobians of fine elements, one coarse element's block at a time.
#include "dicer/quality.hpp"

#include <algorithm>
#include <cmath>

#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"

namespace dicer {
namespace {

Vec3 sub(const Vec3& a, const Vec3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
Vec3 cross(const Vec3& a, const Vec3& b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }
// a / |a| without squaring a first (its squares under- or overflow at
// scales such as 1e-110 or 1e160); zero for a zero vector.
Vec3 unit(const Vec3& a) {
  const double s = std::max({std::fabs(a.x), std::fabs(a.y), std::fabs(a.z)});
  if (!(s > 0) || !std::isfinite(s)) return {0, 0, 0};
  const Vec3 b{a.x / s, a.y / s, a.z / s};
  const double n = norm(b);
  return {b.x / n, b.y / n, b.z / n};
}
// Where the plain products are safe: the lengths' product well inside the
// range of doubles (the product of three lengths, or of two and a normal's).
bool in_range(double l) { return l > 1e-250 && l < 1e250; }

}  // namespace

double hex_scaled_jacobian(const Vec3 (&p)[8]) {
  double worst = 1.0;
  for (int c = 0; c < 8; ++c) {
    // kHexCornerNbr: the corner's three neighbours in right-handed order.
    const Vec3 e1 = sub(p[kHexCornerNbr[c][0]], p[c]), e2 = sub(p[kHexCornerNbr[c][1]], p[c]),
               e3 = sub(p[kHexCornerNbr[c][2]], p[c]);
    const double l = norm(e1) * norm(e2) * norm(e3);
    // A collapsed edge counts as degenerate (unit() gives it length 0), and
    // so does a corner that is not finite (NaN: l != l).
    const double j = in_range(l) ? dot(cross(e1, e2), e3) / l
                     : l == l    ? dot(cross(unit(e1), unit(e2)), unit(e3))
                                 : 0.0;
    worst = std::min(worst, j);
  }
  return worst;
}

double quad_scaled_jacobian(const Vec3 (&p)[4], const Vec3& normal) {
  const double ln = norm(normal);
  // A normal too small to square (ln 0) is still one; NaN is none.
  if (!(ln >= 0) || (normal.x == 0 && normal.y == 0 && normal.z == 0)) return 0.0;
  double worst = 1.0;
  for (int k = 0; k < 4; ++k) {
    const Vec3 e1 = sub(p[(k + 1) % 4], p[k]), e2 = sub(p[(k + 3) % 4], p[k]);
    const double l = norm(e1) * norm(e2) * ln;
    worst = std::min(worst, in_range(l) ? dot(cross(e1, e2), normal) / l
                            : l == l    ? dot(cross(unit(e1), unit(e2)), unit(normal))
                                        : 0.0);
  }
  return worst;
}

double quad_scaled_jacobian(const Vec3 (&p)[4]) {
  Vec3 n{0, 0, 0};
  for (int k = 0; k < 4; ++k) {
    const Vec3 e1 = sub(p[(k + 1) % 4], p[k]), e2 = sub(p[(k + 3) % 4], p[k]);
    const double l = norm(e1) * norm(e2);
    if (in_range(l)) {
      const Vec3 c = cross(e1, e2);
      n = {n.x + c.x / l, n.y + c.y / l, n.z + c.z / l};
    } else {
      const Vec3 c = cross(unit(e1), unit(e2));
      n = {n.x + c.x, n.y + c.y, n.z + c.z};
    }
  }
  return quad_scaled_jacobian(p, n);
}

Vec3 block_normal(const FineBlock& b) {
  auto corner = [&](Id i, Id j) {
    const Id g = b.point_index(i, j, 0);
    return Vec3{b.x[g], b.y[g], b.z[g]};
  };
  const Vec3 a = corner(0, 0), q1 = corner(b.n[0], 0), q2 = corner(b.n[0], b.n[1]), q3 = corner(0, b.n[1]);
  return cross(sub(q2, a), sub(q3, q1));
}

double element_scaled_jacobian(const FineBlock& b, Id i, Id j, Id k, const Vec3& normal) {
  if (b.planes > 1) {  // a volume block holds at least two planes
    Vec3 p[8];
    for (int c = 0; c < 8; ++c) {
      const Id g = b.point_index(i + kHexCorner[c][0], j + kHexCorner[c][1], k + kHexCorner[c][2]);
      p[c] = {b.x[g], b.y[g], b.z[g]};
    }
    return hex_scaled_jacobian(p);
  }
  Vec3 p[4];
  for (int c = 0; c < 4; ++c) {
    const Id g = b.point_index(i + kHexCorner[c][0], j + kHexCorner[c][1], 0);
    p[c] = {b.x[g], b.y[g], b.z[g]};
  }
  return quad_scaled_jacobian(p, normal);
}

QualityReport check_quality(const FineMesh& mesh, const std::function<bool(Id)>& select,
                            const std::function<void(Id, Id)>& progress) {
  QualityReport r;
  FineBlock b;
  const Id H = mesh.num_coarse_elements();
  const bool vol = mesh.mode() == Mode::Volume;
  for (Id h = 0; h < H; ++h) {
    if (progress && (h & 63) == 0) progress(h, H);
    if (select && !select(h)) continue;
    mesh.for_each_slab(h, b, false, [&](const FineBlock& s) {  // O(n^2) held, not the element
      const Vec3 normal = vol ? Vec3{} : block_normal(s);
      const Id ne = s.num_elements();
      for (Id e = 0; e < ne; ++e) {
        const Id i = e % s.n[0], j = (e / s.n[0]) % s.n[1], k = s.plane0 + e / (s.n[0] * s.n[1]);
        const double q = element_scaled_jacobian(s, i, j, k, normal);
        ++r.elements_checked;
        if (!(q > 0)) ++r.inverted;
        if (q < r.min_scaled_jacobian || r.worst_element < 0) {
          r.min_scaled_jacobian = std::min(r.min_scaled_jacobian, q);
          r.worst_element = s.first_element + e, r.worst_coarse_element = h;
        }
      }
    });
  }
  if (progress) progress(H, H);
  return r;
}

void merge_quality(QualityReport& a, const QualityReport& b) {
  a.elements_checked += b.elements_checked;
  a.inverted += b.inverted;
  if (b.worst_element < 0) return;
  if (a.worst_element < 0 || b.min_scaled_jacobian < a.min_scaled_jacobian ||
      (b.min_scaled_jacobian == a.min_scaled_jacobian && b.worst_element < a.worst_element)) {
    a.min_scaled_jacobian = b.min_scaled_jacobian;
    a.worst_element = b.worst_element, a.worst_coarse_element = b.worst_coarse_element;
  }
}

QualityReport check_moved_quality(const FineMesh& mesh, const std::function<void(Id, Id)>& progress) {
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  return check_quality(mesh, [&](Id h) { return R.element(h).curved(); }, progress);
}

}  // namespace dicer
