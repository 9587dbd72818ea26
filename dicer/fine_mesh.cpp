// The implicit fine mesh: classification of grid points to their owning
// entity, and evaluation of the TFI recipe in that entity's canonical frame.
#include "dicer/fine_mesh.hpp"

#include <algorithm>

#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "dicer/tfi.hpp"

namespace dicer {

namespace {

// Hex interior of one coordinate array of a block whose boundary is filled:
// tfi::hex_row once per (j, k), tfi::hex_point along i, the same two calls
// FineMesh::cell_point() makes, fed the same boundary values. Built twice
// (AVX2 and baseline x86-64): both are plain IEEE mul/add/sub in the same
// order with contraction off, so both give the same bits.
__attribute__((target_clones("avx2", "default"))) void hex_interior(double* a, std::array<Id, 3> n,
                                                                     const double* u, const double* U) {
  const Id sj = n[0] + 1, sk = (n[0] + 1) * (n[1] + 1);
  double c[8];
  for (int q = 0; q < 8; ++q) c[q] = a[kHexCorner[q][0] * n[0] + kHexCorner[q][1] * n[1] * sj + kHexCorner[q][2] * n[2] * sk];
  const double* e0 = a;                          // (i, 0, 0)
  const double* e1 = a + n[1] * sj;              // (i, n1, 0)
  const double* e2 = a + n[2] * sk;              // (i, 0, n2)
  const double* e3 = a + n[1] * sj + n[2] * sk;  // (i, n1, n2)
  for (Id k = 1; k < n[2]; ++k) {
    const double w = tfi::weight(k, n[2]);
    const double* f2 = a + k * sk;               // (i, 0, k)
    const double* f3 = a + n[1] * sj + k * sk;   // (i, n1, k)
    for (Id j = 1; j < n[1]; ++j) {
      const double v = tfi::weight(j, n[1]);
      const double* f4 = a + j * sj;             // (i, j, 0)
      const double* f5 = a + j * sj + n[2] * sk; // (i, j, n2)
      const double e[12] = {0, 0, 0, 0, a[j * sj], a[n[0] + j * sj], a[j * sj + n[2] * sk],
                            a[n[0] + j * sj + n[2] * sk], a[k * sk], a[n[0] + k * sk],
                            a[n[0] + n[1] * sj + k * sk], a[n[1] * sj + k * sk]};
      const tfi::HexRow row = tfi::hex_row(v, w, a[j * sj + k * sk], a[n[0] + j * sj + k * sk], e, c);
      double* out = a + j * sj + k * sk;
      for (Id i = 1; i < n[0]; ++i)
        out[i] = tfi::hex_point(row, u[i], U[i], f2[i], f3[i], f4[i], f5[i], e0[i], e1[i], e2[i], e3[i]);
    }
  }
}

}  // namespace

FineMesh::FineMesh(CoarseMesh coarse, Topology topo, Numbering numbering, std::vector<Id> sheet_interval)
    : coarse_(std::move(coarse)),
      topo_(std::move(topo)),
      num_(std::move(numbering)),
      sheet_interval_(std::move(sheet_interval)) {}

FineMesh FineMesh::dice(CoarseMesh coarse, const IntervalRequest& request, std::vector<std::string>* notes) {
  Topology topo = build_topology(coarse);
  Sheets sheets = find_sheets(coarse, topo);
  IntervalPlan plan = resolve_intervals(coarse, topo, sheets, request);
  if (notes) *notes = plan.notes;
  Numbering num(topo, edge_intervals(sheets, plan));
  return FineMesh(std::move(coarse), std::move(topo), std::move(num), std::move(plan.sheet_interval));
}

Vec3 FineMesh::edge_point(Id e, Id t) const {
  const Id a = topo_.edge_v[2 * e], b = topo_.edge_v[2 * e + 1];
  const Id n = num_.edge_n(e);
  if (t == 0) return coarse_.vertex(a);
  if (t == n) return coarse_.vertex(b);
  const double s = tfi::weight(t, n);
  return {tfi::edge(coarse_.x[a], coarse_.x[b], s), tfi::edge(coarse_.y[a], coarse_.y[b], s),
          tfi::edge(coarse_.z[a], coarse_.z[b], s)};
}

Vec3 FineMesh::face_point(Id f, Id u, Id v) const {
  const auto [nu, nv] = num_.face_n(f);
  const Id* fe = &topo_.face_edge[4 * f];
  const std::uint8_t* rev = &topo_.face_edge_rev[4 * f];
  auto along = [&](int k, Id s) {
    const Id n = num_.edge_n(fe[k]);
    return edge_point(fe[k], rev[k] ? n - s : s);
  };
  // Points on the face boundary belong to its edges and vertices.
  if (v == 0) return along(0, u);
  if (v == nv) return along(1, u);
  if (u == 0) return along(2, v);
  if (u == nu) return along(3, v);
  const Vec3 sides[4] = {along(0, u), along(1, u), along(2, v), along(3, v)};
  return face_interior(f, u, v, sides);
}

Vec3 FineMesh::face_interior(Id f, Id u, Id v, const Vec3* s) const {
  const auto [nu, nv] = num_.face_n(f);
  const Id* fv = &topo_.face_v[4 * f];
  const double a = tfi::weight(u, nu), b = tfi::weight(v, nv);
  auto one = [&](const double* X, double Vec3::*m) {
    return tfi::coons(a, b, s[0].*m, s[1].*m, s[2].*m, s[3].*m, X[fv[0]], X[fv[1]], X[fv[2]], X[fv[3]]);
  };
  return {one(coarse_.x.data(), &Vec3::x), one(coarse_.y.data(), &Vec3::y), one(coarse_.z.data(), &Vec3::z)};
}

NodeRef FineMesh::grid_node(Id h, Id i, Id j, Id k) const {
  const auto n = num_.elem_n(h);
  NodeRef r;
  if (coarse_.mode == Mode::Surface) {
    const int ex = (i == 0 || i == n[0]) + (j == 0 || j == n[1]);
    const Id* c = &coarse_.conn[static_cast<size_t>(h) * 4];
    if (ex == 2) {
      static constexpr int kCorner[2][2] = {{0, 3}, {1, 2}};  // [i>0][j>0]
      r.kind = EntityKind::Vertex;
      r.entity = c[kCorner[i > 0][j > 0]];
      return r;
    }
    if (ex == 1) {
      const int le = j == 0 ? 0 : j == n[1] ? 1 : i == 0 ? 2 : 3;
      const Id t = le < 2 ? i : j;
      const Id e = topo_.elem_edge[4 * h + le];
      r.kind = EntityKind::Edge;
      r.entity = e;
      r.local[0] = topo_.elem_edge_rev[4 * h + le] ? num_.edge_n(e) - t : t;
      return r;
    }
    const Id f = topo_.elem_face[h];
    const auto fn = num_.face_n(f);
    const FaceMap fm = face_map(topo_.elem_face_code[h], fn[0], fn[1]);
    r.kind = EntityKind::Face;
    r.entity = f;
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
    r.entity = coarse_.conn[static_cast<size_t>(h) * 8 + kCorner[ext[0]][ext[1]][ext[2]]];
    return r;
  }
  if (count == 2) {
    const int axis = ext[0] < 0 ? 0 : ext[1] < 0 ? 1 : 2;
    int le;
    if (axis == 0) le = ext[1] + 2 * ext[2];
    else if (axis == 1) le = 4 + ext[0] + 2 * ext[2];
    else le = 8 + (ext[1] ? 3 - ext[0] : ext[0]);  // (0,0)->8 (1,0)->9 (1,1)->10 (0,1)->11
    const Id e = topo_.elem_edge[12 * h + le];
    r.kind = EntityKind::Edge;
    r.entity = e;
    r.local[0] = topo_.elem_edge_rev[12 * h + le] ? num_.edge_n(e) - p[axis] : p[axis];
    return r;
  }
  if (count == 1) {
    const int axis = ext[0] >= 0 ? 0 : ext[1] >= 0 ? 1 : 2;
    const int lf = 2 * axis + ext[axis];
    const Id f = topo_.elem_face[6 * h + lf];
    const auto fn = num_.face_n(f);
    const FaceMap fm = face_map(topo_.elem_face_code[6 * h + lf], fn[0], fn[1]);
    const Id a = p[kHexFaceAxes[lf][0]], b = p[kHexFaceAxes[lf][1]];
    r.kind = EntityKind::Face;
    r.entity = f;
    r.local = {fm.u(a, b), fm.v(a, b), 0};
    return r;
  }
  r.kind = EntityKind::Cell;
  r.entity = h;
  r.local = {i, j, k};
  return r;
}

Vec3 FineMesh::cell_point(Id h, Id i, Id j, Id k) const {
  // The 26 boundary values the block fill would have at (i, j, k)'s
  // projections, each from its owner in its canonical frame.
  const auto n = num_.elem_n(h);
  const Id t[3] = {i, j, k};
  double f[3][6], e[3][12], c[3][8];
  for (int q = 0; q < 12; ++q) {
    const Id ed = topo_.elem_edge[12 * h + q], ne = num_.edge_n(ed), tq = t[q / 4];
    const Vec3 x = edge_point(ed, topo_.elem_edge_rev[12 * h + q] ? ne - tq : tq);
    e[0][q] = x.x, e[1][q] = x.y, e[2][q] = x.z;
  }
  for (int q = 0; q < 6; ++q) {
    const Id fa = topo_.elem_face[6 * h + q];
    const auto fn = num_.face_n(fa);
    const FaceCode code = topo_.elem_face_code[6 * h + q];
    const FaceMap fm = face_map(code, fn[0], fn[1]);
    const Id a = t[kHexFaceAxes[q][0]], b = t[kHexFaceAxes[q][1]];
    // The face's canonical sides at this point are hex edges already
    // evaluated above (the same fine nodes, so the same bits).
    Vec3 sides[4];
    for (int side = 0; side < 4; ++side) {
      const int le = hex_face_side_edge(q, code, side);
      sides[side] = {e[0][le], e[1][le], e[2][le]};
    }
    const Vec3 x = face_interior(fa, fm.u(a, b), fm.v(a, b), sides);
    f[0][q] = x.x, f[1][q] = x.y, f[2][q] = x.z;
  }
  for (int q = 0; q < 8; ++q) {
    const Id v = coarse_.conn[static_cast<size_t>(h) * 8 + q];
    c[0][q] = coarse_.x[v], c[1][q] = coarse_.y[v], c[2][q] = coarse_.z[v];
  }
  const double u = tfi::weight(i, n[0]), v = tfi::weight(j, n[1]), w = tfi::weight(k, n[2]);
  double out[3];
  for (int d = 0; d < 3; ++d) {
    const tfi::HexRow row = tfi::hex_row(v, w, f[d][0], f[d][1], e[d], c[d]);
    out[d] = tfi::hex_point(row, u, 1.0 - u, f[d][2], f[d][3], f[d][4], f[d][5], e[d][0], e[d][1], e[d][2], e[d][3]);
  }
  return {out[0], out[1], out[2]};
}

Vec3 FineMesh::node(const NodeRef& r) const {
  switch (r.kind) {
    case EntityKind::Vertex: return coarse_.vertex(r.entity);
    case EntityKind::Edge: return edge_point(r.entity, r.local[0]);
    case EntityKind::Face: return face_point(r.entity, r.local[0], r.local[1]);
    case EntityKind::Cell: return cell_point(r.entity, r.local[0], r.local[1], r.local[2]);
  }
  return {};
}

Vec3 FineMesh::node(Id id) const {
  if (id < 0 || id >= num_nodes())
    throw Error(ErrorKind::Usage, "node id " + std::to_string(id) + " is out of range (the mesh has " +
                                      std::to_string(num_nodes()) + " nodes)");
  return node(num_.locate_node(id));
}

FineElement FineMesh::element(Id id) const {
  if (id < 0 || id >= num_elements())
    throw Error(ErrorKind::Usage, "element id " + std::to_string(id) + " is out of range (the mesh has " +
                                      std::to_string(num_elements()) + " elements)");
  FineElement el;
  el.id = id;
  el.coarse_element = num_.locate_element(id, el.ijk);
  el.block = coarse_.element_block[el.coarse_element];
  const auto [i, j, k] = el.ijk;
  const Id h = el.coarse_element;
  if (mode() == Mode::Volume) {
    el.num_nodes = 8;
    for (int q = 0; q < 8; ++q)
      el.nodes[q] = num_.node_id(grid_node(h, i + kHexCorner[q][0], j + kHexCorner[q][1], k + kHexCorner[q][2]));
  } else {
    el.num_nodes = 4;
    for (int q = 0; q < 4; ++q)
      el.nodes[q] = num_.node_id(grid_node(h, i + kHexCorner[q][0], j + kHexCorner[q][1], 0));
  }
  return el;
}

void FineMesh::fill_face(Id f, FineBlock::Scratch& s) const {
  const auto [nu, nv] = num_.face_n(f);
  const Id* fe = &topo_.face_edge[4 * f];
  const std::uint8_t* rev = &topo_.face_edge_rev[4 * f];
  // Boundary values exactly as face_point() gathers them.
  auto gather = [&](int k, Id len, std::vector<double>* out) {
    const Id n = num_.edge_n(fe[k]);
    for (int d = 0; d < 3; ++d) out[d].resize(static_cast<size_t>(len + 1));
    for (Id q = 1; q < len; ++q) {
      const Vec3 x = edge_point(fe[k], rev[k] ? n - q : q);
      out[0][q] = x.x, out[1][q] = x.y, out[2][q] = x.z;
    }
  };
  gather(0, nu, s.bottom), gather(1, nu, s.top), gather(2, nv, s.left), gather(3, nv, s.right);
  s.s.resize(static_cast<size_t>(nu)), s.t.resize(static_cast<size_t>(nv));
  for (Id u = 1; u < nu; ++u) s.s[u] = tfi::weight(u, nu);
  for (Id v = 1; v < nv; ++v) s.t[v] = tfi::weight(v, nv);
  const size_t count = static_cast<size_t>((nu - 1) * (nv - 1));
  for (int d = 0; d < 3; ++d) {
    const double* X = d == 0 ? coarse_.x.data() : d == 1 ? coarse_.y.data() : coarse_.z.data();
    const double p0 = X[topo_.face_v[4 * f]], p1 = X[topo_.face_v[4 * f + 1]], p2 = X[topo_.face_v[4 * f + 2]],
                 p3 = X[topo_.face_v[4 * f + 3]];
    s.face[d].resize(count);
    double* out = s.face[d].data();
    const double *B = s.bottom[d].data(), *T = s.top[d].data(), *L = s.left[d].data(), *R = s.right[d].data();
    for (Id v = 1; v < nv; ++v) {
      const double t = s.t[v];
      for (Id u = 1; u < nu; ++u) *out++ = tfi::coons(s.s[u], t, B[u], T[u], L[v], R[v], p0, p1, p2, p3);
    }
  }
}

void FineMesh::fill_block(Id h, FineBlock& b, bool nodes_only) const {
  const auto n = num_.elem_n(h);
  const bool vol = mode() == Mode::Volume;
  const int nc = corners();
  b.coarse_element = h;
  b.n = n;
  b.first_element = num_.elem_first_element(h);
  const Id ni = n[0] + 1, nj = n[1] + 1, nk = vol ? n[2] + 1 : 1;
  const size_t np = static_cast<size_t>(ni * nj * nk);
  b.node_id.resize(np);
  b.x.resize(np), b.y.resize(np), b.z.resize(np);
  Id* ids = b.node_id.data();
  double* X[3] = {b.x.data(), b.y.data(), b.z.data()};
  auto put = [&](Id g, Id id, const Vec3& p) { ids[g] = id, X[0][g] = p.x, X[1][g] = p.y, X[2][g] = p.z; };
  auto grid = [&](const int* c, int axis, Id t) {  // grid point of corner c, moved to t along axis
    Id p[3] = {c[0] * n[0], c[1] * n[1], vol ? c[2] * n[2] : 0};
    if (axis >= 0) p[axis] = t;
    return b.point_index(p[0], p[1], p[2]);
  };
  const Id* cv = &coarse_.conn[static_cast<size_t>(h) * nc];
  for (int q = 0; q < nc; ++q) put(grid(kHexCorner[q], -1, 0), cv[q], coarse_.vertex(cv[q]));

  // Edges: every interior point from edge_point in the canonical direction.
  const int epe = topo_.edges_per_element();
  for (int le = 0; le < epe; ++le) {
    const Id e = topo_.elem_edge[static_cast<size_t>(h) * epe + le];
    const bool rev = topo_.elem_edge_rev[static_cast<size_t>(h) * epe + le];
    const Id ne = num_.edge_n(e), base = num_.edge_node_offset(e) - 1;
    const int a = vol ? kHexEdge[le][0] : kQuadEdge[le][0];
    const int axis = vol ? le / 4 : le / 2;
    for (Id t = 1; t < ne; ++t) {
      const Id tc = rev ? ne - t : t;
      put(grid(kHexCorner[a], axis, t), base + tc, edge_point(e, tc));
    }
  }

  // Faces: canonical fill, then scattered through the face map.
  const int fpe = topo_.faces_per_element();
  for (int lf = 0; lf < fpe; ++lf) {
    const Id f = topo_.elem_face[static_cast<size_t>(h) * fpe + lf];
    const auto [nu, nv] = num_.face_n(f);
    if (nu < 2 || nv < 2) continue;
    fill_face(f, b.scratch);
    const FaceMap fm = face_map(topo_.elem_face_code[static_cast<size_t>(h) * fpe + lf], nu, nv);
    const int ax = vol ? kHexFaceAxes[lf][0] : 0, bx = vol ? kHexFaceAxes[lf][1] : 1;
    const Id na = n[ax], nb = n[bx], base = num_.face_node_offset(f);
    Id p[3] = {0, 0, 0};
    if (vol) p[lf / 2] = (lf % 2) ? n[lf / 2] : 0;
    for (Id q = 1; q < nb; ++q)
      for (Id pp = 1; pp < na; ++pp) {
        p[ax] = pp, p[bx] = q;
        const Id c = (fm.u(pp, q) - 1) + (fm.v(pp, q) - 1) * (nu - 1);
        const Id g = b.point_index(p[0], p[1], p[2]);
        ids[g] = base + c;
        for (int d = 0; d < 3; ++d) X[d][g] = b.scratch.face[d][c];
      }
  }

  if (vol && n[0] > 1 && n[1] > 1 && n[2] > 1) {
    // Hex interior: tfi::hex_row once per (j, k), tfi::hex_point along i,
    // the same two calls cell_point() makes, fed the same boundary values.
    auto& s = b.scratch;
    s.u.resize(static_cast<size_t>(n[0])), s.U.resize(static_cast<size_t>(n[0]));
    for (Id i = 1; i < n[0]; ++i) s.u[i] = tfi::weight(i, n[0]), s.U[i] = 1.0 - s.u[i];
    Id id = num_.cell_node_offset(h);
    for (Id k = 1; k < n[2]; ++k)
      for (Id j = 1; j < n[1]; ++j)
        for (Id i = 1; i < n[0]; ++i) ids[b.point_index(i, j, k)] = id++;
    for (int d = 0; d < 3; ++d) hex_interior(X[d], n, s.u.data(), s.U.data());
  }

  // Connectivity.
  if (nodes_only) {
    b.conn.clear();
    return;
  }
  b.conn.resize(static_cast<size_t>(b.num_elements()) * nc);
  Id* out = b.conn.data();
  if (vol) {
    const Id sj = ni, sk = ni * nj;
    const Id off[8] = {0, 1, 1 + sj, sj, sk, 1 + sk, 1 + sj + sk, sj + sk};
    for (Id k = 0; k < n[2]; ++k)
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

std::vector<Id> FineMesh::block_fine_elements() const {
  std::vector<Id> count(coarse_.blocks.size(), 0);
  for (Id h = 0; h < num_coarse_elements(); ++h) count[coarse_.element_block[h]] += num_.elem_num_elements(h);
  return count;
}

NodeCursor::NodeCursor(const FineMesh& mesh, Id begin, Id end)
    : mesh_(mesh), next_(std::max<Id>(begin, 0)), end_(std::min(end, mesh.num_nodes())) {}

bool NodeCursor::next(Id& id, Vec3& xyz) {
  if (next_ >= end_) return false;
  id = next_++;
  const NodeRef r = mesh_.numbering().locate_node(id);
  if (r.kind != EntityKind::Cell) {
    xyz = mesh_.node(r);
    return true;
  }
  if (block_cell_ != r.entity) {
    mesh_.fill_block(r.entity, block_);
    block_cell_ = r.entity;
  }
  const Id g = block_.point_index(r.local[0], r.local[1], r.local[2]);
  xyz = {block_.x[g], block_.y[g], block_.z[g]};
  return true;
}

ElementCursor::ElementCursor(const FineMesh& mesh, Id begin, Id end)
    : mesh_(mesh), next_(std::max<Id>(begin, 0)), end_(std::min(end, mesh.num_elements())) {}

bool ElementCursor::next(FineElement& el) {
  if (next_ >= end_) return false;
  el.id = next_++;
  const Numbering& num = mesh_.numbering();
  el.coarse_element = num.locate_element(el.id, el.ijk);
  if (block_.coarse_element != el.coarse_element || block_.node_id.empty())
    mesh_.fill_block(el.coarse_element, block_);
  el.block = mesh_.coarse().element_block[el.coarse_element];
  el.num_nodes = mesh_.corners();
  const Id local = el.id - block_.first_element;
  std::copy_n(&block_.conn[static_cast<size_t>(local) * el.num_nodes], el.num_nodes, el.nodes.begin());
  return true;
}

}  // namespace dicer
