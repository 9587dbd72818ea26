// Gmsh MSH 4.1 writer (ASCII and binary) for one chunk (ChunkSource).
//
// Layout of the file (Gmsh reference manual, "MSH file format"):
//  - $MeshFormat "4.1 0 8" or "4.1 1 8" + the binary int 1 (byte order).
//  - $PhysicalNames (always ASCII): one per block of the mesh (dim 3, or 2 in
//    surface mode) named as the block or "block <id>"; one per side set of
//    the chunk (dim 2, or 1 in surface mode) named as the set or
//    "sideset <id>". Names are cut to the format's 127 characters; a '"' in
//    a name becomes '\'' and a line break a space (the format cannot quote).
//    Physical group 0 (a block or set of id 0) is not named: Gmsh 4.8's
//    reader puts a name given to tag 0 on group 1.
//  - $Entities: one volume (surface) per block with elements in the chunk,
//    tag = the block's index in the mesh + 1; one surface (curve) per side
//    set with members in the chunk, tag = the set's index + 1. The tags are
//    the mesh's, not the chunk's, so chunk files merged in Gmsh keep each
//    entity's physical group (tags counted per chunk put block 76 on the
//    entity of block 1). Each carries one physical tag; bounding boxes are
//    those of the entity's nodes. No BRep boundaries (points, bounding
//    entities) are written.
//  - $Nodes: every node of the chunk, node tag = global id + 1, each in the
//    block entity of the lowest-tagged entity whose elements use it (Gmsh
//    classifies a node on exactly one entity; elements of other entities may
//    reference it). Within an entity block nodes are in global id order.
//  - $Elements: per block entity, its hexes (type 5; quads, type 3, in
//    surface mode) in global id order, tag = global element id + 1, node
//    tags = global node ids + 1 (Gmsh's linear hex/quad corner order is the
//    VTK/Exodus one). Then per side set entity its boundary quads (type 3;
//    lines, type 1, in surface mode) with the fine element's side corners in
//    Exodus order: kHexSideCorners for hexes, edges (0,1) (1,2) (2,3) (3,0)
//    for shell sides 2..5. Shell face sides 0 and 1 (the quad itself) are
//    skipped: they are not of the set entity's dimension.
//    Boundary element tags are above every volume element tag of the whole
//    mesh and the same in every chunk, so chunk files can be merged:
//    E + 1 + 6 * (set_index * E + global_element) + side, E = fine elements
//    of the mesh (sparse tags are allowed by the format).
// Node sets are not written (MSH has none; `dicer export` says so).
// Physical tags: the block (side set) id when it is an int >= 0 that no
// earlier block (set) took, else the next free tag above the largest one.
// 0 is a group in MSH 4.1 (Gmsh reads it so; deal.ii's default boundary id).
//
// Streaming: the sections need counts and boxes before their records, so
// the writer makes passes over the source (export.hpp): nodes without
// coordinates (counts per entity, the tag range), nodes with coordinates
// (the entities' boxes), then per entity its tags and its coordinates, then
// per block entity its elements; side-set elements come from one more pass
// over the elements when a set has members, and are the only records held
// (O(set sizes)). A chunk's nodes on a boundary between blocks are known
// to the source as runs (ChunkSource::user_sets), so nothing is ordered or
// held per node. Output goes through a 1 MiB buffer to the file
// descriptor; every write is checked; the file is written through
// AtomicOutput and removed on any error.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "dicer/atomic_output.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"

