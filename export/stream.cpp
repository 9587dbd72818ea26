// ChunkStream (export.hpp): a chunk generated pass by pass from the batch
// API, and the set helpers both chunk sources share (sets.hpp).
//
// Why runs: every coarse vertex, edge and face owns one run of consecutive
// node ids (numbering.hpp), and which elements use a node is a property of
// its run. So the nodes lower chunks own (ghosts) and the nodes on a
// boundary between blocks are a few runs found from the element rows, and
// every other node is used by its owning element's block alone: a pass
// needs no per-node lookup beyond the batch it is handed.
#include <algorithm>
#include <cstdio>
#include <map>
#include <numeric>

#include "dicer/batch.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "dicer/numbering.hpp"
#include "dicer/orientation.hpp"
#include "dicer/rows.hpp"
#include "sets.hpp"

namespace dicer {
namespace detail {

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

std::vector<SideRef> side_refs(const MeshSets& sets, Id first, Id end) {
  std::vector<SideRef> out;
  for (size_t s = 0; s < sets.side_sets.size(); ++s) {
    const auto& ss = sets.side_sets[s];
    for (size_t q = 0; q < ss.element.size() && q < ss.side.size(); ++q)
      if (ss.element[q] >= first && ss.element[q] < end && ss.side[q] >= 0 && ss.side[q] <= 5)
        out.push_back({ss.element[q], static_cast<std::int32_t>(s), ss.side[q]});
  }
  std::stable_sort(out.begin(), out.end(), [](const SideRef& a, const SideRef& c) { return a.h < c.h; });
  return out;
}

namespace {

// The cells of coarse element n on Exodus side `side`: [lo, hi) per axis.
// A side's plane alone, O(n^2) of the element's n^3 cells (visiting them
// all took minutes for a side at interval 8000).
void side_cells(Mode mode, const std::array<Id, 3>& n, std::int8_t side, Id lo[3], Id hi[3]) {
  const SidePlane plane = exodus_side_plane(mode, side);
  for (int a = 0; a < 3; ++a) lo[a] = 0, hi[a] = n[a];
  if (plane.axis >= 0) {
    lo[plane.axis] = plane.high ? n[plane.axis] - 1 : 0;
    hi[plane.axis] = lo[plane.axis] + 1;
  }
}

}  // namespace

long double side_faces(Mode mode, const std::array<Id, 3>& n, std::int8_t side) {
  Id lo[3], hi[3];
  side_cells(mode, n, side, lo, hi);
  long double count = 1;
  for (int a = 0; a < 3; ++a) count *= static_cast<long double>(std::max<Id>(hi[a] - lo[a], 0));
  return count;
}

void append_side(Mode mode, Id element_first, const std::array<Id, 3>& n, std::int8_t side, SideMembers& m) {
  Id lo[3], hi[3];
  side_cells(mode, n, side, lo, hi);
  for (Id k = lo[2]; k < hi[2]; ++k)
    for (Id j = lo[1]; j < hi[1]; ++j)
      for (Id i = lo[0]; i < hi[0]; ++i) {
        m.element.push_back(ids::element(element_first, n, i, j, k));
        m.side.push_back(side);
      }
}

std::string gib(long double bytes) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.1Lf GiB", bytes / static_cast<long double>(1ull << 30));
  return buf;
}

void sort_members(SideMembers& m) {
  std::vector<std::pair<Id, std::int8_t>> fs;
  fs.reserve(m.element.size());
  for (size_t q = 0; q < m.element.size(); ++q) fs.emplace_back(m.element[q], m.side[q]);
  std::sort(fs.begin(), fs.end());
  fs.erase(std::unique(fs.begin(), fs.end()), fs.end());
  m.element.clear(), m.side.clear();
  for (const auto& [e, side] : fs) m.element.push_back(e), m.side.push_back(side);
}

void merge_ranges(std::vector<std::array<Id, 2>>& r) {
  std::sort(r.begin(), r.end());
  size_t w = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    if (r[i][0] >= r[i][1]) continue;
    if (w > 0 && r[i][0] <= r[w - 1][1]) r[w - 1][1] = std::max(r[w - 1][1], r[i][1]);
    else r[w++] = r[i];
  }
  r.resize(w);
}

}  // namespace detail

