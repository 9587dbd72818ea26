#include "dicer/numbering.hpp"

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

// Index of the last prefix entry <= x (entity owning offset x).
Id owner(const std::vector<Id>& prefix, Id x) {
  auto it = std::upper_bound(prefix.begin(), prefix.end(), x);
  return static_cast<Id>(it - prefix.begin()) - 1;
}

}  // namespace

Numbering::Numbering(const Topology& t, std::vector<Id> edge_n) : mode_(t.mode), edge_n_(std::move(edge_n)) {
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

Id Numbering::node_id(const NodeRef& r) const {
  switch (r.kind) {
    case EntityKind::Vertex: return r.entity;
    case EntityKind::Edge: return base_[1] + edge_off_[r.entity] + (r.local[0] - 1);
    case EntityKind::Face:
      return base_[2] + face_off_[r.entity] + (r.local[0] - 1) + (r.local[1] - 1) * (face_n_[r.entity][0] - 1);
    case EntityKind::Cell: {
      const auto& n = elem_n_[r.entity];
      return base_[3] + cell_off_[r.entity] + (r.local[0] - 1) +
             (n[0] - 1) * ((r.local[1] - 1) + (n[1] - 1) * (r.local[2] - 1));
    }
  }
  return -1;
}

NodeRef Numbering::locate_node(Id id) const {
  NodeRef r;
  if (id < base_[1]) {
    r.kind = EntityKind::Vertex;
    r.entity = id;
  } else if (id < base_[2]) {
    const Id x = id - base_[1];
    r.kind = EntityKind::Edge;
    r.entity = owner(edge_off_, x);
    r.local[0] = x - edge_off_[r.entity] + 1;
  } else if (id < base_[3]) {
    const Id x = id - base_[2];
    r.kind = EntityKind::Face;
    r.entity = owner(face_off_, x);
    const Id l = x - face_off_[r.entity], w = face_n_[r.entity][0] - 1;
    r.local = {l % w + 1, l / w + 1, 0};
  } else {
    const Id x = id - base_[3];
    r.kind = EntityKind::Cell;
    r.entity = owner(cell_off_, x);
    const Id l = x - cell_off_[r.entity];
    const auto& n = elem_n_[r.entity];
    const Id a = n[0] - 1, b = n[1] - 1;
    r.local = {l % a + 1, (l / a) % b + 1, l / (a * b) + 1};
  }
  return r;
}

Id Numbering::element_id(Id h, Id i, Id j, Id k) const {
  const auto& n = elem_n_[h];
  return elem_offset_[h] + i + n[0] * (j + n[1] * k);
}

Id Numbering::locate_element(Id id, std::array<Id, 3>& ijk) const {
  const Id h = owner(elem_offset_, id);
  const Id l = id - elem_offset_[h];
  const auto& n = elem_n_[h];
  ijk = {l % n[0], (l / n[0]) % n[1], l / (n[0] * n[1])};
  return h;
}

}  // namespace dicer
