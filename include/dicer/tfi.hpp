#pragma once
// Transfinite interpolation: the only definition of where a fine node is.
//
// Each function works on one coordinate in the owning entity's canonical
// frame (DESIGN.md invariant 2). Block fills, node(id) and every exporter
// call these same inline functions with the same inputs, and the build turns
// off floating-point contraction, so every path gives bit-identical results.
// Weights are t/n computed as double(t) / double(n), complements as 1 - t/n.
#include <bit>
#include <cstdint>

namespace dicer::tfi {

inline double weight(std::int64_t t, std::int64_t n) { return static_cast<double>(t) / static_cast<double>(n); }

// Equal spacing on an edge from a (s = 0) to b (s = 1).
inline double edge(double a, double b, double s) { return (1.0 - s) * a + s * b; }

// Coons patch at (s, t) in [0,1]^2 from the four boundary values at the same
// parameters (bottom(s), top(s), left(t), right(t)) and the corners
// p0 = (0,0), p1 = (1,0), p2 = (1,1), p3 = (0,1).
inline double coons(double s, double t, double bottom, double top, double left, double right, double p0,
                    double p1, double p2, double p3) {
  const double S = 1.0 - s, T = 1.0 - t;
  return (T * bottom + t * top) + (S * left + s * right) - ((S * T * p0 + s * T * p1) + (s * t * p2 + S * t * p3));
}

// Trilinear transfinite (Gordon-Hall) interpolation of a hex at (u, v, w),
// written in two stages so a block can reuse the first along a row of i:
//
//   X = U A + u B + (V f2 + v f3) + (W f4 + w f5) - (VW e0 + vW e1 + Vw e2 + vw e3)
//   A = f0 - (W e4 + w e6) - (V e8 + v e11) + (VW c0 + vW c3 + Vw c4 + vw c7)
//   B = f1 - (W e5 + w e7) - (V e9 + v e10) + (VW c1 + vW c2 + Vw c5 + vw c6)
//
// which is the usual sum of six face blends, minus twelve edge blends, plus
// eight corner blends. Face values f0..f5 at the point's projections (faces
// i=0, i=1, j=0, j=1, k=0, k=1), edge values e0..e11 (orientation.hpp's
// kHexEdge order) at the point's parameter, corners c0..c7 (kHexCorner).
struct HexRow {
  double V, v, W, w, VW, vW, Vw, vw;  // weights of the row (j, k)
  double A, B;                        // the i-independent parts
};

inline HexRow hex_row(double v, double w, double f0, double f1, const double* e, const double* c) {
  HexRow r;
  r.v = v, r.w = w, r.V = 1.0 - v, r.W = 1.0 - w;
  r.VW = r.V * r.W, r.vW = r.v * r.W, r.Vw = r.V * r.w, r.vw = r.v * r.w;
  r.A = ((f0 - (r.W * e[4] + r.w * e[6])) - (r.V * e[8] + r.v * e[11])) +
        ((r.VW * c[0] + r.vW * c[3]) + (r.Vw * c[4] + r.vw * c[7]));
  r.B = ((f1 - (r.W * e[5] + r.w * e[7])) - (r.V * e[9] + r.v * e[10])) +
        ((r.VW * c[1] + r.vW * c[2]) + (r.Vw * c[5] + r.vw * c[6]));
  return r;
}

inline double hex_point(const HexRow& r, double u, double U, double f2, double f3, double f4, double f5, double e0,
                        double e1, double e2, double e3) {
  return ((U * r.A + u * r.B) + ((r.V * f2 + r.v * f3) + (r.W * f4 + r.w * f5))) -
         ((r.VW * e0 + r.vW * e1) + (r.Vw * e2 + r.vw * e3));
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
