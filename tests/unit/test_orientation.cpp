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

// The local tables, each enumerated against what it must mean geometrically
// (corner positions of the unit cube), not against another table.
TEST(Orientation, LocalTablesMeanWhatTheySay) {
  // Corners: distinct positions of the unit cube.
  std::set<std::array<int, 3>> seen;
  for (int c = 0; c < 8; ++c) seen.insert({kHexCorner[c][0], kHexCorner[c][1], kHexCorner[c][2]});
  EXPECT_EQ(seen.size(), 8u);
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j) {
      for (int k = 0; k < 2; ++k) {
        const int c = hex_corner_at(i, j, k);
        ASSERT_GE(c, 0);
        EXPECT_EQ((std::array<int, 3>{kHexCorner[c][0], kHexCorner[c][1], kHexCorner[c][2]}), (std::array<int, 3>{i, j, k}));
      }
      EXPECT_EQ(quad_corner_at(i, j), hex_corner_at(i, j, 0));
      EXPECT_LT(quad_corner_at(i, j), 4);
    }
  // Edges: each joins two corners differing along exactly its axis, from
  // low to high; hex_edge_at finds it from the other two coordinates.
  for (int e = 0; e < 12; ++e) {
    const int axis = e / 4;
    const int* a = kHexCorner[kHexEdge[e][0]];
    const int* b = kHexCorner[kHexEdge[e][1]];
    for (int d = 0; d < 3; ++d) EXPECT_EQ(b[d] - a[d], d == axis ? 1 : 0) << "edge " << e;
    const int o1 = axis == 0 ? 1 : 0, o2 = axis == 2 ? 1 : 2;
    EXPECT_EQ(hex_edge_at(axis, a[o1], a[o2]), e);
  }
  for (int e = 0; e < 4; ++e) {
    const int axis = e / 2;
    const int* a = kHexCorner[kQuadEdge[e][0]];
    const int* b = kHexCorner[kQuadEdge[e][1]];
    EXPECT_EQ(b[axis] - a[axis], 1);
    EXPECT_EQ(b[1 - axis], a[1 - axis]);
    EXPECT_EQ(a[2], 0);
    EXPECT_EQ(quad_edge_at(axis, a[1 - axis]), e);
  }
  // Faces: four corners on one side of the cube, in cyclic order, the first
  // free axis (kHexFaceAxes) from h0 to h1 and the second from h0 to h3.
  for (int f = 0; f < 6; ++f) {
    const int axis = f / 2, side = f % 2;
    for (int m = 0; m < 4; ++m) EXPECT_EQ(kHexCorner[kHexFace[f][m]][axis], side) << "face " << f;
    const int* h0 = kHexCorner[kHexFace[f][0]];
    const int* h1 = kHexCorner[kHexFace[f][1]];
    const int* h3 = kHexCorner[kHexFace[f][3]];
    EXPECT_EQ(h1[kHexFaceAxes[f][0]] - h0[kHexFaceAxes[f][0]], 1);
    EXPECT_EQ(h3[kHexFaceAxes[f][1]] - h0[kHexFaceAxes[f][1]], 1);
  }
  // Exodus sides: each hex side's corners share one coordinate, its normal
  // (right-hand rule over the listed order) points out of the cube, and
  // exodus_side_plane names that plane.
  for (int s = 0; s < 6; ++s) {
    const int* c[4];
    for (int q = 0; q < 4; ++q) c[q] = kHexCorner[kHexSideCorners[s][q]];
    const SidePlane p = exodus_side_plane(Mode::Volume, s);
    ASSERT_GE(p.axis, 0);
    for (int q = 0; q < 4; ++q) EXPECT_EQ(c[q][p.axis], p.high ? 1 : 0) << "side " << s;
    const int u[3] = {c[1][0] - c[0][0], c[1][1] - c[0][1], c[1][2] - c[0][2]};
    const int v[3] = {c[3][0] - c[0][0], c[3][1] - c[0][1], c[3][2] - c[0][2]};
    const int n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    EXPECT_EQ(n[p.axis], p.high ? 1 : -1) << "side " << s << " must face outwards";
  }
  for (int s = 2; s < 6; ++s) {
    const int* a = kHexCorner[kShellSideCorners[s - 2][0]];
    const int* b = kHexCorner[kShellSideCorners[s - 2][1]];
    const SidePlane p = exodus_side_plane(Mode::Surface, s);
    ASSERT_GE(p.axis, 0);
    EXPECT_EQ(a[p.axis], p.high ? 1 : 0);
    EXPECT_EQ(b[p.axis], p.high ? 1 : 0);
  }
  EXPECT_EQ(exodus_side_plane(Mode::Surface, 0).axis, -1);
  EXPECT_EQ(exodus_side_plane(Mode::Surface, 1).axis, -1);
  // The mirror swaps i and j and keeps the cube.
  for (int c = 0; c < 8; ++c) {
    const int* a = kHexCorner[c];
    const int* b = kHexCorner[kHexMirror[c]];
    EXPECT_EQ(a[0], b[1]);
    EXPECT_EQ(a[1], b[0]);
    EXPECT_EQ(a[2], b[2]);
  }
  // quad_side_edge: canonical side k of a quad under every code is the local
  // edge joining the local corners that hold its canonical ends.
  for (int code = 0; code < 8; ++code)
    for (int side = 0; side < 4; ++side) {
      const int e = quad_side_edge(static_cast<FaceCode>(code), side);
      ASSERT_GE(e, 0);
      std::set<int> want, have{kQuadEdge[e][0], kQuadEdge[e][1]};
      for (int m = 0; m < 4; ++m)
        for (int end = 0; end < 2; ++end)
          if (code_corner(static_cast<FaceCode>(code), m) == kQuadEdge[side][end]) want.insert(m);
      EXPECT_EQ(have, want) << "code " << code << " side " << side;
    }
}