namespace {

constexpr Id kSpanNodes = Id{1} << 16;  // nodes per span where the source picks (ghosts, id-only passes)

// The batches of coarse elements [h0, h1) (batch.hpp): fn(batch), and
// done(k) after each with the k coarse elements finished since the last.
template <class Done, class Fn>
void for_each_batch(const FineMesh& mesh, Id h0, Id h1, bool coords, bool conn, Done&& done, Fn&& fn) {
  BatchOptions opt;
  opt.coords = coords, opt.conn = conn;
  BatchCursor batches(mesh, h0, h1, opt);
  FineBatch batch;
  Id counted = h0;
  while (batches.next(batch)) {
    done(batch.coarse_element - counted);
    counted = batch.coarse_element;
    fn(batch);
  }
  done(h1 - counted);
}

// The palette of user sets: {b} is entry b; other sets are appended once.
struct Palette {
  std::vector<std::vector<std::int32_t>>& sets;
  std::map<std::vector<std::int32_t>, std::uint32_t> index;
  std::uint32_t of(std::vector<std::int32_t> blocks) {
    std::sort(blocks.begin(), blocks.end());
    blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
    if (blocks.size() == 1) return static_cast<std::uint32_t>(blocks[0]);
    const auto [it, fresh] = index.try_emplace(blocks, static_cast<std::uint32_t>(sets.size()));
    if (fresh) sets.push_back(blocks);
    return it->second;
  }
};

// x, y, z of nodes [first, first + count): FineMesh::nodes over pieces of
// consecutive ids (one owner search, row decode and corner read per coarse
// element, not per node), the bits of node(id). ids, pts: reused work space.
void run_coords(const FineMesh& mesh, Id first, Id count, MeshCursor& cur, std::vector<Id>& ids,
                std::vector<Vec3>& pts, double* x, double* y, double* z) {
  constexpr Id kPiece = 4096;
  for (Id a = 0; a < count; a += kPiece) {
    const Id m = std::min(kPiece, count - a);
    ids.resize(static_cast<size_t>(m)), pts.resize(static_cast<size_t>(m));
    for (Id q = 0; q < m; ++q) ids[q] = first + a + q;
    mesh.nodes(ids, pts, cur);
    for (Id q = 0; q < m; ++q) x[a + q] = pts[q].x, y[a + q] = pts[q].y, z[a + q] = pts[q].z;
  }
}

}  // namespace

