// MSH assembly: the sections of a file (msh_sections.cpp) -> CoarseMesh.
//
// Mapping (see coarse_mesh.hpp):
//  - mode: the highest dimension present (mesh_dimension): Volume if it is 3,
//    then every 3D element must be a hexahedron (type 5, or 17 HEX20, 12
//    HEX27); Surface if it is 2, then every 2D element must be a quadrangle
//    (type 3, or 16 QUAD8, 10 QUAD9). Second-order elements give their mid
//    nodes (take_mid_nodes; Gmsh's node order). Other elements of
//    that dimension are refused (Unsupported); lower-dimensional ones are
//    classification and set information (first-order quads, lines, points)
//    or skipped with one warning.
//  - blocks: the element's physical group (MSH4: first physical tag of its
//    entity; MSH2: first element tag). If no element of the mesh dimension has
//    a physical group, blocks are the elementary entities (id = entity tag,
//    name "entity <tag>"). Otherwise elements without a physical group go to a
//    block per entity, numbered above the largest physical tag (warning).
//    MSH2's physical tag 0 means "none"; MSH4 lists an entity's groups, and
//    a listed 0 is group 0 (as Gmsh reads it).
//  - side sets: physical groups of dimension dim-1 (quads of a volume mesh,
//    lines of a surface mesh), matched to element sides through a sorted
//    key table; a boundary element on an interior face goes to the matching
//    element with the lowest index. Node sets: physical groups of dimension 0.
//  - vertex_geo_dim/tag: MSH4 from the $Nodes entity block; MSH2 from the
//    lowest-dimensional element containing the node.
// Geometry (handedness, duplicates, unused nodes) is left to
// validate_coarse_mesh.
#include <algorithm>
#include <array>
#include <tuple>

#include "input_file.hpp"
#include "msh_reader.hpp"

