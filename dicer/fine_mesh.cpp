// The implicit fine mesh: classification of grid points to their owning
// entity, and evaluation of the TFI recipe in that entity's canonical frame,
// all read from the mesh tables (in memory or paged; the same code).
#include "dicer/fine_mesh.hpp"

#include <algorithm>
#include <atomic>

#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/sheets.hpp"
#include "dicer/tfi.hpp"
#include "dicer/topology.hpp"

namespace dicer {
namespace {

// ---------------------------------------------------------------- records
// Rows copied out of the tables (a row pointer dies when its cursor moves).

struct EdgeRec {
  Id lo, hi, n, off, bound;
};
struct FaceRec {
  Id v[4], e[4], off, nu, nv, bound;
};
struct ElemRec {
  Id conn[8], edge[12], face[6];
  Id elem_off, cell_off, file_id;
  std::int32_t block;
  std::uint64_t flags;
  std::array<Id, 3> n;
  bool rev(int k) const { return (flags >> k) & 1; }
  bool curved() const { return (flags >> kElemCurvedBit) & 1; }
  FaceCode code(int k) const { return static_cast<FaceCode>((flags >> (12 + 3 * k)) & 7); }
};

struct View {
  const MeshTables& t;
  MeshCursor& c;
  ElementLayout L;

  // Rows are data, not trust (a store can be crafted with valid checksums):
  // every id read is checked against its table and every interval against
  // the fine element count before anything is sized or indexed by it.
  [[noreturn]] void corrupt(const char* what, Id row) const {
    throw Error(ErrorKind::Corrupt, (t.origin.empty() ? std::string("in memory") : t.origin) +
                                        ": inconsistent mesh tables: " + what + " row " + std::to_string(row));
  }
  void check(bool ok, const char* what, Id row) const {
    if (!ok) corrupt(what, row);
  }

  Vec3 vertex(Id v) const {
    const double* r = t.vertices.row(v, c.vertices);
    return {r[0], r[1], r[2]};
  }
  EdgeRec edge(Id e) const {
    check(e >= 0 && e < t.edges.rows(), "edge id out of range in a face or element", e);
    const std::int64_t* r = t.edges.row(e, c.edges);
    const EdgeRec rec{r[kEdgeLo], r[kEdgeHi], r[kEdgeN], r[kEdgeNodeOffset], r[kEdgeBound]};
    const Id nv = t.vertices.rows();
    check(rec.lo >= 0 && rec.lo < nv && rec.hi >= 0 && rec.hi < nv && rec.n >= 1 && rec.n <= (Id{1} << 40) &&
              rec.off >= 0 && (rec.bound == -1 || (rec.bound >= 0 && rec.bound <= t.bounding.rows() - (rec.n - 1))),
          "edge", e);
    return rec;
  }
  FaceRec face(Id f) const {
    check(f >= 0 && f < t.faces.rows(), "face id out of range in an element", f);
    const std::int64_t* r = t.faces.row(f, c.faces);
    FaceRec rec;
    for (int k = 0; k < 4; ++k) rec.v[k] = r[kFaceV + k], rec.e[k] = r[kFaceE + k];
    rec.off = r[kFaceNodeOffset];
    rec.bound = r[kFaceBound];
    for (int k = 0; k < 4; ++k) check(rec.v[k] >= 0 && rec.v[k] < t.vertices.rows(), "face", f);
    rec.nu = edge(rec.e[0]).n;
    rec.nv = edge(rec.e[2]).n;
    check(rec.bound == -1 || (rec.bound >= 0 && rec.bound <= t.bounding.rows() - (rec.nu - 1) * (rec.nv - 1)), "face", f);
    return rec;
  }
  ElemRec element(Id h) const {
    check(h >= 0 && h < t.elements.rows(), "element id out of range", h);
    const std::int64_t* r = t.elements.row(h, c.elements);
    ElemRec rec{};
    for (int k = 0; k < L.corners; ++k) rec.conn[k] = r[L.conn() + k];
    for (int k = 0; k < L.edges; ++k) rec.edge[k] = r[L.edge() + k];
    for (int k = 0; k < L.faces; ++k) rec.face[k] = r[L.face() + k];
    rec.elem_off = r[L.elem_offset()], rec.cell_off = r[L.cell_offset()];
    rec.block = static_cast<std::int32_t>(r[L.block()]);
    rec.file_id = r[L.file_id()];
    rec.flags = static_cast<std::uint64_t>(r[L.flags()]);
    rec.n = {r[L.n()], r[L.n() + 1], r[L.n() + 2]};
    const Id nv = t.vertices.rows();
    for (int k = 0; k < L.corners; ++k) check(rec.conn[k] >= 0 && rec.conn[k] < nv, "element corner of", h);
    for (int k = 0; k < L.edges; ++k) check(rec.edge[k] >= 0 && rec.edge[k] < t.edges.rows(), "element edge of", h);
    for (int k = 0; k < L.faces; ++k) check(rec.face[k] >= 0 && rec.face[k] < t.faces.rows(), "element face of", h);
    // Intervals: each >= 1, the block no bigger than 2^40 points (a larger
    // one could never be allocated anyway).
    __int128 points = 1;
    for (int k = 0; k < 3; ++k) {
      check(rec.n[k] >= 1 && rec.n[k] <= (Id{1} << 40), "element interval of", h);
      points *= rec.n[k] + 1;
    }
    check(points <= (static_cast<__int128>(1) << 40) && rec.elem_off >= 0 && rec.cell_off >= 0 && rec.block >= 0,
          "element", h);
    return rec;
  }

