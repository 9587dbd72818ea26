// Point location (locate.hpp): box tree -> group bounds rows -> corner map
// -> fine cell.
#include "dicer/locate.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <new>
#include <thread>

#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/numbering.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"
#include "dicer/tfi.hpp"

namespace dicer {

using P3 = std::array<double, 3>;
using Corners = std::array<P3, 8>;
using Quad = std::array<P3, 4>;

namespace {

// The multilinear map of N = 8 (HEX8) or 4 (QUAD4) corners at xi.
template <size_t N>
P3 corner_map(const std::array<P3, N>& x, const P3& xi) {
  P3 out{0, 0, 0};
  for (size_t q = 0; q < N; ++q) {
    double w = 1;
    for (int d = 0; d < (N == 8 ? 3 : 2); ++d) w *= kHexCorner[q][d] ? xi[d] : 1 - xi[d];
    for (int d = 0; d < 3; ++d) out[d] += w * x[q][d];
  }
  return out;
}

}  // namespace

P3 trilinear(const Corners& x, const P3& xi) { return corner_map(x, xi); }
P3 bilinear(const Quad& x, const P3& xi) { return corner_map(x, xi); }

namespace {

template <size_t N>
double size_of(const std::array<P3, N>& x) {
  double s = 0;
  for (size_t q = 1; q < N; ++q)
    for (int d = 0; d < 3; ++d) s = std::max(s, std::abs(x[q][d] - x[0][d]));
  return s;
}

// Newton on the trilinear map: xi with map(xi) = p, false when it does not
// converge (degenerate or far outside). The map minus p is written once as
// a polynomial in xi from corner differences: cheaper per iteration than
// the 8 shape functions, and its residual is computed about p, not about
// the origin (no cancellation of large coordinates).
bool invert(const Corners& x, const P3& p, P3& xi) {
  const double h = size_of(x);
  if (!(h > 0)) return false;
  // HEX8 corners at (i,j,k): 0 000, 1 100, 2 110, 3 010, 4 001, 5 101, 6 111, 7 011.
  double c[8][3];  // 1, a, b, c, ab, bc, ac, abc
  for (int d = 0; d < 3; ++d) {
    const double v000 = x[0][d], v100 = x[1][d], v110 = x[2][d], v010 = x[3][d];
    const double v001 = x[4][d], v101 = x[5][d], v111 = x[6][d], v011 = x[7][d];
    c[0][d] = v000 - p[d];
    c[1][d] = v100 - v000;
    c[2][d] = v010 - v000;
    c[3][d] = v001 - v000;
    c[4][d] = (v110 - v100) - (v010 - v000);
    c[5][d] = (v011 - v010) - (v001 - v000);
    c[6][d] = (v101 - v100) - (v001 - v000);
    c[7][d] = ((v111 - v110) - (v101 - v100)) - ((v011 - v010) - (v001 - v000));
  }
  auto residual = [&](const P3& s, double* r) {
    for (int d = 0; d < 3; ++d)
      r[d] = c[0][d] + c[1][d] * s[0] + c[2][d] * s[1] + c[3][d] * s[2] + c[4][d] * s[0] * s[1] +
             c[5][d] * s[1] * s[2] + c[6][d] * s[0] * s[2] + c[7][d] * s[0] * s[1] * s[2];
  };
  xi = {0.5, 0.5, 0.5};
  for (int it = 0; it < 40; ++it) {
    const double a = xi[0], b = xi[1], g = xi[2];
    double r[3], J[3][3];  // J[d][k] = dx_d / dxi_k
    residual(xi, r);
    for (int d = 0; d < 3; ++d) {
      J[d][0] = c[1][d] + c[4][d] * b + c[6][d] * g + c[7][d] * b * g;
      J[d][1] = c[2][d] + c[4][d] * a + c[5][d] * g + c[7][d] * a * g;
      J[d][2] = c[3][d] + c[5][d] * b + c[6][d] * a + c[7][d] * a * b;
    }
    // dx = J^-1 r by cofactors.
    const double A00 = J[1][1] * J[2][2] - J[1][2] * J[2][1], A01 = J[0][2] * J[2][1] - J[0][1] * J[2][2],
                 A02 = J[0][1] * J[1][2] - J[0][2] * J[1][1];
    const double A10 = J[1][2] * J[2][0] - J[1][0] * J[2][2], A11 = J[0][0] * J[2][2] - J[0][2] * J[2][0],
                 A12 = J[0][2] * J[1][0] - J[0][0] * J[1][2];
    const double A20 = J[1][0] * J[2][1] - J[1][1] * J[2][0], A21 = J[0][1] * J[2][0] - J[0][0] * J[2][1],
                 A22 = J[0][0] * J[1][1] - J[0][1] * J[1][0];
    const double det = J[0][0] * A00 + J[0][1] * A10 + J[0][2] * A20;
    if (!(std::abs(det) > 1e-300)) return false;
    const double dx[3] = {(A00 * r[0] + A01 * r[1] + A02 * r[2]) / det, (A10 * r[0] + A11 * r[1] + A12 * r[2]) / det,
                          (A20 * r[0] + A21 * r[1] + A22 * r[2]) / det};
    double step = 0;
    for (int k = 0; k < 3; ++k) xi[k] -= dx[k], step = std::max(step, std::abs(dx[k]));
    if (!std::isfinite(step) || step > 1e6) return false;
    // Quadratic convergence: the step after one of 1e-12 is below rounding.
    if (step < 1e-12) break;
  }
  double r[3];
  residual(xi, r);
  return std::max({std::abs(r[0]), std::abs(r[1]), std::abs(r[2])}) <= kLocateTolerance * h;
}

// One axis of a straight element: the corner map's parameter s -> the
// fine cell c holding it (`lower`: the one below, for a point on a shared
// plane) and xi in it. The fine cell's map is the corner map on [s_c,
// s_c+1] (TFI reproduces the corner map at the graded parameters): an
// affine change of parameter. Equal spacing: t = s n, xi = t - c.
struct AxisCell {
  Id c;
  double xi;
};
AxisCell axis_cell(const tfi::Series& S, double s, int lower) {
  const Id n = S.n();
  if (S.grading().kind == tfi::Spacing::Equal) {
    const double t = s * static_cast<double>(n);
    const Id c = std::clamp<Id>(static_cast<Id>(std::floor(t)), 0, n - 1) - lower;
    return {c, t - static_cast<double>(c)};
  }
  const Id c = S.cell(s) - lower;
  if (c < 0) return {c, 0};
  const double a = S.at(c), b = S.at(c + 1);
  return {c, (s - a) / (b - a)};
}

// The corners of fine cell c of a straight element (corner map x) graded
// by S: the corner map at the cell's parameter box, no fine node read.
template <size_t N>
std::array<P3, N> fine_corners(const std::array<P3, N>& x, const tfi::Series* S, const std::array<Id, 3>& c) {
  std::array<P3, N> out;
  for (size_t q = 0; q < N; ++q) {
    P3 s{0, 0, 0};
    for (int d = 0; d < (N == 8 ? 3 : 2); ++d) s[d] = S[d].at(c[d] + kHexCorner[q][d]);
    out[q] = corner_map(x, s);
  }
  return out;
}

bool inside(const P3& xi) {
  for (double v : xi)
    if (!(v >= -kLocateTolerance && v <= 1 + kLocateTolerance)) return false;
  return true;
}

// The nearest point of a bilinear patch (QUAD4 corners) to p: xi in
// [0,1]^2 and the squared distance. Inside: Newton on the gradient of
// |x(xi) - p|^2 / 2 (where its Hessian is positive definite); the border:
// the four edges, straight segments of the patch, exactly.
struct Nearest {
  P3 xi{};
  double d2 = INFINITY;
};

Nearest closest_bilinear(const Quad& x, const P3& p) {
  double c0[3], c1[3], c2[3], c3[3];  // x - p = c0 + c1 u + c2 v + c3 u v
  for (int d = 0; d < 3; ++d) {
    c0[d] = x[0][d] - p[d];
    c1[d] = x[1][d] - x[0][d];
    c2[d] = x[3][d] - x[0][d];
    c3[d] = (x[2][d] - x[1][d]) - (x[3][d] - x[0][d]);
  }
  Nearest best;
  auto consider = [&](double u, double v) {
    double d2 = 0;
    for (int d = 0; d < 3; ++d) {
      const double r = c0[d] + c1[d] * u + c2[d] * v + c3[d] * u * v;
      d2 += r * r;
    }
    if (d2 < best.d2) best = {{u, v, 0}, d2};
  };
  // Newton where the Hessian is positive definite, Gauss-Newton (its
  // J^T J part, a descent direction) where it is not (far from the patch
  // of a twisted quad), each step kept in [0,1]^2. Any point of the patch
  // is a valid candidate; the edges below catch a minimum on the border.
  double u = 0.5, v = 0.5;
  for (int it = 0; it < 40; ++it) {
    double g0 = 0, g1 = 0, huu = 0, huv = 0, hvv = 0, rc = 0;
    for (int d = 0; d < 3; ++d) {
      const double r = c0[d] + c1[d] * u + c2[d] * v + c3[d] * u * v, xu = c1[d] + c3[d] * v, xv = c2[d] + c3[d] * u;
      g0 += r * xu, g1 += r * xv;
      huu += xu * xu, hvv += xv * xv, huv += xu * xv, rc += r * c3[d];
    }
    double det = huu * hvv - (huv + rc) * (huv + rc);
    if (det > 0 && huu > 0) huv += rc;
    else det = huu * hvv - huv * huv;
    if (!(det > 0)) break;
    const double du = (hvv * g0 - huv * g1) / det, dv = (huu * g1 - huv * g0) / det;
    if (!std::isfinite(du) || !std::isfinite(dv)) break;
    const double un = std::clamp(u - du, 0.0, 1.0), vn = std::clamp(v - dv, 0.0, 1.0);
    const double step = std::max(std::abs(un - u), std::abs(vn - v));
    u = un, v = vn;
    if (step < 1e-12) break;
  }
  consider(u, v);
  // Edge from (u0, v0) to (u1, v1): the nearest point of a segment.
  auto edge = [&](double u0, double v0, double u1, double v1) {
    double ra[3], e[3], re = 0, ee = 0;
    for (int d = 0; d < 3; ++d) {
      ra[d] = c0[d] + c1[d] * u0 + c2[d] * v0 + c3[d] * u0 * v0;
      const double rb = c0[d] + c1[d] * u1 + c2[d] * v1 + c3[d] * u1 * v1;
      e[d] = rb - ra[d];
      re += ra[d] * e[d], ee += e[d] * e[d];
    }
    const double s = ee > 0 ? std::clamp(-re / ee, 0.0, 1.0) : 0.0;
    consider(u0 + s * (u1 - u0), v0 + s * (v1 - v0));
  };
  edge(0, 0, 1, 0), edge(0, 1, 1, 1), edge(0, 0, 0, 1), edge(1, 0, 1, 1);
  return best;
}

// Boxes (lo, hi) padded by kLocateTolerance of their largest extent or
// coordinate magnitude, the same pad as each element's bounds gets: a
// point an element's test accepts is inside every box above it.
double pad_of(const double* q) {
  double ext = 0;
  for (int d = 0; d < 3; ++d) ext = std::max({ext, q[3 + d] - q[d], std::abs(q[d]), std::abs(q[3 + d])});
  return kLocateTolerance * ext;
}

// Without branches (& on ints, not &&): scans test many boxes in a row,
// and which hold a random point is unpredictable.
bool holds(const double* q, const P3& p, double pad = 0) {
  const auto i = [](bool b) { return static_cast<unsigned>(b); };
  return i(p[0] >= q[0] - pad) & i(p[0] <= q[3] + pad) & i(p[1] >= q[1] - pad) & i(p[1] <= q[4] + pad) &
         i(p[2] >= q[2] - pad) & i(p[2] <= q[5] + pad);
}

double dist2(const double* q, const P3& p) {
  double s = 0;
  for (int d = 0; d < 3; ++d) {
    const double e = std::max({q[d] - p[d], 0.0, p[d] - q[3 + d]});
    s += e * e;
  }
  return s;
}

// A tree of boxes over the groups: level 0 holds the padded group boxes,
// level l + 1 the union of each kFan consecutive boxes of level l, up to a
// level of at most kFan boxes. Consecutive groups are neighbours along the
// store's space-filling-curve order, so the unions stay compact, and a
// walk of the children in order visits coarse elements in id order.
constexpr size_t kFan = 8;  // <= 32: a child mask fits an unsigned

struct Tree {
  std::vector<std::vector<double>> level;

