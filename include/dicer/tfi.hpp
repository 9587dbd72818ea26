#pragma once
// Transfinite interpolation: the only definition of where a fine node is.
//
// Each function works on one coordinate in the owning entity's canonical
// frame (DESIGN.md invariant 2). Block fills, node(id) and every exporter
// call these same inline functions with the same inputs, and the build turns
// off floating-point contraction, so every path gives bit-identical results.
// Weights along an edge are its grid parameters (Series below: t/n computed
// as double(t) / double(n) when equally spaced), complements 1 - s.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

namespace dicer::tfi {

inline double weight(std::int64_t t, std::int64_t n) { return static_cast<double>(t) / static_cast<double>(n); }

// ---------------------------------------------------------------- grading
//
// Where grid index t of an edge of interval n sits: its parameter s_t in
// [0, 1] (s_0 = 0, s_n = 1). Series::at() is the only definition; every
// path (edge, face and hex TFI, block fills, node(id), the CAD moves, point
// location) asks it, so a graded node has the same bits on every path.
//
//  - Equal: s_t = double(t) / double(n), exactly weight(t, n) (ungraded
//    stores keep their bits).
//  - Geometric, ratio R (CUBIT's bias, Gmsh's Progression): fine edge
//    lengths h, hR, hR^2, ... from the start, s_t = (R^t - 1) / (R^n - 1);
//    `flip`: the series starts at t = n, s_t = 1 - s'_(n-t).
//  - Dual, ratio R (CUBIT's dualbias): the same series from both ends to
//    the middle: lengths h, hR, ..., hR^(c-1) then mirrored, where the
//    middle cell of an odd n is hR^f (f = floor(n/2), c = ceil(n/2)):
//    s_t = (R^t - 1) / (R^c + R^f - 2) for 2t < n, s_(n/2) = 1/2,
//    s_t = 1 - s_(n-t) above. R > 1 is fine at both ends, R < 1 in the middle.
//
// Every graded parameter is rounded to a multiple of 2^-53 (1 - (1 - x)),
// so 1 - s is exact: a flipped series is the mirror of the other bit for
// bit, and a dual series is symmetric bit for bit (s_(n-t) == 1 - s_t).
// Computed with the C library's exp, expm1 and log in a form that neither
// overflows nor cancels (R^t never formed): bit-identical within one build
// and C library, the scope of invariant 2 (every path, thread and rank of
// one installation).
//
// A grading is well formed (grading_ok: what a reader checks, O(1)) when
// its ratio is finite in [1/kMaxRatio, kMaxRatio] and not 1 (equal
// spacing is Equal, ratio 1), and flip is set only on a geometric series;
// every such series is finite and non-decreasing. Dicing also asks that
// its smallest cell at the sheet's interval (Series::smallest_cell) be at
// least kMinCell of the edge: the finest cell equal spacing allows at the
// interval limit, far above the 2^-53 rounding, so cells stay positive.
// Cost: a Series costs one log to make; at() one exp and two expm1 when
// graded, one division when equal. Fills build one per axis and edge per
// block; node(id) one per axis.
enum class Spacing : std::uint8_t { Equal = 0, Geometric = 1, Dual = 2 };

struct Grading {
  Spacing kind = Spacing::Equal;
  bool flip = false;   // geometric: the series starts at t = n
  double ratio = 1;    // R: a cell's length over the previous one's, going away from the start (ends)
  friend bool operator==(const Grading&, const Grading&) = default;
};

inline constexpr double kMaxRatio = 100;
inline constexpr double kMinCell = 0x1p-40;

// The same series seen from the other end of the edge.
inline Grading reversed(Grading g) {
  if (g.kind == Spacing::Geometric) g.flip = !g.flip;
  return g;
}

class Series {
 public:
  Series(std::int64_t n, const Grading& g) : n_(n), g_(g) {
    if (g.kind == Spacing::Equal) return;
    L_ = std::log(g.ratio);
    if (g.kind == Spacing::Dual) c_ = (n + 1) / 2, f_ = n / 2, mid_ = 1.0 + fraction(f_, c_);
  }
  std::int64_t n() const { return n_; }
  const Grading& grading() const { return g_; }