ChunkStream::ChunkStream(const FineMesh& mesh, ChunkRange range, const MeshSets& sets,
                         std::function<void(Id, Id)> progress, std::function<bool()> cancel)
    : mesh_(mesh), range_(range), progress_(std::move(progress)), cancel_(std::move(cancel)) {
  const Id H = mesh.num_coarse_elements();
  if (range_.first_coarse < 0 || range_.end_coarse > H || range_.first_coarse > range_.end_coarse)
    throw Error(ErrorKind::Usage, "chunk range is outside the mesh");
  const Id first = range_.first_coarse, end = range_.end_coarse, span = end - first;
  const Mode mode = mesh.mode();
  const bool vol = mode == Mode::Volume;
  MeshCursor cur;
  const RowReader R(mesh.tables(), cur);
  const auto own = mesh.owned_nodes(first, end, cur);
  range_.node_begin = own[0], range_.node_end = own[1];
  const Id own0 = own[0];

  const auto& blocks = mesh.info().blocks;
  const auto B = static_cast<std::int32_t>(blocks.size());
  block_counts_.assign(blocks.size(), 0);
  for (std::int32_t b = 0; b < B; ++b) user_sets_.push_back({b});
  Palette palette{user_sets_, {}};

  node_first_.resize(static_cast<size_t>(span) + 1), element_first_.resize(node_first_.size());
  block_.resize(static_cast<size_t>(span));
  struct Use {  // a run and one block using it
    Id first, count;
    std::int32_t block;
  };
  std::vector<Use> ghost_uses, shared_uses;
  const std::vector<detail::SideRef> refs = detail::side_refs(sets, first, end);
  size_t next_ref = 0;
  {
    // The chunk's side faces are held until the writer has them (MSH and
    // Exodus write the sets after the elements): 9 bytes each, 25 while
    // they are sorted. More than is free is refused here, by name, not
    // minutes later by the kernel.
    long double faces = 0;
    for (const auto& ref : refs) faces += detail::side_faces(mode, R.element(ref.h).n, ref.side);
    const long double need = 25 * faces, avail = static_cast<long double>(available_memory_bytes());
    if (need > avail) {
      char count[32];
      std::snprintf(count, sizeof count, "%.3Lg", faces);
      throw Error(ErrorKind::Usage,
                  where() + ": the side sets of coarse elements " + std::to_string(first) + ".." + std::to_string(end) +
                      " hold " + count + " fine faces, kept while written: about " + detail::gib(need) +
                      ", more than the " + detail::gib(avail) +
                      " available; export it in more chunks (--chunks N), to VTKHDF (which writes no sets), "
                      "or where more memory is free");
    }
  }
  for (const auto& ss : sets.side_sets) side_sets_.push_back({ss.id, ss.name, {}, {}});
  std::vector<std::vector<Id>> ns_vertices;
  std::vector<std::vector<std::array<Id, 2>>> ns_ranges(sets.node_sets.size());
  for (const auto& ns : sets.node_sets) {
    ns_vertices.push_back(ns.vertex);
    std::sort(ns_vertices.back().begin(), ns_vertices.back().end());
  }

  ElementRow row;
  for (Id h = first; h < end; ++h) {
    const size_t i = static_cast<size_t>(h - first);
    if ((i & 1023) == 0) poll();
    R.element(h, row);
    if (row.block < 0 || row.block >= B) R.corrupt(RowTable::Elements, h, "block index out of range");
    if (row.node_first < (i ? node_first_[i - 1] : own0))
      R.corrupt(RowTable::Elements, h, "node ids do not rise with the elements");
    node_first_[i] = row.node_first, element_first_[i] = row.element_first, block_[i] = row.block;
    block_counts_[static_cast<size_t>(row.block)] += row.n[0] * row.n[1] * (vol ? row.n[2] : 1);
    // Runs h uses but does not own: a lower chunk's (ghosts), or an earlier
    // element's of this chunk, shared between blocks when that owner's
    // block is another.
    auto use = [&](Id run, Id count) {
      if (count <= 0 || row.owns(run)) return;
      if (run < own0) {
        ghost_uses.push_back({run, count, row.block});
        return;
      }
      const auto o = std::upper_bound(node_first_.begin(), node_first_.begin() + static_cast<std::ptrdiff_t>(i), run) -
                     node_first_.begin() - 1;
      if (o < 0) R.corrupt(RowTable::Elements, h, "node " + std::to_string(run) + " has no owner in its chunk");
      if (block_[static_cast<size_t>(o)] != row.block)
        shared_uses.push_back({run, count, row.block}), shared_uses.push_back({run, count, block_[static_cast<size_t>(o)]});
    };
    for (int k = 0; k < R.corners(); ++k) use(row.corner_node[k], 1);
    for (int k = 0; k < R.edges(); ++k) use(row.edge_node[k], ids::edge_nodes(row.n[vol ? k / 4 : k / 2]));
    for (int k = 0; k < R.faces(); ++k) {
      const auto [nu, nv] = face_intervals(row, k, mode);
      use(row.face_node[k], ids::face_nodes(nu, nv));
    }
    for (size_t s = 0; s < ns_vertices.size(); ++s) detail::node_set_ranges(row, mode, ns_vertices[s], ns_ranges[s]);
    for (; next_ref < refs.size() && refs[next_ref].h == h; ++next_ref, poll())
      detail::append_side(mode, row.element_first, row.n, refs[next_ref].side, side_sets_[refs[next_ref].set]);
  }
  node_first_[static_cast<size_t>(span)] = own[1];
  element_first_[static_cast<size_t>(span)] = end < H ? R.element_first(end) : mesh.num_elements();
  if (span == 0) element_first_[0] = element_first_[static_cast<size_t>(span)];
  range_.fine_elements = element_first_.back() - element_first_.front();
  if (node_first_.front() != own0 || node_first_.back() < node_first_[static_cast<size_t>(std::max<Id>(span - 1, 0))] ||
      range_.fine_elements < 0)
    R.corrupt(RowTable::Elements, first, "node or element ids do not rise with the elements");

  // Runs from their uses: sorted, one entry per run with its blocks.
  auto runs_of = [&](std::vector<Use>& uses, std::vector<Run>& out) {
    std::sort(uses.begin(), uses.end(), [](const Use& a, const Use& b) { return a.first < b.first; });
    for (size_t a = 0; a < uses.size();) {
      size_t b = a;
      std::vector<std::int32_t> users;
      for (; b < uses.size() && uses[b].first == uses[a].first; ++b) {
        if (uses[b].count != uses[a].count)
          throw Error(ErrorKind::Corrupt, where() + ": node run " + std::to_string(uses[a].first) +
                                              " is seen with two sizes");
        users.push_back(uses[b].block);
      }
      if (!out.empty() && out.back().first + out.back().count > uses[a].first)
        throw Error(ErrorKind::Corrupt, where() + ": node runs " + std::to_string(out.back().first) + " and " +
                                            std::to_string(uses[a].first) + " overlap");
      out.push_back({uses[a].first, uses[a].count, palette.of(std::move(users))});
      a = b;
    }
    std::vector<Use>().swap(uses);
  };
  runs_of(ghost_uses, ghosts_);
  runs_of(shared_uses, interfaces_);
  ghost_local_.push_back(0);
  for (const Run& g : ghosts_) ghost_local_.push_back(ghost_local_.back() + g.count);
  // Ghost coordinates: runs of ids by the batched query, the same bits as a
  // batch (invariant 2).
  const Id ng = num_ghosts();
  gx_.resize(static_cast<size_t>(ng)), gy_.resize(gx_.size()), gz_.resize(gx_.size());
  {
    std::vector<Id> ids;
    std::vector<Vec3> pts;
    for (size_t k = 0; k < ghosts_.size(); ++k) {
      const auto l = static_cast<size_t>(ghost_local_[k]);
      run_coords(mesh, ghosts_[k].first, ghosts_[k].count, cur, ids, pts, gx_.data() + l, gy_.data() + l,
                 gz_.data() + l);
    }
  }

  // Sets in local numbering.
  for (auto& m : side_sets_) {
    for (Id& e : m.element) e -= element_first_.front();
    detail::sort_members(m);
  }
  for (size_t s = 0; s < sets.node_sets.size(); ++s) {
    auto& rs = ns_ranges[s];
    detail::merge_ranges(rs);
    NodeRanges out{sets.node_sets[s].id, sets.node_sets[s].name, {}};
    for (const auto& r : rs) {
      // A range lies in the own range or in one ghost run (entity runs are
      // whole); split at the own range's start in any case.
      for (Id a = r[0]; a < r[1];) {
        const Id b = a < own0 ? std::min(r[1], own0) : r[1];
        const Id la = local_of(a), lb = local_of(b - 1);
        if (la < 0 || lb - la != b - 1 - a)
          throw Error(ErrorKind::Corrupt, where() + ": node set " + std::to_string(out.id) + ": nodes " +
                                              std::to_string(a) + ".." + std::to_string(b) + " are not the chunk's");
        out.local.push_back({la, lb + 1});
        a = b;
      }
    }
    detail::merge_ranges(out.local);
    node_sets_.push_back(std::move(out));
  }
}

