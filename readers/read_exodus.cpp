// Exodus II reader: builds a CoarseMesh through the Exodus II C library.
//
// The file is opened read-only with 8-byte floats and the int64 API, so all
// ids, counts and connectivity come back as int64 and float32 coordinates are
// widened by the library. Every failing library call becomes a dicer::Error
// naming the file and the entity; the file is always closed (ExodusFile).
//
// Neither netCDF nor Exodus 6.02 check a file against itself, so before
// they read anything: our own parse of a classic header (sizes against the
// file), the attributes ex_open reads into single values, the header's
// counts against the file size, and the shape of every variable a getter
// reads whole (netcdf_checks.hpp). A hostile file is a one-line BadInput,
// never a crash or a huge allocation. netCDF-4 (HDF5) files get all but the
// first: HDF5 opens them as they are. Geometry (handedness, duplicates, unused vertices) is left to
// validate_coarse_mesh.
#include <exodusII.h>
#include <netcdf.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/error.hpp"
#include "exodus_errors.hpp"
#include "input_file.hpp"
#include "isolated.hpp"
#include "netcdf_checks.hpp"

namespace dicer {
namespace {

// ---------------------------------------------------------------- errors ---


[[noreturn]] void fail(ErrorKind kind, const std::string& path, const std::string& what) {
  throw Error(kind, path + ": " + what);
}

// Checks the return code of an Exodus call: negative is an error (positive
// values are warnings such as "no names stored", which are harmless here).
void check(int rc, const std::string& path, const std::string& what) {
  if (rc < 0) fail(ErrorKind::BadInput, path, what + " failed (" + exodus::reason(rc) + ")");
}

// ----------------------------------------------------------- file access ---

class ExodusFile {
 public:
  explicit ExodusFile(int id) : id_(id) {}
  ~ExodusFile() {
    if (id_ >= 0) ex_close(id_);
  }
  ExodusFile(const ExodusFile&) = delete;
  ExodusFile& operator=(const ExodusFile&) = delete;
  int id() const { return id_; }

