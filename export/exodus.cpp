// Exodus II writer: one chunk (ChunkSource) -> one Exodus file, through the Exodus II
// C library (the same library read_exodus.cpp reads with).
//
// File layout:
//  - netCDF-4 (HDF5-based). Integers: the API is 64-bit throughout
//    (EX_ALL_INT64_API); in the file, ids and maps are 64-bit
//    (EX_IDS_INT64_DB | EX_MAPS_INT64_DB: global id + 1 of a small chunk of
//    a big mesh overflows 32 bits) and bulk data (connectivity, set entries:
//    local, 1-based positions in this file) is 32-bit. Not EX_BULK_INT64_DB:
//    Exodus 6.02's ex_put_set_param passes sizeof(int64_t) = 8 as the netCDF
//    type and so stores every set entry as NC_USHORT, failing ("Numeric
//    conversion not representable") past 65535. A chunk therefore holds at
//    most 2^31 - 1 nodes and elements (Error{Usage}: use more chunks).
//    Any 64-bit integer in the file needs netCDF-4 (Exodus 6.02 silently
//    switches to it even without EX_NETCDF4), so every file is netCDF-4 and
//    there is no count threshold; that format also has no 4 GiB-per-variable
//    limit. meshio (netCDF4-python), ParaView/VTK, the Exodus library and
//    read_coarse_mesh read it.
//  - num_dim 3 always (a surface mesh is a 3-D shell), coordinate names x y z.
//  - One element block per block that has elements in the chunk, in
//    MeshInfo::blocks order, id = Block::id, type HEX8 (volume) or SHELL4
//    (surface), with its name (blocks and sets: names up to 255 characters,
//    longer ones cut; the file's name length is the longest name, at least
//    32). Elements are written block by block (stable: within a block, in
//    the chunk's global id order); the element id map follows that order.
//  - Id maps: EX_NODE_MAP = global node id + 1, EX_ELEM_MAP = global element
//    id + 1.
//  - Side sets: every set of the chunk (an empty one too, so a solver finds
//    the boundary it names in every chunk), 1-based element positions in the
//    block-ordered element list, 1-based Exodus sides (hex 1..6; shell 1,2
//    faces, 3..6 edges). Node sets: 1-based local node ids.
//
// The file is written through AtomicOutput (a temporary in the destination
// folder, fsync, rename); on any failure the temporary is closed and
// removed and Error{Io, "<path>: <call> failed (<reason>)"} is thrown.
//
// Streaming: coordinates, id maps, connectivity and node-set entries are
// gathered from the chunk's passes (export.hpp ChunkSource) and go out
// kSlice entries per partial call (ex_put_partial_coord, _id_map,
// _elem_conn, _set); a block's elements are one pass over that block.
// Held whole: side-set members with their file positions (O(set sizes))
// and, for Nemesis, the processor node and element maps (Exodus 6.02 has
// no partial writer for them: 8 B per node and per element).
#include <exodusII.h>
#include <netcdf.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>
#include <system_error>
#include <vector>

#include "dicer/atomic_output.hpp"
#include "dicer/error.hpp"
#include "dicer/export.hpp"
#include "hdf5_lock.hpp"
#include "exodus_errors.hpp"

namespace dicer {
namespace {

constexpr std::int64_t kSlice = std::int64_t{1} << 16;  // id map entries per library call
constexpr std::size_t kMaxName = 255;                   // longest name kept (netCDF-4: NC_MAX_NAME = 256)


// The temporary file (AtomicOutput): closed, and removed unless committed.
class TempExodus {
 public:
  explicit TempExodus(const std::string& final_path)
      : final_(final_path), out_(std::make_unique<AtomicOutput>(final_path)) {}
  ~TempExodus() {
    std::lock_guard lock(hdf5_lock());
    if (exoid_ >= 0) ex_close(exoid_);
  }
  TempExodus(const TempExodus&) = delete;
  TempExodus& operator=(const TempExodus&) = delete;