  explicit Tree(const MeshTables& t) {
    const size_t G = t.group_bounds.size() / 6;
    std::vector<double> boxes(t.group_bounds);
    for (size_t g = 0; g < G; ++g) {
      double* q = &boxes[g * 6];
      for (int d = 0; d < 3; ++d)
        if (!std::isfinite(q[d]) || !std::isfinite(q[3 + d]) || q[d] > q[3 + d])
          throw Error(ErrorKind::Corrupt, (t.origin.empty() ? std::string("in memory") : t.origin) +
                                              ": index/group_bounds row " + std::to_string(g) +
                                              ": bounds not finite or lower above upper");
      const double pad = pad_of(q);
      for (int d = 0; d < 3; ++d) q[d] -= pad, q[3 + d] += pad;
    }
    level.push_back(std::move(boxes));
    while (level.back().size() / 6 > kFan) {
      const std::vector<double>& below = level.back();
      const size_t n = below.size() / 6, m = (n + kFan - 1) / kFan;
      std::vector<double> up(m * 6);
      for (size_t i = 0; i < m; ++i) {
        double* o = &up[i * 6];
        for (int d = 0; d < 3; ++d) o[d] = INFINITY, o[3 + d] = -INFINITY;
        for (size_t c = i * kFan; c < std::min(n, (i + 1) * kFan); ++c)
          for (int d = 0; d < 3; ++d) o[d] = std::min(o[d], below[c * 6 + d]), o[3 + d] = std::max(o[3 + d], below[c * 6 + 3 + d]);
      }
      level.push_back(std::move(up));
    }
  }
};

// No element found: a surface store's miss has no distance within reach,
// so it says so (infinity) rather than 0, which would read "on the surface".
Located missed(const FineMesh& mesh) {
  Located l;
  if (mesh.mode() == Mode::Surface) l.distance = INFINITY;
  return l;
}

struct Searcher {
  const FineMesh& mesh;
  const Tree& tree;
  double max_distance = INFINITY;
  MeshCursor cur;
  struct Queued {
    double d2;
    size_t level, index;
    bool operator>(const Queued& o) const { return d2 > o.d2; }
  };
  std::vector<Queued> heap;  // reused: no allocation per point once warm
  std::vector<std::pair<double, Id>> near;
  std::vector<std::uint8_t> checked;  // per group: bounds rows validated

