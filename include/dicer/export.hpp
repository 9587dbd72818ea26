#pragma once
// Export: pieces of a fine mesh too big to materialise, handed to solvers
// and viewers. Exporters see the mesh only through this header (and the
// public FineMesh API). Writers stream (ChunkStream): their memory is the
// cache budget plus O(slab), not the chunk's size.
//
// A chunk is a contiguous range of coarse elements in the store's (Morton)
// order, chosen so that chunk k of K holds about 1/K of the fine elements
// (the largest is within one coarse element of the ideal). All K chunks
// hold every fine element exactly once; a fine node on a chunk boundary is
// in every chunk that touches it, with the same global id and bit-identical
// coordinates, and `owner` names the lowest chunk that holds it.
//
// A box selection keeps the fine elements whose centroid lies in an
// axis-aligned box; coarse elements whose bounding box misses the box are
// pruned before any fine data is generated.
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "dicer/atomic_output.hpp"
#include "dicer/fine_mesh.hpp"

namespace dicer {

struct ChunkRange {
  Id index = 0, count = 1;         // chunk k of K
  Id first_coarse = 0, end_coarse = 0;  // coarse elements [first, end)
  Id fine_elements = 0;
  Id node_begin = 0, node_end = 0;  // the fine nodes the chunk owns: one id range (owner order)
};

// Balanced split of the coarse elements into `count` chunks by fine element
// count. Throws Error{Usage} for count < 1. O(count log H) rows read.
std::vector<ChunkRange> plan_chunks(const FineMesh& mesh, Id count);
// The same coarse element ranges as `plan` (made on another dicing of the
// same coarse mesh), with mesh's own fine element and node counts: nested
// levels (transfer.hpp) give each rank matching chunks on both. Throws
// Error{Usage} when the plan does not tile mesh's coarse elements.
std::vector<ChunkRange> plan_like(const FineMesh& mesh, const std::vector<ChunkRange>& plan);

struct Box {
  std::array<double, 3> lo{}, hi{};
  bool contains(double x, double y, double z) const {
    return x >= lo[0] && x <= hi[0] && y >= lo[1] && y <= hi[1] && z >= lo[2] && z <= hi[2];
  }
};
// "x0,y0,z0,x1,y1,z1"; throws Error{Usage} naming what is wrong.
Box parse_box(const std::string& text);
// Throws Error{Usage} ("<what>: ...") unless every coordinate is finite and
// lo <= hi on every axis (a NaN box would select nothing, silently).
void check_box(const Box& box, const std::string& what);

// Streams the fine elements whose centroid lies in `box`, in id order:
// fn(block, local element index) with the block's coordinates and
// connectivity filled; `block` is a slab of the coarse element's grid
// (FineBlock's plane0 and layers; the global id is block.first_element +
// index), so memory is O(n^2) per coarse element of interval n, however
// large the element. Time is every fine element of each coarse element the
// box meets. Coarse elements whose bounds (the store's spatial
// index: rows.hpp ElementBounds, curved elements included) miss the box are
// skipped without generating or reading anything else; whole groups of
// kBoundsGroup elements are skipped without reading. Returns the number of
// elements. Throws Error{Usage} for a box check_box refuses.
// [first_coarse, end_coarse) restricts the search (an MPI rank's chunk).
Id for_each_in_box(const FineMesh& mesh, const Box& box,
                   const std::function<void(const FineBlock& block, Id local_element)>& fn, Id first_coarse = 0,
                   Id end_coarse = -1);

// Side and node sets in the store's numbering (CoarseMesh::side_sets etc.).
struct MeshSets {
  std::vector<SideSet> side_sets;
  std::vector<NodeSet> node_sets;
};

// A chunk's members of one set, in local numbering.
struct SideMembers {
  std::int64_t id;
  std::string name;
  std::vector<Id> element;        // local element index, ascending
  std::vector<std::int8_t> side;  // 0-based Exodus side of the fine element (ascending per element)
};
struct NodeMembers {
  std::int64_t id;
  std::string name;
  std::vector<Id> node;  // local node index, ascending
};
// A node set as sorted, disjoint local id ranges [first, end): a coarse
// entity's nodes are one id run, so a set is a few ranges, not a list.
struct NodeRanges {
  std::int64_t id;
  std::string name;
  std::vector<std::array<Id, 2>> local;
};

// ---- What the writers read -------------------------------------------------
//
// A writer reads one chunk (or box selection) of the fine mesh in local
// numbering through ChunkSource, in passes:
//  1. nodes(): local ids 0 .. num_nodes() - 1 in order, in spans of
//     consecutive local ids. Local order is global id order; without a box
//     that is the chunk's ghosts (the nodes lower chunks own that its
//     elements use) and then its own id range [node_begin, node_end).
//  2. elements(): local elements in order (global id order), in spans of
//     consecutive local indices of one block; with a block named, that
//     block's elements only (the Exodus and MSH block order).
//  3. the sets, small (surface-sized) and held whole.
// A span's arrays are valid during the callback only. Every pass gives the
// same bits as node(id) and element(id).
// Two sources: ExportChunk holds the chunk in memory (prepare()), for the
// Python module, box selections and tests; ChunkStream generates every pass
// from the batch API (batch.hpp), so a writer needs O(slab) of fine data
// whatever the chunk's size.

struct NodeSpan {
  Id first = 0, count = 0;                 // local ids [first, first + count)
  const Id* global = nullptr;              // their global ids, ascending
  const double* x = nullptr;               // coordinates; null in a pass without them
  const double* y = nullptr;
  const double* z = nullptr;
  const std::uint32_t* users = nullptr;    // per node: index into user_sets()
};

struct ElementSpan {
  Id first = 0, count = 0;      // local element indices [first, first + count)
  const Id* global = nullptr;   // their global ids, ascending
  std::int32_t block = -1;      // index into mesh().info().blocks
  const Id* conn = nullptr;     // corners() node ids per element (VTK/Exodus order): local, or global if asked
};

class ChunkSource {
 public:
  virtual ~ChunkSource() = default;
  virtual const FineMesh& mesh() const = 0;
  virtual const ChunkRange& range() const = 0;
  Mode mode() const { return mesh().mode(); }
  int corners() const { return mesh().corners(); }
  virtual Id num_nodes() const = 0;
  virtual Id num_elements() const = 0;
  // The lowest and highest global element id of the chunk ({0, -1} when it
  // has none).
  virtual std::array<Id, 2> element_ids() const = 0;
  // The chunk's element count per block (index into mesh().info().blocks).
  virtual std::vector<Id> block_counts() const = 0;
  // The distinct sets of blocks whose elements (in this chunk) use a node,
  // each ascending; NodeSpan::users indexes them. Set b is {b} for every
  // block b of the mesh.
  virtual const std::vector<std::vector<std::int32_t>>& user_sets() const = 0;