  // A predicted point corrected by bounding row `row` (a node on the CAD).
  Vec3 moved(const Vec3& p, Id row) const {
    const std::int64_t* r = t.bounding.row(row, c.bounding);
    return {tfi::bounding_apply(p.x, r[0]), tfi::bounding_apply(p.y, r[1]), tfi::bounding_apply(p.z, r[2])};
  }
  // Equal spacing, canonical t in [0, n]; moved onto the CAD when bounded.
  Vec3 edge_point(const EdgeRec& e, Id t) const {
    if (t == 0) return vertex(e.lo);
    if (t == e.n) return vertex(e.hi);
    const Vec3 a = vertex(e.lo), b = vertex(e.hi);
    const double s = tfi::weight(t, e.n);
    const Vec3 p{tfi::edge(a.x, b.x, s), tfi::edge(a.y, b.y, s), tfi::edge(a.z, b.z, s)};
    return e.bound < 0 ? p : moved(p, e.bound + t - 1);
  }
  // Side k of a face (0 v0v1, 1 v3v2, 2 v0v3, 3 v1v2) at face parameter s.
  Vec3 face_side(const FaceRec& f, int k, Id s) const {
    const EdgeRec e = edge(f.e[k]);
    const bool rev = f.v[kQuadEdge[k][0]] > f.v[kQuadEdge[k][1]];
    return edge_point(e, rev ? e.n - s : s);
  }
  // Coons interior point at (u, v) from the four sides' values there
  // (bottom, top, left, right) and the canonical corners p[0..3].
  static Vec3 coons_point(Id nu, Id nv, Id u, Id v, const Vec3* s, const Vec3* p) {
    const double a = tfi::weight(u, nu), b = tfi::weight(v, nv);
    return {tfi::coons(a, b, s[0].x, s[1].x, s[2].x, s[3].x, p[0].x, p[1].x, p[2].x, p[3].x),
            tfi::coons(a, b, s[0].y, s[1].y, s[2].y, s[3].y, p[0].y, p[1].y, p[2].y, p[3].y),
            tfi::coons(a, b, s[0].z, s[1].z, s[2].z, s[3].z, p[0].z, p[1].z, p[2].z, p[3].z)};
  }
  Vec3 face_interior(const FaceRec& f, Id u, Id v, const Vec3* s) const {
    const Vec3 p[4] = {vertex(f.v[0]), vertex(f.v[1]), vertex(f.v[2]), vertex(f.v[3])};
    const Vec3 x = coons_point(f.nu, f.nv, u, v, s, p);
    return f.bound < 0 ? x : moved(x, f.bound + (u - 1) + (v - 1) * (f.nu - 1));
  }
  Vec3 face_point(const FaceRec& f, Id u, Id v) const {
    if (v == 0) return face_side(f, 0, u);
    if (v == f.nv) return face_side(f, 1, u);
    if (u == 0) return face_side(f, 2, v);
    if (u == f.nu) return face_side(f, 3, v);
    const Vec3 sides[4] = {face_side(f, 0, u), face_side(f, 1, u), face_side(f, 2, v), face_side(f, 3, v)};
    return face_interior(f, u, v, sides);
  }
  // Hex interior point: its 12 edge points and 6 face points, then
  // tfi::hex_row + tfi::hex_point as the block fill does. Every input comes
  // from the element row and its 8 corners alone: an edge's ends and a
  // face's corners are hex corners, and every interval is the hex's own
  // along that axis. The values (and so the bits) are those the owners
  // compute; only the row lookups are saved.
  Vec3 cell_point(const ElemRec& h, Id i, Id j, Id k) const {
    const Id t[3] = {i, j, k};
    Vec3 corner[8];
    for (int q = 0; q < 8; ++q) corner[q] = vertex(h.conn[q]);
    double f[3][6], e[3][12], c[3][8];
    if (h.curved()) {
      // Some boundary is on the CAD: take each edge and face point from its
      // owner (moved values included), exactly as the block fill gathers them.
      for (int q = 0; q < 12; ++q) {
        const EdgeRec er = edge(h.edge[q]);
        const Id n = h.n[q / 4], tc = h.rev(q) ? n - t[q / 4] : t[q / 4];
        check(er.n == n, "interval disagrees with an element using edge", h.edge[q]);
        const Vec3 x = edge_point(er, tc);
        e[0][q] = x.x, e[1][q] = x.y, e[2][q] = x.z;
      }
      for (int q = 0; q < 6; ++q) {
        const FaceRec fr = face(h.face[q]);
        const FaceMap fm = face_map(h.code(q), fr.nu, fr.nv);
        const Id a = t[kHexFaceAxes[q][0]], b = t[kHexFaceAxes[q][1]];
        const Vec3 x = face_point(fr, fm.u(a, b), fm.v(a, b));
        f[0][q] = x.x, f[1][q] = x.y, f[2][q] = x.z;
      }
    }
    for (int q = 0; q < 12 && !h.curved(); ++q) {
      // Canonical direction: lo -> hi vertex id; rev means local end 1 is lo.
      const bool rev = h.rev(q);
      const Vec3& a = corner[kHexEdge[q][rev ? 1 : 0]];
      const Vec3& b = corner[kHexEdge[q][rev ? 0 : 1]];
      const Id n = h.n[q / 4], tc = rev ? n - t[q / 4] : t[q / 4];
      const double s = tfi::weight(tc, n);
      e[0][q] = tfi::edge(a.x, b.x, s), e[1][q] = tfi::edge(a.y, b.y, s), e[2][q] = tfi::edge(a.z, b.z, s);
    }
    for (int q = 0; q < 6 && !h.curved(); ++q) {
      const FaceCode code = h.code(q);
      // Canonical corner m is local face corner m' with code_corner(code, m') == m.
      FaceRec fa{};
      for (int m = 0; m < 4; ++m) fa.v[code_corner(code, m)] = kHexFace[q][m];  // hex corner index, not a vertex id
      const bool swap = code_swaps_axes(code);
      fa.nu = h.n[kHexFaceAxes[q][swap ? 1 : 0]];
      fa.nv = h.n[kHexFaceAxes[q][swap ? 0 : 1]];
      const FaceMap fm = face_map(code, fa.nu, fa.nv);
      const Id a = t[kHexFaceAxes[q][0]], b = t[kHexFaceAxes[q][1]];
      Vec3 sides[4];
      for (int side = 0; side < 4; ++side) {
        const int le = hex_face_side_edge(q, code, side);
        sides[side] = {e[0][le], e[1][le], e[2][le]};
      }
      const Vec3 pc[4] = {corner[fa.v[0]], corner[fa.v[1]], corner[fa.v[2]], corner[fa.v[3]]};
      const Vec3 x = coons_point(fa.nu, fa.nv, fm.u(a, b), fm.v(a, b), sides, pc);
      f[0][q] = x.x, f[1][q] = x.y, f[2][q] = x.z;
    }
    for (int q = 0; q < 8; ++q) c[0][q] = corner[q].x, c[1][q] = corner[q].y, c[2][q] = corner[q].z;
    const double u = tfi::weight(i, h.n[0]), v = tfi::weight(j, h.n[1]), w = tfi::weight(k, h.n[2]);
    double out[3];
    for (int d = 0; d < 3; ++d) {
      const tfi::HexRow row = tfi::hex_row(v, w, f[d][0], f[d][1], e[d], c[d]);
      out[d] = tfi::hex_point(row, u, 1.0 - u, f[d][2], f[d][3], f[d][4], f[d][5], e[d][0], e[d][1], e[d][2], e[d][3]);
    }
    return {out[0], out[1], out[2]};
  }

