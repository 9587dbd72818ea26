// Gmsh MSH 4.1 writer (ASCII and binary) for one ExportChunk.
//
// Layout of the file (Gmsh reference manual, "MSH file format"):
//  - $MeshFormat "4.1 0 8" or "4.1 1 8" + the binary int 1 (byte order).
//  - $PhysicalNames (always ASCII): one per block of the mesh (dim 3, or 2 in
//    surface mode) named as the block or "block <id>"; one per side set of
//    the chunk (dim 2, or 1 in surface mode) named as the set or
//    "sideset <id>". Names are cut to the format's 127 characters; a '"' in
//    a name becomes '\'' and a line break a space (the format cannot quote).
//  - $Entities: one volume (surface) per block with elements in the chunk,
//    tags 1, 2, ... in block order; one surface (curve) per side set with
//    members in the chunk, tags 1, 2, ... in set order. Each carries one
//    physical tag; bounding boxes are those of the entity's nodes. No BRep
//    boundaries (points, bounding entities) are written.
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
// Physical tags: the block (side set) id when it is a positive int that no
// earlier block (set) took, else the next free tag above the largest one.
//
// Streaming: output goes through a 1 MiB buffer to the file descriptor; the
// only chunk-sized work space is the node/element orderings by entity
// (8 B per node and per element, 4 B per node for its entity). Every write
// is checked; the file is written as ".<name>.tmp-<pid>" in the destination
// folder and renamed when complete, and removed on any error.
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

// Buffered, checked output to a file descriptor; ASCII or binary values.
class Out {
 public:
  Out(int fd, std::string where, bool binary) : fd_(fd), where_(std::move(where)), binary_(binary) {
    buf_.resize(kBufferBytes);
  }
  bool binary() const { return binary_; }

