// tfi.hpp's factored hex TFI (hex_plane, hex_row, hex_column, hex_point) against the
// textbook Boolean sum (gordon_hall.hpp) on random, unrelated face, edge and
// corner values: the factoring is algebra, so the two agree to rounding;
// and its straight forms (bilinear_row, _point; trilinear_plane) likewise.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cfloat>
#include <cstdint>
#include <cstdio>
#include <random>
#include <vector>

#include "dicer/orientation.hpp"
#include "dicer/tfi.hpp"
#include "evaluate.hpp"
#include "gordon_hall.hpp"

namespace dicer {
namespace {

constexpr int kTrials = 200000;

// Random values in [-1, 1], every fourth trial shifted by up to 1e6
// (cancellation), and parameters inside (0, 1).
struct RandomInputs {
  std::mt19937_64 rng;
  std::uniform_real_distribution<double> val{-1, 1}, par{0x1p-20, 1 - 0x1p-20};
  explicit RandomInputs(unsigned seed) : rng(seed) {}
  double shift(int trial) { return trial % 4 == 0 ? 1e6 * val(rng) : 0; }
};

void record_worst(double worst) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", worst);
  testing::Test::RecordProperty("worst_relative_error", text);
}

TEST(HexTfi, FactoredFormIsTheTextbookSum) {
  RandomInputs in(5);
  double worst = 0;
  for (int trial = 0; trial < kTrials; ++trial) {
    // Values by position: side[a] in {0, 1, 2} (low, high, free).
    double at[27];
    for (double& x : at) x = in.val(in.rng);
    // Larger offsets now and then: cancellation between faces, edges and corners.
    const double shift = in.shift(trial);
    for (double& x : at) x += shift;
    const std::array<double, 3> s{in.par(in.rng), in.par(in.rng), in.par(in.rng)};
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
  record_worst(worst);
}

// A straight hex: edges the segments between its corners, faces the
// bilinear patches. Its Boolean sum is the trilinear blend of the corners
// (the edge and face terms cancel), which tfi::trilinear_plane and the
// bilinear patch compute for its interior: against the textbook sum of its
// entities' exact values, and so against the corners' blend, to rounding.
TEST(HexTfi, TrilinearFormIsTheBooleanSumOfAStraightHex) {
  RandomInputs in(11);
  double worst = 0;
  for (int trial = 0; trial < kTrials; ++trial) {
    double c[8];
    const double shift = in.shift(trial);
    for (double& x : c) x = in.val(in.rng) + shift;
    const std::array<double, 3> s{in.par(in.rng), in.par(in.rng), in.par(in.rng)};
    // An entity point's value: the corners' blend over its free axes
    // (side 2), in long double.
    auto at = [&](std::array<int, 3> side) {
      long double x = 0;
      for (int q = 0; q < 8; ++q) {
        long double w = 1;
        for (int a = 0; a < 3; ++a) {
          const int hi = kHexCorner[q][a];
          if (side[a] == 2) w *= hi ? static_cast<long double>(s[a]) : 1.0L - static_cast<long double>(s[a]);
          else if (side[a] != hi) w = 0;
        }
        x += w * static_cast<long double>(c[q]);
      }
      return static_cast<double>(x);
    };
    double q[4];
    tfi::trilinear_plane(s[2], c, q);
    const double x = tfi::bilinear_point(tfi::bilinear_row(s[1], q), s[0]);
    const test::GordonHall want = test::gordon_hall(at, s);
    const double err = static_cast<double>(std::fabs(static_cast<long double>(x) - want.x) / want.magnitude);
    worst = std::max(worst, err);
    // The same empirical margin as above; the entity values are rounded to
    // double, a few eps of each, well inside it once summed.
    ASSERT_LE(err, 4 * DBL_EPSILON) << "trial " << trial << ": " << x << " vs " << static_cast<double>(want.x);
    // And the corners' blend itself (the point, all three axes free).
    const long double blend = at({2, 2, 2});
    ASSERT_LE(std::fabs(x - blend), 8 * DBL_EPSILON * (std::fabs(blend) + 1)) << "trial " << trial;
  }
  record_worst(worst);
}

// A straight face: its Coons patch (the textbook form, in long double, of
// sides that are the segments between its corners) is the bilinear patch
// tfi::bilinear_row and _point compute.
TEST(FaceTfi, BilinearFormIsTheCoonsPatchOfStraightSides) {
  RandomInputs in(13);
  double worst = 0;
  for (int trial = 0; trial < kTrials; ++trial) {
    double p[4];
    const double shift = in.shift(trial);
    for (double& x : p) x = in.val(in.rng) + shift;
    const long double s = in.par(in.rng), t = in.par(in.rng), S = 1 - s, T = 1 - t;
    auto lerp = [](double a, double b, long double w) {
      return static_cast<double>((1 - w) * static_cast<long double>(a) + w * static_cast<long double>(b));
    };
    // Sides as coons() takes them: bottom p0 -> p1 at s, top p3 -> p2 at s,
    // left p0 -> p3 at t, right p1 -> p2 at t.
    const long double bottom = lerp(p[0], p[1], s), top = lerp(p[3], p[2], s), left = lerp(p[0], p[3], t),
                      right = lerp(p[1], p[2], t);
    const long double coons = (T * bottom + t * top) + (S * left + s * right) -
                              (S * T * p[0] + s * T * p[1] + s * t * p[2] + S * t * p[3]);
    long double magnitude = std::fabs(bottom) + std::fabs(top) + std::fabs(left) + std::fabs(right);
    for (double x : p) magnitude += std::fabs(static_cast<long double>(x));
    const double x = tfi::bilinear_point(tfi::bilinear_row(static_cast<double>(t), p), static_cast<double>(s));
    const double err = static_cast<double>(std::fabs(static_cast<long double>(x) - coons) / magnitude);
    worst = std::max(worst, err);
    ASSERT_LE(err, 4 * DBL_EPSILON) << "trial " << trial << ": " << x << " vs " << static_cast<double>(coons);
  }
  record_worst(worst);
}

// The patch kernels (evaluate.hpp) against bilinear_row + bilinear_point
// per point, as cell_point and face_tfi compute each: bit for bit, for
// every size up to 20 x 20 (the permute path's 16 rows and past them), a
// grid laid out afresh when its parameters change and reused when only the
// corners do, and nothing written more than kPatchSlack - 1 values past a
// patch. On AVX-512 machines the prepared grid takes the permute path up
// to 16 rows; the avx2 build (scripts/run_tests.sh) tests the other one.
TEST(Patches, EveryKernelGivesEachPointsBits) {
  std::mt19937_64 rng(29);
  std::uniform_real_distribution<double> val(-1e3, 1e3), par(0.0, 1.0);
  detail::PatchGrid grid;
  std::vector<double> s, t;
  int permuted = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    // In sixes: new sizes and parameters, the same again (the grid's
    // reuse), new s only, the same again, new t only, the same again (a
    // reuse after a new s or t would be wrong).
    const int step = trial % 6;
    const bool resize = step == 0;
    const Id nu = resize ? 1 + static_cast<Id>(rng() % 20) : grid.nu;
    const Id nv = resize ? 1 + static_cast<Id>(rng() % 20) : grid.nv;
    if (resize) s.assign(static_cast<size_t>(nu + detail::kPatchSlack), 0.0), t.assign(static_cast<size_t>(nv), 0.0);
    if (step == 0 || step == 2) {
      for (Id u = 1; u < nu; ++u) s[u] = par(rng);
      std::sort(s.begin() + 1, s.begin() + nu);
    }
    if (step == 0 || step == 4) {
      for (Id v = 1; v < nv; ++v) t[v] = par(rng);
      std::sort(t.begin() + 1, t.end());
    }
    double p[4];
    for (double& x : p) x = val(rng);
    const Id count = std::max<Id>(nu - 1, 0) * std::max<Id>(nv - 1, 0);
    constexpr double kSentinel = -12345.0;
    std::vector<double> direct(static_cast<size_t>(count + 2 * detail::kPatchSlack), kSentinel);
    std::vector<double> prepared = direct;
    detail::bilinear_patch(s.data(), t.data(), nu, nv, p, direct.data());
    detail::prepare_patch_grid(s.data(), t.data(), nu, nv, grid);
    permuted += grid.permute;
    detail::bilinear_patch(grid, p, prepared.data());
    for (Id v = 1; v < nv; ++v)
      for (Id u = 1; u < nu; ++u) {
        const double want = tfi::bilinear_point(tfi::bilinear_row(t[v], p), s[u]);
        const auto f = static_cast<size_t>((v - 1) * (nu - 1) + u - 1);
        ASSERT_EQ(std::bit_cast<std::uint64_t>(direct[f]), std::bit_cast<std::uint64_t>(want))
            << "trial " << trial << ", " << nu << " x " << nv << ", point (" << u << ", " << v << ")";
        ASSERT_EQ(std::bit_cast<std::uint64_t>(prepared[f]), std::bit_cast<std::uint64_t>(want))
            << "trial " << trial << ", " << nu << " x " << nv << ", point (" << u << ", " << v << ")";
      }
    for (auto* out : {&direct, &prepared})
      for (size_t f = static_cast<size_t>(count + detail::kPatchSlack - 1); f < out->size(); ++f)
        ASSERT_EQ((*out)[f], kSentinel) << "trial " << trial << ": written past the room at " << f;
  }
  testing::Test::RecordProperty("permute_path_trials", permuted);
  // The permute path ran where evaluate.cpp's guard and this CPU say it
  // should (else the half above checked the row kernel twice).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__) && \
    !defined(DICER_CLONES_NONE) && !defined(DICER_CLONES_AVX2_AT_MOST)
  const bool avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
                      __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl") &&
                      __builtin_cpu_supports("avx512cd");
  EXPECT_EQ(permuted > 0, avx512);
#else
  EXPECT_EQ(permuted, 0);
#endif
}

// series_values (evaluate.hpp's cache) gives Series::at's bits for every
// t asked and nothing else: equal, geometric either way and dual series of
// 1 to 80 intervals (past the cache's 64: computed directly), asked in a
// random order so that the cache's eight slots are taken over and hit again.
TEST(Series, CachedValuesAreEachSeriesBits) {
  std::mt19937_64 rng(28);
  std::vector<std::pair<Id, tfi::Grading>> series;
  for (const Id n : {1, 2, 3, 7, 10, 20, 64, 65, 80})
    for (int kind = 0; kind < 4; ++kind) {
      tfi::Grading g;
      if (kind == 1 || kind == 2) g.kind = tfi::Spacing::Geometric, g.ratio = 1.3, g.flip = kind == 2;
      if (kind == 3) g.kind = tfi::Spacing::Dual, g.ratio = 1.7;
      series.push_back({n, g});
    }
  constexpr double kSentinel = -7.0;
  for (int trial = 0; trial < 2000; ++trial) {
    const auto& [n, g] = series[rng() % series.size()];
    const Id t0 = static_cast<Id>(rng() % static_cast<std::uint64_t>(n + 1));
    const Id t1 = t0 + static_cast<Id>(rng() % static_cast<std::uint64_t>(n + 2 - t0));
    std::vector<double> out(static_cast<size_t>(n + 2), kSentinel);
    detail::series_values(n, g, t0, t1, out.data());
    const tfi::Series want(n, g);
    for (Id t = 0; t < n + 2; ++t) {
      const double w = t >= t0 && t < t1 ? want.at(t) : kSentinel;
      ASSERT_EQ(std::bit_cast<std::uint64_t>(out[static_cast<size_t>(t)]), std::bit_cast<std::uint64_t>(w))
          << "trial " << trial << ": n " << n << ", t " << t << " of [" << t0 << ", " << t1 << ")";
    }
  }
}

}  // namespace
}  // namespace dicer