  // Nodes of fine cell (i, j, k) of coarse element h (surface: the first 4,
  // k = 0): the grid points as their owners give them, as node(id) does.
  template <size_t N>
  std::array<P3, N> cell_nodes(Id h, const std::array<Id, 3>& c) {
    std::array<P3, N> x;
    for (size_t q = 0; q < N; ++q) {
      const Vec3 v = mesh.node(mesh.grid_node(h, c[0] + kHexCorner[q][0], c[1] + kHexCorner[q][1], c[2] + kHexCorner[q][2], cur), cur);
      x[q] = {v.x, v.y, v.z};
    }
    return x;
  }

  // --- volume: containment ---

  // The cell (i, j, k) of coarse element h contains p: xi of it.
  bool in_cell(Id h, const std::array<Id, 3>& c, const P3& p, P3& xi) {
    return invert(cell_nodes<8>(h, c), p, xi) && inside(xi);
  }

  // Lowest-id cell of coarse element h containing p.
  bool in_element(Id h, const P3& p, Located& out) {
    const RowReader R(mesh.tables(), cur);
    Vec3 v[8];
    R.corner_xyz(h, v);
    Corners x;
    for (int q = 0; q < 8; ++q) x[q] = {v[q].x, v[q].y, v[q].z};
    P3 g{0.5, 0.5, 0.5};
    const bool guessed = invert(x, p, g);
    // A straight element that does not hold the point: nothing more to read
    // (its grid and flag are a few fields of its row).
    const RowReader::Cells r = R.cells(h);
    const bool curved = r.curved;
    if (!curved && !(guessed && inside(g))) return false;
    const tfi::Series S[3] = {{r.n[0], r.grading[0]}, {r.n[1], r.grading[1]}, {r.n[2], r.grading[2]}};
    if (!curved) {
      // A straight element is its corners' trilinear map (TFI reproduces
      // it) and its cell (i, j, k) that map on [s_i, s_i+1] x ... (the
      // axes' graded parameters; equal: [i/n, (i+1)/n]): the cell and xi
      // follow from g without reading a fine node. Inside a valid straight
      // hex Newton converges; where it does not, the point is outside. The
      // lowest id: the lowest cell that holds the point. A graded cell's xi
      // is solved again on its own corners (precise however thin the cell).
      if (!guessed) return false;
      const bool graded = !(r.grading[0].kind == tfi::Spacing::Equal && r.grading[1].kind == tfi::Spacing::Equal &&
                            r.grading[2].kind == tfi::Spacing::Equal);
      Id best = -1;
      for (int mask = 0; mask < 8; ++mask) {
        std::array<Id, 3> c;
        P3 xi;
        bool ok = true;
        for (int d = 0; d < 3 && ok; ++d) {
          const AxisCell a = axis_cell(S[d], g[d], mask >> d & 1);
          c[d] = a.c, xi[d] = a.xi;
          ok = c[d] >= 0 && xi[d] >= -kLocateTolerance && xi[d] <= 1 + kLocateTolerance;
        }
        if (!ok) continue;
        const Id id = ids::element(r.element_first, r.n, c[0], c[1], c[2]);
        if (best >= 0 && id >= best) continue;
        if (graded)
          if (P3 fx; invert(fine_corners(x, S, c), p, fx)) xi = fx;
        best = id, out.xi = xi;
      }
      out.element = best;
      return best >= 0;
    }
    std::array<Id, 3> c;
    for (int d = 0; d < 3; ++d) c[d] = axis_cell(S[d], guessed ? g[d] : 0.5, 0).c;
    P3 xi;
    bool found = false;
    // Walk: a step towards the point along every direction it lies beyond.
    // Blocked: the point lies beyond a boundary cell's outer face (the
    // element's boundary, locally nearly flat at a fine cell's scale): it is
    // outside. The walk ends undecided only when a cell's map cannot be
    // inverted or the steps run out (a cycle).
    const Id steps = r.n[0] + r.n[1] + r.n[2] + 3;
    bool blocked = false;
    for (Id step = 0; step < steps; ++step) {
      if (!invert(cell_nodes<8>(h, c), p, xi)) break;
      if (inside(xi)) {
        found = true;
        break;
      }
      bool moved = false;
      for (int d = 0; d < 3; ++d) {
        if (xi[d] < -kLocateTolerance && c[d] > 0) --c[d], moved = true;
        else if (xi[d] > 1 + kLocateTolerance && c[d] < r.n[d] - 1) ++c[d], moved = true;
      }
      if (!moved) {
        blocked = true;
        break;
      }
    }
    if (!found && !blocked) {
      // Undecided: every cell, in id order.
      auto scan = [&] {
        for (Id k = 0; k < r.n[2]; ++k)
          for (Id j = 0; j < r.n[1]; ++j)
            for (Id i = 0; i < r.n[0]; ++i)
              if (c = {i, j, k}; in_cell(h, c, p, xi)) return true;
        return false;
      };
      found = scan();
    }
    if (!found) return false;
    // On a face, edge or node shared with lower cells of this element: the
    // lowest id among them (lower i, j or k is a lower id).
    Id best = ids::element(r.element_first, r.n, c[0], c[1], c[2]);
    P3 best_xi = xi;
    for (int mask = 1; mask < 8; ++mask) {
      std::array<Id, 3> c2 = c;
      bool ok = true;
      for (int d = 0; d < 3 && ok; ++d)
        if (mask >> d & 1) {
          if (c[d] == 0 || xi[d] > kLocateTolerance) ok = false;
          else --c2[d];
        }
      if (!ok) continue;
      P3 xi2;
      const Id id = ids::element(r.element_first, r.n, c2[0], c2[1], c2[2]);
      if (id < best && in_cell(h, c2, p, xi2)) best = id, best_xi = xi2;
    }
    out.element = best;
    out.xi = best_xi;
    return true;
  }

