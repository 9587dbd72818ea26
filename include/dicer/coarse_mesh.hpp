#pragma once
// CoarseMesh: the input of dicing, as read from an Exodus II or Gmsh MSH file.
//
// Layout: vertex coordinates as three arrays (structure of arrays); element
// connectivity as one flat array of corners_per_element() vertex indices per
// element, in VTK/Exodus order (HEX8: bottom 0-3 counter-clockwise seen from
// the top, then top 4-7 above them; QUAD4: counter-clockwise). Indices are
// 0-based positions in x/y/z, never the ids printed in the file; those are
// kept in vertex_file_id / element_file_id for messages and for `sheets`.
//
// Invariants after read_coarse_mesh() returns (validate_coarse_mesh checks
// them, so a mesh built in memory can be checked the same way):
//  - every coordinate is finite; every connectivity entry is in range;
//  - no element repeats a vertex, no two elements share all their corners;
//  - every vertex is used by at least one element (unused ones are dropped);
//  - volume mode: every hex is right-handed (all 8 corner Jacobians > 0);
//    a wholly left-handed file is reoriented with a warning;
//  - element_block[e] indexes blocks;
//  - second-order input: mid has mid_slots(mode) entries per element, each
//    -1 or an index into mid_x/y/z (finite), and no mid node is a corner.
// Cost: memory is O(coarse mesh); nothing here grows with the fine mesh.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "dicer/orientation.hpp"
#include "dicer/types.hpp"

namespace dicer {

struct Topology;

struct Block {
  std::int64_t id = 0;   // as in the file (Exodus block id, MSH physical tag)
  std::string name;      // may be empty
};

// Sides in Exodus numbering, 0-based (orientation.hpp): hex side s of
// element e is the face with local corners kHexSideCorners[s]; shell sides
// 0,1 are the two faces of the quad, 2..5 its edges (kShellSideCorners).
struct SideSet {
  std::int64_t id = 0;
  std::string name;
  std::vector<Id> element;          // 0-based element index
  std::vector<std::int8_t> side;    // 0-based Exodus side
};

// A curve, surface or volume of the geometric model and the entities one
// dimension lower that bound it (tags; orientation signs dropped).
struct GeoEntity {
  int dim = 0, tag = 0;
  std::vector<int> bounding;
  friend bool operator==(const GeoEntity&, const GeoEntity&) = default;
};

struct NodeSet {
  std::int64_t id = 0;
  std::string name;
  std::vector<Id> vertex;           // 0-based vertex index
};

struct CoarseMesh {
  std::string source;                 // path of the file it came from (messages)
  Mode mode = Mode::Volume;
  std::vector<double> x, y, z;        // vertex coordinates
  std::vector<Id> vertex_file_id;     // id of each vertex as numbered in the file
  std::vector<Id> conn;               // corners_per_element() entries per element
  std::vector<Id> element_file_id;    // id of each element as numbered in the file
  std::vector<std::int32_t> element_block;  // index into blocks
  std::vector<Block> blocks;
  std::vector<SideSet> side_sets;
  std::vector<NodeSet> node_sets;
  // Geometric classification of each vertex (Gmsh entity dim 0..3 and tag),
  // -1 where unknown (Exodus files, MSH 2.2 without it). Empty or sized V.
  std::vector<std::int8_t> vertex_geo_dim;
  std::vector<std::int32_t> vertex_geo_tag;
  // Second-order input (HEX20/HEX27, QUAD8/QUAD9; orientation.hpp's mid-node
  // slots): per element mid_slots(mode) entries, each the index of the node
  // in that slot (into mid_x/y/z) or -1 where the element has none (a
  // HEX20's faces and centre; every slot of a first-order element in a file
  // that mixes both). The nodes after the corners, kept apart from the
  // vertices: they shape the fine mesh (quadratic.hpp) but are no fine nodes.
  // All empty for a first-order mesh.
  std::vector<Id> mid;
  std::vector<double> mid_x, mid_y, mid_z;
  std::vector<Id> mid_file_id;        // node id in the file (messages)
  // The model's topology: MSH 4.1 $Entities (or the CAD's, for intervals
  // by entity with --geometry). Empty when unknown (Exodus, MSH 1/2.2).
  std::vector<GeoEntity> geo_entities;
  // Quirks accepted (reoriented, dropped nodes, skipped blocks): one sentence
  // each, WITHOUT the file path; whoever prints them prefixes `source`.
  std::vector<std::string> warnings;
  // The topology validate_coarse_mesh built for its conformity check, kept
  // so that dicing need not build it again (topology_of, topology.hpp,
  // hands it out only while `conn` is what it was built from). A cache:
  // copies share it, and nothing else reads it.
  std::shared_ptr<const Topology> topology;
  std::uint64_t topology_key = 0;

  int corners_per_element() const { return mode == Mode::Volume ? 8 : 4; }
  Id num_vertices() const { return static_cast<Id>(x.size()); }
  Id num_elements() const { return static_cast<Id>(conn.size()) / corners_per_element(); }
  Vec3 vertex(Id v) const { return {x[v], y[v], z[v]}; }
  bool second_order() const { return !mid.empty(); }
  Vec3 mid_node(Id m) const { return {mid_x[m], mid_y[m], mid_z[m]}; }
};

// Reads an Exodus II (.e, .exo, .ex2, .g) or Gmsh MSH 1/2.2/4.1 file, chosen
// by content (netCDF/HDF5 magic vs a first line "$Section"), then
// validate_coarse_mesh().
// Throws Error{BadInput|Unsupported|Io} naming the file and what is wrong.
CoarseMesh read_coarse_mesh(const std::string& path);

// Format readers: parse only; they leave validation to validate_coarse_mesh.
CoarseMesh read_msh(const std::string& path);
CoarseMesh read_exodus(const std::string& path);

// The same mesh with elements along a Morton curve of their centroids (ties
// in file order; `morton` = false keeps the file's element order) and
// vertices in order of first use (locality for paged storage, and the owner
// order of the numbering). Optionally returns, for each new vertex /
// element, its index in `mesh`.
CoarseMesh sfc_order(const CoarseMesh& mesh, std::vector<Id>* old_vertex_of_new = nullptr,
                     std::vector<Id>* old_element_of_new = nullptr, bool morton = true);

// For readers of second-order files: `mid` holds, per element,
// mid_slots(mode) indices into x/y/z (the file's nodes, as conn does) or -1.
// Moves the nodes it names out of the vertex arrays into mid_x/y/z (each
// once, however many elements share it), fills mesh.mid with indices into
// those, and drops them from x/y/z and from node sets: x/y/z keep corners
// only. Throws Error{BadInput} for an index out of range or a node that is
// a corner of one element and a mid node of another, naming both.
void take_mid_nodes(CoarseMesh& mesh, std::vector<Id> mid);

// Checks the invariants above, drops unused vertices, reorients a wholly
// left-handed mesh (warning) and refuses mixed handedness or an inverted hex.
void validate_coarse_mesh(CoarseMesh& mesh);

}  // namespace dicer
