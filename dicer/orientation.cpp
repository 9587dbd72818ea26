// Canonical orientation (see include/dicer/orientation.hpp): the only file
// that turns local corner orders into canonical ones.
#include "dicer/orientation.hpp"

#include "dicer/error.hpp"

namespace dicer {

FaceCode compose(FaceCode a, FaceCode b) {
  for (int c = 0; c < 8; ++c) {
    bool ok = true;
    for (int m = 0; m < 4 && ok; ++m)
      ok = code_corner(static_cast<FaceCode>(c), m) == code_corner(a, code_corner(b, m));
    if (ok) return static_cast<FaceCode>(c);
  }
  DICER_ASSERT(false, "the square's symmetries are closed under composition");
}

FaceCode inverse(FaceCode a) {
  for (int c = 0; c < 8; ++c)
    if (compose(static_cast<FaceCode>(c), a) == 0) return static_cast<FaceCode>(c);
  DICER_ASSERT(false, "every symmetry of the square has an inverse");
}

CanonicalQuad canonical_quad(const std::array<Id, 4>& h) {
  int r = 0;
  for (int m = 1; m < 4; ++m)
    if (h[m] < h[r]) r = m;
  const int s = h[(r + 1) % 4] < h[(r + 3) % 4] ? 1 : -1;
  CanonicalQuad q{};
  for (int m = 0; m < 4; ++m) q.v[m] = h[((r + s * m) % 4 + 4) % 4];
  // Local corner m is canonical corner k with r + s*k == m, i.e. k = s*(m - r).
  q.code = make_code((s == 1 ? -r : r) & 3, s == -1);
  return q;
}

FaceMap face_map(FaceCode code, std::int64_t nu, std::int64_t nv) {
  // Canonical grid position of canonical corner k.
  auto corner = [&](int k, std::int64_t& u, std::int64_t& v) {
    u = (k == 1 || k == 2) ? nu : 0;
    v = (k == 2 || k == 3) ? nv : 0;
  };
  std::int64_t u0, v0, u1, v1, u3, v3;
  corner(code_corner(code, 0), u0, v0);
  corner(code_corner(code, 1), u1, v1);
  corner(code_corner(code, 3), u3, v3);
  auto sgn = [](std::int64_t d) -> std::int64_t { return (d > 0) - (d < 0); };
  return FaceMap{u0, v0, sgn(u1 - u0), sgn(u3 - u0), sgn(v1 - v0), sgn(v3 - v0)};
}

namespace {
// Local edge joining the local corners that hold the canonical ends of
// `side` (kQuadEdge gives a side's canonical corners), for a face whose
// local corners are face_corners[0..3] in an element with edges edges[].
template <int E>
int side_edge(const int* face_corners, const int (&edges)[E][2], FaceCode code, int side) {
  int lc[2] = {-1, -1};
  for (int end = 0; end < 2; ++end)
    for (int m = 0; m < 4; ++m)
      if (code_corner(code, m) == kQuadEdge[side][end]) lc[end] = face_corners[m];
  for (int e = 0; e < E; ++e)
    if ((edges[e][0] == lc[0] && edges[e][1] == lc[1]) || (edges[e][0] == lc[1] && edges[e][1] == lc[0])) return e;
  return -1;
}

struct SideEdgeTable {
  int hex[6][8][4], quad[8][4];
  SideEdgeTable() {
    static constexpr int kQuadCorners[4] = {0, 1, 2, 3};
    for (int c = 0; c < 8; ++c)
      for (int side = 0; side < 4; ++side) {
        for (int f = 0; f < 6; ++f) hex[f][c][side] = side_edge(kHexFace[f], kHexEdge, static_cast<FaceCode>(c), side);
        quad[c][side] = side_edge(kQuadCorners, kQuadEdge, static_cast<FaceCode>(c), side);
      }
  }
};
const SideEdgeTable kSideEdges;
}  // namespace

int hex_face_side_edge(int face, FaceCode code, int side) { return kSideEdges.hex[face][code][side]; }
int quad_side_edge(FaceCode code, int side) { return kSideEdges.quad[code][side]; }

}  // namespace dicer