Id ChunkStream::local_of(Id id) const {
  if (id >= range_.node_begin) return id < range_.node_end ? num_ghosts() + (id - range_.node_begin) : -1;
  const auto it = std::upper_bound(ghosts_.begin(), ghosts_.end(), id, [](Id v, const Run& r) { return v < r.first; });
  if (it == ghosts_.begin()) return -1;
  const size_t k = static_cast<size_t>(it - ghosts_.begin()) - 1;
  return id < ghosts_[k].first + ghosts_[k].count ? ghost_local_[k] + (id - ghosts_[k].first) : -1;
}

void ChunkStream::expect_passes(int passes) const {
  total_ += static_cast<Id>(passes) * (range_.end_coarse - range_.first_coarse);
}

// Called once per batch: coarse_elements finished since the last call.
void ChunkStream::step(Id coarse_elements) const {
  done_ += coarse_elements;
  if (progress_ && coarse_elements > 0) progress_(done_, std::max(done_, total_));
  poll();
}

void ChunkStream::poll() const {
  if (cancel_ && cancel_()) throw Error(ErrorKind::Cancelled, "interrupted");
}

std::string ChunkStream::where() const {
  return mesh_.tables().origin.empty() ? std::string("in memory") : mesh_.tables().origin;
}

// Own nodes [a, b) of coarse element index i, their coordinates (or null)
// from a: one span per stretch of equal users, those the pass keeps.
struct ChunkStream::Emitter {
  const ChunkStream& s;
  const NodePass& pass;
  const std::function<void(const NodeSpan&)>& fn;
  size_t next_interface = 0;  // ids only rise during a pass
  std::vector<Id> global;
  std::vector<std::uint32_t> users;