 private:
  int id_;
};

// Bytes the file may hold per stored byte: 1 for netCDF-3; HDF5 files can be
// compressed, so allow a generous ratio there.
std::uint64_t storage_budget(int ncid, std::int64_t file_size) {
  int format = 0;
  nc_inq_format(ncid, &format);
  const bool compressible = format == NC_FORMAT_NETCDF4 || format == NC_FORMAT_NETCDF4_CLASSIC;
  return mul_sat(static_cast<std::uint64_t>(std::max<std::int64_t>(file_size, 0)), compressible ? 1024 : 1);
}

// A count read from the header must be non-negative and its data (at least
// bytes_each bytes per item) must fit in the file.
void check_count(std::int64_t count, std::uint64_t bytes_each, std::uint64_t budget, std::int64_t file_size,
                 const std::string& path, const std::string& what) {
  if (count < 0) fail(ErrorKind::BadInput, path, "header claims a negative number of " + what);
  if (mul_sat(static_cast<std::uint64_t>(count), bytes_each) > budget) {
    std::ostringstream os;
    os << "header claims " << count << " " << what << ", more than a file of " << file_size
       << " bytes can hold (corrupt or hostile header)";
    fail(ErrorKind::BadInput, path, os.str());
  }
}

// ------------------------------------------------------------ small utils ---

std::string trim(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  std::size_t i = 0;
  while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
  return s.substr(i);
}

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

// Names of all entities of one type, in ex_get_ids order ("" where unnamed).
std::vector<std::string> read_names(int exoid, ex_entity_type type, std::int64_t count, int name_len,
                                    const std::string& path, const std::string& what) {
  std::vector<std::string> names(static_cast<std::size_t>(count));
  if (count == 0) return names;
  std::vector<std::vector<char>> buffers(static_cast<std::size_t>(count),
                                         std::vector<char>(static_cast<std::size_t>(name_len) + 1, '\0'));
  std::vector<char*> pointers;
  for (auto& b : buffers) pointers.push_back(b.data());
  exodus::clear_error();
  check(ex_get_names(exoid, type, pointers.data()), path, "reading " + what + " names");
  for (std::size_t i = 0; i < names.size(); ++i) {
    buffers[i].back() = '\0';
    names[i] = trim(buffers[i].data());
  }
  return names;
}

std::vector<std::int64_t> read_ids(int exoid, ex_entity_type type, std::int64_t count, const std::string& path,
                                   const std::string& what) {
  std::vector<std::int64_t> ids(static_cast<std::size_t>(count));
  if (count == 0) return ids;
  exodus::clear_error();
  check(ex_get_ids(exoid, type, ids.data()), path, "reading " + what + " ids");
  return ids;
}

// A file id map (node or element). Without a stored map the library returns
// 1..n. A map of all zeros (legacy files) or with duplicates is useless for
// messages, so fall back to 1..n with a warning.
std::vector<Id> read_id_map(int exoid, ex_entity_type type, std::int64_t count, const std::string& path,
                            const std::string& what, std::vector<std::string>& warnings) {
  std::vector<Id> map(static_cast<std::size_t>(count));
  if (count == 0) return map;
  exodus::clear_error();
  check(ex_get_id_map(exoid, type, map.data()), path, "reading the " + what + " id map");
  std::vector<Id> sorted = map;
  std::sort(sorted.begin(), sorted.end());
  const bool all_zero = sorted.front() == 0 && sorted.back() == 0;
  const bool duplicates = std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end();
  if (all_zero || duplicates) {
    warnings.push_back("the " + what + " id map " +
                       (all_zero ? "is all zeros" : "has duplicate ids") + "; using " + what + " ids 1.." +
                       std::to_string(count));
    for (std::size_t i = 0; i < map.size(); ++i) map[i] = static_cast<Id>(i) + 1;
  }
  return map;
}

// ----------------------------------------------------------- block types ---

// What an element type is to dicer. Kept: HEX8, HEX20, HEX27 (volume),
// QUAD4/8/9 and SHELL4/8/9 (surface; quads and shells number their sides
// differently); the nodes after the corners are mid nodes (orientation.hpp,
// NodeOrder::Exodus). A name without its node count ("HEX") takes the
// count the block states. Everything else counts only by its dimension:
// refused when it is the mesh's, skipped below it.
enum class Shape { Hex, Quad, Shell, Solid, Face, Bar, Point, Unknown };

Shape classify(const std::string& type, std::int64_t nodes_per_element) {
  const std::string t = upper(type);
  // The name without its node count: "TETRA10" -> "TETRA", "BAR2" -> "BAR".
  std::string base = t;
  while (!base.empty() && std::isdigit(static_cast<unsigned char>(base.back()))) base.pop_back();
  const std::string count = t.substr(base.size());
  const std::string n = std::to_string(nodes_per_element);
  auto kept = [&](const char* name, std::initializer_list<std::int64_t> counts) {
    return base == name && std::find(counts.begin(), counts.end(), nodes_per_element) != counts.end() &&
           (count.empty() || count == n);
  };
  if (kept("HEX", {8, 20, 27}) || (t == "HEXAHEDRON" && (nodes_per_element == 8 || nodes_per_element == 20 ||
                                                         nodes_per_element == 27)))
    return Shape::Hex;
  if (kept("QUAD", {4, 8, 9})) return Shape::Quad;
  if (kept("SHELL", {4, 8, 9})) return Shape::Shell;
  for (const char* solid : {"HEX", "HEXAHEDRON", "TETRA", "TET", "TETRAHEDRON", "WEDGE", "PYRAMID", "NFACED"})
    if (base == solid) return Shape::Solid;
  for (const char* face : {"QUAD", "QUADRILATERAL", "SHELL", "TRI", "TRIANGLE", "TRISHELL", "NSIDED"})
    if (base == face) return Shape::Face;
  for (const char* bar : {"BAR", "BEAM", "TRUSS", "EDGE", "ROD", "SPRING"})
    if (base == bar) return Shape::Bar;
  for (const char* point : {"SPHERE", "CIRCLE", "POINT", "NODE", "PARTICLE"})
    if (base == point) return Shape::Point;
  return Shape::Unknown;
}

// 3 solids, 2 faces, 1 bars, 0 points; -1 for a type dicer does not know.
int dimension(Shape s) {
  switch (s) {
    case Shape::Hex: case Shape::Solid: return 3;
    case Shape::Quad: case Shape::Shell: case Shape::Face: return 2;
    case Shape::Bar: return 1;
    case Shape::Point: return 0;
    case Shape::Unknown: return -1;
  }
  return -1;
}

struct BlockInfo {
  std::int64_t id = 0;
  std::string name;
  std::string type;
  std::int64_t count = 0;
  std::int64_t nodes_per_element = 0;
  Shape shape = Shape::Unknown;
  bool kept = false;          // its elements go into the mesh
  std::int32_t index = -1;    // position in mesh.blocks when kept
};

std::string describe_type(const BlockInfo& b) {
  std::string t = b.type.empty() ? std::string("(untyped)") : b.type;
  // A name with an unexpected node count ("HEX20" with 8 nodes).
  const std::string u = upper(b.type);
  bool generic = u == "HEXAHEDRON";
  for (const char* g : {"HEX", "HEX8", "HEX20", "HEX27", "QUAD", "QUAD4", "QUAD8", "QUAD9", "SHELL", "SHELL4", "SHELL8",
                        "SHELL9"})
    generic = generic || u == g;
  const bool diced = b.shape == Shape::Hex || b.shape == Shape::Quad || b.shape == Shape::Shell;
  if (generic && !diced) t += " with " + std::to_string(b.nodes_per_element) + " nodes per element";
  return t;
}

CoarseMesh read_exodus_here(const std::string& path, std::int64_t file_size);

}  // namespace

CoarseMesh read_exodus(const std::string& path) {
  // The OS first: a missing, unreadable or non-regular file is an I/O error,
  // not a "bad Exodus file".
  std::int64_t file_size = 0;
  {
    const InputFile input(path);
    file_size = input.size();
    const std::string magic = input.head(8);
    const bool classic = magic.size() >= 4 && magic.compare(0, 3, "CDF") == 0 &&
                         (magic[3] == 1 || magic[3] == 2 || magic[3] == 5);
    const bool hdf5 = magic == std::string("\x89HDF\r\n\x1a\n", 8);
    if (!classic && !hdf5)
      fail(ErrorKind::BadInput, path,
           std::string("not a readable Exodus II file (") +
               (file_size == 0 ? "the file is empty" : "no netCDF or HDF5 signature") + ")");
    // netCDF's own header parser trusts the header: check it first.
    if (classic) check_classic_header(input, path);
    // HDF5 parses a netCDF-4 file's metadata as it is: read it in a child
    // process, so that a crash or a runaway allocation there is an error here.
    if (hdf5) return read_isolated(path, file_size, [&] { return read_exodus_here(path, file_size); });
  }
  return read_exodus_here(path, file_size);
}

namespace {

CoarseMesh read_exodus_here(const std::string& path, std::int64_t file_size) {

  // Let netCDF try first: when it cannot open the file, ex_open prints its
  // own guess (a misleading "netcdf-4 not supported") straight to stderr.
  {
    int ncid = -1;
    const int status = nc_open(path.c_str(), NC_NOWRITE, &ncid);
    if (status != NC_NOERR)
      fail(ErrorKind::BadInput, path, "not a readable Exodus II file (" + std::string(nc_strerror(status)) + ")");
    try {
      audit_exodus_attributes(ncid, path);
    } catch (...) {
      nc_close(ncid);
      throw;
    }
    nc_close(ncid);
  }

  ex_opts(0);  // no chatter on stderr, never abort; we report errors ourselves
  int cpu_word_size = 8, io_word_size = 0;
  float version = 0;
  exodus::clear_error();
  const int exoid = ex_open(path.c_str(), EX_READ, &cpu_word_size, &io_word_size, &version);
  if (exoid < 0)
    fail(ErrorKind::BadInput, path, "not a readable Exodus II file (" + exodus::reason(exoid) + ")");
  ExodusFile file(exoid);
  exodus::clear_error();
  check(ex_set_int64_status(exoid, EX_ALL_INT64_API), path, "selecting the 64-bit integer API");

  ex_init_params init{};
  exodus::clear_error();
  if (ex_get_init_ext(exoid, &init) < 0)
    fail(ErrorKind::BadInput, path,
         "not a readable Exodus II file (reading the header failed: " + exodus::reason(-1) + ")");

  // ---- sanity of the header counts before any allocation ----
  const std::uint64_t budget = storage_budget(exoid, file_size);
  // Every block and set is at least a variable in the header: its count is
  // bounded by the file's bytes, compressed or not.
  const std::uint64_t raw = static_cast<std::uint64_t>(file_size);
  if (init.num_dim < 1 || init.num_dim > 3)
    fail(ErrorKind::BadInput, path, "header claims " + std::to_string(init.num_dim) + " dimensions");
  check_count(init.num_nodes, 4 * static_cast<std::uint64_t>(init.num_dim), budget, file_size, path, "nodes");
  check_count(init.num_elem, 4, budget, file_size, path, "elements");
  check_count(init.num_elem_blk, 16, raw, file_size, path, "element blocks");
  check_count(init.num_side_sets, 16, raw, file_size, path, "side sets");
  check_count(init.num_node_sets, 16, raw, file_size, path, "node sets");
  // What the getters below read whole must fit the buffers sized from these.
  audit_exodus_variables(exoid, path);

  CoarseMesh mesh;
  mesh.source = path;

  // Longest stored name (CUBIT uses 32; newer files up to 256).
  std::int64_t name_len = ex_inquire_int(exoid, EX_INQ_DB_MAX_USED_NAME_LENGTH);
  name_len = std::clamp<std::int64_t>(name_len, 32, 256);
  ex_set_max_name_length(exoid, static_cast<int>(name_len));
  const int name_buf = static_cast<int>(name_len);

  // ---- element blocks: types first, to decide the mode ----
  const std::vector<std::int64_t> block_ids =
      read_ids(exoid, EX_ELEM_BLOCK, init.num_elem_blk, path, "element block");
  {
    // The library finds a block by id: a repeated id reads the first block
    // twice (a "duplicated element" or a count that contradicts the header).
    std::vector<std::int64_t> sorted = block_ids;
    std::sort(sorted.begin(), sorted.end());
    if (const auto d = std::adjacent_find(sorted.begin(), sorted.end()); d != sorted.end())
      throw Error(ErrorKind::BadInput, path + ": two element blocks have id " + std::to_string(*d));
  }
  const std::vector<std::string> block_names =
      read_names(exoid, EX_ELEM_BLOCK, init.num_elem_blk, name_buf, path, "element block");
  std::vector<BlockInfo> blocks(block_ids.size());
  std::int64_t total_elements = 0;
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    BlockInfo& info = blocks[b];
    info.id = block_ids[b];
    info.name = block_names[b];
    char type[MAX_STR_LENGTH + 1] = {};
    std::int64_t edges = 0, faces = 0, attrs = 0;
    const std::string what = "element block " + std::to_string(info.id);
    exodus::clear_error();
    check(ex_get_block(exoid, EX_ELEM_BLOCK, info.id, type, &info.count, &info.nodes_per_element, &edges,
                       &faces, &attrs),
          path, "reading " + what);
    type[MAX_STR_LENGTH] = '\0';
    info.type = trim(type);
    check_count(info.count, 4, budget, file_size, path, "elements in " + what);
    if (info.nodes_per_element < 0 || info.nodes_per_element > 1000)
      fail(ErrorKind::BadInput, path,
           what + ": header claims " + std::to_string(info.nodes_per_element) + " nodes per element");
    info.shape = classify(info.type, info.nodes_per_element);
    total_elements += info.count;
    if (total_elements > init.num_elem)
      fail(ErrorKind::BadInput, path,
           "element blocks hold more elements than the header's " + std::to_string(init.num_elem));
  }
  if (total_elements != init.num_elem)
    fail(ErrorKind::BadInput, path,
         "element blocks hold " + std::to_string(total_elements) + " elements but the header claims " +
             std::to_string(init.num_elem));