  // Every interior point of face f in its canonical frame (u fastest, the
  // order of its node ids), one array per coordinate in s.face, moved onto
  // the CAD when bounded: the sides gathered as face_point gathers them.
  // Block fills and the node cursor both fill faces through this.
  void face_fill(const FaceRec& f, FineBlock::Scratch& s) const {
    const Id nu = f.nu, nv = f.nv;
    auto gather = [&](int k, Id len, std::vector<double>* out) {
      for (int d = 0; d < 3; ++d) out[d].resize(static_cast<size_t>(len + 1));
      for (Id q = 1; q < len; ++q) {
        const Vec3 x = face_side(f, k, q);
        out[0][q] = x.x, out[1][q] = x.y, out[2][q] = x.z;
      }
    };
    gather(0, nu, s.bottom), gather(1, nu, s.top), gather(2, nv, s.left), gather(3, nv, s.right);
    s.s.resize(static_cast<size_t>(nu)), s.t.resize(static_cast<size_t>(nv));
    for (Id u = 1; u < nu; ++u) s.s[u] = tfi::weight(u, nu);
    for (Id v = 1; v < nv; ++v) s.t[v] = tfi::weight(v, nv);
    const Vec3 pc[4] = {vertex(f.v[0]), vertex(f.v[1]), vertex(f.v[2]), vertex(f.v[3])};
    const size_t m = static_cast<size_t>((nu - 1) * (nv - 1));
    for (int d = 0; d < 3; ++d) {
      auto comp = [&](const Vec3& p) { return d == 0 ? p.x : d == 1 ? p.y : p.z; };
      const double p0 = comp(pc[0]), p1 = comp(pc[1]), p2 = comp(pc[2]), p3 = comp(pc[3]);
      s.face[d].resize(m);
      double* out = s.face[d].data();
      const double *B = s.bottom[d].data(), *T = s.top[d].data(), *Lf = s.left[d].data(), *R = s.right[d].data();
      for (Id v = 1; v < nv; ++v) {
        const double tv = s.t[v];
        for (Id u = 1; u < nu; ++u) *out++ = tfi::coons(s.s[u], tv, B[u], T[u], Lf[v], R[v], p0, p1, p2, p3);
      }
    }
    if (f.bound >= 0)  // on the CAD: the stored corrections, as face_interior applies them
      for (size_t q = 0; q < m; ++q) {
        const std::int64_t* r = t.bounding.row(f.bound + static_cast<Id>(q), c.bounding);
        for (int d = 0; d < 3; ++d) s.face[d][q] = tfi::bounding_apply(s.face[d][q], r[d]);
      }
  }

  NodeRef grid_node(const ElemRec& h, Id hid, Id i, Id j, Id k) const {
    const auto& n = h.n;
    NodeRef r;
    if (t.mode == Mode::Surface) {
      const int ex = (i == 0 || i == n[0]) + (j == 0 || j == n[1]);
      if (ex == 2) {
        static constexpr int kCorner[2][2] = {{0, 3}, {1, 2}};  // [i>0][j>0]
        r.kind = EntityKind::Vertex;
        r.entity = h.conn[kCorner[i > 0][j > 0]];
        return r;
      }
      if (ex == 1) {
        const int le = j == 0 ? 0 : j == n[1] ? 1 : i == 0 ? 2 : 3;
        const Id tt = le < 2 ? i : j;
        r.kind = EntityKind::Edge;
        r.entity = h.edge[le];
        r.local[0] = h.rev(le) ? edge(h.edge[le]).n - tt : tt;
        return r;
      }
      const FaceRec f = face(h.face[0]);
      const FaceMap fm = face_map(h.code(0), f.nu, f.nv);
      r.kind = EntityKind::Face;
      r.entity = h.face[0];
      r.local = {fm.u(i, j), fm.v(i, j), 0};
      return r;
    }
    const Id p[3] = {i, j, k};
    int ext[3];  // -1 interior, 0 low side, 1 high side
    int count = 0;
    for (int a = 0; a < 3; ++a) {
      ext[a] = p[a] == 0 ? 0 : p[a] == n[a] ? 1 : -1;
      count += ext[a] >= 0;
    }
    if (count == 3) {
      static constexpr int kCorner[2][2][2] = {{{0, 4}, {3, 7}}, {{1, 5}, {2, 6}}};  // [i][j][k]
      r.kind = EntityKind::Vertex;
      r.entity = h.conn[kCorner[ext[0]][ext[1]][ext[2]]];
      return r;
    }
    if (count == 2) {
      const int axis = ext[0] < 0 ? 0 : ext[1] < 0 ? 1 : 2;
      int le;
      if (axis == 0) le = ext[1] + 2 * ext[2];
      else if (axis == 1) le = 4 + ext[0] + 2 * ext[2];
      else le = 8 + (ext[1] ? 3 - ext[0] : ext[0]);  // (0,0)->8 (1,0)->9 (1,1)->10 (0,1)->11
      r.kind = EntityKind::Edge;
      r.entity = h.edge[le];
      r.local[0] = h.rev(le) ? n[axis] - p[axis] : p[axis];
      return r;
    }
    if (count == 1) {
      const int axis = ext[0] >= 0 ? 0 : ext[1] >= 0 ? 1 : 2;
      const int lf = 2 * axis + ext[axis];
      const FaceRec f = face(h.face[lf]);
      const FaceMap fm = face_map(h.code(lf), f.nu, f.nv);
      const Id a = p[kHexFaceAxes[lf][0]], b = p[kHexFaceAxes[lf][1]];
      r.kind = EntityKind::Face;
      r.entity = h.face[lf];
      r.local = {fm.u(a, b), fm.v(a, b), 0};
      return r;
    }
    r.kind = EntityKind::Cell;
    r.entity = hid;
    r.local = {i, j, k};
    return r;
  }

