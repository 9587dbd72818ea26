#pragma once
// FineMesh: the implicit fine mesh. Nothing fine-sized is ever stored; every
// node and element is regenerated on demand from the coarse mesh tables
// (tables.hpp) by the recipe in tfi.hpp.
//
// The tables are either in memory (right after FineMesh::dice) or pages of
// a store read through a bounded PageCache (read_store); the code path is
// the same, so both give the same bits.
//
// Access paths, all bit-identical for the same node id (invariant 2):
//  1. node(id) / element(id): random access, O(log n) lookup + O(1) TFI.
//     Node ids are in owner order (numbering.hpp): coarse element by coarse
//     element, what each owns.
//  2. fill_block(h, block): every node and element of coarse element h, as
//     contiguous arrays (ids, x, y, z, connectivity). O(block size); a
//     reused FineBlock allocates nothing once warm.
//  3. NodeCursor / ElementCursor: whole-mesh iteration in id order.
// Memory: O(blocks) metadata + the tables (in memory) or the cache budget
// (paged), plus one slab (kCursorSlabPoints grid points) per cursor.
// Thread safety: const member functions may be called concurrently; the
// overloads taking a MeshCursor need one cursor per thread.
#include <array>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/intervals.hpp"
#include "dicer/numbering.hpp"
#include "dicer/tables.hpp"
#include "dicer/tfi.hpp"

namespace dicer {

struct FineElement {
  Id id = -1;
  // VTK/Exodus HEX8 order (volume) or QUAD4 order (surface, first 4 used).
  std::array<Id, 8> nodes{};
  int num_nodes = 8;
  Id coarse_element = -1;
  std::int32_t block = -1;       // index into MeshInfo::blocks
  std::array<Id, 3> ijk{};       // position in the coarse element's local grid
};

// The nodes and elements of one coarse element, or of a slab of its grid
// planes (fill_slab). Grid point (i, j, k) is at index
// i + (n[0]+1) * (j + (n[1]+1) * (k - plane0)); element (i, j, k) at
// i + n[0] * (j + n[1] * (k - plane0)), its nodes at conn[corners*e ...].
struct FineBlock {
  Id coarse_element = -1;
  std::array<Id, 3> n{};         // intervals along local i, j, k (k = 1 in surface mode)
  Id first_element = 0;          // fine id of element (0, 0, plane0); elements are consecutive
  Id node_first = 0;             // node ids >= this are the coarse element's own (owner order)
  std::int32_t block = -1;
  Id plane0 = 0;                 // grid planes [plane0, plane0 + planes) are held
  Id planes = 0;
  Id layers = 0;                 // element layers held (planes - 1; 1 in surface mode)
  std::vector<Id> node_id;       // per grid point
  std::vector<double> x, y, z;   // per grid point (empty when filled without coordinates)
  std::vector<Id> conn;          // corners per element, fine node ids (empty if not asked)
  Id num_points() const { return static_cast<Id>(node_id.size()); }
  Id num_elements() const { return n[0] * n[1] * layers; }
  Id point_index(Id i, Id j, Id k) const { return i + (n[0] + 1) * (j + (n[1] + 1) * (k - plane0)); }
  // Bytes its arrays hold (capacities, scratch included): what refilling
  // it with an element no larger than the last needs no new memory for.
  std::size_t held_bytes() const;

