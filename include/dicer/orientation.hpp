#pragma once
// Canonical orientation: the one place that fixes local numbering of hex and
// quad corners, edges and faces, and the 8 orientation codes of a square.
// Everything that turns a local index into a canonical one calls this file.
//
// Canonical frames (DESIGN.md invariant 1):
//  - an edge runs from its lower to its higher vertex id;
//  - a quad face starts at its lowest vertex id v0 and runs towards the lower
//    of v0's two neighbours (v1); v2 is opposite v0, v3 the other neighbour.
//    Its first axis (u) is v0->v1, its second (v) v0->v3.
//
// Face orientation code, values 0..7: a local face with corners h0..h3 (in
// its own cyclic order) relates to the canonical corners v0..v3 by
//     h_m = v_{(r + s*m) mod 4},  code = r + 4*(s == -1).
// The code is a corner permutation; compose() and inverse() are those of
// permutations. A grid point (p, q) of a local face with the local axes
// h0->h1 (p) and h0->h3 (q) maps to canonical (u, v) by face_map().
#include <array>
#include <cstdint>

#include "dicer/types.hpp"

namespace dicer {

// VTK/Exodus HEX8 corner k sits at local (i,j,k) = kHexCorner[k] in {0,1}^3.
inline constexpr int kHexCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                         {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

// Corner q of a structured grid's cell, read from the grid rows around it:
// rows[0] holds grid row (j, k), rows[1] (j + 1, k), rows[2] (j, k + 1),
// rows[3] (j + 1, k + 1), and the cell's corner 0 is point i of rows[0]
// (quads: rows[0..1], q < 4). The sweep's checksum reads cells this way (a
// constant q folds to one load); block connectivity copies the same
// corners as row pairs (fill.cpp's static_assert ties the two).
// grid_cell_row(q): which of the four rows corner q is read from.
constexpr int grid_cell_row(int q) { return kHexCorner[q][1] + 2 * kHexCorner[q][2]; }
template <class T>
constexpr T grid_cell_corner(const T* const* rows, std::int64_t i, int q) {
  return rows[grid_cell_row(q)][i + kHexCorner[q][0]];
}

// Local hex edges: 0-3 run along i, 4-7 along j, 8-11 along k, each from its
// lower to its higher local coordinate. kHexEdgeAxis[e] = e / 4.
inline constexpr int kHexEdge[12][2] = {{0, 1}, {3, 2}, {4, 5}, {7, 6}, {0, 3}, {1, 2},
                                        {4, 7}, {5, 6}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};

// Local hex faces: 2*axis + side (0: i=0, 1: i=n1, 2: j=0, 3: j=n2, 4: k=0,
// 5: k=n3). Corners h0..h3 in the face's frame: h0 the origin, h1 along the
// first free axis (a), h3 along the second (b): (a,b) = (j,k), (i,k), (i,j).
inline constexpr int kHexFace[6][4] = {{0, 3, 7, 4}, {1, 2, 6, 5}, {0, 1, 5, 4},
                                       {3, 2, 6, 7}, {0, 1, 2, 3}, {4, 5, 6, 7}};
// The two free hex axes of each face, in face-frame order (a, b).
inline constexpr int kHexFaceAxes[6][2] = {{1, 2}, {1, 2}, {0, 2}, {0, 2}, {0, 1}, {0, 1}};

// Quad (and surface-mode element) local edges: 0,1 along i; 2,3 along j.
inline constexpr int kQuadEdge[4][2] = {{0, 1}, {3, 2}, {0, 3}, {1, 2}};
// Whether quad edge k runs along (+1) or against (-1) the corners' cycle
// 0 -> 1 -> 2 -> 3 -> 0: a consistently oriented surface traverses each
// inner edge once each way.
inline constexpr int kQuadEdgeCyclic[4] = {1, -1, -1, 1};

// Exodus sides (0-based). HEX8 side s is the face with local corners
// kHexSideCorners[s] (outward normal for a right-handed hex); SHELL4/QUAD4
// sides 0 and 1 are the two faces of the quad, sides 2..5 its edges
// kShellSideCorners[s - 2] (corners k, k+1 mod 4).
inline constexpr int kHexSideCorners[6][4] = {
    {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {0, 4, 7, 3}, {0, 3, 2, 1}, {4, 5, 6, 7}};
inline constexpr int kShellSideCorners[4][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}};

// Mirror i <-> j (corner 0 fixed): turns a left-handed hex right-handed.
inline constexpr int kHexMirror[8] = {0, 3, 2, 1, 4, 7, 6, 5};

// The grid plane an Exodus side lies in: local axis (0 i, 1 j, 2 k) and
// whether it is the high end; axis -1 for a shell's two faces. Derived
// from the corner tables above and kHexCorner.
struct SidePlane {
  int axis;
  bool high;
};
constexpr SidePlane exodus_side_plane(Mode mode, int side) {
  const int* c = mode == Mode::Volume ? kHexSideCorners[side] : side >= 2 ? kShellSideCorners[side - 2] : nullptr;
  const int n = mode == Mode::Volume ? 4 : 2;
  if (!c) return {-1, side == 1};
  for (int a = 0; a < (mode == Mode::Volume ? 3 : 2); ++a) {
    bool same = true;
    for (int q = 1; q < n; ++q) same = same && kHexCorner[c[q]][a] == kHexCorner[c[0]][a];
    if (same) return {a, kHexCorner[c[0]][a] == 1};
  }
  return {-1, false};
}

// The local corner at grid extremes (each 0 or 1) and the local edge along
// `axis` at the extremes (a, b) of the two other axes (in increasing axis
// order): inverses of kHexCorner / kHexEdge / kQuadEdge by search.
constexpr int hex_corner_at(int i, int j, int k) {
  for (int c = 0; c < 8; ++c)
    if (kHexCorner[c][0] == i && kHexCorner[c][1] == j && kHexCorner[c][2] == k) return c;
  return -1;
}
constexpr int quad_corner_at(int i, int j) { return hex_corner_at(i, j, 0); }
constexpr int hex_edge_at(int axis, int a, int b) {
  const int o1 = axis == 0 ? 1 : 0, o2 = axis == 2 ? 1 : 2;
  for (int e = 0; e < 12; ++e) {
    const int* c = kHexCorner[kHexEdge[e][0]];
    if (kHexCorner[kHexEdge[e][1]][axis] != c[axis] && c[o1] == a && c[o2] == b) return e;
  }
  return -1;
}
constexpr int quad_edge_at(int axis, int other) {
  for (int e = 0; e < 4; ++e) {
    const int* c = kHexCorner[kQuadEdge[e][0]];
    if (kHexCorner[kQuadEdge[e][1]][axis] != c[axis] && c[1 - axis] == other) return e;
  }
  return -1;
}

// ---- Second-order elements (HEX20, HEX27; QUAD8, QUAD9) ----
//
// Mid-node slots: where an element's nodes beyond its corners sit, in
// dicer's local numbering. Volume, 19 slots: 0..11 the mid-edge nodes of
// local edges 0..11 (kHexEdge), 12..17 the mid-face nodes of local faces
// 0..5 (kHexFace), 18 the centre. Surface, 5 slots: 0..3 the mid-edge nodes
// of kQuadEdge, 4 the centre (the mid-face node of the quad's one face).
inline constexpr int kHexMidSlots = 19, kQuadMidSlots = 5;
constexpr int mid_slots(Mode mode) { return mode == Mode::Volume ? kHexMidSlots : kQuadMidSlots; }

// The local edge joining corners a and b (either order), -1 if none.
constexpr int hex_edge_between(int a, int b) {
  for (int e = 0; e < 12; ++e)
    if ((kHexEdge[e][0] == a && kHexEdge[e][1] == b) || (kHexEdge[e][0] == b && kHexEdge[e][1] == a)) return e;
  return -1;
}
constexpr int quad_edge_between(int a, int b) {
  for (int e = 0; e < 4; ++e)
    if ((kQuadEdge[e][0] == a && kQuadEdge[e][1] == b) || (kQuadEdge[e][0] == b && kQuadEdge[e][1] == a)) return e;
  return -1;
}
// The local hex face with corners c[0..3] (any order), -1 if none.
constexpr int hex_face_with(const int (&c)[4]) {
  for (int f = 0; f < 6; ++f) {
    int found = 0;
    for (int m = 0; m < 4; ++m)
      for (int q = 0; q < 4; ++q) found += kHexFace[f][q] == c[m];
    if (found == 4) return f;
  }
  return -1;
}

// How the file formats number the nodes after the corners, as the corners
// each one lies between (their own documentation's tables; the tests check
// them against Gmsh's getElementProperties and the Exodus library's side
// node lists). Gmsh (MSH types 17 = HEX20, 12 = HEX27): nodes 8..19 on the
// edges below, 20..25 (HEX27) on the faces below, 26 the centre.
inline constexpr int kGmshHexMidEdge[12][2] = {{0, 1}, {0, 3}, {0, 4}, {1, 2}, {1, 5}, {2, 3},
                                               {2, 6}, {3, 7}, {4, 5}, {4, 7}, {5, 6}, {6, 7}};
inline constexpr int kGmshHexMidFace[6][4] = {{0, 1, 2, 3}, {0, 1, 5, 4}, {0, 3, 7, 4},
                                              {1, 2, 6, 5}, {2, 3, 7, 6}, {4, 5, 6, 7}};
// Exodus (HEX20, HEX27; PATRAN's order): nodes 8..19 on the edges below;
// HEX27: node 20 the centre, 21..26 on the faces -z, +z, -x, +x, -y, +y.
inline constexpr int kExodusHexMidEdge[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {0, 4}, {1, 5},
                                                 {2, 6}, {3, 7}, {4, 5}, {5, 6}, {6, 7}, {7, 4}};
inline constexpr int kExodusHexMidFace[6][4] = {{0, 1, 2, 3}, {4, 5, 6, 7}, {0, 3, 7, 4},
                                                {1, 2, 6, 5}, {0, 1, 5, 4}, {2, 3, 7, 6}};
// Both formats (MSH 16 = QUAD8, 10 = QUAD9; Exodus QUAD8/9, SHELL8/9):
// nodes 4..7 on the edges below, 8 the centre.
inline constexpr int kQuadMidEdge[4][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}};

enum class NodeOrder { Gmsh, Exodus };

// The mid-node slot of node k of a second-order element (k from the number
// of corners up to 26 volume, 8 surface) as `order` numbers it; -1 for any
// other k.
constexpr int mid_slot(NodeOrder order, Mode mode, int k) {
  if (mode == Mode::Surface) {
    if (k >= 4 && k < 8) return quad_edge_between(kQuadMidEdge[k - 4][0], kQuadMidEdge[k - 4][1]);
    return k == 8 ? 4 : -1;
  }
  const bool gmsh = order == NodeOrder::Gmsh;
  if (k >= 8 && k < 20) {
    const int* c = gmsh ? kGmshHexMidEdge[k - 8] : kExodusHexMidEdge[k - 8];
    return hex_edge_between(c[0], c[1]);
  }
  const int face = gmsh ? k - 20 : k - 21, centre = gmsh ? 26 : 20;
  if (k == centre) return 18;
  if (face >= 0 && face < 6) return 12 + hex_face_with(gmsh ? kGmshHexMidFace[face] : kExodusHexMidFace[face]);
  return -1;
}

// Corner neighbours along +i, +j, +k as seen from each hex corner, ordered so
// that det(n0 - c, n1 - c, n2 - c) > 0 for a right-handed hex (Verdict's table).
inline constexpr int kHexCornerNbr[8][3] = {{1, 3, 4}, {2, 0, 5}, {3, 1, 6}, {0, 2, 7},
                                            {7, 5, 0}, {4, 6, 1}, {5, 7, 2}, {6, 4, 3}};

using FaceCode = std::uint8_t;

// Canonical corner index of local corner m under code c.
constexpr int code_corner(FaceCode c, int m) {
  const int r = c & 3, s = (c & 4) ? -1 : 1;
  return ((r + s * m) % 4 + 4) % 4;
}
constexpr FaceCode make_code(int r, bool flip) { return static_cast<FaceCode>((r & 3) | (flip ? 4 : 0)); }
// code_corner(compose(a, b), m) == code_corner(a, code_corner(b, m)).
FaceCode compose(FaceCode a, FaceCode b);
FaceCode inverse(FaceCode a);
// True when the local first axis maps onto the canonical second axis.
constexpr bool code_swaps_axes(FaceCode c) {
  // h0 -> h1 is canonical corner step (r) -> (r+s): along u when {r, r+s}
  // is {0,1} or {2,3}, along v otherwise.
  const int a = code_corner(c, 0), b = code_corner(c, 1);
  const int lo = a < b ? a : b, hi = a < b ? b : a;
  return !((lo == 0 && hi == 1) || (lo == 2 && hi == 3));
}

// Canonical corners of a quad given by its corner vertex ids in local cyclic
// order, and the code relating the local order to them.
struct CanonicalQuad {
  std::array<Id, 4> v;  // canonical corners v0..v3
  FaceCode code;        // local corner m == v[code_corner(code, m)]
};
CanonicalQuad canonical_quad(const std::array<Id, 4>& local);

// Integer affine map from a local face grid to the canonical face grid.
// nu, nv: canonical intervals (u, v). (p, q): local grid point.
struct FaceMap {
  std::int64_t u0, v0;      // canonical point of local (0, 0)
  std::int64_t up, uq, vp, vq;  // du/dp, du/dq, dv/dp, dv/dq in {-1, 0, 1}
  constexpr std::int64_t u(std::int64_t p, std::int64_t q) const { return u0 + up * p + uq * q; }
  constexpr std::int64_t v(std::int64_t p, std::int64_t q) const { return v0 + vp * p + vq * q; }
};

namespace detail {
// Everything below that depends only on (face, code), tabulated once at
// compile time: random queries look these up per face of every point.
struct FaceTables {
  int hex_side_edge[6][8][4], quad_side_edge[8][4];  // see hex_face_side_edge
  int hex_canonical[6][8][4], quad_canonical[8][4];  // see face_canonical_corners
  int unit_map[8][6];  // face_map(code, 1, 1): u0, v0, up, uq, vp, vq
};
constexpr FaceTables make_face_tables() {
  FaceTables t{};
  constexpr int quad_corners[4] = {0, 1, 2, 3};
  // The local edge joining the local corners that hold the canonical ends
  // of `side` (kQuadEdge gives a side's canonical corners).
  auto side_edge = [](const int* face_corners, const int (*edges)[2], int num_edges, int code, int side) {
    int lc[2] = {-1, -1};
    for (int end = 0; end < 2; ++end)
      for (int m = 0; m < 4; ++m)
        if (code_corner(static_cast<FaceCode>(code), m) == kQuadEdge[side][end]) lc[end] = face_corners[m];
    for (int e = 0; e < num_edges; ++e)
      if ((edges[e][0] == lc[0] && edges[e][1] == lc[1]) || (edges[e][0] == lc[1] && edges[e][1] == lc[0])) return e;
    return -1;
  };
  for (int c = 0; c < 8; ++c) {
    for (int side = 0; side < 4; ++side) {
      for (int f = 0; f < 6; ++f) t.hex_side_edge[f][c][side] = side_edge(kHexFace[f], kHexEdge, 12, c, side);
      t.quad_side_edge[c][side] = side_edge(quad_corners, kQuadEdge, 4, c, side);
    }
    for (int m = 0; m < 4; ++m) {
      for (int f = 0; f < 6; ++f) t.hex_canonical[f][c][code_corner(static_cast<FaceCode>(c), m)] = kHexFace[f][m];
      t.quad_canonical[c][code_corner(static_cast<FaceCode>(c), m)] = m;
    }
    // Canonical grid position of local corners 0, 1 and 3 on a unit face.
    int u[4], v[4];
    for (int m : {0, 1, 3}) {
      const int k = code_corner(static_cast<FaceCode>(c), m);
      u[m] = (k == 1 || k == 2) ? 1 : 0;
      v[m] = (k == 2 || k == 3) ? 1 : 0;
    }
    const int row[6] = {u[0], v[0], u[1] - u[0], u[3] - u[0], v[1] - v[0], v[3] - v[0]};
    for (int i = 0; i < 6; ++i) t.unit_map[c][i] = row[i];
  }
  return t;
}
inline constexpr FaceTables kFaceTables = make_face_tables();
}  // namespace detail

// The map of a face with code `code` and canonical intervals (nu, nv): the
// unit face's, scaled (each step is +-1 along one canonical axis).
constexpr FaceMap face_map(FaceCode code, std::int64_t nu, std::int64_t nv) {
  const int* m = detail::kFaceTables.unit_map[code];
  return FaceMap{m[0] * nu, m[1] * nv, m[2], m[3], m[4], m[5]};
}

// Local hex edge (kHexEdge index) that carries canonical side `side` of hex
// face `face` under `code`; sides as in Topology::face_edge: 0 v0v1, 1 v3v2,
// 2 v0v3, 3 v1v2. Table lookup.
constexpr int hex_face_side_edge(int face, FaceCode code, int side) {
  return detail::kFaceTables.hex_side_edge[face][code][side];
}
// The same for a quad (surface mode), whose one face is itself: the local
// quad edge (kQuadEdge index) carrying canonical side `side`.
constexpr int quad_side_edge(FaceCode code, int side) { return detail::kFaceTables.quad_side_edge[code][side]; }

// Canonical corners of local face lf of an element under `code`: the
// element's local corner indices (kHexCorner numbering; surface mode: the
// quad's, lf = 0) of canonical v0..v3. Table lookup.
constexpr const int (&face_canonical_corners(Mode mode, int lf, FaceCode code))[4] {
  return mode == Mode::Volume ? detail::kFaceTables.hex_canonical[lf][code] : detail::kFaceTables.quad_canonical[code];
}

}  // namespace dicer