  struct NodePass {
    bool coords = true;
    std::int32_t lowest_user = -1;  // >= 0: only the nodes whose lowest using block is this one
  };
  virtual void nodes(const NodePass& pass, const std::function<void(const NodeSpan&)>& fn) const = 0;
  struct ElementPass {
    std::int32_t block = -1;   // >= 0: that block's elements only
    bool global_conn = false;  // connectivity in global node ids instead of local ones
  };
  virtual void elements(const ElementPass& pass, const std::function<void(const ElementSpan&)>& fn) const = 0;

  virtual const std::vector<SideMembers>& side_sets() const = 0;  // sorted by element, then side
  virtual const std::vector<NodeRanges>& node_set_ranges() const = 0;
  // Local id of global node `id`; -1 if the chunk's elements do not use it.
  virtual Id local_of(Id id) const = 0;

  // A writer says how many passes with coordinates or connectivity it will
  // make, so that a source reporting progress can scale it. Default: none.
  virtual void expect_passes(int passes) const { (void)passes; }
};

// A chunk generated during each pass, never held: the writers' source for
// `dicer export` (every format, --chunk, --chunks, --nemesis, MPI ranks).
//
// What it holds (the constructor reads the chunk's coarse element rows
// once, no fine data): per coarse element of the chunk its first node and
// element ids and its block (20 B), the ghost nodes with coordinates
// (node(id), bit-identical; O(chunk boundary)), the runs of nodes on a
// boundary between blocks with the blocks using them (O(that boundary)),
// and the sets' members (O(set sizes): 9 B per side-set face, 25 B while
// sorted; more than available_memory_bytes() is Error{Usage} naming them,
// before any is gathered). A pass holds one slab of the batch
// API (kCursorSlabPoints grid points, ~2 MiB) and one element's boundary.
// So memory is the cache budget plus O(coarse elements + boundaries), not
// the chunk's fine size.
// Cost: a nodes() pass without coordinates reads nothing (the id ranges
// are held); one with coordinates, or an elements() pass, is one batch
// sweep (batch.hpp) of the elements concerned (one block's, when a pass
// names a block; its nodes that another block's element owns then come by
// random access, node(id)).
// Progress: `progress(done, total)` after each batch, counting coarse
// elements over the passes a writer announced (expect_passes); `cancel()`
// is polled between batches (true: Error{Cancelled, "interrupted"}).
// Thread safety: passes are const but not concurrent (one batch cursor
// each, progress state shared); the mesh may be shared.
class ChunkStream final : public ChunkSource {
 public:
  // Throws Error{Usage} for a range outside the mesh, Error{Corrupt} for
  // rows that contradict the numbering.
  ChunkStream(const FineMesh& mesh, ChunkRange range, const MeshSets& sets = {},
              std::function<void(Id, Id)> progress = {}, std::function<bool()> cancel = {});

