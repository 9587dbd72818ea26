#pragma once
// Partition: the part of the fine mesh that rank r of P works on, with the
// communication maps a distributed solver needs. No files, no MPI here:
// the MPI layer (mpi/) exchanges the sharing information between ranks,
// a single process computes it for every chunk itself (in_process_sharing),
// and both give the same maps.
//
// Rank r holds chunk r of plan_chunks(mesh, P): a contiguous range of
// coarse elements in store order, balanced by fine elements.
//  - Elements: the chunk's fine elements, global ids one contiguous range
//    [element_begin, element_end), connectivity in local node ids
//    (VTK/Exodus HEX8 or QUAD4 order).
//  - Nodes, local order: the nodes the rank owns first (one global id
//    range, [node_begin, node_end): owner order, numbering.hpp), then the
//    ghosts (nodes its elements use that lower ranks own) sorted by global
//    id, each with its owner rank.
//  - Neighbours: every other rank whose elements use one of this rank's
//    nodes, or own/use one of its ghosts; for each, the local ids of the
//    nodes both use, sorted by global id, so the two sides list the shared
//    nodes in the same order (Nemesis node communication maps).
//
// Sharing works on entity runs: every coarse vertex, edge and face owns one
// run of consecutive node ids, so "which ranks use this node" is decided
// per run, never per node. Cost: a partition materialises its chunk (as an
// ExportChunk does); the runs are O(coarse entities on the chunk's
// boundary).
#include <cstdint>
#include <span>
#include <vector>

#include "dicer/export.hpp"

namespace dicer {

// A run of node ids owned by one coarse entity, and the chunks using it.
struct NodeRun {
  Id first = 0, count = 0;
  std::int32_t owner = 0;               // the chunk owning the run
  std::vector<std::int32_t> users;      // every chunk whose elements use it, owner included, sorted
  friend bool operator==(const NodeRun&, const NodeRun&) = default;
};

// The runs chunk c's elements use that other chunks own (its ghosts), one
// per entity, sorted by first id: reads chunk c's element rows. `users`
// holds only {owner, c}. O(chunk elements).
std::vector<NodeRun> ghost_runs(const FineMesh& mesh, const std::vector<ChunkRange>& plan, Id c);

// For chunk r: every run it uses or owns that two or more chunks use, with
// all their users, from the ghost runs of every chunk (given whole, as a
// single process has them, or exchanged by the MPI layer: see
// sharing_for()). Sorted by first id.
std::vector<NodeRun> sharing_for(Id r, const std::vector<ChunkRange>& plan,
                                 const std::vector<std::vector<NodeRun>>& ghosts_of_every_chunk);
// The same for every chunk at once, in one process: one pass over all
// element rows. Entry c is sharing_for(c, ...).
std::vector<std::vector<NodeRun>> in_process_sharing(const FineMesh& mesh, const std::vector<ChunkRange>& plan);

// Per-rank figures of a partition without building it (projections to
// many ranks): owned, ghost and shared node counts, neighbours.
struct PartitionStats {
  Id rank = 0, elements = 0, owned_nodes = 0, ghost_nodes = 0, shared_nodes = 0;
  Id neighbors = 0;
  Id comm_entries = 0;  // sum over neighbours of the shared node list lengths
};
PartitionStats partition_stats(Id r, const std::vector<ChunkRange>& plan, const std::vector<NodeRun>& sharing);

class Partition {
 public:
  // Chunk `rank` of plan (plan_chunks(mesh, size)), with the sharing runs
  // of that chunk (sharing_for / in_process_sharing / the MPI exchange).
  // Materialises the chunk's nodes and elements (ExportChunk::prepare).
  // progress and cancel as for ExportChunk::prepare.
  Partition(const FineMesh& mesh, const std::vector<ChunkRange>& plan, Id rank, std::vector<NodeRun> sharing,
            const MeshSets& sets = {}, const std::function<void(Id, Id)>& progress = {},
            const std::function<bool()>& cancel = {});

  Id rank() const { return range_.index; }
  Id size() const { return range_.count; }
  const ChunkRange& range() const { return range_; }
  const ExportChunk& chunk() const { return chunk_; }  // the same nodes in global id order (for writers)

  Id num_owned() const { return range_.node_end - range_.node_begin; }
  Id num_nodes() const { return static_cast<Id>(node_global_.size()); }
  Id num_elements() const { return chunk_.num_elements(); }
  std::span<const Id> node_global() const { return node_global_; }          // local -> global id
  std::span<const std::int32_t> node_owner() const { return node_owner_; }  // owner rank of each local node
  std::span<const double> x() const { return x_; }
  std::span<const double> y() const { return y_; }
  std::span<const double> z() const { return z_; }
  Id element_begin() const { return chunk_.num_elements() ? chunk_.element_global()[0] : 0; }
  std::span<const Id> connectivity() const { return conn_; }  // local node ids, corners per element
  int corners() const { return chunk_.corners(); }

  const std::vector<std::int32_t>& neighbors() const { return neighbors_; }
  // Local node ids shared with neighbors()[k], sorted by global id.
  const std::vector<std::vector<Id>>& shared_nodes() const { return shared_; }
  const std::vector<NodeRun>& sharing() const { return sharing_; }
  // Local id in chunk() of local node L of the partition.
  Id chunk_local(Id L) const { return L < num_owned() ? num_nodes() - num_owned() + L : L - num_owned(); }

 private:
  ChunkRange range_;
  ExportChunk chunk_;
  std::vector<NodeRun> sharing_;
  std::vector<Id> node_global_, conn_;
  std::vector<std::int32_t> node_owner_;
  std::vector<double> x_, y_, z_;
  std::vector<std::int32_t> neighbors_;
  std::vector<std::vector<Id>> shared_;
};

// The Nemesis description of chunk `rank` of `processors` (write_exodus
// with `nemesis`) from its sharing runs (sharing_for, in_process_sharing,
// mpi::exchange_sharing): the neighbours, ascending, and per neighbour the
// nodes both use in the chunk's local numbering, sorted by global id;
// global counts. O(shared nodes); no fine data.
NemesisInfo nemesis_info(const ChunkSource& chunk, Id processors, Id rank, const std::vector<NodeRun>& sharing,
                         const SetCounts& counts);
// The same for a partition: nemesis_info(p.chunk(), p.size(), p.rank(), p.sharing(), counts).
NemesisInfo nemesis_info(const Partition& p, const SetCounts& counts);

}  // namespace dicer