  // Work space of fill_block, kept here so a reused block allocates nothing.
  struct Scratch {
    Vec3 corner[8];
    std::vector<double> edge[12][3], face[6][3];  // the element's edges' and faces' points, canonical order
    std::vector<double> bottom[3], top[3], left[3], right[3], s, t, u, v, w, P, G, patch;
    // The boundary (corners, edges, faces) of the element filled last, so a
    // block produced slab by slab evaluates it once: planes k = 0 and k = n[2]
    // whole, then for each 0 < k < n[2] the ring of plane k (j = 0, j = n[1],
    // i = 0, i = n[0]). O(n^2). Keyed on the mesh's identity and element.
    struct Boundary {
      // What is held besides the ids: Corners = the corners (all a
      // straight hex's interior reads; a batch has its owned entities
      // written straight into its arrays, not kept here); All = every
      // entity, in `Scratch`'s canonical arrays, and x holds every
      // boundary point.
      enum class Held : std::uint8_t { Ids, Corners, All };
      std::uint64_t mesh = 0;
      Id h = -1;
      Held held = Held::Ids;
      bool volume = true;
      std::array<Id, 3> n{};
      std::vector<Id> id;
      std::vector<double> x[3];
      Id plane() const { return (n[0] + 1) * (n[1] + 1); }
      Id perimeter() const { return 2 * (n[0] + 1) + 2 * (n[1] - 1); }
      Id size() const { return volume ? 2 * plane() + (n[2] - 1) * perimeter() : plane(); }
      // Slot of boundary grid point (i, j, k); (0, 0, k) is the start of plane
      // k (k = 0, n[2]) or of its ring.
      Id index(Id i, Id j, Id k) const {
        const Id ni = n[0] + 1;
        if (!volume || k == 0) return i + ni * j;
        if (k == n[2]) return plane() + i + ni * j;
        const Id ring = 2 * plane() + (k - 1) * perimeter();
        if (j == 0) return ring + i;
        if (j == n[1]) return ring + ni + i;
        return ring + 2 * ni + (i == 0 ? 0 : n[1] - 1) + j - 1;
      }
    } boundary;
  } scratch;
  MeshCursor cursor;
};

// Small per-mesh facts, always in memory: O(blocks).
// How a sheet is graded (intervals.hpp): its series (flip unused) and,
// geometric, the input file's node id its series starts at (-1 otherwise).
struct SheetGrading {
  tfi::Grading grading;
  Id start = -1;
  friend bool operator==(const SheetGrading&, const SheetGrading&) = default;
};

struct MeshInfo {
  Mode mode = Mode::Volume;
  std::string source;                    // the coarse mesh file it was diced from
  std::string geometry;                  // the CAD file its boundary was put on (dice --geometry), or empty
  int source_order = 1;                  // 2: the file was second order (HEX20/27, QUAD8/9; quadratic.hpp)
  std::string uuid;                      // the store's identity (store/FORMAT.md); empty for a mesh diced here
  Id coarse_vertices = 0, coarse_edges = 0, coarse_faces = 0, coarse_elements = 0, sheets = 0;
  Id nodes = 0, elements = 0;            // fine counts
  std::vector<Block> blocks;
  std::vector<Id> block_coarse_elements, block_fine_elements;
};

class FineMesh {
 public:
  FineMesh() = default;
  FineMesh(MeshInfo info, MeshTables tables, std::shared_ptr<const CoarseMesh> coarse = nullptr);

  // Builds topology, sheets and intervals for `coarse` and dices it, in
  // memory. Coarse elements are first put in space-filling-curve order of
  // their centroids (locality of pages); sheet ids stay those of the input
  // file. `notes` receives how interval conflicts were resolved.
  // `locality_order` = false keeps the input order (benchmarks compare).
  static FineMesh dice(CoarseMesh coarse, const IntervalRequest& request, std::vector<std::string>* notes = nullptr,
                       bool locality_order = true);

  Mode mode() const { return info_.mode; }
  const MeshInfo& info() const { return info_; }
  const MeshTables& tables() const { return tables_; }
  // The name errors give this mesh (read_store gives a store its path).
  void set_origin(std::string name) { tables_.origin = std::move(name); }
  // Interval of every sheet (ids of the input file), when diced in this
  // process or read from a store.
  const std::vector<Id>& sheet_intervals() const { return sheet_intervals_; }
  void set_sheet_intervals(std::vector<Id> s) { sheet_intervals_ = std::move(s); }
  // Grading of every sheet (ids of the input file), as sheet_intervals().
  const std::vector<SheetGrading>& sheet_gradings() const { return sheet_gradings_; }
  void set_sheet_gradings(std::vector<SheetGrading> s) { sheet_gradings_ = std::move(s); }
  // The reordered coarse mesh with its sets, when diced in this process
  // (nullptr when opened from a store: sets stay on disk).
  const CoarseMesh* coarse() const { return coarse_.get(); }
  Id num_nodes() const { return info_.nodes; }
  Id num_elements() const { return info_.elements; }
  Id num_coarse_elements() const { return info_.coarse_elements; }
  int corners() const { return mode() == Mode::Volume ? 8 : 4; }

  // Error{Usage} unless [begin, end) is a range of ids of the mesh
  // (0 <= begin <= end <= count); the message names the first id that is
  // not one, in the words node(id) and element(id) use.
  void check_node_range(Id begin, Id end) const;
  void check_element_range(Id begin, Id end) const;

  // Throw Error{Usage} for an id out of range.
  Vec3 node(Id id) const;
  FineElement element(Id id) const;
  Vec3 node(Id id, MeshCursor& cur) const;
  FineElement element(Id id, MeshCursor& cur) const;
  Vec3 node(const NodeRef& ref, MeshCursor& cur) const;
  // Many queries at once: out[q] = node(ids[q], cur) (element(ids[q],
  // cur)), bit for bit, ids in any order, repeats allowed; Error{Usage}
  // unless out.size() == ids.size(). The ids are visited in increasing
  // order (sorted through an index when they are not already: O(n log n)
  // time, 8n bytes), so each coarse element is searched for, decoded and
  // has its corners read once for all the ids it holds: much cheaper per id
  // than one call each when ids share coarse elements (bench/README).
  // Errors as one call each, the lowest bad id's; out is then partly
  // written.
  void nodes(std::span<const Id> ids, std::span<Vec3> out, MeshCursor& cur) const;
  void elements(std::span<const Id> ids, std::span<FineElement> out, MeshCursor& cur) const;

