// Exodus II writer: one ExportChunk -> one Exodus file, through the Exodus II
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
// Memory beyond the chunk: coordinates are passed straight from the chunk's
// arrays; id maps go out in slices of kSlice entries; connectivity is
// copied one block at a time (Exodus 6.02 has no partial connectivity
// writer), i.e. at most the chunk's own connectivity size once more, plus
// 8 B per element for the block-order permutation and the set members.
#include <exodusII.h>
#include <netcdf.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
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
  explicit TempExodus(const std::string& final_path) : final_(final_path), out_(final_path) {}
  ~TempExodus() {
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
    if (rc < 0) fail(call, exodus::reason(rc));
  }

  void create() {
    int cpu_word_size = 8, io_word_size = 8;
    const int mode = EX_CLOBBER | EX_NETCDF4 | EX_IDS_INT64_DB | EX_MAPS_INT64_DB | EX_ALL_INT64_API;
    exodus::clear_error();
    // Exodus 6.02 formats the path into fixed buffers: hand it the short
    // /proc/self/fd name of the temporary, never the user's long path.
    const int id = ex_create(out_.short_path().c_str(), mode, &cpu_word_size, &io_word_size);
    if (id < 0) fail("ex_create", exodus::reason(id));
    exoid_ = id;
  }
  int id() const { return exoid_; }

  void close_and_rename() {
    const int id = exoid_;
    exoid_ = -1;
    exodus::clear_error();
    check(ex_close(id), "ex_close");
    out_.commit();
  }

 private:
  std::string final_;
  AtomicOutput out_;
  int exoid_ = -1;
};

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
// (the library dereferences what it is given).
void write_nemesis(TempExodus& file, const ExportChunk& chunk, const NemesisInfo& n, const std::vector<Id>& order) {
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
                                static_cast<std::int64_t>(chunk.node_sets().size()),
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
  set_params(chunk.node_sets(), n.node_set_counts, ex_put_ns_param_global, "ex_put_ns_param_global");
  // Border nodes: those on any communication map; the rest are internal.
  const Id nn = chunk.num_nodes(), ne = chunk.num_elements();
  std::vector<char> border(static_cast<size_t>(nn), 0);
  for (const auto& list : n.shared)
    for (Id l : list) {
      if (l < 0 || l >= nn) file.fail("nemesis", "shared node " + std::to_string(l) + " is not in the chunk");
      border[static_cast<size_t>(l)] = 1;
    }
  std::vector<std::int64_t> mapi, mapb, mape;
  for (Id l = 0; l < nn; ++l) (border[static_cast<size_t>(l)] ? mapb : mapi).push_back(l + 1);
  std::vector<std::int64_t> emapi, emapb;
  const int c = chunk.corners();
  const auto conn = chunk.connectivity();
  for (size_t f = 0; f < order.size(); ++f) {  // file positions, in file order
    const Id e = order[f];
    bool b = false;
    for (int q = 0; q < c && !b; ++q) b = border[static_cast<size_t>(conn[static_cast<size_t>(e * c + q)])] != 0;
    (b ? emapb : emapi).push_back(static_cast<std::int64_t>(f) + 1);
  }
  (void)ne;
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

}  // namespace


std::string nemesis_path(const std::string& out, Id processors, Id processor) {
  const std::string p = std::to_string(processors);
  std::string r = std::to_string(processor);
  if (r.size() < p.size()) r.insert(0, p.size() - r.size(), '0');
  return out + "." + p + "." + r;
}

