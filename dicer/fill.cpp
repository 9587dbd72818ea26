// Block filling: every grid point of one coarse element (or a slab of its
// planes), ids and coordinates, as contiguous arrays. The boundary comes
// from element_boundary (each entity's own function, evaluate.hpp), the
// interior a plane at a time: a curved hex's by the hex TFI, a straight
// one's by the trilinear blend of its corners (tfi.hpp, bilinear_patch).
#include <algorithm>
#include <new>
#include <cstdint>
#include <cstring>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/numbering.hpp"
#include "dicer/orientation.hpp"
#include "dicer/tfi.hpp"
#include "clones.hpp"
#include "evaluate.hpp"

namespace dicer {
namespace {

// dst[gs t] = first + cs t and dst[gs t] = src[cs t], t < m: one row of an
// edge or a face scattered into the boundary slots (ids, coordinates).
void scatter_row(Id* dst, Id gs, Id first, Id cs, Id m) {
  for (Id t = 0; t < m; ++t) dst[gs * t] = first + cs * t;
}
// Rows of ids in arithmetic progression: row q < rows at dst + q gq holds
// first + q cq + t cs, t < m (unsigned arithmetic: the step past the last
// id may wrap). A face's ids in its element's boundary slots (a face's rows
// run along consecutive slots, kHexFaceAxes' first axis in
// Boundary::index), a cell plane's interior. The lanes' offsets t cs are
// formed once per call: GCC's own vectorised induction built them from
// scalars on every row (some 20 instructions a row, on rows of 9 ids at
// interval 10; 10% of a sweep there in this function and cell_plane_ids).
// Four lanes (GCC's vector type, as sweep.cpp's hash_lines: one ymm, two
// xmm on baseline x86-64): eight lanes, two ymm on AVX2, went through the
// stack on every store.
DICER_WIDE_CLONES void progression_rows(Id* dst, Id gq, Id first, Id cs, Id cq, Id m, Id rows) {
  typedef std::uint64_t U64x4 __attribute__((vector_size(32)));
  const auto step = static_cast<std::uint64_t>(cs);
  // Whole-vector arithmetic: lane by lane, GCC kept the offsets on the
  // stack and each row's full-width reload missed store forwarding.
  const U64x4 lane = U64x4{0, 1, 2, 3} * step;
  const std::uint64_t step4 = 4 * step;
  auto x = static_cast<std::uint64_t>(first);
  for (Id q = 0; q < rows; ++q, dst += gq, x += static_cast<std::uint64_t>(cq)) {
    U64x4 v = x + lane;
    Id t = 0;
    for (; t + 4 <= m; t += 4, v += step4) std::memcpy(dst + t, &v, sizeof v);
    for (std::uint64_t y = x + static_cast<std::uint64_t>(t) * step; t < m; ++t, y += step) dst[t] = static_cast<Id>(y);
  }
}

void gather_row(double* dst, Id gs, const double* src, Id cs, Id m) {
  for (Id t = 0; t < m; ++t) dst[gs * t] = src[cs * t];
}

using Held = FineBlock::Scratch::Boundary::Held;

// The boundary of coarse element hid (corners, edges, faces) into b's
// scratch (Boundary::index): ids from the element row alone; coordinates
// from element_boundary, of what `held` asks (Boundary::Held): Corners
// evaluates only the corners and leaves B.x alone; with `to` (a straight
// element) also its owned corners, edges and faces, written there
// (detail::owned_places), not kept in the scratch.
void fill_boundary(const detail::Evaluator& E, std::uint64_t mesh, const ElementRow& h, Id hid, FineBlock& b,
                   Held held, const detail::OwnedPlaces* to = nullptr) {
  const auto n = h.n;
  const Mode mode = E.mode();
  const bool vol = mode == Mode::Volume;
  auto& B = b.scratch.boundary;
  // Keyed only once filled: a throw below (a corrupt row, a failed page
  // load) must not leave a half-filled boundary that a retry would take
  // for this element's.
  B.h = -1, B.n = n, B.volume = vol;
  const size_t nb = static_cast<size_t>(B.size());
  B.id.resize(nb);
  const bool coords = held == Held::All;
  for (int d = 0; d < 3; ++d) coords ? B.x[d].resize(nb) : B.x[d].clear();
  auto& s = b.scratch;
  if (held == Held::Corners) {
    // The owned entities only where `to` places them.
    bool want_edge[12] = {}, want_face[6] = {};
    if (to) detail::owned_entities(h, mode, want_edge, want_face);
    detail::element_boundary(E, h, hid, s, want_edge, want_face, to);
    for (int q = 0; to && q < 8; ++q)
      if (double* const* c = to->corner[q]; c[0]) c[0][0] = s.corner[q].x, c[1][0] = s.corner[q].y, c[2][0] = s.corner[q].z;
  } else if (coords) {
    detail::element_boundary(E, h, hid, s);
  }
  Id* ids = B.id.data();
  double* X[3] = {B.x[0].data(), B.x[1].data(), B.x[2].data()};
  auto grid = [&](const int* c, int axis, Id t) {  // boundary slot of corner c, moved to t along axis
    Id p[3] = {c[0] * n[0], c[1] * n[1], vol ? c[2] * n[2] : 0};
    if (axis >= 0) p[axis] = t;
    return B.index(p[0], p[1], p[2]);
  };
  const int nc = vol ? 8 : 4, ne = vol ? 12 : 4, nf = vol ? 6 : 1;
  for (int q = 0; q < nc; ++q) {
    const Id g = grid(kHexCorner[q], -1, 0);
    ids[g] = h.corner_node[q];
    if (coords) X[0][g] = s.corner[q].x, X[1][g] = s.corner[q].y, X[2][g] = s.corner[q].z;
  }
  // Edges: canonical point tc of local edge le sits at local t (tc = t or,
  // reversed, en - t); both its slot and tc are affine in t.
  for (int le = 0; le < ne; ++le) {
    const int a = vol ? kHexEdge[le][0] : kQuadEdge[le][0];
    const int axis = vol ? le / 4 : le / 2;
    const Id en = n[axis];
    if (en < 2) continue;
    const Id g = grid(kHexCorner[a], axis, 1), gs = en > 2 ? grid(kHexCorner[a], axis, 2) - g : 0;
    const Id c1 = h.rev(le) ? en - 1 : 1, cs = h.rev(le) ? -1 : 1;  // tc at t = 1, and its step
    scatter_row(ids + g, gs, ids::edge_node(h.edge_node[le], c1), cs, en - 1);
    for (int d = 0; d < 3 && coords; ++d) gather_row(X[d] + g, gs, s.edge[le][d].data() + (c1 - 1), cs, en - 1);
  }
  // Faces: the canonical fill scattered through the face map.
  for (int lf = 0; lf < nf; ++lf) {
    const auto [nu, nv] = face_intervals(h, lf, mode);
    if (nu < 2 || nv < 2) continue;
    const FaceMap fm = face_map(h.code(lf), nu, nv);
    const int ax = vol ? kHexFaceAxes[lf][0] : 0, bx = vol ? kHexFaceAxes[lf][1] : 1;
    Id p[3] = {0, 0, 0};
    if (vol) p[lf / 2] = (lf % 2) ? n[lf / 2] : 0;
    // Both the slot and the canonical index are affine in (pp, q): a
    // strided copy per row (pp = 1 .. n[ax] - 1 at fixed q), rows apart by
    // constant steps.
    const Id m = n[ax] - 1, cs = fm.up + fm.vp * (nu - 1), cq = fm.uq + fm.vq * (nu - 1);
    auto slot = [&](Id pa, Id q) { return p[ax] = pa, p[bx] = q, B.index(p[0], p[1], p[2]); };
    const Id g1 = slot(1, 1), gs = m > 1 ? slot(2, 1) - g1 : 0, gq = n[bx] > 2 ? slot(1, 2) - g1 : 0;
    const Id c1 = ids::face_node(0, nu, fm.u(1, 1), fm.v(1, 1));  // canonical index at (1, 1)
    DICER_ASSERT(gs == 1 || m < 2, "fill_boundary: a face's rows run along consecutive boundary slots");
    progression_rows(ids + g1, gq, h.face_node[lf] + c1, cs, cq, m, n[bx] - 1);
    for (Id q = 1; q < n[bx] && coords; ++q) {
      const Id g = g1 + (q - 1) * gq, c = c1 + (q - 1) * cq;
      for (int d = 0; d < 3; ++d) gather_row(X[d] + g, gs, s.face[lf][d].data() + c, cs, m);
    }
  }
  B.mesh = mesh, B.h = hid, B.held = held;
}

// The hex's corners c0..c7 (kHexCorner) of coordinate d.
void block_corners(const Vec3* corner, int d, double* c) {
  for (int q = 0; q < 8; ++q) c[q] = component(corner[q], d);
}

// A curved hex's interior, one coordinate, from the block's boundary values:
// tfi::hex_plane once per plane, hex_column once per (i, k), hex_row once
// per (j, k), hex_point for each point, the calls Evaluator::cell_point() makes,
// fed the same boundary values (clones.hpp: every clone gives the same bits).
// One interior plane k (0 < k < n[2]) of one coordinate: a0 and aN are the
// planes k = 0 and k = n[2], ak plane k with its ring (i or j at 0 or n)
// filled; all three with row stride n[0] + 1. A plane at a time, so a block
// can be produced in slabs (cursors hold O(n^2), not O(n^3)).
// u, v: the i- and j-axis parameters, w plane k's (tfi::Series of the
// element's gradings); P, G: room for n[0] column terms each.
// The interior goes to dst: point (i, j) at dst[(j - 1) dj + i - 1] (ak's
// own rows: dst = ak + n[0] + 2, dj = n[0] + 1; compact: dj = n[0] - 1).
// c: the corners (block_corners).
DICER_CLONES void hex_interior_plane(const double* c, const double* a0, const double* aN, const double* ak,
                                     std::array<Id, 3> n, const double* u, const double* v, double w, double* dst,
                                     Id dj, double* P, double* G) {
  const Id sj = n[0] + 1;
  const Id n1 = n[1] * sj;
  const double ek[4] = {ak[0], ak[n[0]], ak[n[0] + n1], ak[n1]};  // the k-edges e8..e11 at plane k
  const tfi::HexPlane plane = tfi::hex_plane(w, ek, c);
  // Columns: the j = 0 and j = n1 faces (ak's first and last rows) and the
  // four i-edges (i, 0 | n1, 0 | n2).
  const double* e0 = a0;
  const double* e1 = a0 + n1;
  const double* e2 = aN;
  const double* e3 = aN + n1;
  for (Id i = 1; i < n[0]; ++i) {
    const tfi::HexColumn col = tfi::hex_column(plane, ak[i], ak[n1 + i], e0[i], e1[i], e2[i], e3[i]);
    P[i] = col.P, G[i] = col.G;
  }
  for (Id j = 1; j < n[1]; ++j) {
    const Id r = j * sj;
    const double* f4 = a0 + r;  // (i, j, 0)
    const double* f5 = aN + r;  // (i, j, n2)
    const double vj = v[j];
    const tfi::HexRow row = tfi::hex_row(plane, vj, ak[r], ak[n[0] + r], a0[r], a0[n[0] + r], aN[r], aN[n[0] + r]);
    double* out = dst + (j - 1) * dj;
    for (Id i = 1; i < n[0]; ++i) out[i - 1] = tfi::hex_point(row, {P[i], G[i]}, u[i], vj, w, f4[i], f5[i]);
  }
}

// The interior points of grid plane k (0 < k < n[2]) of a block: the
// cell's own ids, consecutive along each row (numbering.hpp), into the
// plane's ids (row stride n[0] + 1).
void cell_plane_ids(Id cell_node, std::array<Id, 3> n, Id k, Id* ids) {
  const Id ni = n[0] + 1;
  progression_rows(ids + ni + 1, ni, ids::cell_node(cell_node, n, 1, 1, k), 1, n[0] - 1, n[0] - 1, n[1] - 1);
}

// kHexCorner takes a cell's corners in pairs, one pair per grid row
// around it: row r's ids at i and i + 1, in that order for rows 0 and 2,
// swapped for rows 1 and 3. The rows below copy each pair with one 16-byte
// load and store: 4 stores per hex where one per corner took 8 (the
// compiler's own vectorisation, a transpose of 8 streams, took more
// shuffles still; the store port bounds this loop).
constexpr bool corners_come_in_row_pairs() {
  for (int q = 0; q < 8; ++q)
    if (grid_cell_row(q) != q / 2 || kHexCorner[q][0] != ((q % 2) ^ (q / 2 % 2))) return false;
  return true;
}
static_assert(corners_come_in_row_pairs(), "hex_conn_row copies kHexCorner's pairs: update both together");

// The pair (row[i], row[i + 1]) at out, swapped when `swap`.
template <bool swap>
inline void copy_pair(const Id* row, Id* out) {
#if defined(__SSE2__)
  static_assert(sizeof(Id) == 8);
  __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row));
  if constexpr (swap) v = _mm_shuffle_epi32(v, 0x4E);
  _mm_storeu_si128(reinterpret_cast<__m128i*>(out), v);
#else
  out[0] = row[swap ? 1 : 0], out[1] = row[swap ? 0 : 1];
#endif
}

