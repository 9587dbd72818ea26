// Dicing: coarse mesh + intervals -> the mesh tables' rows (DicedRows),
// compiled into memory (FineMesh::dice) or streamed to a store
// (write_store); and the edits geometry-conforming dicing makes to them.
#include <algorithm>
#include <atomic>

#include "dicer/diced_rows.hpp"
#include "dicer/error.hpp"
#include "dicer/fine_mesh.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"
#include "dicer/sheets.hpp"
#include "dicer/tfi.hpp"
#include "dicer/topology.hpp"
#include "evaluate.hpp"

namespace dicer {

DicedRows::DicedRows(CoarseMesh coarse, const IntervalRequest& request, std::vector<std::string>* notes,
                     bool locality_order) {
  // Sheets and intervals on the input numbering, so sheet ids are the input
  // file's (the topology validation built, when the mesh is unchanged).
  std::shared_ptr<const Topology> t0 = topology_of(coarse);
  coarse.topology.reset();
  Sheets s0 = find_sheets(coarse, *t0);
  IntervalPlan plan = resolve_intervals(coarse, *t0, s0, request);
  if (notes) *notes = plan.notes;
  sheet_gradings_.resize(plan.sheet_grading.size());
  for (size_t s = 0; s < plan.sheet_grading.size(); ++s) {
    const Id v = plan.sheet_start[s];
    sheet_gradings_[s] = {plan.sheet_grading[s], v < 0 ? -1 : coarse.vertex_file_id.empty() ? v + 1 : coarse.vertex_file_id[v]};
  }
  // The sheet of each element's local edges; then t0 can go before the
  // second topology is built (peak memory).
  const int epe = t0->edges_per_element();
  std::vector<Id> slot_sheet(t0->elem_edge.size());
  for (size_t i = 0; i < slot_sheet.size(); ++i) slot_sheet[i] = s0.edge_sheet[t0->elem_edge[i]];
  // Graded sheets: each slot's grading and the input vertex its edge's
  // canonical direction starts at (ungraded meshes keep neither).
  std::vector<tfi::Grading> slot_grading;
  std::vector<Id> slot_start;
  if (std::any_of(plan.sheet_grading.begin(), plan.sheet_grading.end(),
                  [](const tfi::Grading& g) { return g.kind != tfi::Spacing::Equal; })) {
    slot_grading.resize(slot_sheet.size());
    slot_start.resize(slot_sheet.size());
    for (size_t i = 0; i < slot_sheet.size(); ++i) {
      const Id e0 = t0->elem_edge[i];
      slot_grading[i] = plan.edge_grading(s0, e0);
      slot_start[i] = t0->edge_v[2 * e0];
    }
  }
  t0.reset();
  const Id num_sheets = s0.num_sheets();
  s0 = Sheets{};
  sheet_intervals_ = std::move(plan.sheet_interval);
  plan = IntervalPlan{};
  // Store order (Morton, or the file's), vertices in first use, then the
  // owner-order topology the fine mesh is numbered by. The input's arrays
  // go first (peak memory).
  std::vector<Id> old_vertex, old_element;
  mesh_ = std::make_shared<CoarseMesh>(sfc_order(coarse, &old_vertex, &old_element, locality_order));
  coarse = CoarseMesh{};
  const CoarseMesh& m = *mesh_;
  t_ = build_topology(m);
  to_owner_order(t_, m.conn);
  Topology& t = t_;
  // sfc_order keeps each element's corner order, so local edge k of new
  // element h is local edge k of the input's element old_element[h].
  // A graded edge keeps its series' physical direction: it flips when the
  // new vertex numbering reverses the edge's canonical direction.
  edge_sheet_.assign(static_cast<size_t>(t.num_edges()), -1);
  std::vector<Id> edge_n(static_cast<size_t>(t.num_edges()));
  edge_grading_.assign(slot_grading.empty() ? 0 : static_cast<size_t>(t.num_edges()), tfi::Grading{});
  for (size_t h = 0; h < old_element.size(); ++h)
    for (int k = 0; k < epe; ++k) {
      const size_t slot = static_cast<size_t>(old_element[h]) * epe + k;
      const Id e = t.elem_edge[h * epe + k];
      edge_sheet_[e] = slot_sheet[slot];
      if (!slot_grading.empty())
        edge_grading_[e] = old_vertex[t.edge_v[2 * e]] == slot_start[slot] ? slot_grading[slot] : tfi::reversed(slot_grading[slot]);
    }
  slot_sheet = {};
  slot_grading = {};
  slot_start = {};
  old_vertex = {};
  old_element = {};
  for (Id e = 0; e < t.num_edges(); ++e) edge_n[e] = sheet_intervals_[edge_sheet_[e]];
  num_ = Numbering(t, std::move(edge_n));

  const Mode mode = m.mode;
  const Id ne = t.num_edges(), nh = m.num_elements();
  // Surface mode: the quad across each edge from its owner (neighbour
  // queries read it instead of searching); -1 where a non-manifold edge has
  // no single other quad.
  if (mode != Mode::Volume) {
    edge_other_.assign(static_cast<size_t>(ne), -1);
    std::vector<std::int8_t> uses(static_cast<size_t>(ne), 0);
    for (Id h = 0; h < nh; ++h)
      for (int k = 0; k < 4; ++k) {
        const Id e = t.elem_edge[static_cast<size_t>(h) * 4 + k];
        if (uses[e] < 3) ++uses[e];
        if (h != t.edge_owner_elem[e]) edge_other_[e] = h;
      }
    for (Id e = 0; e < ne; ++e)
      if (uses[e] > 2) edge_other_[e] = -1;
  }
  MeshInfo& info = info_;
  info.mode = mode;
  info.source = m.source;
  info.source_order = m.second_order() ? 2 : 1;
  info.blocks = m.blocks;
  info.block_coarse_elements.assign(m.blocks.size(), 0);
  info.block_fine_elements.assign(m.blocks.size(), 0);
  for (Id h = 0; h < nh; ++h) {
    const std::array<Id, 3> n = num_.elem_n(h);
    const Id b = m.element_block[h];
    ++info.block_coarse_elements[b];
    info.block_fine_elements[b] += n[0] * n[1] * (mode == Mode::Volume ? n[2] : 1);
  }
  info.coarse_vertices = m.num_vertices();
  info.coarse_edges = ne;
  info.coarse_faces = t.num_faces();
  info.coarse_elements = nh;
  info.sheets = num_sheets;
  info.nodes = num_.num_nodes();
  info.elements = num_.num_elements();
}

VertexRow DicedRows::vertex(Id v) const {
  const CoarseMesh& m = *mesh_;
  const Id h = t_.vertex_owner_elem[v];
  const int nc = m.corners_per_element();
  int slot = 0;
  while (slot < nc && m.conn[static_cast<size_t>(h) * nc + slot] != v) ++slot;
  return VertexRow{h, slot, num_.vertex_node(v)};
}

EdgeRow DicedRows::edge(Id e) const {
  return EdgeRow{t_.edge_v[2 * e], t_.edge_v[2 * e + 1], num_.edge_n(e), num_.edge_node(e), edge_sheet_[e],
                 t_.edge_owner_elem[e], -1, -1, edge_other_.empty() ? -1 : edge_other_[e], edge_grading(e)};
}

FaceRow DicedRows::face(Id f) const {
  FaceRow r;
  for (int k = 0; k < 4; ++k) r.v[k] = t_.face_v[4 * f + k], r.e[k] = t_.face_edge[4 * f + k];
  r.nu = num_.face_n(f)[0], r.nv = num_.face_n(f)[1];
  r.node = num_.face_node(f), r.owner_element = t_.face_owner_elem[f];
  if (mode() == Mode::Volume) {
    const Id a = t_.face_elem[2 * f], b = t_.face_elem[2 * f + 1];
    r.other_element = b < 0 ? -1 : (a == r.owner_element ? b : a);
  }
  return r;
}

ElementRow DicedRows::element(Id h) const {
  const CoarseMesh& m = *mesh_;
  const Topology& t = t_;
  const bool vol = mode() == Mode::Volume;
  const int nc = m.corners_per_element(), epe = t.edges_per_element(), fpe = t.faces_per_element();
  ElementRow r;
  for (int k = 0; k < nc; ++k) {
    const Id v = m.conn[static_cast<size_t>(h) * nc + k];
    r.corner[k] = v, r.corner_node[k] = num_.vertex_node(v);
  }
  for (int k = 0; k < epe; ++k) {
    const Id e = t.elem_edge[static_cast<size_t>(h) * epe + k];
    r.edge[k] = e, r.edge_node[k] = num_.edge_node(e);
    r.flags |= static_cast<std::uint64_t>(t.elem_edge_rev[static_cast<size_t>(h) * epe + k]) << k;
  }
  for (int k = 0; k < fpe; ++k) {
    const Id f = t.elem_face[static_cast<size_t>(h) * fpe + k];
    r.face[k] = f, r.face_node[k] = num_.face_node(f);
    r.flags |= static_cast<std::uint64_t>(t.elem_face_code[static_cast<size_t>(h) * fpe + k]) << (12 + 3 * k);
  }
  r.node_first = num_.node_first(h);
  r.element_first = num_.element_first(h);
  r.cell_node = num_.cell_node(h);
  r.block = m.element_block[h];
  r.file_id = m.element_file_id[h];
  r.n = num_.elem_n(h);
  if (!vol) r.n[2] = 1;
  // Each axis' grading in its increasing direction: its edges' (one sheet,
  // one direction across it: they agree).
  for (int k = 0; k < epe; ++k) {
    const int axis = vol ? k / 4 : k / 2;
    const tfi::Grading g = r.rev(k) ? tfi::reversed(edge_grading(r.edge[k])) : edge_grading(r.edge[k]);
    if (k % (vol ? 4 : 2) == 0) r.grading[axis] = g;
    DICER_ASSERT(r.grading[axis] == g, "the edges along one axis of an element run one way across their sheet");
  }
  return r;
}

void DicedRows::corners(Id h, Vec3* xyz) const {
  const CoarseMesh& m = *mesh_;
  const int nc = m.corners_per_element();
  for (int k = 0; k < nc; ++k) xyz[k] = m.vertex(m.conn[static_cast<size_t>(h) * nc + k]);
}

std::vector<std::int32_t> DicedRows::vertex_owners() const {
  const CoarseMesh& m = *mesh_;
  const Id nv = m.num_vertices();
  std::vector<std::int32_t> o(static_cast<size_t>(nv) * 2, -1);
  for (size_t v = 0; v < m.vertex_geo_dim.size() && v < m.vertex_geo_tag.size(); ++v)
    o[2 * v] = m.vertex_geo_dim[v], o[2 * v + 1] = m.vertex_geo_tag[v];
  return o;
}

FineMesh DicedRows::compile() && {
  const Mode mode = info_.mode;
  MeshTables tab;
  tab.mode = mode;
  tab.fine_nodes = info_.nodes;
  tab.fine_elements = info_.elements;
  tab.sheets = info_.sheets;
  tab.blocks = static_cast<Id>(info_.blocks.size());
  const Id nv = info_.coarse_vertices, ne = info_.coarse_edges, nf = info_.coarse_faces, nh = info_.coarse_elements;
  auto make = [&](auto tag, RowTable kind, Id rows) {
    using T = decltype(tag);
    const std::int64_t w = row_width(kind, mode);
    std::vector<T> v;
    v.reserve(static_cast<size_t>(rows * w));
    return Table<T>(w, std::move(v));
  };
  tab.vertex_nodes = make(std::int64_t{}, RowTable::VertexNodes, nv);
  tab.edges = make(std::int64_t{}, RowTable::Edges, ne);
  tab.faces = make(std::int64_t{}, RowTable::Faces, nf);
  tab.elements = make(std::int64_t{}, RowTable::Elements, nh);
  tab.corners = make(double{}, RowTable::Corners, nh);
  tab.bounds = make(double{}, RowTable::Bounds, nh);
  tab.bounding = Table<std::int64_t>(3, {});
  tab.vertex_owner = Table<std::int32_t>(2, vertex_owners());
  for (Id v = 0; v < nv; ++v) write_row(tab, v, vertex(v));
  for (Id e = 0; e < ne; ++e) write_row(tab, e, edge(e));
  for (Id f = 0; f < nf; ++f) write_row(tab, f, face(f));
  const int nc = mesh_->corners_per_element();
  for (Id h = 0; h < nh; ++h) {
    Vec3 xyz[8];
    corners(h, xyz);
    write_row(tab, h, element(h));
    write_corners(tab, h, xyz);
    write_bounds(tab, h, corner_bounds(xyz, nc));
  }
  tab.group_bounds = group_bounds(tab);
  FineMesh f(std::move(info_), std::move(tab), std::move(mesh_));
  f.set_sheet_intervals(std::move(sheet_intervals_));
  f.set_sheet_gradings(std::move(sheet_gradings_));
  return f;
}

FineMesh FineMesh::dice(CoarseMesh coarse, const IntervalRequest& request, std::vector<std::string>* notes,
                        bool locality_order) {
  return DicedRows(std::move(coarse), request, notes, locality_order).compile();
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
  if (v < 0 || v >= tables_.num_vertices()) throw Error(ErrorKind::Usage, "set_vertex: no vertex " + std::to_string(v));
  auto& o = tables_.vertex_owner.memory();
  o[2 * v] = dim, o[2 * v + 1] = tag;
  // The corners table holds the vertex coordinates, one copy per element
  // using the vertex (bit-identical by construction): all are updated,
  // through a lazily built vertex -> (element, corner) index.
  const int nc = corners();
  const Id nh = tables_.elements.rows();
  if (vertex_uses_.empty()) {
    MeshCursor cur;
    const RowReader R(tables_, cur);
    vertex_uses_offset_.assign(static_cast<size_t>(tables_.num_vertices()) + 1, 0);
    for (Id h = 0; h < nh; ++h) {
      const ElementRow r = R.element(h);
      for (int k = 0; k < nc; ++k) ++vertex_uses_offset_[r.corner[k] + 1];
    }
    for (size_t i = 1; i < vertex_uses_offset_.size(); ++i) vertex_uses_offset_[i] += vertex_uses_offset_[i - 1];
    vertex_uses_.resize(static_cast<size_t>(vertex_uses_offset_.back()));
    std::vector<Id> fill(vertex_uses_offset_.begin(), vertex_uses_offset_.end() - 1);
    for (Id h = 0; h < nh; ++h) {
      const ElementRow r = R.element(h);
      for (int k = 0; k < nc; ++k) vertex_uses_[fill[r.corner[k]]++] = h * 8 + k;
    }
  }
  auto& c = tables_.corners.memory();
  for (Id u = vertex_uses_offset_[v]; u < vertex_uses_offset_[v + 1]; ++u) {
    const Id h = vertex_uses_[u] / 8, k = vertex_uses_[u] % 8;
    double* p = &c[static_cast<size_t>(h * 3 * nc + 3 * k)];
    p[0] = x.x, p[1] = x.y, p[2] = x.z;
    // The element's box from its corners again, and its group's grown to
    // hold it (a superset stays a valid index; finish_moves makes it exact).
    Vec3 xyz[8];
    for (int q = 0; q < nc; ++q) xyz[q] = {c[h * 3 * nc + 3 * q], c[h * 3 * nc + 3 * q + 1], c[h * 3 * nc + 3 * q + 2]};
    const ElementBounds b = corner_bounds(xyz, nc);
    write_bounds(tables_, h, b);
    double* g = &tables_.group_bounds[static_cast<size_t>(h / kBoundsGroup) * 6];
    for (int d = 0; d < 3; ++d) g[d] = std::min(g[d], b.lo[d]), g[3 + d] = std::max(g[3 + d], b.hi[d]);
  }
}

void FineMesh::set_owner(EntityKind kind, Id entity, std::int64_t owner) {
  require_memory("set_owner");
  serial_ = next_serial();
  MeshCursor cur;
  const RowReader R(tables_, cur);
  if (kind == EntityKind::Edge) {
    EdgeRow r = R.edge(entity);
    r.geo = owner;
    write_row(tables_, entity, r);
  } else if (kind == EntityKind::Face) {
    FaceRow r = R.face(entity);
    r.geo = owner;
    write_row(tables_, entity, r);
  } else {
    throw Error(ErrorKind::Usage, "set_owner: only edges and faces carry owners");
  }
}

std::int64_t FineMesh::owner(EntityKind kind, Id entity, MeshCursor& cur) const {
  const RowReader R(tables_, cur);
  if (kind == EntityKind::Edge) return R.edge(entity).geo;
  if (kind == EntityKind::Face) return R.face(entity).geo;
  if (kind == EntityKind::Vertex) return R.vertex_geo(entity);
  return -1;
}

void FineMesh::move_nodes(EntityKind kind, Id entity, std::span<const Vec3> xyz) {
  require_memory("move_nodes");
  serial_ = next_serial();
  MeshCursor cur;
  const detail::Evaluator E(tables_, cur);
  std::vector<Vec3> pred;
  const Id first_row = tables_.bounding.rows();
  if (kind == EntityKind::Edge) {
    if (faces_moved_) throw Error(ErrorKind::Usage, "move_nodes: every edge must be moved before any face");
    EdgeRow e = E.R.edge(entity);
    if (e.bound >= 0) throw Error(ErrorKind::Usage, "move_nodes: edge " + std::to_string(entity) + " moved twice");
    for (Id t = 1; t < e.n; ++t) pred.push_back(E.edge_point(e, t));
    if (xyz.size() == pred.size() && !pred.empty()) e.bound = first_row, write_row(tables_, entity, e);
  } else if (kind == EntityKind::Face) {
    faces_moved_ = true;
    FaceRow f = E.R.face(entity);
    if (f.bound >= 0) throw Error(ErrorKind::Usage, "move_nodes: face " + std::to_string(entity) + " moved twice");
    for (Id v = 1; v < f.nv; ++v)
      for (Id u = 1; u < f.nu; ++u) pred.push_back(E.face_tfi(f, u, v, true));  // Coons of its sides, moved or not
    if (xyz.size() == pred.size() && !pred.empty()) f.bound = first_row, write_row(tables_, entity, f);
  } else {
    throw Error(ErrorKind::Usage, "move_nodes: only edge and face nodes are moved");
  }
  if (xyz.size() != pred.size())
    throw Error(ErrorKind::Usage, "move_nodes: " + std::to_string(xyz.size()) + " points given for " +
                                      std::to_string(pred.size()) + " nodes");
  auto& b = tables_.bounding.memory();
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
  MeshCursor cur;
  const RowReader R(tables_, cur);
  for (Id h = 0; h < tables_.elements.rows(); ++h) {
    ElementRow r = R.element(h);
    bool curved = false;
    for (int k = 0; k < R.edges(); ++k) curved |= R.edge(r.edge[k]).bound >= 0;
    for (int k = 0; k < R.faces(); ++k) curved |= R.face(r.face[k]).bound >= 0;
    r.flags = (r.flags & ~(std::uint64_t{1} << ElementRow::kCurvedBit)) |
              (static_cast<std::uint64_t>(curved) << ElementRow::kCurvedBit);
    write_row(tables_, h, r);
  }
  // Bounds: a curved element's fine nodes leave its corners' box (a
  // cylinder's wall bulges out): the box of all of them, O(its nodes).
  FineBlock b;
  for (Id h = 0; h < tables_.elements.rows(); ++h) {
    Vec3 xyz[8];
    R.corner_xyz(h, xyz);
    ElementBounds box = corner_bounds(xyz, corners());
    if (R.element(h).curved())
      for_each_slab(h, b, false, [&](const FineBlock& s) {  // O(n^2) held, not the element
        for (Id q = 0; q < s.num_points(); ++q) {
          const double p[3] = {s.x[q], s.y[q], s.z[q]};
          for (int d = 0; d < 3; ++d) box.lo[d] = std::min(box.lo[d], p[d]), box.hi[d] = std::max(box.hi[d], p[d]);
        }
      });
    write_bounds(tables_, h, box);
  }
  tables_.group_bounds = group_bounds(tables_);
}

}  // namespace dicer