  // One rule for every input format (README, Inputs): the highest dimension
  // among the non-empty blocks is the mesh's; its blocks must be HEX8 (or
  // QUAD4/SHELL4), lower-dimensional blocks are skipped with one warning.
  int dim = -1;
  for (const BlockInfo& b : blocks)
    if (b.count > 0) dim = std::max(dim, dimension(b.shape));
  std::string refused, skipped;
  for (const BlockInfo& b : blocks) {
    if (b.count == 0) continue;
    const int d = dimension(b.shape);
    const bool kept = d == 3 ? b.shape == Shape::Hex : b.shape == Shape::Quad || b.shape == Shape::Shell;
    const std::string what = std::to_string(b.count) + " " + describe_type(b);
    if (d < 0 || (d == dim && dim >= 2 && !kept)) {
      refused += (refused.empty() ? "" : ", ") + what + " (block " + std::to_string(b.id) + ")";
    } else if (d < dim) {
      skipped += (skipped.empty() ? "" : ", ") + std::string("block ") + std::to_string(b.id) +
                 (b.name.empty() ? "" : " \"" + b.name + "\"") + " (" + what + ")";
    }
  }
  if (!refused.empty())
    fail(ErrorKind::Unsupported, path,
         "unsupported elements: " + refused +
             "; dicer needs all-hex (HEX8, HEX20, HEX27) or all-quad (QUAD4/8/9, SHELL4/8/9) meshes");
  if (dim >= 0 && dim < 2)
    fail(ErrorKind::Unsupported, path,
         "no hexahedra or quadrilaterals, only elements of dimension " + std::to_string(dim) +
             "; dicer needs all-hex (HEX8, HEX20, HEX27) or all-quad (QUAD4/8/9, SHELL4/8/9) meshes");
  mesh.mode = dim == 2 ? Mode::Surface : Mode::Volume;
  if (mesh.mode == Mode::Volume && init.num_dim != 3 && dim == 3)
    fail(ErrorKind::BadInput, path,
         "hexahedral mesh needs 3 coordinate dimensions, the file has " + std::to_string(init.num_dim));
  if (mesh.mode == Mode::Surface && init.num_dim < 2)
    fail(ErrorKind::BadInput, path,
         "quadrilateral mesh needs 2 or 3 coordinate dimensions, the file has " + std::to_string(init.num_dim));
  if (!skipped.empty())
    mesh.warnings.push_back(std::string("skipped element blocks of lower dimension than the ") +
                            (mesh.mode == Mode::Volume ? "hexahedra" : "quadrilaterals") +
                            " (dicer dices only those): " + skipped);