  void raw(const void* p, std::size_t n) {
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
    used_ = 0;
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

// Physical tags: the id when positive, fitting an int and not taken yet;
// otherwise the next free tag above the largest one.
std::vector<int> physical_tags(const std::vector<std::int64_t>& ids) {
  std::vector<int> out(ids.size(), 0);
  std::set<std::int64_t> used;
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (ids[i] > 0 && ids[i] <= std::numeric_limits<std::int32_t>::max() && used.insert(ids[i]).second)
      out[i] = static_cast<int>(ids[i]);
  std::int64_t next = used.empty() ? 1 : *used.rbegin() + 1;
  for (auto& t : out)
    if (t == 0) {
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

// Corners (local node ids) of side `side` of local element e; 0 when the side
// is not written (shell faces 0/1, bad side).
int side_corners(const ExportChunk& c, Id e, int side, Id out[4]) {
  const auto conn = c.connectivity();
  const std::size_t base = static_cast<std::size_t>(e) * static_cast<std::size_t>(c.corners());
  if (c.mode() == Mode::Volume) {
    if (side < 0 || side > 5) return 0;
    for (int q = 0; q < 4; ++q) out[q] = conn[base + kHexSideCorners[side][q]];
    return 4;
  }
  if (side < 2 || side > 5) return 0;
  const int a = side - 2;
  out[0] = conn[base + a], out[1] = conn[base + (a + 1) % 4];
  return 2;
}

void write_body(const ExportChunk& c, Out& o) {
  const bool vol = c.mode() == Mode::Volume;
  const int dim = vol ? 3 : 2;
  const int nc = c.corners();
  const Id nn = c.num_nodes(), ne = c.num_elements();
  const Id E = c.mesh().num_elements();
  const auto& blocks = c.mesh().info().blocks;
  const auto& sets = c.side_sets();
  const auto ng = c.node_global();
  const auto eg = c.element_global();
  const auto eb = c.element_block();
  const auto conn = c.connectivity();
  const auto X = c.x(), Y = c.y(), Z = c.z();

  // Physical tags.
  std::vector<std::int64_t> ids;
  for (const auto& b : blocks) ids.push_back(b.id);
  const std::vector<int> block_phys = physical_tags(ids);
  ids.clear();
  for (const auto& s : sets) ids.push_back(s.id);
  const std::vector<int> set_phys = physical_tags(ids);

  // Block entities, in block order, for blocks with elements in the chunk.
  std::vector<std::uint64_t> per_block(blocks.size(), 0);
  for (Id e = 0; e < ne; ++e) {
    const auto b = eb[static_cast<std::size_t>(e)];
    if (b < 0 || static_cast<std::size_t>(b) >= blocks.size()) o.fail("element block index out of range");
    ++per_block[static_cast<std::size_t>(b)];
  }
  std::vector<Entity> vents;
  std::vector<int> entity_of_block(blocks.size(), -1);
  for (std::size_t b = 0; b < blocks.size(); ++b)
    if (per_block[b] > 0) {
      entity_of_block[b] = static_cast<int>(vents.size());
      vents.push_back({static_cast<int>(vents.size()) + 1, block_phys[b], b, per_block[b], {}});
    }
  if (vents.empty() && nn > 0) {
    if (blocks.empty()) o.fail("chunk has nodes but the mesh has no blocks");
    vents.push_back({1, block_phys[0], 0, 0, {}});
  }

  // Node classification: the lowest entity whose elements use the node.
  std::vector<std::int32_t> node_ent(static_cast<std::size_t>(nn), std::numeric_limits<std::int32_t>::max());
  for (Id e = 0; e < ne; ++e) {
    const int ent = entity_of_block[static_cast<std::size_t>(eb[static_cast<std::size_t>(e)])];
    Entity& v = vents[static_cast<std::size_t>(ent)];
    for (int q = 0; q < nc; ++q) {
      const Id l = conn[static_cast<std::size_t>(e) * nc + q];
      auto& ne_ = node_ent[static_cast<std::size_t>(l)];
      ne_ = std::min(ne_, ent);
      v.box.add(X[l], Y[l], Z[l]);
    }
  }
  for (auto& v : node_ent)
    if (v == std::numeric_limits<std::int32_t>::max()) v = 0;  // unused node (none expected)
  for (Id l = 0; l < nn; ++l)
    if (ne == 0) vents[0].box.add(X[l], Y[l], Z[l]);
  for (auto& v : vents) v.box.finish();

  // Side set entities.
  std::vector<Entity> sents;
  for (std::size_t s = 0; s < sets.size(); ++s) {
    Entity en{static_cast<int>(sents.size()) + 1, set_phys[s], s, 0, {}};
    Id corner[4];
    for (std::size_t m = 0; m < sets[s].element.size(); ++m) {
      const int k = side_corners(c, sets[s].element[m], sets[s].side[m], corner);
      if (k == 0) continue;
      ++en.count;
      for (int q = 0; q < k; ++q) en.box.add(X[corner[q]], Y[corner[q]], Z[corner[q]]);
    }
    if (en.count > 0) {
      en.box.finish();
      sents.push_back(en);
    }
  }

  // $MeshFormat.
  o.text(o.binary() ? "$MeshFormat\n4.1 1 8\n" : "$MeshFormat\n4.1 0 8\n");
  if (o.binary()) {
    o.bin(std::int32_t{1});
    o.text("\n");
  }
  o.text("$EndMeshFormat\n");

  // $PhysicalNames (ASCII in both modes).
  o.text("$PhysicalNames\n");
  o.num(blocks.size() + sets.size());
  o.text("\n");
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    o.num(dim), o.text(" "), o.num(block_phys[b]), o.text(" \"");
    o.text(msh_name(blocks[b].name.empty() ? "block " + std::to_string(blocks[b].id) : blocks[b].name));
    o.text("\"\n");
  }
  for (std::size_t s = 0; s < sets.size(); ++s) {
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
  auto entity = [&](const Entity& en) {
    o.integer(en.tag);
    for (int a = 0; a < 3; ++a) o.dbl(en.box.lo[a]);
    for (int a = 0; a < 3; ++a) o.dbl(en.box.hi[a]);
    o.size(1);
    o.integer(en.physical);
    o.size(0, '\n');  // no bounding entities
  };
  for (const auto& en : sents) entity(en);  // dim - 1 comes first
  for (const auto& en : vents) entity(en);
  o.text(o.binary() ? "\n$EndEntities\n" : "$EndEntities\n");

  // $Nodes: one entity block per volume (surface) entity that holds nodes.
  std::vector<std::uint64_t> nodes_in(vents.size() + 1, 0);  // counting sort by entity
  for (Id l = 0; l < nn; ++l) ++nodes_in[static_cast<std::size_t>(node_ent[static_cast<std::size_t>(l)]) + 1];
  std::size_t node_blocks = 0;
  for (std::size_t v = 0; v < vents.size(); ++v) node_blocks += nodes_in[v + 1] > 0;
  for (std::size_t v = 1; v <= vents.size(); ++v) nodes_in[v] += nodes_in[v - 1];
  {
    std::vector<Id> order(static_cast<std::size_t>(nn));
    std::vector<std::uint64_t> pos(nodes_in.begin(), nodes_in.end() - 1);
    for (Id l = 0; l < nn; ++l) order[pos[static_cast<std::size_t>(node_ent[static_cast<std::size_t>(l)])]++] = l;
    o.text("$Nodes\n");
    o.size(node_blocks);
    o.size(static_cast<std::uint64_t>(nn));
    o.size(nn > 0 ? static_cast<std::uint64_t>(ng.front()) + 1 : 0);
    o.size(nn > 0 ? static_cast<std::uint64_t>(ng.back()) + 1 : 0, '\n');
    for (std::size_t v = 0; v < vents.size(); ++v) {
      const std::uint64_t first = nodes_in[v], end = nodes_in[v + 1];
      if (first == end) continue;
      o.integer(dim);
      o.integer(vents[v].tag);
      o.integer(0);  // no parametric coordinates
      o.size(end - first, '\n');
      for (std::uint64_t i = first; i < end; ++i) o.size(static_cast<std::uint64_t>(ng[order[i]]) + 1, '\n');
      for (std::uint64_t i = first; i < end; ++i) {
        const Id l = order[i];
        if (o.binary()) {  // one copy per node, not three
          const double xyz[3] = {X[l], Y[l], Z[l]};
          o.raw(xyz, sizeof xyz);
        } else {
          o.dbl(X[l]), o.dbl(Y[l]), o.dbl(Z[l], '\n');
        }
      }
    }
    o.text(o.binary() ? "\n$EndNodes\n" : "$EndNodes\n");
  }
  std::vector<std::int32_t>().swap(node_ent);

  // $Elements.
  std::uint64_t n_elems = static_cast<std::uint64_t>(ne), min_tag = std::numeric_limits<std::uint64_t>::max(),
                max_tag = 0;
  for (Id e = 0; e < ne; ++e) {
    const auto t = static_cast<std::uint64_t>(eg[static_cast<std::size_t>(e)]) + 1;
    min_tag = std::min(min_tag, t), max_tag = std::max(max_tag, t);
  }
  auto side_tag = [&](std::size_t s, Id e, int side) {
    return static_cast<std::uint64_t>(E) + 1 +
           6 * (static_cast<std::uint64_t>(s) * static_cast<std::uint64_t>(E) + static_cast<std::uint64_t>(eg[e])) +
           static_cast<std::uint64_t>(side);
  };
  for (const auto& en : sents) {
    n_elems += en.count;
    const auto& ss = sets[en.source];
    Id corner[4];
    for (std::size_t m = 0; m < ss.element.size(); ++m) {
      if (side_corners(c, ss.element[m], ss.side[m], corner) == 0) continue;
      const auto t = side_tag(en.source, ss.element[m], ss.side[m]);
      min_tag = std::min(min_tag, t), max_tag = std::max(max_tag, t);
    }
  }
  if (n_elems == 0) min_tag = 0;
  o.text("$Elements\n");
  std::size_t elem_blocks = 0;
  for (const auto& v : vents) elem_blocks += v.count > 0;
  o.size(elem_blocks + sents.size());
  o.size(n_elems);
  o.size(min_tag);
  o.size(max_tag, '\n');
  {
    // Elements ordered by entity (counting sort), global id order within.
    std::vector<std::uint64_t> pos(vents.size() + 1, 0);
    for (std::size_t v = 0; v < vents.size(); ++v) pos[v + 1] = pos[v] + vents[v].count;
    std::vector<Id> order(static_cast<std::size_t>(ne));
    {
      std::vector<std::uint64_t> p(pos.begin(), pos.end() - 1);
      for (Id e = 0; e < ne; ++e)
        order[p[static_cast<std::size_t>(entity_of_block[static_cast<std::size_t>(eb[e])])]++] = e;
    }
    for (std::size_t v = 0; v < vents.size(); ++v) {
      if (vents[v].count == 0) continue;
      o.integer(dim);
      o.integer(vents[v].tag);
      o.integer(vol ? kMshHex : kMshQuad);
      o.size(vents[v].count, '\n');
      for (std::uint64_t i = pos[v]; i < pos[v + 1]; ++i) {
        const Id e = order[i];
        if (o.binary()) {  // the tag and the nodes in one copy
          std::size_t rec[9];
          rec[0] = static_cast<std::size_t>(eg[e]) + 1;
          for (int q = 0; q < nc; ++q) rec[q + 1] = static_cast<std::size_t>(ng[conn[static_cast<std::size_t>(e) * nc + q]]) + 1;
          o.raw(rec, sizeof(std::size_t) * static_cast<std::size_t>(nc + 1));
          continue;
        }
        o.size(static_cast<std::uint64_t>(eg[e]) + 1);
        for (int q = 0; q < nc; ++q)
          o.size(static_cast<std::uint64_t>(ng[conn[static_cast<std::size_t>(e) * nc + q]]) + 1,
                 q + 1 == nc ? '\n' : ' ');
      }
    }
  }
  for (const auto& en : sents) {
    const auto& ss = sets[en.source];
    o.integer(dim - 1);
    o.integer(en.tag);
    o.integer(vol ? kMshQuad : kMshLine);
    o.size(en.count, '\n');
    Id corner[4];
    for (std::size_t m = 0; m < ss.element.size(); ++m) {
      const int k = side_corners(c, ss.element[m], ss.side[m], corner);
      if (k == 0) continue;
      o.size(side_tag(en.source, ss.element[m], ss.side[m]));
      for (int q = 0; q < k; ++q) o.size(static_cast<std::uint64_t>(ng[corner[q]]) + 1, q + 1 == k ? '\n' : ' ');
    }
  }
  o.text(o.binary() ? "\n$EndElements\n" : "$EndElements\n");
}

}  // namespace

void write_msh(const ExportChunk& chunk, const std::string& path, bool binary) {
  namespace fs = std::filesystem;
  // Boundary element tags must fit: E + 6 * (S * E + E) + 6 < 2^63.
  const auto E = static_cast<unsigned __int128>(chunk.mesh().num_elements());
  const auto S = static_cast<unsigned __int128>(chunk.side_sets().size());
  if (E + 6 * (S * E + E) + 7 > static_cast<unsigned __int128>(std::numeric_limits<std::int64_t>::max()))
    throw Error(ErrorKind::Overflow, path + ": MSH boundary element tags do not fit 64 bits");

  AtomicOutput out(path);
  const int fd = ::open(out.temp_path().c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(ErrorKind::Io, path + ": cannot create " + out.temp_path() + ": " + std::strerror(errno));
  try {
    Out o(fd, path, binary);
    write_body(chunk, o);
    o.close();
    out.commit();
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    throw Error(ErrorKind::Io, path + ": " + e.what());
  }
}

}  // namespace dicer