// Connectivity of one row of m fine hexes (kHexCorner order) whose corner
// (0, 0, 0) points are p[0..m): rows of the block's node ids (row stride
// sj, plane stride sk).
DICER_CLONES void hex_conn_row(const Id* p, Id sj, Id sk, Id m, Id* out) {
  const Id *r0 = p, *r1 = p + sj, *r2 = p + sk, *r3 = p + sk + sj;
  for (Id i = 0; i < m; ++i, out += 8) {
    copy_pair<false>(r0 + i, out);
    copy_pair<true>(r1 + i, out + 2);
    copy_pair<false>(r2 + i, out + 4);
    copy_pair<true>(r3 + i, out + 6);
  }
}
void quad_conn_row(const Id* p, Id sj, Id m, Id* out) {
  const Id *r0 = p, *r1 = p + sj;
  for (Id i = 0; i < m; ++i, out += 4) {
    copy_pair<false>(r0 + i, out);
    copy_pair<true>(r1 + i, out + 2);
  }
}

}  // namespace

void FineMesh::fill_slab(Id hid, Id k0, Id k1, FineBlock& b, bool coords, bool conn) const {
  fill_slab(hid, k0, k1, b, coords, conn, true, nullptr, nullptr, nullptr, 0);
}

void FineMesh::fill_slab(Id hid, Id k0, Id k1, FineBlock& b, bool coords, bool conn, bool ids_wanted,
                         double* const* interior, const ElementRow* row, double* const* own, Id own_size) const {
  const detail::Evaluator E(tables_, b.cursor);
  ElementRow decoded;
  if (!row) E.R.element(hid, decoded);
  const ElementRow& h = row ? *row : decoded;
  const auto n = h.n;
  const bool vol = mode() == Mode::Volume;
  if (k1 < 0) k1 = vol ? n[2] : 0;
  if (k0 < 0 || k0 > k1 || k1 > (vol ? n[2] : 0) || (conn && vol && k0 == k1))
    throw Error(ErrorKind::Usage, "fill_slab: planes " + std::to_string(k0) + ".." + std::to_string(k1) +
                                      " of coarse element " + std::to_string(hid) + " (it has " +
                                      std::to_string(vol ? n[2] : 0) + ")");
  if (interior) coords = true;
  auto& B = b.scratch.boundary;
  // The compact interior of a straight hex reads only its corners; its
  // owned entities go straight into the batch (`own`), any other
  // element's by way of the scratch (own_boundary_nodes: Held::All).
  const Held need = !coords ? Held::Ids : interior && !h.curved() ? Held::Corners : Held::All;
  if (own) {
    if (!interior || h.curved() || k0 != 0) throw Error(ErrorKind::Usage, "fill_slab: own nodes of a straight hex's first slab only");
    detail::OwnedPlaces to;
    detail::owned_places(E, h, hid, own, own_size, to);  // validated before anything is written
    fill_boundary(E, serial_, h, hid, b, need, &to);     // always: a kept boundary would not write them
  } else if (B.mesh != serial_ || B.h != hid || B.held < need) {
    fill_boundary(E, serial_, h, hid, b, need);
  }
  b.coarse_element = hid;
  b.n = n;
  b.block = h.block;
  b.plane0 = k0;
  b.planes = k1 - k0 + 1;
  b.layers = vol ? k1 - k0 : 1;
  b.first_element = ids::element(h.element_first, n, 0, 0, k0);
  b.node_first = h.node_first;
  const Id ni = n[0] + 1, nj = n[1] + 1, pp = ni * nj;
  const size_t np = static_cast<size_t>(pp * b.planes);
  const bool want_ids = ids_wanted || conn;
  want_ids ? b.node_id.resize(np) : b.node_id.clear();
  // Compact: x, y, z hold one plane, the ring the kernel reads.
  const size_t nx = interior ? static_cast<size_t>(pp) : np;
  for (auto* x : {&b.x, &b.y, &b.z}) coords ? x->resize(nx) : x->clear();
  const Id in = (n[0] - 1) * (n[1] - 1);
  auto& s = b.scratch;
  if (coords && vol) {
    // The three axes' parameters, once per slab (O(n)): the kernel reads tables.
    // u padded for bilinear_patch (zeros: finite, not subnormal).
    s.u.resize(static_cast<size_t>(n[0] + detail::kPatchSlack));
    std::fill(s.u.begin() + n[0], s.u.end(), 0.0);
    s.P.resize(static_cast<size_t>(n[0])), s.G.resize(static_cast<size_t>(n[0]));
    s.v.resize(static_cast<size_t>(n[1])), s.w.resize(static_cast<size_t>(n[2]));
    detail::series_values(n[0], h.grading[0], 1, n[0], s.u.data());
    detail::series_values(n[1], h.grading[1], 1, n[1], s.v.data());
    detail::series_values(n[2], h.grading[2], std::max<Id>(k0, 1), std::min(k1 + 1, n[2]), s.w.data());
  }
  // A straight hex's planes: one patch grid for all of them (evaluate.hpp).
  thread_local detail::PatchGrid patch_grid;
  if (coords && vol && !h.curved()) detail::prepare_patch_grid(s.u.data(), s.v.data(), n[0], n[1], patch_grid);
  for (Id k = k0; k <= k1; ++k) {
    const size_t at = static_cast<size_t>((k - k0) * pp);
    Id* ids = want_ids ? b.node_id.data() + at : nullptr;  // no grid held: never written
    double* X[3] = {nullptr, nullptr, nullptr};
    const size_t xat = interior ? 0 : at;
    if (coords) X[0] = b.x.data() + xat, X[1] = b.y.data() + xat, X[2] = b.z.data() + xat;
    if (!vol || k == 0 || k == n[2]) {  // a face plane: all boundary
      const size_t from = static_cast<size_t>(B.index(0, 0, k));
      if (want_ids) std::copy_n(B.id.data() + from, pp, ids);
      for (int d = 0; d < 3 && coords && !interior; ++d) std::copy_n(B.x[d].data() + from, pp, X[d]);
      continue;
    }
    // The ring of plane k from the side faces and edges, the rest hex interior.
    const size_t ring = static_cast<size_t>(B.index(0, 0, k));
    auto ring_copy = [&](const auto* src, auto* dst) {
      for (Id i = 0; i < ni; ++i) dst[i] = src[i], dst[i + n[1] * ni] = src[ni + i];
      for (Id j = 1; j < n[1]; ++j) dst[j * ni] = src[2 * ni + j - 1], dst[n[0] + j * ni] = src[2 * ni + n[1] - 1 + j - 1];
    };
    if (want_ids) {
      ring_copy(B.id.data() + ring, ids);
      cell_plane_ids(h.cell_node, n, k, ids);
    }
    // Compact: the planes after k0 only (plane k0 ended the previous slab).
    if (interior && (k == k0 || in == 0)) continue;
    if (!coords) continue;
    for (int d = 0; d < 3; ++d) {
      if (!interior || h.curved()) ring_copy(B.x[d].data() + ring, X[d]);  // compact: only the TFI reads it
      double* const dst = interior ? interior[d] + (k - k0 - 1) * in : X[d] + ni + 1;
      double c[8];
      block_corners(s.corner, d, c);
      if (h.curved()) {
        hex_interior_plane(c, B.x[d].data(), B.x[d].data() + pp, X[d], n, s.u.data(), s.v.data(), s.w[k], dst,
                           interior ? n[0] - 1 : ni, s.P.data(), s.G.data());
        continue;
      }
      // A straight hex's plane k: the bilinear patch of its corners'
      // trilinear_plane, as cell_point computes each point. Compact: into
      // the batch's arrays, which have bilinear_patch's room past the last
      // plane (BatchCursor); a whole block's plane by way of the scratch.
      double q[4];
      tfi::trilinear_plane(s.w[k], c, q);
      if (interior) {
        detail::bilinear_patch(patch_grid, q, dst);
        continue;
      }
      s.patch.resize(static_cast<size_t>(in + detail::kPatchSlack));
      detail::bilinear_patch(patch_grid, q, s.patch.data());
      for (Id j = 1; j < n[1]; ++j) std::copy_n(s.patch.data() + (j - 1) * (n[0] - 1), n[0] - 1, dst + (j - 1) * ni);
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
    for (Id k = k0; k < k1; ++k)
      for (Id j = 0; j < n[1]; ++j, out += 8 * n[0]) hex_conn_row(ids + b.point_index(0, j, k), ni, pp, n[0], out);
  } else {
    for (Id j = 0; j < n[1]; ++j, out += 4 * n[0]) quad_conn_row(ids + b.point_index(0, j, 0), ni, n[0], out);
  }
}

namespace detail {

void slab_lines(const FineBlock::Scratch::Boundary& B, Id cell_node, Id k0, Id k1, Id* start, Id* first, Id* step,
                Id* end) {
  const auto n = B.n;
  const Id n0 = n[0], w = n[1] + 1;
  // A row held whole in the boundary (a face plane's, a ring's j = 0 or
  // n[1]): its ends and its interior's first two points.
  auto whole = [&](const Id* q, Id r) {
    start[r] = q[0], end[r] = q[n0];
    first[r] = q[std::min<Id>(n0, 1)];
    step[r] = n0 >= 3 ? q[2] - q[1] : 0;
  };
  const Id* const id = B.id.data();
  for (Id k = k0; k <= k1; ++k) {
    const Id r0 = w * (k - k0);
    if (!B.volume || k == 0 || k == n[2]) {
      for (Id j = 0; j < w; ++j) whole(id + B.index(0, j, k), r0 + j);
      continue;
    }
    // The ring: rows j = 0 and n[1] whole, then the i = 0 and i = n[0]
    // columns, each consecutive (Boundary::index); the rest of each row is
    // the cell's own interior, consecutive ids (numbering.hpp).
    whole(id + B.index(0, 0, k), r0), whole(id + B.index(0, n[1], k), r0 + w - 1);
    const Id m = n[1] - 1, r = r0 + 1;
    if (m == 0) continue;
    const Id* const left = id + B.index(0, 1, k);
    const Id* const right = id + B.index(n0, 1, k);
    std::copy_n(left, m, start + r), std::copy_n(right, m, end + r);
    std::fill_n(step + r, m, n0 >= 3 ? 1 : 0);
    if (n0 < 2) {
      std::copy_n(right, m, first + r);
      continue;
    }
    const Id c = ids::cell_node(cell_node, n, 1, 1, k);  // rows n[0] - 1 apart
    for (Id j = 0; j < m; ++j) first[r + j] = c + j * (n0 - 1);
  }
}

}  // namespace detail

void FineMesh::fill_block(Id hid, FineBlock& b, bool nodes_only) const { fill_slab(hid, 0, -1, b, true, !nodes_only); }

void FineMesh::for_each_slab(Id hid, FineBlock& b, bool conn, const std::function<void(const FineBlock&)>& fn) const {
  const auto n = detail::Evaluator(tables_, b.cursor).R.element(hid).n;
  const bool vol = mode() == Mode::Volume;
  const Id plane = (n[0] + 1) * (n[1] + 1), layers = vol ? std::max<Id>(1, kCursorSlabPoints / plane - 1) : 1;
  // A slab's ids and coordinates (32 B a point) and connectivity, and the
  // element's whole boundary twice (Held::All: its points, and each
  // entity's in the scratch's canonical arrays), 56 B a point.
  const double n0 = double(n[0]), n1 = double(n[1]), n2 = vol ? double(n[2]) : 0.0, p = double(plane);
  const double boundary = vol ? 2 * (n0 * n1 + n1 * n2 + n0 * n2) + 2 : p;
  const double slab = vol ? p * double(layers + 1) : p, cells = n0 * n1 * (vol ? double(layers) : 1.0);
  const double bytes = slab * 32 + boundary * 56 + (conn ? cells * corners() * 8 : 0);
  const char* const how = "is read a slab of grid planes at a time with its whole boundary";
  check_element_memory(*this, hid, n, how, bytes, static_cast<double>(b.held_bytes()));
  auto fill = [&](Id k0, Id k1) {
    try {
      fill_slab(hid, k0, k1, b, true, conn);
    } catch (const std::bad_alloc&) {
      if (bytes < double(1u << 28)) throw;  // a small element: memory ran out elsewhere
      throw element_too_big(*this, hid, n, how, bytes);
    }
  };
  if (!vol) {
    fill(0, 0);
    return fn(b);
  }
  for (Id k0 = 0; k0 < n[2]; k0 += layers) {
    fill(k0, std::min(k0 + layers, n[2]));
    fn(b);
  }
}

}  // namespace dicer
