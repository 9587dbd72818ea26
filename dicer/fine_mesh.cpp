// The implicit fine mesh: random access by id. Evaluation lives in
// evaluate.cpp, block filling in fill.cpp, iteration in cursors.cpp,
// dicing in compile.cpp.
#include "dicer/fine_mesh.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <fstream>

#include "dicer/error.hpp"
#include "dicer/orientation.hpp"
#include "evaluate.hpp"

namespace dicer {

FineMesh::FineMesh(MeshInfo info, MeshTables tables, std::shared_ptr<const CoarseMesh> coarse)
    : info_(std::move(info)), tables_(std::move(tables)), coarse_(std::move(coarse)) {
  // The id searches' columns, dense in memory as a store's loader lays them
  // out per page (rows.hpp search_first).
  if (tables_.elements.in_memory()) {
    tables_.elements.derive_in_memory(element_search_columns(tables_.mode));
    tables_.node_guide = build_id_guide(tables_, true);
    tables_.element_guide = build_id_guide(tables_, false);
  } else {
    tables_.node_page_guide = build_page_guide(tables_.node_index, tables_.fine_nodes);
    tables_.element_page_guide = build_page_guide(tables_.element_index, tables_.fine_elements);
    if (tables_.elements.kept_resident())
      tables_.node_row_guide =
          make_lazy_guide(tables_.elements.rows(), tables_.fine_nodes, static_cast<Id>(tables_.node_index.size()));
  }
}

Vec3 FineMesh::node(Id id) const {
  MeshCursor cur;
  return node(id, cur);
}

namespace {

std::string ids_of(Id count, const char* what) {
  return " (the mesh has " + std::to_string(count) + " " + what + "s, ids 0.." + std::to_string(count - 1) + ")";
}

[[noreturn]] void out_of_range(Id id, Id count, const char* what) {
  throw Error(ErrorKind::Usage, std::string(what) + " id " + std::to_string(id) + " is out of range" + ids_of(count, what));
}

// Ids [begin, end) of `what`s in a mesh of `count`: the first one that is
// not an id, or an empty range past the end.
void check_range(Id begin, Id end, Id count, const char* what) {
  if (begin >= 0 && begin <= end && end <= count) return;
  if (begin < 0) out_of_range(begin, count, what);
  if (end < begin || begin == end)
    throw Error(ErrorKind::Usage, std::string(what) + " ids " + std::to_string(begin) + ":" + std::to_string(end) + ": " +
                                      (end < begin ? "the end is below the start" : "an empty range past the end") +
                                      ids_of(count, what));
  out_of_range(begin < 0 ? begin : std::max(begin, count), count, what);
}

void check_node_id(const FineMesh& m, Id id) {
  if (id < 0 || id >= m.num_nodes()) out_of_range(id, m.num_nodes(), "node");
}

void check_element_id(const FineMesh& m, Id id) {
  if (id < 0 || id >= m.num_elements()) out_of_range(id, m.num_elements(), "element");
}

// Node `ref` of element hid (its row h), which owns it at `owner`'s slot.
// The owner's row is decoded already: cell interiors, and the boundary of a
// straight owner, come from it and its corners alone (`corners`: read
// already, or nullptr).
Vec3 owned_point(const detail::Evaluator& E, const ElementRow& h, Id hid, const NodeRef& ref, const NodeOwner& owner,
                 const Vec3* corners) {
  if (ref.kind == EntityKind::Cell) return E.cell_point(h, hid, ref.local[0], ref.local[1], ref.local[2], corners);
  if (!h.curved()) return E.straight_owned_point(h, hid, owner.slot, ref, corners);
  return E.node(ref);
}

// Whether every corner of hex cell ijk of element h lies inside h.
bool interior_cell(const ElementRow& h, const std::array<Id, 3>& ijk) {
  const auto [i, j, k] = ijk;
  return i > 0 && j > 0 && k > 0 && i + 1 < h.n[0] && j + 1 < h.n[1] && k + 1 < h.n[2];
}

// The corner node ids of fine element el.ijk of element h.
void element_corners(const detail::Evaluator& E, const ElementRow& h, Mode mode, FineElement& el) {
  const auto [i, j, k] = el.ijk;
  const bool vol = mode == Mode::Volume;
  el.block = h.block;
  el.num_nodes = vol ? 8 : 4;
  if (vol && interior_cell(h, el.ijk)) {
    // Every corner inside the cell (most elements at large intervals): the
    // cell's own ids, with no entity lookup per corner.
    for (int q = 0; q < 8; ++q)
      el.nodes[q] = ids::cell_node(h.cell_node, h.n, i + kHexCorner[q][0], j + kHexCorner[q][1], k + kHexCorner[q][2]);
    return;
  }
  if (vol) return E.hex_cell_node_ids(h, i, j, k, el.nodes.data());
  for (int q = 0; q < el.num_nodes; ++q) el.nodes[q] = E.grid_node_id(h, i + kHexCorner[q][0], j + kHexCorner[q][1], 0);
}

// The order to visit ids in (Usage error unless `room` == ids.size()):
// increasing. `order` gets (id, position) pairs
// sorted by id, unless the ids are sorted already (returns true, order
// left empty). An LSD radix sort, 11 bits a pass over only the bits the
// largest id uses, instead of std::sort: ~5x faster on 65,536 random ids
// (bench_store BM_RandomNodeBatch), where std::sort of an index cost more
// than the queries it grouped. Ids are range-checked afterwards, in this
// order; a radix sort would put negative ids last (their top bits), so a
// list holding one goes to std::sort instead, and the lowest bad id is the
// one reported.
struct Visit {
  Id id;
  size_t at;
};

bool visit_order(const char* what, std::span<const Id> ids, size_t room, std::vector<Visit>& order) {
  if (room != ids.size())
    throw Error(ErrorKind::Usage, std::string(what) + "(): " + std::to_string(ids.size()) + " ids but room for " +
                                      std::to_string(room) + " results");
  if (std::is_sorted(ids.begin(), ids.end())) return true;
  const size_t n = ids.size();
  order.resize(n);
  Id top = 0;
  bool negative = false;
  for (size_t q = 0; q < n; ++q) {
    order[q] = Visit{ids[q], q};
    top |= ids[q];
    negative |= ids[q] < 0;
  }
  if (negative) {
    std::sort(order.begin(), order.end(), [](const Visit& a, const Visit& b) { return a.id < b.id; });
    return false;
  }
  constexpr int kBits = 11;
  constexpr size_t kBuckets = size_t{1} << kBits;
  std::vector<Visit> other(n);
  std::vector<size_t> count(kBuckets);
  for (int shift = 0; shift < 63 && (top >> shift) != 0; shift += kBits) {
    std::fill(count.begin(), count.end(), 0);
    for (const Visit& v : order) ++count[static_cast<size_t>(v.id >> shift) & (kBuckets - 1)];
    size_t sum = 0;
    for (size_t& c : count) {
      const size_t here = c;
      c = sum;
      sum += here;
    }
    for (const Visit& v : order) other[count[static_cast<size_t>(v.id >> shift) & (kBuckets - 1)]++] = v;
    order.swap(other);
  }
  return false;
}
}  // namespace

void FineMesh::check_node_range(Id begin, Id end) const { check_range(begin, end, num_nodes(), "node"); }
void FineMesh::check_element_range(Id begin, Id end) const { check_range(begin, end, num_elements(), "element"); }

Vec3 FineMesh::node(Id id, MeshCursor& cur) const {
  check_node_id(*this, id);
  detail::Uninitialised<ElementRow> storage;  // element_grid / element write every field
  ElementRow& row = *storage;
  const Id hid = owner_element(tables_, id, cur);
  const detail::Evaluator E(tables_, cur);
  // The row and its corners at once: their misses overlap, where reading
  // the grid first and then the corners made them follow each other. (A
  // curved element's boundary nodes do not need the corners: a pin of a
  // page they would not have read, cheap once the cache is warm.)
  E.R.prefetch_element(hid);
  if (mode() == Mode::Volume) {
    // Most nodes lie inside a straight element (two thirds at interval 8,
    // more above): its grid and corners place them, and the row's entity
    // columns stay undecoded.
    E.R.element_grid(hid, row);
    if (!row.curved()) {
      if (id >= row.cell_node && id - row.cell_node < ids::cell_nodes(row.n)) {
        const auto l = ids::cell_local(id - row.cell_node, row.n);
        return E.cell_point(row, hid, l[0], l[1], l[2], nullptr);
      }
    }
  }
  mode() == Mode::Volume ? E.R.element_entities(hid, row) : E.R.element(hid, row);
  NodeOwner owner;
  const NodeRef ref = owned_node(tables_, hid, row, id, cur, &owner);
  return owned_point(E, row, hid, ref, owner, nullptr);
}

void FineMesh::nodes(std::span<const Id> ids, std::span<Vec3> out, MeshCursor& cur) const {
  std::vector<Visit> order;
  const bool sorted = visit_order("nodes", ids, out.size(), order);
  const detail::Evaluator E(tables_, cur);
  detail::Uninitialised<ElementRow> storage;
  ElementRow& row = *storage;
  detail::Uninitialised<Vec3, 8> corners;
  Id hid = -1, lo = 0, hi = 0;  // hid owns ids [lo, hi)
  for (size_t q = 0; q < ids.size(); ++q) {
    const size_t at = sorted ? q : order[q].at;
    const Id id = sorted ? ids[q] : order[q].id;
    if (id < lo || id >= hi) {
      check_node_id(*this, id);
      hid = owner_element(tables_, id, cur);  // checks that element hid + 1 starts past id
      E.R.element(hid, row);
      E.R.corner_xyz(hid, corners.data());
      lo = row.node_first;
      hi = hid + 1 < num_coarse_elements() ? E.R.node_first(hid + 1) : num_nodes();
    }
    NodeOwner owner;
    const NodeRef ref = owned_node(tables_, hid, row, id, cur, &owner);
    out[at] = owned_point(E, row, hid, ref, owner, corners.data());
  }
}

Vec3 FineMesh::node(const NodeRef& ref, MeshCursor& cur) const { return detail::Evaluator(tables_, cur).node(ref); }

std::array<Id, 2> FineMesh::owned_nodes(Id first, Id end, MeshCursor& cur) const {
  if (first < 0 || end > num_coarse_elements() || first > end)
    throw Error(ErrorKind::Usage, "owned_nodes: coarse elements " + std::to_string(first) + ".." + std::to_string(end) +
                                      " outside the mesh");
  const RowReader R(tables_, cur);
  auto at = [&](Id h) { return h < num_coarse_elements() ? R.element(h).node_first : num_nodes(); };
  return {at(first), first == end ? at(first) : at(end)};
}

NodeRef FineMesh::locate_node(Id id, MeshCursor& cur) const { return dicer::locate_node(tables_, id, cur); }
Id FineMesh::node_id(const NodeRef& ref, MeshCursor& cur) const { return dicer::node_id(tables_, ref, cur); }
Id FineMesh::locate_element(Id id, std::array<Id, 3>& ijk, MeshCursor& cur) const {
  return dicer::locate_element(tables_, id, ijk, cur);
}

NodeRef FineMesh::grid_node(Id h, Id i, Id j, Id k, MeshCursor& cur) const {
  const detail::Evaluator E(tables_, cur);
  return E.grid_node(E.R.element(h), h, i, j, k);
}

FineElement FineMesh::element(Id id) const {
  MeshCursor cur;
  return element(id, cur);
}

FineElement FineMesh::element(Id id, MeshCursor& cur) const {
  check_element_id(*this, id);
  FineElement el;
  el.id = id;
  detail::Uninitialised<ElementRow> storage;  // locate_element writes every field
  ElementRow& h = *storage;
  const bool vol = mode() == Mode::Volume;
  // A cell inside the interior (most, at large intervals) takes its node
  // ids from the grid alone (element_corners' first case): no entity
  // columns read.
  el.coarse_element = dicer::locate_element(tables_, id, el.ijk, cur, &h, vol);
  const detail::Evaluator E(tables_, cur);
  if (vol && !interior_cell(h, el.ijk)) E.R.element_entities(el.coarse_element, h);
  element_corners(E, h, mode(), el);
  return el;
}

void FineMesh::elements(std::span<const Id> ids, std::span<FineElement> out, MeshCursor& cur) const {
  std::vector<Visit> order;
  const bool sorted = visit_order("elements", ids, out.size(), order);
  const detail::Evaluator E(tables_, cur);
  detail::Uninitialised<ElementRow> storage;
  ElementRow& row = *storage;
  Id hid = -1, lo = 0, hi = 0;  // hid holds fine elements [lo, hi)
  for (size_t q = 0; q < ids.size(); ++q) {
    const size_t at = sorted ? q : order[q].at;
    const Id id = sorted ? ids[q] : order[q].id;
    FineElement& el = out[at];
    el = FineElement{};
    el.id = id;
    if (id < lo || id >= hi) {
      check_element_id(*this, id);
      hid = dicer::locate_element(tables_, id, el.ijk, cur, &row);  // checks id against the row's elements
      lo = row.element_first;
      hi = lo + row.n[0] * row.n[1] * row.n[2];  // a validated grid: under kMaxElementPoints
    } else {
      el.ijk = ids::element_local(id - lo, row.n);
    }
    el.coarse_element = hid;
    element_corners(E, row, mode(), el);
  }
}

namespace {
std::uint64_t kib_field(const char* file, const std::string& key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key, 0) == 0) return std::strtoull(line.c_str() + key.size(), nullptr, 10) * 1024;
  return UINT64_MAX;
}
}  // namespace