  Vec3 node(const NodeRef& r) const {
    switch (r.kind) {
      case EntityKind::Vertex: return vertex(r.entity);
      case EntityKind::Edge: return edge_point(edge(r.entity), r.local[0]);
      case EntityKind::Face: return face_point(face(r.entity), r.local[0], r.local[1]);
      case EntityKind::Cell: return cell_point(element(r.entity), r.local[0], r.local[1], r.local[2]);
    }
    return {};
  }
};

// Hex interior, one coordinate, from the block's boundary values:
// tfi::hex_row once per (j, k), tfi::hex_point along i, the same two calls
// View::cell_point() makes, fed the same boundary values. Built twice
// (AVX2 and baseline x86-64): both are plain IEEE mul/add/sub in the same
// order with contraction off, so both give the same bits.
// (ThreadSanitizer builds: GCC 12's ifunc resolver for target_clones runs
// before the TSan runtime is up and crashes the binary at start-up.)
#if defined(__SANITIZE_THREAD__)
#define DICER_CLONES
#else
#define DICER_CLONES __attribute__((target_clones("avx2", "default")))
#endif
// One interior plane k (0 < k < n[2]) of one coordinate: a0 and aN are the
// planes k = 0 and k = n[2], ak plane k with its ring (i or j at 0 or n)
// filled; all three with row stride n[0] + 1. A plane at a time, so a block
// can be produced in slabs (cursors hold O(n^2), not O(n^3)).
DICER_CLONES void hex_interior_plane(const double* a0, const double* aN, double* ak, std::array<Id, 3> n, Id k,
                                     const double* u, const double* U) {
  const Id sj = n[0] + 1;
  const Id n1 = n[1] * sj;
  double c[8];
  for (int q = 0; q < 8; ++q) c[q] = (kHexCorner[q][2] ? aN : a0)[kHexCorner[q][0] * n[0] + kHexCorner[q][1] * n1];
  const double* e0 = a0;       // (i, 0, 0)
  const double* e1 = a0 + n1;  // (i, n1, 0)
  const double* e2 = aN;       // (i, 0, n2)
  const double* e3 = aN + n1;  // (i, n1, n2)
  const double w = tfi::weight(k, n[2]);
  const double* f2 = ak;       // (i, 0, k)
  const double* f3 = ak + n1;  // (i, n1, k)
  for (Id j = 1; j < n[1]; ++j) {
    const double v = tfi::weight(j, n[1]);
    const double* f4 = a0 + j * sj;  // (i, j, 0)
    const double* f5 = aN + j * sj;  // (i, j, n2)
    const double e[12] = {0, 0, 0, 0, a0[j * sj], a0[n[0] + j * sj], aN[j * sj], aN[n[0] + j * sj],
                          ak[0], ak[n[0]], ak[n[0] + n1], ak[n1]};
    const tfi::HexRow row = tfi::hex_row(v, w, ak[j * sj], ak[n[0] + j * sj], e, c);
    double* out = ak + j * sj;
    for (Id i = 1; i < n[0]; ++i)
      out[i] = tfi::hex_point(row, u[i], U[i], f2[i], f3[i], f4[i], f5[i], e0[i], e1[i], e2[i], e3[i]);
  }
}

// ---------------------------------------------------------------- dice

// Coarse mesh + topology + intervals -> the four tables and the metadata.
FineMesh compile(std::shared_ptr<const CoarseMesh> cm, const Topology& t, const Numbering& num,
                 const std::vector<Id>& edge_sheet, Id num_sheets) {
  const CoarseMesh& m = *cm;
  MeshTables tab;
  tab.mode = m.mode;
  const ElementLayout L = tab.layout();
  std::vector<double> verts(static_cast<size_t>(m.num_vertices()) * 3);
  for (Id v = 0; v < m.num_vertices(); ++v) verts[3 * v] = m.x[v], verts[3 * v + 1] = m.y[v], verts[3 * v + 2] = m.z[v];
  // Lowest coarse element using each vertex, edge and face (chunk ownership).
  const int epe = t.edges_per_element(), fpe = t.faces_per_element(), cpe = m.corners_per_element();
  std::vector<std::int64_t> vmin(static_cast<size_t>(m.num_vertices()), -1), emin(static_cast<size_t>(t.num_edges()), -1),
      fmin(static_cast<size_t>(t.num_faces()), -1);
  for (Id h = m.num_elements() - 1; h >= 0; --h) {
    for (int k = 0; k < cpe; ++k) vmin[m.conn[static_cast<size_t>(h) * cpe + k]] = h;
    for (int k = 0; k < epe; ++k) emin[t.elem_edge[static_cast<size_t>(h) * epe + k]] = h;
    for (int k = 0; k < fpe; ++k) fmin[t.elem_face[static_cast<size_t>(h) * fpe + k]] = h;
  }
  std::vector<std::int64_t> edges(static_cast<size_t>(t.num_edges()) * kEdgeWidth);
  for (Id e = 0; e < t.num_edges(); ++e) {
    std::int64_t* r = &edges[static_cast<size_t>(e) * kEdgeWidth];
    r[kEdgeLo] = t.edge_v[2 * e], r[kEdgeHi] = t.edge_v[2 * e + 1], r[kEdgeN] = num.edge_n(e);
    r[kEdgeNodeOffset] = num.edge_node_offset(e), r[kEdgeSheet] = edge_sheet[e], r[kEdgeMinElement] = emin[e];
    r[kEdgeOwner] = -1, r[kEdgeBound] = -1;
  }
  std::vector<std::int64_t> faces(static_cast<size_t>(t.num_faces()) * kFaceWidth);
  for (Id f = 0; f < t.num_faces(); ++f) {
    std::int64_t* r = &faces[static_cast<size_t>(f) * kFaceWidth];
    for (int k = 0; k < 4; ++k) r[kFaceV + k] = t.face_v[4 * f + k], r[kFaceE + k] = t.face_edge[4 * f + k];
    r[kFaceNodeOffset] = num.face_node_offset(f);
    r[kFaceMinElement] = fmin[f];
    r[kFaceOwner] = -1, r[kFaceBound] = -1;
  }
  const Id ne = m.num_elements();
  const int W = L.width();
  std::vector<std::int64_t> elems(static_cast<size_t>(ne) * W);
  MeshInfo info;
  info.mode = m.mode;
  info.source = m.source;
  info.blocks = m.blocks;
  info.block_coarse_elements.assign(m.blocks.size(), 0);
  info.block_fine_elements.assign(m.blocks.size(), 0);
  for (Id h = 0; h < ne; ++h) {
    std::int64_t* r = &elems[static_cast<size_t>(h) * W];
    for (int k = 0; k < L.corners; ++k) r[L.conn() + k] = m.conn[static_cast<size_t>(h) * L.corners + k];
    std::uint64_t flags = 0;
    for (int k = 0; k < L.edges; ++k) {
      r[L.edge() + k] = t.elem_edge[static_cast<size_t>(h) * L.edges + k];
      flags |= static_cast<std::uint64_t>(t.elem_edge_rev[static_cast<size_t>(h) * L.edges + k]) << k;
    }
    for (int k = 0; k < L.faces; ++k) {
      r[L.face() + k] = t.elem_face[static_cast<size_t>(h) * L.faces + k];
      flags |= static_cast<std::uint64_t>(t.elem_face_code[static_cast<size_t>(h) * L.faces + k]) << (12 + 3 * k);
    }
    r[L.elem_offset()] = num.elem_first_element(h);
    r[L.cell_offset()] = m.mode == Mode::Volume ? num.cell_node_offset(h) : num.num_nodes();
    r[L.block()] = m.element_block[h];
    r[L.file_id()] = m.element_file_id[h];
    r[L.flags()] = static_cast<std::int64_t>(flags);
    const auto n = num.elem_n(h);
    r[L.n()] = n[0], r[L.n() + 1] = n[1], r[L.n() + 2] = n[2];
    ++info.block_coarse_elements[m.element_block[h]];
    info.block_fine_elements[m.element_block[h]] += n[0] * n[1] * n[2];
  }
  tab.vertices = Table<double>(3, std::move(verts));
  tab.vertex_elements = Table<std::int64_t>(1, std::move(vmin));
  tab.edges = Table<std::int64_t>(kEdgeWidth, std::move(edges));
  tab.faces = Table<std::int64_t>(kFaceWidth, std::move(faces));
  tab.elements = Table<std::int64_t>(W, std::move(elems));
  tab.bounding = Table<std::int64_t>(3, {});
  std::vector<std::int32_t> vowner(static_cast<size_t>(m.num_vertices()) * 2, -1);
  for (size_t v = 0; v < m.vertex_geo_dim.size() && v < m.vertex_geo_tag.size(); ++v)
    vowner[2 * v] = m.vertex_geo_dim[v], vowner[2 * v + 1] = m.vertex_geo_tag[v];
  tab.vertex_owner = Table<std::int32_t>(2, std::move(vowner));
  info.coarse_vertices = m.num_vertices();
  info.coarse_edges = t.num_edges();
  info.coarse_faces = t.num_faces();
  info.coarse_elements = ne;
  info.sheets = num_sheets;
  info.nodes = num.num_nodes();
  info.elements = num.num_elements();
  info.kind_base = num.kind_base();
  return FineMesh(std::move(info), std::move(tab), std::move(cm));
}

}  // namespace

FineMesh::FineMesh(MeshInfo info, MeshTables tables, std::shared_ptr<const CoarseMesh> coarse)
    : info_(std::move(info)), tables_(std::move(tables)), coarse_(std::move(coarse)) {}

FineMesh FineMesh::dice(CoarseMesh coarse, const IntervalRequest& request, std::vector<std::string>* notes,
                        bool locality_order) {
  // Sheets and intervals on the input numbering, so sheet ids are the input file's.
  const Topology t0 = build_topology(coarse);
  const Sheets s0 = find_sheets(coarse, t0);
  IntervalPlan plan = resolve_intervals(coarse, t0, s0, request);
  if (notes) *notes = plan.notes;
  // Locality order, then the topology the fine mesh is numbered by.
  std::vector<Id> old_vertex;
  std::shared_ptr<CoarseMesh> ordered;
  if (locality_order) {
    ordered = std::make_shared<CoarseMesh>(sfc_order(coarse, &old_vertex));
  } else {
    old_vertex.resize(static_cast<size_t>(coarse.num_vertices()));
    for (Id v = 0; v < coarse.num_vertices(); ++v) old_vertex[v] = v;
    ordered = std::make_shared<CoarseMesh>(std::move(coarse));
  }
  const Topology t = build_topology(*ordered);
  std::vector<Id> edge_sheet(static_cast<size_t>(t.num_edges())), edge_n(static_cast<size_t>(t.num_edges()));
  for (Id e = 0; e < t.num_edges(); ++e) {
    const Id old = find_edge(t0, old_vertex[t.edge_v[2 * e]], old_vertex[t.edge_v[2 * e + 1]]);
    edge_sheet[e] = s0.edge_sheet[old];
    edge_n[e] = plan.sheet_interval[edge_sheet[e]];
  }
  const Numbering num(t, std::move(edge_n));
  FineMesh f = compile(ordered, t, num, edge_sheet, s0.num_sheets());
  f.sheet_intervals_ = std::move(plan.sheet_interval);
  return f;
}

// ---------------------------------------------------------------- geometry

std::uint64_t FineMesh::next_serial() {
  static std::atomic<std::uint64_t> last{0};
  return ++last;
}

void FineMesh::require_memory(const char* what) const {
  if (!tables_.edges.in_memory() || !tables_.bounding.in_memory())
    throw Error(ErrorKind::Usage, std::string(what) + ": the mesh must be diced in this process (not opened from a store)");
}

void FineMesh::set_vertex(Id v, const Vec3& x, int dim, int tag) {
  require_memory("set_vertex");
  serial_ = next_serial();
  if (tables_.bounding.rows() > 0) throw Error(ErrorKind::Usage, "set_vertex after nodes were moved");
  auto& m = tables_.vertices.memory();
  m[3 * v] = x.x, m[3 * v + 1] = x.y, m[3 * v + 2] = x.z;
  auto& o = tables_.vertex_owner.memory();
  o[2 * v] = dim, o[2 * v + 1] = tag;
}

void FineMesh::set_owner(EntityKind kind, Id entity, std::int64_t owner) {
  require_memory("set_owner");
  serial_ = next_serial();
  if (kind == EntityKind::Edge) tables_.edges.memory()[static_cast<size_t>(entity) * kEdgeWidth + kEdgeOwner] = owner;
  else if (kind == EntityKind::Face) tables_.faces.memory()[static_cast<size_t>(entity) * kFaceWidth + kFaceOwner] = owner;
  else throw Error(ErrorKind::Usage, "set_owner: only edges and faces carry owners");
}

std::int64_t FineMesh::owner(EntityKind kind, Id entity, MeshCursor& cur) const {
  if (kind == EntityKind::Edge) return tables_.edges.row(entity, cur.edges)[kEdgeOwner];
  if (kind == EntityKind::Face) return tables_.faces.row(entity, cur.faces)[kFaceOwner];
  if (kind == EntityKind::Vertex) {
    const std::int32_t* r = tables_.vertex_owner.row(entity, cur.vertex_owner);
    return r[0] < 0 ? -1 : pack_owner(r[0], r[1]);
  }
  return -1;
}

void FineMesh::move_nodes(EntityKind kind, Id entity, std::span<const Vec3> xyz) {
  require_memory("move_nodes");
  serial_ = next_serial();
  MeshCursor cur;
  const View V{tables_, cur, tables_.layout()};
  std::vector<Vec3> pred;
  std::int64_t* bound = nullptr;
  if (kind == EntityKind::Edge) {
    if (faces_moved_) throw Error(ErrorKind::Usage, "move_nodes: every edge must be moved before any face");
    const EdgeRec e = V.edge(entity);
    if (e.bound >= 0) throw Error(ErrorKind::Usage, "move_nodes: edge " + std::to_string(entity) + " moved twice");
    for (Id t = 1; t < e.n; ++t) pred.push_back(V.edge_point(e, t));
    bound = &tables_.edges.memory()[static_cast<size_t>(entity) * kEdgeWidth + kEdgeBound];
  } else if (kind == EntityKind::Face) {
    faces_moved_ = true;
    const FaceRec f = V.face(entity);
    if (f.bound >= 0) throw Error(ErrorKind::Usage, "move_nodes: face " + std::to_string(entity) + " moved twice");
    for (Id v = 1; v < f.nv; ++v)
      for (Id u = 1; u < f.nu; ++u) pred.push_back(V.face_point(f, u, v));  // Coons of the moved sides
    bound = &tables_.faces.memory()[static_cast<size_t>(entity) * kFaceWidth + kFaceBound];
  } else {
    throw Error(ErrorKind::Usage, "move_nodes: only edge and face nodes are moved");
  }
  if (xyz.size() != pred.size())
    throw Error(ErrorKind::Usage, "move_nodes: " + std::to_string(xyz.size()) + " points given for " +
                                      std::to_string(pred.size()) + " nodes");
  if (pred.empty()) return;
  auto& b = tables_.bounding.memory();
  *bound = tables_.bounding.rows();
  for (size_t q = 0; q < pred.size(); ++q) {
    b.push_back(tfi::bounding_code(pred[q].x, xyz[q].x));
    b.push_back(tfi::bounding_code(pred[q].y, xyz[q].y));
    b.push_back(tfi::bounding_code(pred[q].z, xyz[q].z));
  }
  tables_.bounding.reshape();
}

void FineMesh::finish_moves() {
  require_memory("finish_moves");
  serial_ = next_serial();
  const ElementLayout L = tables_.layout();
  auto& el = tables_.elements.memory();
  const auto& ed = tables_.edges.memory();
  const auto& fa = tables_.faces.memory();
  for (Id h = 0; h < tables_.elements.rows(); ++h) {
    std::int64_t* r = &el[static_cast<size_t>(h) * L.width()];
    bool curved = false;
    for (int k = 0; k < L.edges; ++k) curved |= ed[static_cast<size_t>(r[L.edge() + k]) * kEdgeWidth + kEdgeBound] >= 0;
    for (int k = 0; k < L.faces; ++k) curved |= fa[static_cast<size_t>(r[L.face() + k]) * kFaceWidth + kFaceBound] >= 0;
    const std::uint64_t flags = static_cast<std::uint64_t>(r[L.flags()]) & ~(std::uint64_t{1} << kElemCurvedBit);
    r[L.flags()] = static_cast<std::int64_t>(flags | (static_cast<std::uint64_t>(curved) << kElemCurvedBit));
  }
}

// ---------------------------------------------------------------- queries

Vec3 FineMesh::node(Id id) const {
  MeshCursor cur;
  return node(id, cur);
}

Vec3 FineMesh::node(Id id, MeshCursor& cur) const {
  if (id < 0 || id >= num_nodes())
    throw Error(ErrorKind::Usage, "node id " + std::to_string(id) + " is out of range (the mesh has " +
                                      std::to_string(num_nodes()) + " nodes)");
  return node(locate_node(id, cur), cur);
}

Vec3 FineMesh::node(const NodeRef& ref, MeshCursor& cur) const {
  return View{tables_, cur, tables_.layout()}.node(ref);
}

NodeRef FineMesh::locate_node(Id id, MeshCursor& cur) const {
  return dicer::locate_node(tables_, info_.kind_base, info_.nodes, id, cur);
}
Id FineMesh::node_id(const NodeRef& ref, MeshCursor& cur) const {
  return dicer::node_id(tables_, info_.kind_base, ref, cur);
}
Id FineMesh::locate_element(Id id, std::array<Id, 3>& ijk, MeshCursor& cur) const {
  return dicer::locate_element(tables_, id, ijk, cur);
}

NodeRef FineMesh::grid_node(Id h, Id i, Id j, Id k, MeshCursor& cur) const {
  const View v{tables_, cur, tables_.layout()};
  return v.grid_node(v.element(h), h, i, j, k);
}

FineElement FineMesh::element(Id id) const {
  MeshCursor cur;
  return element(id, cur);
}

FineElement FineMesh::element(Id id, MeshCursor& cur) const {
  if (id < 0 || id >= num_elements())
    throw Error(ErrorKind::Usage, "element id " + std::to_string(id) + " is out of range (the mesh has " +
                                      std::to_string(num_elements()) + " elements)");
  const View v{tables_, cur, tables_.layout()};
  FineElement el;
  el.id = id;
  el.coarse_element = dicer::locate_element(tables_, id, el.ijk, cur);
  const ElemRec h = v.element(el.coarse_element);
  el.block = h.block;
  const auto [i, j, k] = el.ijk;
  const bool vol = mode() == Mode::Volume;
  el.num_nodes = vol ? 8 : 4;
  for (int q = 0; q < el.num_nodes; ++q)
    el.nodes[q] = dicer::node_id(
        tables_, info_.kind_base,
        v.grid_node(h, el.coarse_element, i + kHexCorner[q][0], j + kHexCorner[q][1], vol ? k + kHexCorner[q][2] : 0),
        cur);
  return el;
}

// ---------------------------------------------------------------- blocks

namespace {
// The boundary of coarse element h (corners, edges, faces) into b's
// scratch (Boundary::index): ids always, coordinates if asked.
void fill_boundary(const View& V, std::uint64_t mesh, const ElemRec& h, Id hid, FineBlock& b, bool coords) {
  const auto n = h.n;
  const bool vol = V.t.mode == Mode::Volume;
  auto& B = b.scratch.boundary;
  B.mesh = mesh, B.h = hid, B.coords = coords, B.n = n, B.volume = vol;
  const size_t nb = static_cast<size_t>(B.size());
  B.id.resize(nb);
  for (int d = 0; d < 3; ++d) coords ? B.x[d].resize(nb) : B.x[d].clear();
  Id* ids = B.id.data();
  double* X[3] = {B.x[0].data(), B.x[1].data(), B.x[2].data()};
  auto put = [&](Id g, Id id, const Vec3& p) {
    ids[g] = id;
    if (coords) X[0][g] = p.x, X[1][g] = p.y, X[2][g] = p.z;
  };
  auto grid = [&](const int* c, int axis, Id t) {  // boundary slot of corner c, moved to t along axis
    Id p[3] = {c[0] * n[0], c[1] * n[1], vol ? c[2] * n[2] : 0};
    if (axis >= 0) p[axis] = t;
    return B.index(p[0], p[1], p[2]);
  };
  for (int q = 0; q < V.L.corners; ++q) put(grid(kHexCorner[q], -1, 0), h.conn[q], coords ? V.vertex(h.conn[q]) : Vec3{});

  // Edges: every interior point from edge_point in the canonical direction.
  for (int le = 0; le < V.L.edges; ++le) {
    const EdgeRec e = V.edge(h.edge[le]);
    const int a = vol ? kHexEdge[le][0] : kQuadEdge[le][0];
    const int axis = vol ? le / 4 : le / 2;
    for (Id t = 1; t < e.n; ++t) {
      const Id tc = h.rev(le) ? e.n - t : t;
      put(grid(kHexCorner[a], axis, t), e.off + tc - 1, coords ? V.edge_point(e, tc) : Vec3{});
    }
  }

  // Faces: canonical fill, then scattered through the face map.
  auto& s = b.scratch;
  for (int lf = 0; lf < V.L.faces; ++lf) {
    const FaceRec f = V.face(h.face[lf]);
    const Id nu = f.nu, nv = f.nv;
    if (nu < 2 || nv < 2) continue;
    if (coords) V.face_fill(f, s);
    const FaceMap fm = face_map(h.code(lf), nu, nv);
    const int ax = vol ? kHexFaceAxes[lf][0] : 0, bx = vol ? kHexFaceAxes[lf][1] : 1;
    const Id na = n[ax], nbb = n[bx];
    Id p[3] = {0, 0, 0};
    if (vol) p[lf / 2] = (lf % 2) ? n[lf / 2] : 0;
    for (Id q = 1; q < nbb; ++q)
      for (Id pp = 1; pp < na; ++pp) {
        p[ax] = pp, p[bx] = q;
        const Id c = (fm.u(pp, q) - 1) + (fm.v(pp, q) - 1) * (nu - 1);
        const Id g = B.index(p[0], p[1], p[2]);
        ids[g] = f.off + c;
        if (coords)
          for (int d = 0; d < 3; ++d) X[d][g] = s.face[d][c];
      }
  }
}
}  // namespace

void FineMesh::fill_slab(Id hid, Id k0, Id k1, FineBlock& b, bool coords, bool conn) const {
  const View V{tables_, b.cursor, tables_.layout()};
  const ElemRec h = V.element(hid);
  const auto n = h.n;
  const bool vol = mode() == Mode::Volume;
  if (k1 < 0) k1 = vol ? n[2] : 0;
  if (k0 < 0 || k0 > k1 || k1 > (vol ? n[2] : 0) || (conn && vol && k0 == k1))
    throw Error(ErrorKind::Usage, "fill_slab: planes " + std::to_string(k0) + ".." + std::to_string(k1) +
                                      " of coarse element " + std::to_string(hid) + " (it has " +
                                      std::to_string(vol ? n[2] : 0) + ")");
  auto& B = b.scratch.boundary;
  if (B.mesh != serial_ || B.h != hid || (coords && !B.coords)) fill_boundary(V, serial_, h, hid, b, coords);
  b.coarse_element = hid;
  b.n = n;
  b.block = h.block;
  b.plane0 = k0;
  b.planes = k1 - k0 + 1;
  b.layers = vol ? k1 - k0 : 1;
  b.first_element = h.elem_off + n[0] * n[1] * k0;
  const Id ni = n[0] + 1, nj = n[1] + 1, pp = ni * nj;
  const size_t np = static_cast<size_t>(pp * b.planes);
  b.node_id.resize(np);
  for (auto* x : {&b.x, &b.y, &b.z}) coords ? x->resize(np) : x->clear();
  auto& s = b.scratch;
  if (coords && vol) {
    s.u.resize(static_cast<size_t>(n[0])), s.U.resize(static_cast<size_t>(n[0]));
    for (Id i = 1; i < n[0]; ++i) s.u[i] = tfi::weight(i, n[0]), s.U[i] = 1.0 - s.u[i];
  }
  for (Id k = k0; k <= k1; ++k) {
    const size_t at = static_cast<size_t>((k - k0) * pp);
    Id* ids = b.node_id.data() + at;
    double* X[3] = {nullptr, nullptr, nullptr};
    if (coords) X[0] = b.x.data() + at, X[1] = b.y.data() + at, X[2] = b.z.data() + at;
    if (!vol || k == 0 || k == n[2]) {  // a face plane: all boundary
      const size_t from = static_cast<size_t>(B.index(0, 0, k));
      std::copy_n(B.id.data() + from, pp, ids);
      for (int d = 0; d < 3 && coords; ++d) std::copy_n(B.x[d].data() + from, pp, X[d]);
      continue;
    }
    // The ring of plane k from the side faces and edges, the rest hex interior.
    const size_t ring = static_cast<size_t>(B.index(0, 0, k));
    auto ring_copy = [&](const auto* src, auto* dst) {
      for (Id i = 0; i < ni; ++i) dst[i] = src[i], dst[i + n[1] * ni] = src[ni + i];
      for (Id j = 1; j < n[1]; ++j) dst[j * ni] = src[2 * ni + j - 1], dst[n[0] + j * ni] = src[2 * ni + n[1] - 1 + j - 1];
    };
    ring_copy(B.id.data() + ring, ids);
    const Id base = h.cell_off + (n[0] - 1) * (n[1] - 1) * (k - 1);
    for (Id j = 1; j < n[1]; ++j)
      for (Id i = 1; i < n[0]; ++i) ids[i + ni * j] = base + (i - 1) + (n[0] - 1) * (j - 1);
    for (int d = 0; d < 3 && coords; ++d) {
      ring_copy(B.x[d].data() + ring, X[d]);
      hex_interior_plane(B.x[d].data(), B.x[d].data() + pp, X[d], n, k, s.u.data(), s.U.data());
    }
  }

  if (!conn) {
    b.conn.clear();
    return;
  }
  const int nc = corners();
  b.conn.resize(static_cast<size_t>(b.num_elements()) * nc);
  Id* out = b.conn.data();
  const Id* ids = b.node_id.data();
  if (vol) {
    const Id sj = ni, sk = pp;
    const Id off[8] = {0, 1, 1 + sj, sj, sk, 1 + sk, 1 + sj + sk, sj + sk};
    for (Id k = k0; k < k1; ++k)
      for (Id j = 0; j < n[1]; ++j)
        for (Id i = 0; i < n[0]; ++i) {
          const Id g = b.point_index(i, j, k);
          for (int q = 0; q < 8; ++q) *out++ = ids[g + off[q]];
        }
  } else {
    const Id off[4] = {0, 1, 1 + ni, ni};
    for (Id j = 0; j < n[1]; ++j)
      for (Id i = 0; i < n[0]; ++i) {
        const Id g = b.point_index(i, j, 0);
        for (int q = 0; q < 4; ++q) *out++ = ids[g + off[q]];
      }
  }
}

void FineMesh::fill_block(Id hid, FineBlock& b, bool nodes_only) const { fill_slab(hid, 0, -1, b, true, !nodes_only); }

// ---------------------------------------------------------------- cursors

namespace {
// Grid planes per cursor slab: O(interval^2) values, never a whole block.
Id slab_planes(const std::array<Id, 3>& n, Id points) { return std::max<Id>(1, points / ((n[0] + 1) * (n[1] + 1))); }
}  // namespace

NodeCursor::NodeCursor(const FineMesh& mesh, Id begin, Id end, Id slab_points)
    : mesh_(mesh), next_(std::max<Id>(begin, 0)), end_(std::min(end, mesh.num_nodes())), slab_points_(slab_points) {}

bool NodeCursor::next(Id& id, Vec3& xyz) {
  if (next_ >= end_) return false;
  id = next_++;
  if (id < range_first_ || id >= range_end_) enter(id);
  const Id l = id - range_first_;
  switch (range_ref_.kind) {
    case EntityKind::Vertex: xyz = mesh_.node(NodeRef{EntityKind::Vertex, id, {0, 0, 0}}, cur_); return true;
    case EntityKind::Edge:
    case EntityKind::Face: {
      const auto q = static_cast<size_t>(l);
      xyz = {line_[0][q], line_[1][q], line_[2][q]};
      return true;
    }
    case EntityKind::Cell: break;
  }
  // Cell interior: (i, j, k) from the local index, then the slab holding plane k.
  const Id i = l % range_w0_ + 1, j = (l / range_w0_) % range_w1_ + 1, k = l / (range_w0_ * range_w1_) + 1;
  if (k < block_.plane0 || k >= block_.plane0 + block_.planes || block_.coarse_element != range_ref_.entity)
    mesh_.fill_slab(range_ref_.entity, k, std::min(k + slab_planes(range_n_, slab_points_) - 1, range_n_[2] - 1), block_, true, false);
  const Id g = block_.point_index(i, j, k);
  xyz = {block_.x[g], block_.y[g], block_.z[g]};
  return true;
}

// The entity owning node `id`: its id range, and for edges and faces all of
// its points at once (one canonical fill, not one evaluation per node).
void NodeCursor::enter(Id id) {
  const NodeRef r = mesh_.locate_node(id, cur_);
  const auto& base = mesh_.info().kind_base;
  const View V{mesh_.tables(), cur_, mesh_.tables().layout()};
  range_ref_ = r;
  switch (r.kind) {
    case EntityKind::Vertex:
      range_first_ = 0, range_end_ = base[1];
      break;
    case EntityKind::Edge: {
      const EdgeRec e = V.edge(r.entity);
      range_first_ = e.off, range_end_ = e.off + e.n - 1;
      for (auto& a : line_) a.resize(static_cast<size_t>(e.n - 1));
      for (Id t = 1; t < e.n; ++t) {
        const Vec3 x = V.edge_point(e, t);
        line_[0][t - 1] = x.x, line_[1][t - 1] = x.y, line_[2][t - 1] = x.z;
      }
      break;
    }
    case EntityKind::Face: {
      const FaceRec f = V.face(r.entity);
      range_first_ = f.off, range_end_ = f.off + (f.nu - 1) * (f.nv - 1);
      V.face_fill(f, face_);
      for (int d = 0; d < 3; ++d) line_[d].swap(face_.face[d]);
      break;
    }
    case EntityKind::Cell: {
      const ElemRec h = V.element(r.entity);
      range_w0_ = h.n[0] - 1, range_w1_ = h.n[1] - 1, range_n_ = h.n;
      range_first_ = h.cell_off, range_end_ = h.cell_off + range_w0_ * range_w1_ * (h.n[2] - 1);
      break;
    }
  }
  if (id < range_first_ || id >= range_end_)
    V.corrupt("node numbering: the entity found for a node id does not hold it; entity", r.entity);
}

ElementCursor::ElementCursor(const FineMesh& mesh, Id begin, Id end, Id slab_points)
    : mesh_(mesh), next_(std::max<Id>(begin, 0)), end_(std::min(end, mesh.num_elements())), slab_points_(slab_points) {}

bool ElementCursor::next(FineElement& el) {
  if (next_ >= end_) return false;
  el.id = next_++;
  const bool held = !block_.conn.empty() && el.id >= block_.first_element &&
                    el.id < block_.first_element + block_.num_elements();
  if (!held) {
    // A slab of element layers, ids and connectivity only (no coordinates).
    std::array<Id, 3> ijk;
    const Id h = mesh_.locate_element(el.id, ijk, cur_);
    if (mesh_.mode() == Mode::Volume) {
      const View V{mesh_.tables(), cur_, mesh_.tables().layout()};
      const std::array<Id, 3> n = V.element(h).n;
      mesh_.fill_slab(h, ijk[2], std::min(ijk[2] + slab_planes(n, slab_points_), n[2]), block_, false, true);
    } else {
      mesh_.fill_slab(h, 0, 0, block_, false, true);
    }
  }
  const Id l = el.id - block_.first_element;
  el.coarse_element = block_.coarse_element;
  el.ijk = {l % block_.n[0], (l / block_.n[0]) % block_.n[1], l / (block_.n[0] * block_.n[1]) + block_.plane0};
  el.block = block_.block;
  el.num_nodes = mesh_.corners();
  std::copy_n(&block_.conn[static_cast<size_t>(l) * el.num_nodes], el.num_nodes, el.nodes.begin());
  return true;
}

}  // namespace dicer