  for (BlockInfo& b : blocks) {
    if (b.count > 0 && dimension(b.shape) < dim) continue;
    b.kept = true;
    b.index = static_cast<std::int32_t>(mesh.blocks.size());
    mesh.blocks.push_back(Block{b.id, b.name});
  }

  // ---- nodes ----
  const std::size_t num_nodes = static_cast<std::size_t>(init.num_nodes);
  mesh.vertex_file_id = read_id_map(exoid, EX_NODE_MAP, init.num_nodes, path, "node", mesh.warnings);
  mesh.x.assign(num_nodes, 0.0);
  mesh.y.assign(num_nodes, 0.0);
  mesh.z.assign(num_nodes, 0.0);
  if (num_nodes > 0) {
    exodus::clear_error();
    check(ex_get_coord(exoid, mesh.x.data(), mesh.y.data(), init.num_dim >= 3 ? mesh.z.data() : nullptr), path,
          "reading node coordinates");
    // The Exodus library (5.14) skips a coordinate variable whose netCDF id
    // is 0 (the file's first variable: legal, if unusual) and reports
    // success, leaving that axis at 0: a flattened mesh, silently. Such a
    // variable is read through netCDF itself (the exoid is the netCDF id),
    // from the layout the library read (a file holding both coord and
    // coordx/y/z had the wrong one put over the right one).
    double* axis[3] = {mesh.x.data(), mesh.y.data(), mesh.z.data()};
    const bool split_axes = ex_large_model(exoid) != 0;  // coordx/y/z, else coord
    for (int d = 0; split_axes && d < std::min<int>(static_cast<int>(init.num_dim), 3); ++d) {
      const char* name[3] = {"coordx", "coordy", "coordz"};
      int id = -1, ndims = 0, dim = -1;
      std::size_t len = 0;
      if (nc_inq_varid(exoid, name[d], &id) != NC_NOERR || id != 0) continue;
      if (nc_inq_varndims(exoid, id, &ndims) != NC_NOERR || ndims != 1 || nc_inq_vardimid(exoid, id, &dim) != NC_NOERR ||
          nc_inq_dimlen(exoid, dim, &len) != NC_NOERR || len != num_nodes)
        throw Error(ErrorKind::BadInput, path + ": variable '" + name[d] + "' is not one value per node");
      if (const int st = nc_get_var_double(exoid, id, axis[d]); st != NC_NOERR)
        throw Error(ErrorKind::BadInput, path + ": reading node coordinates (" + name[d] + "): " + nc_strerror(st));
    }
    {
      int id = -1;  // the older single array coord[num_dim][num_nodes], first in the file: the same gap
      if (!split_axes && nc_inq_varid(exoid, "coord", &id) == NC_NOERR && id == 0) {
        const int dims = std::min<int>(static_cast<int>(init.num_dim), 3);
        for (int d = 0; d < dims; ++d) {
          const std::size_t start[2] = {static_cast<std::size_t>(d), 0}, count[2] = {1, num_nodes};
          if (const int st = nc_get_vara_double(exoid, id, start, count, axis[d]); st != NC_NOERR)
            throw Error(ErrorKind::BadInput, path + ": reading node coordinates (coord): " + nc_strerror(st));
        }
      }
    }
  }
  bool all_zero = true;
  for (std::size_t v = 0; v < num_nodes; ++v) {
    all_zero = all_zero && mesh.x[v] == 0 && mesh.y[v] == 0 && mesh.z[v] == 0;
    if (!std::isfinite(mesh.x[v]) || !std::isfinite(mesh.y[v]) || !std::isfinite(mesh.z[v])) {
      std::ostringstream os;
      os << "node " << mesh.vertex_file_id[v] << ": coordinate is not finite (" << mesh.x[v] << ", " << mesh.y[v]
         << ", " << mesh.z[v] << ")";
      fail(ErrorKind::BadInput, path, os.str());
    }
  }

