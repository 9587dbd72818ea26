#pragma once
// FineMesh: the implicit fine mesh. Nothing fine-sized is ever stored; every
// node and element is regenerated on demand from the coarse mesh, its
// topology and the intervals (the recipe in tfi.hpp).
//
// Access paths, all bit-identical for the same node id (invariant 2):
//  1. node(id) / element(id): random access, O(log n) lookup + O(1) TFI.
//  2. fill_block(h, block): every node and element of coarse element h, as
//     contiguous arrays (ids, x, y, z, connectivity). Cost O(block size);
//     the Block's buffers are reused between calls (no allocation once warm).
//  3. NodeCursor / ElementCursor: whole-mesh iteration in id order.
// Memory: O(coarse mesh) plus one block buffer per cursor.
// Thread safety: all const member functions may be called concurrently.
#include <array>
#include <span>
#include <string>
#include <vector>

#include "dicer/coarse_mesh.hpp"
#include "dicer/intervals.hpp"
#include "dicer/numbering.hpp"
#include "dicer/sheets.hpp"
#include "dicer/topology.hpp"

namespace dicer {

struct FineElement {
  Id id = -1;
  // VTK/Exodus HEX8 order (volume) or QUAD4 order (surface, first 4 used).
  std::array<Id, 8> nodes{};
  int num_nodes = 8;
  Id coarse_element = -1;
  std::int32_t block = -1;       // index into CoarseMesh::blocks
  std::array<Id, 3> ijk{};       // position in the coarse element's local grid
};

// The nodes and elements of one coarse element. Grid point (i, j, k) is at
// index i + (n[0]+1) * (j + (n[1]+1) * k); element (i, j, k) at
// i + n[0] * (j + n[1] * k), its nodes at conn[corners*e ...].
struct FineBlock {
  Id coarse_element = -1;
  std::array<Id, 3> n{};         // intervals along local i, j, k (k = 1 in surface mode)
  Id first_element = 0;          // fine id of element (0,0,0); elements are consecutive
  std::vector<Id> node_id;       // per grid point
  std::vector<double> x, y, z;   // per grid point
  std::vector<Id> conn;          // corners per element, fine node ids (empty if nodes_only)
  Id num_points() const { return static_cast<Id>(node_id.size()); }
  Id num_elements() const { return n[0] * n[1] * n[2]; }
  Id point_index(Id i, Id j, Id k) const { return i + (n[0] + 1) * (j + (n[1] + 1) * k); }

  // Work space of fill_block, kept here so a reused block allocates nothing.
  struct Scratch {
    std::vector<double> face[3], bottom[3], top[3], left[3], right[3], s, t, u, U;
  } scratch;
};

class FineMesh {
 public:
  FineMesh() = default;
  FineMesh(CoarseMesh coarse, Topology topo, Numbering numbering, std::vector<Id> sheet_interval);

  // Builds topology, sheets and intervals for `coarse` and dices it.
  // `notes` receives how interval conflicts were resolved.
  static FineMesh dice(CoarseMesh coarse, const IntervalRequest& request, std::vector<std::string>* notes = nullptr);

  Mode mode() const { return coarse_.mode; }
  const CoarseMesh& coarse() const { return coarse_; }
  const Topology& topology() const { return topo_; }
  const Numbering& numbering() const { return num_; }
  const std::vector<Id>& sheet_intervals() const { return sheet_interval_; }
  Id num_nodes() const { return num_.num_nodes(); }
  Id num_elements() const { return num_.num_elements(); }
  Id num_coarse_elements() const { return topo_.num_elements(); }
  int corners() const { return coarse_.corners_per_element(); }

  // Throws Error{Usage} for an id out of range.
  Vec3 node(Id id) const;
  Vec3 node(const NodeRef& ref) const;
  FineElement element(Id id) const;

  // The node at grid point (i, j, k) of coarse element h, as its owner sees it.
  NodeRef grid_node(Id h, Id i, Id j, Id k) const;

  // Fills out with every node of coarse element h (ids, x, y, z) and, unless
  // nodes_only, its elements' connectivity (conn).
  void fill_block(Id h, FineBlock& out, bool nodes_only = false) const;

  // Fine elements in each block (index into coarse().blocks).
  std::vector<Id> block_fine_elements() const;

 private:
  Vec3 edge_point(Id e, Id t) const;  // canonical t in [0, n]
  Vec3 face_point(Id f, Id u, Id v) const;
  // Coons interior point of face f from its four sides' values at (u, v)
  // (bottom, top, left, right in the canonical frame).
  Vec3 face_interior(Id f, Id u, Id v, const Vec3* sides) const;
  // Interior of face f, canonical frame, (u-1) + (v-1)(nu-1) order.
  void fill_face(Id f, FineBlock::Scratch& s) const;
  Vec3 cell_point(Id h, Id i, Id j, Id k) const;

  CoarseMesh coarse_;
  Topology topo_;
  Numbering num_;
  std::vector<Id> sheet_interval_;
};

// Whole-mesh node iteration in id order [begin, end).
class NodeCursor {
 public:
  NodeCursor(const FineMesh& mesh, Id begin, Id end);
  explicit NodeCursor(const FineMesh& mesh) : NodeCursor(mesh, 0, mesh.num_nodes()) {}
  // Next node; false at the end.
  bool next(Id& id, Vec3& xyz);

 private:
  const FineMesh& mesh_;
  Id next_, end_;
  FineBlock block_;  // cell interiors come from a block fill, not per-node TFI
  Id block_cell_ = -1;
};

// Whole-mesh element iteration in id order [begin, end).
class ElementCursor {
 public:
  ElementCursor(const FineMesh& mesh, Id begin, Id end);
  explicit ElementCursor(const FineMesh& mesh) : ElementCursor(mesh, 0, mesh.num_elements()) {}
  bool next(FineElement& out);
  // The block holding the last element returned (its coordinates are there).
  const FineBlock& block() const { return block_; }

 private:
  const FineMesh& mesh_;
  Id next_, end_;
  FineBlock block_;
};

}  // namespace dicer