namespace dicer {
namespace {

constexpr int kMshHex = 5, kMshQuad = 3, kMshLine = 1;
constexpr std::size_t kBufferBytes = std::size_t{1} << 20;
// Written bytes handed to the disk (sync_file_range) each time this many
// more are written: the disk works while the mesh is generated, so the
// final fsync (AtomicOutput::commit) waits for the last stretch only.
constexpr std::uint64_t kWriteBehindBytes = std::uint64_t{32} << 20;

// A value's bytes at p (native order; p need not be aligned).
template <class T>
inline void store(char* p, T v) {
  std::memcpy(p, &v, sizeof v);
}

// Buffered, checked output to a file descriptor; ASCII or binary values.
class Out {
 public:
  Out(int fd, std::string where, bool binary) : fd_(fd), where_(std::move(where)), binary_(binary) {
    buf_.resize(kBufferBytes);
  }
  bool binary() const { return binary_; }

  // Bytes written so far (the file offset of the next byte).
  std::uint64_t offset() const { return flushed_ + used_; }

  // Room for n <= kBufferBytes bytes that the caller fills now.
  char* room(std::size_t n) {
    if (buf_.size() - used_ < n) flush();
    char* p = buf_.data() + used_;
    used_ += n;
    return p;
  }

  void raw(const void* p, std::size_t n) {
    if (n <= buf_.size() - used_) {  // the common case: one copy
      std::memcpy(buf_.data() + used_, p, n);
      used_ += n;
      return;
    }
    const char* c = static_cast<const char*>(p);
    while (n > 0) {
      if (used_ == buf_.size()) flush();
      const std::size_t k = std::min(n, buf_.size() - used_);
      std::memcpy(buf_.data() + used_, c, k);
      used_ += k, c += k, n -= k;
    }
  }
  void text(std::string_view s) { raw(s.data(), s.size()); }

  // Binary: the value's bytes (native order, announced by the int 1).
  template <class T>
  void bin(T v) {
    raw(&v, sizeof v);
  }
  // ASCII integer / double (shortest text that reads back to the same bits).
  template <class T>
  void num(T v) {
    char s[40];
    const auto r = std::to_chars(s, s + sizeof s, v);
    raw(s, static_cast<std::size_t>(r.ptr - s));
  }
  void real(double v) {
    char s[40];
    const auto r = std::to_chars(s, s + sizeof s, v);
    raw(s, static_cast<std::size_t>(r.ptr - s));
  }

  // A size_t, int or double field, followed (ASCII) by `sep`.
  void size(std::uint64_t v, char sep = ' ') {
    if (binary_) {
      bin(static_cast<std::size_t>(v));
    } else {
      num(v);
      raw(&sep, 1);
    }
  }
  void integer(std::int32_t v, char sep = ' ') {
    if (binary_) {
      bin(v);
    } else {
      num(v);
      raw(&sep, 1);
    }
  }
  void dbl(double v, char sep = ' ') {
    if (binary_) {
      bin(v);
    } else {
      real(v);
      raw(&sep, 1);
    }
  }

  void flush() {
    std::size_t done = 0;
    while (done < used_) {
      const ssize_t w = ::write(fd_, buf_.data() + done, used_ - done);
      if (w < 0) {
        if (errno == EINTR) continue;
        fail("write failed: " + std::string(std::strerror(errno)));
      }
      if (w == 0) fail("write failed: no bytes written");
      done += static_cast<std::size_t>(w);
    }
    flushed_ += used_;
    used_ = 0;
    if (flushed_ - synced_ >= kWriteBehindBytes) {
      // A hint: where the kernel cannot, the final fsync does it all.
      ::sync_file_range(fd_, static_cast<off_t>(synced_), static_cast<off_t>(flushed_ - synced_), SYNC_FILE_RANGE_WRITE);
      synced_ = flushed_;
    }
  }
  // Rewrites bytes already flushed at `at` (the entity boxes).
  void patch(std::uint64_t at, const void* p, std::size_t n) {
    flush();
    if (::pwrite(fd_, p, n, static_cast<off_t>(at)) != static_cast<ssize_t>(n))
      fail("write failed: " + std::string(std::strerror(errno)));
  }
  void close() {
    flush();
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) fail("close failed: " + std::string(std::strerror(errno)));
  }
  ~Out() {
    if (fd_ >= 0) ::close(fd_);
  }
  [[noreturn]] void fail(const std::string& what) const { throw Error(ErrorKind::Io, where_ + ": " + what); }