void write_exodus(const ExportChunk& chunk, const std::string& path, const NemesisInfo* nem) {
  // netCDF-4 is HDF5 underneath: take the process-wide HDF5 lock (the
  // store's read-ahead thread may be loading pages meanwhile).
  std::lock_guard hdf5_guard(hdf5_lock());
  if (path.empty() || path.back() == '/') throw Error(ErrorKind::Usage, path + ": not a file name");

  const MeshInfo& info = chunk.mesh().info();
  const int corners = chunk.corners();
  const bool volume = chunk.mode() == Mode::Volume;
  const Id num_nodes = chunk.num_nodes();
  const Id num_elements = chunk.num_elements();
  const auto elem_block = chunk.element_block();
  const auto elem_global = chunk.element_global();
  const auto conn = chunk.connectivity();

  constexpr Id kMaxLocal = 2147483647;  // 32-bit bulk data, see above
  if (num_nodes > kMaxLocal || num_elements > kMaxLocal)
    throw Error(ErrorKind::Usage, path + ": a chunk of " + std::to_string(num_nodes) + " nodes and " +
                                      std::to_string(num_elements) +
                                      " elements is too big for one Exodus file (at most 2147483647 of each); "
                                      "export in more chunks");

  // ---- block order: counting sort of the chunk's elements by block ----
  const std::size_t nblocks = info.blocks.size();
  std::vector<Id> block_start(nblocks + 1, 0);
  for (Id e = 0; e < num_elements; ++e) {
    const std::int32_t b = elem_block[static_cast<std::size_t>(e)];
    if (b < 0 || static_cast<std::size_t>(b) >= nblocks)
      throw Error(ErrorKind::Usage, path + ": element " + std::to_string(elem_global[static_cast<std::size_t>(e)]) +
                                        " has no block");
    ++block_start[static_cast<std::size_t>(b) + 1];
  }
  for (std::size_t b = 0; b < nblocks; ++b) block_start[b + 1] += block_start[b];
  // order[f]: the chunk element at 0-based file position f.
  std::vector<Id> order(static_cast<std::size_t>(num_elements));
  {
    std::vector<Id> next(block_start.begin(), block_start.end() - 1);
    for (Id e = 0; e < num_elements; ++e)
      order[static_cast<std::size_t>(next[static_cast<std::size_t>(elem_block[static_cast<std::size_t>(e)])]++)] = e;
  }
  std::vector<std::size_t> present;  // block indices with elements here (every block in a Nemesis file)
  for (std::size_t b = 0; b < nblocks; ++b)
    if (nem || block_start[b + 1] > block_start[b]) present.push_back(b);

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
  for (const auto& s : chunk.side_sets()) longest = std::max(longest, s.name.size());
  for (const auto& s : chunk.node_sets()) longest = std::max(longest, s.name.size());
  const int name_len = static_cast<int>(std::min(longest, kMaxName));
  if (name_len > MAX_NAME_LENGTH) {
    const int status = nc_put_att_int(exoid, NC_GLOBAL, "maximum_name_length", NC_INT, 1, &name_len);
    if (status != NC_NOERR) file.fail("nc_put_att_int(maximum_name_length)", nc_strerror(status));
    exodus::clear_error();
    file.check(ex_set_max_name_length(exoid, name_len), "ex_set_max_name_length");
  }
  const auto cut = [&](const std::string& name) { return name.substr(0, static_cast<std::size_t>(name_len)); };
  if (nem) write_nemesis(file, chunk, *nem, order);

  // ---- header ----
  ex_init_params init{};
  {
    std::string source = std::filesystem::path(info.source).filename().string();
    std::string title = "dicer: chunk " + std::to_string(chunk.range().index + 1) + " of " +
                        std::to_string(chunk.range().count) + (source.empty() ? "" : " from " + source);
    title.resize(std::min<std::size_t>(title.size(), MAX_LINE_LENGTH));
    std::copy(title.begin(), title.end(), init.title);
  }
  init.num_dim = 3;
  init.num_nodes = num_nodes;
  init.num_elem = num_elements;
  init.num_elem_blk = static_cast<std::int64_t>(present.size());
  init.num_side_sets = static_cast<std::int64_t>(chunk.side_sets().size());
  init.num_node_sets = static_cast<std::int64_t>(chunk.node_sets().size());
  exodus::clear_error();
  file.check(ex_put_init_ext(exoid, &init), "ex_put_init_ext");

  // ---- nodes ----
  {
    NameList names{{"x", "y", "z"}, {}};
    exodus::clear_error();
    file.check(ex_put_coord_names(exoid, names.data()), "ex_put_coord_names");
  }
  if (num_nodes > 0) {
    exodus::clear_error();
    file.check(ex_put_coord(exoid, chunk.x().data(), chunk.y().data(), chunk.z().data()), "ex_put_coord");
  }
  std::vector<std::int64_t> buffer;
  const auto node_global = chunk.node_global();
  for (Id first = 0; first < num_nodes; first += kSlice) {
    const Id n = std::min(kSlice, num_nodes - first);
    buffer.resize(static_cast<std::size_t>(n));
    for (Id i = 0; i < n; ++i)
      buffer[static_cast<std::size_t>(i)] = node_global[static_cast<std::size_t>(first + i)] + 1;
    exodus::clear_error();
    file.check(ex_put_partial_id_map(exoid, EX_NODE_MAP, first + 1, n, buffer.data()),
               "ex_put_partial_id_map(node)");
  }

  // ---- element blocks ----
  for (std::size_t b : present) {
    const std::int64_t id = info.blocks[b].id;
    const Id count = block_start[b + 1] - block_start[b];
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
  for (std::size_t b : present) {
    const std::int64_t id = info.blocks[b].id;
    const Id first = block_start[b], count = block_start[b + 1] - first;
    if (count == 0) continue;  // an empty block (Nemesis lists every block)
    buffer.resize(static_cast<std::size_t>(count * corners));
    const std::size_t width = static_cast<std::size_t>(corners);
    std::size_t k = 0;
    for (Id f = first; f < first + count; ++f) {
      const std::size_t e = static_cast<std::size_t>(order[static_cast<std::size_t>(f)]);
      for (std::size_t c = 0; c < width; ++c) buffer[k++] = conn[e * width + c] + 1;
    }
    exodus::clear_error();
    file.check(ex_put_conn(exoid, EX_ELEM_BLOCK, id, buffer.data(), nullptr, nullptr),
               "ex_put_conn(" + std::to_string(id) + ")");
  }
  for (Id first = 0; first < num_elements; first += kSlice) {
    const Id n = std::min(kSlice, num_elements - first);
    buffer.resize(static_cast<std::size_t>(n));
    for (Id i = 0; i < n; ++i)
      buffer[static_cast<std::size_t>(i)] =
          elem_global[static_cast<std::size_t>(order[static_cast<std::size_t>(first + i)])] + 1;
    exodus::clear_error();
    file.check(ex_put_partial_id_map(exoid, EX_ELEM_MAP, first + 1, n, buffer.data()),
               "ex_put_partial_id_map(element)");
  }
  // Sets need the inverse: the 0-based file position of each chunk element.
  std::vector<Id> file_pos(order.size());
  for (std::size_t f = 0; f < order.size(); ++f) file_pos[static_cast<std::size_t>(order[f])] = static_cast<Id>(f);
  std::vector<Id>().swap(order);

  // ---- side sets ----
  for (const auto& set : chunk.side_sets()) {
    const std::int64_t count = static_cast<std::int64_t>(set.element.size());
    const std::string what = "(side set " + std::to_string(set.id) + ")";
    exodus::clear_error();
    file.check(ex_put_set_param(exoid, EX_SIDE_SET, set.id, count, 0), "ex_put_set_param" + what);
    if (count == 0) continue;
    std::vector<std::int64_t> elems(static_cast<std::size_t>(count)), sides(static_cast<std::size_t>(count));
    for (std::size_t i = 0; i < set.element.size(); ++i) {
      elems[i] = file_pos[static_cast<std::size_t>(set.element[i])] + 1;
      sides[i] = set.side[i] + 1;
    }
    exodus::clear_error();
    file.check(ex_put_set(exoid, EX_SIDE_SET, set.id, elems.data(), sides.data()), "ex_put_set" + what);
  }
  if (!chunk.side_sets().empty()) {
    NameList names;
    for (const auto& set : chunk.side_sets()) names.text.push_back(cut(set.name));
    exodus::clear_error();
    file.check(ex_put_names(exoid, EX_SIDE_SET, names.data()), "ex_put_names(side sets)");
  }

  // ---- node sets ----
  for (const auto& set : chunk.node_sets()) {
    const std::int64_t count = static_cast<std::int64_t>(set.node.size());
    const std::string what = "(node set " + std::to_string(set.id) + ")";
    exodus::clear_error();
    file.check(ex_put_set_param(exoid, EX_NODE_SET, set.id, count, 0), "ex_put_set_param" + what);
    if (count == 0) continue;
    std::vector<std::int64_t> nodes(set.node.begin(), set.node.end());
    for (std::int64_t& v : nodes) v += 1;
    exodus::clear_error();
    file.check(ex_put_set(exoid, EX_NODE_SET, set.id, nodes.data(), nullptr), "ex_put_set" + what);
  }
  if (!chunk.node_sets().empty()) {
    NameList names;
    for (const auto& set : chunk.node_sets()) names.text.push_back(cut(set.name));
    exodus::clear_error();
    file.check(ex_put_names(exoid, EX_NODE_SET, names.data()), "ex_put_names(node sets)");
  }

  file.close_and_rename();
}

}  // namespace dicer