  // Exodus writes in netCDF no-fill mode, so coordinates that were never
  // written read back as zeros: refuse that rather than dice a point.
  if (all_zero && num_nodes > 1)
    fail(ErrorKind::BadInput, path,
         "node coordinates: all " + std::to_string(num_nodes) +
             " nodes are at the origin (coordinates missing or never written)");

  // ---- elements ----
  const std::vector<Id> file_elem_id = read_id_map(exoid, EX_ELEM_MAP, init.num_elem, path, "element", mesh.warnings);
  // File element index (0-based over all blocks) -> mesh element, -1 if skipped.
  std::vector<Id> mesh_element(static_cast<std::size_t>(init.num_elem), -1);
  // Per mesh element: does its block use QUAD numbering (edges 1..4)?
  std::vector<bool> quad_numbering;
  const int corners = mesh.corners_per_element();
  std::int64_t kept_elements = 0;
  for (const BlockInfo& b : blocks)
    if (b.kept) kept_elements += b.count;
  mesh.conn.reserve(static_cast<std::size_t>(kept_elements * corners));
  mesh.element_file_id.reserve(static_cast<std::size_t>(kept_elements));
  mesh.element_block.reserve(static_cast<std::size_t>(kept_elements));
  // Second-order blocks: mid-node slots of every kept element (file node
  // indices, -1 none; first-order elements of a mixed file have none).
  const std::size_t slots = static_cast<std::size_t>(mid_slots(mesh.mode));
  std::vector<Id> mid;
  for (const BlockInfo& b : blocks)
    if (b.kept && b.count > 0 && b.nodes_per_element > corners) mid.reserve(static_cast<std::size_t>(kept_elements) * slots);
  const bool second_order = mid.capacity() > 0;
  std::size_t file_index = 0;
  for (const BlockInfo& b : blocks) {
    const std::size_t first = file_index;
    file_index += static_cast<std::size_t>(b.count);
    if (!b.kept || b.count == 0) continue;
    const std::string what = "element block " + std::to_string(b.id);
    std::vector<std::int64_t> conn(static_cast<std::size_t>(b.count * b.nodes_per_element));
    exodus::clear_error();
    check(ex_get_conn(exoid, EX_ELEM_BLOCK, b.id, conn.data(), nullptr, nullptr), path,
          "reading the connectivity of " + what);
    for (std::int64_t e = 0; e < b.count; ++e) {
      const std::size_t fe = first + static_cast<std::size_t>(e);
      if (second_order) mid.resize(mid.size() + slots, -1);
      for (int k = 0; k < b.nodes_per_element; ++k) {
        const std::int64_t node = conn[static_cast<std::size_t>(e * b.nodes_per_element + k)];
        if (node < 1 || node > init.num_nodes) {
          std::ostringstream os;
          os << what << ": element " << file_elem_id[fe] << " references node " << node << " (file has "
             << init.num_nodes << " nodes)";
          fail(ErrorKind::BadInput, path, os.str());
        }
        if (k < corners) mesh.conn.push_back(node - 1);
        else mid[mid.size() - slots + static_cast<std::size_t>(mid_slot(NodeOrder::Exodus, mesh.mode, k))] = node - 1;
      }
      mesh_element[fe] = static_cast<Id>(mesh.element_file_id.size());
      mesh.element_file_id.push_back(file_elem_id[fe]);
      mesh.element_block.push_back(b.index);
      quad_numbering.push_back(b.shape == Shape::Quad);
    }
  }