  double at(std::int64_t t) const {
    if (g_.kind == Spacing::Equal) return weight(t, n_);
    if (t <= 0) return 0.0;
    if (t >= n_) return 1.0;
    if (g_.kind == Spacing::Geometric) return g_.flip ? 1.0 - snap(fraction(n_ - t, n_)) : snap(fraction(t, n_));
    if (2 * t == n_) return 0.5;
    return 2 * t < n_ ? snap(fraction(t, c_) / mid_) : 1.0 - snap(fraction(n_ - t, c_) / mid_);
  }

  // The cell c in [0, n) with at(c) <= s < at(c + 1) (s below 0: 0; at or
  // above 1: n - 1). O(1) from the closed-form inverse, checked against at().
  std::int64_t cell(double s) const {
    if (!(s > 0)) return 0;
    if (!(s < 1)) return n_ - 1;
    const double x = inverse(s);
    std::int64_t c = x >= 0 && x < static_cast<double>(n_) ? static_cast<std::int64_t>(x) : x >= 0 ? n_ - 1 : 0;
    for (int step = 0; step < 64; ++step) {
      if (at(c) > s) --c;
      else if (at(c + 1) <= s) ++c;
      else return c;
    }
    std::int64_t lo = 0, hi = n_;  // at(lo) <= s < at(hi): bisection (never needed in practice)
    while (hi - lo > 1) {
      const std::int64_t m = lo + (hi - lo) / 2;
      (at(m) <= s ? lo : hi) = m;
    }
    return lo;
  }

  // The shortest cell, as a fraction of the edge (the series is monotone
  // from each end: the shortest is at an end or in the middle).
  double smallest_cell() const {
    double m = 1;
    for (const std::int64_t t : {std::int64_t{1}, n_, n_ / 2, n_ / 2 + 1})
      if (t >= 1 && t <= n_) m = std::min(m, at(t) - at(t - 1));
    return m;
  }

 private:
  static double snap(double x) { return 1.0 - (1.0 - x); }
  // (R^t - 1) / (R^m - 1), 0 <= t <= m, R = e^L != 1.
  double fraction(std::int64_t t, std::int64_t m) const {
    const double a = static_cast<double>(t), b = static_cast<double>(m);
    if (L_ < 0) return std::expm1(a * L_) / std::expm1(b * L_);
    return std::exp((a - b) * L_) * (std::expm1(-a * L_) / std::expm1(-b * L_));
  }
  // t with fraction(t, m) = q.
  double unfraction(double q, std::int64_t m) const {
    const double b = static_cast<double>(m);
    if (L_ < 0) return std::log1p(q * std::expm1(b * L_)) / L_;
    return b + std::log1p((1.0 - q) * std::expm1(-b * L_)) / L_;
  }
  // A real t with at(t) ~ s, for cell().
  double inverse(double s) const {
    const double n = static_cast<double>(n_);
    if (g_.kind == Spacing::Equal) return s * n;
    if (g_.kind == Spacing::Geometric) return g_.flip ? n - unfraction(1.0 - s, n_) : unfraction(s, n_);
    return s <= 0.5 ? unfraction(s * mid_, c_) : n - unfraction((1.0 - s) * mid_, c_);
  }