  // Coarse elements of group g in order (element ids grow with them, so
  // the first that contains p holds the lowest id).
  // The elements' boxes are tested with the group's pad, which is no less
  // than their own (a test a little looser: it only filters).
  bool scan_group(Id g, const P3& p, Located& out) {
    const RowReader R(mesh.tables(), cur);
    const Id end = std::min(mesh.num_coarse_elements(), (g + 1) * kBoundsGroup);
    const double pad = pad_of(&mesh.tables().group_bounds[static_cast<size_t>(g) * 6]);
    check_group(R, g);
    for (Id h = g * kBoundsGroup; h < end;) {
      const double* rows;
      const Id k = R.bounds_rows(h, end - h, rows, /*checked=*/true);
      static_assert(kBoundsGroup <= 64);
      std::uint64_t hit = 0;
      for (Id i = 0; i < k; ++i) hit |= std::uint64_t{holds(rows + 6 * i, p, pad)} << i;
      // `rows` may be unpinned by the elements' reads: only `hit` is used.
      for (; hit; hit &= hit - 1)
        if (in_element(h + std::countr_zero(hit), p, out)) return true;
      h += k;
    }
    return false;
  }

  // Validates group g's bounds rows the first time this searcher meets it:
  // a store is immutable, so a row re-read after its page left the cache is
  // the same bytes.
  void check_group(const RowReader& R, Id g) {
    if (checked.empty()) checked.assign(mesh.tables().group_bounds.size() / 6, 0);
    if (!checked[static_cast<size_t>(g)]) {
      const Id end = std::min(mesh.num_coarse_elements(), (g + 1) * kBoundsGroup);
      const double* rows;
      for (Id h = g * kBoundsGroup; h < end;) h += R.bounds_rows(h, end - h, rows);
      checked[static_cast<size_t>(g)] = 1;
    }
  }