  // Numbering (DESIGN.md invariant 3), see numbering.hpp for the layout.
  // The nodes coarse elements [first, end) own: one id range.
  std::array<Id, 2> owned_nodes(Id first, Id end, MeshCursor& cur) const;
  NodeRef locate_node(Id id, MeshCursor& cur) const;
  Id node_id(const NodeRef& ref, MeshCursor& cur) const;
  Id locate_element(Id id, std::array<Id, 3>& ijk, MeshCursor& cur) const;
  // The node at grid point (i, j, k) of coarse element h, as its owner sees it.
  NodeRef grid_node(Id h, Id i, Id j, Id k, MeshCursor& cur) const;

  // Fills out with every node of coarse element h (ids, x, y, z) and, unless
  // nodes_only, its elements' connectivity (conn).
  void fill_block(Id h, FineBlock& out, bool nodes_only = false) const;
  // Grid planes k0..k1 of coarse element h (k1 = -1: the last; both 0 in
  // surface mode), with the element layers between them when `conn`
  // (then k0 < k1 in volume mode), coordinates only when `coords`. The same
  // values, bit for bit, as fill_block. A block's boundary is evaluated once
  // and kept in `out` (O(n^2)), so consecutive slabs of one element cost
  // only their own planes: cursors use this to hold O(n^2), not O(n^3).
  void fill_slab(Id h, Id k0, Id k1, FineBlock& out, bool coords, bool conn) const;
  // Coarse element h a slab at a time, for callers that visit every fine
  // element of it: fill_slab (coordinates; connectivity when conn) over
  // consecutive planes of about kCursorSlabPoints grid points, fn(out)
  // after each; one slab when the element is small (up to ~40 intervals).
  // Memory O(n^2) for interval n where fill_block holds O(n^3) (a box
  // meeting one element of interval 400 held 6 GB). Element e of a slab is
  // grid element (i, j, plane0 + layer): FineBlock's layout.
  void for_each_slab(Id h, FineBlock& out, bool conn, const std::function<void(const FineBlock&)>& fn) const;

  // ---- Geometry-conforming dicing (geometry/conform.cpp drives these, and
  // dicer/quadratic.cpp the move_nodes of second-order input; they need the
  // in-memory tables of a mesh diced in this process).
  // Moves coarse vertex v (snapped onto its CAD entity) and records its owner.
  // Only before any move_nodes.
  void set_vertex(Id v, const Vec3& x, int dim, int tag);
  // Records the geometric owner (pack_owner) of a coarse edge or face.
  void set_owner(EntityKind kind, Id entity, std::int64_t owner);
  // Owner of a vertex, edge or face (-1 unknown). Works on a store too.
  std::int64_t owner(EntityKind kind, Id entity, MeshCursor& cur) const;
  // Replaces the interior fine nodes of a coarse edge (n-1 points, canonical
  // order) or face ((nu-1)(nv-1) points, u fastest) by `xyz`, kept as
  // bounding rows relative to the TFI prediction. Every edge must be moved
  // before the first face (a face's prediction is the Coons patch of its
  // moved sides); each entity at most once. Then finish_moves().
  void move_nodes(EntityKind kind, Id entity, std::span<const Vec3> xyz);
  // Flags the elements that touch moved nodes (their interiors read them).
  void finish_moves();
  // Records the CAD file the boundary was put on (MeshInfo::geometry).
  void set_geometry_source(std::string cad_path) { info_.geometry = std::move(cad_path); }
  // Number of fine nodes moved (onto the CAD, or a second-order mesh's
  // quadratic edges and faces): rows of the bounding arrays.
  Id num_bounding_nodes() const { return tables_.bounding.rows(); }

