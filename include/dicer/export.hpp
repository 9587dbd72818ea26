#pragma once
// Export: pieces of a fine mesh too big to materialise, handed to solvers
// and viewers. Exporters see the mesh only through this header (and the
// public FineMesh API); their memory is bounded by the chunk, not the mesh.
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
#include <optional>
#include <span>
#include <string>
#include <vector>

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

// Streams the fine elements whose centroid lies in `box`, in id order:
// fn(block, local element index) with the block's coordinates and
// connectivity filled. Coarse elements whose bounds (the store's spatial
// index: rows.hpp ElementBounds, curved elements included) miss the box are
// skipped without generating or reading anything else; whole groups of
// kBoundsGroup elements are skipped without reading. Returns the number of
// elements.
// [first_coarse, end_coarse) restricts the search (an MPI rank's chunk).
Id for_each_in_box(const FineMesh& mesh, const Box& box,
                   const std::function<void(const FineBlock& block, Id local_element)>& fn, Id first_coarse = 0,
                   Id end_coarse = -1);

// Side and node sets in the store's numbering (CoarseMesh::side_sets etc.).
struct MeshSets {
  std::vector<SideSet> side_sets;
  std::vector<NodeSet> node_sets;
};

// One chunk (or box selection) with local numbering, ready to write.
// Build it with prepare(); then the spans stay valid until it is destroyed.
// Memory: O(nodes + elements of the chunk): 8 B per element id, 32 B per
// node (global id, x, y, z), 4 B per node owner, corners x 8 B of
// connectivity per element, plus set members.
class ExportChunk {
 public:
  ExportChunk(const FineMesh& mesh, ChunkRange range, std::optional<Box> box = std::nullopt);

  // Generates everything; progress(done, total) after each coarse element;
  // cancel() is polled between coarse elements (returns true to stop: then
  // prepare throws Error{Cancelled, "interrupted"}).
  void prepare(const MeshSets& sets, const std::function<void(Id, Id)>& progress = {},
               const std::function<bool()>& cancel = {});

  // The whole plan this chunk belongs to (plan_chunks(mesh, range.count)),
  // when the caller has it: prepare() then needs no search of its own to
  // name the owners of shared nodes.
  void set_plan(std::vector<ChunkRange> plan) { plan_ = std::move(plan); }

  const FineMesh& mesh() const { return mesh_; }
  const ChunkRange& range() const { return range_; }
  Mode mode() const { return mesh_.mode(); }
  int corners() const { return mesh_.corners(); }
  Id num_nodes() const { return static_cast<Id>(node_global_.size()); }
  Id num_elements() const { return static_cast<Id>(elem_global_.size()); }

  // Nodes in local order: sorted by global id. Without a box: the nodes
  // other chunks own (lower ids), then the chunk's own id range.
  std::span<const Id> node_global() const { return node_global_; }
  std::span<const double> x() const { return x_; }
  std::span<const double> y() const { return y_; }
  std::span<const double> z() const { return z_; }
  std::span<const std::int32_t> node_owner() const { return owner_; }  // lowest chunk index holding the node

  // Elements in global id order, grouped by nothing: see block_of.
  std::span<const Id> element_global() const { return elem_global_; }
  std::span<const std::int32_t> element_block() const { return elem_block_; }  // index into mesh().info().blocks
  // corners() local node ids (0-based) per element, VTK/Exodus HEX8 or QUAD4 order.
  std::span<const Id> connectivity() const { return conn_; }

  // Per set: the chunk's members.
  struct SideMembers {
    std::int64_t id;
    std::string name;
    std::vector<Id> element;          // local element index
    std::vector<std::int8_t> side;    // 0-based Exodus side of the fine element
  };
  struct NodeMembers {
    std::int64_t id;
    std::string name;
    std::vector<Id> node;             // local node index
  };
  const std::vector<SideMembers>& side_sets() const { return side_sets_; }
  const std::vector<NodeMembers>& node_sets() const { return node_sets_; }

 private:
  const FineMesh& mesh_;
  ChunkRange range_;
  std::optional<Box> box_;
  std::vector<ChunkRange> plan_;
  std::vector<Id> node_global_, elem_global_, conn_;
  std::vector<double> x_, y_, z_;
  std::vector<std::int32_t> owner_, elem_block_;
  std::vector<SideMembers> side_sets_;
  std::vector<NodeMembers> node_sets_;
};

// Bytes an ExportChunk of `range` holds once prepared (what its comment
// above lists), from the range's element and own node counts (O(1) rows
// read). prepare() refuses a chunk (no box) whose estimate exceeds the
// memory available to the process (MemAvailable, RLIMIT_AS) with
// Error{Usage} giving the estimate and a chunk count that fits.
std::uint64_t estimate_chunk_bytes(const FineMesh& mesh, const ChunkRange& range);
void refuse_if_too_big(const FineMesh& mesh, const ChunkRange& range);

// Writers. Each writes to `path` through a temporary name in the same
// folder, renamed when complete (an interrupted export leaves nothing under
// the final name). Throw Error{Io|Usage}.
//
// VTKHDF (UnstructuredGrid 1.0, one partition per chunk): chunks are
// appended one after another with write_vtkhdf_partition; `finish` renames.
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
  VtkHdfWriter(const std::string& path, Id partitions);
  // Collective: size() partitions, this rank writes partition rank().
  VtkHdfWriter(const std::string& path, const VtkHdfCollective& collective);
  ~VtkHdfWriter();
  void write_partition(const ExportChunk& chunk);
  void finish();

 private:
  struct Impl;
  Impl* impl_;
};

// Gmsh MSH 4.1, ASCII or binary: one volume (surface) entity and physical
// group per block, boundary elements per side set as surface (curve)
// entities with physical groups.
void write_msh(const ExportChunk& chunk, const std::string& path, bool binary);

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
void write_exodus(const ExportChunk& chunk, const std::string& path, const NemesisInfo* nemesis = nullptr);

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