  // Children of box `index` of level `l + 1` (the top: index 0), in order.
  bool descend(size_t l, size_t index, const P3& p, Located& out) {
    const std::vector<double>& L = tree.level[l];
    const size_t first = index * kFan, last = std::min(L.size() / 6, first + kFan);
    unsigned hit = 0;
    for (size_t c = first; c < last; ++c) hit |= unsigned{holds(&L[c * 6], p)} << (c - first);
    for (; hit; hit &= hit - 1) {
      const size_t c = first + static_cast<size_t>(std::countr_zero(hit));
      if (l == 0 ? scan_group(static_cast<Id>(c), p, out) : descend(l - 1, c, p, out)) return true;
    }
    return false;
  }

  // --- surface: nearest ---

  // Offer element `id` at distance d: nearer by more than the tolerance, or
  // as near with a lower id.
  static void offer(Located& best, Id id, const P3& xi, double d, double tol) {
    if (best.element < 0 || d < best.distance - tol || (d <= best.distance + tol && id < best.element))
      best.element = id, best.xi = xi, best.distance = d;
  }

  double bound(const Located& best) const { return best.element < 0 ? max_distance : std::min(max_distance, best.distance); }

  void nearest_in_element(Id h, const P3& p, Located& best) {
    const RowReader R(mesh.tables(), cur);
    Vec3 v[4];
    R.corner_xyz(h, v);
    Quad x;
    for (int q = 0; q < 4; ++q) x[q] = {v[q].x, v[q].y, v[q].z};
    const double tol = kLocateTolerance * size_of(x);
    const Nearest g = closest_bilinear(x, p);
    const double limit = bound(best) + tol;
    // A straight quad farther than the answer: no row to decode.
    const RowReader::Cells r = R.cells(h);
    const bool curved = r.curved;
    if (!curved && !(std::sqrt(g.d2) <= limit)) return;
    const tfi::Series S[2] = {{r.n[0], r.grading[0]}, {r.n[1], r.grading[1]}};
    if (!curved) {
      // A straight quad is its corners' bilinear map, cell (i, j) that map
      // on [s_i, s_i+1] x [s_j, s_j+1] (the graded parameters): the cell
      // from g, no fine node read; on a line shared with lower cells, the
      // lowest of them. A graded cell's xi is solved again on its corners.
      const double d = std::sqrt(g.d2);
      if (!(d <= limit)) return;
      const bool graded = !(r.grading[0].kind == tfi::Spacing::Equal && r.grading[1].kind == tfi::Spacing::Equal);
      for (int mask = 3; mask >= 0; --mask) {  // higher masks: lower ids first
        std::array<Id, 3> c{0, 0, 0};
        P3 xi{0, 0, 0};
        bool ok = true;
        for (int k = 0; k < 2 && ok; ++k) {
          const AxisCell a = axis_cell(S[k], g.xi[k], mask >> k & 1);
          c[k] = a.c, xi[k] = std::clamp(a.xi, 0.0, 1.0);
          ok = c[k] >= 0 && a.xi <= 1 + kLocateTolerance;
        }
        if (!ok || !(d <= max_distance)) continue;
        if (graded) xi = closest_bilinear(fine_corners(x, S, c), p).xi;
        offer(best, ids::element(r.element_first, r.n, c[0], c[1], 0), xi, d, tol);
      }
      return;
    }
    // Curved: every cell. The distance over a curved element's cells has
    // more than one local minimum, so a walk from the coarse patch's guess
    // could stop in the wrong one (5 of 300 random points on a QUAD9 store
    // got a quad up to 3e-3 farther than the nearest, stop 55). A cell is
    // skipped when the box of its four nodes is farther than the answer so
    // far (a bilinear cell lies in its nodes' convex hull); the element's
    // nodes are filled once and kept for the next point, O(n^2) memory, as
    // a surface export holds.
    const Way& w = element_nodes(h, r.n);
    const FineBlock& b = w.block;
    auto scan_row = [&](Id j) {
      for (Id i = 0; i < r.n[0]; ++i) {
        Quad q;
        double box[6] = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
        for (int k = 0; k < 4; ++k) {
          const Id g = b.point_index(i + kHexCorner[k][0], j + kHexCorner[k][1], 0);
          q[k] = {b.x[g], b.y[g], b.z[g]};
          for (int d = 0; d < 3; ++d) box[d] = std::min(box[d], q[k][d]), box[3 + d] = std::max(box[3 + d], q[k][d]);
        }
        const double reach = bound(best) + tol;
        if (!(std::sqrt(dist2(box, p)) <= reach)) continue;
        const Nearest near = closest_bilinear(q, p);
        const double d = std::sqrt(near.d2);
        if (d <= reach && d <= max_distance) offer(best, ids::element(r.element_first, r.n, i, j, 0), near.xi, d, tol);
      }
    };
    // The row of cells whose box is nearest first (a close answer prunes
    // the rest), then every row whose box is within reach, in id order.
    Id first = 0;
    double first_d2 = INFINITY;
    for (Id j = 0; j < r.n[1]; ++j)
      if (const double d2 = dist2(&w.row_box[static_cast<size_t>(j) * 6], p); d2 < first_d2) first = j, first_d2 = d2;
    scan_row(first);
    for (Id j = 0; j < r.n[1]; ++j)
      if (j != first && std::sqrt(dist2(&w.row_box[static_cast<size_t>(j) * 6], p)) <= bound(best) + tol) scan_row(j);
  }