 private:
  MeshInfo info_;
  MeshTables tables_;
  std::shared_ptr<const CoarseMesh> coarse_;
  std::vector<Id> sheet_intervals_;
  std::vector<SheetGrading> sheet_gradings_;
  bool faces_moved_ = false;
  std::vector<Id> vertex_uses_, vertex_uses_offset_;  // set_vertex: vertex -> 8 * element + corner (CSR)
  // Identity of this mesh's content (a new value on every change), the key
  // of a FineBlock's cached boundary.
  std::uint64_t serial_ = next_serial();
  // For BatchCursor: fill_slab with the interior points of planes k0 < k <=
  // min(k1, n[2] - 1) written compact, in id order, to interior[d] (volume
  // mode), and out.x, y, z left as work space. interior[d] has room for 8
  // doubles past those points (the straight kernel writes whole blocks:
  // dicer/evaluate.hpp, bilinear_patch). row: h's row, already
  // decoded by the caller (null: decoded here). own (a straight hex, k0 =
  // 0): the coordinates of the nodes h owns outside its interior written
  // to own[d][id - node_first] (own_size values, then room for 8 doubles
  // the interior overwrites), with no copy through the block's scratch.
  // ids = false (and no conn): out.node_id left empty (the batch's lines
  // come from the boundary the slab keeps, detail::slab_lines).
  friend class BatchCursor;
  void fill_slab(Id h, Id k0, Id k1, FineBlock& out, bool coords, bool conn, bool ids, double* const* interior,
                 const ElementRow* row, double* const* own = nullptr, Id own_size = 0) const;
  static std::uint64_t next_serial();
  void require_memory(const char* what) const;
};

// What this process can still allocate, in bytes: the memory the kernel
// says is available (MemAvailable) and, under an address-space limit
// (RLIMIT_AS), what is not mapped yet. Reads /proc: for a check before a
// large allocation, not per block.
std::uint64_t available_memory_bytes();

// The memory a coarse element takes to be read `how` (a slab of grid
// planes, whole, ...) is O(interval^2) or more: an element too large for
// this process is refused by name (a Usage error naming the store, the
// element, its intervals, `how` and about `bytes`), before allocating when
// the bytes beyond those the caller already holds (`held`, reused) exceed
// 256 MiB and what available_memory_bytes() says is left, and on a failed
// allocation (element_too_big). The kernel grants memory lazily: without
// the check the machine would swap, or kill the process.
Error element_too_big(const FineMesh& mesh, Id h, const std::array<Id, 3>& n, const char* how, double bytes);
void check_element_memory(const FineMesh& mesh, Id h, const std::array<Id, 3>& n, const char* how,
                          double bytes, double held);

namespace detail {
// What a memory cgroup (v2 memory.max - memory.current, v1
// memory.limit_in_bytes - memory.usage_in_bytes, of the process's group
// and its ancestors; usage less the reclaimable inactive file pages of
// memory.stat) leaves, in bytes; UINT64_MAX without a limit.
// `proc_cgroup`: /proc/self/cgroup's text; `root`: the cgroup mount.
std::uint64_t cgroup_memory_left(const std::string& proc_cgroup, const std::string& root);
}  // namespace detail

// Grid points a cursor's slab holds (rounded to whole planes, at least
// one): 2^16 points are ~2 MiB of ids and coordinates at any interval.
inline constexpr Id kCursorSlabPoints = Id{1} << 16;

class BatchCursor;
struct FineBatch;

// Whole-mesh node iteration in id order [begin, end), one node per call,
// over the batches of batch.hpp (a coarse element's own boundary nodes,
// then its interior slab by slab): O(interval^2) memory. Starting mid-way
// costs at most one slab before `begin`.
class NodeCursor {
 public:
  NodeCursor(const FineMesh& mesh, Id begin, Id end, Id slab_points = kCursorSlabPoints);
  explicit NodeCursor(const FineMesh& mesh) : NodeCursor(mesh, 0, mesh.num_nodes()) {}
  ~NodeCursor();
  NodeCursor(const NodeCursor&) = delete;
  NodeCursor& operator=(const NodeCursor&) = delete;
  // Next node; false at the end.
  bool next(Id& id, Vec3& xyz);

 private:
  const FineMesh& mesh_;
  Id next_, end_, slab_points_;
  std::unique_ptr<BatchCursor> batches_;  // made at the first call
  std::unique_ptr<FineBatch> batch_;      // the batch holding next_
};

// Whole-mesh element iteration in id order [begin, end), over the batches
// of batch.hpp (connectivity only, no coordinates).
class ElementCursor {
 public:
  ElementCursor(const FineMesh& mesh, Id begin, Id end, Id slab_points = kCursorSlabPoints);
  explicit ElementCursor(const FineMesh& mesh) : ElementCursor(mesh, 0, mesh.num_elements()) {}
  ~ElementCursor();
  ElementCursor(const ElementCursor&) = delete;
  ElementCursor& operator=(const ElementCursor&) = delete;
  bool next(FineElement& out);

 private:
  const FineMesh& mesh_;
  Id next_, end_, slab_points_;
  std::unique_ptr<BatchCursor> batches_;
  std::unique_ptr<FineBatch> batch_;
};

}  // namespace dicer