 private:
  int fd_;
  std::string where_;
  bool binary_;
  std::vector<char> buf_;
  std::size_t used_ = 0;
  std::uint64_t flushed_ = 0, synced_ = 0;
};

struct BBox {
  double lo[3] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                  std::numeric_limits<double>::infinity()};
  double hi[3] = {-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                  -std::numeric_limits<double>::infinity()};
  void add(double x, double y, double z) {
    const double p[3] = {x, y, z};
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
  }
  void finish() {
    for (int a = 0; a < 3; ++a)
      if (lo[a] > hi[a]) lo[a] = hi[a] = 0;
  }
};

struct Entity {
  int tag = 0;
  int physical = 0;
  std::size_t source = 0;  // block index or side set index
  std::uint64_t count = 0; // elements
  BBox box;
};

// Physical tags: the id when >= 0, fitting an int and not taken yet;
// otherwise the next free tag above the largest one.
std::vector<int> physical_tags(const std::vector<std::int64_t>& ids) {
  std::vector<int> out(ids.size(), -1);
  std::set<std::int64_t> used;
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (ids[i] >= 0 && ids[i] <= std::numeric_limits<std::int32_t>::max() && used.insert(ids[i]).second)
      out[i] = static_cast<int>(ids[i]);
  std::int64_t next = used.empty() ? 1 : *used.rbegin() + 1;
  for (auto& t : out)
    if (t < 0) {
      while (used.count(next)) ++next;
      if (next > std::numeric_limits<std::int32_t>::max())
        throw Error(ErrorKind::Overflow, "MSH physical tags do not fit an int");
      used.insert(next);
      t = static_cast<int>(next);
    }
  return out;
}

std::string msh_name(std::string s) {
  for (char& c : s)
    if (c == '"') c = '\'';
    else if (c == '\n' || c == '\r') c = ' ';
  if (s.size() > 127) s.resize(127);
  return s;
}

// Corners (ids from `conn`, the element's corners) of side `side`, Exodus
// order; 0 when the side is not written (shell faces 0/1, bad side).
int side_corners(Mode mode, const Id* conn, int side, Id out[4]) {
  if (!msh_writes_side(mode, side)) return 0;
  if (mode == Mode::Volume) {
    for (int q = 0; q < 4; ++q) out[q] = conn[kHexSideCorners[side][q]];
    return 4;
  }
  const int a = side - 2;
  out[0] = conn[a], out[1] = conn[(a + 1) % 4];
  return 2;
}

// A side set's written boundary elements: tag and corner node tags.
struct SideElements {
  std::vector<std::uint64_t> tag;
  std::vector<std::uint64_t> node;  // k per element, global id + 1
};

