// merge_quality: a check shared out over parts (ConformOptions::parts,
// dice --geometry under mpirun) merged back equals one check over all.
#include <gtest/gtest.h>

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