  const FineMesh& mesh() const override { return mesh_; }
  const ChunkRange& range() const override { return range_; }
  Id num_nodes() const override { return num_ghosts() + (range_.node_end - range_.node_begin); }
  Id num_elements() const override { return range_.fine_elements; }
  std::array<Id, 2> element_ids() const override {
    return range_.fine_elements > 0 ? std::array<Id, 2>{element_first_.front(), element_first_.back() - 1}
                                    : std::array<Id, 2>{0, -1};
  }
  std::vector<Id> block_counts() const override { return block_counts_; }
  const std::vector<std::vector<std::int32_t>>& user_sets() const override { return user_sets_; }
  void nodes(const NodePass& pass, const std::function<void(const NodeSpan&)>& fn) const override;
  void elements(const ElementPass& pass, const std::function<void(const ElementSpan&)>& fn) const override;
  const std::vector<SideMembers>& side_sets() const override { return side_sets_; }
  const std::vector<NodeRanges>& node_set_ranges() const override { return node_sets_; }
  void expect_passes(int passes) const override;

  Id local_of(Id id) const override;  // O(log ghost runs)
  Id num_ghosts() const { return ghost_local_.empty() ? 0 : ghost_local_.back(); }

 private:
  struct Run {  // a run of consecutive node ids used by blocks user_sets_[users]
    Id first, count;
    std::uint32_t users;
  };
  struct Emitter;
  void step(Id coarse_elements) const;
  void poll() const;
  std::string where() const;

  const FineMesh& mesh_;
  ChunkRange range_;
  std::function<void(Id, Id)> progress_;
  std::function<bool()> cancel_;
  std::vector<Id> node_first_, element_first_;  // per coarse element of the chunk, + the end
  std::vector<std::int32_t> block_;             // per coarse element of the chunk
  std::vector<Id> block_counts_;
  std::vector<std::vector<std::int32_t>> user_sets_;
  std::vector<Run> ghosts_;            // sorted by first
  std::vector<Id> ghost_local_;        // local id of each ghost run's first node, + the end
  std::vector<double> gx_, gy_, gz_;   // ghost coordinates, in local order
  std::vector<Run> interfaces_;        // own runs used by more than one block, sorted
  std::vector<SideMembers> side_sets_;
  std::vector<NodeRanges> node_sets_;
  mutable Id done_ = 0, total_ = 0;
};

// One chunk (or box selection) with local numbering, held in memory.
// Build it with prepare(); then the spans stay valid until it is destroyed.
// Memory: O(nodes + elements of the chunk): 8 B per element id, 32 B per
// node (global id, x, y, z), 4 B per node owner and 4 B per node for its
// using blocks, corners x 8 B of connectivity per element, plus set
// members. The writers stream (ChunkStream); this is for callers that want
// the arrays (the Python module) and for box selections.
class ExportChunk final : public ChunkSource {
 public:
  using SideMembers = dicer::SideMembers;
  using NodeMembers = dicer::NodeMembers;
  ExportChunk(const FineMesh& mesh, ChunkRange range, std::optional<Box> box = std::nullopt);

  // Generates everything (without a box: from a ChunkStream's passes);
  // progress(done, total) after each coarse element; cancel() is polled
  // between coarse elements (returns true to stop: then prepare throws
  // Error{Cancelled, "interrupted"}).
  void prepare(const MeshSets& sets, const std::function<void(Id, Id)>& progress = {},
               const std::function<bool()>& cancel = {});

  // The whole plan this chunk belongs to (plan_chunks(mesh, range.count)),
  // when the caller has it: prepare() then needs no search of its own to
  // name the owners of shared nodes.
  void set_plan(std::vector<ChunkRange> plan) { plan_ = std::move(plan); }