namespace dicer::msh {
namespace {

// One rule for every input format (README, Inputs): the highest dimension
// present is the mesh's. Its elements must all be hexahedra (quadrangles
// for a surface), first or second order; lower-dimensional ones are side and node sets
// or are skipped, with one warning naming them. Returns that dimension.
int mesh_dimension(const std::string& path, const MshSections& sec, std::vector<std::string>& warnings) {
  int dim = -1;
  for (int d = 0; d < 4; ++d)
    if (sec.groups[d].size() > 0) dim = d;
  for (const auto& [key, n] : sec.others) dim = std::max(dim, type_dim(std::get<0>(key)));

  std::map<Id, std::size_t> refused;  // type -> count
  for (const auto& [key, n] : sec.others) {
    const int d = type_dim(std::get<0>(key));
    if (d == dim || d < 0) refused[std::get<0>(key)] += n;
  }
  if (!refused.empty()) {
    std::string list;
    for (const auto& [type, n] : refused) {
      if (!list.empty()) list += ", ";
      list += std::to_string(n) + " " + type_name(static_cast<int>(type)) + " (type " + std::to_string(type) + ")";
    }
    throw Error(ErrorKind::Unsupported, path + ": unsupported elements: " + list +
                                            "; dicer needs all-hex (type 5; 17, 12 second order) or all-quad "
                                            "(type 3; 16, 10 second order) meshes");
  }
  if (dim < 2)
    throw Error(ErrorKind::Unsupported,
                path + ": no hexahedra (type 5, 17, 12) or quadrangles (type 3, 16, 10); dicer needs all-hex or "
                       "all-quad meshes");

  // Skipped: other types of lower dimension, and lines in physical groups of
  // a volume mesh (dicer has no edge sets). Counted by physical group, or by
  // entity where there is none.
  // (type, in a physical group, physical, entity dim, entity)
  std::map<std::tuple<Id, bool, Id, int, Id>, std::size_t> skipped;
  auto count = [&](Id type, std::span<const int> physical, int entity_dim, Id entity, std::size_t n) {
    if (physical.empty()) skipped[{type, false, 0, entity_dim, entity}] += n;
    else skipped[{type, true, physical[0], type_dim(type), 0}] += n;
  };
  for (const auto& [key, n] : sec.others) {
    const auto& [type, entity_dim, entity, physical] = key;
    std::span<const int> p;
    const int tag = static_cast<int>(physical);
    if (physical != 0) {
      p = std::span<const int>(&tag, 1);
    } else if (sec.msh4) {
      auto it = sec.entity_physicals.find({entity_dim, static_cast<int>(entity)});
      if (it != sec.entity_physicals.end()) p = it->second;
    }
    count(type, p, entity_dim, entity, n);
  }
  if (dim == 3)
    for (std::size_t i = 0; i < sec.groups[1].size(); ++i)
      if (std::span<const int> p = sec.physicals(1, i); !p.empty()) count(kLine, p, 1, 0, 1);
  if (!skipped.empty()) {
    std::string list;
    for (const auto& [key, n] : skipped) {
      const auto& [type, grouped, physical, entity_dim, entity] = key;
      list += (list.empty() ? "" : ", ") + std::to_string(n) + " " + type_name(static_cast<int>(type)) + " (type " +
              std::to_string(type) + ") in ";
      if (grouped) {
        list += "physical group " + std::to_string(physical);
        auto it = sec.physical_names.find({entity_dim, physical});
        if (it != sec.physical_names.end() && !it->second.empty()) list += " \"" + it->second + "\"";
      } else {
        list += "entity " + std::to_string(entity);
      }
    }
    warnings.push_back(std::string("skipped elements of lower dimension than the ") +
                       (dim == 3 ? "hexahedra" : "quadrangles") + " (dicer dices only those): " + list);
  }
  return dim;
}

// MSH2 states no classification: a node lies on the lowest-dimensional
// element that holds it.
void classify_from_elements(MshSections& sec) {
  for (int d = 0; d < 4; ++d) {
    const Group& g = sec.groups[d];
    for (std::size_t i = 0; i < g.conn.size(); ++i) {
      const Id v = g.conn[i];
      if (sec.geo_dim[v] < 0) {
        sec.geo_dim[v] = static_cast<std::int8_t>(d);
        sec.geo_tag[v] = g.entity[i / static_cast<std::size_t>(kNodesOfDim[d])];
      }
    }
  }
}

void assign_blocks(const MshSections& sec, int dim, CoarseMesh& mesh) {
  const Group& cells = sec.groups[dim];
  const std::size_t num_cells = cells.size();
  std::map<Id, std::string> block_names;  // id -> name
  std::vector<Id> cell_block_id(num_cells);
  std::map<Id, Id> orphan_entities;        // entity tag -> block id (mixed case)
  Id max_physical = std::numeric_limits<Id>::min();
  for (std::size_t i = 0; i < num_cells; ++i) {
    std::span<const int> p = sec.physicals(dim, i);
    if (!p.empty()) max_physical = std::max<Id>(max_physical, p[0]);
  }
  const bool by_physical = max_physical != std::numeric_limits<Id>::min();
  std::size_t orphans = 0;
  std::map<std::vector<int>, std::size_t> several;  // an MSH4 entity's groups -> its cells
  for (std::size_t i = 0; i < num_cells; ++i) {
    std::span<const int> p = sec.physicals(dim, i);
    if (p.size() > 1) ++several[std::vector<int>(p.begin(), p.end())];
    if (!p.empty()) {
      cell_block_id[i] = p[0];
      auto it = sec.physical_names.find({dim, p[0]});
      block_names.emplace(p[0], it != sec.physical_names.end() ? it->second : std::string());
    } else if (!by_physical) {
      cell_block_id[i] = cells.entity[i];
      block_names.emplace(cells.entity[i], "entity " + std::to_string(cells.entity[i]));
    } else {
      orphan_entities.emplace(cells.entity[i], 0);
      ++orphans;
    }
  }
  if (orphans > 0) {
    Id next = max_physical;
    for (auto& [entity, id] : orphan_entities) {
      id = ++next;
      block_names.emplace(id, "entity " + std::to_string(entity));
    }
    for (std::size_t i = 0; i < num_cells; ++i)
      if (sec.physicals(dim, i).empty()) cell_block_id[i] = orphan_entities[cells.entity[i]];
    mesh.warnings.push_back(std::to_string(orphans) + " " + (dim == 3 ? "hexahedra" : "quadrangles") +
                            " are in no physical group; they were put in blocks named 'entity <tag>' with ids from " +
                            std::to_string(max_physical + 1));
  }
  // An element has one block: the first group wins, said (MSH 2's repeated
  // elements are counted in assemble).
  std::size_t told = 0, untold = 0;
  for (const auto& [groups, n] : several) {
    if (++told > 5) {
      untold += n;
      continue;
    }
    std::string list;
    for (const int g : groups) {
      list += (list.empty() ? "" : ", ") + std::to_string(g);
      auto it = sec.physical_names.find({dim, g});
      if (it != sec.physical_names.end() && !it->second.empty()) list += " \"" + it->second + "\"";
    }
    mesh.warnings.push_back(std::to_string(n) + " " + (dim == 3 ? "hexahedra" : "quadrangles") +
                            " are in physical groups " + list + ": each was put in the block of the first, " +
                            std::to_string(groups.front()) + " (an element has one block)");
  }
  if (untold > 0)
    mesh.warnings.push_back(std::to_string(untold) + " more " + (dim == 3 ? "hexahedra" : "quadrangles") +
                            " are in several physical groups; each was put in the block of its first");
  std::map<Id, std::int32_t> block_index;
  for (const auto& [id, name] : block_names) {
    block_index.emplace(id, static_cast<std::int32_t>(mesh.blocks.size()));
    mesh.blocks.push_back(Block{id, name});
  }
  mesh.element_block.resize(num_cells);
  for (std::size_t i = 0; i < num_cells; ++i) mesh.element_block[i] = block_index[cell_block_id[i]];
}

// Side sets: physical groups of dimension dim-1, matched to element sides
// by the sorted corner ids of each side.
void assign_side_sets(const MshSections& sec, int dim, CoarseMesh& mesh) {
  const Group& cells = sec.groups[dim];
  const Group& bnd = sec.groups[dim - 1];
  bool any_side = false;
  for (std::size_t i = 0; i < bnd.size() && !any_side; ++i) any_side = !sec.physicals(dim - 1, i).empty();
  if (!any_side) return;

  using Key = std::array<Id, 4>;  // sorted corners; -1 pads a line's two
  struct Side {
    Key key;
    Id element;
    std::int8_t side;
  };
  const std::size_t num_cells = cells.size();
  const std::size_t corners = static_cast<std::size_t>(kNodesOfDim[dim]);
  std::vector<Side> sides;
  sides.reserve(num_cells * (dim == 3 ? 6 : 4));
  for (std::size_t e = 0; e < num_cells; ++e) {
    const Id* c = &cells.conn[e * corners];
    if (dim == 3) {
      for (int s = 0; s < 6; ++s) {
        Key k;
        for (int j = 0; j < 4; ++j) k[j] = c[kHexSideCorners[s][j]];
        std::sort(k.begin(), k.end());
        sides.push_back({k, static_cast<Id>(e), static_cast<std::int8_t>(s)});
      }
    } else {
      for (int s = 2; s < 6; ++s) {
        Key k{-1, -1, c[kShellSideCorners[s - 2][0]], c[kShellSideCorners[s - 2][1]]};
        std::sort(k.begin(), k.end());
        sides.push_back({k, static_cast<Id>(e), static_cast<std::int8_t>(s)});
      }
    }
  }
  auto less = [](const Side& a, const Side& b) { return std::tie(a.key, a.element) < std::tie(b.key, b.element); };
  std::sort(sides.begin(), sides.end(), less);

  std::map<Id, SideSet> side_sets;
  std::size_t unmatched = 0;
  Id first_unmatched = 0;
  const int bnd_corners = kNodesOfDim[dim - 1];
  for (std::size_t i = 0; i < bnd.size(); ++i) {
    std::span<const int> p = sec.physicals(dim - 1, i);
    if (p.empty()) continue;
    Key k{-1, -1, -1, -1};
    for (int j = 0; j < bnd_corners; ++j)
      k[4 - bnd_corners + j] = bnd.conn[i * static_cast<std::size_t>(bnd_corners) + j];
    std::sort(k.begin(), k.end());
    auto it = std::lower_bound(sides.begin(), sides.end(), Side{k, -1, 0}, less);
    if (it == sides.end() || it->key != k) {
      if (unmatched++ == 0) first_unmatched = bnd.tag[i];
      continue;
    }
    for (int tag : p) {
      SideSet& ss = side_sets[tag];
      ss.element.push_back(it->element);
      ss.side.push_back(it->side);
    }
  }
  for (auto& [id, ss] : side_sets) {
    ss.id = id;
    auto it = sec.physical_names.find({dim - 1, id});
    if (it != sec.physical_names.end()) ss.name = it->second;
    mesh.side_sets.push_back(std::move(ss));
  }
  if (unmatched > 0)
    mesh.warnings.push_back(std::to_string(unmatched) + " " + (dim == 3 ? "quadrangles" : "lines") +
                            " in physical groups match no " + (dim == 3 ? "hexahedron face" : "quadrangle edge") +
                            " and were skipped (the first is element " + std::to_string(first_unmatched) + ")");
}

// Node sets: physical groups of dimension 0 (point elements).
void assign_node_sets(const MshSections& sec, CoarseMesh& mesh) {
  std::map<Id, std::vector<Id>> node_sets;
  for (std::size_t i = 0; i < sec.groups[0].size(); ++i)
    for (int tag : sec.physicals(0, i)) node_sets[tag].push_back(sec.groups[0].conn[i]);
  for (auto& [id, vertices] : node_sets) {
    std::sort(vertices.begin(), vertices.end());
    vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
    NodeSet ns;
    ns.id = id;
    auto it = sec.physical_names.find({0, id});
    if (it != sec.physical_names.end()) ns.name = it->second;
    ns.vertex = std::move(vertices);
    mesh.node_sets.push_back(std::move(ns));
  }
}

}  // namespace

CoarseMesh assemble(const std::string& path, MshSections sec) {
  CoarseMesh mesh;
  mesh.source = path;
  const int dim = mesh_dimension(path, sec, mesh.warnings);
  mesh.mode = dim == 3 ? Mode::Volume : Mode::Surface;
  if (!sec.msh4) classify_from_elements(sec);
  assign_blocks(sec, dim, mesh);
  if (sec.periodic)
    mesh.warnings.push_back("its $Periodic section is not applied: sheets of the paired boundaries get their intervals "
                            "independently, so the fine mesh need not match across them (give them one interval)");
  if (sec.repeated > 0)
    mesh.warnings.push_back(std::to_string(sec.repeated) +
                            " element(s) are listed again, same tag and nodes, for a further physical group (Gmsh's "
                            "MSH 2 writer does this); each was kept once, in its first group");
  assign_side_sets(sec, dim, mesh);
  assign_node_sets(sec, mesh);

  mesh.x = std::move(sec.x);
  mesh.y = std::move(sec.y);
  mesh.z = std::move(sec.z);
  mesh.vertex_file_id = std::move(sec.node_tag);
  mesh.vertex_geo_dim = std::move(sec.geo_dim);
  mesh.vertex_geo_tag = std::move(sec.geo_tag);
  mesh.geo_entities = std::move(sec.entities);
  mesh.conn = std::move(sec.groups[dim].conn);
  mesh.element_file_id = std::move(sec.groups[dim].tag);
  if (!sec.groups[dim].mid.empty()) take_mid_nodes(mesh, std::move(sec.groups[dim].mid));
  return mesh;
}

}  // namespace dicer::msh

namespace dicer {

// Our own bounds-checked parser, not the Gmsh API: Gmsh 4.8 segfaults on
// some malformed or unusual MSH files and keeps global state.
CoarseMesh read_msh(const std::string& path) {
  msh::Lexer lex(path, InputFile(path).read_all());
  return msh::assemble(path, msh::read_sections(lex));
}

}  // namespace dicer