  std::int64_t n_;
  Grading g_;
  double L_ = 0, mid_ = 1;
  std::int64_t c_ = 0, f_ = 0;
};

// Parameter of grid index t (0 <= t <= n): Series(n, g).at(t).
inline double param(std::int64_t t, std::int64_t n, const Grading& g) { return Series(n, g).at(t); }

inline bool grading_ok(const Grading& g) {
  switch (g.kind) {
    case Spacing::Equal: return g.ratio == 1.0 && !g.flip;
    case Spacing::Geometric: break;
    case Spacing::Dual:
      if (g.flip) return false;
      break;
    default: return false;
  }
  return g.ratio >= 1.0 / kMaxRatio && g.ratio <= kMaxRatio && g.ratio != 1.0;
}

// The point at parameter s on an edge from a (s = 0) to b (s = 1).
inline double edge(double a, double b, double s) { return (1.0 - s) * a + s * b; }

// Coons patch at (s, t) in [0,1]^2 from the four boundary values at the same
// parameters (bottom(s), top(s), left(t), right(t)) and the corners
// p0 = (0,0), p1 = (1,0), p2 = (1,1), p3 = (0,1): the interior of a face
// that is moved or has a moved side (a straight face's: bilinear_* below).
inline double coons(double s, double t, double bottom, double top, double left, double right, double p0,
                    double p1, double p2, double p3) {
  const double S = 1.0 - s, T = 1.0 - t;
  return (T * bottom + t * top) + (S * left + s * right) - ((S * T * p0 + s * T * p1) + (s * t * p2 + S * t * p3));
}

// Trilinear transfinite (Gordon-Hall) interpolation of a hex at (u, v, w):
// the usual sum of six face blends, minus twelve edge blends, plus eight
// corner blends, factored so a block does three multiplies and six adds
// per point and coordinate, a few per row and column, the rest per plane:
//
//   X  = (A + u D) + (P + v G) + (f4 + w (f5 - f4))
//   A  = (f0 - (W e4 + w e6)) + (a0 + v da),  B likewise from f1, e5, e7, b0, db;  D = B - A   row (j, k)
//   P  = f2 - (W e0 + w e2),  Q = f3 - (W e1 + w e3),  G = Q - P                           column (i, k)
//   a0 = (W c0 + w c4) - e8,  a1 = (W c3 + w c7) - e11,  da = a1 - a0                      plane k
//   b0 = (W c1 + w c5) - e9,  b1 = (W c2 + w c6) - e10,  db = b1 - b0
//
// with U = 1 - u, V = 1 - v, W = 1 - w: U A + u B = A + u D; the four
// i-edges' blends fold into the j-faces' (V f2 + v f3 - (VW e0 + vW e1 +
// Vw e2 + vw e3) = P + v G), and the k-edges' into the corners' (the
// i = 0 face's share V ((W c0 + w c4) - e8) + v ((W c3 + w c7) - e11)).
// Face values f0..f5 at the point's projections (faces i=0, i=1, j=0, j=1,
// k=0, k=1), edge values e0..e11 (orientation.hpp's kHexEdge order) at the
// point's parameter, corners c0..c7 (kHexCorner). Interior points only
// (0 < u, v, w < 1): the boundary is its entities' own. A curved hex's
// interior (a straight one's: trilinear_plane below). Every path calls
// these four with the same inputs, so the bits agree (contraction is off).
struct HexPlane {
  double w, W;            // plane k's weights
  double a0, da, b0, db;  // the corners and k-edges, folded
};
struct HexRow {
  double A, D;  // the i-independent parts of row (j, k)
};
struct HexColumn {
  double P, G;  // the j-independent parts of column (i, k)
};

// e: the four k-edges' values e8..e11 at w; c: corners c0..c7.
inline HexPlane hex_plane(double w, const double* e, const double* c) {
  HexPlane p;
  p.w = w, p.W = 1.0 - w;
  p.a0 = (p.W * c[0] + w * c[4]) - e[0];
  p.da = ((p.W * c[3] + w * c[7]) - e[3]) - p.a0;
  p.b0 = (p.W * c[1] + w * c[5]) - e[1];
  p.db = ((p.W * c[2] + w * c[6]) - e[2]) - p.b0;
  return p;
}

// f0, f1: the i = 0 and i = 1 faces at (v, w); e4..e7 the j-edges at v.
inline HexRow hex_row(const HexPlane& p, double v, double f0, double f1, double e4, double e5, double e6, double e7) {
  const double A = (f0 - (p.W * e4 + p.w * e6)) + (p.a0 + v * p.da);
  const double B = (f1 - (p.W * e5 + p.w * e7)) + (p.b0 + v * p.db);
  return {A, B - A};
}

// f2, f3: the j = 0 and j = 1 faces at (u, w); e0..e3 the i-edges at u.
inline HexColumn hex_column(const HexPlane& p, double f2, double f3, double e0, double e1, double e2, double e3) {
  const double P = f2 - (p.W * e0 + p.w * e2), Q = f3 - (p.W * e1 + p.w * e3);
  return {P, Q - P};
}

inline double hex_point(const HexRow& r, const HexColumn& c, double u, double v, double w, double f4, double f5) {
  return ((r.A + u * r.D) + (c.P + v * c.G)) + (f4 + w * (f5 - f4));
}

// Straight entities (since 0.5). A face whose four sides are straight and
// whose own nodes are not moved has the bilinear patch of its corners as
// its Coons patch (the side terms cancel the corner terms), and a straight
// hex (ElementRow::curved() false: every edge and face of it straight) the
// trilinear blend of its corners as its Boolean sum. Both are computed
// directly: one multiply and one add per point and coordinate instead of
// coons' twelve and nine, or the factored hex sum's three and six, and no
// side, edge or face value is read.
//
//   face:  X = A + s D,  A = T p0 + t p3,  D = (T p1 + t p2) - A           row t
//   hex:   q_k = W c_k + w c_(k+4) (k < 4), then the face form over q      plane w
//          with s = u, t = v
//
// p0..p3 as coons() orders them ((0,0), (1,0), (1,1), (0,1)); c0..c7
// kHexCorner, whose c0..c3 run the same way in (i, j) and c4..c7 lie above
// them. Interior points only. Every path (block fill, node(id), the
// evaluator) calls these with the same inputs, so the bits agree.
struct Bilinear {
  double A, D;  // row t's terms
};
inline Bilinear bilinear_row(double t, const double* p) {
  const double T = 1.0 - t;
  const double A = T * p[0] + t * p[3];
  return {A, (T * p[1] + t * p[2]) - A};
}
inline double bilinear_point(const Bilinear& r, double s) { return r.A + s * r.D; }
inline void trilinear_plane(double w, const double* c, double* q) {
  const double W = 1.0 - w;
  for (int k = 0; k < 4; ++k) q[k] = W * c[k] + w * c[k + 4];
}

// Bounding fine arrays (nodes moved onto the CAD or onto a second-order
// mesh's quadratic edges and faces) are stored as corrections
// to this recipe: the difference between the bit patterns of the moved value
// and of its TFI prediction (computed by the functions above from the already
// moved edges), zigzag-coded so small corrections of either sign have zero
// high bytes (which the store's byte shuffle + LZ4 then squeeze). Lossless by
// construction: integer arithmetic modulo 2^64 on the bits, and the reader
// recomputes the same prediction bit for bit.
inline std::int64_t bounding_code(double predicted, double moved) {
  const std::uint64_t d = std::bit_cast<std::uint64_t>(moved) - std::bit_cast<std::uint64_t>(predicted);
  const std::int64_t s = static_cast<std::int64_t>(d);
  return static_cast<std::int64_t>((d << 1) ^ static_cast<std::uint64_t>(s >> 63));
}
inline double bounding_apply(double predicted, std::int64_t code) {
  const std::uint64_t z = static_cast<std::uint64_t>(code);
  const std::uint64_t d = (z >> 1) ^ (0 - (z & 1));
  return std::bit_cast<double>(std::bit_cast<std::uint64_t>(predicted) + d);
}

}  // namespace dicer::tfi