  const FineMesh& mesh() const override { return mesh_; }
  const ChunkRange& range() const override { return range_; }
  Id num_nodes() const override { return static_cast<Id>(node_global_.size()); }
  Id num_elements() const override { return static_cast<Id>(elem_global_.size()); }
  std::array<Id, 2> element_ids() const override {
    return elem_global_.empty() ? std::array<Id, 2>{0, -1} : std::array<Id, 2>{elem_global_.front(), elem_global_.back()};
  }

  // Nodes in local order: sorted by global id. Without a box: the nodes
  // other chunks own (lower ids), then the chunk's own id range.
  std::span<const Id> node_global() const { return node_global_; }
  std::span<const double> x() const { return x_; }
  std::span<const double> y() const { return y_; }
  std::span<const double> z() const { return z_; }
  std::span<const std::int32_t> node_owner() const { return owner_; }  // lowest chunk index holding the node
  std::span<const std::uint32_t> node_users() const { return users_; }  // index into user_sets()

  // Elements in global id order, grouped by nothing: see block_of.
  std::span<const Id> element_global() const { return elem_global_; }
  std::span<const std::int32_t> element_block() const { return elem_block_; }  // index into mesh().info().blocks
  // corners() local node ids (0-based) per element, VTK/Exodus HEX8 or QUAD4 order.
  std::span<const Id> connectivity() const { return conn_; }

  // Per set: the chunk's members.
  const std::vector<SideMembers>& side_sets() const override { return side_sets_; }
  const std::vector<NodeMembers>& node_sets() const { return node_sets_; }

  // ChunkSource, over the arrays above.
  std::vector<Id> block_counts() const override;
  const std::vector<std::vector<std::int32_t>>& user_sets() const override { return user_sets_; }
  void nodes(const NodePass& pass, const std::function<void(const NodeSpan&)>& fn) const override;
  void elements(const ElementPass& pass, const std::function<void(const ElementSpan&)>& fn) const override;
  const std::vector<NodeRanges>& node_set_ranges() const override { return node_ranges_; }
  Id local_of(Id id) const override;  // O(log nodes)

 private:
  void prepare_box(const MeshSets& sets, const std::function<void(Id, Id)>& progress,
                   const std::function<bool()>& cancel);
  const FineMesh& mesh_;
  ChunkRange range_;
  std::optional<Box> box_;
  std::vector<ChunkRange> plan_;
  std::vector<Id> node_global_, elem_global_, conn_;
  std::vector<double> x_, y_, z_;
  std::vector<std::int32_t> owner_, elem_block_;
  std::vector<std::uint32_t> users_;
  std::vector<std::vector<std::int32_t>> user_sets_;
  std::vector<SideMembers> side_sets_;
  std::vector<NodeMembers> node_sets_;
  std::vector<NodeRanges> node_ranges_;
};

// Bytes an ExportChunk of `range` holds once prepared (what its comment
// above lists), from the range's element and own node counts (O(1) rows
// read). ExportChunk::prepare() refuses a chunk (no box) whose estimate
// exceeds the memory available to the process (MemAvailable, RLIMIT_AS)
// with Error{Usage} giving the estimate and a chunk count that fits. A
// ChunkStream needs no such check: it holds no fine data.
std::uint64_t estimate_chunk_bytes(const FineMesh& mesh, const ChunkRange& range);
void refuse_if_too_big(const FineMesh& mesh, const ChunkRange& range);

// Writers. Each writes to `path` through a temporary name in the same
// folder, renamed when complete (an interrupted export leaves nothing under
// the final name). Throw Error{Io|Usage}.
//
// VTKHDF (UnstructuredGrid 1.0, one partition per chunk): chunks are
// appended one after another with write_partition; `finish` renames. Each
// partition's datasets are sized up front and filled by hyperslab writes
// as a pass produces them. Compression: `deflate` 0 (the default) stores
// the datasets without a filter; 1..9 use HDF5's built-in deflate at that
// level with byte shuffle first (the only filters ParaView/VTK 9.1's
// vtkHDFReader opens without a plugin). bench/README.md "Streaming export"
// has the rates and sizes that chose the default.
//
// Collective mode (the MPI layer, include/dicer/mpi.hpp, fills this in so
// that export/ needs no MPI header): every rank of a job writes its one
// partition of the same parallel HDF5 file, rank r as partition r, at the
// offsets of the partitions before it. The same datasets and values as
// one process appending the P chunks in order.
struct VtkHdfCollective {
  int rank = 0, size = 1;
  std::int64_t file_access = -1;  // hid_t: an MPI-IO file access property list
  std::int64_t transfer = -1;     // hid_t: a collective transfer property list
  // One value from every rank, in rank order (an allgather).
  std::function<std::vector<std::int64_t>(std::int64_t)> allgather;
  // Rank 0's string on every rank.
  std::function<std::string(const std::string&)> broadcast;
  // Every rank passes its local failure (or nullptr); throws on every rank
  // if any failed (mpi::checkpoint).
  std::function<void(std::exception_ptr)> checkpoint;
};

class VtkHdfWriter {
 public:
  VtkHdfWriter(const std::string& path, Id partitions, int deflate = 0);
  // Collective: size() partitions, this rank writes partition rank().
  VtkHdfWriter(const std::string& path, const VtkHdfCollective& collective, int deflate = 0);
  ~VtkHdfWriter();
  void write_partition(const ChunkSource& chunk);
  void finish();

