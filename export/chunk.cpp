// Chunks and box selections of the fine mesh, with local numbering: what
// every writer consumes. Memory is bounded by the chunk.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <numeric>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/orientation.hpp"

namespace dicer {
namespace {

// Exodus side (0-based) of a hex -> (axis, high side); of a shell -> the
// same for its edge sides 2..5 (axis 0 = i, 1 = j), faces 0/1 -> (-1, _).
struct SidePlane {
  int axis;
  bool high;
};
SidePlane hex_side_plane(int side) {
  static constexpr SidePlane k[6] = {{1, false}, {0, true}, {1, true}, {0, false}, {2, false}, {2, true}};
  return k[side];
}
SidePlane shell_side_plane(int side) {
  static constexpr SidePlane k[6] = {{-1, false}, {-1, true}, {1, false}, {0, true}, {1, true}, {0, false}};
  return k[side];
}

bool coarse_box_misses(const FineMesh& mesh, Id h, const Box& box, MeshCursor& cur) {
  const MeshTables& t = mesh.tables();
  const ElementLayout L = t.layout();
  Id corners[8];
  {
    const std::int64_t* row = t.elements.row(h, cur.elements);
    std::copy_n(row + L.conn(), L.corners, corners);
  }
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int q = 0; q < L.corners; ++q) {
    const double* p = t.vertices.row(corners[q], cur.vertices);
    for (int d = 0; d < 3; ++d) lo[d] = std::min(lo[d], p[d]), hi[d] = std::max(hi[d], p[d]);
  }
  for (int d = 0; d < 3; ++d)
    if (hi[d] < box.lo[d] || lo[d] > box.hi[d]) return true;
  return false;
}

// A run of consecutive global node ids and the local id of its first.
struct NodeRange {
  Id global, count, local;
};

void centroid(const FineBlock& b, Id e, int corners, double c[3]) {
  c[0] = c[1] = c[2] = 0;
  const Id i = e % b.n[0], j = (e / b.n[0]) % b.n[1], k = e / (b.n[0] * b.n[1]);
  for (int q = 0; q < corners; ++q) {
    const Id g = b.point_index(i + kHexCorner[q][0], j + kHexCorner[q][1], corners == 8 ? k + kHexCorner[q][2] : 0);
    c[0] += b.x[g], c[1] += b.y[g], c[2] += b.z[g];
  }
  for (int d = 0; d < 3; ++d) c[d] /= corners;
}

}  // namespace

std::vector<ChunkRange> plan_chunks(const FineMesh& mesh, Id count) {
  if (count < 1) throw Error(ErrorKind::Usage, "chunk count must be at least 1 (got " + std::to_string(count) + ")");
  const MeshTables& t = mesh.tables();
  const ElementLayout L = t.layout();
  const Id nh = mesh.num_coarse_elements(), total = mesh.num_elements();
  MeshCursor cur;
  // Boundary k: the first coarse element whose first fine element is at or
  // past k * total / count (so each boundary misses the ideal by less than
  // one coarse element).
  std::vector<Id> start(static_cast<size_t>(count) + 1, nh);
  start[0] = 0;
  Id k = 1;
  for (Id h = 0; h < nh && k < count; ++h) {
    const Id off = t.elements.row(h, cur.elements)[L.elem_offset()];
    while (k < count && static_cast<__int128>(off) * count >= static_cast<__int128>(total) * k) start[k++] = h;
  }
  while (k < count) start[k++] = nh;
  std::vector<ChunkRange> out;
  for (Id c = 0; c < count; ++c) {
    ChunkRange r{c, count, start[c], std::max(start[c], start[c + 1]), 0};
    const Id a = r.first_coarse < nh ? t.elements.row(r.first_coarse, cur.elements)[L.elem_offset()] : total;
    const Id b = r.end_coarse < nh ? t.elements.row(r.end_coarse, cur.elements)[L.elem_offset()] : total;
    r.fine_elements = b - a;
    out.push_back(r);
  }
  return out;
}

Box parse_box(const std::string& text) {
  Box b;
  double v[6];
  const char* p = text.c_str();
  for (int i = 0; i < 6; ++i) {
    char* end = nullptr;
    v[i] = std::strtod(p, &end);
    if (end == p || !std::isfinite(v[i]))
      throw Error(ErrorKind::Usage, "--box: \"" + text + "\" is not six numbers x0,y0,z0,x1,y1,z1");
    p = end;
    if (i < 5) {
      if (*p != ',') throw Error(ErrorKind::Usage, "--box: \"" + text + "\" is not six numbers x0,y0,z0,x1,y1,z1");
      ++p;
    }
  }
  if (*p != '\0') throw Error(ErrorKind::Usage, "--box: \"" + text + "\" has trailing characters");
  for (int d = 0; d < 3; ++d) {
    b.lo[d] = v[d], b.hi[d] = v[d + 3];
    if (b.lo[d] > b.hi[d])
      throw Error(ErrorKind::Usage, "--box: lower corner above upper corner along axis " + std::string(1, "xyz"[d]));
  }
  return b;
}