  // ---- side sets ----
  const std::vector<std::int64_t> side_set_ids = read_ids(exoid, EX_SIDE_SET, init.num_side_sets, path, "side set");
  const std::vector<std::string> side_set_names =
      read_names(exoid, EX_SIDE_SET, init.num_side_sets, name_buf, path, "side set");
  for (std::size_t s = 0; s < side_set_ids.size(); ++s) {
    SideSet set;
    set.id = side_set_ids[s];
    set.name = side_set_names[s];
    const std::string what = "side set " + std::to_string(set.id);
    std::int64_t count = 0, num_df = 0;
    exodus::clear_error();
    check(ex_get_set_param(exoid, EX_SIDE_SET, set.id, &count, &num_df), path, "reading " + what);
    check_count(count, 8, budget, file_size, path, "sides in " + what);
    std::vector<std::int64_t> elems(static_cast<std::size_t>(count)), sides(static_cast<std::size_t>(count));
    if (count > 0) {
      exodus::clear_error();
      check(ex_get_set(exoid, EX_SIDE_SET, set.id, elems.data(), sides.data()), path, "reading " + what);
    }
    std::int64_t dropped = 0;
    for (std::size_t i = 0; i < elems.size(); ++i) {
      const std::int64_t fe = elems[i];
      if (fe < 1 || fe > init.num_elem) {
        std::ostringstream os;
        os << what << ": entry " << i + 1 << " references element " << fe << " (file has " << init.num_elem
           << " elements)";
        fail(ErrorKind::BadInput, path, os.str());
      }
      const Id e = mesh_element[static_cast<std::size_t>(fe - 1)];
      if (e < 0) {
        ++dropped;
        continue;
      }
      // Exodus side numbers are 1-based: hex 1..6, shell 1..6 (1,2 faces,
      // 3..6 edges), quad 1..4 (edges, stored as shell edges 2..5).
      const bool quad = mesh.mode == Mode::Surface && quad_numbering[static_cast<std::size_t>(e)];
      const std::int64_t max_side = quad ? 4 : 6;
      const std::int64_t side = sides[i];
      if (side < 1 || side > max_side) {
        std::ostringstream os;
        os << what << ": element " << mesh.element_file_id[static_cast<std::size_t>(e)] << " has side " << side
           << " (a " << (mesh.mode == Mode::Volume ? "hex" : quad ? "quad" : "shell") << " has sides 1.." << max_side
           << ")";
        fail(ErrorKind::BadInput, path, os.str());
      }
      set.element.push_back(e);
      set.side.push_back(static_cast<std::int8_t>(quad ? side + 1 : side - 1));
    }
    if (dropped > 0)
      mesh.warnings.push_back(what + ": dropped " + std::to_string(dropped) +
                              " sides on elements of skipped blocks");
    mesh.side_sets.push_back(std::move(set));
  }

