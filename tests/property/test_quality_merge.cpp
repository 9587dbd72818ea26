// merge_quality: a check shared out over parts (ConformOptions::parts,
// dice --geometry under mpirun) merged back equals one check over all.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include "dicer/quality.hpp"
#include "random_mesh.hpp"

using namespace dicer;

namespace {

void expect_same(const QualityReport& a, const QualityReport& b) {
  EXPECT_EQ(a.min_scaled_jacobian, b.min_scaled_jacobian);
  EXPECT_EQ(a.worst_element, b.worst_element);
  EXPECT_EQ(a.worst_coarse_element, b.worst_coarse_element);
  EXPECT_EQ(a.inverted, b.inverted);
  EXPECT_EQ(a.elements_checked, b.elements_checked);
}

TEST(QualityMerge, InterleavedPartsMergeToTheWholeCheck) {
  for (int seed = 0; seed < 6; ++seed) {
    std::mt19937_64 rng(seed);
    test::BoxSpec spec;
    spec.a = 3 + seed % 3, spec.b = 2, spec.c = 2;
    IntervalRequest req;
    req.global = 2 + seed % 2;
    const FineMesh f = FineMesh::dice(test::random_box(spec, rng), req);
    const QualityReport whole = check_quality(f);
    ASSERT_GT(whole.elements_checked, 0);
    for (Id parts : {1, 2, 3, 5}) {
      SCOPED_TRACE("seed " + std::to_string(seed) + ", " + std::to_string(parts) + " parts");
      QualityReport merged;
      for (Id p = 0; p < parts; ++p)  // in part order, as the exchange hands them over
        merge_quality(merged, check_quality(f, [&](Id h) { return h % parts == p; }));
      expect_same(merged, whole);
    }
  }
  // Equal minima: the lower fine element wins whatever the order of parts.
  QualityReport a, b;
  a.min_scaled_jacobian = b.min_scaled_jacobian = 0.5;
  a.worst_element = 7, b.worst_element = 3;
  a.elements_checked = b.elements_checked = 1;
  QualityReport m;
  merge_quality(m, a), merge_quality(m, b);
  EXPECT_EQ(m.worst_element, 3);
  EXPECT_EQ(m.elements_checked, 2);
}

}  // namespace

// The scaled Jacobian does not depend on the unit: a box and a sheared
// prism give the same values at scales whose squared lengths under- or
// overflow (1e-110, 1e160); a tangled hex stays inverted there.
TEST(QualityMerge, ScaledJacobianIsTheSameAtAnyScale) {
  const Vec3 box[8] = {{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {0, 1, 0}, {0, 0, 3}, {2, 0, 3}, {2, 1, 3}, {0, 1, 3}};
  Vec3 sheared[8], tangled[8];
  for (int k = 0; k < 8; ++k) {
    sheared[k] = {box[k].x + 0.5 * box[k].z, box[k].y, box[k].z};
    tangled[k] = box[k];
  }
  tangled[6] = {-0.5, -0.5, 3};
  const Vec3 quad[4] = {{0, 0, 0}, {2, 0, 0}, {2.5, 1, 0}, {0, 1, 0}};
  const double want_box = hex_scaled_jacobian(box), want_sheared = hex_scaled_jacobian(sheared);
  const double want_quad = quad_scaled_jacobian(quad);
  EXPECT_DOUBLE_EQ(want_box, 1.0);
  EXPECT_NEAR(want_sheared, 3 / std::sqrt(9 + 2.25), 1e-15);  // the slanted edge (1.5, 0, 3) against z
  for (const double s : {1e-110, 1e-160, 1e160}) {
    auto scaled = [s](const Vec3(&p)[8]) {
      std::array<Vec3, 8> q;
      for (int k = 0; k < 8; ++k) q[k] = {p[k].x * s, p[k].y * s, p[k].z * s};
      return q;
    };
    const auto b = scaled(box), h = scaled(sheared), t = scaled(tangled);
    Vec3 bb[8], hh[8], tt[8], qq[4];
    std::copy(b.begin(), b.end(), bb), std::copy(h.begin(), h.end(), hh), std::copy(t.begin(), t.end(), tt);
    for (int k = 0; k < 4; ++k) qq[k] = {quad[k].x * s, quad[k].y * s, quad[k].z * s};
    EXPECT_NEAR(hex_scaled_jacobian(bb), want_box, 1e-15) << s;
    EXPECT_NEAR(hex_scaled_jacobian(hh), want_sheared, 1e-15) << s;
    EXPECT_LE(hex_scaled_jacobian(tt), 0.0) << s;
    EXPECT_NEAR(quad_scaled_jacobian(qq), want_quad, 1e-15) << s;
  }
  // A corner that is not a number is no element (it scored 0.98 once the
  // out-of-range path took the NaN products).
  for (const int axis : {0, 1, 2}) {
    Vec3 nan_hex[8], nan_quad[4];
    std::copy(std::begin(sheared), std::end(sheared), nan_hex);
    std::copy(std::begin(quad), std::end(quad), nan_quad);
    (axis == 0 ? nan_hex[6].x : axis == 1 ? nan_hex[6].y : nan_hex[6].z) = std::nan("");
    (axis == 0 ? nan_quad[2].x : axis == 1 ? nan_quad[2].y : nan_quad[2].z) = std::nan("");
    EXPECT_FALSE(hex_scaled_jacobian(nan_hex) > 0) << axis;
    EXPECT_FALSE(quad_scaled_jacobian(nan_quad) > 0) << axis;
  }
}