Id for_each_in_box(const FineMesh& mesh, const Box& box, const std::function<void(const FineBlock&, Id)>& fn) {
  MeshCursor cur;
  FineBlock b;
  Id count = 0;
  const int nc = mesh.corners();
  for (Id h = 0; h < mesh.num_coarse_elements(); ++h) {
    if (coarse_box_misses(mesh, h, box, cur)) continue;
    mesh.fill_block(h, b);
    for (Id e = 0; e < b.num_elements(); ++e) {
      double c[3];
      centroid(b, e, nc, c);
      if (!box.contains(c[0], c[1], c[2])) continue;
      ++count;
      if (fn) fn(b, e);
    }
  }
  return count;
}

ExportChunk::ExportChunk(const FineMesh& mesh, ChunkRange range, std::optional<Box> box)
    : mesh_(mesh), range_(range), box_(box) {
  if (range_.first_coarse < 0 || range_.end_coarse > mesh.num_coarse_elements() || range_.first_coarse > range_.end_coarse)
    throw Error(ErrorKind::Usage, "chunk range is outside the mesh");
}

void ExportChunk::prepare(const MeshSets& sets, const std::function<void(Id, Id)>& progress,
                          const std::function<bool()>& cancel) {
  const MeshTables& t = mesh_.tables();
  const ElementLayout L = t.layout();
  const int nc = corners();
  const bool vol = mode() == Mode::Volume;
  const Id first = range_.first_coarse, end = range_.end_coarse, span = end - first;
  MeshCursor cur;
  FineBlock b;
  auto check_cancel = [&] {
    if (cancel && cancel()) throw Error(ErrorKind::Usage, "interrupted");
  };
  std::vector<std::uint8_t> kept_coarse(static_cast<size_t>(span), 1);

  // Pass 1: which elements are kept and which nodes they use, as ranges of
  // global ids. Without a box a chunk uses whole entities: the vertices,
  // edges, faces and cells of its coarse elements, each one contiguous range
  // of ids (numbering.hpp), so the sorted id list is the entities' ranges in
  // id order, no per-node sort. With a box, the ids of kept elements' nodes
  // are sorted and deduplicated, each a range of one.
  node_global_.clear(), elem_global_.clear(), conn_.clear(), elem_block_.clear();
  std::vector<NodeRange> ranges;
  if (!box_) {
    std::vector<Id> verts, edges, faces;
    for (Id h = first; h < end; ++h) {
      const std::int64_t* row = t.elements.row(h, cur.elements);
      verts.insert(verts.end(), row + L.conn(), row + L.conn() + L.corners);
      edges.insert(edges.end(), row + L.edge(), row + L.edge() + L.edges);
      faces.insert(faces.end(), row + L.face(), row + L.face() + L.faces);
      const Id n0 = row[L.n()], n1 = row[L.n() + 1], n2 = row[L.n() + 2];  // surface: interiors are face nodes
      if (vol) ranges.push_back({row[L.cell_offset()], (n0 - 1) * (n1 - 1) * (n2 - 1), 0});
    }
    for (auto* v : {&verts, &edges, &faces}) {
      std::sort(v->begin(), v->end());
      v->erase(std::unique(v->begin(), v->end()), v->end());
    }
    for (Id v : verts) ranges.push_back({v, 1, 0});
    for (Id e : edges) {
      const std::int64_t* r = t.edges.row(e, cur.edges);
      ranges.push_back({r[kEdgeNodeOffset], r[kEdgeN] - 1, 0});
    }
    for (Id f : faces) {
      const std::int64_t* r = t.faces.row(f, cur.faces);
      const Id off = r[kFaceNodeOffset], e0 = r[kFaceE], e2 = r[kFaceE + 2];
      const Id w0 = t.edges.row(e0, cur.edges)[kEdgeN] - 1, w1 = t.edges.row(e2, cur.edges)[kEdgeN] - 1;
      ranges.push_back({off, w0 * w1, 0});
    }
    check_cancel();
  } else {
    for (Id h = first; h < end; ++h) {
      check_cancel();
      if (coarse_box_misses(mesh_, h, *box_, cur)) {
        kept_coarse[h - first] = 0;
        if (progress) progress(h - first + 1, 2 * span);
        continue;
      }
      mesh_.fill_block(h, b);
      bool any = false;
      for (Id e = 0; e < b.num_elements(); ++e) {
        double c[3];
        centroid(b, e, nc, c);
        if (!box_->contains(c[0], c[1], c[2])) continue;
        any = true;
        node_global_.insert(node_global_.end(), b.conn.begin() + e * nc, b.conn.begin() + (e + 1) * nc);
      }
      if (!any) kept_coarse[h - first] = 0;
      if (progress) progress(h - first + 1, 2 * span);
    }
    std::sort(node_global_.begin(), node_global_.end());
    node_global_.erase(std::unique(node_global_.begin(), node_global_.end()), node_global_.end());
    for (Id g : node_global_) ranges.push_back({g, 1, 0});
  }
  // Ranges in id order, adjacent ones merged (a whole mesh is one range per
  // kind of entity), each with its first local id.
  std::sort(ranges.begin(), ranges.end(), [](const NodeRange& a, const NodeRange& b) { return a.global < b.global; });
  {
    size_t w = 0;
    Id local = 0;
    for (const NodeRange& r : ranges) {
      if (r.count == 0) continue;
      if (r.global < 0 || r.count < 0 || r.global > mesh_.num_nodes() - r.count)
        throw Error(ErrorKind::Corrupt, (t.origin.empty() ? std::string("in memory") : t.origin) +
                                            ": inconsistent mesh tables: node id range " + std::to_string(r.global) +
                                            " + " + std::to_string(r.count) + " outside the mesh");
      if (w > 0 && ranges[w - 1].global + ranges[w - 1].count == r.global) {
        ranges[w - 1].count += r.count;
      } else {
        if (w > 0 && ranges[w - 1].global + ranges[w - 1].count > r.global)
          throw Error(ErrorKind::Corrupt, (t.origin.empty() ? std::string("in memory") : t.origin) +
                                              ": inconsistent mesh tables: overlapping node id ranges at id " +
                                              std::to_string(r.global));
        ranges[w] = r;
        ranges[w].local = local;
        ++w;
      }
      local += r.count;
    }
    ranges.resize(w);
    if (!box_) {
      node_global_.resize(static_cast<size_t>(local));
      for (const NodeRange& r : ranges) std::iota(&node_global_[r.local], &node_global_[r.local] + r.count, r.global);
    }
  }
  node_global_.shrink_to_fit();

  // Pass 2: each grid point mapped to its local id through the ranges (the
  // range of the previous point first: runs of one entity need no search),
  // then coordinates scattered and connectivity taken from grid offsets.
  const Id nn = num_nodes();
  x_.assign(static_cast<size_t>(nn), 0), y_.assign(static_cast<size_t>(nn), 0), z_.assign(static_cast<size_t>(nn), 0);
  if (!box_) {  // every element of the chunk is kept: size the arrays once
    const Id ne = std::clamp<Id>(range_.fine_elements, 0, mesh_.num_elements());
    elem_global_.reserve(static_cast<size_t>(ne)), elem_block_.reserve(static_cast<size_t>(ne));
    conn_.reserve(static_cast<size_t>(ne) * nc);
  }
  std::vector<Id> local;
  const NodeRange* in = ranges.empty() ? nullptr : &ranges.front();
  auto local_of = [&](Id id) -> Id {
    if (in == nullptr) return -1;
    if (id < in->global || id >= in->global + in->count) {
      auto it = std::upper_bound(ranges.begin(), ranges.end(), id, [](Id g, const NodeRange& r) { return g < r.global; });
      if (it == ranges.begin()) return -1;
      --it;
      if (id >= it->global + it->count) return -1;  // a point no kept element uses (box)
      in = &*it;
    }
    return in->local + (id - in->global);
  };
  for (Id h = first; h < end; ++h) {
    check_cancel();
    if (kept_coarse[h - first]) {
      mesh_.fill_block(h, b, true);
      local.resize(static_cast<size_t>(b.num_points()));
      for (Id g = 0; g < b.num_points(); ++g) {
        const Id l = local_of(b.node_id[g]);
        local[g] = l;
        if (l < 0) continue;
        x_[l] = b.x[g], y_[l] = b.y[g], z_[l] = b.z[g];
      }
      const auto n = b.n;
      const Id sj = n[0] + 1, sk = (n[0] + 1) * (n[1] + 1);
      const Id off[8] = {0, 1, 1 + sj, sj, sk, 1 + sk, 1 + sj + sk, sj + sk};
      for (Id k = 0; k < n[2]; ++k)
        for (Id j = 0; j < n[1]; ++j)
          for (Id i = 0; i < n[0]; ++i) {
            const Id g0 = b.point_index(i, j, k);
            if (box_) {
              double c[3] = {0, 0, 0};
              for (int q = 0; q < nc; ++q) {
                const Id g = g0 + off[q];
                c[0] += b.x[g], c[1] += b.y[g], c[2] += b.z[g];
              }
              for (double& v : c) v /= nc;
              if (!box_->contains(c[0], c[1], c[2])) continue;
            }
            elem_global_.push_back(b.first_element + i + n[0] * (j + n[1] * k));
            elem_block_.push_back(b.block);
            for (int q = 0; q < nc; ++q) conn_.push_back(local[g0 + off[q]]);
          }
    }
    if (progress) progress(span + h - first + 1, 2 * span);
  }

  // Owners: the chunk of the lowest coarse element using the node's owning
  // entity (chunks are contiguous in coarse order).
  owner_.assign(static_cast<size_t>(nn), static_cast<std::int32_t>(range_.index));
  std::vector<ChunkRange> plan;
  if (!box_ && range_.count > 1) plan = plan_chunks(mesh_, range_.count);
  auto chunk_of = [&](Id h) {
    Id c = range_.index;
    while (c > 0 && plan[c].first_coarse > h) --c;
    return static_cast<std::int32_t>(c);
  };
  const bool any_node_sets = !sets.node_sets.empty();
  std::vector<std::vector<Id>> node_set_sorted;
  for (const auto& ns : sets.node_sets) {
    node_set_sorted.push_back(ns.vertex);
    std::sort(node_set_sorted.back().begin(), node_set_sorted.back().end());
    node_sets_.push_back({ns.id, ns.name, {}});
  }
  const auto& base = mesh_.info().kind_base;
  for (Id l = 0; l < nn && (!plan.empty() || any_node_sets); ++l) {
    const Id g = node_global_[l];
    if (g >= base[3] && !any_node_sets) continue;  // hex interior: only this chunk holds it
    const NodeRef r = mesh_.locate_node(g, cur);
    Id verts[8];
    int nv = 0;
    Id min_elem = first;
    switch (r.kind) {
      case EntityKind::Vertex:
        verts[nv++] = r.entity;
        min_elem = t.vertex_elements.row(r.entity, cur.vertex_elements)[0];
        break;
      case EntityKind::Edge: {
        const std::int64_t* e = t.edges.row(r.entity, cur.edges);
        verts[nv++] = e[kEdgeLo], verts[nv++] = e[kEdgeHi];
        min_elem = e[kEdgeMinElement];
        break;
      }
      case EntityKind::Face: {
        const std::int64_t* f = t.faces.row(r.entity, cur.faces);
        for (int q = 0; q < 4; ++q) verts[nv++] = f[kFaceV + q];
        min_elem = f[kFaceMinElement];
        break;
      }
      case EntityKind::Cell: {
        const std::int64_t* row = t.elements.row(r.entity, cur.elements);
        for (int q = 0; q < L.corners; ++q) verts[nv++] = row[L.conn() + q];
        min_elem = r.entity;
        break;
      }
    }
    if (!plan.empty() && min_elem < first) owner_[l] = chunk_of(min_elem);
    // Node sets: a fine node belongs to a set when every vertex of its
    // owning entity does.
    for (size_t s = 0; s < node_set_sorted.size(); ++s) {
      const auto& vs = node_set_sorted[s];
      bool all = nv > 0;
      for (int q = 0; q < nv && all; ++q) all = std::binary_search(vs.begin(), vs.end(), verts[q]);
      if (all) node_sets_[s].node.push_back(l);
    }
  }

  // Side sets: the fine elements on each coarse side, with the same side number.
  for (const auto& ss : sets.side_sets) {
    SideMembers m{ss.id, ss.name, {}, {}};
    for (size_t q = 0; q < ss.element.size(); ++q) {
      const Id h = ss.element[q];
      if (h < first || h >= end || !kept_coarse[h - first]) continue;
      const int side = ss.side[q];
      if (side < 0 || side > 5) continue;
      const std::int64_t* row = t.elements.row(h, cur.elements);
      const Id off = row[L.elem_offset()];
      const std::array<Id, 3> n = {row[L.n()], row[L.n() + 1], row[L.n() + 2]};
      const SidePlane plane = vol ? hex_side_plane(side) : shell_side_plane(side);
      for (Id k = 0; k < n[2]; ++k)
        for (Id j = 0; j < n[1]; ++j)
          for (Id i = 0; i < n[0]; ++i) {
            const Id p[3] = {i, j, k};
            if (plane.axis >= 0 && p[plane.axis] != (plane.high ? n[plane.axis] - 1 : 0)) continue;
            const Id gid = off + i + n[0] * (j + n[1] * k);
            const auto it = std::lower_bound(elem_global_.begin(), elem_global_.end(), gid);
            if (it == elem_global_.end() || *it != gid) continue;  // outside the box
            m.element.push_back(static_cast<Id>(it - elem_global_.begin()));
            m.side.push_back(static_cast<std::int8_t>(side));
          }
    }
    side_sets_.push_back(std::move(m));
  }
}

}  // namespace dicer