  void emit(Id a, Id b, std::uint32_t u, const double* x, const double* y, const double* z) {
    if (pass.lowest_user >= 0 && s.user_sets_[u].front() != pass.lowest_user) return;
    const auto n = static_cast<size_t>(b - a);
    if (global.size() < n) global.resize(n), users.resize(n);
    std::iota(global.begin(), global.begin() + static_cast<std::ptrdiff_t>(n), a);
    std::fill_n(users.begin(), n, u);
    NodeSpan span;
    span.first = s.num_ghosts() + (a - s.range_.node_begin), span.count = b - a;
    span.global = global.data(), span.users = users.data();
    span.x = x, span.y = y, span.z = z;
    fn(span);
  }
  // [a, b) of one element of block `block`, split where interface runs begin and end.
  void range(Id a, Id b, std::int32_t block, const double* x, const double* y, const double* z) {
    const auto& runs = s.interfaces_;
    for (Id p = a; p < b;) {
      while (next_interface < runs.size() && runs[next_interface].first + runs[next_interface].count <= p)
        ++next_interface;
      Id q = b;
      std::uint32_t u = static_cast<std::uint32_t>(block);
      if (next_interface < runs.size() && runs[next_interface].first <= p) {
        q = std::min(b, runs[next_interface].first + runs[next_interface].count);
        u = runs[next_interface].users;
      } else if (next_interface < runs.size()) {
        q = std::min(b, runs[next_interface].first);
      }
      const Id o = p - a;
      emit(p, q, u, x ? x + o : nullptr, y ? y + o : nullptr, z ? z + o : nullptr);
      p = q;
    }
  }
};

