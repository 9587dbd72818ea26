// tfi.hpp's factored hex TFI (hex_plane, hex_row, hex_column, hex_point) against the
// textbook Boolean sum (gordon_hall.hpp) on random, unrelated face, edge and
// corner values: the factoring is algebra, so the two agree to rounding.
#include <gtest/gtest.h>

#include <cfloat>
#include <cstdio>
#include <random>

#include "dicer/orientation.hpp"
#include "dicer/tfi.hpp"
#include "gordon_hall.hpp"

namespace dicer {
namespace {

TEST(HexTfi, FactoredFormIsTheTextbookSum) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> val(-1, 1), par(0x1p-20, 1 - 0x1p-20);
  double worst = 0;
  for (int trial = 0; trial < 200000; ++trial) {
    // Values by position: side[a] in {0, 1, 2} (low, high, free).
    double at[27];
    for (double& x : at) x = val(rng);
    // Larger offsets now and then: cancellation between faces, edges and corners.
    const double shift = trial % 4 == 0 ? 1e6 * val(rng) : 0;
    for (double& x : at) x += shift;
    const std::array<double, 3> s{par(rng), par(rng), par(rng)};
    auto pos = [&](int i, int j, int k) { return at[i + 3 * j + 9 * k]; };
    // tfi.hpp's inputs in its own order: faces i=0, i=1, j=0, j=1, k=0, k=1;
    // edges kHexEdge (axis q / 4, the other axes at the first corner's sides);
    // corners kHexCorner.
    const double f[6] = {pos(0, 2, 2), pos(1, 2, 2), pos(2, 0, 2), pos(2, 1, 2), pos(2, 2, 0), pos(2, 2, 1)};
    double e[12], c[8];
    for (int q = 0; q < 12; ++q) {
      int side[3];
      for (int a = 0; a < 3; ++a) side[a] = a == q / 4 ? 2 : kHexCorner[kHexEdge[q][0]][a];
      e[q] = pos(side[0], side[1], side[2]);
    }
    for (int q = 0; q < 8; ++q) c[q] = pos(kHexCorner[q][0], kHexCorner[q][1], kHexCorner[q][2]);
    const tfi::HexPlane plane = tfi::hex_plane(s[2], e + 8, c);
    const tfi::HexRow row = tfi::hex_row(plane, s[1], f[0], f[1], e[4], e[5], e[6], e[7]);
    const tfi::HexColumn col = tfi::hex_column(plane, f[2], f[3], e[0], e[1], e[2], e[3]);
    const double x = tfi::hex_point(row, col, s[0], s[1], s[2], f[4], f[5]);
    const test::GordonHall want = test::gordon_hall([&](std::array<int, 3> d) { return pos(d[0], d[1], d[2]); }, s);
    const double err = static_cast<double>(std::fabs(static_cast<long double>(x) - want.x) / want.magnitude);
    worst = std::max(worst, err);
    // Empirical bound, not a proof (the path has a few dozen roundings):
    // the worst seen is ~0.4 eps of the magnitudes, so 4 eps leaves a 10x
    // margin, while a wrong coefficient or a 1e-13 perturbation exceeds it.
    ASSERT_LE(err, 4 * DBL_EPSILON) << "trial " << trial << ": " << x << " vs " << static_cast<double>(want.x);
  }
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", worst);
  RecordProperty("worst_relative_error", text);
}

}  // namespace
}  // namespace dicer