  // Curved quads' nodes, the last few filled: a point near a coarse edge
  // or vertex has two to four candidates, and a stream of nearby points
  // meets the same ones. The other ways are given up when keeping them
  // would pass 64 MiB. Each refused by name when it cannot fit.
  static constexpr int kWays = 4;
  struct Way {
    FineBlock block;
    std::vector<double> row_box;  // per row j of cells: the box of grid rows j and j + 1
    Id element = -1;
    std::uint64_t used = 0;
  };
  std::array<Way, kWays> ways;
  std::uint64_t clock = 0;
  const Way& element_nodes(Id h, const std::array<Id, 3>& n) {
    for (Way& w : ways)
      if (w.element == h) {
        w.used = ++clock;
        return w;
      }
    Way* w = &ways[0];
    for (Way& x : ways)
      if (x.used < w->used) w = &x;
    w->element = -1;
    const char* how = "is searched whole by point location (a curved quad)";
    // fill_slab's measure (for_each_slab): 32 B a point, 56 B a boundary
    // point, and every point of a quad is one.
    const double need = 88.0 * static_cast<double>(n[0] + 1) * static_cast<double>(n[1] + 1) + 48.0 * static_cast<double>(n[1]);
    double others = 0;
    for (const Way& x : ways)
      if (&x != w) others += static_cast<double>(x.block.held_bytes());
    if (others + need > double(64u << 20))
      for (Way& x : ways)
        if (&x != w) x = Way{};
    check_element_memory(mesh, h, n, how, need, static_cast<double>(w->block.held_bytes()));
    try {
      mesh.fill_block(h, w->block, /*nodes_only=*/true);
    } catch (const std::bad_alloc&) {
      w->block = FineBlock{};
      if (need < double(1u << 28)) throw;  // a small element: memory ran out elsewhere
      throw element_too_big(mesh, h, n, how, need);
    }
    const FineBlock& b = w->block;
    w->row_box.assign(static_cast<size_t>(n[1]) * 6, 0.0);
    for (Id j = 0; j < n[1]; ++j) {
      double* box = &w->row_box[static_cast<size_t>(j) * 6];
      for (int d = 0; d < 3; ++d) box[d] = INFINITY, box[3 + d] = -INFINITY;
      for (Id jj = j; jj <= j + 1; ++jj)
        for (Id i = 0; i <= n[0]; ++i) {
          const Id g = b.point_index(i, jj, 0);
          const double x[3] = {b.x[g], b.y[g], b.z[g]};
          for (int d = 0; d < 3; ++d) box[d] = std::min(box[d], x[d]), box[3 + d] = std::max(box[3 + d], x[d]);
        }
    }
    w->element = h, w->used = ++clock;
    return *w;
  }