  // ---- node sets ----
  const std::vector<std::int64_t> node_set_ids = read_ids(exoid, EX_NODE_SET, init.num_node_sets, path, "node set");
  const std::vector<std::string> node_set_names =
      read_names(exoid, EX_NODE_SET, init.num_node_sets, name_buf, path, "node set");
  for (std::size_t s = 0; s < node_set_ids.size(); ++s) {
    NodeSet set;
    set.id = node_set_ids[s];
    set.name = node_set_names[s];
    const std::string what = "node set " + std::to_string(set.id);
    std::int64_t count = 0, num_df = 0;
    exodus::clear_error();
    check(ex_get_set_param(exoid, EX_NODE_SET, set.id, &count, &num_df), path, "reading " + what);
    check_count(count, 4, budget, file_size, path, "nodes in " + what);
    std::vector<std::int64_t> nodes(static_cast<std::size_t>(count));
    if (count > 0) {
      exodus::clear_error();
      check(ex_get_set(exoid, EX_NODE_SET, set.id, nodes.data(), nullptr), path, "reading " + what);
    }
    set.vertex.reserve(nodes.size());
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      if (nodes[i] < 1 || nodes[i] > init.num_nodes) {
        std::ostringstream os;
        os << what << ": entry " << i + 1 << " references node " << nodes[i] << " (file has " << init.num_nodes
           << " nodes)";
        fail(ErrorKind::BadInput, path, os.str());
      }
      set.vertex.push_back(nodes[i] - 1);
    }
    mesh.node_sets.push_back(std::move(set));
  }

  if (second_order) take_mid_nodes(mesh, std::move(mid));
  return mesh;
}

}  // namespace

}  // namespace dicer
