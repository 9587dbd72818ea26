// Chunks and box selections of the fine mesh, with local numbering, held in
// memory (ExportChunk); the chunk plan and box search. The streaming source
// the CLI writes from is export/stream.cpp.
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <numeric>
#include <sstream>

#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/numbering.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"
#include "sets.hpp"

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

// Element e of the block or slab b (FineBlock: layers above plane0).
void centroid(const FineBlock& b, Id e, int corners, double c[3]) {
  c[0] = c[1] = c[2] = 0;
  const Id i = e % b.n[0], j = (e / b.n[0]) % b.n[1], k = b.plane0 + e / (b.n[0] * b.n[1]);
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
  for (int d = 0; d < 3; ++d) b.lo[d] = v[d], b.hi[d] = v[d + 3];
  check_box(b, "--box");
  return b;
}

void check_box(const Box& box, const std::string& what) {
  for (int d = 0; d < 3; ++d) {
    const std::string axis(1, "xyz"[d]);
    if (!std::isfinite(box.lo[d]) || !std::isfinite(box.hi[d]))
      throw Error(ErrorKind::Usage, what + ": a corner's " + axis + " is not a finite number");
    if (box.lo[d] > box.hi[d]) throw Error(ErrorKind::Usage, what + ": lower corner above upper corner along axis " + axis);
  }
}

Id for_each_in_box(const FineMesh& mesh, const Box& box, const std::function<void(const FineBlock&, Id)>& fn,
                   Id first_coarse, Id end_coarse) {
  check_box(box, "box query");
  MeshCursor cur;
  FineBlock b;
  Id count = 0;
  const int nc = mesh.corners();
  if (end_coarse < 0) end_coarse = mesh.num_coarse_elements();
  for (Id h = std::max<Id>(first_coarse, 0); h < std::min(end_coarse, mesh.num_coarse_elements()); ++h) {
    if (coarse_box_misses(mesh, h, box, cur)) continue;
    mesh.for_each_slab(h, b, static_cast<bool>(fn), [&](const FineBlock& slab) {
      for (Id e = 0; e < slab.num_elements(); ++e) {
        double c[3];
        centroid(slab, e, nc, c);
        if (!box.contains(c[0], c[1], c[2])) continue;
        ++count;
        if (fn) fn(slab, e);
      }
    });
  }
  return count;
}

ExportChunk::ExportChunk(const FineMesh& mesh, ChunkRange range, std::optional<Box> box)
    : mesh_(mesh), range_(range), box_(box) {
  if (range_.first_coarse < 0 || range_.end_coarse > mesh.num_coarse_elements() || range_.first_coarse > range_.end_coarse)
    throw Error(ErrorKind::Usage, "chunk range is outside the mesh");
  if (box_) check_box(*box_, "export box");
  // The own node range follows from the coarse range (owner order); a
  // caller-made ChunkRange need not know it.
  MeshCursor cur;
  const auto own = mesh.owned_nodes(range_.first_coarse, range_.end_coarse, cur);
  range_.node_begin = own[0], range_.node_end = own[1];
}