void write_body(const ChunkSource& c, Out& o) {
  const bool vol = c.mode() == Mode::Volume;
  const int dim = vol ? 3 : 2;
  const int nc = c.corners(), k_side = vol ? 4 : 2;
  const Id nn = c.num_nodes(), ne = c.num_elements();
  const auto E = static_cast<std::uint64_t>(c.mesh().num_elements());
  const auto& blocks = c.mesh().info().blocks;
  const auto& sets = c.side_sets();
  const auto& users = c.user_sets();

  // Physical tags.
  std::vector<std::int64_t> ids;
  for (const auto& b : blocks) ids.push_back(b.id);
  const std::vector<int> block_phys = physical_tags(ids);
  ids.clear();
  for (const auto& s : sets) ids.push_back(s.id);
  const std::vector<int> set_phys = physical_tags(ids);

  // Block entities, in block order, for blocks with elements in the chunk.
  const std::vector<Id> per_block = c.block_counts();
  std::vector<Entity> vents;
  std::vector<int> entity_of_block(blocks.size(), -1);
  for (std::size_t b = 0; b < blocks.size(); ++b)
    if (per_block[b] > 0) {
      entity_of_block[b] = static_cast<int>(vents.size());
      vents.push_back({static_cast<int>(b) + 1, block_phys[b], b, static_cast<std::uint64_t>(per_block[b]), {}});
    }
  const bool no_elements = vents.empty();
  if (no_elements && nn > 0) {
    if (blocks.empty()) o.fail("chunk has nodes but the mesh has no blocks");
    vents.push_back({1, block_phys[0], 0, 0, {}});
  }
  // A node's entity: the lowest-tagged one whose elements use it (entities
  // are in block order, so the lowest using block's).
  auto entity_of = [&](std::uint32_t u) {
    if (no_elements) return 0;
    const int e = entity_of_block[static_cast<std::size_t>(users[u].front())];
    if (e < 0) o.fail("a node's using block has no elements in the chunk");
    return e;
  };

  // Side-set boundary elements, from one pass over the elements (global
  // connectivity) when a set has members.
  std::vector<SideElements> side(sets.size());
  bool any_side = false;
  for (const auto& s : sets) any_side |= !s.element.empty();
  // Passes with coordinates or connectivity: the side elements', the boxes'
  // (ASCII), the coordinates', the elements'.
  c.expect_passes(2 + (any_side ? 1 : 0) + (o.binary() ? 0 : 1));
  if (any_side) {
    std::vector<std::size_t> at(sets.size(), 0);
    c.elements({-1, true}, [&](const ElementSpan& span) {
      for (std::size_t s = 0; s < sets.size(); ++s) {
        const auto& m = sets[s];
        for (std::size_t& q = at[s]; q < m.element.size() && m.element[q] < span.first + span.count; ++q) {
          const Id l = m.element[q] - span.first;
          if (l < 0) o.fail("side set members out of order");
          Id corner[4];
          const int k = side_corners(c.mode(), span.conn + l * nc, m.side[q], corner);
          if (k == 0) continue;
          const auto eg = static_cast<std::uint64_t>(span.global[l]);
          side[s].tag.push_back(E + 1 + 6 * (static_cast<std::uint64_t>(s) * E + eg) + static_cast<std::uint64_t>(m.side[q]));
          for (int a = 0; a < k; ++a) side[s].node.push_back(static_cast<std::uint64_t>(corner[a]) + 1);
        }
      }
    });
  }
  std::vector<Entity> sents;
  for (std::size_t s = 0; s < sets.size(); ++s)
    if (!side[s].tag.empty()) sents.push_back({static_cast<int>(s) + 1, set_phys[s], s, side[s].tag.size(), {}});

  // Nodes per entity, and the node tag range (ids only).
  std::vector<std::uint64_t> nodes_in(vents.size(), 0);
  Id lo_node = -1, hi_node = -1;
  c.nodes({false, -1}, [&](const NodeSpan& span) {
    for (Id q = 0; q < span.count; ++q) ++nodes_in[static_cast<std::size_t>(entity_of(span.users[q]))];
    if (span.count > 0) {
      if (lo_node < 0) lo_node = span.global[0];
      hi_node = span.global[span.count - 1];
    }
  });

  // Bounding boxes: a block entity's holds every node its elements use; a
  // side set entity's the corners of its boundary elements, found by a
  // merge (both ascend by global id within a pass). ASCII: one pass with
  // coordinates first; binary: during the $Nodes section's coordinate
  // passes, the boxes written in $Entities then patched in place.
  std::vector<std::pair<Id, std::size_t>> corner_set;  // (global id, side entity)
  for (std::size_t v = 0; v < sents.size(); ++v)
    for (std::uint64_t t : side[sents[v].source].node) corner_set.emplace_back(static_cast<Id>(t) - 1, v);
  std::sort(corner_set.begin(), corner_set.end());
  corner_set.erase(std::unique(corner_set.begin(), corner_set.end()), corner_set.end());
  std::size_t next_corner = 0;
  auto add_boxes = [&](const NodeSpan& span) {
    const bool one = !no_elements && users[span.users[0]].size() == 1 &&
                     std::all_of(span.users, span.users + span.count, [&](std::uint32_t u) { return u == span.users[0]; });
    if (one || no_elements) {  // one entity for the whole span
      BBox& box = vents[no_elements ? 0 : static_cast<std::size_t>(entity_of(span.users[0]))].box;
      for (Id q = 0; q < span.count; ++q) box.add(span.x[q], span.y[q], span.z[q]);
    } else {
      for (Id q = 0; q < span.count; ++q)
        for (const std::int32_t b : users[span.users[q]])
          vents[static_cast<std::size_t>(entity_of_block[static_cast<std::size_t>(b)])].box.add(span.x[q], span.y[q],
                                                                                                span.z[q]);
    }
    if (corner_set.empty()) return;
    for (Id q = 0; q < span.count; ++q)
      for (; next_corner < corner_set.size() && corner_set[next_corner].first <= span.global[q]; ++next_corner)
        if (corner_set[next_corner].first == span.global[q])
          sents[corner_set[next_corner].second].box.add(span.x[q], span.y[q], span.z[q]);
  };
  if (!o.binary()) {
    c.nodes({true, -1}, add_boxes);
    for (auto& v : vents) v.box.finish();
    for (auto& v : sents) v.box.finish();
  }

  // $MeshFormat.
  o.text(o.binary() ? "$MeshFormat\n4.1 1 8\n" : "$MeshFormat\n4.1 0 8\n");
  if (o.binary()) {
    o.bin(std::int32_t{1});
    o.text("\n");
  }
  o.text("$EndMeshFormat\n");

  // $PhysicalNames (ASCII in both modes).
  // Group 0 goes unnamed (see the top).
  o.text("$PhysicalNames\n");
  o.num(std::count_if(block_phys.begin(), block_phys.end(), [](int t) { return t != 0; }) +
        std::count_if(set_phys.begin(), set_phys.end(), [](int t) { return t != 0; }));
  o.text("\n");
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    if (block_phys[b] == 0) continue;
    o.num(dim), o.text(" "), o.num(block_phys[b]), o.text(" \"");
    o.text(msh_name(blocks[b].name.empty() ? "block " + std::to_string(blocks[b].id) : blocks[b].name));
    o.text("\"\n");
  }
  for (std::size_t s = 0; s < sets.size(); ++s) {
    if (set_phys[s] == 0) continue;
    o.num(dim - 1), o.text(" "), o.num(set_phys[s]), o.text(" \"");
    o.text(msh_name(sets[s].name.empty() ? "sideset " + std::to_string(sets[s].id) : sets[s].name));
    o.text("\"\n");
  }
  o.text("$EndPhysicalNames\n");

  // $Entities.
  o.text("$Entities\n");
  const std::uint64_t n_lower = sents.size(), n_upper = vents.size();
  o.size(0);                                   // points
  o.size(vol ? 0 : n_lower);                   // curves
  o.size(vol ? n_lower : n_upper);             // surfaces
  o.size(vol ? n_upper : 0, '\n');             // volumes
  std::vector<std::uint64_t> box_at;  // binary: where each entity's box is, sents then vents
  auto entity = [&](const Entity& en) {
    o.integer(en.tag);
    box_at.push_back(o.offset());
    for (int a = 0; a < 3; ++a) o.dbl(en.box.lo[a]);
    for (int a = 0; a < 3; ++a) o.dbl(en.box.hi[a]);
    o.size(1);
    o.integer(en.physical);
    o.size(0, '\n');  // no bounding entities
  };
  for (const auto& en : sents) entity(en);  // dim - 1 comes first
  for (const auto& en : vents) entity(en);
  o.text(o.binary() ? "\n$EndEntities\n" : "$EndEntities\n");

  // $Nodes: one entity block per volume (surface) entity that holds nodes,
  // its tags (ids only), then its coordinates.
  std::size_t node_blocks = 0;
  for (std::uint64_t n : nodes_in) node_blocks += n > 0;
  o.text("$Nodes\n");
  o.size(node_blocks);
  o.size(static_cast<std::uint64_t>(nn));
  o.size(nn > 0 ? static_cast<std::uint64_t>(lo_node) + 1 : 0);
  o.size(nn > 0 ? static_cast<std::uint64_t>(hi_node) + 1 : 0, '\n');
  for (std::size_t v = 0; v < vents.size(); ++v) {
    if (nodes_in[v] == 0) continue;
    o.integer(dim);
    o.integer(vents[v].tag);
    o.integer(0);  // no parametric coordinates
    o.size(nodes_in[v], '\n');
    const ChunkSource::NodePass tags{false, no_elements ? -1 : static_cast<std::int32_t>(vents[v].source)};
    std::uint64_t written = 0;
    c.nodes(tags, [&](const NodeSpan& span) {
      written += static_cast<std::uint64_t>(span.count);
      if (!o.binary()) {
        for (Id q = 0; q < span.count; ++q) o.size(static_cast<std::uint64_t>(span.global[q]) + 1, '\n');
        return;
      }
      for (Id q = 0; q < span.count;) {  // straight into the buffer
        const Id n = std::min<Id>(span.count - q, kBufferBytes / sizeof(std::size_t));
        char* t = o.room(static_cast<std::size_t>(n) * sizeof(std::size_t));
        for (Id i = 0; i < n; ++i) store(t + 8 * i, static_cast<std::size_t>(span.global[q + i]) + 1);
        q += n;
      }
    });
    next_corner = 0;
    c.nodes({true, tags.lowest_user}, [&](const NodeSpan& span) {
      if (!o.binary()) {
        for (Id q = 0; q < span.count; ++q) o.dbl(span.x[q]), o.dbl(span.y[q]), o.dbl(span.z[q], '\n');
        return;
      }
      add_boxes(span);
      for (Id q = 0; q < span.count;) {  // x y z per node, straight into the buffer
        const Id n = std::min<Id>(span.count - q, kBufferBytes / (3 * sizeof(double)));
        char* p = o.room(static_cast<std::size_t>(n) * 3 * sizeof(double));
        for (Id i = 0; i < n; ++i, p += 24) store(p, span.x[q + i]), store(p + 8, span.y[q + i]), store(p + 16, span.z[q + i]);
        q += n;
      }
    });
    if (written != nodes_in[v]) o.fail("an entity's node count changed between passes");
  }
  o.text(o.binary() ? "\n$EndNodes\n" : "$EndNodes\n");
  if (o.binary()) {  // the boxes, now known
    std::size_t k = 0;
    for (auto* list : {&sents, &vents})
      for (Entity& en : *list) {
        en.box.finish();
        const double b[6] = {en.box.lo[0], en.box.lo[1], en.box.lo[2], en.box.hi[0], en.box.hi[1], en.box.hi[2]};
        o.patch(box_at[k++], b, sizeof b);
      }
  }

  // $Elements.
  std::uint64_t n_elems = static_cast<std::uint64_t>(ne), min_tag = std::numeric_limits<std::uint64_t>::max(),
                max_tag = 0;
  if (ne > 0) {
    const auto range = c.element_ids();
    min_tag = static_cast<std::uint64_t>(range[0]) + 1, max_tag = static_cast<std::uint64_t>(range[1]) + 1;
  }
  for (const auto& en : sents) {
    n_elems += en.count;
    for (std::uint64_t t : side[en.source].tag) min_tag = std::min(min_tag, t), max_tag = std::max(max_tag, t);
  }
  if (n_elems == 0) min_tag = 0;
  o.text("$Elements\n");
  std::size_t elem_blocks = 0;
  for (const auto& v : vents) elem_blocks += v.count > 0;
  o.size(elem_blocks + sents.size());
  o.size(n_elems);
  o.size(min_tag);
  o.size(max_tag, '\n');
  for (const auto& v : vents) {
    if (v.count == 0) continue;
    o.integer(dim);
    o.integer(v.tag);
    o.integer(vol ? kMshHex : kMshQuad);
    o.size(v.count, '\n');
    c.elements({static_cast<std::int32_t>(v.source), true}, [&](const ElementSpan& span) {
      if (!o.binary()) {
        for (Id e = 0; e < span.count; ++e) {
          const Id* nodes = span.conn + e * nc;
          o.size(static_cast<std::uint64_t>(span.global[e]) + 1);
          for (int q = 0; q < nc; ++q) o.size(static_cast<std::uint64_t>(nodes[q]) + 1, q + 1 == nc ? '\n' : ' ');
        }
        return;
      }
      const auto rec = static_cast<std::size_t>(nc + 1);  // the tag and the node tags
      for (Id e = 0; e < span.count;) {  // straight into the buffer
        const Id n = std::min<Id>(span.count - e, kBufferBytes / (rec * sizeof(std::size_t)));
        char* t = o.room(static_cast<std::size_t>(n) * rec * sizeof(std::size_t));
        for (Id i = 0; i < n; ++i, t += rec * sizeof(std::size_t)) {
          const Id* nodes = span.conn + (e + i) * nc;
          store(t, static_cast<std::size_t>(span.global[e + i]) + 1);
          for (int q = 0; q < nc; ++q) store(t + 8 * (q + 1), static_cast<std::size_t>(nodes[q]) + 1);
        }
        e += n;
      }
    });
  }
  for (const auto& en : sents) {
    const SideElements& se = side[en.source];
    o.integer(dim - 1);
    o.integer(en.tag);
    o.integer(vol ? kMshQuad : kMshLine);
    o.size(en.count, '\n');
    for (std::size_t m = 0; m < se.tag.size(); ++m) {
      o.size(se.tag[m]);
      for (int q = 0; q < k_side; ++q) o.size(se.node[m * k_side + q], q + 1 == k_side ? '\n' : ' ');
    }
  }
  o.text(o.binary() ? "\n$EndElements\n" : "$EndElements\n");
}

}  // namespace