void ChunkStream::nodes(const NodePass& pass, const std::function<void(const NodeSpan&)>& fn) const {
  // Ghosts: local ids 0 .. num_ghosts() - 1, run after run.
  {
    std::vector<Id> global;
    std::vector<std::uint32_t> users;
    Id at = 0;  // first local id of the pending span
    auto flush = [&](Id end) {
      if (end > at) {
        NodeSpan span;
        span.first = at, span.count = end - at;
        span.global = global.data(), span.users = users.data();
        if (pass.coords) span.x = gx_.data() + at, span.y = gy_.data() + at, span.z = gz_.data() + at;
        fn(span);
      }
      global.clear(), users.clear();
    };
    for (size_t k = 0; k < ghosts_.size(); ++k) {
      const Run& g = ghosts_[k];
      if (pass.lowest_user >= 0 && user_sets_[g.users].front() != pass.lowest_user) {
        flush(ghost_local_[k]);
        at = ghost_local_[k + 1];
        continue;
      }
      for (Id q = 0; q < g.count; ++q) {
        if (static_cast<Id>(global.size()) == kSpanNodes) {
          flush(ghost_local_[k] + q);
          at = ghost_local_[k] + q;
        }
        global.push_back(g.first + q), users.push_back(g.users);
      }
    }
    flush(num_ghosts());
  }

  // Own nodes, element by element in store order.
  Emitter out{*this, pass, fn, 0, {}, {}};
  const Id first = range_.first_coarse, span = range_.end_coarse - first;
  const std::int32_t v = pass.lowest_user;
  MeshCursor cur;
  std::vector<double> xyz[3];
  std::vector<Id> ids;
  std::vector<Vec3> pts;
  for (Id i = 0; i < span;) {
    if (v >= 0 && block_[static_cast<size_t>(i)] != v) {
      // Another block's element: only its interface runs that block v
      // uses first (whose lowest using block is v), by random access.
      const Id a = node_first_[static_cast<size_t>(i)], b = node_first_[static_cast<size_t>(i) + 1];
      auto it = std::lower_bound(interfaces_.begin(), interfaces_.end(), a,
                                 [](const Run& r, Id x) { return r.first < x; });
      for (; it != interfaces_.end() && it->first < b; ++it) {
        if (user_sets_[it->users].front() != v) continue;
        for (auto& c : xyz) c.resize(static_cast<size_t>(it->count));
        if (pass.coords)
          run_coords(mesh_, it->first, it->count, cur, ids, pts, xyz[0].data(), xyz[1].data(), xyz[2].data());
        out.range(it->first, it->first + it->count, block_[static_cast<size_t>(i)], pass.coords ? xyz[0].data() : nullptr,
                  pass.coords ? xyz[1].data() : nullptr, pass.coords ? xyz[2].data() : nullptr);
      }
      if ((i & 1023) == 0) poll();
      ++i;
      continue;
    }
    // A stretch [i, j) of elements the pass takes whole.
    Id j = i + 1;
    while (j < span && (v < 0 || block_[static_cast<size_t>(j)] == v)) ++j;
    if (!pass.coords) {
      for (Id e = i; e < j; ++e) {
        const Id a = node_first_[static_cast<size_t>(e)], b = node_first_[static_cast<size_t>(e) + 1];
        for (Id p = a; p < b; p += kSpanNodes) {
          out.range(p, std::min(b, p + kSpanNodes), block_[static_cast<size_t>(e)], nullptr, nullptr, nullptr);
          if (b - a > kSpanNodes) poll();  // one element can own 10^12 nodes: a signal must not wait for it
        }
        if ((e & 1023) == 0) poll();
      }
    } else {
      for_each_batch(mesh_, first + i, first + j, true, false, [&](Id done) { step(done); }, [&](const FineBatch& b) {
        out.range(b.node_begin, b.node_end, b.block, b.x.data(), b.y.data(), b.z.data());
      });
    }
    i = j;
  }
}

void ChunkStream::elements(const ElementPass& pass, const std::function<void(const ElementSpan&)>& fn) const {
  const Id first = range_.first_coarse, span = range_.end_coarse - first;
  const Id e0 = element_first_.front(), own0 = range_.node_begin, ng = num_ghosts();
  std::vector<Id> global, local;
  for (Id i = 0; i < span;) {
    if (pass.block >= 0 && block_[static_cast<size_t>(i)] != pass.block) {
      ++i;
      continue;
    }
    Id j = i + 1;
    while (j < span && (pass.block < 0 || block_[static_cast<size_t>(j)] == pass.block)) ++j;
    for_each_batch(mesh_, first + i, first + j, false, true, [&](Id done) { step(done); }, [&](const FineBatch& batch) {
      const auto n = static_cast<size_t>(batch.num_elements());
      if (global.size() < n) global.resize(n);
      std::iota(global.begin(), global.begin() + static_cast<std::ptrdiff_t>(n), batch.element_begin);
      ElementSpan out;
      out.first = batch.element_begin - e0, out.count = batch.num_elements();
      out.global = global.data(), out.block = batch.block;
      if (pass.global_conn) {
        out.conn = batch.conn.data();
      } else {
        // Own nodes map by an offset (a loop without branches); the few
        // ghosts are looked up afterwards.
        local.resize(batch.conn.size());
        const Id shift = ng - own0, own_end = range_.node_end;
        bool ghosts = false;
        for (size_t q = 0; q < local.size(); ++q) {
          const Id id = batch.conn[q];
          local[q] = id + shift;
          ghosts |= (id < own0) | (id >= own_end);
        }
        if (ghosts)
          for (size_t q = 0; q < local.size(); ++q) {
            const Id id = batch.conn[q];
            if (id >= own0 && id < own_end) continue;
            local[q] = local_of(id);
            if (local[q] < 0)
              throw Error(ErrorKind::Corrupt, where() + ": element " + std::to_string(global[q / batch.corners]) +
                                                  " uses node " + std::to_string(id) + ", which its chunk does not hold");
          }
        out.conn = local.data();
      }
      fn(out);
    });
    i = j;
  }
}

}  // namespace dicer
