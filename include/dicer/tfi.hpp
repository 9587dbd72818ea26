#pragma once
// Transfinite interpolation: the only definition of where a fine node is.
//
// Each function works on one coordinate in the owning entity's canonical
// frame (DESIGN.md invariant 2). Block fills, node(id) and every exporter
// call these same inline functions with the same inputs, and the build turns
// off floating-point contraction, so every path gives bit-identical results.
// Weights are t/n computed as double(t) / double(n).
#include <cstdint>

namespace dicer::tfi {

inline double weight(std::int64_t t, std::int64_t n) { return static_cast<double>(t) / static_cast<double>(n); }

// Equal spacing on an edge from a (t = 0) to b (t = n).
inline double edge(double a, double b, double s) { return (1.0 - s) * a + s * b; }

// Coons patch at (s, t) in [0,1]^2 from the four boundary values at the same
// parameters (bottom(s), top(s), left(t), right(t)) and the corners
// p0 = (0,0), p1 = (1,0), p2 = (1,1), p3 = (0,1).
inline double coons(double s, double t, double bottom, double top, double left, double right, double p0,
                    double p1, double p2, double p3) {
  const double S = 1.0 - s, T = 1.0 - t;
  return (T * bottom + t * top) + (S * left + s * right) - ((S * T * p0 + s * T * p1) + (s * t * p2 + S * t * p3));
}

// Trilinear transfinite (Gordon-Hall) interpolation at (u, v, w) in [0,1]^3.
// f[6]: face values at the point's projection (orientation.hpp face order:
// i=0, i=1, j=0, j=1, k=0, k=1). e[12]: edge values (kHexEdge order).
// c[8]: corners (kHexCorner order).
inline double hex(double u, double v, double w, const double* f, const double* e, const double* c) {
  const double U = 1.0 - u, V = 1.0 - v, W = 1.0 - w;
  const double faces = (U * f[0] + u * f[1]) + (V * f[2] + v * f[3]) + (W * f[4] + w * f[5]);
  const double edges = ((V * W * e[0] + v * W * e[1]) + (V * w * e[2] + v * w * e[3])) +
                       ((U * W * e[4] + u * W * e[5]) + (U * w * e[6] + u * w * e[7])) +
                       ((U * V * e[8] + u * V * e[9]) + (u * v * e[10] + U * v * e[11]));
  const double corners = ((U * V * W * c[0] + u * V * W * c[1]) + (u * v * W * c[2] + U * v * W * c[3])) +
                         ((U * V * w * c[4] + u * V * w * c[5]) + (u * v * w * c[6] + U * v * w * c[7]));
  return faces - edges + corners;
}

}  // namespace dicer::tfi