  [[noreturn]] void fail(const std::string& call, const std::string& reason) const {
    throw Error(ErrorKind::Io, final_ + ": " + call + " failed (" + reason + ")");
  }
  // Negative return codes are errors; positive ones are warnings, harmless
  // here (names are cut to the file's limit before they are written).
  void check(int rc, const std::string& call) const {
    if (rc < 0) {
      const int err = errno;
      fail(call, exodus::reason(rc) + exodus::os_reason(err));
    }
  }

  void create() {
    int cpu_word_size = 8, io_word_size = 8;
    const int mode = EX_CLOBBER | EX_NETCDF4 | EX_IDS_INT64_DB | EX_MAPS_INT64_DB | EX_ALL_INT64_API;
    exodus::clear_error();
    // Exodus 6.02 formats the path into fixed buffers: hand it the short
    // /proc/self/fd name of the temporary, never the user's long path.
    const int id = ex_create(out_->short_path().c_str(), mode, &cpu_word_size, &io_word_size);
    if (id < 0) fail("ex_create", exodus::reason(id));
    exoid_ = id;
  }
  int id() const { return exoid_; }

  // Commits, or leaves the file in *pending (PendingFile).
  void close_and_rename(PendingFile* pending) {
    const int id = exoid_;
    exoid_ = -1;
    exodus::clear_error();
    check(ex_close(id), "ex_close");
    commit_or_pend(out_, pending);
  }

