// Chunks and box selections of the fine mesh, with local numbering: what
// every writer consumes. Memory is bounded by the chunk.
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <numeric>
#include <sstream>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/numbering.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"

namespace dicer {
namespace {

// The spatial index (tables.hpp group_bounds, rows.hpp ElementBounds): a
// coarse element whose group's box or own box misses `box` has no node, so
// no centroid, in it. The group test reads nothing (the index is in
// memory), so a small box reads the bounds pages of its groups only.
bool coarse_box_misses(const FineMesh& mesh, Id h, const Box& box, MeshCursor& cur) {
  const MeshTables& t = mesh.tables();
  const size_t g = static_cast<size_t>(h / kBoundsGroup) * 6;
  if (g + 6 <= t.group_bounds.size()) {
    const double* q = &t.group_bounds[g];
    for (int d = 0; d < 3; ++d)
      if (q[3 + d] < box.lo[d] || q[d] > box.hi[d]) return true;
  }
  return !RowReader(t, cur).bounds(h).overlaps(box.lo, box.hi);
}

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

namespace {

// The chunks whose coarse element ranges start at start[c] (start[count] =
// H), with mesh's fine element and node counts.
std::vector<ChunkRange> chunks_from(const FineMesh& mesh, const std::vector<Id>& start) {
  const Id nh = mesh.num_coarse_elements(), total = mesh.num_elements(), count = static_cast<Id>(start.size()) - 1;
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  auto first_element = [&](Id h) { return h < nh ? R.element(h).element_first : total; };
  auto first_node = [&](Id h) { return h < nh ? R.element(h).node_first : mesh.num_nodes(); };
  std::vector<ChunkRange> out;
  for (Id c = 0; c < count; ++c) {
    ChunkRange r{c, count, start[c], std::max(start[c], start[c + 1]), 0, 0, 0};
    r.fine_elements = first_element(r.end_coarse) - first_element(r.first_coarse);
    r.node_begin = first_node(r.first_coarse);
    r.node_end = first_node(r.end_coarse);
    if (r.fine_elements < 0 || r.node_end < r.node_begin)
      R.corrupt(RowTable::Elements, r.first_coarse, "element or node ids do not rise with the elements");
    out.push_back(r);
  }
  return out;
}

}  // namespace

std::vector<ChunkRange> plan_chunks(const FineMesh& mesh, Id count) {
  if (count < 1) throw Error(ErrorKind::Usage, "chunk count must be at least 1 (got " + std::to_string(count) + ")");
  const Id nh = mesh.num_coarse_elements(), total = mesh.num_elements();
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  // Boundary k: the first coarse element whose first fine element is at or
  // past k * total / count (so each boundary misses the ideal by less than
  // one coarse element); a binary search each, O(count log H) rows.
  std::vector<Id> start(static_cast<size_t>(count) + 1, nh);
  start[0] = 0;
  for (Id k = 1; k < count; ++k) {
    Id lo = start[k - 1], hi = nh;
    while (lo < hi) {
      const Id mid = lo + (hi - lo) / 2;
      if (static_cast<__int128>(R.element_first(mid)) * count >= static_cast<__int128>(total) * k) hi = mid;
      else lo = mid + 1;
    }
    start[k] = lo;
  }
  return chunks_from(mesh, start);
}

std::vector<ChunkRange> plan_like(const FineMesh& mesh, const std::vector<ChunkRange>& plan) {
  std::vector<Id> start;
  for (size_t c = 0; c < plan.size(); ++c) {
    const ChunkRange& r = plan[c];
    if (r.first_coarse != (c ? plan[c - 1].end_coarse : 0) || r.end_coarse < r.first_coarse ||
        r.count != static_cast<Id>(plan.size()) || r.index != static_cast<Id>(c))
      throw Error(ErrorKind::Usage, "plan_like: chunk " + std::to_string(c) + " does not follow on from the one before");
    start.push_back(r.first_coarse);
  }
  if (plan.empty() || plan.back().end_coarse != mesh.num_coarse_elements())
    throw Error(ErrorKind::Usage, "plan_like: the plan does not cover the " + std::to_string(mesh.num_coarse_elements()) +
                                      " coarse elements of " + (mesh.tables().origin.empty() ? "the mesh" : mesh.tables().origin));
  start.push_back(plan.back().end_coarse);
  return chunks_from(mesh, start);
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

Id for_each_in_box(const FineMesh& mesh, const Box& box, const std::function<void(const FineBlock&, Id)>& fn,
                   Id first_coarse, Id end_coarse) {
  MeshCursor cur;
  FineBlock b;
  Id count = 0;
  const int nc = mesh.corners();
  if (end_coarse < 0) end_coarse = mesh.num_coarse_elements();
  for (Id h = std::max<Id>(first_coarse, 0); h < std::min(end_coarse, mesh.num_coarse_elements()); ++h) {
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
  // The own node range follows from the coarse range (owner order); a
  // caller-made ChunkRange need not know it.
  MeshCursor cur;
  const auto own = mesh.owned_nodes(range_.first_coarse, range_.end_coarse, cur);
  range_.node_begin = own[0], range_.node_end = own[1];
}

namespace {

// Node-set membership of a fine node: every vertex of its owning entity is
// in the set. Per coarse element, the entities whose corners are all in
// the set give whole id ranges (numbering.hpp), no per-node test.
void node_set_ranges(const ElementRow& h, Mode mode, const std::vector<Id>& sorted_vertices,
                     std::vector<std::array<Id, 2>>& out) {
  const bool vol = mode == Mode::Volume;
  const int nc = vol ? 8 : 4, ne = vol ? 12 : 4, nf = vol ? 6 : 1;
  bool in[8];
  bool any = false, all = true;
  for (int k = 0; k < nc; ++k) {
    in[k] = std::binary_search(sorted_vertices.begin(), sorted_vertices.end(), h.corner[k]);
    any |= in[k], all &= in[k];
  }
  if (!any) return;
  for (int k = 0; k < nc; ++k)
    if (in[k]) out.push_back({h.corner_node[k], h.corner_node[k] + 1});
  for (int k = 0; k < ne; ++k) {
    const int a = vol ? kHexEdge[k][0] : kQuadEdge[k][0], b = vol ? kHexEdge[k][1] : kQuadEdge[k][1];
    if (in[a] && in[b])
      out.push_back({h.edge_node[k], h.edge_node[k] + ids::edge_nodes(h.n[vol ? k / 4 : k / 2])});
  }
  for (int k = 0; k < nf; ++k) {
    bool face_in = true;
    for (int m = 0; m < 4; ++m) face_in &= in[vol ? kHexFace[k][m] : m];
    const auto [nu, nv] = face_intervals(h, k, mode);
    if (face_in) out.push_back({h.face_node[k], h.face_node[k] + ids::face_nodes(nu, nv)});
  }
  if (all && vol) out.push_back({h.cell_node, h.cell_node + ids::cell_nodes(h.n)});
}

}  // namespace

void ExportChunk::prepare(const MeshSets& sets, const std::function<void(Id, Id)>& progress,
                          const std::function<bool()>& cancel) {
  if (!box_) refuse_if_too_big(mesh_, range_);  // a box keeps an unknown part of it
  const Mode mode = this->mode();
  const int nc = corners();
  const Id first = range_.first_coarse, end = range_.end_coarse, span = end - first;
  MeshCursor cur;
  const RowReader R(mesh_.tables(), cur);
  FineBlock b;
  auto check_cancel = [&] {
    if (cancel && cancel()) throw Error(ErrorKind::Cancelled, "interrupted");
  };
  node_global_.clear(), elem_global_.clear(), conn_.clear(), elem_block_.clear();
  x_.clear(), y_.clear(), z_.clear();
  side_sets_.clear(), node_sets_.clear();
  std::vector<std::uint8_t> kept_coarse(static_cast<size_t>(span), 1);
  std::vector<std::vector<Id>> node_set_sorted;
  std::vector<std::vector<std::array<Id, 2>>> node_set_ids(sets.node_sets.size());
  for (const auto& ns : sets.node_sets) {
    node_set_sorted.push_back(ns.vertex);
    std::sort(node_set_sorted.back().begin(), node_set_sorted.back().end());
    node_sets_.push_back({ns.id, ns.name, {}});
  }
  // Side-set members of the chunk's elements, in element order, so the pass
  // below handles them as it meets each element (no second read of rows).
  struct SideRef {
    Id h;
    std::int32_t set;
    std::int8_t side;
  };
  std::vector<SideRef> side_refs;
  for (size_t s = 0; s < sets.side_sets.size(); ++s) {
    const auto& ss = sets.side_sets[s];
    side_sets_.push_back({ss.id, ss.name, {}, {}});
    for (size_t q = 0; q < ss.element.size() && q < ss.side.size(); ++q)
      if (ss.element[q] >= first && ss.element[q] < end && ss.side[q] >= 0 && ss.side[q] <= 5)
        side_refs.push_back({ss.element[q], static_cast<std::int32_t>(s), ss.side[q]});
  }
  std::sort(side_refs.begin(), side_refs.end(), [](const SideRef& a, const SideRef& c) { return a.h < c.h; });
  size_t next_side = 0;
  // The fine elements of block b on each coarse side of b's element that a
  // side set names, as (global element id, side) for now.
  auto sides_of = [&](const FineBlock& blk) {
    for (; next_side < side_refs.size() && side_refs[next_side].h < blk.coarse_element; ++next_side) {
    }
    for (; next_side < side_refs.size() && side_refs[next_side].h == blk.coarse_element; ++next_side) {
      const SideRef& ref = side_refs[next_side];
      const auto& n = blk.n;
      const SidePlane plane = exodus_side_plane(mode, ref.side);
      auto& out = side_sets_[ref.set];
      for (Id k = 0; k < n[2]; ++k)
        for (Id j = 0; j < n[1]; ++j)
          for (Id i = 0; i < n[0]; ++i) {
            const Id p[3] = {i, j, k};
            if (plane.axis >= 0 && p[plane.axis] != (plane.high ? n[plane.axis] - 1 : 0)) continue;
            out.element.push_back(ids::element(blk.first_element, n, i, j, k));
            out.side.push_back(ref.side);
          }
    }
  };
  auto elements_of = [&](const FineBlock& blk, bool keep_all, auto&& on_element) {
    const auto n = blk.n;
    const Id sj = n[0] + 1, sk = (n[0] + 1) * (n[1] + 1);
    const Id off[8] = {0, 1, 1 + sj, sj, sk, 1 + sk, 1 + sj + sk, sj + sk};
    for (Id k = 0; k < blk.layers; ++k)
      for (Id j = 0; j < n[1]; ++j)
        for (Id i = 0; i < n[0]; ++i) {
          const Id g0 = blk.point_index(i, j, k + blk.plane0);
          if (!keep_all) {  // the same centroid as for_each_in_box
            double c[3];
            centroid(blk, i + n[0] * (j + n[1] * k), nc, c);
            if (!box_->contains(c[0], c[1], c[2])) continue;
          }
          on_element(ids::element(blk.first_element, n, i, j, k), g0, off);
        }
  };

  if (!box_) {
    // One pass in store order (each page read once). The chunk's own nodes
    // are one id range [node_begin, node_end) (owner order); the others its
    // elements use (ghosts) have lower ids, owned by earlier chunks. Local
    // order is global id order: ghosts, then the own range.
    const Id own0 = range_.node_begin, nown = range_.node_end - range_.node_begin;
    if (nown < 0 || own0 < 0 || range_.node_end > mesh_.num_nodes())
      R.corrupt(RowTable::Elements, first, "the chunk's own node range lies outside the mesh");
    std::vector<double> ox(static_cast<size_t>(nown)), oy(ox.size()), oz(ox.size());
    struct Ghost {
      Id id;
      double x, y, z;
    };
    std::vector<Ghost> ghosts;
    const Id ne = std::clamp<Id>(range_.fine_elements, 0, mesh_.num_elements());
    elem_global_.reserve(static_cast<size_t>(ne)), elem_block_.reserve(static_cast<size_t>(ne));
    conn_.reserve(static_cast<size_t>(ne) * nc);
    for (Id h = first; h < end; ++h) {
      check_cancel();
      mesh_.fill_block(h, b, true);
      for (Id g = 0; g < b.num_points(); ++g) {
        const Id id = b.node_id[g];
        if (id >= own0 && id - own0 < nown) {
          ox[id - own0] = b.x[g], oy[id - own0] = b.y[g], oz[id - own0] = b.z[g];
        } else if (id < own0) {
          ghosts.push_back({id, b.x[g], b.y[g], b.z[g]});
        } else {
          R.corrupt(RowTable::Elements, h, "node " + std::to_string(id) + " lies past the chunk's own node range");
        }
      }
      elements_of(b, true, [&](Id gid, Id g0, const Id* off) {
        elem_global_.push_back(gid);
        elem_block_.push_back(b.block);
        for (int q = 0; q < nc; ++q) {
          const Id id = b.node_id[g0 + off[q]];
          conn_.push_back(id >= own0 ? id - own0 : -1 - id);  // ghosts provisionally as -1 - id
        }
      });
      if (!node_set_sorted.empty()) {
        const ElementRow row = R.element(h);
        for (size_t s = 0; s < node_set_sorted.size(); ++s) node_set_ranges(row, mode, node_set_sorted[s], node_set_ids[s]);
      }
      sides_of(b);
      if (progress) progress(h - first + 1, span);
    }
    std::sort(ghosts.begin(), ghosts.end(), [](const Ghost& a, const Ghost& c) { return a.id < c.id; });
    ghosts.erase(std::unique(ghosts.begin(), ghosts.end(), [](const Ghost& a, const Ghost& c) { return a.id == c.id; }),
                 ghosts.end());
    const Id ng = static_cast<Id>(ghosts.size());
    node_global_.resize(static_cast<size_t>(ng + nown));
    x_.resize(node_global_.size()), y_.resize(node_global_.size()), z_.resize(node_global_.size());
    for (Id q = 0; q < ng; ++q)
      node_global_[q] = ghosts[q].id, x_[q] = ghosts[q].x, y_[q] = ghosts[q].y, z_[q] = ghosts[q].z;
    std::iota(node_global_.begin() + ng, node_global_.end(), own0);
    std::copy(ox.begin(), ox.end(), x_.begin() + ng), std::copy(oy.begin(), oy.end(), y_.begin() + ng);
    std::copy(oz.begin(), oz.end(), z_.begin() + ng);
    for (Id& c : conn_) {
      if (c >= 0) {
        c += ng;
      } else {
        const Id id = -1 - c;
        c = std::lower_bound(ghosts.begin(), ghosts.end(), id, [](const Ghost& a, Id v) { return a.id < v; }) - ghosts.begin();
      }
    }
  } else {
    // Box: the kept elements' nodes, sorted and deduplicated, then a second
    // pass for coordinates and connectivity.
    for (Id h = first; h < end; ++h) {
      check_cancel();
      if (coarse_box_misses(mesh_, h, *box_, cur)) {
        kept_coarse[h - first] = 0;
        if (progress) progress(h - first + 1, 2 * span);
        continue;
      }
      mesh_.fill_block(h, b);
      bool any = false;
      elements_of(b, false, [&](Id, Id g0, const Id* off) {
        any = true;
        for (int q = 0; q < nc; ++q) node_global_.push_back(b.node_id[g0 + off[q]]);
      });
      if (!any) kept_coarse[h - first] = 0;
      if (progress) progress(h - first + 1, 2 * span);
    }
    std::sort(node_global_.begin(), node_global_.end());
    node_global_.erase(std::unique(node_global_.begin(), node_global_.end()), node_global_.end());
    node_global_.shrink_to_fit();
    const size_t nn = node_global_.size();
    x_.assign(nn, 0), y_.assign(nn, 0), z_.assign(nn, 0);
    auto local_of = [&](Id id) -> Id {
      const auto it = std::lower_bound(node_global_.begin(), node_global_.end(), id);
      return (it != node_global_.end() && *it == id) ? it - node_global_.begin() : -1;
    };
    for (Id h = first; h < end; ++h) {
      check_cancel();
      if (kept_coarse[h - first]) {
        mesh_.fill_block(h, b, true);
        elements_of(b, false, [&](Id gid, Id g0, const Id* off) {
          elem_global_.push_back(gid);
          elem_block_.push_back(b.block);
          for (int q = 0; q < nc; ++q) {
            const Id g = g0 + off[q], l = local_of(b.node_id[g]);
            x_[l] = b.x[g], y_[l] = b.y[g], z_[l] = b.z[g];
            conn_.push_back(l);
          }
        });
        if (!node_set_sorted.empty()) {
          const ElementRow row = R.element(h);
          for (size_t s = 0; s < node_set_sorted.size(); ++s) node_set_ranges(row, mode, node_set_sorted[s], node_set_ids[s]);
        }
        sides_of(b);
      }
      if (progress) progress(span + h - first + 1, 2 * span);
    }
  }

  // Owners: the chunk whose own node range holds the id (owner order), so
  // the lowest chunk holding the node.
  const Id nn = num_nodes();
  owner_.assign(static_cast<size_t>(nn), static_cast<std::int32_t>(range_.index));
  if (range_.count > 1) {
    const std::vector<ChunkRange> plan = plan_.empty() ? plan_chunks(mesh_, range_.count) : plan_;
    size_t c = 0;
    for (Id l = 0; l < nn; ++l) {  // ids rise with l: the chunk index only moves forward
      const Id g = node_global_[l];
      while (c + 1 < plan.size() && plan[c + 1].node_begin <= g) ++c;
      owner_[l] = static_cast<std::int32_t>(c);
    }
  }

  // Node sets: the id ranges found per element, as local indices.
  for (size_t s = 0; s < node_set_ids.size(); ++s) {
    auto& rs = node_set_ids[s];
    std::sort(rs.begin(), rs.end());
    auto& out = node_sets_[s].node;
    for (const auto& r : rs)
      for (Id id = r[0]; id < r[1]; ++id) {
        const auto it = std::lower_bound(node_global_.begin(), node_global_.end(), id);
        if (it != node_global_.end() && *it == id) out.push_back(it - node_global_.begin());
      }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
  }

  // Side sets: global element ids to local indices (elements outside a box
  // drop out), sorted by element then side.
  for (auto& m : side_sets_) {
    std::vector<std::pair<Id, std::int8_t>> fs;
    for (size_t q = 0; q < m.element.size(); ++q) {
      const auto it = std::lower_bound(elem_global_.begin(), elem_global_.end(), m.element[q]);
      if (it != elem_global_.end() && *it == m.element[q]) fs.emplace_back(it - elem_global_.begin(), m.side[q]);
    }
    std::sort(fs.begin(), fs.end());
    fs.erase(std::unique(fs.begin(), fs.end()), fs.end());
    m.element.clear(), m.side.clear();
    for (const auto& [e, side] : fs) m.element.push_back(e), m.side.push_back(side);
  }
}

}  // namespace dicer

namespace dicer {

SetCounts global_set_counts(const FineMesh& mesh, const MeshSets& sets) {
  SetCounts out;
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  const Mode mode = mesh.mode();
  for (const auto& ss : sets.side_sets) {
    std::vector<std::pair<Id, int>> members;
    for (size_t q = 0; q < ss.element.size() && q < ss.side.size(); ++q)
      if (ss.element[q] >= 0 && ss.element[q] < mesh.num_coarse_elements() && ss.side[q] >= 0 && ss.side[q] <= 5)
        members.emplace_back(ss.element[q], ss.side[q]);
    std::sort(members.begin(), members.end());
    members.erase(std::unique(members.begin(), members.end()), members.end());
    std::int64_t n = 0;
    for (const auto& [h, side] : members) {
      const auto& iv = R.element(h).n;
      const SidePlane plane = exodus_side_plane(mode, side);
      std::int64_t faces = 1;
      for (int a = 0; a < 3; ++a)
        if (a != plane.axis) faces *= iv[a];
      n += faces;
    }
    out.side.push_back(n);
  }
  for (const auto& ns : sets.node_sets) {
    std::vector<Id> vs = ns.vertex;
    std::sort(vs.begin(), vs.end());
    vs.erase(std::unique(vs.begin(), vs.end()), vs.end());
    auto in = [&](Id v) { return std::binary_search(vs.begin(), vs.end(), v); };
    std::int64_t n = 0;
    for (Id v : vs)
      if (v >= 0 && v < mesh.tables().num_vertices()) ++n;
    for (Id e = 0; e < mesh.tables().edges.rows(); ++e) {
      const EdgeRow r = R.edge(e);
      if (in(r.lo) && in(r.hi)) n += ids::edge_nodes(r.n);
    }
    for (Id f = 0; f < mesh.tables().faces.rows(); ++f) {
      const FaceRow r = R.face(f);
      if (in(r.v[0]) && in(r.v[1]) && in(r.v[2]) && in(r.v[3])) n += ids::face_nodes(r.nu, r.nv);
    }
    if (mode == Mode::Volume)
      for (Id h = 0; h < mesh.num_coarse_elements(); ++h) {
        const ElementRow r = R.element(h);
        bool all = true;
        for (int k = 0; k < 8 && all; ++k) all = in(r.corner[k]);
        if (all) n += ids::cell_nodes(r.n);
      }
    out.node.push_back(n);
  }
  return out;
}

// ---- memory estimate ---------------------------------------------------------

std::uint64_t estimate_chunk_bytes(const FineMesh& mesh, const ChunkRange& range) {
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  const Id h = mesh.num_coarse_elements();
  auto first_element = [&](Id e) { return e >= h ? mesh.num_elements() : R.element_first(e); };
  const Id elements = first_element(range.end_coarse) - first_element(range.first_coarse);
  const auto own = mesh.owned_nodes(range.first_coarse, range.end_coarse, cur);
  // The chunk's own nodes; those it shares with lower chunks lie on one
  // boundary surface, small beside them, and are not counted.
  const Id nodes = own[1] - own[0];
  // What prepare() keeps (ExportChunk's members): per element its global id,
  // block index and connectivity; per node its global id, x, y, z, owner.
  const unsigned __int128 per_element = 8 + 4 + 8 * static_cast<unsigned>(mesh.corners());
  const unsigned __int128 per_node = 8 + 24 + 4;
  const unsigned __int128 bytes = per_element * static_cast<std::uint64_t>(std::max<Id>(elements, 0)) +
                                  per_node * static_cast<std::uint64_t>(std::max<Id>(nodes, 0));
  return bytes > UINT64_MAX ? UINT64_MAX : static_cast<std::uint64_t>(bytes);
}

namespace {

std::uint64_t kib_field(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key, 0) == 0) return std::strtoull(line.c_str() + key.size(), nullptr, 10) * 1024;
  return UINT64_MAX;
}

// What this process can still allocate: the memory the kernel says is
// available, and under an address-space limit (RLIMIT_AS) what is not
// mapped yet.
std::uint64_t available_memory_bytes() {
  std::uint64_t avail = kib_field("/proc/meminfo", "MemAvailable:");
  if (avail == UINT64_MAX) {
    const long pages = ::sysconf(_SC_AVPHYS_PAGES), size = ::sysconf(_SC_PAGESIZE);
    if (pages > 0 && size > 0) avail = static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(size);
  }
  struct rlimit rl {};
  if (::getrlimit(RLIMIT_AS, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY) {
    const std::uint64_t mapped = kib_field("/proc/self/status", "VmSize:");
    const std::uint64_t left = mapped == UINT64_MAX || mapped >= rl.rlim_cur ? 0 : rl.rlim_cur - mapped;
    avail = std::min(avail, left);
  }
  return avail;
}

std::string gib(std::uint64_t bytes) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f GiB", static_cast<double>(bytes) / double(1ull << 30));
  return buf;
}

}  // namespace

// Until exports stream, a chunk lives in memory whole: one that cannot fit
// is refused before it is built (it ran for minutes and died out of memory).
void refuse_if_too_big(const FineMesh& mesh, const ChunkRange& range) {
  const std::uint64_t need = estimate_chunk_bytes(mesh, range), avail = available_memory_bytes();
  if (need <= avail) return;
  // Chunks are balanced by elements: N chunks of the mesh, each at most
  // half of what is available now.
  const long double whole = static_cast<long double>(need) * static_cast<long double>(std::max<Id>(range.count, 1));
  const long double n = std::ceil(2 * whole / std::max<long double>(static_cast<long double>(avail), 1));
  std::ostringstream msg;
  msg << "export: chunk " << range.index << " of " << range.count << " (coarse elements " << range.first_coarse << ".."
      << range.end_coarse << ") needs about " << gib(need) << " of memory, more than the " << gib(avail)
      << " available; export it in pieces: --chunks N (VTKHDF, Nemesis) or --chunk K/N for K = 0..N-1, with N >= "
      << static_cast<unsigned long long>(std::min<long double>(n, 1e18L));
  throw Error(ErrorKind::Usage, msg.str());
}

}  // namespace dicer