std::uint64_t available_memory_bytes() {
  std::uint64_t avail = kib_field("/proc/meminfo", "MemAvailable:");
  if (avail == UINT64_MAX) {
    const long pages = ::sysconf(_SC_AVPHYS_PAGES), size = ::sysconf(_SC_PAGESIZE);
    if (pages > 0 && size > 0) avail = static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(size);
  }
  // A container's memory limit (Docker, Kubernetes, systemd slices): the
  // kernel kills the group past it, whatever MemAvailable says.
  {
    std::ifstream in("/proc/self/cgroup");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    avail = std::min(avail, detail::cgroup_memory_left(text, "/sys/fs/cgroup"));
  }
  struct rlimit rl {};
  if (::getrlimit(RLIMIT_AS, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY) {
    const std::uint64_t mapped = kib_field("/proc/self/status", "VmSize:");
    const std::uint64_t left = mapped == UINT64_MAX || mapped >= rl.rlim_cur ? 0 : rl.rlim_cur - mapped;
    avail = std::min(avail, left);
  }
  return avail;
}

namespace detail {

std::uint64_t cgroup_memory_left(const std::string& proc_cgroup, const std::string& root) {
  // A file's first word as a byte count; "max" (v2) or a v1 "unlimited"
  // (a page-rounded 2^63 - 1) or no file: no limit.
  auto number = [](const std::string& file) -> std::uint64_t {
    std::ifstream in(file);
    std::string word;
    if (!(in >> word) || word.empty() || word.find_first_not_of("0123456789") != std::string::npos) return UINT64_MAX;
    const std::uint64_t v = std::strtoull(word.c_str(), nullptr, 10);
    return v >= (std::uint64_t{1} << 62) ? UINT64_MAX : v;
  };
  std::uint64_t left = UINT64_MAX;
  // Usage counts the page cache, which the kernel reclaims before it
  // kills: inactive file pages are not spent (as `docker stats` counts).
  auto inactive = [](const std::string& file, const std::string& key) -> std::uint64_t {
    std::ifstream in(file);
    std::string k;
    std::uint64_t v = 0;
    while (in >> k >> v)
      if (k == key) return v;
    return 0;
  };
  // Each group from the process's own up to the mount (a cgroup namespace
  // shows its own group as the mount itself).
  auto walk = [&](const std::string& base, std::string path, const char* limit, const char* usage, const char* stat_key) {
    while (true) {
      const std::string dir = base + path;
      const std::uint64_t max = number(dir + "/" + limit);
      if (max != UINT64_MAX) {
        std::uint64_t used = number(dir + "/" + usage);  // unreadable: unknown, not full
        used = used == UINT64_MAX ? 0 : used - std::min(used, inactive(dir + "/memory.stat", stat_key));
        left = std::min(left, max - std::min(max, used));
      }
      const std::size_t up = path.find_last_of('/');
      if (path.empty() || path == "/" || up == std::string::npos) break;  // paths start with '/'
      path.erase(up);
    }
  };
  std::size_t at = 0;
  while (at < proc_cgroup.size()) {
    std::size_t eol = proc_cgroup.find('\n', at);
    if (eol == std::string::npos) eol = proc_cgroup.size();
    const std::string line = proc_cgroup.substr(at, eol - at);
    at = eol + 1;
    const std::size_t a = line.find(':'), b = a == std::string::npos ? a : line.find(':', a + 1);
    if (b == std::string::npos) continue;
    const std::string controllers = line.substr(a + 1, b - a - 1), path = line.substr(b + 1);
    if (line.compare(0, a, "0") == 0 && controllers.empty()) {
      walk(root, path, "memory.max", "memory.current", "inactive_file");  // v2
    } else {
      std::size_t c = 0;  // v1: "memory" among the comma-separated controllers
      bool memory = false;
      while (c <= controllers.size()) {
        const std::size_t e = std::min(controllers.find(',', c), controllers.size());
        memory |= controllers.compare(c, e - c, "memory") == 0;
        c = e + 1;
      }
      if (memory) walk(root + "/memory", path, "memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file");
    }
  }
  return left;
}

}  // namespace detail

Error element_too_big(const FineMesh& mesh, Id h, const std::array<Id, 3>& n, const char* how, double bytes) {
  char need[64];
  std::snprintf(need, sizeof need, "%.1f GiB", bytes / double(1ull << 30));
  const std::string& origin = mesh.tables().origin;
  return Error(ErrorKind::Usage, (origin.empty() ? std::string("the mesh") : origin) + ": coarse element " +
                                     std::to_string(h) + " (intervals " + std::to_string(n[0]) + " x " +
                                     std::to_string(n[1]) + " x " + std::to_string(n[2]) + ") " + std::string(how) + ", about " +
                                     need + ", more memory than this process can allocate; dice with smaller "
                                     "intervals (more coarse elements), or run where more memory is free");
}

void check_element_memory(const FineMesh& mesh, Id h, const std::array<Id, 3>& n, const char* how,
                          double bytes, double held) {
  const double more = bytes - held;
  if (more > double(1u << 28) && more > static_cast<double>(available_memory_bytes()))
    throw element_too_big(mesh, h, n, how, bytes);
}

std::size_t FineBlock::held_bytes() const {
  auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  std::size_t sum = bytes(node_id) + bytes(x) + bytes(y) + bytes(z) + bytes(conn) + bytes(scratch.boundary.id);
  for (int d = 0; d < 3; ++d) {
    for (int e = 0; e < 12; ++e) sum += bytes(scratch.edge[e][d]);
    for (int f = 0; f < 6; ++f) sum += bytes(scratch.face[f][d]);
    sum += bytes(scratch.bottom[d]) + bytes(scratch.top[d]) + bytes(scratch.left[d]) + bytes(scratch.right[d]) +
           bytes(scratch.boundary.x[d]);
  }
  for (const auto* v : {&scratch.s, &scratch.t, &scratch.u, &scratch.v, &scratch.w, &scratch.P, &scratch.G, &scratch.patch})
    sum += bytes(*v);
  return sum;
}

}  // namespace dicer
