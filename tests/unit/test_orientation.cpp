// Orientation codes proven by enumeration (STYLE.md #9): every code composed,
// inverted and applied, every rotation of a quad and of a hex.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <set>

#include "dicer/orientation.hpp"
#include "random_mesh.hpp"

using namespace dicer;

TEST(Orientation, CodesArePermutationsAndFormAGroup) {
  std::set<std::array<int, 4>> perms;
  for (int c = 0; c < 8; ++c) {
    std::array<int, 4> p;
    for (int m = 0; m < 4; ++m) p[m] = code_corner(static_cast<FaceCode>(c), m);
    std::array<int, 4> s = p;
    std::sort(s.begin(), s.end());
    EXPECT_EQ(s, (std::array<int, 4>{0, 1, 2, 3})) << "code " << c;
    // Adjacent corners stay adjacent (a symmetry of the square).
    for (int m = 0; m < 4; ++m) EXPECT_EQ((std::abs(p[m] - p[(m + 1) % 4]) % 2), 1);
    perms.insert(p);
  }
  EXPECT_EQ(perms.size(), 8u);
  for (int a = 0; a < 8; ++a) {
    const auto fa = static_cast<FaceCode>(a);
    EXPECT_EQ(compose(inverse(fa), fa), 0);
    EXPECT_EQ(compose(fa, inverse(fa)), 0);
    for (int b = 0; b < 8; ++b)
      for (int m = 0; m < 4; ++m)
        EXPECT_EQ(code_corner(compose(fa, static_cast<FaceCode>(b)), m),
                  code_corner(fa, code_corner(static_cast<FaceCode>(b), m)));
  }
}

TEST(Orientation, CanonicalQuadFollowsTheDesignRule) {
  // All 8 cyclic orders of the same 4 ids give the same canonical corners,
  // and the code maps local corners back onto them.
  const std::array<Id, 4> ids = {42, 7, 19, 23};  // cyclic order around the quad
  std::set<std::array<Id, 4>> canon;
  for (int r = 0; r < 4; ++r)
    for (int flip = 0; flip < 2; ++flip) {
      std::array<Id, 4> local;
      for (int m = 0; m < 4; ++m) local[m] = ids[((flip ? r - m : r + m) % 4 + 4) % 4];
      const CanonicalQuad q = canonical_quad(local);
      canon.insert(q.v);
      for (int m = 0; m < 4; ++m) EXPECT_EQ(local[m], q.v[code_corner(q.code, m)]);
    }
  ASSERT_EQ(canon.size(), 1u);
  const auto v = *canon.begin();
  EXPECT_EQ(v[0], 7);   // lowest id
  EXPECT_EQ(v[1], 19);  // the lower of 7's neighbours (42, 19)
  EXPECT_EQ(v[2], 23);  // opposite 7
  EXPECT_EQ(v[3], 42);
}

TEST(Orientation, FaceMapSendsLocalCornersToCanonicalCorners) {
  for (int c = 0; c < 8; ++c) {
    const auto code = static_cast<FaceCode>(c);
    const Id nu = 5, nv = 3;
    // Local axis lengths follow from whether the code swaps axes.
    const Id np = code_swaps_axes(code) ? nv : nu, nq = code_swaps_axes(code) ? nu : nv;
    const FaceMap fm = face_map(code, nu, nv);
    const Id lp[4] = {0, np, np, 0}, lq[4] = {0, 0, nq, nq};
    const Id cu[4] = {0, nu, nu, 0}, cv[4] = {0, 0, nv, nv};
    for (int m = 0; m < 4; ++m) {
      const int k = code_corner(code, m);
      EXPECT_EQ(fm.u(lp[m], lq[m]), cu[k]) << "code " << c << " corner " << m;
      EXPECT_EQ(fm.v(lp[m], lq[m]), cv[k]) << "code " << c << " corner " << m;
    }
    // A bijection of the grid.
    std::set<std::pair<Id, Id>> hit;
    for (Id p = 0; p <= np; ++p)
      for (Id q = 0; q <= nq; ++q) {
        const Id u = fm.u(p, q), v = fm.v(p, q);
        EXPECT_TRUE(u >= 0 && u <= nu && v >= 0 && v <= nv);
        hit.insert({u, v});
      }
    EXPECT_EQ(hit.size(), static_cast<size_t>((nu + 1) * (nv + 1)));
  }
}

TEST(Orientation, TwentyFourHexRotationsArePureRotations) {
  const auto rots = test::hex_rotations();
  ASSERT_EQ(rots.size(), 24u);
  for (const auto& r : rots) {
    // Corner positions after relabelling: still a unit cube with right-handed corner 0 frame.
    auto pos = [&](int k, int d) { return kHexCorner[r[k]][d]; };
    int e[3][3];
    const int nb[3] = {1, 3, 4};
    for (int a = 0; a < 3; ++a)
      for (int d = 0; d < 3; ++d) e[a][d] = pos(nb[a], d) - pos(0, d);
    const int det = e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) - e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                    e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    EXPECT_EQ(det, 1);
  }
}

TEST(Orientation, HexFacesAndEdgesAreConsistentWithCorners) {
  for (int f = 0; f < 6; ++f) {
    const int axis = f / 2, side = f % 2;
    for (int m = 0; m < 4; ++m) EXPECT_EQ(kHexCorner[kHexFace[f][m]][axis], side);
    // h1 - h0 runs along the face's first free axis, h3 - h0 along its second.
    for (int d = 0; d < 3; ++d) {
      EXPECT_EQ(kHexCorner[kHexFace[f][1]][d] - kHexCorner[kHexFace[f][0]][d], d == kHexFaceAxes[f][0] ? 1 : 0);
      EXPECT_EQ(kHexCorner[kHexFace[f][3]][d] - kHexCorner[kHexFace[f][0]][d], d == kHexFaceAxes[f][1] ? 1 : 0);
    }
  }
  for (int e = 0; e < 12; ++e)
    for (int d = 0; d < 3; ++d)
      EXPECT_EQ(kHexCorner[kHexEdge[e][1]][d] - kHexCorner[kHexEdge[e][0]][d], d == e / 4 ? 1 : 0);
}

TEST(Orientation, HexFaceSideEdgesJoinTheRightCorners) {
  for (int f = 0; f < 6; ++f)
    for (int c = 0; c < 8; ++c) {
      std::set<int> edges;
      for (int side = 0; side < 4; ++side) {
        const int e = hex_face_side_edge(f, static_cast<FaceCode>(c), side);
        ASSERT_GE(e, 0);
        edges.insert(e);
        // The edge's two corners both lie on face f.
        for (int end = 0; end < 2; ++end) EXPECT_EQ(kHexCorner[kHexEdge[e][end]][f / 2], f % 2);
      }
      EXPECT_EQ(edges.size(), 4u);  // the four edges of the face, each once
    }
}