void commit_or_pend(PendingFile& file, PendingFile* pending) {
  if (!pending) return file->commit();
  file->park();
  *pending = std::move(file);
}

bool msh_writes_side(Mode mode, int side) {
  return mode == Mode::Volume ? side >= 0 && side <= 5 : side >= 2 && side <= 5;
}

void write_msh(const ChunkSource& chunk, const std::string& path, bool binary, PendingFile* pending) {
  namespace fs = std::filesystem;
  // Boundary element tags must fit: E + 6 * (S * E + E) + 6 < 2^63.
  const auto E = static_cast<unsigned __int128>(chunk.mesh().num_elements());
  const auto S = static_cast<unsigned __int128>(chunk.side_sets().size());
  if (E + 6 * (S * E + E) + 7 > static_cast<unsigned __int128>(std::numeric_limits<std::int64_t>::max()))
    throw Error(ErrorKind::Overflow, path + ": MSH boundary element tags do not fit 64 bits");

  auto out = std::make_unique<AtomicOutput>(path);
  const int fd = ::open(out->temp_path().c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(ErrorKind::Io, path + ": cannot create " + out->temp_path() + ": " + std::strerror(errno));
  try {
    Out o(fd, path, binary);
    write_body(chunk, o);
    o.close();
    commit_or_pend(out, pending);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(ErrorKind::Io, path + ": " + e.what());
  }
}

}  // namespace dicer