  // The group's elements nearest box first, while a box is nearer than
  // the answer (its pad, 2x the group's, no less than any element's: a
  // filter a little looser than exact).
  void nearest_in_group(Id g, const P3& p, Located& best) {
    const RowReader R(mesh.tables(), cur);
    const Id end = std::min(mesh.num_coarse_elements(), (g + 1) * kBoundsGroup);
    const double pad = 2 * pad_of(&mesh.tables().group_bounds[static_cast<size_t>(g) * 6]);
    near.clear();
    check_group(R, g);
    for (Id h = g * kBoundsGroup; h < end;) {
      const double* rows;
      const Id k = R.bounds_rows(h, end - h, rows, /*checked=*/true);
      const double lim = bound(best) + pad, lim2 = lim * lim;
      for (Id i = 0; i < k; ++i)
        if (const double d2 = dist2(rows + 6 * i, p); d2 <= lim2) near.push_back({d2, h + i});
      h += k;
    }
    std::sort(near.begin(), near.end());
    for (const auto& [d2, h] : near) {
      const double lim = bound(best) + pad;
      if (d2 > lim * lim) break;
      nearest_in_element(h, p, best);
    }
  }

  Located nearest(const P3& p) {
    Located best;
    heap.clear();
    const size_t top = tree.level.size() - 1;
    auto push = [&](size_t l, size_t i) {
      const double d2 = dist2(&tree.level[l][i * 6], p), lim = bound(best);
      if (d2 <= lim * lim) heap.push_back({d2, l, i}), std::push_heap(heap.begin(), heap.end(), std::greater<>());
    };
    for (size_t i = 0; i < tree.level[top].size() / 6; ++i) push(top, i);
    while (!heap.empty()) {
      std::pop_heap(heap.begin(), heap.end(), std::greater<>());
      const Queued q = heap.back();
      heap.pop_back();
      const double lim = bound(best);
      if (q.d2 > lim * lim) break;  // every box left is farther than the answer
      if (q.level == 0) {
        nearest_in_group(static_cast<Id>(q.index), p, best);
      } else {
        const size_t n = tree.level[q.level - 1].size() / 6;
        for (size_t c = q.index * kFan; c < std::min(n, (q.index + 1) * kFan); ++c) push(q.level - 1, c);
      }
    }
    return best.element < 0 ? missed(mesh) : best;
  }

