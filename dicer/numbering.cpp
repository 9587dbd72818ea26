#include "dicer/numbering.hpp"

#include "dicer/tables.hpp"

#include <algorithm>

#include "dicer/error.hpp"

namespace dicer {
namespace {

Id mul(Id a, Id b, const char* what) {
  Id r;
  if (__builtin_mul_overflow(a, b, &r))
    throw Error(ErrorKind::Overflow, std::string("fine ") + what + " count overflows 64-bit ids: " +
                                         std::to_string(a) + " x " + std::to_string(b));
  return r;
}
Id add(Id a, Id b, const char* what) {
  Id r;
  if (__builtin_add_overflow(a, b, &r))
    throw Error(ErrorKind::Overflow, std::string("fine ") + what + " count overflows 64-bit ids: " +
                                         std::to_string(a) + " + " + std::to_string(b));
  return r;
}

}  // namespace

Numbering::Numbering(const Topology& t, std::vector<Id> edge_n) : edge_n_(std::move(edge_n)) {
  const Id ne = t.num_edges(), nf = t.num_faces(), nh = t.num_elements();
  if (static_cast<Id>(edge_n_.size()) != ne)
    throw Error(ErrorKind::BadInput, "interval list has " + std::to_string(edge_n_.size()) + " entries for " +
                                         std::to_string(ne) + " edges");
  for (Id e = 0; e < ne; ++e)
    if (edge_n_[e] < 1) throw Error(ErrorKind::BadInput, "edge " + std::to_string(e) + " has interval < 1");
  face_n_.resize(static_cast<size_t>(nf));
  for (Id f = 0; f < nf; ++f) {
    const Id* fe = &t.face_edge[4 * f];
    if (edge_n_[fe[0]] != edge_n_[fe[1]] || edge_n_[fe[2]] != edge_n_[fe[3]])
      throw Error(ErrorKind::BadInput, "face " + std::to_string(f) +
                                           ": opposite edges have different intervals (not one per sheet)");
    face_n_[f] = {edge_n_[fe[0]], edge_n_[fe[2]]};
  }
  const int epe = t.edges_per_element();
  elem_n_.resize(static_cast<size_t>(nh));
  for (Id h = 0; h < nh; ++h) {
    const Id* ee = &t.elem_edge[h * epe];
    elem_n_[h] = t.mode == Mode::Volume ? std::array<Id, 3>{edge_n_[ee[0]], edge_n_[ee[4]], edge_n_[ee[8]]}
                                        : std::array<Id, 3>{edge_n_[ee[0]], edge_n_[ee[2]], 1};
  }
  edge_off_.assign(static_cast<size_t>(ne) + 1, 0);
  for (Id e = 0; e < ne; ++e) edge_off_[e + 1] = add(edge_off_[e], edge_n_[e] - 1, "node");
  face_off_.assign(static_cast<size_t>(nf) + 1, 0);
  for (Id f = 0; f < nf; ++f)
    face_off_[f + 1] = add(face_off_[f], mul(face_n_[f][0] - 1, face_n_[f][1] - 1, "node"), "node");
  const bool vol = t.mode == Mode::Volume;
  cell_off_.assign(static_cast<size_t>(vol ? nh : 0) + 1, 0);
  elem_offset_.assign(static_cast<size_t>(nh) + 1, 0);
  for (Id h = 0; h < nh; ++h) {
    const auto& n = elem_n_[h];
    if (vol)
      cell_off_[h + 1] = add(cell_off_[h], mul(mul(n[0] - 1, n[1] - 1, "node"), n[2] - 1, "node"), "node");
    elem_offset_[h + 1] = add(elem_offset_[h], mul(mul(n[0], n[1], "element"), n[2], "element"), "element");
  }
  base_[0] = 0;
  base_[1] = t.num_vertices;
  base_[2] = add(base_[1], edge_off_.back(), "node");
  base_[3] = add(base_[2], face_off_.back(), "node");
  num_nodes_ = add(base_[3], cell_off_.back(), "node");
}

namespace {

// Last row whose column `col` is <= x (the entity owning offset x); rows
// with no nodes share their successor's offset and are skipped by taking
// the last such row.
Id owner_row(const Table<std::int64_t>& t, int col, Id x, TableCursor& cur, const std::vector<std::int64_t>& index) {
  Id lo = 0, hi = t.rows();  // first row with value > x, in [lo, hi]
  if (!index.empty()) {
    // The last page whose first row is <= x holds the answer.
    const Id p = static_cast<Id>(std::upper_bound(index.begin(), index.end(), x) - index.begin()) - 1;
    if (p < 0) return -1;
    lo = p * t.rows_per_page();
    hi = std::min(t.rows(), lo + t.rows_per_page());
  }
  while (lo < hi) {
    const Id mid = lo + (hi - lo) / 2;
    if (t.row(mid, cur)[col] <= x) lo = mid + 1;
    else hi = mid;
  }
  return lo - 1;
}

}  // namespace

NodeRef locate_node(const MeshTables& t, const std::array<Id, 4>& base, Id nodes, Id id, MeshCursor& cur) {
  (void)nodes;
  NodeRef r;
  const ElementLayout L = t.layout();
  if (id < base[1]) {
    r.kind = EntityKind::Vertex;
    r.entity = id;
  } else if (id < base[2]) {
    r.kind = EntityKind::Edge;
    r.entity = owner_row(t.edges, kEdgeNodeOffset, id, cur.edges, t.edge_index);
    r.local[0] = id - t.edges.row(r.entity, cur.edges)[kEdgeNodeOffset] + 1;
  } else if (id < base[3]) {
    r.kind = EntityKind::Face;
    r.entity = owner_row(t.faces, kFaceNodeOffset, id, cur.faces, t.face_index);
    const std::int64_t* f = t.faces.row(r.entity, cur.faces);
    const Id l = id - f[kFaceNodeOffset], e0 = f[kFaceE];
    const Id w = t.edges.row(e0, cur.edges)[kEdgeN] - 1;
    r.local = {l % w + 1, l / w + 1, 0};
  } else {
    r.kind = EntityKind::Cell;
    r.entity = owner_row(t.elements, L.cell_offset(), id, cur.elements, t.cell_index);
    const std::int64_t* h = t.elements.row(r.entity, cur.elements);
    const Id l = id - h[L.cell_offset()];
    const Id a = h[L.n()] - 1, b = h[L.n() + 1] - 1;
    r.local = {l % a + 1, (l / a) % b + 1, l / (a * b) + 1};
  }
  return r;
}

Id node_id(const MeshTables& t, const std::array<Id, 4>& base, const NodeRef& r, MeshCursor& cur) {
  (void)base;
  const ElementLayout L = t.layout();
  switch (r.kind) {
    case EntityKind::Vertex: return r.entity;
    case EntityKind::Edge: return t.edges.row(r.entity, cur.edges)[kEdgeNodeOffset] + (r.local[0] - 1);
    case EntityKind::Face: {
      const std::int64_t* f = t.faces.row(r.entity, cur.faces);
      const Id off = f[kFaceNodeOffset], e0 = f[kFaceE];
      const Id w = t.edges.row(e0, cur.edges)[kEdgeN] - 1;
      return off + (r.local[0] - 1) + (r.local[1] - 1) * w;
    }
    case EntityKind::Cell: {
      const std::int64_t* h = t.elements.row(r.entity, cur.elements);
      const Id a = h[L.n()] - 1, b = h[L.n() + 1] - 1;
      return h[L.cell_offset()] + (r.local[0] - 1) + a * ((r.local[1] - 1) + b * (r.local[2] - 1));
    }
  }
  return -1;
}

Id locate_element(const MeshTables& t, Id id, std::array<Id, 3>& ijk, MeshCursor& cur) {
  const ElementLayout L = t.layout();
  const Id h = owner_row(t.elements, L.elem_offset(), id, cur.elements, t.elem_index);
  const std::int64_t* row = t.elements.row(h, cur.elements);
  const Id l = id - row[L.elem_offset()], n0 = row[L.n()], n1 = row[L.n() + 1];
  ijk = {l % n0, (l / n0) % n1, l / (n0 * n1)};
  return h;
}

}  // namespace dicer