 private:
  struct Impl;
  Impl* impl_;
};

// A finished file not yet in place (AtomicOutput, parked): commit() puts it
// there; destroyed uncommitted, it is removed. Files that belong together
// (a Nemesis set OUT.N.r, an MSH set under mpirun) are written each into
// one, then committed together: a failure or a signal while any is being
// written leaves every old file as it was.
using PendingFile = std::unique_ptr<AtomicOutput>;
// A writer's last step: commits `file`, or with `pending` parks it there.
void commit_or_pend(PendingFile& file, PendingFile* pending);

// Gmsh MSH 4.1, ASCII or binary: one volume (surface) entity and physical
// group per block, boundary elements per side set as surface (curve)
// entities with physical groups. Passes: nodes without coordinates (counts,
// tags), nodes with coordinates twice (entity boxes, then the $Nodes
// section), elements once per block entity (plus once with global
// connectivity when side sets have members).
// `pending`: the file is left there uncommitted (PendingFile), not committed.
void write_msh(const ChunkSource& chunk, const std::string& path, bool binary, PendingFile* pending = nullptr);
// Whether write_msh writes side `side` (0-based Exodus) of an element:
// every hex side; a shell's edge sides 2..5 but not its face sides 0 and 1,
// the quad itself, for which MSH has no boundary element.
bool msh_writes_side(Mode mode, int side);

// Exodus II through the Exodus library: element blocks with names, side sets
// and node sets, global node and element id maps (1-based: global id + 1),
// 64-bit integers; netCDF-4 when the counts need it.
//
// With `nemesis`, the file is one processor's part of a Nemesis (decomposed
// Exodus) set, OUT.P.r (nemesis_path): global parameters, load-balance
// parameters, processor node and element maps and node communication maps
// (the Partition's), every global block and set listed in every file.
// Element-based decomposition: nodes on a processor boundary are "border"
// nodes in every file that has them, there are no "external" nodes; an
// element with a border node is a border element; no element maps.
struct NemesisInfo {
  Id processors = 1, processor = 0;
  Id global_nodes = 0, global_elements = 0;
  std::vector<std::int64_t> side_set_counts, node_set_counts;  // global, in the chunk's set order
  std::vector<std::int32_t> neighbors;                         // node map ids: the neighbouring processors
  std::vector<std::vector<Id>> shared;                         // per neighbour: chunk-local node ids (0-based)
};
// Coordinates, id maps, connectivity and node sets go out with the Exodus
// library's partial writers (ex_put_partial_coord, _id_map, _elem_conn,
// _set) slice by slice; side sets whole. Nemesis adds a pass over the
// elements before the header (border elements) and holds its processor
// node and element maps: 8 B per node and per element (Exodus 6.02 has no
// partial writer for them).
// `pending`: as for write_msh.
void write_exodus(const ChunkSource& chunk, const std::string& path, const NemesisInfo* nemesis = nullptr,
                  PendingFile* pending = nullptr);

// "OUT.P.r" with r zero-padded to the digits of P (SEACAS epu/decomp, MOOSE).
std::string nemesis_path(const std::string& out, Id processors, Id processor);

// Global fine counts of each set, from the coarse rows alone (no fine data):
// a side set's fine faces, a node set's fine nodes (every node whose owning
// entity has all its corners in the set). O(coarse rows).
struct SetCounts {
  std::vector<std::int64_t> side, node;
};
SetCounts global_set_counts(const FineMesh& mesh, const MeshSets& sets);


}  // namespace dicer