  Located locate(const P3& p) {
    if (mesh.mode() == Mode::Surface) return nearest(p);
    Located out;
    if (descend(tree.level.size() - 1, 0, p, out)) return out;
    return Located{};
  }
};

void require_index(const FineMesh& mesh, double max_distance) {
  if (!(max_distance >= 0)) throw Error(ErrorKind::Usage, "point location: the maximum distance must be 0 or more");
  if (mesh.mode() == Mode::Volume && max_distance != INFINITY)  // as the command line refuses --max-distance
    throw Error(ErrorKind::Usage, "point location: a maximum distance is for surface stores; " +
                                      (mesh.tables().origin.empty() ? std::string("the mesh") : mesh.tables().origin) +
                                      " is a volume store, where a point is in the element that contains it or in none");
  const size_t groups = static_cast<size_t>((mesh.num_coarse_elements() + kBoundsGroup - 1) / kBoundsGroup);
  if (mesh.tables().group_bounds.size() != groups * 6)
    throw Error(ErrorKind::Corrupt, "the spatial index does not have one box per group of coarse elements");
}

}  // namespace

Located locate_point(const FineMesh& mesh, const std::array<double, 3>& p, double max_distance) {
  require_index(mesh, max_distance);
  if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
    throw Error(ErrorKind::Usage, "point location: the point has a coordinate that is not finite");
  if (mesh.num_coarse_elements() == 0) return missed(mesh);
  const Tree tree(mesh.tables());
  Searcher s{mesh, tree, max_distance, {}, {}, {}, {}, {}, 0};
  return s.locate(p);
}

std::vector<Located> locate_points(const FineMesh& mesh, const std::vector<double>& xyz, int threads, double max_distance) {
  require_index(mesh, max_distance);
  if (xyz.size() % 3 != 0) throw Error(ErrorKind::Usage, "locate_points: coordinates are not a multiple of 3");
  // A NaN point would come back "outside" (-1), indistinguishable from a
  // real miss.
  for (size_t i = 0; i < xyz.size(); ++i)
    if (!std::isfinite(xyz[i]))
      throw Error(ErrorKind::Usage, "point location: point " + std::to_string(i / 3) + " has a coordinate that is not finite");
  const size_t n = xyz.size() / 3;
  std::vector<Located> out(n, missed(mesh));
  if (mesh.num_coarse_elements() == 0) return out;
  threads = std::max(1, std::min<int>(threads, static_cast<int>(std::max<size_t>(1, n / 64))));
  const Tree tree(mesh.tables());
  auto work = [&](size_t first, size_t end) {
    Searcher s{mesh, tree, max_distance, {}, {}, {}, {}, {}, 0};
    for (size_t i = first; i < end; ++i) out[i] = s.locate({xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]});
  };
  if (threads == 1) {
    work(0, n);
    return out;
  }
  std::vector<std::thread> pool;
  std::vector<std::exception_ptr> errors(static_cast<size_t>(threads));
  for (int k = 0; k < threads; ++k)
    pool.emplace_back([&, k] {
      try {
        work(n * k / threads, n * (k + 1) / threads);
      } catch (...) {
        errors[k] = std::current_exception();
      }
    });
  for (auto& th : pool) th.join();
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
  return out;
}

}  // namespace dicer