void ExportChunk::prepare(const MeshSets& sets, const std::function<void(Id, Id)>& progress,
                          const std::function<bool()>& cancel) {
  node_global_.clear(), elem_global_.clear(), conn_.clear(), elem_block_.clear();
  x_.clear(), y_.clear(), z_.clear(), users_.clear(), user_sets_.clear();
  side_sets_.clear(), node_sets_.clear(), node_ranges_.clear();
  if (!box_) {
    refuse_if_too_big(mesh_, range_);
    // The chunk's two passes, kept.
    const ChunkStream s(mesh_, range_, sets, progress, cancel);
    s.expect_passes(2);
    const auto nn = static_cast<size_t>(s.num_nodes()), ne = static_cast<size_t>(s.num_elements());
    node_global_.reserve(nn), x_.reserve(nn), y_.reserve(nn), z_.reserve(nn), users_.reserve(nn);
    s.nodes({}, [&](const NodeSpan& n) {
      node_global_.insert(node_global_.end(), n.global, n.global + n.count);
      x_.insert(x_.end(), n.x, n.x + n.count), y_.insert(y_.end(), n.y, n.y + n.count);
      z_.insert(z_.end(), n.z, n.z + n.count), users_.insert(users_.end(), n.users, n.users + n.count);
    });
    elem_global_.reserve(ne), elem_block_.reserve(ne), conn_.reserve(ne * static_cast<size_t>(corners()));
    s.elements({}, [&](const ElementSpan& e) {
      elem_global_.insert(elem_global_.end(), e.global, e.global + e.count);
      elem_block_.insert(elem_block_.end(), static_cast<size_t>(e.count), e.block);
      conn_.insert(conn_.end(), e.conn, e.conn + e.count * corners());
    });
    user_sets_ = s.user_sets();
    side_sets_ = s.side_sets();
    node_ranges_ = s.node_set_ranges();
    for (const NodeRanges& r : node_ranges_) {
      node_sets_.push_back({r.id, r.name, {}});
      for (const auto& [a, b] : r.local)
        for (Id l = a; l < b; ++l) node_sets_.back().node.push_back(l);
    }
    range_ = s.range();
  } else {
    prepare_box(sets, progress, cancel);
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
}

// Box: the kept elements' nodes, sorted and deduplicated, then a second
// pass for coordinates and connectivity. A kept element's centroid needs
// all its corners, owned or not, so this reads every node of a coarse
// element the box meets, a slab at a time (FineMesh::for_each_slab).
void ExportChunk::prepare_box(const MeshSets& sets, const std::function<void(Id, Id)>& progress,
                              const std::function<bool()>& cancel) {
  const Mode mode = this->mode();
  const int nc = corners();
  const Id first = range_.first_coarse, end = range_.end_coarse, span = end - first;
  MeshCursor cur;
  const RowReader R(mesh_.tables(), cur);
  FineBlock b;
  auto check_cancel = [&] {
    if (cancel && cancel()) throw Error(ErrorKind::Cancelled, "interrupted");
  };
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
  const std::vector<detail::SideRef> refs = detail::side_refs(sets, first, end);
  for (const auto& ss : sets.side_sets) side_sets_.push_back({ss.id, ss.name, {}, {}});
  size_t next_side = 0;
  auto elements_of = [&](const FineBlock& blk, auto&& on_element) {
    const auto n = blk.n;
    const Id sj = n[0] + 1, sk = (n[0] + 1) * (n[1] + 1);
    const Id off[8] = {0, 1, 1 + sj, sj, sk, 1 + sk, 1 + sj + sk, sj + sk};
    for (Id k = 0; k < blk.layers; ++k)
      for (Id j = 0; j < n[1]; ++j)
        for (Id i = 0; i < n[0]; ++i) {
          const Id g0 = blk.point_index(i, j, k + blk.plane0);
          double c[3];  // the same centroid as for_each_in_box
          centroid(blk, i + n[0] * (j + n[1] * k), nc, c);  // k: the slab's layer
          if (!box_->contains(c[0], c[1], c[2])) continue;
          on_element(ids::element(blk.first_element, n, i, j, k), g0, off);
        }
  };

  for (Id h = first; h < end; ++h) {
    check_cancel();
    if (coarse_box_misses(mesh_, h, *box_, cur)) {
      kept_coarse[h - first] = 0;
      if (progress) progress(h - first + 1, 2 * span);
      continue;
    }
    bool any = false;
    mesh_.for_each_slab(h, b, false, [&](const FineBlock& slab) {
      elements_of(slab, [&](Id, Id g0, const Id* off) {
        any = true;
        for (int q = 0; q < nc; ++q) node_global_.push_back(slab.node_id[g0 + off[q]]);
      });
    });
    if (!any) kept_coarse[h - first] = 0;
    if (progress) progress(h - first + 1, 2 * span);
  }
  std::sort(node_global_.begin(), node_global_.end());
  node_global_.erase(std::unique(node_global_.begin(), node_global_.end()), node_global_.end());
  node_global_.shrink_to_fit();
  const size_t nn = node_global_.size();
  x_.assign(nn, 0), y_.assign(nn, 0), z_.assign(nn, 0);
  for (Id h = first; h < end; ++h) {
    check_cancel();
    if (kept_coarse[h - first]) {
      Id element_first = -1;  // the coarse element's first fine element (its first slab's)
      mesh_.for_each_slab(h, b, false, [&](const FineBlock& slab) {
        if (slab.plane0 == 0) element_first = slab.first_element;
        elements_of(slab, [&](Id gid, Id g0, const Id* off) {
          elem_global_.push_back(gid);
          elem_block_.push_back(slab.block);
          for (int q = 0; q < nc; ++q) {
            const Id g = g0 + off[q], l = local_of(slab.node_id[g]);
            x_[l] = slab.x[g], y_[l] = slab.y[g], z_[l] = slab.z[g];
            conn_.push_back(l);
          }
        });
      });
      if (!node_set_sorted.empty()) {
        const ElementRow row = R.element(h);
        for (size_t s = 0; s < node_set_sorted.size(); ++s)
          detail::node_set_ranges(row, mode, node_set_sorted[s], node_set_ids[s]);
      }
      for (; next_side < refs.size() && refs[next_side].h < h; ++next_side) {
      }
      for (; next_side < refs.size() && refs[next_side].h == h; ++next_side)
        detail::append_side(mode, element_first, b.n, refs[next_side].side, side_sets_[refs[next_side].set]);
    }
    if (progress) progress(span + h - first + 1, 2 * span);
  }

  // Node sets: the id ranges found per element, as local indices.
  for (size_t s = 0; s < node_set_ids.size(); ++s) {
    auto& rs = node_set_ids[s];
    detail::merge_ranges(rs);
    auto& out = node_sets_[s].node;
    for (const auto& r : rs)
      for (Id id = r[0]; id < r[1]; ++id)
        if (const Id l = local_of(id); l >= 0) out.push_back(l);
    NodeRanges ranges{node_sets_[s].id, node_sets_[s].name, {}};
    for (Id l : out) {
      if (!ranges.local.empty() && ranges.local.back()[1] == l) ++ranges.local.back()[1];
      else ranges.local.push_back({l, l + 1});
    }
    node_ranges_.push_back(std::move(ranges));
  }

  // Side sets: global element ids to local indices (elements outside the
  // box drop out), sorted by element then side.
  for (auto& m : side_sets_) {
    SideMembers kept{m.id, m.name, {}, {}};
    for (size_t q = 0; q < m.element.size(); ++q) {
      const auto it = std::lower_bound(elem_global_.begin(), elem_global_.end(), m.element[q]);
      if (it != elem_global_.end() && *it == m.element[q])
        kept.element.push_back(it - elem_global_.begin()), kept.side.push_back(m.side[q]);
    }
    detail::sort_members(kept);
    m = std::move(kept);
  }

  // Using blocks of each node, from the kept elements.
  for (std::int32_t blk = 0; blk < static_cast<std::int32_t>(mesh_.info().blocks.size()); ++blk)
    user_sets_.push_back({blk});
  std::map<std::vector<std::int32_t>, std::uint32_t> index;
  std::map<std::pair<std::uint32_t, std::int32_t>, std::uint32_t> joined;  // (set, block) -> set
  constexpr std::uint32_t kNone = UINT32_MAX;
  users_.assign(nn, kNone);
  for (size_t e = 0; e < elem_global_.size(); ++e) {
    const std::int32_t blk = elem_block_[e];
    for (int q = 0; q < nc; ++q) {
      std::uint32_t& u = users_[static_cast<size_t>(conn_[e * nc + q])];
      if (u == kNone) {
        u = static_cast<std::uint32_t>(blk);
        continue;
      }
      const auto& have = user_sets_[u];
      if (std::binary_search(have.begin(), have.end(), blk)) continue;
      const auto [it, fresh] = joined.try_emplace({u, blk}, 0);
      if (fresh) {
        std::vector<std::int32_t> set = have;
        set.insert(std::upper_bound(set.begin(), set.end(), blk), blk);
        const auto [jt, added] = index.try_emplace(set, static_cast<std::uint32_t>(user_sets_.size()));
        if (added) user_sets_.push_back(std::move(set));
        it->second = jt->second;
      }
      u = it->second;
    }
  }
}

std::vector<Id> ExportChunk::block_counts() const {
  std::vector<Id> out(mesh_.info().blocks.size(), 0);
  for (std::int32_t b : elem_block_) {
    if (b < 0 || static_cast<size_t>(b) >= out.size())
      throw Error(ErrorKind::Usage, "chunk " + std::to_string(range_.index) + ": block index " + std::to_string(b) +
                                        " out of range");
    ++out[static_cast<size_t>(b)];
  }
  return out;
}

Id ExportChunk::local_of(Id id) const {
  const auto it = std::lower_bound(node_global_.begin(), node_global_.end(), id);
  return (it != node_global_.end() && *it == id) ? it - node_global_.begin() : -1;
}

void ExportChunk::nodes(const NodePass& pass, const std::function<void(const NodeSpan&)>& fn) const {
  constexpr Id kSpan = Id{1} << 16;
  const Id nn = num_nodes();
  if (static_cast<Id>(users_.size()) != nn || static_cast<Id>(x_.size()) != nn)
    throw Error(ErrorKind::Usage, "chunk " + std::to_string(range_.index) + " is not prepared");
  auto keep = [&](Id l) { return pass.lowest_user < 0 || user_sets_[users_[l]].front() == pass.lowest_user; };
  for (Id a = 0; a < nn;) {
    if (!keep(a)) {
      ++a;
      continue;
    }
    Id b = a + 1;
    while (b < nn && b - a < kSpan && keep(b)) ++b;
    NodeSpan s;
    s.first = a, s.count = b - a, s.global = node_global_.data() + a, s.users = users_.data() + a;
    if (pass.coords) s.x = x_.data() + a, s.y = y_.data() + a, s.z = z_.data() + a;
    fn(s);
    a = b;
  }
}

void ExportChunk::elements(const ElementPass& pass, const std::function<void(const ElementSpan&)>& fn) const {
  constexpr Id kSpan = Id{1} << 14;
  const Id ne = num_elements();
  const int nc = corners();
  std::vector<Id> global;
  for (Id a = 0; a < ne;) {
    const std::int32_t blk = elem_block_[static_cast<size_t>(a)];
    Id b = a + 1;
    while (b < ne && b - a < kSpan && elem_block_[static_cast<size_t>(b)] == blk) ++b;
    if (pass.block < 0 || blk == pass.block) {
      ElementSpan s;
      s.first = a, s.count = b - a, s.global = elem_global_.data() + a, s.block = blk;
      s.conn = conn_.data() + a * nc;
      if (pass.global_conn) {
        global.resize(static_cast<size_t>((b - a) * nc));
        for (size_t q = 0; q < global.size(); ++q) global[q] = node_global_[static_cast<size_t>(s.conn[q])];
        s.conn = global.data();
      }
      fn(s);
    }
    a = b;
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

namespace {

// What prepare() keeps (ExportChunk's members): per element its global id,
// block index and connectivity; per node its global id, x, y, z, owner,
// using blocks. estimate_chunk_bytes and refuse_if_too_big's largest-element
// bound both use these rates.
constexpr unsigned chunk_bytes_per_element(int corners) { return 8 + 4 + 8 * static_cast<unsigned>(corners); }
constexpr unsigned kChunkBytesPerNode = 8 + 24 + 4 + 4;

}  // namespace

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
  const unsigned __int128 per_element = chunk_bytes_per_element(mesh.corners());
  const unsigned __int128 per_node = kChunkBytesPerNode;
  const unsigned __int128 bytes = per_element * static_cast<std::uint64_t>(std::max<Id>(elements, 0)) +
                                  per_node * static_cast<std::uint64_t>(std::max<Id>(nodes, 0));
  return bytes > UINT64_MAX ? UINT64_MAX : static_cast<std::uint64_t>(bytes);
}

// A held chunk lives in memory whole: one that cannot fit is refused before
// it is built (it would run for minutes and die out of memory). The CLI's
// exports stream and need no such check.
void refuse_if_too_big(const FineMesh& mesh, const ChunkRange& range) {
  const std::uint64_t need = estimate_chunk_bytes(mesh, range), avail = available_memory_bytes();
  if (need <= avail) return;
  // Chunks are balanced by elements: N chunks of the mesh, each at most
  // half of what is available now.
  const long double whole = static_cast<long double>(need) * static_cast<long double>(std::max<Id>(range.count, 1));
  const long double n = std::ceil(2 * whole / std::max<long double>(static_cast<long double>(avail), 1));
  std::ostringstream msg;
  msg << "export: chunk " << range.index << " of " << range.count << " (coarse elements " << range.first_coarse << ".."
      << range.end_coarse << ") needs about " << detail::gib(need) << " of memory, more than the " << detail::gib(avail)
      << " available; ";
  // No chunk is smaller than its largest coarse element: when that one
  // alone does not fit, no N helps.
  const Id H = mesh.num_coarse_elements();
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  const bool vol = mesh.mode() == Mode::Volume;
  long double largest = 0;
  Id which = range.first_coarse;
  for (Id h = range.first_coarse; h < range.end_coarse; ++h) {
    const auto e = R.element(h).n;
    const long double a = e[0], b = e[1], c = vol ? e[2] : 1;
    const long double bytes = a * b * c * chunk_bytes_per_element(mesh.corners()) +
                              (a + 1) * (b + 1) * (vol ? c + 1 : 1) * kChunkBytesPerNode;
    if (bytes > largest) largest = bytes, which = h;
  }
  if (largest > static_cast<long double>(avail))
    msg << "a chunk holds whole coarse elements, and coarse element " << which << " alone needs about "
        << detail::gib(static_cast<std::uint64_t>(std::min<long double>(largest, static_cast<long double>(UINT64_MAX))))
        << ": stream it instead (dicer export; Python: Store.batches()), or run where more memory is free";
  else
    msg << "take it in pieces: N chunks (--chunks N, --chunk K/N for K = 0..N-1; Python: chunk(k, N)) with N >= "
        << static_cast<unsigned long long>(std::min(n, static_cast<long double>(H)));
  throw Error(ErrorKind::Usage, msg.str());
}

}  // namespace dicer
