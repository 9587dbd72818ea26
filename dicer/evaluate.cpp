// Evaluation of the recipe at one point, in the owning entity's canonical
// frame, from validated rows (see evaluate.hpp).
#include "evaluate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/tfi.hpp"
#include "clones.hpp"

namespace dicer::detail {
namespace {

Vec3 lerp(const Vec3& a, const Vec3& b, double s) {
  return {tfi::edge(a.x, b.x, s), tfi::edge(a.y, b.y, s), tfi::edge(a.z, b.z, s)};
}

// Coons interior point at face parameters (a, b) from the four sides'
// values there (bottom, top, left, right) and the canonical corners p[0..3].
Vec3 coons_point(double a, double b, const Vec3* s, const Vec3* p) {
  return {tfi::coons(a, b, s[0].x, s[1].x, s[2].x, s[3].x, p[0].x, p[1].x, p[2].x, p[3].x),
          tfi::coons(a, b, s[0].y, s[1].y, s[2].y, s[3].y, p[0].y, p[1].y, p[2].y, p[3].y),
          tfi::coons(a, b, s[0].z, s[1].z, s[2].z, s[3].z, p[0].z, p[1].z, p[2].z, p[3].z)};
}

// The bilinear patch of p[0..3] at (a, b): a straight face's point (tfi.hpp).
Vec3 bilinear_point(double a, double b, const Vec3* p) {
  auto at = [&](double Vec3::*d) {
    const double q[4] = {p[0].*d, p[1].*d, p[2].*d, p[3].*d};
    return tfi::bilinear_point(tfi::bilinear_row(b, q), a);
  };
  return {at(&Vec3::x), at(&Vec3::y), at(&Vec3::z)};
}

// The interior points of an edge from a to b, one coordinate, at
// parameters s[1..n-1], as edge_point computes each.
DICER_CLONES void edge_fill(double a, double b, const double* s, Id n, double* out) {
  for (Id t = 1; t < n; ++t) out[t - 1] = tfi::edge(a, b, s[t]);
}

// The interior of a face that is moved or has a moved side, one
// coordinate, in canonical order (u fastest): tfi::coons at parameters
// s[u], t[v] from the sides' values there and the corners p[0..3], as
// face_tfi computes each (clones.hpp: same bits).
DICER_CLONES void coons_fill(const double* s, const double* t, Id nu, Id nv, const double* bottom, const double* top,
                             const double* left, const double* right, const double* p, double* out) {
  const double p0 = p[0], p1 = p[1], p2 = p[2], p3 = p[3];
  for (Id v = 1; v < nv; ++v, out += nu - 1) {
    const double tv = t[v], l = left[v], r = right[v];
    for (Id u = 1; u < nu; ++u) out[u - 1] = tfi::coons(s[u], tv, bottom[u], top[u], l, r, p0, p1, p2, p3);
  }
}

}  // namespace

// Each row in whole blocks of kPatchSlack points: a loop of a fixed count,
// which the vectoriser turns into straight vector code for each clone
// (GCC's vector types of 8 doubles went by way of the stack in the AVX2
// clone). Elementwise mul then add: the bits of bilinear_point in any lane.
DICER_WIDE_CLONES void bilinear_patch(const double* __restrict s, const double* t, Id nu, Id nv, const double* p,
                                      double* __restrict out) {
  const Id m = nu - 1;
  for (Id v = 1; v < nv; ++v, out += m) {
    const tfi::Bilinear row = tfi::bilinear_row(t[v], p);
    for (Id i = 0; i < m; i += kPatchSlack)
      for (Id l = 0; l < kPatchSlack; ++l) out[i + l] = tfi::bilinear_point(row, s[1 + i + l]);
  }
}

// The permute path: GCC on x86-64 with AVX-512 clones built (the avx2 and
// none builds test the path other machines take), chosen at run time.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__) && \
    !defined(DICER_CLONES_NONE) && !defined(DICER_CLONES_AVX2_AT_MOST)
#define DICER_PATCH_PERMUTE 1
namespace {
bool has_avx512() {
  static const bool yes = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
                          __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl") &&
                          __builtin_cpu_supports("avx512cd");
  return yes;
}
// Explicit mul, add and sub (no contraction): bilinear_row's A = T p0 + t p3,
// D = (T p1 + t p2) - A, then A + s D, in every lane.
__attribute__((target("arch=x86-64-v4"))) void patch_permute(const PatchGrid& g, const double* p, double* out) {
  const __m512d p0 = _mm512_set1_pd(p[0]), p1 = _mm512_set1_pd(p[1]), p2 = _mm512_set1_pd(p[2]),
                p3 = _mm512_set1_pd(p[3]);
  __m512d A[2], D[2];
  for (int h = 0; h < 2; ++h) {
    // Unaligned loads: a thread_local grid in a module loaded by dlopen
    // (the Python package) need not get its alignas(64).
    const __m512d T = _mm512_loadu_pd(g.T + 8 * h), t = _mm512_loadu_pd(g.t + 8 * h);
    A[h] = _mm512_add_pd(_mm512_mul_pd(T, p0), _mm512_mul_pd(t, p3));
    D[h] = _mm512_sub_pd(_mm512_add_pd(_mm512_mul_pd(T, p1), _mm512_mul_pd(t, p2)), A[h]);
  }
  const auto n = static_cast<Id>(g.row.size());  // whole blocks of 8
  for (Id f = 0; f < n; f += 8) {
    const __m512i lane = _mm512_loadu_si512(g.row.data() + f);
    const __m512d a = _mm512_permutex2var_pd(A[0], lane, A[1]), d = _mm512_permutex2var_pd(D[0], lane, D[1]);
    _mm512_storeu_pd(out + f, _mm512_add_pd(a, _mm512_mul_pd(_mm512_loadu_pd(g.s.data() + f), d)));
  }
}
}  // namespace
#endif

void prepare_patch_grid(const double* s, const double* t, Id nu, Id nv, PatchGrid& g) {
#ifdef DICER_PATCH_PERMUTE
  // Laid out for these parameters already: row 1's points hold s[1 ..
  // nu - 1], the lanes t[1 .. nv - 1].
  const bool same = g.permute && g.nu == nu && g.nv == nv &&
                    std::memcmp(g.s.data(), s + 1, static_cast<size_t>(nu - 1) * sizeof(double)) == 0 &&
                    std::memcmp(g.t, t + 1, static_cast<size_t>(nv - 1) * sizeof(double)) == 0;
  g.su = s, g.tv = t, g.nu = nu, g.nv = nv;
  if (same) return;
  g.permute = false;
  if (nv - 1 > 16 || nu < 2 || nv < 2 || !has_avx512()) return;
  for (Id l = 0; l < 16; ++l) {
    g.t[l] = l + 1 < nv ? t[l + 1] : 0.0;
    g.T[l] = 1.0 - g.t[l];  // bilinear_row's T, the same bits
  }
  const Id m = nu - 1, count = m * (nv - 1), blocks = (count + 7) / 8 * 8;
  g.s.resize(static_cast<size_t>(blocks)), g.row.resize(static_cast<size_t>(blocks));
  for (Id v = 1, f = 0; v < nv; ++v)
    for (Id u = 1; u < nu; ++u, ++f) g.s[static_cast<size_t>(f)] = s[u], g.row[static_cast<size_t>(f)] = v - 1;
  std::fill(g.s.begin() + count, g.s.end(), 0.0), std::fill(g.row.begin() + count, g.row.end(), 0);
  g.permute = true;  // last: a throw above leaves no grid to reuse
#else
  g.su = s, g.tv = t, g.nu = nu, g.nv = nv, g.permute = false;
#endif
}

void series_values(Id n, const tfi::Grading& g, Id t0, Id t1, double* out) {
  constexpr Id kMaxN = 64;
  constexpr int kSlots = 8;
  struct Slot {
    Id n = -1;
    tfi::Grading g;
    std::array<double, kMaxN + 1> at;
  };
  thread_local std::array<Slot, kSlots> slots;
  thread_local int next = 0;
  DICER_ASSERT(0 <= t0 && t0 <= t1 && t1 <= n + 1, "series_values: parameters of the series' points");
  if (n < 1 || n > kMaxN) {
    const tfi::Series series(n, g);
    for (Id t = t0; t < t1; ++t) out[t] = series.at(t);
    return;
  }
  Slot* hit = nullptr;
  for (Slot& c : slots)
    if (c.n == n && c.g == g) hit = &c;
  if (hit == nullptr) {
    hit = &slots[static_cast<size_t>(next)];
    next = (next + 1) % kSlots;
    const tfi::Series series(n, g);
    for (Id t = 0; t <= n; ++t) hit->at[static_cast<size_t>(t)] = series.at(t);
    hit->n = n, hit->g = g;
  }
  std::copy(hit->at.begin() + t0, hit->at.begin() + t1, out + t0);
}

void bilinear_patch(const PatchGrid& g, const double* p, double* out) {
#ifdef DICER_PATCH_PERMUTE
  if (g.permute) return patch_permute(g, p, out);
#endif
  bilinear_patch(g.su, g.tv, g.nu, g.nv, p, out);
}

std::array<tfi::Grading, 2> face_grading(Mode mode, const ElementRow& h, int lf) {
  const FaceCode code = h.code(lf);
  const auto cc = face_canonical_corners(mode, lf, code);
  std::array<tfi::Grading, 2> out;
  for (int axis = 0; axis < 2; ++axis) {
    const int side = 2 * axis;  // v0v1 (u), v0v3 (v)
    const tfi::Grading g = h.edge_grading(face_side_edge(mode, lf, code, side), mode);
    out[axis] = h.corner[cc[kQuadEdge[side][0]]] < h.corner[cc[kQuadEdge[side][1]]] ? g : tfi::reversed(g);
  }
  return out;
}

Vec3 Evaluator::moved(const Vec3& p, Id row) const {
  const auto c = R.bounding(row);
  const Vec3 x{tfi::bounding_apply(p.x, c[0]), tfi::bounding_apply(p.y, c[1]), tfi::bounding_apply(p.z, c[2])};
  if (!std::isfinite(x.x) || !std::isfinite(x.y) || !std::isfinite(x.z))
    throw Error(ErrorKind::Corrupt, (R.tables().origin.empty() ? std::string("in memory") : R.tables().origin) +
                                        ": geometry/bounding row " + std::to_string(row) +
                                        ": the corrected coordinate is not finite");
  return x;
}

EdgeRow Evaluator::edge_of(const ElementRow& h, int k) const {
  const EdgeRow er = R.edge(h.edge[k]);
  const Mode m = mode();
  if (er.n != h.n[m == Mode::Volume ? k / 4 : k / 2])
    R.corrupt(RowTable::Edges, h.edge[k], "interval disagrees with an element using the edge");
  if (!(er.grading == h.edge_grading(k, m)))
    R.corrupt(RowTable::Edges, h.edge[k], "grading disagrees with an element using the edge");
  return er;
}

Vec3 Evaluator::edge_point(const EdgeRow& e, Id t) const {
  if (t == 0) return R.xyz(e.lo);
  if (t == e.n) return R.xyz(e.hi);
  const Vec3 p = lerp(R.xyz(e.lo), R.xyz(e.hi), tfi::param(t, e.n, e.grading));
  return e.bound < 0 ? p : moved(p, e.bound + t - 1);
}

EdgeRow Evaluator::face_side_row(const FaceRow& f, int k) const {
  const EdgeRow e = R.edge(f.e[k]);
  if (e.n != (k < 2 ? f.nu : f.nv)) R.corrupt(RowTable::Faces, f.e[k], "side interval disagrees with its face");
  return e;
}

Vec3 Evaluator::face_side(const FaceRow& f, int k, const EdgeRow& e, Id s) const {
  const bool rev = f.v[kQuadEdge[k][0]] > f.v[kQuadEdge[k][1]];
  return edge_point(e, rev ? e.n - s : s);
}

Vec3 Evaluator::face_point(const FaceRow& f, Id u, Id v) const {
  const int side = v == 0 ? 0 : v == f.nv ? 1 : u == 0 ? 2 : u == f.nu ? 3 : -1;
  if (side >= 0) return face_side(f, side, face_side_row(f, side), side < 2 ? u : v);
  const Vec3 x = face_tfi(f, u, v, f.bound >= 0);
  return f.bound < 0 ? x : moved(x, ids::face_node(f.bound, f.nu, u, v));
}

Vec3 Evaluator::face_tfi(const FaceRow& f, Id u, Id v, bool coons) const {
  const EdgeRow e[4] = {face_side_row(f, 0), face_side_row(f, 1), face_side_row(f, 2), face_side_row(f, 3)};
  const Vec3 p[4] = {R.xyz(f.v[0]), R.xyz(f.v[1]), R.xyz(f.v[2]), R.xyz(f.v[3])};
  const auto g = R.face_grading(f, e);
  const double a = tfi::param(u, f.nu, g[0]), b = tfi::param(v, f.nv, g[1]);
  if (!coons && e[0].bound < 0 && e[1].bound < 0 && e[2].bound < 0 && e[3].bound < 0) return bilinear_point(a, b, p);
  const Vec3 sides[4] = {face_side(f, 0, e[0], u), face_side(f, 1, e[1], u), face_side(f, 2, e[2], v),
                         face_side(f, 3, e[3], v)};
  return coons_point(a, b, sides, p);
}

// A straight hex's point is the trilinear blend of its corners; a curved
// one's the Boolean sum of its 12 edge points and 6 face points at the
// point's parameters, their owners' values (edge_point, face_point), through
// tfi::hex_plane, hex_row, hex_column and hex_point. Both as the block fill
// computes them, so the bits agree.
Vec3 Evaluator::cell_point(const ElementRow& h, Id hid, Id i, Id j, Id k, const Vec3* corners) const {
  const Id t[3] = {i, j, k};
  Uninitialised<Vec3, 8> read;
  if (!corners) R.corner_xyz(hid, read.data());
  const Vec3* corner = corners ? corners : read.data();
  double c[3][8];
  for (int q = 0; q < 8; ++q) c[0][q] = corner[q].x, c[1][q] = corner[q].y, c[2][q] = corner[q].z;
  const double u = tfi::param(i, h.n[0], h.grading[0]), v = tfi::param(j, h.n[1], h.grading[1]),
               w = tfi::param(k, h.n[2], h.grading[2]);
  double out[3];
  if (!h.curved()) {
    for (int d = 0; d < 3; ++d) {
      double q[4];
      tfi::trilinear_plane(w, c[d], q);
      out[d] = tfi::bilinear_point(tfi::bilinear_row(v, q), u);
    }
    return {out[0], out[1], out[2]};
  }
  double f[3][6], e[3][12];
  for (int q = 0; q < 12; ++q) {
    const Id n = h.n[q / 4];
    const Vec3 x = edge_point(edge_of(h, q), h.rev(q) ? n - t[q / 4] : t[q / 4]);
    e[0][q] = x.x, e[1][q] = x.y, e[2][q] = x.z;
  }
  for (int q = 0; q < 6; ++q) {
    const int A = kHexFaceAxes[q][0], B = kHexFaceAxes[q][1];
    const auto [nu, nv] = face_intervals(h, q, Mode::Volume);
    const FaceMap fm = face_map(h.code(q), nu, nv);
    const Vec3 x = face_point(R.face(h.face[q]), fm.u(t[A], t[B]), fm.v(t[A], t[B]));
    f[0][q] = x.x, f[1][q] = x.y, f[2][q] = x.z;
  }
  for (int d = 0; d < 3; ++d) {
    const tfi::HexPlane plane = tfi::hex_plane(w, e[d] + 8, c[d]);
    const tfi::HexRow row = tfi::hex_row(plane, v, f[d][0], f[d][1], e[d][4], e[d][5], e[d][6], e[d][7]);
    const tfi::HexColumn col = tfi::hex_column(plane, f[d][2], f[d][3], e[d][0], e[d][1], e[d][2], e[d][3]);
    out[d] = tfi::hex_point(row, col, u, v, w, f[d][4], f[d][5]);
  }
  return {out[0], out[1], out[2]};
}

namespace {

// Which local entity of an element holds grid point (i, j, k), and the
// point's canonical coordinates in it.
struct GridEntity {
  EntityKind kind;
  int slot;                   // local corner, edge or face index (cell: -1)
  std::array<Id, 3> local;    // canonical t / (u, v) / (i, j, k)
};

GridEntity grid_entity(const ElementRow& h, Mode mode, Id i, Id j, Id k) {
  const auto& n = h.n;
  if (mode == Mode::Surface) {
    const int ex = (i == 0 || i == n[0]) + (j == 0 || j == n[1]);
    if (ex == 2) return {EntityKind::Vertex, quad_corner_at(i > 0, j > 0), {0, 0, 0}};
    if (ex == 1) {
      const int axis = (j == 0 || j == n[1]) ? 0 : 1;
      const int le = axis == 0 ? quad_edge_at(0, j > 0) : quad_edge_at(1, i > 0);
      const Id tt = axis == 0 ? i : j, ne = n[axis];
      return {EntityKind::Edge, le, {h.rev(le) ? ne - tt : tt, 0, 0}};
    }
    const auto [nu, nv] = face_intervals(h, 0, mode);
    const FaceMap fm = face_map(h.code(0), nu, nv);
    return {EntityKind::Face, 0, {fm.u(i, j), fm.v(i, j), 0}};
  }
  const Id p[3] = {i, j, k};
  int ext[3];  // -1 interior, 0 low side, 1 high side
  int count = 0;
  for (int a = 0; a < 3; ++a) {
    ext[a] = p[a] == 0 ? 0 : p[a] == n[a] ? 1 : -1;
    count += ext[a] >= 0;
  }
  if (count == 3) return {EntityKind::Vertex, hex_corner_at(ext[0], ext[1], ext[2]), {0, 0, 0}};
  if (count == 2) {
    const int axis = ext[0] < 0 ? 0 : ext[1] < 0 ? 1 : 2;
    const int le = hex_edge_at(axis, ext[axis == 0 ? 1 : 0], ext[axis == 2 ? 1 : 2]);
    return {EntityKind::Edge, le, {h.rev(le) ? n[axis] - p[axis] : p[axis], 0, 0}};
  }
  if (count == 1) {
    const int axis = ext[0] >= 0 ? 0 : ext[1] >= 0 ? 1 : 2;
    const int lf = 2 * axis + ext[axis];
    const auto [nu, nv] = face_intervals(h, lf, mode);
    const FaceMap fm = face_map(h.code(lf), nu, nv);
    const Id a = p[kHexFaceAxes[lf][0]], b = p[kHexFaceAxes[lf][1]];
    return {EntityKind::Face, lf, {fm.u(a, b), fm.v(a, b), 0}};
  }
  return {EntityKind::Cell, -1, {i, j, k}};
}

// Sorts a[0..n) by `less`, n a handful (the 6 faces, the 26 owned
// ranges): an insertion sort, as std::sort does below 16 elements; GCC 12
// warned -Warray-bounds inside std::sort's unrolled path on these small
// fixed arrays.
template <class T, class Less>
void sort_few(T* a, int n, Less less) {
  for (int i = 1; i < n; ++i)
    for (int j = i; j > 0 && less(a[j], a[j - 1]); --j) std::swap(a[j], a[j - 1]);
}

}  // namespace

NodeRef Evaluator::grid_node(const ElementRow& h, Id hid, Id i, Id j, Id k) const {
  const GridEntity g = grid_entity(h, mode(), i, j, k);
  switch (g.kind) {
    case EntityKind::Vertex: return {g.kind, h.corner[g.slot], g.local};
    case EntityKind::Edge: return {g.kind, h.edge[g.slot], g.local};
    case EntityKind::Face: return {g.kind, h.face[g.slot], g.local};
    case EntityKind::Cell: break;
  }
  return {EntityKind::Cell, hid, g.local};
}

Id Evaluator::grid_node_id(const ElementRow& h, Id i, Id j, Id k) const {
  const GridEntity g = grid_entity(h, mode(), i, j, k);
  switch (g.kind) {
    case EntityKind::Vertex: return h.corner_node[g.slot];
    case EntityKind::Edge: return ids::edge_node(h.edge_node[g.slot], g.local[0]);
    case EntityKind::Face:
      return ids::face_node(h.face_node[g.slot], face_intervals(h, g.slot, mode())[0], g.local[0], g.local[1]);
    case EntityKind::Cell: break;
  }
  return ids::cell_node(h.cell_node, h.n, i, j, k);
}

namespace {

// Node ids over one region of a hex's grid: base + c . (i, j, k).
struct AffineIds {
  Id base;
  std::array<Id, 3> c;
};

// The map of region s (per axis: 0 the low side, 1 the high side, 2
// inside). Each case takes its affine id from numbering's own formula,
// evaluated at the origin and one step along each free axis.
AffineIds region_ids(const ElementRow& h, const int* s) {
  const auto& n = h.n;
  const int inside = (s[0] == 2) + (s[1] == 2) + (s[2] == 2);
  AffineIds A{0, {0, 0, 0}};
  if (inside == 0) {
    A.base = h.corner_node[hex_corner_at(s[0], s[1], s[2])];
  } else if (inside == 1) {
    const int axis = s[0] == 2 ? 0 : s[1] == 2 ? 1 : 2;
    const int le = hex_edge_at(axis, s[axis == 0 ? 1 : 0], s[axis == 2 ? 1 : 2]);
    const bool rev = h.rev(le);
    auto id = [&](Id p) { return ids::edge_node(h.edge_node[le], rev ? n[axis] - p : p); };
    A.base = id(0), A.c[axis] = id(1) - id(0);
  } else if (inside == 2) {
    const int axis = s[0] != 2 ? 0 : s[1] != 2 ? 1 : 2;
    const int lf = 2 * axis + s[axis];
    // Not a structured binding: Clang before 16 (Debian 12's 14, the fuzz
    // build) cannot capture one in a lambda.
    const std::array<Id, 2> nf = face_intervals(h, lf, Mode::Volume);
    const Id nu = nf[0];
    const FaceMap fm = face_map(h.code(lf), nu, nf[1]);
    auto id = [&](Id a, Id b) { return ids::face_node(h.face_node[lf], nu, fm.u(a, b), fm.v(a, b)); };
    A.base = id(0, 0);
    A.c[kHexFaceAxes[lf][0]] = id(1, 0) - A.base, A.c[kHexFaceAxes[lf][1]] = id(0, 1) - A.base;
  } else {
    auto id = [&](Id i, Id j, Id k) { return ids::cell_node(h.cell_node, n, i, j, k); };
    A.base = id(0, 0, 0);
    A.c = {id(1, 0, 0) - A.base, id(0, 1, 0) - A.base, id(0, 0, 1) - A.base};
  }
  return A;
}

}  // namespace

void Evaluator::hex_cell_node_ids(const ElementRow& h, Id i, Id j, Id k, Id* out) const {
  DICER_ASSERT(mode() == Mode::Volume, "hex_cell_node_ids: a hex's cell");
  const Id p[3] = {i, j, k};
  // Per axis the cell's two grid planes: p (the low side or inside) and
  // p + 1 (the high side or inside); `two` where they differ.
  int lo[3], hi[3], two[3];
  for (int a = 0; a < 3; ++a) {
    lo[a] = p[a] == 0 ? 0 : 2;
    hi[a] = p[a] + 1 == h.n[a] ? 1 : 2;
    two[a] = lo[a] != hi[a];
  }
  // One map per combination of the axes' regions, then each corner from
  // its combination's map (only those are read).
  AffineIds maps[8];
  for (int m = 0; m < 8; ++m) {
    if (((m & 1) && !two[0]) || ((m & 2) && !two[1]) || ((m & 4) && !two[2])) continue;
    const int s[3] = {m & 1 ? hi[0] : lo[0], m & 2 ? hi[1] : lo[1], m & 4 ? hi[2] : lo[2]};
    maps[m] = region_ids(h, s);
  }
  for (int q = 0; q < 8; ++q) {
    const int* c = kHexCorner[q];
    const AffineIds& A = maps[(c[0] & two[0]) | (c[1] & two[1]) << 1 | (c[2] & two[2]) << 2];
    out[q] = A.base + A.c[0] * (i + c[0]) + A.c[1] * (j + c[1]) + A.c[2] * (k + c[2]);
  }
}

Vec3 Evaluator::straight_owned_point(const ElementRow& h, Id hid, int slot, const NodeRef& r,
                                     const Vec3* corners) const {
  DICER_ASSERT(!h.curved() && r.kind != EntityKind::Cell, "straight_owned_point: a straight element's own boundary");
  const Mode m = mode();
  const bool vol = m == Mode::Volume;
  Uninitialised<Vec3, 8> read;
  if (!corners) R.corner_xyz(hid, read.data());
  const Vec3* corner = corners ? corners : read.data();
  if (r.kind == EntityKind::Vertex) return corner[slot];
  // Local edge k at canonical t, as edge_point: lo -> hi vertex id.
  auto edge_at = [&](int k, Id t) {
    const int a = vol ? kHexEdge[k][0] : kQuadEdge[k][0], b = vol ? kHexEdge[k][1] : kQuadEdge[k][1];
    const Id n = h.n[vol ? k / 4 : k / 2];
    return lerp(corner[h.rev(k) ? b : a], corner[h.rev(k) ? a : b], tfi::param(t, n, h.edge_grading(k, m)));
  };
  if (r.kind == EntityKind::Edge) return edge_at(slot, r.local[0]);
  // Face: interior point (u, v) of a straight face, as face_point: the
  // bilinear patch of its canonical corners.
  const FaceCode code = h.code(slot);
  const auto [nu, nv] = face_intervals(h, slot, m);
  const auto cc = face_canonical_corners(m, slot, code);
  const Vec3 p[4] = {corner[cc[0]], corner[cc[1]], corner[cc[2]], corner[cc[3]]};
  const auto g = face_grading(m, h, slot);
  return bilinear_point(tfi::param(r.local[0], nu, g[0]), tfi::param(r.local[1], nv, g[1]), p);
}

Vec3 Evaluator::node(const NodeRef& r) const {
  switch (r.kind) {
    case EntityKind::Vertex: return R.xyz(r.entity);
    case EntityKind::Edge: return edge_point(R.edge(r.entity), r.local[0]);
    case EntityKind::Face: return face_point(R.face(r.entity), r.local[0], r.local[1]);
    case EntityKind::Cell: return cell_point(R.element(r.entity), r.entity, r.local[0], r.local[1], r.local[2]);
  }
  return {};
}

void element_boundary(const Evaluator& E, const ElementRow& h, Id hid, FineBlock::Scratch& out, const bool* want_edge,
                      const bool* want_face, const OwnedPlaces* to) {
  const Mode mode = E.mode();
  const bool vol = mode == Mode::Volume, curved = h.curved();
  DICER_ASSERT(!to || !curved, "element_boundary: owned places only for a straight element");
  const int ne = vol ? 12 : 4, nf = vol ? 6 : 1;
  E.R.corner_xyz(hid, out.corner);
  // A curved element's faces need the edges along their sides (a straight
  // one's are bilinear patches of its corners).
  bool need_edge[12] = {};
  for (int k = 0; k < ne; ++k) need_edge[k] = !want_edge || want_edge[k];
  for (int lf = 0; lf < nf && curved; ++lf)
    if (!want_face || want_face[lf])
      for (int side = 0; side < 4; ++side) need_edge[face_side_edge(mode, lf, h.code(lf), side)] = true;

  Id series_n = -1;  // the edge parameters held in out.s
  tfi::Grading series_g;
  bool bound_edge[12] = {};  // local edge k's nodes are moved
  // Edges: each point exact, nothing written past them.
  auto edges = [&] {
    for (int k = 0; k < ne; ++k) {
      if (!need_edge[k]) continue;
      const Id n = h.n[vol ? k / 4 : k / 2];
      auto& pts = out.edge[k];
      double* dst[3] = {nullptr, nullptr, nullptr};
      if (to && to->edge[k][0]) {
        std::copy_n(to->edge[k], 3, dst);
      } else {
        for (int d = 0; d < 3; ++d) {
          pts[d].resize(static_cast<size_t>(std::max<Id>(n - 1, 0)));
          dst[d] = pts[d].data();
        }
      }
      if (curved) {
        const EdgeRow er = E.edge_of(h, k);
        bound_edge[k] = er.bound >= 0;
        for (Id t = 1; t < n; ++t) {
          const Vec3 x = E.edge_point(er, t);
          dst[0][t - 1] = x.x, dst[1][t - 1] = x.y, dst[2][t - 1] = x.z;
        }
      } else {
        const int a = vol ? kHexEdge[k][0] : kQuadEdge[k][0], b = vol ? kHexEdge[k][1] : kQuadEdge[k][1];
        const Vec3& lo = out.corner[h.rev(k) ? b : a];
        const Vec3& hi = out.corner[h.rev(k) ? a : b];
        const tfi::Grading g = h.edge_grading(k, mode);
        if (n != series_n || !(g == series_g)) {  // edges along one axis mostly share their series
          out.s.resize(static_cast<size_t>(std::max<Id>(n, 1)));
          series_values(n, g, 1, n, out.s.data());
          series_n = n, series_g = g;
        }
        edge_fill(lo.x, hi.x, out.s.data(), n, dst[0]);
        edge_fill(lo.y, hi.y, out.s.data(), n, dst[1]);
        edge_fill(lo.z, hi.z, out.s.data(), n, dst[2]);
      }
    }
  };

  auto& s = out;
  // Faces placed by `to` in increasing address order: a face's slack
  // lands on a face after it, on an edge or corner (written after every
  // face), or on the interior (written after the boundary), never on a
  // face already written.
  int order[6] = {0, 1, 2, 3, 4, 5};
  if (to) sort_few(order, nf, [&](int a, int b) { return std::less<>()(to->face[a][0], to->face[b][0]); });
  auto faces = [&] {
    for (int of = 0; of < nf; ++of) {
      const int lf = order[of];
      if (want_face && !want_face[lf]) continue;
      const FaceCode code = h.code(lf);
      const auto [nu, nv] = face_intervals(h, lf, mode);
      const auto cc = face_canonical_corners(mode, lf, code);
      const size_t m = static_cast<size_t>(ids::face_nodes(nu, nv));
      // A placed face with no points has nothing to write, and the room a
      // patch may write past its points (bilinear_patch) is the start of the
      // entity after it, already written if placed lower in the order.
      if (to && to->face[lf][0] && m == 0) continue;
      Id bound = -1;  // the face's first bounding row, as face_point reads it
      if (curved && m > 0) {
        const FaceRow fr = E.R.face(h.face[lf]);
        if (fr.nu != nu || fr.nv != nv) E.R.corrupt(RowTable::Faces, h.face[lf], "intervals disagree with an element using the face");
        bound = fr.bound;
      }
      // Straight (face_tfi): unmoved, and so are its four sides.
      bool straight = bound < 0;
      for (int side = 0; side < 4; ++side) straight &= !bound_edge[face_side_edge(mode, lf, code, side)];
      // Sides in the face's canonical frame, at parameters 1..len-1.
      std::vector<double>* side_out[4] = {s.bottom, s.top, s.left, s.right};
      for (int side = 0; side < 4 && !straight; ++side) {
        const int le = face_side_edge(mode, lf, code, side);
        const Id len = side < 2 ? nu : nv;
        const bool forward = h.corner[cc[kQuadEdge[side][0]]] < h.corner[cc[kQuadEdge[side][1]]];
        for (int d = 0; d < 3; ++d) {
          side_out[side][d].resize(static_cast<size_t>(len + 1));
          const double* src = out.edge[le][d].data();
          for (Id q = 1; q < len; ++q) side_out[side][d][q] = src[(forward ? q : len - q) - 1];
        }
      }
      // bilinear_patch reads s past nu - 1 (zeros: finite, not subnormal).
      s.s.resize(static_cast<size_t>(nu + kPatchSlack)), s.t.resize(static_cast<size_t>(nv));
      std::fill(s.s.begin() + nu, s.s.end(), 0.0);
      const auto g = face_grading(mode, h, lf);
      series_values(nu, g[0], 1, nu, s.s.data());
      series_values(nv, g[1], 1, nv, s.t.data());
      thread_local PatchGrid grid;
      if (straight) prepare_patch_grid(s.s.data(), s.t.data(), nu, nv, grid);
      const bool placed = to && to->face[lf][0];
      DICER_ASSERT(!placed || straight, "element_boundary: a placed face is straight");
      for (int d = 0; d < 3; ++d) {
        auto& face = out.face[lf][d];
        if (!placed) face.resize(m + (straight ? static_cast<size_t>(kPatchSlack) : 0));
        double* const dst = placed ? to->face[lf][d] : face.data();
        const double p[4] = {component(out.corner[cc[0]], d), component(out.corner[cc[1]], d),
                             component(out.corner[cc[2]], d), component(out.corner[cc[3]], d)};
        if (straight)
          bilinear_patch(grid, p, dst);
        else
          coons_fill(s.s.data(), s.t.data(), nu, nv, s.bottom[d].data(), s.top[d].data(), s.left[d].data(),
                     s.right[d].data(), p, dst);
      }
      if (bound >= 0)  // the stored corrections, as face_point applies them
        for (size_t q = 0; q < m; ++q) {
          const Vec3 x = E.moved({out.face[lf][0][q], out.face[lf][1][q], out.face[lf][2][q]}, bound + static_cast<Id>(q));
          out.face[lf][0][q] = x.x, out.face[lf][1][q] = x.y, out.face[lf][2][q] = x.z;
        }
    }
  };
  // A curved element's faces read its edges: edges first. Placed
  // entities (a straight element's, which its faces do not read): faces
  // first, so that an edge placed after a face is written over that
  // face's slack (corners, fill_boundary's, come last).
  if (to) {
    faces();
    edges();
  } else {
    edges();
    faces();
  }
}

void facet_points(const Evaluator& E, const ElementRow& h, Id hid, int slot, FineBlock::Scratch& s,
                  std::vector<Id>& ids, std::vector<Vec3>& xyz) {
  const Mode mode = E.mode();
  const bool vol = mode == Mode::Volume;
  bool want_edge[12] = {}, want_face[6] = {};
  if (vol) {
    want_face[slot] = true;
    for (int side = 0; side < 4; ++side) want_edge[face_side_edge(mode, slot, h.code(slot), side)] = true;
  } else {
    want_edge[slot] = true;
  }
  element_boundary(E, h, hid, s, want_edge, want_face);
  ids.clear(), xyz.clear();
  auto put = [&](Id i, Id j, Id k) {
    const GridEntity g = grid_entity(h, mode, i, j, k);
    ids.push_back(E.grid_node_id(h, i, j, k));
    switch (g.kind) {
      case EntityKind::Vertex: xyz.push_back(s.corner[g.slot]); return;
      case EntityKind::Edge: {
        const auto& a = s.edge[g.slot];
        const size_t q = static_cast<size_t>(g.local[0] - 1);
        xyz.push_back({a[0][q], a[1][q], a[2][q]});
        return;
      }
      case EntityKind::Face: {
        const auto& a = s.face[g.slot];
        const auto nu = face_intervals(h, g.slot, mode)[0];
        const size_t q = static_cast<size_t>(ids::face_node(0, nu, g.local[0], g.local[1]));
        xyz.push_back({a[0][q], a[1][q], a[2][q]});
        return;
      }
      case EntityKind::Cell: break;
    }
    E.R.corrupt(RowTable::Elements, hid, "a facet point lies inside its element");
  };
  const auto& n = h.n;
  if (vol) {
    const int axis = slot / 2, a = kHexFaceAxes[slot][0], b = kHexFaceAxes[slot][1];
    Id p[3] = {0, 0, 0};
    p[axis] = slot % 2 ? n[axis] : 0;
    for (Id q = 0; q <= n[b]; ++q)
      for (Id r = 0; r <= n[a]; ++r) {
        p[a] = r, p[b] = q;
        put(p[0], p[1], p[2]);
      }
  } else {
    const int axis = slot / 2, c = kQuadEdge[slot][0];
    Id p[2] = {kHexCorner[c][0] * n[0], kHexCorner[c][1] * n[1]};
    for (Id t = 0; t <= n[axis]; ++t) {
      p[axis] = t;
      put(p[0], p[1], 0);
    }
  }
}

void owned_entities(const ElementRow& h, Mode mode, bool want_edge[12], bool want_face[6]) {
  const bool vol = mode == Mode::Volume;
  const int ne = vol ? 12 : 4, nf = vol ? 6 : 1;
  std::fill_n(want_edge, 12, false), std::fill_n(want_face, 6, false);
  for (int k = 0; k < ne; ++k) want_edge[k] = h.owns(h.edge_node[k]) && h.n[vol ? k / 4 : k / 2] > 1;
  for (int k = 0; k < nf; ++k) want_face[k] = h.owns(h.face_node[k]);
}

Id owned_places(const Evaluator& E, const ElementRow& h, Id hid, double* const out[3], Id size, OwnedPlaces& at) {
  const Mode mode = E.mode();
  const bool vol = mode == Mode::Volume;
  const int nc = E.R.corners(), ne = E.R.edges(), nf = E.R.faces();
  const Id first = h.node_first;
  const Id end = vol ? h.cell_node : h.cell_node + ids::face_nodes(h.n[0], h.n[1]);
  bool want_edge[12], want_face[6];
  owned_entities(h, mode, want_edge, want_face);
  if (end < first) E.R.corrupt(RowTable::Elements, hid, "the element's own node ids run backwards");
  if (end - first != size) E.R.corrupt(RowTable::Elements, hid, "the element's own node range disagrees with its row");
  at = OwnedPlaces{};
  // The ranges must tile [first, end) exactly: a range in bounds and a
  // count that adds up still let two entities overlap and leave a gap,
  // whose coordinates would be whatever the batch held before.
  struct Range {
    Id at, count;
  };
  Range ranges[26];
  int nr = 0;
  auto place = [&](double* (&to)[3], Id node, Id count) {
    if (node < first || node - first + count > size)
      E.R.corrupt(RowTable::Elements, hid, "an owned entity's node ids lie outside the element's own range");
    for (int d = 0; d < 3; ++d) to[d] = out[d] + (node - first);
    if (count > 0) ranges[nr++] = {node - first, count};
  };
  for (int k = 0; k < nc; ++k)
    if (h.owns(h.corner_node[k])) place(at.corner[k], h.corner_node[k], 1);
  for (int k = 0; k < ne; ++k)
    if (want_edge[k]) place(at.edge[k], h.edge_node[k], ids::edge_nodes(h.n[vol ? k / 4 : k / 2]));
  for (int k = 0; k < nf; ++k)
    if (want_face[k]) {
      const auto [nu, nv] = face_intervals(h, k, mode);
      place(at.face[k], h.face_node[k], ids::face_nodes(nu, nv));
    }
  sort_few(ranges, nr, [](const Range& a, const Range& b) { return a.at < b.at; });
  Id next = 0;
  for (int i = 0; i < nr; ++i) {
    if (ranges[i].at != next)
      E.R.corrupt(RowTable::Elements, hid, ranges[i].at < next ? "two owned entities share node ids"
                                                                : "the element's own node ids are not all its entities'");
    next += ranges[i].count;
  }
  if (next != size) E.R.corrupt(RowTable::Elements, hid, "the element's own node ids are not all its entities'");
  return end;
}

Id own_boundary_nodes(const Evaluator& E, const ElementRow& h, Id hid, const FineBlock::Scratch& s,
                      double* const out[3], Id size) {
  DICER_ASSERT(s.boundary.h == hid && s.boundary.held == FineBlock::Scratch::Boundary::Held::All,
               "own_boundary_nodes: the scratch holds every entity of this element (a direct fill keeps only corners)");
  OwnedPlaces at;
  const Id end = owned_places(E, h, hid, out, size, at);
  const bool vol = E.mode() == Mode::Volume;
  for (int k = 0; k < E.R.corners(); ++k)
    if (at.corner[k][0]) at.corner[k][0][0] = s.corner[k].x, at.corner[k][1][0] = s.corner[k].y, at.corner[k][2][0] = s.corner[k].z;
  for (int k = 0; k < E.R.edges(); ++k)
    if (at.edge[k][0])
      for (int d = 0; d < 3; ++d)
        std::copy_n(s.edge[k][d].data(), ids::edge_nodes(h.n[vol ? k / 4 : k / 2]), at.edge[k][d]);
  for (int k = 0; k < E.R.faces(); ++k)
    if (at.face[k][0]) {
      const auto [nu, nv] = face_intervals(h, k, E.mode());
      for (int d = 0; d < 3; ++d) std::copy_n(s.face[k][d].data(), ids::face_nodes(nu, nv), at.face[k][d]);
    }
  return end;
}

}  // namespace dicer::detail