 private:
  std::string final_;
  PendingFile out_;
  int exoid_ = -1;
};

// Runs a pass over the chunk without the HDF5 lock (netCDF-4 is HDF5
// underneath): the pass loads store pages, which the cache's read-ahead
// thread does under that lock while this thread waits for the page.
// Library calls made inside the pass take the lock again (it is recursive).
template <class Fn>
void unlocked(std::unique_lock<std::recursive_mutex>& lock, Fn&& fn) {
  lock.unlock();
  struct Relock {
    std::unique_lock<std::recursive_mutex>& l;
    ~Relock() { l.lock(); }
  } relock{lock};
  fn();
}

// char* array for the name functions (they take non-const char**).
struct NameList {
  std::vector<std::string> text;
  std::vector<char*> ptr;
  char** data() {
    ptr.clear();
    for (std::string& s : text) ptr.push_back(s.data());
    return ptr.data();
  }
};

// The Nemesis part of processor n.processor's file (see export.hpp). Written
// before ex_put_init_ext, as SEACAS and libMesh do. All arrays int64 (the
// file uses the 64-bit API); an empty array is passed as a one-element dummy
// (the library dereferences what it is given). `present`: the blocks in
// file order, `per_block` their element counts.
void write_nemesis(TempExodus& file, const ChunkSource& chunk, const NemesisInfo& n,
                   const std::vector<std::size_t>& present, const std::vector<Id>& per_block,
                   std::unique_lock<std::recursive_mutex>& lock) {
  const int exoid = file.id();
  const int proc = static_cast<int>(n.processor);
  const MeshInfo& info = chunk.mesh().info();
  auto ptr = [](std::vector<std::int64_t>& v) {
    if (v.empty()) v.reserve(1);
    return v.data();
  };
  char ftype[] = "p";
  exodus::clear_error();
  file.check(ex_put_init_info(exoid, static_cast<int>(n.processors), 1, ftype), "ex_put_init_info");
  exodus::clear_error();
  file.check(ex_put_init_global(exoid, n.global_nodes, n.global_elements, static_cast<std::int64_t>(info.blocks.size()),
                                static_cast<std::int64_t>(chunk.node_set_ranges().size()),
                                static_cast<std::int64_t>(chunk.side_sets().size())),
             "ex_put_init_global");
  {
    std::vector<std::int64_t> ids, counts;
    for (size_t b = 0; b < info.blocks.size(); ++b) ids.push_back(info.blocks[b].id), counts.push_back(info.block_fine_elements[b]);
    exodus::clear_error();
    if (!ids.empty()) file.check(ex_put_eb_info_global(exoid, ptr(ids), ptr(counts)), "ex_put_eb_info_global");
  }
  // Global set parameters: ids, global counts, no distribution factors.
  auto set_params = [&](const auto& chunk_sets, const std::vector<std::int64_t>& global_counts, auto put, const char* call) {
    if (chunk_sets.empty()) return;
    std::vector<std::int64_t> ids, counts = global_counts, df(chunk_sets.size(), 0);
    for (const auto& set : chunk_sets) ids.push_back(set.id);
    counts.resize(ids.size());
    exodus::clear_error();
    file.check(put(exoid, ptr(ids), ptr(counts), ptr(df)), call);
  };
  set_params(chunk.side_sets(), n.side_set_counts, ex_put_ss_param_global, "ex_put_ss_param_global");
  set_params(chunk.node_set_ranges(), n.node_set_counts, ex_put_ns_param_global, "ex_put_ns_param_global");
  // Border nodes: those on any communication map (a bit each); the rest are internal.
  const Id nn = chunk.num_nodes();
  std::vector<std::uint64_t> border(static_cast<size_t>(nn / 64 + 1), 0);
  auto is_border = [&](Id l) { return (border[static_cast<size_t>(l >> 6)] >> (l & 63)) & 1; };
  for (const auto& list : n.shared)
    for (Id l : list) {
      if (l < 0 || l >= nn) file.fail("nemesis", "shared node " + std::to_string(l) + " is not in the chunk");
      border[static_cast<size_t>(l >> 6)] |= std::uint64_t{1} << (l & 63);
    }
  std::vector<std::int64_t> mapi, mapb, mape;
  for (Id l = 0; l < nn; ++l) (is_border(l) ? mapb : mapi).push_back(l + 1);
  // Border elements: those with a border node, by 1-based file position.
  std::vector<std::int64_t> emapi, emapb;
  const int c = chunk.corners();
  std::int64_t f = 0;
  unlocked(lock, [&] {
    for (std::size_t b : present) {
      if (per_block[b] == 0) continue;
      chunk.elements({static_cast<std::int32_t>(b), false}, [&](const ElementSpan& span) {
        for (Id e = 0; e < span.count; ++e) {
          bool bd = false;
          for (int q = 0; q < c && !bd; ++q) bd = is_border(span.conn[e * c + q]);
          (bd ? emapb : emapi).push_back(++f);
        }
      });
    }
  });
  exodus::clear_error();
  file.check(ex_put_loadbal_param(exoid, static_cast<std::int64_t>(mapi.size()), static_cast<std::int64_t>(mapb.size()), 0,
                                  static_cast<std::int64_t>(emapi.size()), static_cast<std::int64_t>(emapb.size()),
                                  static_cast<std::int64_t>(n.neighbors.size()), 0, proc),
             "ex_put_loadbal_param");
  std::vector<std::int64_t> map_ids, map_counts, none;
  for (size_t k = 0; k < n.neighbors.size(); ++k)
    map_ids.push_back(n.neighbors[k]), map_counts.push_back(static_cast<std::int64_t>(n.shared[k].size()));
  exodus::clear_error();
  file.check(ex_put_cmap_params(exoid, ptr(map_ids), ptr(map_counts), ptr(none), ptr(none), proc), "ex_put_cmap_params");
  for (size_t k = 0; k < n.neighbors.size(); ++k) {
    std::vector<std::int64_t> nodes, procs(n.shared[k].size(), n.neighbors[k]);
    for (Id l : n.shared[k]) nodes.push_back(l + 1);
    exodus::clear_error();
    file.check(ex_put_node_cmap(exoid, n.neighbors[k], ptr(nodes), ptr(procs), proc),
               "ex_put_node_cmap(" + std::to_string(n.neighbors[k]) + ")");
  }
  exodus::clear_error();
  file.check(ex_put_processor_node_maps(exoid, ptr(mapi), ptr(mapb), ptr(mape), proc), "ex_put_processor_node_maps");
  exodus::clear_error();
  file.check(ex_put_processor_elem_maps(exoid, ptr(emapi), ptr(emapb), proc), "ex_put_processor_elem_maps");
}

// Values gathered from a pass's spans and handed to the library kSlice at a
// time: put(first, n) writes buffered entries [first, first + n) (0-based).
struct Slices {
  std::vector<std::int64_t> a, b;
  std::vector<double> x, y, z;
  Id first = 0;  // index of the buffer's first entry
};

}  // namespace


std::string nemesis_path(const std::string& out, Id processors, Id processor) {
  const std::string p = std::to_string(processors);
  std::string r = std::to_string(processor);
  if (r.size() < p.size()) r.insert(0, p.size() - r.size(), '0');
  return out + "." + p + "." + r;
}


void write_exodus(const ChunkSource& chunk, const std::string& path, const NemesisInfo* nem, PendingFile* pending) {
  // netCDF-4 is HDF5 underneath: take the process-wide HDF5 lock (the
  // store's read-ahead thread may be loading pages meanwhile), except
  // during the chunk's passes (unlocked()).
  std::unique_lock lock(hdf5_lock());
  if (path.empty() || path.back() == '/') throw Error(ErrorKind::Usage, path + ": not a file name");

  const MeshInfo& info = chunk.mesh().info();
  const int corners = chunk.corners();
  const bool volume = chunk.mode() == Mode::Volume;
  const Id num_nodes = chunk.num_nodes();
  const Id num_elements = chunk.num_elements();
  const auto& side_sets = chunk.side_sets();
  const auto& node_sets = chunk.node_set_ranges();

  constexpr Id kMaxLocal = 2147483647;  // 32-bit bulk data, see above
  if (num_nodes > kMaxLocal || num_elements > kMaxLocal)
    throw Error(ErrorKind::Usage, path + ": a chunk of " + std::to_string(num_nodes) + " nodes and " +
                                      std::to_string(num_elements) +
                                      " elements is too big for one Exodus file (at most 2147483647 of each); "
                                      "export in more chunks");

  // ---- block order: the chunk's elements block by block ----
  const std::size_t nblocks = info.blocks.size();
  const std::vector<Id> per_block = chunk.block_counts();
  std::vector<Id> block_start(nblocks + 1, 0);
  for (std::size_t b = 0; b < nblocks; ++b) block_start[b + 1] = block_start[b] + per_block[b];
  std::vector<std::size_t> present;  // block indices with elements here (every block in a Nemesis file)
  for (std::size_t b = 0; b < nblocks; ++b)
    if (nem || per_block[b] > 0) present.push_back(b);
  chunk.expect_passes(nem ? 3 : 2);

  ex_opts(0);  // no chatter on stderr, never abort; errors become dicer::Error
  TempExodus file(path);
  file.create();
  const int exoid = file.id();

  // Name length: Exodus 6.02 sizes the file's name dimension (len_name) from
  // the "maximum_name_length" attribute when ex_put_init_ext defines it, and
  // ex_set_max_name_length changes only the API side, so the attribute is set
  // here, still in define mode (newer Exodus versions do the same
  // internally). Names are cut to kMaxName characters by us, so the library
  // never truncates (it would print a warning on stderr).
  std::size_t longest = MAX_NAME_LENGTH;
  for (std::size_t b : present) longest = std::max(longest, info.blocks[b].name.size());
  for (const auto& s : side_sets) longest = std::max(longest, s.name.size());
  for (const auto& s : node_sets) longest = std::max(longest, s.name.size());
  const int name_len = static_cast<int>(std::min(longest, kMaxName));
  if (name_len > MAX_NAME_LENGTH) {
    const int status = nc_put_att_int(exoid, NC_GLOBAL, "maximum_name_length", NC_INT, 1, &name_len);
    if (status != NC_NOERR) file.fail("nc_put_att_int(maximum_name_length)", nc_strerror(status));
    exodus::clear_error();
    file.check(ex_set_max_name_length(exoid, name_len), "ex_set_max_name_length");
  }
  const auto cut = [&](const std::string& name) { return name.substr(0, static_cast<std::size_t>(name_len)); };
  if (nem) write_nemesis(file, chunk, *nem, present, per_block, lock);

  // ---- header ----
  ex_init_params init{};
  {
    std::string source = std::filesystem::path(info.source).filename().string();
    // K/N as `--chunk K/N` and the Nemesis suffixes count them: from 0.
    std::string title = "dicer: chunk " + std::to_string(chunk.range().index) + "/" +
                        std::to_string(chunk.range().count) + (source.empty() ? "" : " from " + source);
    title.resize(std::min<std::size_t>(title.size(), MAX_LINE_LENGTH));
    std::copy(title.begin(), title.end(), init.title);
  }
  init.num_dim = 3;
  init.num_nodes = num_nodes;
  init.num_elem = num_elements;
  init.num_elem_blk = static_cast<std::int64_t>(present.size());
  init.num_side_sets = static_cast<std::int64_t>(side_sets.size());
  init.num_node_sets = static_cast<std::int64_t>(node_sets.size());
  exodus::clear_error();
  file.check(ex_put_init_ext(exoid, &init), "ex_put_init_ext");

  // ---- nodes: coordinates and the id map, kSlice nodes per call ----
  {
    NameList names{{"x", "y", "z"}, {}};
    exodus::clear_error();
    file.check(ex_put_coord_names(exoid, names.data()), "ex_put_coord_names");
  }
  Slices buf;
  auto put_nodes = [&] {
    const auto n = static_cast<std::int64_t>(buf.a.size());
    if (n == 0) return;
    std::lock_guard call(hdf5_lock());
    exodus::clear_error();
    file.check(ex_put_partial_coord(exoid, buf.first + 1, n, buf.x.data(), buf.y.data(), buf.z.data()),
               "ex_put_partial_coord");
    exodus::clear_error();
    file.check(ex_put_partial_id_map(exoid, EX_NODE_MAP, buf.first + 1, n, buf.a.data()), "ex_put_partial_id_map(node)");
    buf.first += n;
    buf.a.clear(), buf.x.clear(), buf.y.clear(), buf.z.clear();
  };
  unlocked(lock, [&] {
    chunk.nodes({true, -1}, [&](const NodeSpan& span) {
      for (Id q = 0; q < span.count; ++q) {
        buf.a.push_back(span.global[q] + 1);
        buf.x.push_back(span.x[q]), buf.y.push_back(span.y[q]), buf.z.push_back(span.z[q]);
        if (static_cast<Id>(buf.a.size()) == kSlice) put_nodes();
      }
    });
  });
  put_nodes();
  if (buf.first != num_nodes) file.fail("export", "the chunk's node pass gave " + std::to_string(buf.first) + " nodes");

  // ---- element blocks ----
  for (std::size_t b : present) {
    const std::int64_t id = info.blocks[b].id;
    const Id count = per_block[b];
    exodus::clear_error();
    file.check(ex_put_block(exoid, EX_ELEM_BLOCK, id, volume ? "HEX8" : "SHELL4", count, count ? corners : 0, 0, 0, 0),
               "ex_put_block(" + std::to_string(id) + ")");
  }
  if (!present.empty()) {
    NameList names;
    for (std::size_t b : present) names.text.push_back(cut(info.blocks[b].name));
    exodus::clear_error();
    file.check(ex_put_names(exoid, EX_ELEM_BLOCK, names.data()), "ex_put_names(element blocks)");
  }
  // Connectivity (1-based local ids) and the element id map, block by block,
  // kSlice elements per call; side-set members learn their file positions
  // on the way (sets hold local element indices, ascending).
  std::vector<std::vector<std::int64_t>> side_pos(side_sets.size());
  for (std::size_t s = 0; s < side_sets.size(); ++s) side_pos[s].assign(side_sets[s].element.size(), -1);
  for (std::size_t b : present) {
    const std::int64_t id = info.blocks[b].id;
    if (per_block[b] == 0) continue;  // an empty block (Nemesis lists every block)
    buf.first = block_start[b];       // file position of the buffer's first element
    auto put_elements = [&] {
      const auto n = static_cast<std::int64_t>(buf.a.size());
      if (n == 0) return;
      std::lock_guard call(hdf5_lock());
      exodus::clear_error();
      file.check(ex_put_partial_elem_conn(exoid, id, buf.first - block_start[b] + 1, n, buf.b.data()),
                 "ex_put_partial_elem_conn(" + std::to_string(id) + ")");
      exodus::clear_error();
      file.check(ex_put_partial_id_map(exoid, EX_ELEM_MAP, buf.first + 1, n, buf.a.data()),
                 "ex_put_partial_id_map(element)");
      buf.first += n;
      buf.a.clear(), buf.b.clear();
    };
    unlocked(lock, [&] {
      chunk.elements({static_cast<std::int32_t>(b), false}, [&](const ElementSpan& span) {
        const Id at = buf.first + static_cast<Id>(buf.a.size());  // file position of span.first
        for (std::size_t s = 0; s < side_sets.size(); ++s) {
          const auto& el = side_sets[s].element;
          for (auto it = std::lower_bound(el.begin(), el.end(), span.first);
               it != el.end() && *it < span.first + span.count; ++it)
            side_pos[s][static_cast<std::size_t>(it - el.begin())] = at + (*it - span.first);
        }
        for (Id e = 0; e < span.count; ++e) {
          buf.a.push_back(span.global[e] + 1);
          for (int q = 0; q < corners; ++q) buf.b.push_back(span.conn[e * corners + q] + 1);
          if (static_cast<Id>(buf.a.size()) == kSlice) put_elements();
        }
      });
    });
    put_elements();
    if (buf.first != block_start[b + 1])
      file.fail("export", "block " + std::to_string(id) + ": the element pass gave a different count");
  }

  // ---- side sets ----
  for (std::size_t s = 0; s < side_sets.size(); ++s) {
    const auto& set = side_sets[s];
    const std::int64_t count = static_cast<std::int64_t>(set.element.size());
    const std::string what = "(side set " + std::to_string(set.id) + ")";
    exodus::clear_error();
    file.check(ex_put_set_param(exoid, EX_SIDE_SET, set.id, count, 0), "ex_put_set_param" + what);
    if (count == 0) continue;
    std::vector<std::int64_t> elems(static_cast<std::size_t>(count)), sides(static_cast<std::size_t>(count));
    for (std::size_t i = 0; i < set.element.size(); ++i) {
      if (side_pos[s][i] < 0) file.fail("export", "side set " + std::to_string(set.id) + ": a member is not in the chunk");
      elems[i] = side_pos[s][i] + 1;
      sides[i] = set.side[i] + 1;
    }
    exodus::clear_error();
    file.check(ex_put_set(exoid, EX_SIDE_SET, set.id, elems.data(), sides.data()), "ex_put_set" + what);
  }
  if (!side_sets.empty()) {
    NameList names;
    for (const auto& set : side_sets) names.text.push_back(cut(set.name));
    exodus::clear_error();
    file.check(ex_put_names(exoid, EX_SIDE_SET, names.data()), "ex_put_names(side sets)");
  }

  // ---- node sets: 1-based local ids, from the ranges, kSlice per call ----
  for (const auto& set : node_sets) {
    std::int64_t count = 0;
    for (const auto& r : set.local) count += r[1] - r[0];
    const std::string what = "(node set " + std::to_string(set.id) + ")";
    exodus::clear_error();
    file.check(ex_put_set_param(exoid, EX_NODE_SET, set.id, count, 0), "ex_put_set_param" + what);
    if (count == 0) continue;
    buf.a.clear();
    buf.first = 0;
    auto put_members = [&] {
      const auto n = static_cast<std::int64_t>(buf.a.size());
      if (n == 0) return;
      exodus::clear_error();
      file.check(ex_put_partial_set(exoid, EX_NODE_SET, set.id, buf.first + 1, n, buf.a.data(), nullptr),
                 "ex_put_partial_set" + what);
      buf.first += n;
      buf.a.clear();
    };
    for (const auto& r : set.local)
      for (Id l = r[0]; l < r[1]; ++l) {
        buf.a.push_back(l + 1);
        if (static_cast<Id>(buf.a.size()) == kSlice) put_members();
      }
    put_members();
  }
  if (!node_sets.empty()) {
    NameList names;
    for (const auto& set : node_sets) names.text.push_back(cut(set.name));
    exodus::clear_error();
    file.check(ex_put_names(exoid, EX_NODE_SET, names.data()), "ex_put_names(node sets)");
  }

  file.close_and_rename(pending);
}

}  // namespace dicer
